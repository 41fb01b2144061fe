"""Path tracing with next-event estimation and multiple importance sampling.

What it estimates
    The pixel measurement of the rendering equation, one camera path per sample. At every
    surface vertex it samples a light (next-event estimation, NEE) and the BSDF; the BSDF ray
    also finds emitters, and the two estimates of direct light are combined with MIS (power
    heuristic by default) so neither small lights nor large glossy lobes blow up the variance.
Bias and consistency
    Unbiased for paths within the bounce limits (Cycles' meaning of "bounces": ``max_bounces =
    0`` is direct light only; the per-kind limits count sampled lobes, :mod:`.bounces`);
    Russian roulette removes paths without bias. Light carried by longer paths is missing, as
    in every renderer with a bounce limit.
Parameters
    ``max_bounces``, ``diffuse_bounces``, ``glossy_bounces``, ``transmission_bounces``,
    ``transparent_max_bounces``, ``use_russian_roulette``, ``rr_min_bounces`` (roulette starts
    after that many bounces, with survival probability ``min(1, max(throughput))``);
    ``mis_heuristic`` in ``balance | power | maximum | cutoff | none | bsdf | light`` with
    ``mis_beta`` (power) and ``mis_alpha`` (cutoff), see :mod:`core.sampling.mis`: ``bsdf``
    skips next-event estimation (and so cannot see point, spot or sharp sun lights), ``light``
    drops emitters that BSDF rays find after a bounce where NEE could have sampled them. The light sampler's
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
    (diffuse, glossy or transmission). Transparent surfaces (Transparent BSDF, Alpha) pass
    rays straight through, keeping the MIS state of the vertex before them, and let shadow
    rays through with their attenuation (:mod:`.shadows`). Smooth glossy and glass surfaces
    bend the shading normal so that mirror reflections stay above the geometry
    (:func:`.common.valid_reflection_normals`). With Film > Transparent, camera rays that
    escape give alpha 0 instead of the world. Scenes whose materials are all diffuse take a
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
from ..materials.bsdf import (KIND_DIELECTRIC, KIND_DIFFUSE, LOBE_DIFFUSE, LOBE_REFLECT,
                              LOBE_TRANSMIT, RADIANCE, crosses_surface, eval_bsdf, pdf_bsdf,
                              sample_bsdf)
from ..materials.frame import shading_frame, to_local, to_world
from ..materials.lambert import eval_lambert, pdf_lambert, sample_lambert
from ..materials.lower_view import lower_view_params, view_below
from ..rows import scaled
from ..sampling.mis import MIS
from ..scene import VIS_CAMERA, VIS_DIFFUSE, VIS_SHADOW
from .base import BatchOutput, Integrator, render_in_chunks
from .bounces import BounceCounts, BounceLimits
from .shadows import shadow_transmittance
from .common import (add_emitters_along_rays, add_rows, camera_rays, finite_rows,
                     geometric_side_valid, intersect_by_class, max_component,
                     ray_class, roulette_at, russian_roulette, shading_tangents,
                     surface_hits, surface_interaction, take_rows,
                     valid_reflection_normals, with_base_normals, with_bump_normals,
                     with_coat_normals,
                     bends_normals)

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
            weight = weight * geometric_side_valid(self.ng, self.wo, wi, False)[:, None]
        k = pdf.shape[0]
        lobe = np.where(pdf > 0, LOBE_REFLECT | LOBE_DIFFUSE, 0).astype(np.uint8)
        return (wi, weight, pdf, np.zeros(k, bool), np.full(k, VIS_DIFFUSE, np.int32),
                np.zeros(k, bool), None, lobe)


def _coat_normals(prep, si):
    """``si.n_coat`` bent for a valid reflection where the material allows it, as Cycles
    bends the coat's normal (``maybe_ensure_valid_specular_reflection``)."""
    n = si.n_coat
    bend = bends_normals(prep.scene, si.prim) & np.any(n != 0.0, axis=1)
    if not bend.any():
        return n
    return np.where(bend[:, None], valid_reflection_normals(si.ng, si.wo, n), n)


