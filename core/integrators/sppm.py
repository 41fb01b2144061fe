"""Stochastic progressive photon mapping (Hachisuka & Jensen 2009), as pbrt-v4 lays it out.

What it estimates
    The pixel measurement, by passes. Each pass traces one camera path per pixel through
    specular bounces to its *visible point* (the first hit that is not a pure delta BSDF,
    :mod:`core.photons.visible`), adding the emitters the path sees and the visible point's
    direct light by next-event estimation. Then ``photons`` photons leave the lights
    (:mod:`core.photons.tracing`); those arriving after at least one bounce and within a
    pixel's radius ``r`` of its visible point add ``beta_vp f(wo, wi_p) power_p`` to the
    pixel's flux ``phi`` and one to its count ``M``. After the pass every pixel with ``M > 0``
    shrinks its radius and rescales its accumulated flux ``tau``::

        N' = N + alpha M,   r' = r sqrt(N' / (N + M)),   tau' = (tau + phi) (r' / r)^2

    The image is ``direct / passes + tau / (photons emitted pi r^2)``. Photons and camera
    paths pass transparent surfaces straight through (no bounce), the shadow rays cross them
    attenuated (:mod:`core.photons.passes`); on a transparent film the camera rays that escape
    give the alpha (:meth:`SPPM.pass_transparency`) and leave the world out.
Bias and consistency
    **Biased but consistent.** Density estimation blurs the incident light over a disk of
    radius ``r`` (and catches photons on nearby surfaces of other orientation, near edges and
    corners), so each pass's estimate is biased; since ``r`` shrinks to zero while the photon
    count behind each pixel grows without bound (for ``0 < alpha < 1``), both the bias and the
    variance vanish as passes grow. ``alpha`` trades them: small values shrink the radius fast
    (less bias, more noise), values near one keep more photons (less noise, more bias).
    Light paths are bounded as the path tracer's: ``max_bounces + 1`` scattering vertices.
Parameters
    ``photons`` per pass, ``photon_radius`` (initial radius in scene units; 0:
    :func:`core.photons.tracing.sppm_auto_radius`, 1.25 scene diagonals over the larger image
    side in pixels, a few pixels at any resolution, or with ``sppm_radius`` ``'pixel'``
    :data:`FOOTPRINT_PIXELS` pixel footprints at each pixel's first visible point, or with
    ``'adaptive'`` the scene radius halved per pixel by Lepski's rule over nested disks,
    :mod:`core.photons.adaptive`, where a smaller disk's estimate disagrees beyond noise),
    ``sppm_alpha``, ``photon_surface_test`` (photons of other surfaces are not counted,
    :mod:`core.photons.compatible`), ``sppm_coverage`` (divide by the share of the disk on a
    compatible surface, :mod:`core.photons.coverage`, instead of the whole disk),
    ``photon_memory`` (MB cap of a pass's photons), ``max_bounces``. Lookups use a kd-tree
    (``scipy.spatial.cKDTree``, see :mod:`core.photons.lookup`) with a uniform kernel (the
    radius update counts photons). The surface test and the coverage change the estimate only
    where the disk meets other surfaces or a surface's edge, and as ``r -> 0`` neither changes
    it at interior points of smooth surfaces: consistency is kept, and both remove bias.
When to use it
    Light that reaches diffuse surfaces only through mirrors or smooth glass from small or point
    lights (caustics, a point light seen in a mirror on the floor): path tracing cannot find it
    (a point light is never hit), BDPT only where the lit surface is seen directly (light-path
    vertices joined to the pinhole), not where it is seen through a mirror or glass again
    (``L S D S E`` paths), which photon mapping renders like any other.
When it fails
    Glossy surfaces seen directly blur (the estimate averages the lobe over the disk), and
    scenes where few photons land in view converge slowly.

Render loop: a pass is one call of :meth:`SPPM.render_pass` (``whole_passes``): photons are
shared by every pixel and the per-pixel state changes between passes, so the image is not a
mean of independent samples; the film shows the current estimate after each pass. The image
is, however, the mean of per-pass estimates ``direct_k + phi_k / (photons pi r_k^2)`` (Knaus
and Zwicker 2011), whose spread gives the Variance pass (:meth:`SPPM.pass_sum_sq`): the
variance of this biased estimate, not its mean squared error. Within a pass the camera paths
and the photons are cut into one chunk per worker thread at least and run in one batch of
chunks, then the lookups in chunks of ``QUERY_CHUNK`` visible points; cancel is polled
between chunks. Photons straight from a light are not stored (direct light
comes from next-event estimation).
"""

