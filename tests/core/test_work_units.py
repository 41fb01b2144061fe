"""The render loop's work units: several are queued per thread, and a time limit or a cancel
drops the ones no worker has started while keeping (in order) those that ran."""

from concurrent.futures import Future

import numpy as np

from sampling_lab.core import passes as passes_module
from sampling_lab.core import scenes
from sampling_lab.core.render import render
from tests.helpers import plain_settings


def _futures(started, queued):
    futures = [Future() for _ in range(started + queued)]
    for f in futures[:started]:
        assert f.set_running_or_notify_cancel()
    return futures


def test_started_keeps_running_units_in_order_and_cancels_the_queued_ones():
    futures = _futures(started=2, queued=3)
    kept = passes_module._started(futures)
    assert kept == futures[:2]
    assert all(f.cancelled() for f in futures[2:])
    assert not any(f.cancelled() for f in futures[:2])


def test_started_keeps_every_unit_when_all_have_started():
    futures = _futures(started=3, queued=0)
    assert passes_module._started(futures) == futures


def test_queued_units_give_the_same_image_as_one_unit_in_flight(monkeypatch):
    """In-order accumulation: queuing units ahead changes nothing in a render of fixed sample
    count (bit for bit, whatever finishes first)."""
    scene = scenes.cornell_box(24, 24, "area")
    settings = plain_settings(spp=6, threads=2, seed=4)
    queued = render(scene, settings, unit_paths=256)
    monkeypatch.setattr(passes_module, "IN_FLIGHT", 1)
    one = render(scene, settings, unit_paths=256)
    assert np.array_equal(queued.combined(), one.combined())
    assert np.array_equal(queued.variance(), one.variance())


def test_next_pass_units_are_queued_before_a_pass_is_shown(monkeypatch):
    """Pipelined passes: when a pass's last unit is awaited, units of the next pass are
    already handed to the workers (no worker idles at a pass's end), and the image is that of
    one unit at a time (bit for bit)."""
    events, pool = [], passes_module.ThreadPoolExecutor

    class Recording(pool):
        def submit(self, fn, unit, *args, **kwargs):
            events.append(("submit", unit[2]))  # the unit's first sample index
            return super().submit(fn, unit, *args, **kwargs)

    monkeypatch.setattr(passes_module, "ThreadPoolExecutor", Recording)
    scene = scenes.cornell_box(24, 24, "area")
    settings = plain_settings(spp=6, threads=2, seed=4)
    # 256-path units: 3 samples per pixel per pass, 7 units per pass, two passes.
    piped = render(scene, settings, unit_paths=256,
                   on_update=lambda result: events.append(("pass", None)))
    first_shown = events.index(("pass", None))
    assert ("submit", 3) in events[:first_shown]
    assert [e for e in events if e[0] == "pass"] == [("pass", None)] * 2
    monkeypatch.setattr(passes_module, "IN_FLIGHT", 1)
    monkeypatch.setattr(passes_module, "ThreadPoolExecutor", pool)
    settings = plain_settings(spp=6, threads=1, seed=4)
    one = render(scene, settings, unit_paths=256)
    assert np.array_equal(piped.film.sum, one.film.sum)
    assert np.array_equal(piped.film.sum_sq, one.film.sum_sq)


def _batches_and_image(monkeypatch, scene, settings, batch_units):
    """The work units run and the image of a final render with ``batch_units``, the path
    tracer's units being 256 paths (so that a small image has many)."""
    from sampling_lab.core.integrators.path import PathTracer

    monkeypatch.setattr(PathTracer, "unit_paths", 256)
    monkeypatch.setattr(PathTracer, "batch_units", batch_units)
    units, run_unit = [], passes_module.Passes.run_unit
    monkeypatch.setattr(passes_module.Passes, "run_unit",
                        lambda self, unit: units.append(unit) or run_unit(self, unit))
    res = render(scene, settings)
    return units, res


def test_batched_units_give_the_same_image_bit_for_bit(monkeypatch):
    """``batch_units``: a final render that runs several units per batch keeps the pass size
    and each pixel's samples of a pass in one batch, so every pixel sums the same numbers in
    the same order (the BSDF path, with a glass ball and a point light, and the Lambert
    path; several passes, a filter wider than a pixel)."""
    for scene in (scenes.cornell_sphere(20, 20, ball="glass"), scenes.cornell_box(20, 20)):
        settings = plain_settings(spp=9, threads=2, seed=3, filter_width=2.0)
        one_units, one = _batches_and_image(monkeypatch, scene, settings, 1)
        three_units, three = _batches_and_image(monkeypatch, scene, settings, 3)
        assert len(three_units) < len(one_units)  # the batches really differ
        assert one.stats["spp"] == three.stats["spp"] == 9
        # The film's float64 sums, not the float32 image: regrouped sums differ in last bits.
        assert np.array_equal(one.film.sum, three.film.sum)
        assert np.array_equal(one.film.sum_sq, three.film.sum_sq)
        assert np.array_equal(one.film.count, three.film.count)


def test_chunked_batches_give_the_same_image_bit_for_bit(monkeypatch):
    """``chunk_paths``: the path tracer walks a batch in chunks and joins their outputs before
    the film sees them, so the film's sums do not depend on the chunk size (a glass ball and
    a point light, a 2-pixel filter, chunks that split pixels' samples)."""
    from sampling_lab.core.integrators.path import PathTracer

    scene = scenes.cornell_sphere(20, 20, ball="glass")
    settings = plain_settings(spp=9, threads=2, seed=3, filter_width=2.0)
    films, calls = [], []
    chunk = PathTracer._render_chunk
    monkeypatch.setattr(PathTracer, "_render_chunk",
                        lambda self, stream, *a: calls.append(len(stream)) or chunk(self, stream,
                                                                                    *a))
    for size in (None, 700):
        monkeypatch.setattr(PathTracer, "chunk_paths", size)
        calls.clear()
        films.append(render(scene, settings).film)
        assert max(calls) <= (size or 20 * 20 * 9)
    assert len(calls) > 20 * 20 * 9 // 700  # the chunks really ran
    for name in ("sum", "sum_sq", "count"):
        assert np.array_equal(getattr(films[0], name), getattr(films[1], name))
