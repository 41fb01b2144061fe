"""Bidirectional path tracing: every connection strategy (s, t), combined by MIS.

What it estimates
    The same pixel measurement as :mod:`.path`. For each sample it traces a camera subpath
    ``z_0 (camera), z_1, ...`` and a light subpath ``y_0 (on an emitter), y_1, ...`` and forms
    every path of ``k`` segments from ``s`` light and ``t`` camera vertices, ``s + t = k + 1``:
    ``s = 0`` (the camera subpath hits an emitter), ``s = 1`` (a fresh point on an emitter is
    connected to ``z_{t-1}``: next-event estimation), ``s >= 2, t >= 2`` (``y_{s-1}`` is
    connected to ``z_{t-1}`` by a shadow ray) and ``t = 1`` (``y_{s-1}`` is connected to the
    pinhole and splatted onto the film where it lands; ``s = 1, t = 1`` connects the light
    subpath's point on an emitter to the pinhole, so small lamps seen directly are not left
    to camera rays alone).
Bias and consistency
    Unbiased for paths of up to ``max_bounces + 1`` scattering vertices, as the path tracer.
    MIS weights are computed from each path's per-vertex densities, in area measure (solid angle
    toward infinite emitters), as Veach's ratio recurrence (pbrt's ``MISWeight``): the weights of
    all strategies that can make a path sum to one for every heuristic, so every setting of
    ``mis_heuristic`` is unbiased: ``balance``, ``power`` (``mis_beta``), ``maximum``,
    ``cutoff`` (``mis_alpha``), or ``none`` (every strategy that can make the path gets the same
    weight). Strategies next to a delta BSDF vertex, and ``s = 0`` for delta lights, cannot make
    a path and get weight zero; so do strategies whose density is zero.
    Densities used for MIS ignore Russian roulette, and light points for ``s = 1`` are sampled
    by area (not by solid angle as the path tracer's ``solid_angle`` setting does).
Parameters
    ``max_bounces``, ``use_russian_roulette``, ``rr_min_bounces``, ``mis_heuristic``,
    ``mis_beta``, ``mis_alpha``; light selection and the world's importance map as
    :class:`core.lights.LightSampler`; ``strategy_views`` and ``strategy_max_length`` write one
    image per strategy (its own estimate, and its MIS-weighted share).
Limitations
    Perspective cameras only (light subpaths must be able to reach the film). Object ray
    visibility is honoured for camera rays and shadow rays; light subpath rays trace every
    object. Soft Falloff point lights are rendered as spheres, and sphere lights shine on
    points inside them only through ``s <= 1`` strategies (:mod:`core.lights.emission`).
Render region
    A region is rendered as a smaller film: camera subpaths start in the region's pixels only,
    each with its one light subpath as in a full render (so the region costs its share of the
    time), and ``t = 1`` connections are made only toward film positions whose splats reach a
    region pixel (the window plus the filter's reach). Splats are divided by the light subpaths
    traced, so each is still an unbiased estimate; MIS weights use the density of camera rays
    over the region (``1 / (A_region cos^3)``), the sample counts this render really has. Camera
    strategies give the same samples as the full render's pixels; the light strategies have
    ``region / frame`` as many light paths behind each pixel, so pixels that light paths
    dominate (caustics) are noisier than in a full-frame render of the same ``spp``.
When to use it
    Caustics (small lights seen through glass or mirrors on diffuse receivers) and scenes lit
    indirectly, where camera paths rarely find the light and light paths rarely find the
    camera but connections between them do.

Stages: generate camera subpath (with ``s = 0`` emission) -> generate light subpath ->
connect ``s = 1`` -> connect ``s, t >= 2`` -> connect ``t = 1`` (splat).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..camera import camera_pdf, camera_position, importance, project
from ..materials.bsdf import IMPORTANCE, RADIANCE, BSDFParams, eval_bsdf, pdf_bsdf, sample_bsdf
from ..materials.frame import shading_frame, to_local, to_world
from ..sampling.mis import MIS
from ..scene import VIS_CAMERA, VIS_SHADOW
from .base import BatchOutput, Integrator, Splats
from .common import (camera_rays, geometric_side_valid, intersect_by_class, max_component,
                     ray_class, russian_roulette, strategy_pass_names, surface_interaction)

# Paths per chunk: keeps the subpath arrays (depth x paths) small.
CHUNK = 8192
# Sample dimensions: 0-1 pixel filter; per camera vertex: BSDF lobe, BSDF 2-D, roulette, light
# selection, light point 2-D (for s = 1); then the light subpath: selection, point 2-D,
# direction 2-D, and per light vertex: lobe, BSDF 2-D, roulette.
DIMS_CAMERA = 2
DIMS_PER_CAMERA_VERTEX = 7
DIMS_LIGHT_START = 5
DIMS_PER_LIGHT_VERTEX = 4


def _dot(a, b):
    return np.einsum("ij,ij->i", a, b)


def _empty_params(n):
    return BSDFParams(np.zeros(n, np.int32), np.zeros((n, 3)), np.ones(n), np.ones(n),
                      np.zeros((n, 3)))


def _scatter_params(dst, rows, src):
    dst.kind[rows] = src.kind
    dst.color[rows] = src.color
    dst.alpha[rows] = src.alpha
    dst.eta[rows] = src.eta
    dst.tint[rows] = src.tint


@dataclass
class Subpath:
    """Vertices of a batch of subpaths, depth-major: arrays of shape ``(D, n, ...)``.

    Vertex 0 is the endpoint (the pinhole, or the point on the emitter); vertices ``1..D-1``
    are surface hits. ``pdf_fwd`` is the density with which the subpath's own sampling made
    the vertex, ``pdf_rev`` the density with which the other side would make it (known once
    the next vertex is sampled); both are in area measure, solid angle for infinite light
    endpoints, and one next to a delta vertex (the discrete choices cancel in MIS ratios).
    ``d_prev`` and ``cos_prev`` are the distance to the previous vertex and the cosine there
    (along the edge, geometric normal; one for points, the pinhole and infinite endpoints),
    used to turn solid-angle densities at this vertex into area densities at the previous one.
    """

    valid: np.ndarray
    p: np.ndarray
    ng: np.ndarray
    prim: np.ndarray
    fs: np.ndarray
    ft: np.ndarray
    fn: np.ndarray
    wo: np.ndarray
    wo_local: np.ndarray
    params: list
    connectible: np.ndarray
    delta: np.ndarray
    beta: np.ndarray
    pdf_fwd: np.ndarray
    pdf_rev: np.ndarray
    d_prev: np.ndarray
    cos_prev: np.ndarray

    @staticmethod
    def empty(depth, n):
        z3 = lambda: np.zeros((depth, n, 3))  # noqa: E731
        return Subpath(np.zeros((depth, n), bool), z3(), z3(), np.zeros((depth, n), np.int64),
                       z3(), z3(), z3(), z3(), z3(), [None] * depth,
                       np.zeros((depth, n), bool), np.zeros((depth, n), bool), z3(),
                       np.zeros((depth, n)), np.zeros((depth, n)), np.full((depth, n), np.inf),
                       np.ones((depth, n)))


class _Context:
    """What the stages of one chunk share: the integrator's per-render constants, this
    batch's counters and the light subpaths' endpoints once sampled."""

    def __init__(self, integrator, counters, emission, pixel_filter):
        self.prep = integrator.prep
        self.settings = integrator.settings
        self.counters = counters
        self.emission = emission
        self.cam = integrator.cam
        self.cam_pos = integrator.cam_pos
        self.smooth = integrator.smooth
        self.mis = integrator.mis
        self.weighs = integrator.weighs
        self.view_length = integrator.view_length
        # Light paths reach edge pixels through the filter's reach outside the image.
        self.film_margin = 0.5 * pixel_filter.support
        self.window = integrator.window
        self.film_pixels = integrator.film_pixels
        self.light_points = None  # the light subpaths' endpoints, once sampled


# ------------------------------------------------------------------------------------ BSDFs
class _Gathered:
    """Vertex ``j`` of a subpath for the rows of one connection: what evaluating its BSDF
    needs, gathered once (parameters, shading frame, incoming direction)."""

    def __init__(self, ctx, sub, j, rows, mode):
        self.smooth, self.mode = ctx.smooth, mode
        self.params = sub.params[j].take(rows)
        self.fs, self.ft, self.fn = sub.fs[j, rows], sub.ft[j, rows], sub.fn[j, rows]
        self.wo, self.wo_l, self.ng = sub.wo[j, rows], sub.wo_local[j, rows], sub.ng[j, rows]

    def take(self, idx):
        """The rows ``idx`` of this gather (after shadow rays removed some)."""
        out = object.__new__(_Gathered)
        out.smooth, out.mode = self.smooth, self.mode
        out.params = self.params.take(idx)
        for name in ("fs", "ft", "fn", "wo", "wo_l", "ng"):
            setattr(out, name, getattr(self, name)[idx])
        return out

    def local(self, w):
        """World directions ``w (m, 3)`` in the vertices' shading frames."""
        return to_local(w, self.fs, self.ft, self.fn)

    def f(self, w, w_l):
        """``f |cos|`` toward ``w`` (world) / ``w_l`` (local), with the geometric-side rule and,
        in importance mode, the shading-normal correction (Veach 5.3)."""
        f = eval_bsdf(self.params, self.wo_l, w_l, self.mode)
        if self.smooth:
            f *= _smooth_factor(self.ng, self.fn, self.wo, w, self.wo_l, w_l, self.mode)[:, None]
        return f

    def pdf_toward(self, w_l):
        """Solid-angle density of sampling ``w_l`` given the incoming direction."""
        return pdf_bsdf(self.params, self.wo_l, w_l)

    def pdf_back(self, w_l):
        """Solid-angle density of sampling the incoming direction given ``w_l``."""
        return pdf_bsdf(self.params, w_l, self.wo_l)


