"""Path tracing with next-event estimation and multiple importance sampling.

What it estimates
    The pixel measurement of the rendering equation, one camera path per sample. At every
    surface vertex it samples a light (next-event estimation, NEE) and the BSDF; the BSDF ray
    also finds emitters, and the two estimates of direct light are combined with MIS (power
    heuristic by default) so neither small lights nor large glossy lobes blow up the variance.
Bias and consistency
    Unbiased for paths of up to ``max_bounces + 1`` scattering vertices (Cycles' meaning of
    "bounces": ``max_bounces = 0`` is direct light only); Russian roulette removes paths without
    bias. Light carried by longer paths is missing, as in every renderer with a bounce limit.
Parameters
    ``max_bounces``, ``use_russian_roulette``, ``rr_min_bounces`` (roulette starts after that many
    bounces, with survival probability ``min(1, max(throughput))``); ``mis_heuristic`` in
    ``balance | power | maximum | cutoff | none | bsdf | light`` with ``mis_beta`` (power) and
    ``mis_alpha`` (cutoff), see :mod:`core.sampling.mis`: ``bsdf`` skips next-event estimation
    (and so cannot see point, spot or sharp sun lights), ``light`` drops emitters that BSDF rays
    find after a bounce where NEE could have sampled them. The light sampler's
    ``light_selection``, ``light_sampling`` and ``distribution`` are set in
    :func:`core.prepare.prepare` (see :class:`core.lights.LightSampler`).
Materials
    Every BSDF family of :mod:`core.materials.bsdf` (diffuse, conductor and mirror, smooth and
    rough dielectric, layered coat), in radiance mode, in local frames around the stored
    geometric normal. Mixed materials (fractional Metallic, Transmission or Alpha, Mix
    Shaders) choose one component per vertex with the lobe number
    (:meth:`core.prepare.PreparedScene.choose_bsdf`), which both NEE and BSDF sampling use.
    NEE skips delta-only surfaces; after a delta bounce the emitter found
    keeps weight one (no MIS); the sampled lobe sets the next ray's object visibility class
    (diffuse, glossy or transmission). Scenes whose materials are all diffuse take a
    world-space Lambert path with the same estimator.
When to use it
    The default for most scenes: diffuse and glossy transport lit by area lights, the sky, or
    lamps seen directly.
When it fails
    Light that reaches the camera only through delta surfaces from a small or point light
    (caustics through glass, a point light seen in a mirror) has zero or tiny probability of being
    found from the camera side: those paths show as fireflies or are missing. Use BDPT there.

Stages of one bounce (pbrt-v4's wavefront integrator): intersect -> handle escaped -> handle
emission -> sample lights -> sample BSDF -> Russian roulette -> compact.
"""

from __future__ import annotations

import numpy as np

from ..accel import Hits
from ..materials.bsdf import (KIND_DIELECTRIC, LOBE_TRANSMIT, RADIANCE, eval_bsdf, pdf_bsdf,
                              sample_bsdf)
from ..materials.frame import shading_frame, to_local, to_world
from ..materials.lambert import eval_lambert, pdf_lambert, sample_lambert
from ..sampling.mis import MIS
from ..scene import VIS_CAMERA, VIS_DIFFUSE, VIS_SHADOW
from .base import BatchOutput, Integrator
from .common import (add_emitters_along_rays, add_rows, camera_rays, finite_rows,
                     geometric_side_valid, intersect_by_class, max_component, next_1d_if,
                     ray_class, roulette_at, russian_roulette, surface_hits,
                     surface_interaction, take_rows)

# Dimensions of the sample vector: 0-1 pixel filter, then a block per bounce (light selection,
# light position 2-D, BSDF lobe, BSDF direction 2-D, Russian roulette).
DIMS_CAMERA = 2
DIMS_PER_BOUNCE = 7


class _LambertShading:
    """Shading of a batch when every material of the scene is diffuse (world-space Lambert).

    Same estimator as :class:`_BSDFShading` on diffuse rows, without the local frames.
    """

    def __init__(self, prep, si):
        self.albedo = take_rows(prep.tri_albedo, si.prim)
        self.ns = si.ns
        self.nee_rows = None  # every row takes part in next-event estimation
        # Smooth shading: reflections must stay on wo's side of the geometric surface.
        self.ng = si.ng if prep.scene.corner_normals is not None else None
        self.wo = si.wo

    def set_base_color(self, rows, color):
        """Replace the albedo of ``rows`` (textured hits) by ``color (j, 3)``."""
        self.albedo[rows] = color

    def eval_pdf(self, rows, wi):
        """``f cos`` and the pdf of ``wi (k, 3)`` at the rows ``rows`` (None: every row)."""
        ns = _rows(self.ns, rows)
        f = eval_lambert(_rows(self.albedo, rows), ns, wi)
        if self.ng is not None:
            f *= geometric_side_valid(_rows(self.ng, rows), _rows(self.wo, rows), wi,
                                      False)[:, None]
        return f, pdf_lambert(ns, wi)

    def sample(self, u):
        wi, weight, pdf = sample_lambert(self.albedo, self.ns, u)
        if self.ng is not None:
            weight *= geometric_side_valid(self.ng, self.wo, wi, False)[:, None]
        k = pdf.shape[0]
        return (wi, weight, pdf, np.zeros(k, bool), np.full(k, VIS_DIFFUSE, np.int32),
                np.zeros(k, bool), None)


