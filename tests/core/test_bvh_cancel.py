"""Embree's BVH build through ``core.embree_commit``: a cancel stops it half-way (the progress
monitor says so to Embree), Ctrl-C's handler runs meanwhile, and a build that is not cancelled
gives the same hits and the same image as embreex's own.

No wall-clock time is asserted (:data:`HANG_S` only bounds the waits for Embree's threads);
the latency is measured by ``python -m sampling_lab bench-limits --bvh`` (docs/LIMITS.md).
"""

from __future__ import annotations

import os
import signal
import threading

import numpy as np
import pytest

from sampling_lab.core import embree_commit, scenes
from sampling_lab.core.hard_cases import many_triangles
from sampling_lab.core.render import render
from sampling_lab.core.sampling.stream import Aborted
from tests.helpers import plain_settings

HANG_S = 60.0
# Large enough that the BVH build takes a while (0.4 s for 1 M triangles on a quiet machine,
# against the 0.02 s between cancel polls).
BIG = 1_000_000


@pytest.fixture
def commits(monkeypatch):
    """Records each BVH build's report and sets ``started`` when a build begins."""
    started = threading.Event()
    reports = []
    original = embree_commit.commit

    def recording(lib, handle, device, cancel=None, report=None, keep=None):
        report = report or embree_commit.BuildReport("ctypes")
        reports.append(report)
        started.set()
        return original(lib, handle, device, cancel, report, keep)

    monkeypatch.setattr(embree_commit, "commit", recording)
    return started, reports


def test_the_embree_library_is_found_and_the_layout_checks_pass():
    from embreex import rtcore, rtcore_scene

    lib = embree_commit.library()
    assert not isinstance(lib, str), lib
    device, other = rtcore.EmbreeDevice(), rtcore.EmbreeDevice()
    scene = rtcore_scene.EmbreeScene(device)
    handle, device_handle = embree_commit.scene_handle(lib, scene, device)
    assert handle and device_handle and scene.is_committed == 0
    # The check that would catch a field read at the wrong place: another device object.
    with pytest.raises(embree_commit.LayoutMismatch):
        embree_commit.scene_handle(lib, scene, other)


def test_a_cancel_during_the_bvh_build_stops_it_through_the_progress_monitor(commits):
    """The core's cancel hook says stop once the BVH build has begun: Embree's progress
    monitor refuses at a call before the build's end (``RTC_ERROR_CANCELLED``), and the render
    returns cancelled, without samples, with an empty film."""
    started, reports = commits
    scene = many_triangles(BIG, 8, 6)
    result = render(scene, plain_settings(spp=4, threads=2), cancel=started.is_set)
    assert result.cancelled and result.stats["spp"] == 0
    assert result.sample_count().max() == 0 and np.isfinite(result.combined()).all()
    assert embree_commit.wait_abandoned(HANG_S)
    (report,) = reports
    assert report.error == embree_commit.RTC_ERROR_CANCELLED
    assert 0 < report.refused_at_call <= report.monitor_calls


def test_a_cancel_while_the_buffers_fill_stops_between_steps(monkeypatch, commits):
    started, reports = commits
    monkeypatch.setattr(embree_commit, "FILL_ROWS", 1000)
    scene = many_triangles(20_000)
    polls = []

    def cancel():
        polls.append(1)
        return len(polls) > 3

    with pytest.raises(Aborted, match="buffers"):
        embree_commit.build_scene(scene.vertices, scene.triangles, cancel)
    assert len(polls) == 4 and not started.is_set()  # no BVH build began


def test_ctrl_c_is_handled_while_the_bvh_builds(commits):
    """The command line's SIGINT handler (a flag its cancel hook reads) runs while Embree
    builds, since the build runs on a helper thread with the GIL released and the calling
    thread waits on a lock; the monitor then stops the build."""
    started, reports = commits
    interrupted = []
    previous = signal.signal(signal.SIGINT, lambda *_: interrupted.append(True))
    try:
        def interrupt():
            if started.wait(HANG_S):
                os.kill(os.getpid(), signal.SIGINT)

        threading.Thread(target=interrupt, daemon=True).start()
        result = render(many_triangles(BIG, 8, 6), plain_settings(spp=4, threads=2),
                        cancel=lambda: bool(interrupted))
    finally:
        signal.signal(signal.SIGINT, previous)
    assert interrupted and result.cancelled and result.stats["spp"] == 0
    assert embree_commit.wait_abandoned(HANG_S)
    assert reports[0].error == embree_commit.RTC_ERROR_CANCELLED
    assert reports[0].refused_at_call > 0


