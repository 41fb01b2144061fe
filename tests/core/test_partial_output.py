"""A render's EXR says in its header whether it is the whole render: ``samplingLab.partial``
is "true" after Ctrl-C (with the samples taken) and "false" for a complete render, read back
with the OpenEXR package."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import numpy as np

from sampling_lab.core import scenes
from sampling_lab.core.exr import read_metadata, read_multilayer, render_metadata
from sampling_lab.core.render import render
from tests.helpers import plain_settings


def _cli(*args):
    return [sys.executable, "-m", "sampling_lab", "render", "cornell", *args]


def test_a_complete_render_is_marked_complete(tmp_path):
    out = tmp_path / "full.exr"
    done = subprocess.run(_cli("--resolution", "8x6", "--spp", "3", "-o", str(out)),
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-500:]
    header = read_metadata(out)
    assert header["samplingLab.partial"] == "false"
    assert header["samplingLab.spp"] == "3"
    assert header["samplingLab.samples"] == str(8 * 6 * 3)


def test_ctrl_c_writes_an_exr_marked_partial_with_the_samples_taken(tmp_path):
    out = tmp_path / "partial.exr"
    proc = subprocess.Popen(_cli("--resolution", "32x24", "--time", "60", "-o", str(out)),
                            stderr=subprocess.PIPE, text=True)
    proc.stderr.read(1)  # the progress bar's first output: the render loop is running
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err[-500:]
    header = read_metadata(out)
    assert header["samplingLab.partial"] == "true"
    count = read_multilayer(str(out))["Sample Count"]
    # Every sample taken is in the file, and the header counts them.
    assert int(header["samplingLab.samples"]) == int(count.sum()) > 0
    assert int(header["samplingLab.spp"]) <= count.min()


def test_render_metadata_says_cancelled_renders_are_partial():
    scene = scenes.cornell_box(8, 6)
    full = render(scene, plain_settings(spp=2))
    cut = render(scene, plain_settings(spp=1000), cancel=lambda: True)
    assert render_metadata(full) == {"samplingLab.partial": "false", "samplingLab.spp": "2",
                                     "samplingLab.samples": "96"}
    assert render_metadata(cut)["samplingLab.partial"] == "true"
    assert np.isfinite(cut.combined()).all()


class _Failing:
    """Wraps an integrator's ``render_samples``: the ``fail_at``-th call raises."""

    def __init__(self, original, fail_at):
        self.original, self.fail_at, self.calls = original, fail_at, 0

    def __call__(self, integrator, *args):
        self.calls += 1
        if self.calls == self.fail_at:
            raise RuntimeError("unit broke")
        return self.original(integrator, *args)


def _fail_path_tracer(monkeypatch, fail_at):
    from sampling_lab.core.integrators.path import PathTracer

    failing = _Failing(PathTracer.render_samples, fail_at)
    monkeypatch.setattr(PathTracer, "render_samples",
                        lambda self, *args: failing(self, *args))
    return failing


def test_a_render_that_fails_half_way_keeps_the_units_finished_before(monkeypatch):
    scene = scenes.cornell_box(16, 12)
    settings = plain_settings(spp=8, threads=1)
    full = render(scene, settings, unit_paths=96)  # 16 units of 96 paths
    _fail_path_tracer(monkeypatch, fail_at=3)
    cut = render(scene, settings, unit_paths=96)
    assert cut.error == "RuntimeError: unit broke" and cut.cancelled
    count = cut.sample_count()
    # The two units before the failure are kept, and the image is finite.
    assert count.sum() == 2 * 96 < full.sample_count().sum()
    assert np.isfinite(cut.combined()).all()
    assert render_metadata(cut)["samplingLab.partial"] == "true"
    assert render_metadata(cut)["samplingLab.error"] == "RuntimeError: unit broke"


def test_the_cli_writes_a_failed_render_marked_partial_and_exits_1(monkeypatch, tmp_path,
                                                                    capsys):
    from sampling_lab import cli
    from sampling_lab.core.integrators.path import PathTracer

    monkeypatch.setattr(PathTracer, "batch_units", 1)  # the frame is two 64 k-path units
    _fail_path_tracer(monkeypatch, fail_at=2)
    out = tmp_path / "failed.exr"
    code = cli.main(["render", "cornell", "--resolution", "160x120", "--spp", "4",
                     "--threads", "1", "--sampler", "independent", "-o", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 1, err
    assert "render failed (RuntimeError: unit broke)" in err and "Traceback" not in err
    header = read_metadata(out)
    assert header["samplingLab.partial"] == "true"
    assert int(header["samplingLab.samples"]) == int(read_multilayer(str(out))["Sample Count"].sum()) > 0