class _BSDFShading:
    """Shading of a batch through :mod:`core.materials.bsdf`: local frames around the stored
    (unflipped) geometric normal, so dielectrics know whether the path is inside or outside."""

    def __init__(self, prep, si, u_lobe, u, v):
        # One component of mixed materials per vertex, used for NEE and BSDF sampling alike.
        self.params, delta_only, self.u_lobe = prep.choose_bsdf(si.prim, u_lobe, u, v)
        self.ng = None
        if prep.scene.corner_normals is None:
            self.s, self.t, self.n = shading_frame(si.ng)
        else:
            # Smooth shading: the frame's +Z is the shading normal on the stored front side
            # (si.ns is flipped toward wo exactly when ng is), plus the geometric-side test.
            front = np.where(np.einsum("ij,ij->i", si.ns, si.ng) < 0, -1.0, 1.0)
            self.s, self.t, self.n = shading_frame(si.ns * front[:, None])
            self.ng, self.wo_world = si.ng, si.wo
        self.wo = to_local(si.wo, self.s, self.t, self.n)
        # Next-event estimation cannot contribute through smooth mirrors and glass.
        self.nee_rows = np.nonzero(~delta_only)[0] if delta_only.any() else None

    def eval_pdf(self, rows, wi):
        """``f cos`` and the pdf of ``wi (k, 3)`` at the rows ``rows`` (None: every row)."""
        p = self.params if rows is None else self.params.take(rows)
        wo = _rows(self.wo, rows)
        wi_local = to_local(wi, _rows(self.s, rows), _rows(self.t, rows), _rows(self.n, rows))
        f = eval_bsdf(p, wo, wi_local, RADIANCE)
        if self.ng is not None:
            transmit = wo[:, 2] * wi_local[:, 2] < 0
            f *= geometric_side_valid(_rows(self.ng, rows), _rows(self.wo_world, rows), wi,
                                      transmit)[:, None]
        return f, pdf_bsdf(p, wo, wi_local)

    def sample(self, u):
        smp = sample_bsdf(self.params, self.wo, self.u_lobe, u, RADIANCE)
        wi = to_world(smp.wi, self.s, self.t, self.n)
        weight = smp.weight
        if self.ng is not None:
            transmit = (smp.lobe & LOBE_TRANSMIT) != 0
            weight = weight * geometric_side_valid(self.ng, self.wo_world, wi, transmit)[:, None]
        return (wi, weight, smp.pdf, smp.delta, ray_class(smp.lobe), self.pass_through(smp),
                self.eta_squared(smp))

    def eta_squared(self, smp):
        """``etap^2 (k,)`` of rows whose sample refracted (1 elsewhere): the factor by which
        radiance transport scaled their weight down (see :mod:`core.materials.dielectric`),
        None when no row refracted."""
        p = self.params
        refracted = (((smp.lobe & LOBE_TRANSMIT) != 0) & (p.eta > 0)
                     & (np.sign(smp.wi[:, 2]) != np.sign(self.wo[:, 2])))
        if not refracted.any():
            return None
        eta = np.where(refracted, p.eta, 1.0)
        return np.where(self.wo[:, 2] > 0, eta * eta, 1.0 / (eta * eta))

    def pass_through(self, smp):
        """Rows whose sample went straight through a smooth dielectric of IOR 1 (Transparent
        BSDF, Principled Alpha): the ray keeps its kind, as Cycles' transparent bounces do."""
        p = self.params
        return (smp.delta & ((smp.lobe & LOBE_TRANSMIT) != 0) & (p.kind == KIND_DIELECTRIC)
                & (p.eta == 1.0))


