"""Command line: ``python -m sampling_lab render`` writes the EXR, PNG and JSON it promises, and
every usage error exits with code 2 and one line on stderr.

Renders and a few usage errors run as ``sys.executable -m sampling_lab ...``, as a user runs them
(exit code, stdout and stderr of the real entry point); the other usage errors call
``cli.main(argv)``, which is what ``__main__`` runs, one after another in a single helper
process, so the test process never imports the add-on (and with it ``bpy``). All processes start
together (``cli_runs``) so the suite waits for them once.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from sampling_lab.core.exr import read_multilayer
from sampling_lab.core.render import RenderSettings, render
from sampling_lab.core.scenes import BUILTIN

W, H, SPP = 32, 24, 2
RENDER = ["render", "cornell", "--spp", str(SPP), "--resolution", f"{W}x{H}"]

ERROR_CASES = {
    "unknown option": RENDER + ["-o", "{tmp}/a.exr", "--no-such-option"],
    "unknown scene": ["render", "no_such_scene", "-o", "{tmp}/a.exr"],
    "unknown integrator": RENDER + ["-o", "{tmp}/a.exr", "--integrator", "no_such_integrator"],
    "unknown sampler": RENDER + ["-o", "{tmp}/a.exr", "--sampler", "no_such_sampler"],
    "missing .blend": ["render", "{tmp}/missing.blend", "-o", "{tmp}/a.exr"],
    "directory .blend": ["render", "{tmp}/folder.blend", "-o", "{tmp}/a.exr"],
    "zero resolution": ["render", "cornell", "-o", "{tmp}/a.exr", "--resolution", "0x24"],
    "malformed resolution": ["render", "cornell", "-o", "{tmp}/a.exr", "--resolution", "32by24"],
    "incomplete resolution": ["render", "cornell", "-o", "{tmp}/a.exr", "--resolution", "32x"],
    "missing output": ["render", "cornell"],
    "no command": [],
    "output under a file": RENDER + ["-o", "{tmp}/a_file/a.exr"],
    "output is a folder": RENDER + ["-o", "{tmp}/folder.exr"],
    "zero samples": ["render", "cornell", "-o", "{tmp}/a.exr", "--spp", "0"],
    "negative resolution": ["render", "cornell", "-o", "{tmp}/a.exr", "--resolution", "-5x10"],
    "negative time": ["render", "cornell", "-o", "{tmp}/a.exr", "--time", "-1"],
    "infinite time": ["render", "cornell", "-o", "{tmp}/a.exr", "--time", "inf"],
    "NaN time": ["render", "cornell", "-o", "{tmp}/a.exr", "--time", "nan"],
    "negative seed": ["render", "cornell", "-o", "{tmp}/a.exr", "--seed", "-1"],
    "negative threads": ["render", "cornell", "-o", "{tmp}/a.exr", "--threads", "-2"],
    "image as scene": ["render", "image.exr", "-o", "{tmp}/a.exr"],
    "huge resolution": ["render", "cornell", "-o", "{tmp}/a.exr", "--resolution",
                        "100000x100000"],
}
# What each of those errors must name (the cause, in the user's terms).
ERROR_WORDS = {
    "output under a file": "is a file, not a folder",
    "output is a folder": "it is a folder",
    "zero samples": "--time SECONDS",
    "negative resolution": "'-5x10'",
    "negative time": "-1.0 is not a number in [0, inf] (it is negative)",
    "infinite time": "--time inf never stops",
    "NaN time": "nan is not a number in [0, inf] (it is NaN)",
    "negative seed": "seed: -1 is not an integer in [0, 2147483647] (it is negative)",
    "negative threads": "(it is negative)",
    "huge resolution": "a 100000 x 100000 image needs about",
    "image as scene": "'image.exr' is not a scene: give a .blend file",
}
# Flags the light tracer does not use (each prints a note) beside one it uses (--max-depth).
NOT_FOR_LIGHT = ["--integrator", "light", "--mis", "balance", "--mis-beta", "3",
                 "--light-selection", "tree", "--strategy-max-length", "4", "--max-depth", "4"]
RUNS = {
    "json": RENDER + ["-o", "{tmp}/out.exr", "--json", "--png"],
    "plain": RENDER + ["-o", "{tmp}/plain.exr"],
    "error: unknown scene": ERROR_CASES["unknown scene"],
    "error: corrupt .blend": ["render", "{tmp}/corrupt.blend", "-o", "{tmp}/a.exr"],
    "no bpy": RENDER + ["-o", "{tmp}/nobpy.exr", "--quiet"],
    "notes": RENDER + ["-o", "{tmp}/notes.exr", "--quiet", *NOT_FOR_LIGHT],
}

# Runs main(argv) for each case with Python-level stdout and stderr captured.
DRIVER = """
import contextlib, io, json, sys
from sampling_lab.cli import main
results = {}
for name, argv in json.loads(sys.argv[1]).items():
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except BaseException as exc:  # a traceback is a failure of the case, not the driver
            code = f"raised {exc!r}"
    results[name] = [code, out.getvalue(), err.getvalue()]
