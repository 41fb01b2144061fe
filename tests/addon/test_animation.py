"""Animation renders in Blender: the equivalent of
``blender -b scene.blend -E SAMPLING_LAB -o //frames/f_#### -s 1 -e 3 -a``.

The scene is a Cornell box (direct light only: one bounce of noise from sampling the area
lamp) with a small block that moves across the floor, keyframed on frames 1, 2 and 3. Pixels the
block never touches (in no frame does it change them: the same pixels of a render without the
block are bit-identical) must be bit-identical in every frame with a fixed seed, and differ with
Animate Seed; every frame must be the still render of its frame.
"""

from pathlib import Path

import bpy
import numpy as np
import pytest

import scenes

FRAMES = (1, 2, 3)
BLOCK_X = {1: -0.5, 2: 0.0, 3: 0.5}


def _moving_block_scene(scene, tmp_path):
    """The animated scene, saved as ``tmp_path/scene.blend`` (so ``//`` is ``tmp_path``)."""
    scenes.cornell_box(scene, "area", resolution=(24, 24), blocks=False)
    scenes.set_sampling_lab(scene, samples=4, seed=2, max_bounces=0)
    block = scenes.add_block(scene, "Mover", (BLOCK_X[1], -0.3, 0.2), (0.4, 0.4, 0.4),
                             material=bpy.data.materials["White"])
    for frame, x in BLOCK_X.items():
        block.location.x = x
        block.keyframe_insert("location", frame=frame)
    scene.frame_start, scene.frame_end = FRAMES[0], FRAMES[-1]
    scenes.set_output_multilayer_exr(scene, "//frames/f_####")
    scene.render.use_file_extension = True
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    return block


def _render_animation(scene):
    """Render frames ``frame_start..frame_end``; the passes of each frame by frame number."""
    bpy.ops.render.render(animation=True, scene=scene.name)
    frames = {}
    for frame in range(scene.frame_start, scene.frame_end + 1, scene.frame_step):
        frames[frame] = scenes.read_blender_exr(bpy.path.abspath(scene.render.frame_path(
            frame=frame)))
    return frames


def _still(scene, path, frame):
    scene.frame_set(frame)
    return scenes.render_to_exr(scene, path)["Combined"]


def test_animation_writes_every_frame_of_its_object_animation(empty_scene, tmp_path, capfd):
    block = _moving_block_scene(empty_scene, tmp_path)
    capfd.readouterr()
    frames = _render_animation(empty_scene)
    log = capfd.readouterr().out

    # Every frame where Blender's pattern puts it, and nothing else.
    written = sorted(p.name for p in (tmp_path / "frames").iterdir())
    assert written == ["f_0001.exr", "f_0002.exr", "f_0003.exr"]
    for frame in FRAMES:
        assert Path(bpy.path.abspath(empty_scene.render.frame_path(frame=frame))) == (
            tmp_path / "frames" / f"f_{frame:04d}.exr")
        # One stats line per frame.
        assert log.count(f"Sampling Lab: frame {frame}: 4 spp (2304 samples)") == 1, log

    combined = {f: frames[f]["Combined"] for f in FRAMES}
    # Each frame is the still render of its frame: the block where that frame puts it.
    for frame in FRAMES:
        still = _still(empty_scene, tmp_path / f"still_{frame}.exr", frame)
        np.testing.assert_array_equal(combined[frame], still, err_msg=f"frame {frame}")

    # Pixels the block touches in no frame: equal to a render without the block.
    block.hide_render = True
    empty = _still(empty_scene, tmp_path / "empty.exr", 1)
    untouched = np.all([np.all(combined[f] == empty, axis=-1) for f in FRAMES], axis=0)
    variance = frames[1]["Variance"].sum(axis=-1)
    # Many of them are noisy (their equality is the same noise, not a noise-free image; the
    # ceiling, which the downward lamp does not light, is black).
    assert (untouched & (variance > 0)).mean() > 0.3
    for frame in FRAMES[1:]:
        np.testing.assert_array_equal(combined[frame][untouched], combined[1][untouched])

    # Where the block is on frame 1 (and not on frame 3) the frames differ.
    moved = np.any(combined[1] != empty, axis=-1) & np.all(combined[3] == empty, axis=-1)
    assert moved.sum() >= 8
    assert np.all(np.any(combined[1][moved] != combined[3][moved], axis=-1))