class PathTracer(Integrator):
    """Path tracing with next-event estimation and MIS (see the module docstring).

    Built once per render: the MIS and whether next-event estimation runs at all.
    """

    # Twice the default unit: a 36-triangle Cornell box unit takes ~0.13 s on one core, and
    # the per-call NumPy cost of the deep, sparse bounces is spread over more paths.
    unit_paths = 1 << 16

    def __init__(self, prep, settings):
        super().__init__(prep, settings)
        self.mis = MIS.from_settings(settings)
        # BSDF sampling alone never samples lights: skip NEE and its shadow rays altogether.
        self.use_nee = self.mis.samples_lights
        # A light tree chooses lights from the shading normal too: NEE and the MIS weights of
        # emitters found by rays must then see the same normal.
        self.normals = prep.lights.selector.point_dependent

    def render_samples(self, stream, pixel_filter, counters):
        """Radiance of one camera path per entry of ``stream`` (finite, non-negative)."""
        prep, settings, mis = self.prep, self.settings, self.mis
        n = len(stream)
        L = np.zeros((n, 3))
        counters.camera_samples += n
        o, d, tmax = camera_rays(prep, pixel_filter, stream)
        rows_of = np.arange(n)
        beta = np.ones((n, 3))
        pdf_prev = np.zeros(n)
        use_mis = np.zeros(n, bool)
        vis = np.full(n, VIS_CAMERA, np.int32)
        # Camera rays, also after passing straight through transparent surfaces.
        camera_ray = np.ones(n, bool)
        n_prev = None  # shading normals at the rays' origins (light tree only)
        # Product of etap^2 over the refractions so far (None: none yet): Russian roulette
        # looks at beta * eta_scale, the throughput without radiance's 1 / etap^2 (pbrt-v4's
        # etaScale), so a path inside glass is not killed for a factor that leaving undoes.
        eta_scale = None

        for bounce in range(settings.max_bounces + 2):
            # Intersect, then add what the ray sees of emitters: world, lamps, emissive triangles.
            hits = intersect_by_class(prep.accel, o, d, tmax, vis)
            counters.rays += o.shape[0]
            _add_emitters(prep, L, beta, o, d, hits, rows_of, pdf_prev, use_mis, camera_ray, mis,
                          n_prev)
            if bounce == settings.max_bounces + 1:
                break  # this segment only gathered emission (Cycles' "terminate on next surface")

            # Compact to surface hits; degenerate triangles end the path.
            live = surface_hits(prep, hits)
            if live.size == 0:
                break
            si = surface_interaction(prep, hits, d, live)
            if live.size < rows_of.size:
                stream.compact(live)
                rows_of, beta = rows_of[live], take_rows(beta, live)
                vis, camera_ray = vis[live], camera_ray[live]
            # This bounce's numbers, all drawn up front in the order of their dimensions: the
            # BSDF lobe number also chooses the component of mixed materials before NEE needs it.
            # Numbers nothing reads are skipped, not drawn (a Lambert-only scene chooses no
            # lobe; roulette starts after rr_min_bounces): every number is a function of its
            # dimension, so the others keep their values.
            stream.skip_to(DIMS_CAMERA + bounce * DIMS_PER_BOUNCE)
            u_sel = stream.next_1d()
            u_light = stream.next_2d()
            u_lobe = next_1d_if(stream, not prep.lambert_only)
            u_bsdf = stream.next_2d()
            u_rr = next_1d_if(stream, roulette_at(settings, bounce))
            shading = self._shading(si, hits, live, u_lobe)

            # Sample lights: NEE with a shadow ray, MIS against BSDF sampling.
            if self.use_nee:
                nee = shading.nee_rows
                if nee is None or nee.size:
                    _next_event(prep, shading, si, nee, _rows(u_sel, nee), _rows(u_light, nee),
                                beta, L, rows_of, mis, counters, self.normals)

            # Sample the BSDF for the next segment: delta bounces are not MIS-weighted later.
            wi, weight, pdf_b, delta, vis_next, through, eta_sq = shading.sample(u_bsdf)
            beta = beta * weight
            alive = (pdf_b > 0) & finite_rows(beta)
            if eta_scale is not None and live.size < eta_scale.size:
                eta_scale = eta_scale[live]
            if eta_sq is not None:
                eta_scale = eta_sq if eta_scale is None else eta_scale * eta_sq

            alive, beta = russian_roulette(beta, alive, u_rr, settings, bounce, eta_scale)
            keep = np.nonzero(alive)[0]
            if keep.size == 0:
                break
            # Compact only when a path ended (after a bounce inside a closed room none does).
            if keep.size < alive.size:
                stream.compact(keep)
                rows_of, beta = rows_of[keep], take_rows(beta, keep)
                p, ng, prim = take_rows(si.p, keep), take_rows(si.ng, keep), si.prim[keep]
                ns = take_rows(si.ns, keep) if self.normals else None
                wi = take_rows(wi, keep)
                pdf_b, delta, through = pdf_b[keep], delta[keep], through[keep]
                eta_scale = None if eta_scale is None else eta_scale[keep]
                vis, vis_next, camera_ray = vis[keep], vis_next[keep], camera_ray[keep]
            else:
                p, ng, prim = si.p, si.ng, si.prim
                ns = si.ns if self.normals else None
            o = prep.accel.offset_origin(p, ng, prim, wi)
            d = wi
            tmax = None  # bounce rays are unbounded
            pdf_prev = pdf_b
            n_prev = ns
            use_mis = ~delta
            camera_ray = camera_ray & through
            vis = np.where(through, vis, vis_next)

        # No NaN or Inf reaches the film: a non-finite estimate is dropped (counted as zero).
        bad = ~finite_rows(L)
        L[bad] = 0.0
        return BatchOutput(np.maximum(L, 0.0))

    def _shading(self, si, hits, live, u_lobe):
        """Stage *surface shading* of the hits ``live``: Lambert in world space when every
        material is diffuse, else the BSDF in local frames."""
        prep = self.prep
        if prep.lambert_only:
            shading = _LambertShading(prep, si)
            if prep.scene.textures:
                shading.set_base_color(*prep.textured_base_color(si.prim, hits.u[live],
                                                                 hits.v[live]))
            return shading
        return _BSDFShading(prep, si, u_lobe, hits.u[live], hits.v[live])