def _smooth_factor(ng, ns, wo, wi, wo_l, wi_l, mode):
    transmit = wo_l[:, 2] * wi_l[:, 2] < 0
    ok = geometric_side_valid(ng, wo, wi, transmit).astype(np.float64)
    if mode == IMPORTANCE:
        num = np.abs(_dot(wo, ns)) * np.abs(_dot(wi, ng))
        den = np.abs(_dot(wo, ng)) * np.abs(_dot(wi, ns))
        ok *= np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
    return ok


def _to_area(pdf_sa, cos_at, dist):
    """Solid-angle density -> area density at a point ``dist`` away (cosine ``cos_at`` there);
    unchanged toward infinite endpoints (``dist = inf``)."""
    finite = np.isfinite(dist)
    d2 = np.where(finite, dist * dist, 1.0)
    return np.where(finite, pdf_sa * np.abs(cos_at) / np.maximum(d2, 1e-300), pdf_sa)


# ------------------------------------------------------------------------------------ MIS
def strategy_weight(mis, p_light, p_camera, delta, s, delta_light, direct=None):
    """MIS weight ``(m,)`` of strategy ``s`` for paths of ``k + 1`` vertices ``x_0..x_k``.

    Parameters
    ----------
    mis : core.sampling.mis.MIS
        The render's heuristic (not a single-strategy setting).
    p_light, p_camera : list of k + 1 arrays (m,)
        ``p_light[i]``: density with which the light side makes ``x_i`` (from ``x_{i-1}``;
        ``x_0``'s: the emitter's origin density); ``p_camera[i]``: the same from the camera
        side (``x_k`` is the pinhole). The density of strategy ``s'`` is
        ``prod_{i < s'} p_light[i] * prod_{i >= s'} p_camera[i]``; only ratios are formed.
    delta : list of k + 1 arrays (m,) bool
        Vertices scattered by a delta lobe: strategies connecting at them are impossible.
    s : int
        The strategy that made the paths (light vertices used).
    delta_light : (m,) bool
        ``x_0`` is a point or a directional delta light: ``s' = 0`` is impossible.
    direct : (m,) bool or None
        For ``k = 1`` (an emitter seen directly): whether ``s' = 1, t' = 1`` (a point on the
        emitter connected to the pinhole) can make the path: finite emitters seen by the camera,
        not infinite ones. None: it cannot.

    Notes
    -----
    Strategies ``s' = 0..k`` (``t' = k + 1 - s' >= 1``).
    """
    k = len(p_light) - 1
    m = delta_light.shape[0]
    ratio = [None] * (k + 1)
    ratio[s] = np.ones(m)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for sp in range(s - 1, -1, -1):
            num, den = p_camera[sp], p_light[sp]
            ratio[sp] = np.where(den > 0, ratio[sp + 1] * num / np.where(den > 0, den, 1.0), 0.0)
        for sp in range(s + 1, k + 1):
            num, den = p_light[sp - 1], p_camera[sp - 1]
            ratio[sp] = np.where(den > 0, ratio[sp - 1] * num / np.where(den > 0, den, 1.0), 0.0)
    terms, valid = [], []
    for sp in range(k + 1):
        if sp == 0:
            ok = ~delta_light
        elif sp == k:
            if k >= 2:
                ok = ~delta[k - 1]
            else:
                ok = np.zeros(m, bool) if direct is None else np.asarray(direct, bool)
        else:
            ok = ~delta[sp - 1] & ~delta[sp]
        if sp == s:
            ok = np.ones(m, bool)
        r = np.nan_to_num(ratio[sp], nan=0.0, posinf=np.inf)
        valid.append(ok & (r > 0))
        terms.append(np.where(ok, r, 0.0))
    w = mis.weight(np.stack(terms), s, np.stack(valid))
    return np.where(np.isfinite(w), w, 0.0)


