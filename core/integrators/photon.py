"""Photon mapping (Jensen's two-pass method): photon maps first, then camera paths gather.

What it estimates
    The pixel measurement. A first pass traces ``photons`` photons from the lights
    (:mod:`core.photons.tracing`) into two maps: the *caustic map* (photons that reached a
    non-specular surface through specular bounces only, ``L S+ D``) and the *global map* (every
    stored photon). Then each sample traces a camera path through specular bounces to its
    visible point (:mod:`core.photons.visible`) and adds

    - emission seen directly or through specular bounces, and direct light by next-event
      estimation (light sampling);
    - caustics: a density estimate in the caustic map at the visible point;
    - indirect light: *final gathering*, ``gather_rays`` BSDF-sampled rays from the visible
      point (followed through specular bounces), each looking up the global map where it lands
      (the light reflected there, direct and indirect); emitters the gather rays hit are left
      to next-event estimation. With ``gather_rays = 0`` the global map's indirect photons are
      read at the visible point itself (fast, blotchy).

    Density estimation uses the ``photon_k`` nearest photons (``photon_lookup = 'knn'``) or a
    fixed ``photon_radius`` (``'radius'``), weighted by ``photon_kernel`` (:mod:`core.photons
    .kernels`; see :mod:`core.photons.estimate`).

    Photons, camera paths and gather rays pass transparent surfaces straight through (no
    bounce), the shadow rays cross them attenuated (:mod:`core.photons.passes`). On a
    transparent film (Film > Transparent) the camera rays that escape give the alpha and
    leave the world out of the sample (:func:`core.photons.visible.trace_visible_points`).
Bias and consistency
    **Biased but consistent.** The density estimates blur light over their disk; the maps are
    fixed for the render, so more samples per pixel average the gather and direct-light noise
    but not this blur. The bias vanishes as the photon count grows with the radius (or ``k``
    over the photon count) shrinking. Paths are bounded as the path tracer's (``max_bounces +
    1`` scattering vertices).
Parameters
    ``photons``, ``photon_lookup``, ``photon_k``, ``photon_radius`` (0: 1/100 of the scene's
    bounding-box diagonal), ``photon_kernel``, ``gather_rays``, ``photon_memory``.
When to use it
    Caustics from small or point lights seen by a pinhole, as SPPM, when a fixed photon budget
    and a smooth (if blurred) result are wanted.
When it fails
    Its blur does not go away with more samples: raise the photon count (and memory) instead.

Render loop: whole passes (see :mod:`.base`): the first pass also builds the maps (its chunks
answer cancel); every pass adds one sample per pixel, the film shows their mean.
"""

from __future__ import annotations

import time

import numpy as np

from ..materials.bsdf import RADIANCE, sample_bsdf
from ..materials.frame import to_world
from ..photons.estimate import PhotonMap
from ..photons.tracing import BYTES_PER_PHOTON, CHUNK, photon_setup, trace_photon_chunks
from ..photons.visible import (DIMS_CAMERA, DIMS_PER_BOUNCE, follow_specular,
                               trace_visible_points)
from .base import Counters, Integrator
from .common import add_rows, ray_class, take_rows


class _GatherStream:
    """Sample numbers of gather rays: ray ``g`` of visible point ``i`` reads the stream entry of
    ``i`` at dimensions shifted by ``base + g * stride`` (rows ``g * k + i``)."""

    def __init__(self, stream, entries, rays, base, stride):
        self.stream, self.entries = stream, entries
        self.rays, self.base, self.stride = rays, base, stride
        self.dimension = 0
        self.kept = None  # rows kept by compact (None: all)

    def compact(self, keep):
        """Keep the rows ``keep`` (index array) of what the draws return (the transparent
        passes draw from a compacted copy, :mod:`core.photons.passes`)."""
        self.kept = keep if self.kept is None else self.kept[keep]

    def skip_to(self, dimension):
        self.stream.check_abort()  # a cancelled render stops here (core.render)
        self.dimension = int(dimension)

    def _take(self, count):
        out = np.concatenate([
            self.stream.sample(self.base + g * self.stride + self.dimension, count)[self.entries]
            for g in range(self.rays)])
        self.dimension += count
        return out if self.kept is None else out[self.kept]

    def next_1d(self):
        return self._take(1)[:, 0]

    def next_2d(self):
        return self._take(2)