from __future__ import annotations

import time

import numpy as np

from ..camera import view_extent
from ..materials.frame import to_world
from ..photons.adaptive import SCALES, NestedDisks, scale_sums
from ..photons.compatible import compatible
from ..photons.coverage import disk_coverage
from ..photons.lookup import QUERY_CHUNK, PhotonTree
from ..photons.tracing import (BYTES_PER_PHOTON, CHUNK, Photons, photon_chunk, photon_setup,
                               spans, sppm_auto_radius)
from ..photons.visible import join_points, trace_visible_points
from .base import Counters, Integrator


# Footprint radius: this many pixel footprints at a pixel's first visible point.
FOOTPRINT_PIXELS = 1.5


def footprint_scale(camera):
    """``fn(dist) -> radius`` of one pixel's footprint at path length ``dist``: the pixel's
    angle times the distance for a perspective camera (its width for an orthographic one);
    None for a camera with no pixels."""
    if camera.width < 1 or camera.height < 1:
        return None
    half_x, half_y, _, _ = view_extent(camera)
    pixel = max(2.0 * half_x / camera.width, 2.0 * half_y / camera.height)
    if camera.type == "ORTHO":
        return lambda dist: np.full(np.shape(dist), pixel)
    return lambda dist: pixel * np.asarray(dist, np.float64)