# ------------------------------------------------------------------------------------ walks
def _walk(ctx, sub, o, d, tmax, beta, pdf_prev, prev_delta, vis, rows, stream, mode, dims_of,
          depth, on_segment=None):
    """Stage *random walk*: extend ``sub`` from vertex 0 with the rays ``o, d`` of ``rows``.

    Vertices ``1..depth-1`` are made. ``pdf_prev (m,)`` is the solid-angle density of the first
    ray (the disk's area density for infinite light endpoints, whose ``d_prev`` is inf),
    ``prev_delta`` whether it came from a delta lobe, ``beta (m, 3)`` its throughput. With
    ``on_segment(j, rows, o, d, hits, beta, pdf_prev, prev_delta)`` (the camera side, for ``s = 0``)
    one more segment is traced after the last vertex, for the emitters it finds.
    """
    prep, settings = ctx.prep, ctx.settings
    n = sub.valid.shape[1]
    last = depth + int(on_segment is not None)
    for j in range(1, last):
        hits = intersect_by_class(prep.accel, o, d, tmax, vis)
        ctx.counters.rays += o.shape[0]
        if on_segment is not None:
            on_segment(j, rows, o, d, hits, beta, pdf_prev, prev_delta)
        if j == depth:
            break
        live = np.nonzero(hits.hit)[0]
        live = live[prep.tri_area[hits.prim[live]] > 0]
        if live.size == 0:
            break
        si = surface_interaction(prep, hits, d, live)
        r = rows[live]
        stream.skip_to(dims_of(j))
        u_lobe = stream.next_1d()[r]
        u_bsdf = stream.next_2d()[r]
        u_rr = stream.next_1d()[r]
        params, delta_only, u_lobe = prep.choose_bsdf(si.prim, u_lobe, hits.u[live],
                                                      hits.v[live])
        if ctx.smooth:
            front = np.where(_dot(si.ns, si.ng) < 0, -1.0, 1.0)
            fs, ft, fn = shading_frame(si.ns * front[:, None])
        else:
            fs, ft, fn = shading_frame(si.ng)
        wo_l = to_local(si.wo, fs, ft, fn)

        # Store vertex j; its forward density in area measure (times the cosine alone after an
        # infinite endpoint, whose rays are parallel).
        if j == 1:
            dist = np.linalg.norm(si.p - sub.p[0, r], axis=1)
            dist = np.where(np.isfinite(sub.d_prev[0, r]), dist, np.inf)
            sub.cos_prev[j, r] = sub.cos_prev[0, r]
        else:
            dist = hits.t[live]
            sub.cos_prev[j, r] = np.abs(_dot(sub.ng[j - 1, r], si.wo))
        cos_here = np.abs(_dot(si.ng, si.wo))
        fwd = np.where(np.isinf(dist), pdf_prev[live] * cos_here,
                       _to_area(pdf_prev[live], cos_here, dist))
        sub.valid[j, r] = True
        sub.p[j, r], sub.ng[j, r], sub.prim[j, r] = si.p, si.ng, si.prim
        sub.fs[j, r], sub.ft[j, r], sub.fn[j, r] = fs, ft, fn
        sub.wo[j, r], sub.wo_local[j, r] = si.wo, wo_l
        if sub.params[j] is None:
            sub.params[j] = _empty_params(n)
        _scatter_params(sub.params[j], r, params)
        sub.connectible[j, r] = ~delta_only
        sub.beta[j, r] = beta[live]
        sub.d_prev[j, r] = dist
        sub.pdf_fwd[j, r] = np.where(prev_delta[live], 1.0, fwd)
        if j == depth - 1 and on_segment is None:
            break

        # Sample the BSDF for the next vertex; the reverse density goes to vertex j - 1.
        smp = sample_bsdf(params, wo_l, u_lobe, u_bsdf, mode)
        wi = to_world(smp.wi, fs, ft, fn)
        weight = smp.weight
        if ctx.smooth:
            weight = weight * _smooth_factor(si.ng, fn, si.wo, wi, wo_l, smp.wi, mode)[:, None]
        back = _to_area(pdf_bsdf(params, smp.wi, wo_l), sub.cos_prev[j, r], dist)
        sub.pdf_rev[j - 1, r] = np.where(smp.delta, 1.0, back)
        sub.delta[j, r] = smp.delta
        beta = beta[live] * weight
        alive = (smp.pdf > 0) & np.isfinite(beta).all(axis=1)
        alive, beta = russian_roulette(beta, alive, u_rr, settings, j - 1)
        keep = np.nonzero(alive)[0]
        if keep.size == 0:
            break
        rows = r[keep]
        beta = beta[keep]
        o = prep.accel.offset_origin(si.p[keep], si.ng[keep], si.prim[keep], wi[keep])
        d = wi[keep]
        tmax = np.full(keep.size, np.inf)
        pdf_prev = smp.pdf[keep]
        prev_delta = smp.delta[keep]
        vis = ray_class(smp.lobe[keep])


