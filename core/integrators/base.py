"""The integrator contract: what :func:`core.render.render` asks of every estimator.

An integrator is built once per render, from the prepared scene and the settings
(``cls(prep, settings)``), before any work unit runs: everything it derives from them (its
:class:`core.sampling.mis.MIS`, camera constants, the names of its layers) is computed there.
The render loop then calls :meth:`Integrator.render_samples` once per work unit, from several
worker threads at once: a call reads the integrator and the prepared scene and writes only its
own arrays and the ``counters`` it is given.

What the render loop reads from an integrator:

``unit_paths`` (class attribute)
    Paths per work unit: small enough that a unit takes well under a second (cancel and
    progress stay prompt), large enough to amortise NumPy's per-call cost. Expensive samples
    (BDPT) ask for smaller units. The pass size follows from it, so it is part of what makes an
    image bit-identical: changing it changes the order in which splats are summed.
``batch_units`` (class attribute)
    How many of those units a final render runs as one batch (the viewport: one), to spread
    the per-call cost over more paths where the memory allows. The pass size stays that of
    ``unit_paths``, and every pixel's samples of a pass stay in one batch, so without splats
    the image is the same bit for bit.
``chunk_paths`` (class or instance attribute)
    At most this many paths per call of :meth:`Integrator.render_samples` on the arrays
    (None: the whole batch at once): a batch is cut into consecutive chunks
    (:func:`render_in_chunks`) so that its arrays stay within the caches or memory. The
    outputs are joined in order before the film sees them, so the image is the same bit for
    bit.
``splats`` (class attribute)
    Whether :meth:`~Integrator.render_samples` returns light-path splats (light tracing, BDPT)
    besides one radiance per camera sample.
``strategy_views`` (class attribute)
    Whether the integrator can write one image per strategy (``settings.strategy_views``).
``whole_passes`` (class attribute)
    Whether the integrator renders whole passes itself (SPPM: its photons serve every pixel and
    its per-pixel radii change between passes, so its image is no mean of independent
    samples). The render loop then calls ``render_pass(pass_index, frame_pixels, sampler,
    pixel_filter, counters, map_chunks)`` once per pass instead of :meth:`render_samples`,
    shows the ``(n_pixels, 3)`` image it returns (None: cancelled, the pass is dropped) and
    adds ``render_stats(seconds)`` (a dict) to the render's stats; ``pass_sum_sq()`` gives the
    film's Variance pass (None: zero, not estimated); see :mod:`.sppm`.
``layers`` (instance attribute)
    Names of the extra images this render writes, in the order the render passes list them;
    :class:`BatchOutput` carries values for no other names.
``prepare_render(progress, cancel)``, ``messages()``, ``stats()``
    Work done once per render before the first work unit, with the render's progress and
    cancel callbacks (radiosity solves its system there; the others do nothing); what the
    render tells the user once about it; figures added to the render stats.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import ClassVar, NamedTuple

import numpy as np

# Paths per work unit of the path tracer (the default): large enough for NumPy to amortise its
# Python overhead, small enough that a unit takes well under a second and fits in memory.
UNIT_PATHS = 1 << 15


@dataclass
class Counters:
    """Work done by one batch (summed by the render loop).

    Attributes
    ----------
    rays : int
        Rays traced (camera, bounce and shadow rays).
    camera_samples : int
        Camera paths started.
    distribution_s : float
        Seconds spent in discrete choices (light and emissive-triangle selection).
    distribution_samples : int
        Discrete draws made in that time.
    """

    rays: int = 0
    camera_samples: int = 0
    distribution_s: float = 0.0
    distribution_samples: int = 0

    def add(self, other: "Counters"):
        """Accumulate another batch's counts into this one."""
        self.rays += other.rays
        self.camera_samples += other.camera_samples
        self.distribution_s += other.distribution_s
        self.distribution_samples += other.distribution_samples


class Splats(NamedTuple):
    """Light-path contributions anywhere on the film (:meth:`core.film.Film.splat`).

    Attributes
    ----------
    xy : (m, 2) float64
        Film positions, in frame pixels, y up.
    value : (m, 3) float64
        Their values, spread with the render's pixel filter.
    """

    xy: np.ndarray
    value: np.ndarray

    @staticmethod
    def join(parts):
        """One :class:`Splats` of the ``parts`` in order (empty if there are none)."""
        parts = list(parts)
        if not parts:
            return Splats(np.zeros((0, 2)), np.zeros((0, 3)))
        return Splats(np.concatenate([p.xy for p in parts]),
                      np.concatenate([p.value for p in parts]))