def test_animate_seed_adds_the_frame_number_to_the_seed(empty_scene, tmp_path):
    block = _moving_block_scene(empty_scene, tmp_path)
    block.hide_render = True  # a still scene: only the seed changes between frames
    fixed = _render_animation(empty_scene)
    empty_scene.sampling_lab.use_animated_seed = True
    animated = _render_animation(empty_scene)
    noisy = fixed[1]["Variance"].sum(axis=-1) > 0
    assert noisy.mean() > 0.3
    for frame in FRAMES[1:]:
        # Off: the same noise in every frame; on: new noise where there is noise.
        np.testing.assert_array_equal(fixed[frame]["Combined"], fixed[1]["Combined"])
        changed = np.any(animated[frame]["Combined"] != animated[1]["Combined"], axis=-1)
        # (A few pixels' variance is float rounding of equal samples.)
        assert changed[noisy].mean() > 0.97 and changed.mean() > 0.3
    # On: frame f uses seed + f (Cycles' Animate Seed gives each frame its own seed).
    empty_scene.sampling_lab.use_animated_seed = False
    for frame in FRAMES:
        empty_scene.sampling_lab.seed = 2 + frame
        still = _still(empty_scene, tmp_path / f"seed_{frame}.exr", frame)
        np.testing.assert_array_equal(animated[frame]["Combined"], still)


def test_frame_range_and_step_choose_the_frames_written(empty_scene, tmp_path):
    _moving_block_scene(empty_scene, tmp_path)
    empty_scene.render.resolution_percentage = 25
    empty_scene.frame_start, empty_scene.frame_end, empty_scene.frame_step = 2, 6, 2
    frames = _render_animation(empty_scene)
    written = sorted(p.name for p in (tmp_path / "frames").iterdir())
    assert written == ["f_0002.exr", "f_0004.exr", "f_0006.exr"]
    assert all(f["Combined"].shape == (6, 6, 4) for f in frames.values())


def test_resolution_percentage_renders_the_scaled_frame(empty_scene, tmp_path):
    """50 % of 32 x 24 is the same image as 16 x 12 at 100 % (the camera sees the same view)."""
    scenes.cornell_box_mesh_light(empty_scene, resolution=(32, 24))
    scenes.set_sampling_lab(empty_scene, samples=2, seed=1)
    empty_scene.render.resolution_percentage = 50
    half = scenes.render_to_exr(empty_scene, tmp_path / "half.exr")
    scenes.set_resolution(empty_scene, 16, 12)
    small = scenes.render_to_exr(empty_scene, tmp_path / "small.exr")
    assert half["Combined"].shape == (12, 16, 4)
    for name in ("Combined", "Variance", "Sample Count"):
        np.testing.assert_array_equal(half[name], small[name], err_msg=name)
    assert half["Combined"][..., :3].mean() > 0


def test_persistent_data_keeps_the_scene_while_only_the_camera_moves(empty_scene, tmp_path,
                                                                      capfd):
    """With Persistent Data the prepared scene (BVH, light tables) of one frame is reused by the
    next when only the camera moved, with the same image as a fresh preparation; a frame where
    an object moved is prepared again."""
    block = _moving_block_scene(empty_scene, tmp_path)
    block.animation_data_clear()
    block.location.x = BLOCK_X[1]
    for frame in (1, 2):  # the block stays put on frames 1 and 2, moves on frame 3
        block.keyframe_insert("location", frame=frame)
    block.location.x = BLOCK_X[3]
    block.keyframe_insert("location", frame=3)
    camera = empty_scene.camera
    for frame, z in ((1, 1.0), (2, 1.2), (3, 1.2)):
        camera.location.z = z
        camera.keyframe_insert("location", frame=frame)
    fresh = _render_animation(empty_scene)
    capfd.readouterr()
    empty_scene.render.use_persistent_data = True
    kept = _render_animation(empty_scene)
    log = capfd.readouterr().out
    lines = {f: next(line for line in log.splitlines() if f"Sampling Lab: frame {f}: " in line)
             for f in FRAMES}
    assert "scene kept from the last render" not in lines[1]  # a new engine: nothing kept
    assert "scene kept from the last render" in lines[2]      # only the camera moved
    assert "scene kept from the last render" not in lines[3]  # the block moved
    for frame in FRAMES:
        np.testing.assert_array_equal(kept[frame]["Combined"], fresh[frame]["Combined"])
    assert not np.array_equal(kept[1]["Combined"], kept[2]["Combined"])
