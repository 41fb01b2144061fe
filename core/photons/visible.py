"""Visible points: camera paths followed through specular chains to the first non-specular hit.

Both photon-mapping estimators look photons up where the camera path first meets a surface
that density estimation can handle (any BSDF that is not a pure delta: diffuse, glossy, rough
glass). Until then the path follows delta bounces (mirrors, smooth glass) as a path tracer
does, collecting the emitters it sees with weight one (nothing else could sample them: no
next-event estimation through a delta bounce). At the visible point the direct light is
estimated by next-event estimation (light sampling, weight one; the photons that arrive
straight from an emitter are then not used for this point). Transparent surfaces on the way
are passed straight through, not bounces (:mod:`.passes`), and the shadow rays of next-event
estimation cross them with their transmittance.

A :class:`VisiblePoints` keeps what evaluating the point's BSDF for a photon's direction
needs (:meth:`VisiblePoints.f`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera import camera_position
from ..integrators.common import (add_emitters_along_rays, add_rows, bends_normals,
                                  camera_rays, intersect_by_class, max_component, ray_class,
                                  shading_tangents, surface_hits, surface_interaction,
                                  take_rows, valid_reflection_normals, with_base_normals,
                                  with_bump_normals, with_coat_normals, coat_normals_in_front)
from ..integrators.shadows import shadow_transmittance
from ..materials.bsdf import KIND_DIFFUSE, RADIANCE, BSDFParams, eval_bsdf, sample_bsdf
from ..materials.frame import shading_frame, to_local, to_world
from ..materials.lower_view import lower_view_params, shaded_below, view_below
from ..sampling.mis import MIS
from ..scene import VIS_CAMERA, VIS_SHADOW
from .passes import lobe_numbers, pass_walk, transparent_limit

# Sample dimensions: 0-1 pixel filter, then per bounce the BSDF lobe, the BSDF direction 2-D,
# the light choice and the light point 2-D.
DIMS_CAMERA = 2
DIMS_PER_BOUNCE = 6
# Solid angle -> area: photons arriving at grazing angles to the geometry are dropped below it.
MIN_COS = 1e-4


@dataclass
class VisiblePoints:
    """Non-specular camera-path hits of a batch, struct-of-arrays (``k`` of ``n`` paths).

    Attributes
    ----------
    rows : (k,) int64
        Path (stream entry) of each point.
    p, ng : (k, 3) float64
        Position and unit geometric normal.
    frame : tuple of three (k, 3) float64
        Shading frame (s, t, n) the BSDF is evaluated in.
    wo_local : (k, 3) float64
        Direction back toward the camera, in the frame.
    params : core.materials.bsdf.BSDFParams
        The BSDF (one chosen component of mixed materials).
    beta : (k, 3) float64
        Camera-path throughput up to the point (the specular chain's).
    bounces : (k,) int64
        Specular bounces before the point (0: seen directly).
    prim : (k,) int64
        Triangle of each point.
    dist : (k,) float64
        Length of the path from its start (the pinhole) to the point, through the specular
        chain (the pixel-footprint radius of :mod:`core.integrators.sppm` scales with it).
    passed : (k,) int32
        Transparent surfaces the path passed straight through before the point (:mod:`.passes`).
    """

    rows: np.ndarray
    p: np.ndarray
    ng: np.ndarray
    frame: tuple
    wo_local: np.ndarray
    params: BSDFParams
    beta: np.ndarray
    bounces: np.ndarray
    prim: np.ndarray = None
    dist: np.ndarray = None
    passed: np.ndarray = None

    def take(self, idx):
        """The points ``idx`` (index array or slice) as a new :class:`VisiblePoints`."""
        return VisiblePoints(self.rows[idx], self.p[idx], self.ng[idx],
                             tuple(a[idx] for a in self.frame), self.wo_local[idx],
                             self.params.take(idx), self.beta[idx], self.bounces[idx],
                             None if self.prim is None else self.prim[idx],
                             None if self.dist is None else self.dist[idx],
                             None if self.passed is None else self.passed[idx])

    def f(self, idx, wi):
        """BSDF value ``f(wo, wi)`` (no cosine) of the points ``idx (m,)`` for unit world
        directions ``wi (m, 3)`` toward where photons came from: ``f |cos_s| / |cos_g|``,
        what turns photon flux per area into reflected radiance with shading normals."""
        s, t, n = (take_rows(a, idx) for a in self.frame)
        wi_l = to_local(wi, s, t, n)
        fc = eval_bsdf(self.params.take(idx), take_rows(self.wo_local, idx), wi_l, RADIANCE)
        cos_g = np.abs(np.einsum("ij,ij->i", take_rows(self.ng, idx), wi))
        ok = cos_g > MIN_COS
        return fc * np.where(ok, 1.0 / np.where(ok, cos_g, 1.0), 0.0)[:, None]


def _frame(prep, si, params):
    """The visible points' frames and ``params``, as the path tracer's: around the shading
    normal on ``ng``'s front, bent for the view on glossy rows where the material allows
    (:func:`..integrators.common.valid_reflection_normals`; layered rows keep their base
    around the unbent normal)."""
    tangent = shading_tangents(prep, si)
    if prep.scene.corner_normals is None:
        return shading_frame(si.ng, tangent), params
    ns = si.ns
    glossy = (params.kind != KIND_DIFFUSE) & bends_normals(prep.scene, si.prim)
    if glossy.any():
        ns = np.where(glossy[:, None], valid_reflection_normals(si.ng, si.wo, ns), ns)
    front = np.where(np.einsum("ij,ij->i", ns, si.ng) < 0, -1.0, 1.0)
    frame = shading_frame(ns * front[:, None], tangent)
    return frame, with_base_normals(params, si.ns * front[:, None], frame)


def trace_visible_points(prep, stream, pixel_filter, max_bounces, counters, direct,
                         transparent=None, transparency=None):
    """Stage *visible points*: one camera path per entry of ``stream``.

    Parameters
    ----------
    prep : core.prepare.PreparedScene
    stream : core.sampling.stream.SampleStream
    pixel_filter : core.film.PixelFilter
    max_bounces : int
        Specular bounces allowed before the visible point.
    counters : core.integrators.base.Counters
    direct : (n, 3) float64
        Receives the emission the paths see and the direct light at their visible points
        (next-event estimation).
    transparent : int or None
        The Transparent limit (:mod:`.passes`; None: the option's default).
    transparency : (n,) float64 or None
        On a transparent film (Film > Transparent): receives what of each camera sample
        reaches the background (the mean throughput of its camera rays that escape, straight
        or through transparent passes, as the path tracer's); the world they see is then not
        added to ``direct`` (it still lights the scene).

    Returns
    -------
    VisiblePoints
    """
    n = len(stream)
    o, d, tmax = camera_rays(prep, pixel_filter, stream)
    # Rays start at the near clipping plane: their length from the pinhole counts too.
    eye = camera_position(prep.scene.camera)
    return follow_specular(prep, stream, o, d, tmax, np.ones((n, 3)), np.arange(n),
                           np.full(n, VIS_CAMERA, np.int32), max_bounces, counters, direct,
                           start=np.linalg.norm(o - eye, axis=1), transparent=transparent,
                           transparency=transparency)


def follow_specular(prep, stream, o, d, tmax, beta, rows, vis, max_bounces, counters,
                    direct=None, dims=DIMS_CAMERA, start=None,
                    transparent=None, passed=None, transparency=None):
    """Follow rays through specular bounces to their first non-specular hits.

    Parameters
    ----------
    o, d : (m, 3) float64
        Rays of the stream entries ``rows (m,)``; ``tmax (m,)`` or None.
    beta : (m, 3) float64
        Their throughput.
    vis : (m,) int32
        Their object-visibility class (``VIS_CAMERA`` for camera rays).
    direct : (n, 3) float64 or None
        With an array: camera paths, which add the emitters they see (camera rays with the
        lamps' camera visibility) and the direct light at their visible points. None: rays
        whose light from emitters is estimated elsewhere (final gathering), which add neither.
    dims : int
        First sample dimension of bounce 0 (:data:`DIMS_PER_BOUNCE` per bounce).
    start : (m,) float64 or None
        Path length before the rays' origins (the points' ``dist`` adds it; None: zero).
    transparent : int or None
        The Transparent limit (None: the option's default); ``passed (m,)`` the passes the
        paths made before (None: none).
    transparency : (n,) float64 or None
        Camera paths on a transparent film (:func:`trace_visible_points`).
    """
    parts = []
    travelled = np.zeros(rows.size) if start is None else np.asarray(start, np.float64)
    transparent = transparent_limit(transparent)
    walk = pass_walk(prep, transparent, counters, rows.size, passed)
    for bounce in range(max_bounces + 1):
        hits = intersect_by_class(prep.accel, o, d, tmax, vis)
        counters.rays += rows.size
        seen = (None if direct is None
                else _emitters_seen(prep, direct, bounce == 0, transparency))
        if seen is not None:
            seen(rows, o, d, hits, beta)
        dim = dims + bounce * DIMS_PER_BOUNCE
        u_pass = None
        if walk is not None:  # straight through transparent surfaces (not bounces)
            hits, beta, u_pass = walk.resolve(bounce, rows, o, d, tmax, hits, beta, vis, stream,
                                              dim, seen)
        live = surface_hits(prep, hits)
        if live.size == 0:
            break
        si = surface_interaction(prep, hits, d, live, keep_below=True)
        rows, beta = rows[live], take_rows(beta, live)
        travelled = travelled[live] + hits.t[live]
        if walk is not None:
            walk.take(live)
        stream.skip_to(dim)
        u_lobe, u_bsdf = stream.next_1d()[rows], stream.next_2d()[rows]
        u_lobe = lobe_numbers(u_lobe, u_pass, live)
        u_sel, u_light = stream.next_1d()[rows], stream.next_2d()[rows]
        params, delta_only, u_lobe = prep.choose_bsdf(si.prim, u_lobe, hits.u[live],
                                                      hits.v[live])
        (fs, ft, fn), params = _frame(prep, si, params)
        wo_l = to_local(si.wo, fs, ft, fn)
        params = with_coat_normals(params, coat_normals_in_front(si), (fs, ft, fn))
        if prep.scene.corner_normals is not None:
            # A smooth normal the view falls below is kept and shaded as the path tracer does
            # (Cycles' rule, core.materials.lower_view): such rows are no longer specular.
            below = view_below(np.einsum("ij,ij->i", si.wo, si.ng), wo_l[:, 2])
            delta_only = delta_only & ~shaded_below(params, below)
            params, wo_l = lower_view_params(params, wo_l, below)
        params = with_bump_normals(params, si, (fs, ft, fn))
        vp = np.nonzero(~delta_only)[0]
        if vp.size:
            point = VisiblePoints(rows[vp], si.p[vp], si.ng[vp], (fs[vp], ft[vp], fn[vp]),
                                  wo_l[vp], params.take(vp), beta[vp],
                                  np.full(vp.size, bounce, np.int64), si.prim[vp],
                                  travelled[vp],
                                  np.zeros(vp.size, np.int32) if walk is None
                                  else walk.passed[vp])
            if direct is not None:
                _direct_light(prep, point, u_sel[vp], u_light[vp], direct, counters,
                              transparent)
            parts.append(point)
        # Specular rows bounce on (the BSDF sample of a delta lobe is the only direction).
        spec = np.nonzero(delta_only)[0]
        if spec.size == 0 or bounce == max_bounces:
            break
        smp = sample_bsdf(params.take(spec), wo_l[spec], u_lobe[spec], u_bsdf[spec], RADIANCE)
        wi = to_world(smp.wi, fs[spec], ft[spec], fn[spec])
        beta = beta[spec] * smp.weight
        ok = np.nonzero((smp.pdf > 0) & (max_component(beta) > 0)
                        & np.isfinite(beta).all(axis=1))[0]
        rows, beta, wi, spec = rows[spec][ok], beta[ok], wi[ok], spec[ok]
        travelled = travelled[spec]
        if walk is not None:
            walk.take(spec)
        o = prep.accel.offset_origin(si.p[spec], si.ng[spec], si.prim[spec], wi)
        d, tmax = wi, None
        vis = ray_class(smp.lobe[ok])
    return join_points(parts)


def _emitters_seen(prep, direct, camera, transparency=None):
    """``fn(rows, o, d, hits, beta)`` adding to ``direct`` the emitters a segment of the
    camera paths ``rows`` sees (weight one: nothing else samples light seen directly or through
    specular bounces); ``camera``: the segments are camera rays. On a transparent film camera
    rays that escape add the mean of their throughput to ``transparency`` instead of the
    world's light."""
    no_mis = MIS("power")  # never consulted: every weight here is one (use_mis false)
    clear = camera and prep.scene.film_transparent

    def seen(rows, o, d, hits, beta):
        add_emitters_along_rays(prep, direct, beta, o, d, hits, rows, np.zeros(rows.size),
                                np.zeros(rows.size, bool), camera, no_mis, world=not clear)
        if clear and transparency is not None:
            escaped = np.nonzero(~hits.hit)[0]
            np.add.at(transparency, rows[escaped], take_rows(beta, escaped).mean(axis=1))
    return seen


def _direct_light(prep, point, u_sel, u_light, direct, counters, transparent):
    """Stage *sample lights* at the visible points: ``beta f Li T / pdf`` into ``direct``,
    ``T`` the shadow ray's transmittance through transparent surfaces (at most
    ``transparent`` minus the point's passes)."""
    wi, dist, li, pdf_l, _, light_normal = prep.lights.sample(point.p, u_sel, u_light, counters)
    s, t, n = point.frame
    fc = eval_bsdf(point.params, point.wo_local, to_local(wi, s, t, n), RADIANCE)
    ok = np.nonzero((pdf_l > 0) & (max_component(fc) > 0) & (max_component(li) > 0))[0]
    if ok.size == 0:
        return
    budget = np.maximum(int(transparent) - point.passed[ok], 0)
    through = shadow_transmittance(prep, *prep.accel.shadow_rays(
        point.p[ok], point.ng[ok], point.prim[ok], wi[ok], dist[ok], light_normal[ok]),
        budget, counters, VIS_SHADOW)
    counters.rays += ok.size
    add_rows(direct, point.rows[ok],
             point.beta[ok] * fc[ok] * li[ok] * through / pdf_l[ok][:, None])


def join_points(parts):
    """One :class:`VisiblePoints` of ``parts`` in order (empty if there are none)."""
    if not parts:
        z3 = np.zeros((0, 3))
        return VisiblePoints(np.zeros(0, np.int64), z3, z3, (z3, z3, z3), z3,
                             BSDFParams(np.zeros(0, np.int32), z3, np.ones(0), np.ones(0), z3),
                             z3, np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0),
                             np.zeros(0, np.int32))
    cat = np.concatenate
    return VisiblePoints(
        cat([p.rows for p in parts]), cat([p.p for p in parts]), cat([p.ng for p in parts]),
        tuple(cat([p.frame[i] for p in parts]) for i in range(3)),
        cat([p.wo_local for p in parts]),
        BSDFParams.concat([p.params for p in parts]),
        cat([p.beta for p in parts]), cat([p.bounces for p in parts]),
        cat([p.prim for p in parts]), cat([p.dist for p in parts]),
        cat([p.passed for p in parts]))