# One work unit without a render loop (tests, one-off use); a render builds PathTracer once.


def _add_emitters(prep, L, beta, o, d, hits, rows_of, pdf_prev, use_mis, camera_ray, mis,
                  n_prev=None):
    """Stage *handle escaped + handle emission*, with camera rays (``camera_ray (n,)``: lamps
    show only if visible to the camera) and other rays handled apart; ``n_prev (n, 3)``: shading
    normals at the origins, for a light tree (None otherwise)."""
    groups = ([(None, bool(camera_ray[0]))] if np.all(camera_ray == camera_ray[:1])
              else [(np.nonzero(camera_ray)[0], True), (np.nonzero(~camera_ray)[0], False)])
    for rows, camera in groups:
        if rows is None:
            add_emitters_along_rays(prep, L, beta, o, d, hits, rows_of, pdf_prev, use_mis,
                                    camera, mis, n_prev)
            continue
        sub = Hits(hits.prim[rows], hits.t[rows], hits.u[rows], hits.v[rows])
        add_emitters_along_rays(prep, L, beta[rows], o[rows], d[rows], sub, rows_of[rows],
                                pdf_prev[rows], use_mis[rows], camera, mis,
                                None if n_prev is None else n_prev[rows])


def _next_event(prep, shading, si, rows, u_sel, u_light, beta, L, rows_of, mis, counters,
                normals=False):
    """Stage *sample lights* on the shading rows ``rows`` (None: every row): adds
    ``beta f Li w / pdf`` to ``L``; ``normals``: the light selection also takes the shading
    normals (a light tree)."""
    p = _rows(si.p, rows)
    wi, dist, li, pdf_l, delta, light_normal = prep.lights.sample(
        p, u_sel, u_light, counters, n=_rows(si.ns, rows) if normals else None)
    f, pdf_b = shading.eval_pdf(rows, wi)
    ok = (pdf_l > 0) & (max_component(f) > 0) & (max_component(li) > 0)
    cand = np.nonzero(ok)[0]
    if cand.size == 0:
        return
    # Rows of the shading batch: gathered once, and not at all when every row takes part.
    cand_rows = cand if rows is None else rows[cand]
    blocked = prep.accel.occluded(*prep.accel.shadow_rays(
        take_rows(p, cand), take_rows(si.ng, cand_rows), si.prim[cand_rows], take_rows(wi, cand),
        dist[cand], take_rows(light_normal, cand)), VIS_SHADOW)
    counters.rays += cand.size
    unblocked = ~blocked
    vis, vis_rows = cand[unblocked], cand_rows[unblocked]
    # Delta lights cannot be found by BSDF sampling: their samples keep weight one.
    w = np.where(delta[vis], 1.0, mis.light_weight(pdf_l[vis], pdf_b[vis]))
    contrib = (take_rows(beta, vis_rows) * take_rows(f, vis) * take_rows(li, vis)
               * (w / pdf_l[vis])[:, None])
    add_rows(L, rows_of[vis_rows], contrib)


def _rows(a, rows):
    """``a[rows]``, or ``a`` itself when ``rows`` is None (every row: no copy)."""
    return a if rows is None else take_rows(a, rows)