def test_the_build_finishes_while_another_thread_keeps_the_gil_busy(commits):
    """Embree's worker threads take the GIL for each monitor call: with a Python thread
    spinning beside the build, the build still ends (no deadlock) and is complete."""
    started, reports = commits
    scene = many_triangles(300_000)
    stop = threading.Event()

    def spin():
        x = 0
        while not stop.is_set():
            x += 1

    spinner = threading.Thread(target=spin, daemon=True)
    spinner.start()
    try:
        built, report = embree_commit.build_scene(scene.vertices, scene.triangles)
    finally:
        stop.set()
        spinner.join()
    assert report.method == "ctypes" and report.error == embree_commit.RTC_ERROR_NONE
    assert report.monitor_calls > 0 and report.refused_at_call == 0
    assert built.is_committed == 1


def _rays(n, seed):
    rng = np.random.default_rng(seed)
    o = rng.uniform(-0.9, 0.9, (n, 3)).astype(np.float32)
    o[:, 2] = rng.uniform(0.1, 1.0, n)
    d = rng.normal(size=(n, 3))
    d[:, 2] = -np.abs(d[:, 2]) - 1.0  # mostly downward: most rays hit the plane
    return o, (d / np.linalg.norm(d, axis=1)[:, None]).astype(np.float32)


def test_a_bvh_built_through_ctypes_gives_embreex_hits():
    """Same mesh, same flags, same buffers: every hit's triangle, distance and barycentrics
    equal embreex's own build's, bit for bit (a mesh attached with a vertex or index off, or
    other scene flags, would move hits)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = many_triangles(200_000)
    ours, report = embree_commit.build_scene(scene.vertices, scene.triangles)
    assert report.method == "ctypes"
    theirs = rtcore_scene.EmbreeScene()
    TriangleMesh(theirs, scene.vertices, scene.triangles)
    o, d = _rays(50_000, 3)
    a, b = ours.run(o, d, output=1), theirs.run(o, d, output=1)
    assert (a["primID"] >= 0).mean() > 0.5
    for key in ("primID", "tfar", "u", "v"):
        assert np.array_equal(a[key], b[key]), key


def test_the_image_is_the_same_through_ctypes_and_through_the_embreex_fallback(monkeypatch):
    """A render whose BVH was built through ctypes equals, bit for bit, one whose build fell
    back to embreex's path (as when the library is not found); the stats say which was
    used and why."""
    scene = scenes.cornell_box(24, 18)
    settings = plain_settings(spp=4, threads=2)
    ours = render(scene, settings)
    assert ours.stats["bvh_build"] == "ctypes" and ours.stats["bvh_scenes"] == 1
    monkeypatch.setattr(embree_commit, "library", lambda: "no Embree library (test)")
    theirs = render(scene, settings)
    assert theirs.stats["bvh_build"] == "embreex: no Embree library (test)"
    assert ours.combined().max() > 0
    assert np.array_equal(ours.combined(), theirs.combined())


def test_ctrl_c_during_the_bvh_build_exits_130_and_writes_nothing(commits, monkeypatch,
                                                                  tmp_path, capsys):
    """The command line (in this process, with its own SIGINT handler): Ctrl-C while Embree
    builds ends with exit code 130 and no samples, so nothing is written and a file already
    at the output path is left as it was."""
    from sampling_lab import cli

    started, reports = commits
    monkeypatch.setitem(cli.builtin_scenes.BUILTIN, "big_plane",
                        lambda w, h: many_triangles(BIG, w, h))
    out = tmp_path / "kept.exr"
    out.write_bytes(b"an earlier render")

    def interrupt():
        if started.wait(HANG_S):
            os.kill(os.getpid(), signal.SIGINT)

    threading.Thread(target=interrupt, daemon=True).start()
    code = cli.main(["render", "big_plane", "--resolution", "8x6", "--spp", "4", "--quiet",
                     "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 130, err
    assert "cancelled before any sample was taken; nothing written" in err
    assert out.read_bytes() == b"an earlier render"
    assert embree_commit.wait_abandoned(HANG_S)
    assert reports[0].error == embree_commit.RTC_ERROR_CANCELLED


def test_a_build_not_stopped_at_once_is_left_to_stop_in_the_background(commits, monkeypatch):
    """With no time to wait (``ABANDON_S = 0``), a cancelled build returns at once while
    Embree's threads still run: they stop at the monitor's next call, holding the scene until
    then, and :func:`wait_abandoned` sees them end."""
    started, reports = commits
    monkeypatch.setattr(embree_commit, "ABANDON_S", 0.0)
    scene = many_triangles(BIG)
    with pytest.raises(Aborted):
        embree_commit.build_scene(scene.vertices, scene.triangles, started.is_set)
    assert embree_commit.wait_abandoned(HANG_S)
    (report,) = reports
    assert report.error == embree_commit.RTC_ERROR_CANCELLED and report.refused_at_call > 0
