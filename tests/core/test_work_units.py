"""The render loop's work units: several are queued per thread, and a time limit or a cancel
drops the ones no worker has started while keeping (in order) those that ran."""

from concurrent.futures import Future

import numpy as np

from sampling_lab.core import render as render_module
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
    kept = render_module._started(futures)
    assert kept == futures[:2]
    assert all(f.cancelled() for f in futures[2:])
    assert not any(f.cancelled() for f in futures[:2])


def test_started_keeps_every_unit_when_all_have_started():
    futures = _futures(started=3, queued=0)
    assert render_module._started(futures) == futures


def test_queued_units_give_the_same_image_as_one_unit_in_flight(monkeypatch):
    """In-order accumulation: queuing units ahead changes nothing in a render of fixed sample
    count (bit for bit, whatever finishes first)."""
    scene = scenes.cornell_box(24, 24, "area")
    settings = plain_settings(spp=6, threads=2, seed=4)
    queued = render(scene, settings, unit_paths=256)
    monkeypatch.setattr(render_module, "IN_FLIGHT", 1)
    one = render(scene, settings, unit_paths=256)
    assert np.array_equal(queued.combined(), one.combined())
    assert np.array_equal(queued.variance(), one.variance())


def test_next_pass_units_are_queued_before_a_pass_is_shown(monkeypatch):
    """Pipelined passes: when a pass's last unit is awaited, units of the next pass are
    already handed to the workers (no worker idles at a pass's end), and the image is that of
    one unit at a time (bit for bit)."""
    events, pool = [], render_module.ThreadPoolExecutor

    class Recording(pool):
        def submit(self, fn, unit, *args, **kwargs):
            events.append(("submit", unit[2]))  # the unit's first sample index
            return super().submit(fn, unit, *args, **kwargs)

    monkeypatch.setattr(render_module, "ThreadPoolExecutor", Recording)
    scene = scenes.cornell_box(24, 24, "area")
    settings = plain_settings(spp=6, threads=2, seed=4)
    # 256-path units: 3 samples per pixel per pass, 7 units per pass, two passes.
    piped = render(scene, settings, unit_paths=256,
                   on_update=lambda result: events.append(("pass", None)))
    first_shown = events.index(("pass", None))
    assert ("submit", 3) in events[:first_shown]
    assert [e for e in events if e[0] == "pass"] == [("pass", None)] * 2
    monkeypatch.setattr(render_module, "IN_FLIGHT", 1)
    monkeypatch.setattr(render_module, "ThreadPoolExecutor", pool)
    settings = plain_settings(spp=6, threads=1, seed=4)
    one = render(scene, settings, unit_paths=256)
    assert np.array_equal(piped.combined(), one.combined())
    assert np.array_equal(piped.variance(), one.variance())
