"""The passes of a render: work units on worker threads or processes, accumulated into the film
in unit order.

A pass adds ``spp_per_pass`` samples to every pixel. Each pass is cut into work units (a range of
pixels times a range of sample indices) that worker threads (``threads``, one per core by default)
run concurrently; Embree and large NumPy operations release the GIL. With ``workers='processes'``
(path, light and BDPT: :func:`core.applied_settings.worker_mode`) the units run in worker
processes instead (:mod:`core.workers`), which share no GIL; this loop still accumulates them.
Units cover disjoint pixels and their results are accumulated in unit order, and every random
number is a function of (pixel, sample index, dimension, seed), so the same seed gives a
bit-identical image whatever the thread or process count or timing. :func:`core.render.render`
says when a render halts.
"""

from __future__ import annotations

import os
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from concurrent.futures import TimeoutError as FutureTimeout

import numpy as np

from .film import PixelFilter, SplatSums, UnitPixels, unit_sums
from .integrators.base import UNIT_PATHS, Counters
from .sampling.stream import Aborted

# Seconds between polls of ``cancel()`` while work units run.
POLL_S = 0.05

# Work units per pass when the image is small: a pass keeps several threads busy. The pass size
# must not depend on the thread count, or the film's sums would be added in another order.
PASS_UNITS = 8

# Work units submitted per worker thread (or process) at a time (see Passes._run_units).
IN_FLIGHT = 2

# Seconds a cancelled render waits for each worker process's unit to stop before it fails.
STOP_WAIT_S = 30.0