class _BSDFShading:
    """Shading of a batch through :mod:`core.materials.bsdf`: local frames around the stored
    (unflipped) geometric normal, so dielectrics know whether the path is inside or outside."""

    def __init__(self, prep, si, u_lobe, u, v):
        # One component of mixed materials per vertex, used for NEE and BSDF sampling alike.
        self.params, delta_only, self.u_lobe = prep.choose_bsdf(si.prim, u_lobe, u, v)
        self.ng = None
        tangent = shading_tangents(prep, si)
        if prep.scene.corner_normals is None:
            self.s, self.t, self.n = shading_frame(si.ng, tangent)
        else:
            # Smooth shading: the frame's +Z is the shading normal on the stored front side
            # (si.ns is flipped toward wo exactly when ng is), plus the geometric-side test.
            # Glossy and glass rows bend it so that their mirror reflection stays above the
            # geometry, as Cycles' glossy closures (diffuse ones keep it) where the material's
            # Bump Map Correction allows; rows the view still falls below are shaded by
            # Cycles' rule for that case (lower_view).
            ns = si.ns
            glossy = (self.params.kind != KIND_DIFFUSE) & bends_normals(prep.scene, si.prim)
            if glossy.any():
                ns = np.where(glossy[:, None], valid_reflection_normals(si.ng, si.wo, ns), ns)
            front = np.where(np.einsum("ij,ij->i", ns, si.ng) < 0, -1.0, 1.0)
            self.s, self.t, self.n = shading_frame(ns * front[:, None], tangent)
            self.ng, self.wo_world = si.ng, si.wo
        self.wo = to_local(si.wo, self.s, self.t, self.n)
        if self.ng is not None:
            self.params = with_base_normals(self.params, si.ns * front[:, None],
                                            (self.s, self.t, self.n))
            if si.n_coat is not None:
                self.params = with_coat_normals(
                    self.params, _coat_normals(prep, si) * front[:, None], (self.s, self.t, self.n))
            below = view_below(np.einsum("ij,ij->i", si.wo, si.ng), self.wo[:, 2])
            self.params, self.wo = lower_view_params(self.params, self.wo, below)
        self.params = with_bump_normals(self.params, si, (self.s, self.t, self.n))
        # Next-event estimation cannot contribute through smooth mirrors and glass.
        self.nee_rows = np.nonzero(~delta_only)[0] if delta_only.any() else None

    def eval_pdf(self, rows, wi):
        """``f cos`` and the pdf of ``wi (k, 3)`` at the rows ``rows`` (None: every row)."""
        p = self.params if rows is None else self.params.take(rows)
        wo = _rows(self.wo, rows)
        wi_local = to_local(wi, _rows(self.s, rows), _rows(self.t, rows), _rows(self.n, rows))
        f = eval_bsdf(p, wo, wi_local, RADIANCE)
        if self.ng is not None:
            transmit = crosses_surface(p, wo, wi_local)
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
                self.eta_squared(smp), smp.lobe)

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
    # Final renders run two units per batch: about a third fewer NumPy calls per sample, so
    # less time under the GIL, which is what the second worker thread waits for.
    batch_units = 2
    # ... walked in chunks of 32 k paths: arrays of 32 k rows stay nearer the core (on an Intel
    # Xeon VM, 2026-11-26, 131 k-row batches cost about 7 % more CPU per sample; BENCHMARKS.md).
    chunk_paths = 1 << 15

    def __init__(self, prep, settings):
        super().__init__(prep, settings)
        self.mis = MIS.from_settings(settings)
        # BSDF sampling alone never samples lights: skip NEE and its shadow rays altogether.
        self.use_nee = self.mis.samples_lights
        # A light tree chooses lights from the shading normal too: NEE and the MIS weights of
        # emitters found by rays must then see the same normal.
        self.normals = prep.lights.selector.point_dependent
        self.limits = BounceLimits.from_settings(settings)
        # Whether any surface lets a path pass straight through (a transparent component):
        # only then does a path keep its MIS state past the bounce that read it.
        self.passes_through = prep.material_transparency is not None

    def render_samples(self, stream, pixel_filter, counters):
        """Radiance of one camera path per entry of ``stream`` (finite, non-negative), in
        chunks of at most ``chunk_paths`` paths."""
        if self.chunk_paths is not None and len(stream) > self.chunk_paths:
            return render_in_chunks(self._render_chunk, stream, self.chunk_paths,
                                    pixel_filter, counters)
        return self._render_chunk(stream, pixel_filter, counters)

    def _render_chunk(self, stream, pixel_filter, counters):
        """:meth:`render_samples` of at most ``chunk_paths`` paths."""
        prep, limits = self.prep, self.limits
        n = len(stream)
        L = np.zeros((n, 3))
        counters.camera_samples += n
        o, d, tmax = camera_rays(prep, pixel_filter, stream)
        path = _Paths(n, o)
        # Film > Transparent: what of each camera sample reaches the background (alpha = 1 - it).
        transparency = np.zeros(n) if prep.scene.film_transparent else None

        for step in range(limits.steps):
            # Intersect, then add what the ray sees of emitters: world, lamps, emissive triangles.
            hits = intersect_by_class(prep.accel, o, d, tmax, path.vis)
            counters.rays += o.shape[0]
            stream.check_abort()  # and after the closest hits: a cancel waits for a stage
            _add_emitters(prep, L, path.beta, o, d, hits, path.rows_of, path.pdf_prev,
                          path.use_mis, path.camera_ray, self.mis, path.n_prev, path.o_mis,
                          path.t_mis)
            if transparency is not None:
                _add_transparency(transparency, path, hits)
            if not self.passes_through:
                # Read only by the emitters just added: the next segment sets it afresh, so
                # the compactions below need not carry it.
                path.forget_mis_state()

            # Compact to surface hits; degenerate triangles end the path, and so does the
            # transparent limit (that segment only gathered emission, Cycles' "terminate on
            # next surface").
            live = surface_hits(prep, hits)
            live = live[~path.stop_next[live]]
            if live.size == 0:
                break
            si = surface_interaction(prep, hits, d, live, keep_below=True)
            if live.size < len(path):
                stream.compact(live)
                path.take(live)
            # This bounce's numbers, all drawn up front in the order of their dimensions: the
            # BSDF lobe number also chooses the component of mixed materials before NEE needs it.
            # Numbers nothing reads are skipped, not drawn (a Lambert-only scene chooses no
            # lobe; roulette starts after rr_min_bounces): every number is a function of its
            # dimension, so the others keep their values.
            # One call for all (stream.next_slots: 1-D, 2-D, 1-D or skipped, 2-D, 1-D or skipped).
            stream.skip_to(DIMS_CAMERA + step * DIMS_PER_BOUNCE)
            u_sel, u_light, u_lobe, u_bsdf, u_rr = stream.next_slots(
                (1, 2, int(not prep.lambert_only), 2, int(roulette_at(self.settings, step))))
            shading = self._shading(si, hits, live, u_lobe)
            if self.use_nee:
                self._sample_lights(shading, si, path, u_sel, u_light, L, counters)
                stream.check_abort()
            if not self._scatter(shading, si, path, u_bsdf, u_rr, step, stream):
                break
            o, d, tmax = path.o, path.d, None  # bounce rays are unbounded

        # No NaN or Inf reaches the film: a non-finite estimate is dropped (counted as zero).
        bad = ~finite_rows(L)
        L[bad] = 0.0
        if transparency is not None:
            transparency = np.clip(np.nan_to_num(transparency, nan=0.0), 0.0, 1.0)
        return BatchOutput(np.maximum(L, 0.0), transparency=transparency)

    def _sample_lights(self, shading, si, path, u_sel, u_light, L, counters):
        """Stage *sample lights*: NEE with a (transparent) shadow ray, MIS against BSDF
        sampling, at the rows that still scatter (not delta-only, not finishing)."""
        nee = shading.nee_rows
        finishing = path.counts.finishing
        if finishing.any():
            mask = ~finishing if nee is None else ~finishing[nee]
            nee = np.nonzero(mask)[0] if nee is None else nee[mask]
        if nee is not None and nee.size == 0:
            return
        # Without transparent materials no shadow ray crosses a surface: no budget to count.
        budget = (0 if self.prep.material_transparency is None
                  else path.counts.shadow_budget(self.limits, nee))
        _next_event(self.prep, shading, si, nee, _rows(u_sel, nee), _rows(u_light, nee),
                    path.beta, L, path.rows_of, self.mis, counters, self.normals, budget)

    def _scatter(self, shading, si, path, u_bsdf, u_rr, step, stream):
        """Stage *sample BSDF + Russian roulette + compact*: the next segment of every path
        that goes on (``path.o``, ``path.d``); False when none does. Delta bounces are not
        MIS-weighted later; a pass through a transparent surface keeps the MIS state of the
        vertex before it."""
        wi, weight, pdf_b, delta, vis_next, through, eta_sq, lobe = shading.sample(u_bsdf)
        beta = path.beta * weight
        alive = (pdf_b > 0) & finite_rows(beta)
        # Finishing paths only pass through transparent surfaces (Cycles evaluates only
        # their transparent closures; choosing a component keeps that unbiased).
        alive &= through | ~path.counts.finishing
        if eta_sq is not None:
            path.eta_scale = eta_sq if path.eta_scale is None else path.eta_scale * eta_sq
        path.stop_next = path.counts.advance(lobe, through, self.limits)
        alive, path.beta = russian_roulette(beta, alive, u_rr, self.settings, step,
                                            path.eta_scale)
        keep = np.nonzero(alive)[0]
        if keep.size == 0:
            return False
        p, ng, prim, ns = si.p, si.ng, si.prim, si.ns if self.normals else None
        # Compact only when a path ended (after a bounce inside a closed room none does).
        if keep.size < alive.size:
            stream.compact(keep)
            path.take(keep)
            p, ng, prim = take_rows(p, keep), take_rows(ng, keep), prim[keep]
            ns = take_rows(ns, keep) if self.normals else None
            wi, pdf_b, delta, through = take_rows(wi, keep), pdf_b[keep], delta[keep], through[keep]
            vis_next = vis_next[keep]
        path.next_segment(self.prep.accel.offset_origin(p, ng, prim, wi), wi, pdf_b, delta,
                          through, vis_next, ns)
        return True

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