class Tally:
    """What one batch's strategies add up to: the image (one value per camera sample), the
    light-path splats and, with strategy views of paths up to ``view_length`` segments, one
    image per strategy ``(s, t)``: its own estimate and its MIS-weighted share."""

    def __init__(self, n, view_length):
        self.image = np.zeros((n, 3))
        self.splats = []
        self.view_length = view_length  # 0: no strategy views
        self.camera_layers = {}
        self.splat_layers = {}

    def add(self, s, t, rows, value, weight):
        """Add strategy ``(s, t)``'s contributions to the camera samples ``rows``."""
        self.image[rows] += value * weight[:, None]
        if s + t - 1 <= self.view_length:
            key = f"Strategy s{s} t{t}"
            layers = self.camera_layers
            for name, v in ((key, value), (key + " weighted", value * weight[:, None])):
                if name not in layers:
                    layers[name] = np.zeros_like(self.image)
                layers[name][rows] += v

    def splat(self, s, xy, value, weight):
        """Add strategy ``(s, 1)``'s contributions at film positions ``xy``."""
        self.splats.append(Splats(xy, value * weight[:, None]))
        if s <= self.view_length:
            key = f"Strategy s{s} t1"
            for name, v in ((key, value), (key + " weighted", value * weight[:, None])):
                self.splat_layers.setdefault(name, []).append(Splats(xy, v))

    def output(self, light_paths):
        """The batch's :class:`BatchOutput`: no NaN, Inf or negative value in the image."""
        image = self.image
        image[~np.isfinite(image).all(axis=1)] = 0.0
        splats = Splats.join(self.splats)
        return BatchOutput(np.maximum(image, 0.0), Splats(splats.xy, np.maximum(splats.value, 0.0)),
                           light_paths,
                           {name: np.where(np.isfinite(v), v, 0.0)
                            for name, v in self.camera_layers.items()},
                           {name: Splats.join(parts) for name, parts in self.splat_layers.items()})


# ------------------------------------------------------------------------------------ s = 0
def _camera_emission(ctx, cam_sub, out):
    """``on_segment`` of the camera walk: emitters along the segment from vertex ``j - 1``
    (strategy ``s = 0, t = j + 1``), MIS-weighted against the strategies that connect."""
    prep, em = ctx.prep, ctx.emission
    ls = prep.lights

    def handle(j, rows, o, d, hits, beta, pdf_prev, prev_delta):
        found = []  # (local rows, emitter index, point, normal, distance)
        n = rows.size
        escaped = np.nonzero(~hits.hit)[0]
        if escaped.size:
            if ls.has_world:
                found.append((escaped, np.full(escaped.size, ls.world_index),
                              np.zeros((escaped.size, 3)), np.zeros((escaped.size, 3)),
                              np.full(escaped.size, np.inf)))
            for li in ls.infinite_lamps(camera=j == 1):
                found.append((escaped, np.full(escaped.size, li), np.zeros((escaped.size, 3)),
                              np.zeros((escaped.size, 3)), np.full(escaped.size, np.inf)))
        found += _lamp_hits(ctx, o, d, hits.t, j == 1)
        hit_rows = np.nonzero(hits.hit)[0]
        if hit_rows.size and ls.emissive_tris.size:
            e = ls.tri_emitter[hits.prim[hit_rows]]
            sel = e >= 0
            if sel.any():
                lr = hit_rows[sel]
                prim = hits.prim[lr]
                q = (prep.tri_v0[prim] + hits.u[lr][:, None] * prep.tri_e1[prim]
                     + hits.v[lr][:, None] * prep.tri_e2[prim])
                found.append((lr, e[sel], q, prep.tri_normal[prim], hits.t[lr]))
        for lr, index, q, normal, t in found:
            if lr.size == 0:
                continue
            r = rows[lr]
            w_travel = -d[lr]
            receiver = cam_sub.p[j - 1, r]
            value = beta[lr] * em.radiance(index, q, normal, w_travel, receiver)
            ok = max_component(value) > 0
            if not ok.any():
                continue
            lr, index, q, normal, t, r, value = (lr[ok], index[ok], q[ok], normal[ok], t[ok],
                                                 r[ok], value[ok])
            if not ctx.weighs:
                weight = np.ones(lr.size)  # light tracing sees emitters through the camera
            else:
                if j == 1:  # distances from the pinhole, not from the near clipping plane
                    t = np.where(np.isfinite(t), np.linalg.norm(q - ctx.cam_pos, axis=1), t)
                weight = _s0_weight(ctx, cam_sub, j, r, index, q, normal, t, -d[lr],
                                    pdf_prev[lr], prev_delta[lr])
            out.add(0, j + 1, r, value, weight)

    return handle


