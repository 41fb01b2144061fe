"""Film > Transparent for estimators whose image does not come from camera paths (MLT).

On a transparent film a pixel's alpha is one minus the share of its camera rays that reach the
background, also through transparent surfaces (Transparent BSDF, a Principled BSDF's Alpha, a
Mix with a Transparent BSDF), each pass times the surface's transparency ``sum_c w_c color_c``
(:func:`.shadows.shadow_transmittance`). The path tracer samples each pass (it chooses the
transparent component with probability ``w_c`` and keeps ``color_c``) and adds the mean of the
throughput of the camera rays that escape; here the same camera rays (the sampler's dimensions
0-1, through the pixel filter) take that in expectation, so the alpha has the path tracer's
expectation, and is bit for bit the path tracer's where no transparent surface is crossed.

The Transparent limit ``T`` applies as in the path tracer (:mod:`.bounces`): a camera ray
reaches the background through at most ``max(T, 1)`` transparent surfaces.
"""

from __future__ import annotations

import numpy as np

from ..scene import VIS_CAMERA
from .base import Counters
from .common import camera_rays
from .shadows import shadow_transmittance

# Camera rays per task on the worker threads (cancel is polled between tasks).
CHUNK = 1 << 15


def camera_transparency(prep, pixel_filter, stream, transparent_limit, counters):
    """What of each camera sample of ``stream`` reaches the background, ``(n,)`` in [0, 1].

    Parameters
    ----------
    prep : core.prepare.PreparedScene
    pixel_filter : core.film.PixelFilter
        Importance-sampled for the camera rays (dimensions 0-1 of ``stream``).
    stream : core.sampling.stream.SampleStream
        One camera sample per entry.
    transparent_limit : int
        The Transparent bounce limit ``T``.
    counters : Counters
        Incremented with the rays traced.
    """
    o, d, tmax = camera_rays(prep, pixel_filter, stream)
    counters.rays += o.shape[0]
    through = shadow_transmittance(prep, o, d, np.asarray(tmax, np.float64),
                                   max(int(transparent_limit), 1), counters, VIS_CAMERA)
    clear = np.nan_to_num(through.mean(axis=1), nan=0.0, posinf=0.0, neginf=0.0)
    return np.clip(clear, 0.0, 1.0)


def pass_transparency(prep, settings, pass_index, frame_pixels, sampler, pixel_filter,
                      counters, map_chunks):
    """Stage *film alpha*: one camera sample per pixel of ``frame_pixels (n,)`` (sample index
    ``pass_index`` of ``sampler``), in chunks on the worker threads; the transparency ``(n,)``
    of each, or None if the render was cancelled."""
    n = frame_pixels.size

    def chunk(start):
        rows = np.arange(start, min(start + CHUNK, n))
        stream = sampler.stream(frame_pixels[rows], np.full(rows.size, pass_index, np.int64))
        local = Counters()
        return camera_transparency(prep, pixel_filter, stream,
                                   settings.transparent_max_bounces, local), local

    parts = map_chunks(chunk, range(0, n, CHUNK))
    if parts is None:
        return None
    for _, local in parts:
        counters.add(local)
    return np.concatenate([clear for clear, _ in parts]) if parts else np.zeros(0)
