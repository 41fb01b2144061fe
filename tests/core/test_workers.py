"""Work units in worker processes (core.workers): the same image as threads bit for bit, cancel
and failures answered, the pool kept between renders."""

import dataclasses
import os
import signal
import time

import numpy as np
import pytest

from sampling_lab.core import workers
from sampling_lab.core.render import RenderSettings, preparation_key, render
from sampling_lab.core.scenes import cornell_box, many_lights
from tests.helpers import plain_settings

SIZE = 24


@pytest.fixture(scope="module")
def scene():
    return cornell_box(SIZE, SIZE)


def _images(result):
    """Everything a render writes: Combined (with alpha), Variance, Sample Count, layers."""
    return {"combined": result.combined(), "variance": result.variance(),
            "count": result.sample_count(), **result.layers()}


def _assert_same_images(a, b):
    assert a.error is None and b.error is None, (a.error, b.error)
    images_a, images_b = _images(a), _images(b)
    assert images_a.keys() == images_b.keys()
    for name in images_a:
        np.testing.assert_array_equal(images_a[name], images_b[name], err_msg=name)


def _both(scene, settings, **kw):
    """The render on two threads and on two worker processes."""
    threads = render(scene, dataclasses.replace(settings, threads=2, workers="threads"), **kw)
    processes = render(scene, dataclasses.replace(settings, threads=2, workers="processes"),
                       **kw)
    assert threads.stats["workers_text"] == "2 threads"
    assert processes.stats["workers_text"] == "2 worker processes"
    return threads, processes


@pytest.mark.parametrize("integrator, extra", [
    ("path", {}),
    ("light", {}),  # splats only
    ("bdpt", {"strategy_views": True, "strategy_max_length": 2}),  # splats and layers
])
def test_processes_render_the_threads_image_bit_for_bit(scene, integrator, extra):
    # Small units: several per pass, so the accumulation order is exercised.
    _assert_same_images(*_both(scene, RenderSettings(integrator=integrator, spp=4, **extra),
                               unit_paths=SIZE * SIZE))


@pytest.mark.parametrize("integrator", ["path", "bdpt"])
def test_processes_render_a_region_and_a_transparent_film_as_threads(integrator):
    # Many small lamps over a floor: the background shows beside it.
    transparent = dataclasses.replace(many_lights(SIZE, SIZE), film_transparent=True)
    threads, processes = _both(transparent, RenderSettings(integrator=integrator, spp=2,
                                                           region=(0, 5, 19, 24)))
    _assert_same_images(threads, processes)
    alpha = processes.combined()[..., 3]
    assert (alpha < 1).any() and (alpha > 0).any()  # the film really is transparent


def test_a_time_limited_process_render_keeps_whole_units(scene):
    unit = 2 * SIZE * SIZE  # 16 spp per pass, 8 units of 72 pixels each
    limited = render(scene, plain_settings(spp=0, time_limit=0.5, threads=2,
                                           workers="processes"), unit_paths=unit)
    assert limited.error is None and not limited.cancelled
    count = limited.sample_count().ravel()
    done = limited.stats["spp"]
    # Every unit adds 16 samples to its pixels; units of up to two passes were in flight.
    assert done > 0 and set(np.unique(count)) <= {done, done + 16, done + 32}
    # A pixel holds whole units: as many samples as the threads render of that many.
    for spp in np.unique(count):
        reference = render(scene, plain_settings(spp=int(spp), threads=2), unit_paths=unit)
        same = count == spp
        np.testing.assert_array_equal(limited.combined().reshape(-1, 4)[same],
                                      reference.combined().reshape(-1, 4)[same])


def test_cancel_stops_the_units_running_in_processes(scene):
    render(scene, RenderSettings(spp=1, threads=2, workers="processes"))  # workers started
    settings = RenderSettings(integrator="bdpt", spp=64, threads=2, workers="processes")
    first = []

    def cancel():
        first.append(time.perf_counter())
        return time.perf_counter() - first[0] > 0.5

    # One unit per worker of 64 x 64 x 32 BDPT paths: seconds each. A unit that did not hear
    # the stop would finish and be kept; stopped units are dropped.
    big = cornell_box(64, 64)
    out = render(big, settings, cancel=cancel, unit_paths=64 * 64 * 32)
    assert out.cancelled and out.error is None
    assert out.stats["samples"] == 0 and not out.sample_count().any()
    # The workers are free again: the next render is the threads render.
    _assert_same_images(*_both(scene, RenderSettings(spp=2)))


def test_a_cancelled_process_render_keeps_the_units_it_finished(scene):
    units = []
    out = render(scene, RenderSettings(spp=64, threads=2, workers="processes"),
                 progress=lambda *_: units.append(1), cancel=lambda: len(units) >= 3,
                 unit_paths=SIZE * SIZE)
    assert out.cancelled and out.error is None
    count = out.sample_count()
    assert 0 < count.sum() == out.stats["samples"] < SIZE * SIZE * 64
    assert np.isfinite(out.combined()).all()