def _lamp_hits(ctx, o, d, tmax, camera):
    """Points where rays meet lamp shapes (spheres, area lights) before ``tmax``:
    a list of ``(rows, emitter index, point, normal, distance)`` (see
    :meth:`core.lights.LightSampler.lamp_points`)."""
    return ctx.prep.lights.lamp_points(o, d, tmax, camera)


def _s0_weight(ctx, cam, j, r, index, q, normal, t, w_travel, pdf_prev, prev_delta):
    """MIS weight of emitters found by the camera subpath's segment from ``z_{j-1}``."""
    em = ctx.emission
    k = j
    m = r.size
    infinite = em.is_infinite(index)
    p_light = [None] * (k + 1)
    p_camera = [None] * (k + 1)
    delta = [np.zeros(m, bool) for _ in range(k + 1)]
    p_light[0] = em.pdf_origin(index, w_travel)
    cos_l = np.where(infinite, 1.0, np.abs(_dot(normal, w_travel)))
    p_camera[0] = np.where(prev_delta, 1.0, _to_area(pdf_prev, cos_l, t))
    # The emitter makes z_{j-1} by its direction density.
    cos_z = np.abs(_dot(cam.ng[j - 1, r], w_travel))
    pdf_dir = em.pdf_direction(index, normal, w_travel)
    p_light[1] = np.where(infinite, pdf_dir * cos_z, _to_area(pdf_dir, cos_z, t))
    for i in range(1, k + 1):
        zi = k - i
        p_camera[i] = cam.pdf_fwd[zi, r] if zi > 0 else np.ones(m)
        if i >= 2:
            p_light[i] = cam.pdf_rev[zi, r] if zi > 0 else np.ones(m)
        if 0 < zi:
            delta[i] = cam.delta[zi, r]
    delta_light = np.zeros(m, bool)
    return strategy_weight(ctx.mis, p_light, p_camera, delta, 0, delta_light, direct=~infinite)


# ------------------------------------------------------------------------------------ connect
def _connect(ctx, L, C, s, t, out, fresh=None):
    """Strategies ``s >= 1, t >= 2``: light vertex ``s - 1`` (or the fresh emitter point for
    ``s = 1``) joined to camera vertex ``t - 1`` by a shadow ray."""
    prep, em = ctx.prep, ctx.emission
    zj = t - 1
    if s == 1:
        rows = np.nonzero(C.valid[zj] & C.connectible[zj] & (fresh.index >= 0))[0]
    else:
        yj = s - 1
        rows = np.nonzero(C.valid[zj] & C.connectible[zj] & L.valid[yj] & L.connectible[yj])[0]
    if rows.size == 0:
        return
    z = C.p[zj, rows]
    if s == 1:
        infinite = fresh.infinite[rows]
        index = fresh.index[rows]
        y = fresh.p[rows]
        to_y = np.where(infinite[:, None], -fresh.w_inf[rows], y - z)
    else:
        y = L.p[s - 1, rows]
        infinite = np.zeros(rows.size, bool)
        to_y = y - z
    dist = np.where(infinite, np.inf, np.linalg.norm(to_y, axis=1))
    ok = (dist > 0)
    w = to_y / np.where(infinite, 1.0, np.maximum(dist, 1e-300))[:, None]  # z -> y
    zv = _Gathered(ctx, C, zj, rows, RADIANCE)
    w_z = zv.local(w)
    f_z = zv.f(w, w_z)
    yv = w_y = None
    if s == 1:
        normal = fresh.normal[rows]
        le = em.radiance(index, y, normal, -w, z)
        point = fresh.delta_light[rows] & ~infinite
        cos_y = np.where(infinite | point, 1.0, np.abs(_dot(normal, w)))
        f_y = le * cos_y[:, None]
        beta_y = 1.0 / np.where(fresh.pdf_origin[rows] > 0, fresh.pdf_origin[rows], np.inf)
        value = f_y * f_z * C.beta[zj, rows] * beta_y[:, None]
    else:
        yv = _Gathered(ctx, L, s - 1, rows, IMPORTANCE)
        w_y = yv.local(-w)
        f_y = yv.f(-w, w_y)
        value = L.beta[s - 1, rows] * f_y * f_z * C.beta[zj, rows]
    g = np.where(infinite, 1.0, 1.0 / np.maximum(np.where(infinite, 1.0, dist) ** 2, 1e-300))
    value = value * g[:, None]
    ok &= (max_component(value) > 0) & np.isfinite(value).all(axis=1)
    cand = np.nonzero(ok)[0]
    if cand.size == 0:
        return
    if s == 1:
        y_normal = np.where(infinite[cand, None], 0.0, fresh.normal[rows[cand]])
    else:
        y_normal = L.ng[s - 1, rows[cand]]
    blocked = prep.accel.occluded(*prep.accel.shadow_rays(
        z[cand], C.ng[zj, rows[cand]], C.prim[zj, rows[cand]], w[cand], dist[cand], y_normal),
        VIS_SHADOW)
    ctx.counters.rays += cand.size
    keep = cand[~blocked]
    if keep.size == 0:
        return
    conn = {"w": w[keep], "dist": dist[keep], "infinite": infinite[keep],
            "y_normal": y_normal[~blocked], "z": zv.take(keep), "w_z": w_z[keep]}
    if s == 1:
        conn["index"] = index[keep]
    else:
        conn["y"], conn["w_y"] = yv.take(keep), w_y[keep]
    weight = _connect_weight(ctx, L, C, s, t, rows[keep], conn, fresh)
    out.add(s, t, rows[keep], value[keep], weight)