print(json.dumps(results))
"""


@pytest.fixture(scope="module")
def cli_runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cli")
    (tmp / "corrupt.blend").write_bytes(b"this is not a blend file\n" * 10)
    (tmp / "folder.blend").mkdir()
    (tmp / "folder.exr").mkdir()
    (tmp / "a_file").write_text("a file where the output wants a folder\n")
    # A bpy that cannot be imported, for the run that must not need Blender.
    (tmp / "no_bpy" / "bpy").mkdir(parents=True)
    (tmp / "no_bpy" / "bpy" / "__init__.py").write_text("raise ImportError('no bpy here')\n")

    def run(args, env=None):
        argv = [a.format(tmp=tmp) for a in args]
        return subprocess.run([sys.executable, "-m", "sampling_lab", *argv], cwd=tmp, env=env,
                              capture_output=True, text=True, timeout=300)

    def drive():
        cases = {k: [a.format(tmp=tmp) for a in v] for k, v in ERROR_CASES.items()}
        r = subprocess.run([sys.executable, "-c", DRIVER, json.dumps(cases)], cwd=tmp,
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        return json.loads(r.stdout.splitlines()[-1])

    no_bpy_env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(tmp / "no_bpy")] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    with ThreadPoolExecutor(max_workers=3) as pool:
        futures = {name: pool.submit(run, args, no_bpy_env if name == "no bpy" else None)
                   for name, args in RUNS.items()}
        driven = pool.submit(drive)
        results = {name: f.result() for name, f in futures.items()}
        results["main"] = driven.result()
    return tmp, results


def test_render_writes_exr_with_combined_variance_and_sample_count(cli_runs):
    tmp, runs = cli_runs
    r = runs["json"]
    assert r.returncode == 0, r.stderr
    passes = read_multilayer(tmp / "out.exr")
    assert set(passes) >= {"Combined", "Variance", "Sample Count"}
    assert passes["Combined"].shape == (H, W, 4)
    assert passes["Variance"].shape == (H, W, 3)
    assert passes["Sample Count"].shape == (H, W, 1)
    assert np.all(passes["Combined"][..., 3] == 1.0)
    assert np.all(np.isfinite(passes["Combined"])) and np.all(passes["Variance"] >= 0)
    assert np.all(passes["Sample Count"] == SPP)


def test_render_exr_is_the_image_core_render_makes(cli_runs):
    """The CLI renders the named scene with the default seed: bit-identical to render()."""
    tmp, runs = cli_runs
    assert runs["json"].returncode == 0, runs["json"].stderr
    expected = render(BUILTIN["cornell"](W, H), RenderSettings(spp=SPP, threads=2))
    passes = read_multilayer(tmp / "out.exr")
    np.testing.assert_array_equal(passes["Combined"], expected.combined())
    assert passes["Combined"][..., :3].max() > 0  # the Cornell box is lit


def test_json_flag_prints_one_json_line_of_figures_on_stdout(cli_runs):
    _, runs = cli_runs
    r = runs["json"]
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert len(lines) == 1, f"stdout holds {len(lines)} lines: {r.stdout!r}"
    stats = json.loads(lines[0])
    assert stats["spp"] == SPP
    assert stats["samples"] == W * H * SPP
    for key in ("time_s", "samples_per_s", "rays_per_s"):
        assert isinstance(stats[key], float) and stats[key] > 0, key


def test_png_flag_writes_a_png_preview_beside_the_exr(cli_runs):
    tmp, runs = cli_runs
    assert runs["json"].returncode == 0, runs["json"].stderr
    data = (tmp / "out.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert data[12:16] == b"IHDR"
    assert struct.unpack(">II", data[16:24]) == (W, H)
    assert not (tmp / "plain.png").exists(), "a PNG was written without --png"


def test_progress_bar_goes_to_stderr_not_stdout(cli_runs):
    tmp, runs = cli_runs
    r = runs["plain"]
    assert r.returncode == 0, r.stderr
    assert r.stdout == ""
    assert "100.0%" in r.stderr and "[####" in r.stderr
    assert (tmp / "plain.exr").is_file()
    # With --json the bar is still there, on stderr, and stdout carries only the JSON.
    assert "100.0%" in runs["json"].stderr


def test_final_progress_line_reports_every_sample_done(cli_runs):
    _, runs = cli_runs
    last = [line for line in runs["plain"].stderr.splitlines() if "%" in line][-1]
    assert f"Sample {SPP}/{SPP}" in last, last


def _assert_usage_error(returncode, stdout, stderr, python_stdout=True):
    assert returncode == 2, f"exit code {returncode}; stderr: {stderr[-500:]}"
    lines = stderr.splitlines()
    assert len(lines) == 1, f"stderr holds {len(lines)} lines: {stderr!r}"
    assert lines[0].startswith("sampling_lab: error:"), lines[0]
    if python_stdout:  # (Blender's C code may print its own notes to the process's stdout)
        assert stdout == ""


@pytest.mark.parametrize("case", list(ERROR_CASES))
def test_usage_errors_exit_2_with_one_line_on_stderr(cli_runs, case):
    tmp, runs = cli_runs
    code, out, err = runs["main"][case]
    _assert_usage_error(code, out, err)
    assert not (tmp / "a.exr").exists()


@pytest.mark.parametrize("case", list(ERROR_WORDS))
def test_usage_errors_name_their_cause_before_rendering(cli_runs, case):
    _, runs = cli_runs
    code, _, err = runs["main"][case]
    assert code == 2 and ERROR_WORDS[case] in err, err
    assert "%" not in err  # refused before the progress bar ever showed


def test_json_lists_every_layer_the_exr_holds(cli_runs):
    tmp, runs = cli_runs
    stats = json.loads(runs["json"].stdout.splitlines()[0])
    assert stats["layers"] == list(read_multilayer(str(tmp / "out.exr")))
    assert stats["layers"][:3] == ["Combined", "Variance", "Sample Count"]


def test_a_failed_write_goes_to_the_temporary_folder_and_says_where(tmp_path, monkeypatch,
                                                                      capsys):
    from sampling_lab import cli

    (tmp_path / "a_file").write_text("in the way\n")
    monkeypatch.setattr(cli.tempfile, "tempdir", str(tmp_path))
    image = np.ones((2, 3, 4), np.float32)
    written = cli.write_output(str(tmp_path / "a_file" / "x.exr"), {"Combined": image})
    assert written == str(tmp_path / "sampling_lab-x.exr")
    assert np.array_equal(read_multilayer(written)["Combined"], image)
    assert written in capsys.readouterr().err


def test_frame_on_a_built_in_scene_prints_a_note(tmp_path):
    r = subprocess.run([sys.executable, "-m", "sampling_lab", *RENDER, "--frame", "3", "--quiet",
                        "-o", str(tmp_path / "f.exr")], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert "note: --frame 3 does not apply to the built-in scene 'cornell'" in r.stderr


def test_ctrl_c_writes_the_samples_taken_and_exits_130(tmp_path):
    """SIGINT during a render of up to 60 s: the EXR holds the samples taken, exit code 130."""
    import signal
    import time

    out = tmp_path / "c.exr"
    proc = subprocess.Popen([sys.executable, "-m", "sampling_lab", "render", "cornell",
                             "--resolution", "32x24", "--time", "60", "-o", str(out)],
                            stderr=subprocess.PIPE, text=True)
    # Wait for the progress bar's first line: the render loop is running.
    proc.stderr.read(1)
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err[-500:]
    assert "cancelled; writing the samples taken" in err
    count = read_multilayer(str(out))["Sample Count"]
    assert count.min() >= 1


@pytest.mark.parametrize("case", [
    "unknown scene", "corrupt .blend"])
def test_usage_errors_of_the_entry_point_exit_2_with_one_line_on_stderr(cli_runs, case):
    _, runs = cli_runs
    r = runs[f"error: {case}"]
    _assert_usage_error(r.returncode, r.stdout, r.stderr, python_stdout=False)


def test_built_in_scenes_render_without_bpy(cli_runs):
    tmp, runs = cli_runs
    r = runs["no bpy"]
    assert r.returncode == 0, r.stderr[-800:]
    assert read_multilayer(tmp / "nobpy.exr")["Combined"].shape == (H, W, 4)


def test_render_command_works_without_the_tools_folder(tmp_path):
    # The extension archive leaves tools/ out: `render` must not need it (the tools' commands
    # are then simply absent). A None entry in sys.modules makes the import fail as a missing
    # package would.
    code = (
        "import sys; sys.modules['sampling_lab.tools'] = None\n"
        "from sampling_lab import cli\n"
        "parser = cli.build_parser()\n"
        "assert 'bench' not in parser.format_help(), parser.format_help()\n"
        f"sys.exit(cli.main(['render', 'cornell', '-o', r'{tmp_path / 'x.exr'}', '--spp', '1',"
        " '--resolution', '8x8', '--quiet']))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "x.exr").exists()


def test_flags_the_integrator_does_not_use_print_one_note_each(cli_runs):
    _, runs = cli_runs
    r = runs["notes"]
    assert r.returncode == 0, r.stderr
    notes = [line for line in r.stderr.splitlines() if line.startswith("note: --")]
    assert notes == [
        "note: --mis balance does not apply to light; it is ignored",
        "note: --mis-beta 3.0 does not apply to light; it is ignored",
        "note: --light-selection tree does not apply to light: it uses power",
        "note: --strategy-max-length 4 does not apply to light; it is ignored",
    ], r.stderr


def test_unused_options_are_the_ones_the_panels_grey_out():
    from sampling_lab.core.applied_settings import unused_options

    def unused(**kw):
        return unused_options(RenderSettings(**kw))

    assert "mis_heuristic" not in unused() and "max_bounces" not in unused()
    assert unused(integrator="light")["mis_heuristic"] == "n/a"
    assert unused(mis_heuristic="balance")["mis_beta"] == "n/a"
    radiosity = unused(integrator="radiosity")
    assert radiosity["max_bounces"] == radiosity["use_russian_roulette"] == "n/a"
    assert "rr_min_bounces" in unused(use_russian_roulette=False)
    assert "rr_min_bounces" not in unused()
    assert "strategy_max_length" in unused(integrator="bdpt")
    assert not {"strategy_views", "strategy_max_length"} & set(
        unused(integrator="bdpt", strategy_views=True))
    assert "photons" in unused() and "photons" not in unused(integrator="sppm")


def test_help_documents_threads_zero_and_the_seed_range():
    from sampling_lab.cli import build_parser

    render = build_parser()._subparsers._group_actions[0].choices["render"]
    text = " ".join(render.format_help().split())
    assert "0 is one per CPU core" in text
    assert "--seed SEED" in text and "in [0, 2147483647]" in text
