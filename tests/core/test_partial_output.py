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