def test_a_units_error_in_a_worker_comes_back_with_its_traceback(scene):
    settings = RenderSettings(spp=2, threads=2, workers="processes")
    units = workers.ProcessUnits(2, scene, settings, preparation_key(scene, settings),
                                 (0, 0, SIZE, SIZE), SIZE)
    try:
        with pytest.raises(workers.WorkerUnitError) as failure:
            units.submit(("not", "a", "unit")).result(timeout=120)
    finally:
        units.release()
    assert failure.value.error.startswith("ValueError: ")
    assert "render_unit" in failure.value.remote_traceback


def test_a_worker_failure_is_the_renders_error_and_the_next_render_works(scene):
    settings = RenderSettings(spp=2, threads=2, workers="processes")
    render(scene, settings)
    brighter = cornell_box(SIZE, SIZE, light="area")
    # The pool believes its workers hold the new scene: it is not sent, and they fail.
    for child in workers.pool().children:
        child.key = preparation_key(brighter, settings)
    out = render(brighter, settings)
    assert out.cancelled and out.error.startswith(
        "RuntimeError: this worker process does not hold the scene"), out.error
    assert "start_render" in out.traceback
    # A worker that failed is sent the scene again.
    _assert_same_images(*_both(brighter, settings))


def test_a_killed_worker_fails_the_render_clearly_and_is_replaced(scene):
    settings = RenderSettings(spp=256, threads=2, workers="processes")
    render(scene, RenderSettings(spp=1, threads=2, workers="processes"))
    pool = workers.pool()
    started = pool.started
    victim = pool.children[0].proc
    units = []

    def progress(*_):
        units.append(1)
        if len(units) == 2:
            os.kill(victim.pid, signal.SIGKILL)

    out = render(scene, settings, progress=progress, unit_paths=SIZE * SIZE)
    assert out.cancelled
    assert out.error.startswith(f"WorkerDied: a worker process (pid {victim.pid}) exited "
                                f"with code -9 (killed by signal 9)"), out.error
    assert out.stats["samples"] >= 2 * SIZE * SIZE and np.isfinite(out.combined()).all()
    # The next render replaces the dead worker and is the threads render.
    _assert_same_images(*_both(scene, RenderSettings(spp=2)))
    assert pool.started == started + 1


def test_the_pool_is_kept_and_a_changed_scene_is_shipped_again(scene):
    settings = RenderSettings(spp=2, threads=2, workers="processes")
    render(scene, settings)
    pool = workers.pool()
    started, children = pool.started, list(pool.children)
    again = render(scene, settings)
    assert again.stats["workers_shipped"] == 0
    brighter = cornell_box(SIZE, SIZE, light="area")
    changed = render(brighter, settings)
    assert changed.stats["workers_shipped"] == 2
    assert pool.started == started and pool.children == children
    _assert_same_images(render(brighter, dataclasses.replace(settings, workers="threads")),
                        changed)


def test_what_keeps_threads_says_why():
    scene = cornell_box(8, 8)
    one = render(scene, RenderSettings(spp=1, threads=1, workers="processes"))
    assert (one.stats["workers"], one.stats["workers_note"]) == (
        "threads", "one thread needs no worker process")
    sppm = render(scene, RenderSettings(integrator="sppm", spp=1, threads=2, photons=1000,
                                        workers="processes"))
    assert sppm.stats["workers_text"] == "2 threads"
    assert "sppm keeps threads" in sppm.stats["workers_note"]


def test_shutdown_ends_the_workers_and_the_next_render_starts_new_ones(scene):
    settings = RenderSettings(spp=1, threads=2, workers="processes")
    render(scene, settings)
    procs = [child.proc for child in workers.pool().children]
    workers.shutdown()
    assert all(proc.poll() is not None for proc in procs)  # shutdown waits for them
    again = render(scene, settings)
    assert again.error is None and again.stats["workers_shipped"] == 2


def test_a_scene_whose_copies_would_not_fit_keeps_threads():
    gb = 2 ** 30
    # 2 workers x 10 M triangles x 400 bytes = 7.5 GB: more than half of 8 GB, not of 32 GB.
    assert workers.memory_note(10_000_000, 2, memory=32 * gb) == ""
    note = workers.memory_note(10_000_000, 2, memory=8 * gb)
    assert note.startswith("2 worker processes would each copy the 10,000,000 triangles")
    assert "threads share one copy" in note


def test_a_second_render_while_the_workers_are_busy_uses_threads(scene):
    settings = RenderSettings(spp=2, threads=2, workers="processes")
    inner = []

    def progress(*_):  # a render started while this one holds the workers
        if not inner:
            inner.append(render(scene, settings))

    outer = render(scene, settings, progress=progress)
    assert outer.stats["workers"] == "processes"
    assert inner[0].stats["workers"] == "threads"
    assert inner[0].stats["workers_note"].startswith("the worker processes are busy")
    _assert_same_images(outer, inner[0])
    assert render(scene, settings).stats["workers"] == "processes"  # released
