"""The command line renders a saved .blend exactly as the engine does inside Blender."""

import json
import subprocess
import sys

import bpy
import numpy as np

import scenes as S
from sampling_lab.core.exr import read_multilayer


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "sampling_lab", "render", *args],
                          capture_output=True, text=True, timeout=600)


def test_cli_render_of_a_saved_blend_matches_the_engine_bit_for_bit(empty_scene, tmp_path):
    scene = empty_scene
    S.cornell_box(scene, "area", (24, 16))
    S.set_sampling_lab(scene, samples=3, seed=11, max_bounces=3)
    engine = S.render_to_exr(scene, tmp_path / "engine.exr")
    blend = tmp_path / "box.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)

    run = _cli(str(blend), "-o", str(tmp_path / "cli.exr"), "--json", "--quiet")
    assert run.returncode == 0, run.stderr
    stats = json.loads(run.stdout.strip().splitlines()[-1])
    assert stats["spp"] == 3 and stats["width"] == 24 and stats["height"] == 16
    cli = read_multilayer(tmp_path / "cli.exr")
    for name in ("Combined", "Variance", "Sample Count"):
        np.testing.assert_array_equal(cli[name], engine[name])


def test_cli_overrides_resolution_samples_and_frame_of_a_blend(empty_scene, tmp_path):
    scene = empty_scene
    S.cornell_box(scene, "point", (24, 16))
    blend = tmp_path / "box.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    run = _cli(str(blend), "-o", str(tmp_path / "o.exr"), "--resolution", "10x6", "--spp", "2",
               "--frame", "5", "--json", "--quiet")
    assert run.returncode == 0, run.stderr
    out = read_multilayer(tmp_path / "o.exr")
    assert out["Combined"].shape == (6, 10, 4)
    assert (out["Sample Count"] == 2).all()


def test_cli_blend_without_camera_exits_2_with_one_line(empty_scene, tmp_path):
    S.add_quad(empty_scene, "Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    blend = tmp_path / "nocam.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    run = _cli(str(blend), "-o", str(tmp_path / "o.exr"))
    assert run.returncode == 2
    lines = run.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("sampling_lab: error:") and "camera" in lines[0]
    # Blender's own "Read blend: ..." line, printed by its C code while the file loads, is hidden.
    assert run.stdout == "", run.stdout
    assert not (tmp_path / "o.exr").exists()