def _connect_weight(ctx, L, C, s, t, rows, conn, fresh):
    """MIS weight of a connection ``y = x_{s-1}`` (light side) -> ``z = x_s`` (camera side).

    ``conn`` holds the connection's ``w`` (from z to y, world), ``dist``, ``infinite``,
    ``y_normal``, the gathered camera vertex ``z`` and ``w`` in its frame ``w_z``; and either
    the emitter ``index`` (``s = 1``) or the gathered light vertex ``y`` and ``-w`` in its frame
    ``w_y``.
    """
    em = ctx.emission
    k = s + t - 1
    m = rows.size
    zj = t - 1
    w, dist, infinite, y_normal = conn["w"], conn["dist"], conn["infinite"], conn["y_normal"]
    zv, w_z = conn["z"], conn["w_z"]
    p_light = [None] * (k + 1)
    p_camera = [None] * (k + 1)
    delta = [np.zeros(m, bool) for _ in range(k + 1)]
    cos_z = np.abs(_dot(zv.ng, w))
    # Light side: stored densities up to y, then y -> z, then z -> z_{t-2}.
    if s == 1:
        p_light[0] = fresh.pdf_origin[rows]
        cos_y = np.where(infinite | fresh.delta_light[rows], 1.0, np.abs(_dot(y_normal, w)))
        pdf_dir = em.pdf_direction(conn["index"], y_normal, -w)
        p_light[1] = np.where(infinite, pdf_dir * cos_z, _to_area(pdf_dir, cos_z, dist))
        delta_light = fresh.delta_light[rows]
    else:
        yv, w_y = conn["y"], conn["w_y"]
        for i in range(s):
            p_light[i] = L.pdf_fwd[i, rows]
            if 0 < i < s - 1:
                delta[i] = L.delta[i, rows]
        cos_y = np.abs(_dot(y_normal, w))
        p_light[s] = _to_area(yv.pdf_toward(w_y), cos_z, dist)
        delta_light = ctx.light_points.delta_light[rows]
    if zj >= 2:
        p_light[s + 1] = _to_area(zv.pdf_back(w_z), C.cos_prev[zj, rows], C.d_prev[zj, rows])
    for i in range(s + 2, k + 1):
        zi = k - i
        p_light[i] = C.pdf_rev[zi, rows] if zi > 0 else np.ones(m)
    # Camera side: stored densities down to z, then z -> y, then y -> y_{s-2}.
    for i in range(s, k + 1):
        zi = k - i
        p_camera[i] = C.pdf_fwd[zi, rows] if zi > 0 else np.ones(m)
        if s < i < k:
            delta[i] = C.delta[zi, rows]
    pdf_zy = zv.pdf_toward(w_z)
    p_camera[s - 1] = np.where(infinite, pdf_zy, _to_area(pdf_zy, cos_y, dist))
    if s >= 2:
        p_camera[s - 2] = _to_area(yv.pdf_back(w_y), L.cos_prev[s - 1, rows],
                                   L.d_prev[s - 1, rows])
        for i in range(s - 2):
            p_camera[i] = L.pdf_rev[i, rows]
    return strategy_weight(ctx.mis, p_light, p_camera, delta, s, delta_light)


def _connect_camera(ctx, L, s, out):
    """Strategy ``t = 1``: light vertex ``s - 1`` seen by the pinhole, splatted."""
    prep, cam = ctx.prep, ctx.cam
    yj = s - 1
    rows = np.nonzero(L.valid[yj] & L.connectible[yj])[0]
    if rows.size == 0:
        return
    film_xy, visible, cos_theta, dist = project(cam, L.p[yj, rows], ctx.film_margin, ctx.window)
    seen = np.nonzero(visible)[0]
    if seen.size == 0:
        return
    rows, film_xy, cos_theta, dist = rows[seen], film_xy[seen], cos_theta[seen], dist[seen]
    y = L.p[yj, rows]
    w = (ctx.cam_pos - y) / np.maximum(dist, 1e-300)[:, None]  # y -> camera
    yv = _Gathered(ctx, L, yj, rows, IMPORTANCE)
    w_y = yv.local(w)
    we = importance(cam, cos_theta)
    value = L.beta[yj, rows] * yv.f(w, w_y) * (we / np.maximum(dist * dist, 1e-300))[:, None]
    ok = (max_component(value) > 0) & np.isfinite(value).all(axis=1)
    cand = np.nonzero(ok)[0]
    if cand.size == 0:
        return
    o, dirs, tmax = prep.accel.shadow_rays(y[cand], yv.ng[cand], L.prim[yj, rows[cand]],
                                           w[cand], dist[cand], np.zeros((cand.size, 3)))
    blocked = prep.accel.occluded(o, dirs, tmax, VIS_CAMERA)
    ctx.counters.rays += cand.size
    keep = cand[~blocked]
    if keep.size == 0:
        return
    rows, w, w_y, dist, value, film_xy, cos_theta = (rows[keep], w[keep], w_y[keep], dist[keep],
                                                     value[keep], film_xy[keep], cos_theta[keep])
    if not ctx.weighs:
        weight = np.ones(rows.size)
    else:
        yv = yv.take(keep)
        k = s
        m = rows.size
        p_light = [L.pdf_fwd[i, rows] for i in range(s)] + [np.ones(m)]
        delta = [np.zeros(m, bool)] + [L.delta[i, rows] for i in range(1, s - 1)] + [
            np.zeros(m, bool), np.zeros(m, bool)]
        p_camera = [None] * (k + 1)
        p_camera[k] = np.ones(m)
        pdf_cam = camera_pdf(cam, cos_theta, ctx.film_pixels)
        p_camera[s - 1] = _to_area(pdf_cam, np.abs(_dot(yv.ng, w)), dist)
        p_camera[s - 2] = _to_area(yv.pdf_back(w_y), L.cos_prev[yj, rows], L.d_prev[yj, rows])
        for i in range(s - 2):
            p_camera[i] = L.pdf_rev[i, rows]
        weight = strategy_weight(ctx.mis, p_light, p_camera, delta, s,
                                 ctx.light_points.delta_light[rows])
    out.splat(s, film_xy, value, weight)