def _units(n_pixels, first_sample, spp_in_pass, unit_paths=UNIT_PATHS):
    """Work units of a pass: (pixel_start, pixel_stop, first_sample, n_samples).

    Units hold at most ``unit_paths`` paths (one pixel at least) and are of equal size, so no
    small leftover unit runs alone at the end of a pass. The split does not depend on the
    thread count: splats from several units reach the same pixels, and their sums must be
    added in the same order whatever the threads.
    """
    count = -(-n_pixels * spp_in_pass // max(1, unit_paths))
    per_unit = -(-n_pixels // max(1, min(count, n_pixels)))
    return [(p, min(p + per_unit, n_pixels), first_sample, spp_in_pass)
            for p in range(0, n_pixels, per_unit)]

class Passes:
    """The passes of one render: work units run on worker threads, accumulated into the film
    in unit order, with progress, cancel and the time limit checked between units."""

    def __init__(self, settings, integrator, sampler, film, cam, progress, cancel,
                 unit_paths=None, processes=None):
        self.settings, self.integrator = settings, integrator
        self.sampler, self.film = sampler, film
        self.frame_width = cam.width
        self.progress, self.cancel = progress, cancel
        self.pixel_filter = PixelFilter(settings.filter_type, settings.filter_width)
        self.total_spp = settings.spp if settings.spp > 0 else None
        # Integrators whose samples cost more (BDPT) ask for smaller units: cancel stays prompt.
        self.unit_paths = unit_paths or integrator.unit_paths
        # Final renders may run several units as one batch; passes keep the units' size.
        self.batch_paths = self.unit_paths * (1 if unit_paths else integrator.batch_units)
        # Sized by the whole frame, so a region's pixels sum their samples in the same passes as
        # a full-frame render (bit-identical pixels).
        self.spp_per_pass = max(1, min(self.unit_paths * PASS_UNITS // (cam.width * cam.height),
                                       64))
        self.threads = thread_count(settings)
        # core.workers.ProcessUnits: the units run in worker processes instead of threads.
        self.processes = processes
        self.counters = Counters()
        self.done_spp = 0
        self.unshown = 0  # units added to the film since on_pass() was last called
        self.t_start = time.perf_counter()
        # Set once cancel() says so: the units in flight stop at their next bounce.
        self.stop = threading.Event()

    def elapsed(self):
        return time.perf_counter() - self.t_start

    def out_of_time(self):
        return self.settings.time_limit > 0 and self.elapsed() >= self.settings.time_limit

    def run_unit(self, unit):
        """Render one work unit ``(pixel_start, pixel_stop, first_sample, n_samples)``."""
        return render_unit(self.integrator, self.sampler, self.film, self.frame_width,
                           self.pixel_filter, unit, self.stop.is_set)

    def accumulate(self, sums, out, local, taps=None):
        """Add one unit's output to the film (in unit order: the image is deterministic);
        ``sums``: its camera samples summed per pixel (:class:`core.film.UnitSums`); ``taps``:
        the splats' filter taps if :meth:`run_unit` made them, or their per-pixel sums
        (:class:`core.film.SplatSums`)."""
        film, pixel_filter = self.film, self.pixel_filter
        self.unshown += 1
        self.counters.add(local)
        film.add_unit_sums(sums)
        if isinstance(taps, SplatSums):
            film.add_splat_sums(taps)
        elif taps is not None:
            film.add_splat_taps(*taps)
        elif out.splats is not None and len(out.splats.xy):
            film.splat(out.splats.xy, out.splats.value, pixel_filter)
        film.add_splat_paths(out.light_paths)
        if out.camera_layers:
            pixels = sums.pixels.array()  # one pixel per sample
        for name, values in out.camera_layers.items():
            film.add_layer(name, pixels, values)
        for name, splats in out.splat_layers.items():
            film.splat_layer(name, splats.xy, splats.value, pixel_filter)

    def report(self, fraction):
        if self.progress is None:
            return
        el = self.elapsed()
        counters = self.counters
        sps = counters.camera_samples / el if el > 0 else 0.0
        spp_txt = f"{self.done_spp}/{self.total_spp}" if self.total_spp else f"{self.done_spp}"
        self.progress(min(fraction, 1.0),
                      f"Sample {spp_txt} | {sps / 1e6:.2f} M samples/s | "
                      f"{counters.rays / max(el, 1e-9) / 1e6:.2f} M rays/s | "
                      f"{distribution_text(self.integrator.prep.lights, counters)}")

    def run(self, on_pass):
        """Run passes until the sample count, the time limit or ``cancel``; calls ``on_pass()``
        after every pass. Returns whether the render was cancelled."""
        if self.integrator.whole_passes:
            return self.run_whole_passes(on_pass)
        return self._run_unit_passes(on_pass)

    def _run_unit_passes(self, on_pass):
        """:meth:`run` for integrators that render work units."""
        if self.processes is not None:
            try:
                return self._run_units(self.processes.submit, on_pass)
            except BaseException:
                self._halt()  # a unit failed: the others stop at their next bounce
                raise
        pool = ThreadPoolExecutor(max_workers=self.threads)
        try:
            return self._run_units(lambda unit: pool.submit(self.run_unit, unit), on_pass)
        except BaseException:
            self.stop.set()  # a unit failed: the others stop at their next bounce
            raise
        finally:
            pool.shutdown(wait=True)

    def _halt(self):
        """Stop the units in flight at their next bounce (threads and worker processes)."""
        self.stop.set()
        if self.processes is not None:
            self.processes.stop()

    def _planned_units(self):
        """Every work unit of the render, pass after pass: ``(k, unit, index, count)``, ``k``
        the pass's samples per pixel, ``index`` the unit's place among the pass's ``count``
        units (an endless sequence under a time limit alone)."""
        done = self.done_spp
        while self.total_spp is None or done < self.total_spp:
            k = (self.spp_per_pass if self.total_spp is None
                 else min(self.spp_per_pass, self.total_spp - done))
            units = _units(self.film.n_pixels, done, k, self.batch_paths)
            for index, unit in enumerate(units):
                yield k, unit, index, len(units)
            done += k

    def _run_units(self, submit, on_pass):
        """Run the planned units (``submit(unit)`` -> a ``Future`` of :meth:`run_unit`'s
        result), up to :data:`IN_FLIGHT` per thread or process at a time, and add them
        to the film in plan order (the image does not depend on timing). The next pass's units
        start while the last ones of a pass run, so no worker idles at a pass's end (small
        images have few units per pass). A render stopped part-way calls ``on_pass()`` once
        more for the units it kept. Returns whether the render was cancelled."""
        planned, pending = self._planned_units(), []
        while True:
            while len(pending) < IN_FLIGHT * self.threads and not self.out_of_time():
                nxt = next(planned, None)
                if nxt is None:
                    break
                pending.append((submit(nxt[1]), nxt))
            if not pending:
                return False
            future, (k, _, index, count) = pending.pop(0)
            futures = [f for f, _ in pending]
            if self._cancelled_while_waiting(future):
                self._abort([future] + futures)
                break
            self.accumulate(*future.result())
            self._unit_done(k, index + 1, count, on_pass)
            if self.cancel is not None and self.cancel():
                self._abort(futures)
                break
            if self.out_of_time():
                if self.processes is not None:
                    self.processes.close()  # queued units are dropped (None), as _started's
                for f in _started(futures):  # finish what runs; its samples are kept
                    out = f.result()
                    if out is not None:
                        self.accumulate(*out)
                self._show(on_pass)
                return False
        self._show(on_pass)
        return True

    def _unit_done(self, k, finished, count, on_pass):
        """Report progress after the ``finished``-th of a pass's ``count`` units; at the last,
        count the pass's ``k`` samples per pixel as done and call ``on_pass()``."""
        total_spp = self.total_spp
        if finished < count:
            self.report((self.done_spp + k * finished / count) / total_spp if total_spp
                        else self.elapsed() / self.settings.time_limit)
            return
        self.done_spp += k
        self.report(self.done_spp / total_spp if total_spp
                    else self.elapsed() / self.settings.time_limit)
        self._show(on_pass)

    def _show(self, on_pass):
        """``on_pass()`` if units were added to the film since it was last called."""
        if self.unshown:
            self.unshown = 0
            on_pass()

    def run_whole_passes(self, on_pass):
        """Passes of an integrator that renders a whole pass itself (``whole_passes``, SPPM):
        one pass is one sample per pixel; the film shows the integrator's image after each.
        The time limit is checked between passes (a pass under way is finished); cancel is
        polled between the pass's chunks, and a cancelled pass is dropped."""
        film, integrator = self.film, self.integrator
        pixels = np.arange(film.n_pixels, dtype=np.int64)
        frame_pixels = ((film.y0 + pixels // film.width) * self.frame_width + film.x0
                        + pixels % film.width)
        sampler = _AbortingSampler(self.sampler, self.stop.is_set)
        with ThreadPoolExecutor(max_workers=self.threads) as pool:
            while self.total_spp is None or self.done_spp < self.total_spp:
                if self.out_of_time():
                    break
                image = integrator.render_pass(
                    self.done_spp, frame_pixels, sampler, self.pixel_filter,
                    self.counters, lambda fn, items: self._map_chunks(pool, fn, items))
                if image is None:
                    return True
                self.done_spp += 1
                show_estimate(film, image, self.done_spp, integrator.pass_sum_sq(),
                              integrator.pass_transparency())
                self.report(self.done_spp / self.total_spp if self.total_spp
                            else self.elapsed() / self.settings.time_limit)
                on_pass()
        return False

    def _map_chunks(self, pool, fn, items):
        """``[fn(item) for item in items]`` on the worker threads (at most ``threads`` in
        flight, results in order); None as soon as ``cancel()`` says so."""
        items, results, pending = list(items), [], []
        i = 0
        while i < len(items) or pending:
            while i < len(items) and len(pending) < self.threads:
                pending.append(pool.submit(fn, items[i]))
                i += 1
            cancelled = self._cancelled_while_waiting(pending[0])
            if not cancelled:
                results.append(pending.pop(0).result())
                cancelled = self.cancel is not None and self.cancel()
            if cancelled:
                self.stop.set()
                for f in pending:  # they stop at their next bounce
                    try:
                        f.result()
                    except Aborted:
                        pass
                return None
        return results

    def _cancelled_while_waiting(self, future):
        """Wait for ``future``, polling ``cancel()`` every :data:`POLL_S` s; True if it said so
        first."""
        while not wait([future], timeout=POLL_S, return_when=FIRST_COMPLETED)[0]:
            if self.cancel is not None and self.cancel():
                return True
        return False

    def _abort(self, pending):
        """Stop the units in flight at their next bounce; keep those that finished first."""
        self._halt()
        # A worker process answers a stop within a bounce; one that does not is stuck.
        timeout = STOP_WAIT_S if self.processes is not None else None
        for f in _started(pending):
            try:
                out = f.result(timeout)
            except FutureTimeout:
                raise RuntimeError(f"a worker process did not stop within {STOP_WAIT_S:.0f} s "
                                   f"of the cancel") from None
            if out is not None:
                self.accumulate(*out)
        return True


def render_unit(integrator, sampler, film, frame_width, pixel_filter, unit, abort):
    """Render one work unit ``(pixel_start, pixel_stop, first_sample, n_samples)`` (on a worker
    thread, or in a worker process: :mod:`core.worker_child`).

    Parameters
    ----------
    film : core.film.Film or core.worker_child.FilmWindow
        Where the film lies in the frame (``x0``, ``y0``, ``width``, ``height``) and its
        ``splat_taps``; nothing it accumulates is read.
    frame_width : int
        Camera width in pixels (streams and camera rays are indexed by frame pixel).
    abort : callable() -> bool
        The stream stops at its next bounce once it says so.

    Returns
    -------
    tuple or None
        ``(sums, BatchOutput, Counters, taps)`` for :meth:`Passes.accumulate` (``sums``: the
        camera samples summed per pixel, :class:`core.film.UnitSums`, the output's
        ``radiance`` and ``transparency`` then None; ``taps``: the splats' filter taps or
        their ``SplatSums``, see ``Film.unit_splats``; None without splats), or None
        if ``abort`` stopped it.
    """
    p0, p1, s0, k = unit
    unit_pixels = UnitPixels(p0, p1, k)
    pixels = unit_pixels.array()
    samples = np.tile(np.arange(s0, s0 + k, dtype=np.int64), p1 - p0)
    # Streams and camera rays are indexed by frame pixel, the film by window pixel (the same
    # numbers when the film is the whole frame).
    if film.x0 == 0 and film.y0 == 0 and film.width == frame_width:
        frame_pixels = pixels
    else:
        frame_pixels = ((film.y0 + pixels // film.width) * frame_width + film.x0
                        + pixels % film.width)
    local = Counters()
    stream = sampler.stream(frame_pixels, samples)
    stream.abort = abort
    try:
        out = integrator.render_samples(stream, pixel_filter, local)
    except Aborted:
        return None
    # The filter taps of the light-path splats are made here, on the worker: the render
    # loop, whose thread the next unit waits for, only adds them up.
    # A small film gets their per-pixel sums instead (Film.unit_splats): a smaller payload
    # from a worker process, and less work for the render loop.
    taps = (film.unit_splats(out.splats.xy, out.splats.value, pixel_filter)
            if out.splats is not None and len(out.splats.xy) else None)
    if taps is not None:
        out.splats = None  # in the taps now: not sent back twice
    # Summed per pixel here too: a smaller payload from a worker process (k / 2 times), and
    # the render loop, which every worker waits for, only adds the sums.
    sums = unit_sums(unit_pixels, out.radiance, out.transparency)
    out.radiance = out.transparency = None  # in the sums now: not sent back twice
    return sums, out, local, taps


def _started(pending):
    """The futures of ``pending`` (in submission order) that a worker has started; the rest
    are cancelled. The pool starts them first in, first out, so the started ones come first
    and the accumulation order is kept."""
    for j, f in enumerate(pending):
        if f.cancel():
            for rest in pending[j + 1:]:
                rest.cancel()
            return pending[:j]
    return pending


class _AbortingSampler:
    """``sampler`` whose streams stop at their next bounce once ``abort()`` says so (the
    whole-pass integrators make their own streams from the sampler they are given)."""

    def __init__(self, sampler, abort):
        self.sampler, self.abort = sampler, abort

    def stream(self, pixel, sample_index):
        stream = self.sampler.stream(pixel, sample_index)
        stream.abort = self.abort
        return stream

    def __getattr__(self, name):
        return getattr(self.sampler, name)


def show_estimate(film, image, passes, sum_sq=None, transparency=None):
    """Make ``film`` show ``image (n_pixels, 3)`` as the estimate of ``passes`` samples per
    pixel (integrators with ``whole_passes``: the film's sums are replaced). ``sum_sq
    (n_pixels, 3)``: the sum of the squared per-pass estimates whose mean ``image`` is (SPPM),
    which gives the Variance pass; None: the variance is zero (not estimated).
    ``transparency (n_pixels,)``: the sum over the passes of what reached a transparent film's
    background (the alpha); None: an opaque film."""
    film.count[:] = passes
    film.sum[:] = image * passes
    film.sum_sq[:] = image * image * passes if sum_sq is None else sum_sq
    if transparency is not None:
        film.transparency = np.array(transparency, np.float64)


def thread_count(settings):
    """Worker threads of a render: ``settings.threads``, or one per CPU core if it is 0."""
    return settings.threads if settings.threads > 0 else max(1, os.cpu_count() or 1)


def distribution_text(lights, counters):
    """One phrase on the light choice's cost: table kind, build time, sampling time so far."""
    kind = "alias table" if lights.method == "alias" else "CDF"
    return (f"lights by {kind}: build {1e3 * lights.build_s:.2f} ms, "
            f"sampling {1e3 * counters.distribution_s:.1f} ms")