@dataclass
class BatchOutput:
    """What an integrator returns for one work unit.

    Attributes
    ----------
    radiance : (n, 3) float64
        Camera-sample estimates, one per entry of the unit's stream (may be all zero);
        finite and non-negative.
    splats : Splats or None
        Light-path contributions (integrators whose ``splats`` is true).
    light_paths : int
        Light paths traced (the splats' denominator).
    camera_layers : dict of str to (n, 3) float64
        Extra images by layer name (one of the integrator's ``layers``), one value per camera
        sample as ``radiance``.
    splat_layers : dict of str to Splats
        Extra images by layer name, as light-path splats.
    transparency : (n,) float64 or None
        Per camera sample, the part of it that reached a transparent film's background (the
        mean of the throughput of camera rays that escaped, Cycles' ``transparent``): the
        pixel's alpha is one minus its mean. None: an opaque sample (alpha one).
    """

    radiance: np.ndarray
    splats: Splats = None
    light_paths: int = 0
    camera_layers: dict = field(default_factory=dict)
    splat_layers: dict = field(default_factory=dict)
    transparency: np.ndarray = None

    @staticmethod
    def join(parts):
        """One output of consecutive parts of a stream, in order; a camera layer that a part
        lacks is zero on that part's samples."""
        parts = list(parts)
        camera_names = dict.fromkeys(name for p in parts for name in p.camera_layers)
        splat_names = dict.fromkeys(name for p in parts for name in p.splat_layers)
        splats = [p.splats for p in parts if p.splats is not None]
        transparency = (np.concatenate([np.zeros(p.radiance.shape[0]) if p.transparency is None
                                        else p.transparency for p in parts])
                        if any(p.transparency is not None for p in parts) else None)
        return BatchOutput(
            np.concatenate([p.radiance for p in parts]),
            Splats.join(splats) if splats else None,
            sum(p.light_paths for p in parts),
            {name: np.concatenate([p.camera_layers[name] if name in p.camera_layers
                                   else np.zeros_like(p.radiance) for p in parts])
             for name in camera_names},
            {name: Splats.join(p.splat_layers[name] for p in parts if name in p.splat_layers)
             for name in splat_names}, transparency)


def render_in_chunks(render_samples, stream, chunk, pixel_filter, counters):
    """``render_samples(part, pixel_filter, counters)`` on consecutive parts of ``stream`` of
    at most ``chunk`` paths each, joined in order (:meth:`BatchOutput.join`): the same output
    as one call on the whole stream, in arrays ``chunk`` rows long."""
    n, parts = len(stream), []
    for start in range(0, n, chunk):
        part = copy.copy(stream)
        part.compact(np.arange(start, min(start + chunk, n)))
        parts.append(render_samples(part, pixel_filter, counters))
    return BatchOutput.join(parts)


class Integrator:
    """Base class of the estimators (see the module docstring for the contract).

    Parameters
    ----------
    prep : core.prepare.PreparedScene
    settings : core.render.RenderSettings
    """

    unit_paths: ClassVar[int] = UNIT_PATHS
    batch_units: ClassVar[int] = 1
    chunk_paths: ClassVar[int | None] = None
    splats: ClassVar[bool] = False
    strategy_views: ClassVar[bool] = False
    whole_passes: ClassVar[bool] = False

    def __init__(self, prep, settings):
        self.prep = prep
        self.settings = settings
        self.layers = ()

    def prepare_render(self, progress=None, cancel=None) -> bool:
        """Work done once before the first work unit (default: none). ``progress(fraction,
        text)`` and ``cancel()`` are the render's; returns whether ``cancel`` stopped it."""
        return False

    def messages(self) -> list:
        """What this render tells the user once (approximations, bias); default none."""
        return []

    def stats(self) -> dict:
        """Figures of this estimator's own work for the render stats; default none."""
        return {}

    def pass_sum_sq(self):
        """``whole_passes`` integrators: per-pixel sum ``(n_pixels, 3)`` of the squared per-pass
        estimates whose mean the image is (the film's Variance pass), or None: the variance is
        not estimated and the pass is zero (default)."""
        return None

    def pass_transparency(self):
        """``whole_passes`` integrators on a transparent film: per-pixel sum ``(n_pixels,)``
        over the passes of what of each pass's camera sample reached the background (as
        :attr:`BatchOutput.transparency`), or None: an opaque film (default)."""
        return None

    def render_samples(self, stream, pixel_filter, counters: Counters) -> BatchOutput:
        """Estimates of one work unit: one sample per entry of ``stream``.

        Parameters
        ----------
        stream : core.sampling.stream.SampleStream
            One sample vector per (pixel, sample index); the integrator draws every random
            number from it.
        pixel_filter : core.film.PixelFilter
            Importance-sampled for camera rays; light-path splats are spread with it.
        counters : Counters
            Incremented with the work done.
        """
        raise NotImplementedError