def _connect_emitter_to_camera(ctx, L, out):
    """Strategy ``s = 1, t = 1``: the light subpath's point on a (finite, camera-visible)
    emitter seen by the pinhole, splatted; MIS against the camera ray that hits it."""
    prep, cam, em = ctx.prep, ctx.cam, ctx.emission
    pts = ctx.light_points
    ls = prep.lights
    lamp = (pts.index >= 0) & (pts.index < ls.n_lights)
    seen_by_camera = np.where(lamp, ls.lights.visible_camera[np.where(lamp, pts.index, 0)]
                              if ls.n_lights else False, True)
    rows = np.nonzero((pts.index >= 0) & ~pts.infinite & ~pts.delta_light & seen_by_camera
                      & (pts.pdf_origin > 0))[0]
    if rows.size == 0:
        return
    p = pts.p[rows]
    film_xy, visible, cos_theta, dist = project(cam, p, ctx.film_margin, ctx.window)
    seen = np.nonzero(visible)[0]
    if seen.size == 0:
        return
    rows, p, film_xy, cos_theta, dist = (rows[seen], p[seen], film_xy[seen], cos_theta[seen],
                                         dist[seen])
    w = (ctx.cam_pos - p) / np.maximum(dist, 1e-300)[:, None]  # emitter -> camera
    normal = pts.normal[rows]
    le = em.radiance(pts.index[rows], p, normal, w, np.broadcast_to(ctx.cam_pos, p.shape))
    cos_l = np.abs(_dot(normal, w))
    g = importance(cam, cos_theta) * cos_l / np.maximum(dist * dist, 1e-300)
    value = le * (g / pts.pdf_origin[rows])[:, None]
    ok = np.nonzero((max_component(value) > 0) & np.isfinite(value).all(axis=1))[0]
    if ok.size == 0:
        return
    rows, w, dist, value, film_xy, cos_theta, cos_l = (rows[ok], w[ok], dist[ok], value[ok],
                                                       film_xy[ok], cos_theta[ok], cos_l[ok])
    # From the pinhole toward the point, stopping just short of it (emissive triangles are
    # geometry; lamps are not).
    origins = np.broadcast_to(ctx.cam_pos, (rows.size, 3)).copy()
    blocked = prep.accel.occluded(origins, -w, dist * (1.0 - 1e-5), VIS_CAMERA)
    ctx.counters.rays += rows.size
    keep = np.nonzero(~blocked)[0]
    if keep.size == 0:
        return
    rows, dist, value, film_xy, cos_theta, cos_l = (rows[keep], dist[keep], value[keep],
                                                    film_xy[keep], cos_theta[keep], cos_l[keep])
    m = rows.size
    p_camera = [_to_area(camera_pdf(cam, cos_theta, ctx.film_pixels), cos_l, dist), np.ones(m)]
    p_light = [pts.pdf_origin[rows], np.ones(m)]
    weight = strategy_weight(ctx.mis, p_light, p_camera, [np.zeros(m, bool)] * 2, 1,
                             np.zeros(m, bool), direct=np.ones(m, bool))
    out.splat(1, film_xy, value, weight)