class _Paths:
    """State of a batch of camera paths, struct-of-arrays (rows of the live paths).

    ``rows_of`` maps them to the unit's samples; ``beta`` is the throughput; ``vis`` the
    object visibility class of their current ray and ``camera_ray`` whether it still is a
    camera ray (also after transparent passes). The MIS state (``pdf_prev``, ``use_mis``,
    ``n_prev``) belongs to the last vertex that scattered, at ``o_mis``, ``t_mis`` behind the
    current ray's origin ``o`` (0 unless the ray passed transparent surfaces). ``eta_scale``
    is the product of ``etap^2`` over refractions (None: none yet): Russian roulette looks at
    ``beta * eta_scale``, the throughput without radiance's ``1 / etap^2`` (pbrt-v4's
    etaScale), so a path inside glass is not killed for a factor that leaving undoes.
    ``counts`` are the bounce counts (:mod:`.bounces`), ``stop_next`` the paths whose next
    surface only adds emission.
    """

    def __init__(self, n, o):
        self.rows_of = np.arange(n)
        self.beta = np.ones((n, 3))
        self.vis = np.full(n, VIS_CAMERA, np.int32)
        self.camera_ray = np.ones(n, bool)
        self.pdf_prev = np.zeros(n)
        self.use_mis = np.zeros(n, bool)
        self.n_prev = None  # shading normals at the MIS origins (light tree only)
        self.o_mis, self.t_mis = o, np.zeros(n)
        self.eta_scale = None
        self.counts = BounceCounts(n)
        self.stop_next = np.zeros(n, bool)
        self.o = self.d = None

    def __len__(self):
        return self.rows_of.size

    def take(self, rows):
        """Keep the paths ``rows (k,)``."""
        self.rows_of, self.beta = self.rows_of[rows], take_rows(self.beta, rows)
        self.vis, self.camera_ray = self.vis[rows], self.camera_ray[rows]
        if self.pdf_prev is not None:
            self.pdf_prev, self.use_mis = self.pdf_prev[rows], self.use_mis[rows]
            self.o_mis, self.t_mis = take_rows(self.o_mis, rows), self.t_mis[rows]
        self.n_prev = None if self.n_prev is None else take_rows(self.n_prev, rows)
        self.eta_scale = None if self.eta_scale is None else self.eta_scale[rows]
        self.counts.take(rows)
        self.stop_next = self.stop_next[rows]

    def forget_mis_state(self):
        """Drop the MIS state (``pdf_prev``, ``use_mis``, ``n_prev``, ``o_mis``, ``t_mis``)
        until :meth:`next_segment` sets it again; only for scenes where no path passes
        through a surface (which would keep it)."""
        self.pdf_prev = self.use_mis = self.n_prev = self.o_mis = self.t_mis = None

    def next_segment(self, o, d, pdf_b, delta, through, vis_next, ns):
        """Start the next rays ``o, d (n, 3)`` from the vertices just sampled: ``through``
        rows passed a transparent surface and keep their kind and their MIS state."""
        if through.any():
            self.t_mis = np.where(through, np.einsum("ij,ij->i", o - self.o_mis, d), 0.0)
            self.o_mis = np.where(through[:, None], self.o_mis, o)
            self.pdf_prev = np.where(through, self.pdf_prev, pdf_b)
            self.use_mis = np.where(through, self.use_mis, ~delta)
            if ns is not None and self.n_prev is not None:
                ns = np.where(through[:, None], self.n_prev, ns)
            self.camera_ray = self.camera_ray & through
            self.vis = np.where(through, self.vis, vis_next)
        else:
            self.o_mis, self.t_mis = o, np.zeros(o.shape[0])
            self.pdf_prev, self.use_mis = pdf_b, ~delta
            self.camera_ray = np.zeros(o.shape[0], bool)
            self.vis = vis_next
        self.n_prev = ns
        self.o, self.d = o, d


