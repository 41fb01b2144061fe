"""The worker process's side of :mod:`core.workers`: render work units sent over stdin.

A worker is a plain Python process (``sys.executable``; inside Blender, Blender's bundled
Python, which cannot import ``bpy``): :data:`core.workers.BOOT` makes the parent's package
importable under the parent's name and calls :func:`main`. Messages are pickled tuples:

from the parent (stdin)
    ``("render", render_id, key, scene_or_None, camera, settings, window, frame_width)``: the
    next units belong to this render. ``scene`` is sent only when this worker has not prepared the
    scene of preparation key ``key`` (:func:`core.render.preparation_key`); the worker prepares
    it once and keeps it, as the parent keeps persistent data.
    ``("unit", unit_id, unit)``: render one work unit of the current render.
    ``("stop", render_id)``: units of that render stop at their next bounce (read by a reader
    thread while a unit runs, so a cancel is answered within a bounce).
    ``("close", render_id)``: the render is out of time: the unit running finishes, the
    queued ones of that render are answered None without running (as a thread pool cancels
    the units no thread has started).
from the worker (the original stdout; ``print`` goes to stderr)
    ``("done", unit_id, result)``: :func:`core.passes.render_unit`'s result (None: stopped);
    ``("error", unit_id, "TypeName: message", traceback)``.

The worker exits when its stdin closes: the parent quit, crashed or shut the pool down.
"""

from __future__ import annotations

import os
import pickle
import queue
import sys
import threading
import traceback
from typing import NamedTuple

from .film import Film, PixelFilter
from .integrators import integrator_class
from .passes import render_unit
from .prepare import prepare
from .sampling.samplers import make_sampler


class FilmWindow(NamedTuple):
    """Where a render's film lies in the frame: what :func:`core.passes.render_unit` reads of a
    film (a worker needs no film of its own)."""

    x0: int
    y0: int
    width: int
    height: int

    n_pixels = Film.n_pixels
    _tap_weights = Film._tap_weights
    splat_taps = Film.splat_taps
    unit_splats = Film.unit_splats


class _Worker:
    """One worker's state: the prepared scenes it keeps and the current render."""

    def __init__(self, out):
        self.out = out
        self.prepared = {}  # preparation key -> PreparedScene (the last one only)
        self.render_id = -1
        self.stopped = -1  # the latest render id the parent stopped
        self.closed = -1  # the latest render id whose queued units are dropped
        self.job = None  # (integrator, sampler, window, frame_width, pixel_filter) or the error

    def send(self, message):
        pickle.dump(message, self.out, protocol=pickle.HIGHEST_PROTOCOL)
        self.out.flush()

    def aborted(self, render_id):
        return self.stopped >= render_id

    def start_render(self, render_id, key, scene, camera, settings, window, frame_width):
        """Build what the units of a render need (its failure fails each of its units)."""
        from .render import used_settings, with_camera

        self.render_id = render_id
        try:
            if key not in self.prepared and scene is None:
                raise RuntimeError(f"this worker process does not hold the scene it was asked "
                                   f"to render (preparation key {key[:12]})")
            if key not in self.prepared:
                used = used_settings(settings)
                sampling = "solid_angle" if used["light_sampling"] == "solid_angle" else "area"
                self.prepared = {key: prepare(scene, settings.light_selection, sampling,
                                              settings.distribution)}
            prep = with_camera(self.prepared[key], camera)
            self.job = (integrator_class(settings.integrator)(prep, settings),
                        make_sampler(settings.sampler, seed=settings.seed,
                                     spp=settings.spp if settings.spp > 0 else None,
                                     width=frame_width),
                        FilmWindow(*window), frame_width,
                        PixelFilter(settings.filter_type, settings.filter_width))
        except Exception as exc:  # noqa: BLE001 - reported with every unit of the render
            self.job = (f"{type(exc).__name__}: {exc}", traceback.format_exc())

    def run_unit(self, unit_id, unit):
        if isinstance(self.job[0], str):
            self.send(("error", unit_id, *self.job))
            return
        integrator, sampler, window, frame_width, pixel_filter = self.job
        render_id = self.render_id
        if self.closed >= render_id:
            self.send(("done", unit_id, None))
            return
        try:
            result = render_unit(integrator, sampler, window, frame_width, pixel_filter, unit,
                                 lambda: self.aborted(render_id))
        except Exception as exc:  # noqa: BLE001 - the parent's render fails with it
            self.send(("error", unit_id, f"{type(exc).__name__}: {exc}",
                       traceback.format_exc()))
            return
        self.send(("done", unit_id, result))


def _read(stdin, worker, inbox):
    """Reader thread: queue the parent's messages; a stop takes effect at once; end of input
    ends the process (the parent is gone or shut the pool down)."""
    try:
        while True:
            message = pickle.load(stdin)
            if message[0] == "stop":
                worker.stopped = max(worker.stopped, message[1])
            elif message[0] == "close":
                worker.closed = max(worker.closed, message[1])
            else:
                inbox.put(message)
    except (EOFError, OSError, pickle.UnpicklingError):
        pass
    finally:
        os._exit(0)


def main():
    """Serve the parent until stdin closes."""
    # Results go to the original stdout; anything printed (by us or a library) to stderr.
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    worker, inbox = _Worker(out), queue.Queue()
    threading.Thread(target=_read, args=(sys.stdin.buffer, worker, inbox), daemon=True).start()
    from .allocator import keep_freed_batches

    keep_freed_batches()
    while True:
        message = inbox.get()
        if message[0] == "render":
            worker.start_render(*message[1:])
        elif message[0] == "unit":
            worker.run_unit(*message[1:])