# ------------------------------------------------------------------------------------ driver
def _light_subpath(ctx, stream, n, base, depth):
    """Stage *generate light subpath*: emitter point and direction, then the random walk."""
    em, prep = ctx.emission, ctx.prep
    L = Subpath.empty(depth, n)
    stream.skip_to(base)
    u_sel = stream.next_1d()
    u_pos = stream.next_2d()
    u_dir = stream.next_2d()
    pts = em.sample_points(u_sel, u_pos, ctx.counters)
    origin, w, pdf_dir, cos_l, le = em.sample_directions(pts, u_dir)
    ctx.light_points = pts
    L.valid[0] = pts.index >= 0
    L.p[0] = np.where(pts.infinite[:, None], origin, pts.p)
    L.ng[0] = pts.normal
    L.pdf_fwd[0] = pts.pdf_origin
    L.cos_prev[0] = np.where(pts.infinite | pts.delta_light, 1.0, cos_l)
    L.d_prev[0] = np.where(pts.infinite, np.inf, 0.0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        beta = le * (cos_l / (pts.pdf_origin * pdf_dir))[:, None]
    good = (pts.index >= 0) & (pdf_dir > 0) & (pts.pdf_origin > 0) & np.isfinite(beta).all(1)
    rows = np.nonzero(good)[0]
    rows = rows[max_component(beta[rows]) > 0]
    if depth < 2 or rows.size == 0:
        return L
    # Rays leave lamps (not geometry) from the point itself, emissive triangles pushed off.
    o = origin[rows]
    k = prep.lights.n_lights
    tri = np.nonzero((pts.index[rows] >= k) & ~pts.infinite[rows])[0]
    if tri.size:
        prim = prep.lights.emissive_tris[pts.index[rows][tri] - k]
        o[tri] = prep.accel.offset_origin(o[tri], pts.normal[rows][tri], prim, w[rows][tri])
    _walk(ctx, L, o, w[rows], np.full(rows.size, np.inf), beta[rows], pdf_dir[rows],
          np.zeros(rows.size, bool), np.full(rows.size, VIS_SHADOW, np.int32), rows, stream,
          IMPORTANCE, lambda j: base + DIMS_LIGHT_START + (j - 1) * DIMS_PER_LIGHT_VERTEX,
          depth)
    return L


def _camera_subpath(ctx, pixel_filter, stream, n, depth, out):
    """Stage *generate camera subpath*, adding the emitters it finds (``s = 0``) to ``out``."""
    prep, cam = ctx.prep, ctx.cam
    C = Subpath.empty(depth, n)
    o, d, tmax = camera_rays(prep, pixel_filter, stream)
    C.valid[0] = True
    C.p[0] = ctx.cam_pos
    C.d_prev[0] = 0.0
    C.beta[0] = 1.0
    m = np.asarray(cam.to_world, np.float64)
    axis = -m[:3, 2] / np.linalg.norm(m[:3, 2])
    pdf_cam = camera_pdf(cam, d @ axis, ctx.film_pixels)
    _walk(ctx, C, o, d, tmax, np.ones((n, 3)), pdf_cam, np.zeros(n, bool),
          np.full(n, VIS_CAMERA, np.int32), np.arange(n), stream, RADIANCE,
          lambda j: DIMS_CAMERA + (j - 1) * DIMS_PER_CAMERA_VERTEX, depth,
          _camera_emission(ctx, C, out))
    return C


class Bidirectional(Integrator):
    """The estimators built from a camera and a light subpath per sample (light tracing and
    BDPT): subpaths, the strategies every one of them uses (emitters seen by the camera
    subpath, ``s = 0``; light vertices seen by the pinhole, ``t = 1``), and the chunking.

    A subclass says how many camera vertices it traces (:meth:`camera_depth`), whether it
    weighs its strategies by MIS (``weighs``) and which strategies it adds
    (:meth:`connect`).
    """

    splats = True
    weighs: ClassVar[bool] = True

    def __init__(self, prep, settings):
        super().__init__(prep, settings)
        self.cam = prep.scene.camera
        if self.cam.type != "PERSP":
            raise ValueError("light tracing and BDPT need a perspective camera "
                             "(an orthographic camera cannot be reached from the lights)")
        self.cam_pos = camera_position(self.cam)
        self.smooth = prep.scene.corner_normals is not None
        self.mis = MIS.from_settings(settings)
        self.view_length = (int(settings.strategy_max_length)
                            if self.strategy_views and settings.strategy_views else 0)
        if self.view_length:
            self.layers = tuple(strategy_pass_names(self.view_length))
        # A render region is a smaller film: splats outside it are not traced, and camera rays
        # are drawn over its pixels only (their density, for MIS, is over the region's area).
        self.window = settings.region
        self.film_pixels = (None if self.window is None else
                            (self.window[2] - self.window[0]) * (self.window[3] - self.window[1]))

    def camera_depth(self, depth):
        """Vertices of the camera subpaths when light subpaths have ``depth``."""
        return depth

    def connect(self, ctx, stream, C, L, out):
        """Strategies beyond ``s = 0`` and ``t = 1``: none here."""

    def render_samples(self, stream, pixel_filter, counters):
        """Image contributions of one sample (a camera and a light subpath) per entry of
        ``stream``, in chunks of at most ``CHUNK`` paths."""
        n = len(stream)
        if n > CHUNK:
            parts = []
            for start in range(0, n, CHUNK):
                part = copy.copy(stream)
                part.compact(np.arange(start, min(start + CHUNK, n)))
                parts.append(self.render_samples(part, pixel_filter, counters))
            return BatchOutput.join(parts)
        prep, settings = self.prep, self.settings
        emission = prep.emission  # built by core.prepare.prepare
        ctx = _Context(self, counters, emission, pixel_filter)
        counters.camera_samples += n
        depth = settings.max_bounces + 2  # vertices per subpath (endpoint included)
        out = Tally(n, ctx.view_length)
        C = _camera_subpath(ctx, pixel_filter, stream, n, self.camera_depth(depth), out)
        base = DIMS_CAMERA + (depth + 1) * DIMS_PER_CAMERA_VERTEX
        L = _light_subpath(ctx, stream, n, base, depth)
        self.connect(ctx, stream, C, L, out)
        for s in range(2, depth + 1):
            if not L.valid[s - 1].any():
                break
            _connect_camera(ctx, L, s, out)
        return out.output(n)


class BDPT(Bidirectional):
    """Bidirectional path tracing (see the module docstring)."""

    # A BDPT sample costs 5-16 path-tracing samples, so units are smaller than the path
    # tracer's to keep cancel and progress within a second (a call has ~0.1 s of fixed Python
    # cost, so much smaller units would be slower).
    unit_paths = 1 << 13
    strategy_views = True

    def connect(self, ctx, stream, C, L, out):
        """Strategies ``s >= 1, t >= 2`` (a fresh emitter point for ``s = 1``), then
        ``s = 1, t = 1``."""
        depth = C.valid.shape[0]
        for t in range(2, depth + 1):
            zj = t - 1
            if not C.valid[zj].any():
                break
            # s = 1: a fresh point on an emitter for every camera vertex.
            stream.skip_to(DIMS_CAMERA + (zj - 1) * DIMS_PER_CAMERA_VERTEX + 4)
            u_sel = stream.next_1d()
            u_pos = stream.next_2d()
            fresh = ctx.emission.sample_points(u_sel, u_pos, ctx.counters)
            _connect(ctx, L, C, 1, t, out, fresh)
            for s in range(2, depth + 2 - t):
                if not L.valid[s - 1].any():
                    break
                _connect(ctx, L, C, s, t, out)
        _connect_emitter_to_camera(ctx, L, out)


render_samples = BDPT.one_batch
# Read by addon/cli.py until it asks integrator_class(name).strategy_views.
HAS_STRATEGY_VIEWS = BDPT.strategy_views