class PhotonMapping(Integrator):
    """Jensen's two-pass photon mapping (see the module docstring)."""

    whole_passes = True
    unit_paths = CHUNK

    def __init__(self, prep, settings):
        super().__init__(prep, settings)
        self.photons, self.radius, self.photon_sampler = photon_setup(prep, settings)
        self.maps = None
        self.sum = None
        self.clear = None  # Film > Transparent: the samples' transparency summed per pixel
        self.passes = 0
        self.photon_s = 0.0
        bounces = settings.max_bounces
        self.gather_base = DIMS_CAMERA + (bounces + 1) * DIMS_PER_BOUNCE
        self.gather_stride = 3 + (bounces + 1) * DIMS_PER_BOUNCE

    def _lookup(self):
        s = self.settings
        return dict(lookup=s.photon_lookup, k=s.photon_k, radius=self.radius,
                    kernel=s.photon_kernel, surface_test=s.photon_surface_test)

    def _build_maps(self, map_chunks, counters):
        t0 = time.perf_counter()
        photons = trace_photon_chunks(self.prep, self.settings, self.photon_sampler,
                                      self.photons, 0, map_chunks, counters)
        if photons is None:
            return False
        self.photon_s = time.perf_counter() - t0
        self.maps = (PhotonMap(photons.take(photons.caustic), self.photons),
                     PhotonMap(photons, self.photons))
        return True

    def render_pass(self, pass_index, frame_pixels, sampler, pixel_filter, counters,
                    map_chunks):
        """One sample per pixel (after building the maps on the first pass); the mean image
        ``(n_pixels, 3)`` so far, or None if cancelled (see :class:`.base.Integrator`)."""
        if self.maps is None and not self._build_maps(map_chunks, counters):
            return None
        n = frame_pixels.size
        # Gather rays multiply the lookups of a sample: smaller chunks keep cancel prompt.
        size = max(256, CHUNK // (4 * max(1, self.settings.gather_rays)))

        def chunk(start):
            rows = np.arange(start, min(start + size, n))
            stream = sampler.stream(frame_pixels[rows], np.full(rows.size, pass_index,
                                                                 np.int64))
            local = Counters()
            return self._samples(stream, pixel_filter, local), local

        parts = map_chunks(chunk, range(0, n, size))
        if parts is None:
            return None
        for _, local in parts:
            counters.add(local)
        radiance = np.concatenate([L for (L, _), _ in parts])
        radiance[~np.isfinite(radiance).all(axis=1)] = 0.0
        self.sum = radiance if self.sum is None else self.sum + radiance
        if self.prep.scene.film_transparent:
            clear = np.concatenate([c for (_, c), _ in parts])
            self.clear = clear if self.clear is None else self.clear + clear
        self.passes += 1
        return np.maximum(self.sum / self.passes, 0.0)

    def pass_transparency(self):
        """Per-pixel sum ``(n_pixels,)`` of the samples' transparency on a transparent film
        (the alpha, :meth:`.base.Integrator.pass_transparency`); None on an opaque one."""
        return self.clear

    def _samples(self, stream, pixel_filter, counters):
        """Radiance ``(n, 3)`` of one camera sample per stream entry, and on a transparent
        film what of each reached the background ``(n,)`` (else None)."""
        n, bounces = len(stream), self.settings.max_bounces
        counters.camera_samples += n
        L = np.zeros((n, 3))
        clear = np.zeros(n) if self.prep.scene.film_transparent else None
        points = trace_visible_points(self.prep, stream, pixel_filter, bounces, counters, L,
                                      self.settings.transparent_max_bounces, clear)
        caustic, global_map = self.maps
        limit = bounces + 1 - points.bounces
        poll = stream.check_abort  # between lookup steps: a cancelled render stops there
        add_rows(L, points.rows, points.beta * caustic.radiance(points, limit, poll=poll,
                                                                **self._lookup()))
        if self.settings.gather_rays == 0:
            # No gather: the global map's other indirect photons, read here.
            indirect = global_map.radiance(points, limit, min_hit=2, skip_caustic=True,
                                           poll=poll, **self._lookup())
            add_rows(L, points.rows, points.beta * indirect)
        else:
            self._final_gather(stream, points, L, counters)
        return L, clear

    def _final_gather(self, stream, points, L, counters):
        """Stage *final gathering*: BSDF rays from the visible points into the global map."""
        k, rays = points.rows.size, int(self.settings.gather_rays)
        if k == 0:
            return
        rep = np.tile(np.arange(k), rays)
        gs = _GatherStream(stream, points.rows, rays, self.gather_base, self.gather_stride)
        u_lobe, u_dir = gs.next_1d(), gs.next_2d()
        params = points.params.take(rep)
        smp = sample_bsdf(params, take_rows(points.wo_local, rep), u_lobe, u_dir, RADIANCE)
        s, t, nrm = (take_rows(a, rep) for a in points.frame)
        wi = to_world(smp.wi, s, t, nrm)
        beta = take_rows(points.beta, rep) * smp.weight / rays
        ok = np.nonzero((smp.pdf > 0) & np.isfinite(beta).all(axis=1))[0]
        if ok.size == 0:
            return
        rep, beta, wi = rep[ok], beta[ok], wi[ok]
        o = self.prep.accel.offset_origin(points.p[rep], points.ng[rep], points.prim[rep], wi)
        gs_rows = ok  # gather-stream row of every surviving ray (ray g of point i: g k + i)
        hits = follow_specular(self.prep, gs, o, wi, None, beta, gs_rows,
                               ray_class(smp.lobe[ok]), self.settings.max_bounces, counters,
                               direct=None, dims=3,
                               transparent=self.settings.transparent_max_bounces,
                               passed=points.passed[rep])
        if hits.rows.size == 0:
            return
        origin = gs_rows.searchsorted(hits.rows)  # rows are ascending: index into `rep`
        vp = rep[origin]
        # Paths within the bounce limit: camera + visible point + gather chain + photon hit.
        limit = (self.settings.max_bounces - points.bounces[vp] - hits.bounces)
        _, global_map = self.maps
        # The lookups are most of a chunk's time: cancel is polled between their steps.
        found = hits.beta * global_map.radiance(hits, limit, poll=stream.check_abort,
                                                **self._lookup())
        # Several gather rays per point: sum them per point first (add_rows needs unique rows).
        per_point = np.stack([np.bincount(vp, found[:, c], minlength=k) for c in range(3)],
                             axis=1)
        add_rows(L, points.rows, per_point)

    def render_stats(self, seconds):
        """Photon figures for the render stats."""
        stored = sum(len(m) for m in self.maps) if self.maps else 0
        return {"estimator_bias": "biased, consistent (as photons grow and the radius shrinks)",
                "photons_emitted": self.photons if self.maps else 0,
                "photons_per_s": self.photons / self.photon_s if self.photon_s > 0 else 0.0,
                "photons_stored": stored,
                "photon_memory_peak_mb": stored * BYTES_PER_PHOTON / (1 << 20),
                "photon_radius_initial": self.radius,
                "variance_pass": "not estimated (zero): every sample reads one set of photon "
                                 "maps, whose noise a per-pixel spread would not show"}