class SPPM(Integrator):
    """Stochastic progressive photon mapping (see the module docstring)."""

    whole_passes = True
    unit_paths = CHUNK

    def __init__(self, prep, settings):
        super().__init__(prep, settings)
        self.photons, self.radius0, self.photon_sampler = photon_setup(prep, settings,
                                                                       sppm_auto_radius)
        self.alpha = float(settings.sppm_alpha)
        # Per-pixel initial radii from the pixel footprint (auto radius only).
        self.footprint = (settings.sppm_radius == "pixel" and not settings.photon_radius
                          and footprint_scale(prep.scene.camera) is not None)
        # Nested disks and Lepski's rule per pixel (core.photons.adaptive; auto radius only).
        self.adaptive = settings.sppm_radius == "adaptive" and not settings.photon_radius
        self.switches = 0
        self.surface_test = bool(settings.photon_surface_test)
        self.coverage = bool(settings.sppm_coverage)
        self.state = None
        self.peak_bytes = 0
        self.photons_stored = 0
        self.photon_s = 0.0
        from ..passes import thread_count  # the render loop imports the integrators

        self.workers = thread_count(settings)

    def _start(self, n_pixels):
        # r is NaN until a pixel's first visible point sets it (footprint radii).
        r0 = np.nan if self.footprint else self.radius0
        self.state = {"r": np.full(n_pixels, r0), "N": np.zeros(n_pixels),
                      "tau": np.zeros((n_pixels, 3)), "direct": np.zeros((n_pixels, 3)),
                      "sum_sq": np.zeros((n_pixels, 3)), "passes": 0,
                      "clear": (np.zeros(n_pixels) if self.prep.scene.film_transparent
                                else None),
                      "disks": NestedDisks(n_pixels) if self.adaptive else None}

    def render_pass(self, pass_index, frame_pixels, sampler, pixel_filter, counters,
                    map_chunks):
        """One SPPM pass over the film's pixels; returns the image ``(n_pixels, 3)`` after it,
        or None if the render was cancelled during the pass (the pass is then discarded).

        Parameters
        ----------
        pass_index : int
            Sample index of the camera streams and the photon streams.
        frame_pixels : (n_pixels,) int64
            Frame pixel of every film pixel.
        sampler : core.sampling.samplers.Sampler
        pixel_filter : core.film.PixelFilter
        counters : Counters
        map_chunks : callable(fn, items) -> list or None
            Runs ``fn`` on the items on the worker threads, in order; None when cancelled.
        """
        n = frame_pixels.size
        if self.state is None:
            self._start(n)
        traced = self._trace(pass_index, frame_pixels, sampler, pixel_filter, counters,
                             map_chunks)
        if traced is None:
            return None
        direct, points, photons, clear = traced
        if self.footprint:
            self._first_radii(points)
        tree = PhotonTree(photons.p, origin=np.zeros(3))
        found = map_chunks(lambda span: self._gather(points.take(slice(*span)), photons, tree),
                           spans(points.rows.size, self.workers, QUERY_CHUNK))
        if found is None:
            return None
        phi = np.concatenate([f[0] for f in found]) if found else np.zeros((0, 3))
        m = np.concatenate([f[1] for f in found]) if found else np.zeros(0)
        # No NaN or Inf may stay in the per-pixel sums (they would blank a pixel for good).
        bad = ~np.isfinite(phi).all(axis=1)
        phi[bad] = 0.0
        direct[~np.isfinite(direct).all(axis=1)] = 0.0
        self._add_pass_estimate(direct, points.rows, phi)
        sub = None
        if self.adaptive:
            sub = (tuple(np.concatenate([f[2][k] for f in found]) for k in range(2)) if found
                   else (np.zeros((0, SCALES - 1, 3)), np.zeros((0, SCALES - 1))))
            sub[0][bad] = 0.0
            sub[0][~np.isfinite(sub[0]).all(axis=2)] = 0.0
        self._update(points.rows, phi, m, sub)
        self.state["direct"] += direct
        if clear is not None:
            self.state["clear"] += clear
        self.state["passes"] += 1
        return self.image()

    def _first_radii(self, points):
        """Footprint radii: pixels without a radius yet take :data:`FOOTPRINT_PIXELS` pixel
        footprints at their visible point of this pass (path length x pixel angle)."""
        r = self.state["r"]
        new = np.isnan(r[points.rows])
        footprint = footprint_scale(self.prep.scene.camera)
        r[points.rows[new]] = np.maximum(FOOTPRINT_PIXELS * footprint(points.dist[new]), 1e-9)

    def _add_pass_estimate(self, direct, rows, phi):
        """Add the squares of this pass's own estimate ``direct + phi / (photons pi r^2)`` (with
        the radii it used) to ``sum_sq``: the image is the mean of these per-pass estimates,
        so their spread gives its variance (:meth:`pass_sum_sq`)."""
        x = direct.copy()
        r = self.state["r"][rows]
        with np.errstate(invalid="ignore", divide="ignore"):
            found = phi / (float(self.photons) * np.pi * r * r)[:, None]
        found[~np.isfinite(found).all(axis=1)] = 0.0  # no radius yet: no photons either
        x[rows] += found
        self.state["sum_sq"] += x * x

    def pass_sum_sq(self):
        """Per-pixel sum ``(n_pixels, 3)`` of the squared per-pass estimates, for the film's
        Variance pass (:func:`core.passes.show_estimate`): the image is their mean (Knaus and
        Zwicker 2011), so sample variance / passes estimates the variance of the image *given
        the radii* (the photons of different passes are independent). It is the variance of a
        biased estimator, not its error (MSE): the bias is not in it. The pass estimates'
        expectations drift as the radius shrinks, which adds to the spread: an overestimate,
        slight once the radii change slowly."""
        return None if self.state is None else self.state["sum_sq"]

    def pass_transparency(self):
        """Per-pixel sum ``(n_pixels,)`` over the passes of what of each pass's camera path
        reached a transparent film's background (the alpha); None on an opaque film."""
        return None if self.state is None else self.state["clear"]

    def _trace(self, pass_index, frame_pixels, sampler, pixel_filter, counters, map_chunks):
        """Stages *visible points* (one camera path per pixel, with its direct light) and
        *photon tracing* (``photons`` photons, those after one bounce at least kept), their
        chunks in one call of ``map_chunks`` so that both keep every worker thread busy:
        ``(direct (n, 3), VisiblePoints, Photons, clear)``, ``clear (n,)`` what of each
        camera path reached a transparent film's background (None: an opaque film), or None if
        cancelled."""
        n = frame_pixels.size
        prep, settings = self.prep, self.settings

        def camera(span):
            rows = np.arange(*span)
            stream = sampler.stream(frame_pixels[rows], np.full(rows.size, pass_index,
                                                                 np.int64))
            local = Counters()
            local.camera_samples += rows.size
            direct = np.zeros((rows.size, 3))
            clear = np.zeros(rows.size) if prep.scene.film_transparent else None
            points = trace_visible_points(prep, stream, pixel_filter, settings.max_bounces,
                                          local, direct, settings.transparent_max_bounces,
                                          clear)
            points.rows = points.rows + span[0]
            return (direct, points, clear), local

        def photon(span):
            t0 = time.perf_counter()
            photons, local = photon_chunk(prep, settings, self.photon_sampler, pass_index, span,
                                          min_hit=2)
            return (photons, time.perf_counter() - t0), local

        tasks = ([(camera, span) for span in spans(n, self.workers)]
                 + [(photon, span) for span in spans(self.photons, self.workers)])
        parts = map_chunks(lambda task: task[0](task[1]), tasks)
        if parts is None:
            return None
        for _, local in parts:
            counters.add(local)
        cams = [out for (fn, _), (out, _) in zip(tasks, parts) if fn is camera]
        lights = [out for (fn, _), (out, _) in zip(tasks, parts) if fn is photon]
        # Photon time summed over the chunks, divided by the threads that ran them in parallel.
        self.photon_s += sum(t for _, t in lights) / self.workers
        photons = Photons.join(p for p, _ in lights)
        self.peak_bytes = max(self.peak_bytes, len(photons) * BYTES_PER_PHOTON)
        self.photons_stored += len(photons)
        direct = np.concatenate([d for d, _, _ in cams]) if cams else np.zeros((0, 3))
        clear = (np.concatenate([c for _, _, c in cams]) if cams and cams[0][2] is not None
                 else None)
        return direct, join_points([p for _, p, _ in cams]), photons, clear

    def _gather(self, points, photons, tree):
        """Flux ``phi (k, 3)`` (times the points' throughput) and photon counts ``m (k,)`` of
        every visible point from the photons (``tree`` over their positions) within its
        pixel's radius, and with the adaptive radius the same within the nested disks
        (:func:`core.photons.adaptive.scale_sums`; else None)."""
        i, j, d, live, radii = self._pairs(points, photons, tree)
        phi, m, contrib = self._flux(points, photons, i, j)
        sub = scale_sums(i, d, contrib, radii, m.size) if self.adaptive else None
        if self.coverage:
            share = self._coverage(points.take(live), radii[live])
            phi[live] /= share[:, None]
            if sub is not None:
                self._nested_coverage(points, sub[0], live[share < 1.0], radii)
        if sub is not None:
            sub = (sub[0] * points.beta[:, None, :], sub[1])
        return phi * points.beta, m, sub

    def _nested_coverage(self, points, phi, edge, radii):
        """Divide the nested disks' flux ``phi (k, SCALES - 1, 3)`` by their own share on a
        compatible surface, probed for the points ``edge`` whose own disk is not wholly on
        it (a disk wholly on it holds its nested disks wholly too: their share is one)."""
        if edge.size == 0:
            return
        near = points.take(edge)
        for s in range(phi.shape[1]):
            share = self._coverage(near, radii[edge] * 0.5 ** (s + 1))
            phi[edge, s] /= share[:, None]

    def _pairs(self, points, photons, tree):
        """``(i, j, d, live, radii)``: the (point, photon) pairs that count and their
        distances, the points with a radius and every point's radius."""
        radii = self.state["r"][points.rows]
        live = np.nonzero(np.isfinite(radii))[0]  # a footprint radius is set for each point
        i, j, d = tree.pairs_within(points.p[live], radii[live])
        i = live[i]
        # Paths no longer than the path tracer's: specular bounces + photon hits <= B + 1.
        ok = points.bounces[i] + photons.hit[j] <= self.settings.max_bounces + 1
        if self.surface_test:
            ok &= compatible(points.p[i], points.ng[i], photons.p[j], photons.n[j], radii[i])
        return i[ok], j[ok], d[ok], live, radii

    @staticmethod
    def _flux(points, photons, i, j):
        """Per point, the sum of ``f power`` over the pairs ``(i, j)`` and their count, and
        each pair's ``f power`` ``(m, 3)``."""
        k = points.rows.size
        contrib = (points.f(i, photons.wi[j].astype(np.float64))
                   * photons.power[j].astype(np.float64))
        phi = np.stack([np.bincount(i, contrib[:, c], minlength=k) for c in range(3)],
                       axis=1).astype(np.float64)  # (no pairs: bincount gives integers)
        return phi, np.bincount(i, minlength=k).astype(np.float64), contrib

    def _coverage(self, points, radii):
        """Share of each point's disk on a compatible surface (:mod:`core.photons.coverage`),
        probed from the side the camera sees."""
        wo = to_world(points.wo_local, *points.frame)
        side = np.where(np.einsum("ij,ij->i", points.ng, wo) < 0, -1.0, 1.0)
        return disk_coverage(self.prep, points.p, points.ng * side[:, None], radii)

    def _update(self, pixels, phi, m, sub=None):
        """The progressive radius reduction of the pixels ``pixels`` that found photons; with
        the adaptive radius ``sub`` holds the nested disks' sums of the pass, which are
        rescaled alike, and Lepski's rule may then halve a pixel's radius
        (:class:`core.photons.adaptive.NestedDisks`)."""
        s = self.state
        hit = m > 0
        px, phi, m = pixels[hit], phi[hit], m[hit]
        n_old, r_old = s["N"][px], s["r"][px]
        n_new = n_old + self.alpha * m
        r_new = r_old * np.sqrt(n_new / (n_old + m))
        ratio2 = (r_new / r_old) ** 2
        s["tau"][px] = (s["tau"][px] + phi) * ratio2[:, None]
        s["N"][px], s["r"][px] = n_new, r_new
        if sub is not None:
            s["disks"].add(px, sub[0][hit], sub[1][hit], ratio2)
            self.switches += s["disks"].switch(s, px)

    def image(self):
        """The current estimate ``(n_pixels, 3)``, finite and non-negative."""
        s = self.state
        passes = max(s["passes"], 1)
        emitted = float(self.photons) * passes
        with np.errstate(invalid="ignore", divide="ignore"):
            indirect = s["tau"] / (emitted * np.pi * s["r"] ** 2)[:, None]
        indirect[~np.isfinite(indirect).all(axis=1)] = 0.0  # no radius yet: no photons
        img = s["direct"] / passes + indirect
        img[~np.isfinite(img).all(axis=1)] = 0.0
        return np.maximum(img, 0.0)

    def render_stats(self, seconds):
        """Photon figures for the render stats."""
        passes = self.state["passes"] if self.state else 0
        emitted = self.photons * passes
        return {"estimator_bias": "biased, consistent (radius shrinks with passes)",
                "photons_emitted": emitted,
                "photons_per_s": emitted / self.photon_s if self.photon_s > 0 else 0.0,
                "photons_stored": self.photons_stored,
                "photon_memory_peak_mb": self.peak_bytes / (1 << 20),
                "photon_radius_initial": ("pixel footprint" if self.footprint
                                          else self.radius0),
                "photon_radius_halvings": (int(self.state["disks"].halvings.sum())
                                           if self.adaptive and self.state else "n/a"),
                "photon_radius_mean": (float(np.nanmean(self.state["r"]))
                                       if self.state and np.isfinite(self.state["r"]).any()
                                       else self.radius0),
                "variance_pass": "spread of the per-pass estimates: the variance of this "
                                 "biased estimate, not its error (no bias in it)"}