# One work unit without a render loop (tests, one-off use); a render builds PathTracer once.


def _add_transparency(transparency, path, hits):
    """Stage *transparent film*: camera rays (also after transparent passes) that escaped add
    the mean of their throughput to their sample's ``transparency (N,)``, as Cycles'
    transparent background."""
    escaped = np.nonzero(~hits.hit & path.camera_ray)[0]
    if escaped.size:
        np.add.at(transparency, path.rows_of[escaped], take_rows(path.beta, escaped).mean(axis=1))


def _add_emitters(prep, L, beta, o, d, hits, rows_of, pdf_prev, use_mis, camera_ray, mis,
                  n_prev=None, o_mis=None, t_mis=None):
    """Stage *handle escaped + handle emission*, with camera rays (``camera_ray (n,)``: lamps
    show only if visible to the camera) and other rays handled apart; ``n_prev (n, 3)``: shading
    normals at the MIS origins ``o_mis (n, 3)``, for a light tree (None otherwise); ``t_mis
    (n,)``: how far behind ``o`` they lie (see :func:`.common.add_emitters_along_rays`)."""
    groups = ([(None, bool(camera_ray[0]))] if np.all(camera_ray == camera_ray[:1])
              else [(np.nonzero(camera_ray)[0], True), (np.nonzero(~camera_ray)[0], False)])
    transparent_film = prep.scene.film_transparent
    for rows, camera in groups:
        world = not (camera and transparent_film)
        if rows is None:
            add_emitters_along_rays(prep, L, beta, o, d, hits, rows_of, pdf_prev, use_mis,
                                    camera, mis, n_prev, o_mis, t_mis, world)
            continue
        sub = Hits(hits.prim[rows], hits.t[rows], hits.u[rows], hits.v[rows])
        add_emitters_along_rays(prep, L, beta[rows], o[rows], d[rows], sub, rows_of[rows],
                                pdf_prev[rows], use_mis[rows], camera, mis,
                                None if n_prev is None else n_prev[rows],
                                None if o_mis is None else o_mis[rows],
                                None if t_mis is None else t_mis[rows], world)


