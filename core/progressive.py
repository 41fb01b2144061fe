"""Progressive renders on a worker thread: coarse previews, then passes of the full film.

The rendered viewport (``addon/viewport.py``) runs one :class:`ProgressiveRender` per 3D view.
Its worker thread renders the :func:`progressive_stages` of a scene with
:func:`core.render.render` and publishes a :class:`Frame` (the film's mean) after every pass;
:meth:`ProgressiveRender.start` cancels the render under way and returns at once, so the caller
(Blender's main thread) never waits for a render. The stages share one prepared scene
(acceleration structure, light tables): only the camera's film size changes between them.

Nothing here imports ``bpy``.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import traceback

import numpy as np

from .integrators import integrator_class
from .render import render
from .view_camera import film_camera

# Longest side, in film pixels, of the first (coarsest) preview.
START_RESOLUTION = 64
# Viewport work units hold this share of an integrator's paths per unit: a restart waits for
# the units in flight, so smaller units keep it under about 0.1 s (tools/viewport_cancel.py).
UNIT_SHARE = 4


def unit_paths(settings):
    """Paths per work unit of a viewport render with ``settings``."""
    return max(1, integrator_class(settings.integrator).unit_paths // UNIT_SHARE)


def progressive_stages(width, height, pixel_size=1, samples=0, start_resolution=START_RESOLUTION):
    """The renders of one viewport render: coarse previews, then the full film.

    Parameters
    ----------
    width, height : int
        Region size in pixels.
    pixel_size : int
        Region pixels per film pixel at full resolution.
    samples : int
        Samples per pixel of the full film (0: unlimited).
    start_resolution : int
        Longest side of the coarsest preview in film pixels.

    Returns
    -------
    list of (int, int)
        ``(divisor, spp)``: region pixels per film pixel and samples per pixel. Previews take one
        sample at ``pixel_size * 2^k``, halving down to ``2 * pixel_size`` (together they cost
        at most a third of one full-film sample); the last entry is ``(pixel_size, samples)``.
    """
    divisor = pixel_size
    while max(-(-width // divisor), -(-height // divisor)) > start_resolution:
        divisor *= 2
    stages = []
    while divisor > pixel_size:
        stages.append((divisor, 1))
        divisor //= 2
    stages.append((pixel_size, int(samples)))
    return stages


@dataclasses.dataclass
class Frame:
    """The latest image of a viewport render.

    Attributes
    ----------
    pixels : (h, w, 4) float32
        The film's mean, RGBA, row 0 at the bottom (``core.film.Film.combined``).
    pixel_size : int
        Region pixels per film pixel.
    spp : int
        Samples per pixel in every film pixel.
    generation : int
        Which start of :class:`ProgressiveRender` it belongs to.
    final : bool
        Whether it is the full film (not a preview).
    serial : int
        Counts the frames of a :class:`ProgressiveRender` (tells view_draw to upload it).
    """

    pixels: np.ndarray
    pixel_size: int
    spp: int
    generation: int
    final: bool
    serial: int = 0


def texture_pixels(frame):
    """``frame`` as the data of an RGBA float texture of ``(w, h)``.

    Returns
    -------
    (h * w * 4,) float32
        C-contiguous, rows from the bottom (a GPU texture's first row is its bottom row).
    """
    return np.ascontiguousarray(frame.pixels, np.float32).reshape(-1)


@dataclasses.dataclass
class _Job:
    generation: int
    scene: object
    settings: object
    stages: list
    cancel: threading.Event = dataclasses.field(default_factory=threading.Event)
    thread: threading.Thread = None
    error: str = ""
    stats: dict = dataclasses.field(default_factory=dict)


class ProgressiveRender:
    """Renders of one viewport on a worker thread, one at a time, each restartable.

    Parameters
    ----------
    notify : callable() or None
        Called by the worker thread after it published a frame or finished (it must not touch
        ``bpy``: it only flags a redraw).
    """

    def __init__(self, notify=None):
        self._lock = threading.Lock()
        self._job = None
        self._frame = None
        self._generation = 0
        self._serial = 0
        self.notify = notify
        # Polled by the redraw timer: a frame was published since the last look.
        self.new_frame = threading.Event()

    @property
    def generation(self):
        """Number of the latest :meth:`start`."""
        return self._generation

    @property
    def running(self):
        """Whether a worker thread is rendering (or about to)."""
        job = self._job
        return job is not None and (job.thread.is_alive() or job.thread.ident is None)

    @property
    def error(self):
        """The latest render's error message ('' if none)."""
        job = self._job
        return job.error if job is not None else ""

    @property
    def stats(self):
        """``core.render`` stats of the latest render's last stage (``stage``: its index in the
        stages, ``cancelled``: whether cancel stopped it)."""
        job = self._job
        return dict(job.stats) if job is not None else {}

    def frame(self):
        """The latest :class:`Frame` of the current render, or None before its first pass."""
        with self._lock:
            return self._frame

    def start(self, scene, settings, stages):
        """Cancel the render under way and start rendering ``scene``; returns at once.

        Parameters
        ----------
        scene : core.scene.Scene
            Its camera is the full-resolution film (:func:`view_camera`).
        settings : core.render.RenderSettings
            ``spp`` and ``time_limit`` are replaced stage by stage.
        stages : list of (int, int)
            :func:`progressive_stages`.

        Returns
        -------
        int
            The new generation.
        """
        with self._lock:
            previous = self._job
            self._generation += 1
            job = _Job(self._generation, scene, settings, list(stages))
            job.thread = threading.Thread(target=self._run, args=(job, previous), daemon=True,
                                          name=f"sampling-lab-viewport-{job.generation}")
            self._job = job
            # A restart clears the film: nothing of the old render is shown as the new one.
            self._frame = None
        if previous is not None:
            previous.cancel.set()
        job.thread.start()
        return job.generation

    def cancel(self):
        """Ask the render under way to stop; returns at once."""
        job = self._job
        if job is not None:
            job.cancel.set()

    def stop(self, timeout=None):
        """Cancel the render under way and wait for its worker thread (see :meth:`wait`)."""
        self.cancel()
        return self.wait(timeout)

    def wait(self, timeout=None):
        """Wait for the render under way to finish (it is not cancelled).

        Returns
        -------
        bool
            True once no worker thread runs (False if ``timeout`` seconds passed first).
        """
        job = self._job
        if job is None:
            return True
        job.thread.join(timeout)
        return not job.thread.is_alive()

    def _run(self, job, previous):
        try:
            if previous is not None:
                # One render at a time: the old one stops after its units in flight.
                previous.thread.join()
            last = len(job.stages) - 1
            prepared = None
            for index, (divisor, spp) in enumerate(job.stages):
                if job.cancel.is_set():
                    break
                scene = dataclasses.replace(job.scene,
                                            camera=film_camera(job.scene.camera, divisor))
                settings = dataclasses.replace(job.settings, spp=spp,
                                               time_limit=0.0 if spp > 0 else math.inf)

                def on_update(result, divisor=divisor, final=(index == last)):
                    self._publish(job, result, divisor, final)

                out = render(scene, settings, cancel=lambda: self._poll(job),
                             on_update=on_update, prepared=prepared,
                             unit_paths=unit_paths(settings))
                # The next stage differs only in its film size: no second Embree build.
                prepared = out.prepared
                job.stats = dict(out.stats, cancelled=out.cancelled, stage=index)
        except Exception as ex:  # noqa: BLE001 - a worker error must not reach Blender
            traceback.print_exc()
            job.error = f"{type(ex).__name__}: {ex}"
        finally:
            self._notify()

    def _poll(self, job):
        """The cancel flag, polled by ``core.render`` between work units."""
        return job.cancel.is_set()

    def _publish(self, job, result, divisor, final):
        # A pass cut short by cancel leaves pixels with unequal counts: never shown.
        if job.cancel.is_set():
            return
        count = result.film.count
        frame = Frame(pixels=result.combined(), pixel_size=divisor,
                      spp=int(count.min()) if count.size else 0, generation=job.generation,
                      final=final)
        with self._lock:
            if job is not self._job:
                return
            self._serial += 1
            frame.serial = self._serial
            self._frame = frame
        self._notify()

    def _notify(self):
        self.new_frame.set()
        if self.notify is not None:
            try:
                self.notify()
            except Exception:  # noqa: BLE001
                traceback.print_exc()