def _next_event(prep, shading, si, rows, u_sel, u_light, beta, L, rows_of, mis, counters,
                normals=False, budget=0):
    """Stage *sample lights* on the shading rows ``rows`` (None: every row): adds
    ``beta f Li T w / pdf`` to ``L``, ``T`` the transmittance of the shadow ray through
    transparent surfaces (at most ``budget (k,)`` of them, :mod:`.shadows`); ``normals``: the
    light selection also takes the shading normals (a light tree)."""
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
    counters.rays += cand.size
    rays = prep.accel.shadow_rays(take_rows(p, cand), take_rows(si.ng, cand_rows),
                                  si.prim[cand_rows], take_rows(wi, cand), dist[cand],
                                  take_rows(light_normal, cand))
    if prep.material_transparency is None:
        # Opaque scene: a shadow ray passes whole or not at all (transmittance 1 or 0).
        unblocked = np.nonzero(~prep.accel.occluded(*rays, VIS_SHADOW))[0]
        transmit = None
    else:
        transmit = shadow_transmittance(prep, *rays, np.broadcast_to(budget, ok.shape)[cand],
                                        counters, VIS_SHADOW)
        unblocked = np.nonzero(max_component(transmit) > 0)[0]
    vis, vis_rows = cand[unblocked], cand_rows[unblocked]
    pdf_vis = pdf_l[vis]
    w = mis.light_weight(pdf_vis, pdf_b[vis])
    if prep.lights.delta.any():
        # Delta lights cannot be found by BSDF sampling: their samples keep weight one.
        w = np.where(delta[vis], 1.0, w)
    contrib = take_rows(beta, vis_rows) * take_rows(f, vis) * take_rows(li, vis)
    if transmit is not None:
        contrib *= take_rows(transmit, unblocked)
    add_rows(L, rows_of[vis_rows], scaled(contrib, w / pdf_vis, out=contrib))


def _rows(a, rows):
    """``a[rows]``, or ``a`` itself when ``rows`` is None (every row: no copy)."""
    return a if rows is None else take_rows(a, rows)
