"""Connection strategies of the bidirectional estimators: light vertices (or fresh points on
emitters) joined to camera vertices (``s >= 1, t >= 2``, :func:`connect_all`, all lengths in
batches), light vertices seen by the pinhole and splatted (``t = 1``, :func:`connect_camera`
for stored subpaths, :func:`camera_splatter` during a light walk that stores none, both
through :func:`splat_vertices`), and a point on an emitter seen by the pinhole (``s = 1,
t = 1``, :func:`connect_emitter_to_camera`). Each traces its shadow rays and adds its
MIS-weighted contributions to the batch's :class:`.strategy_views.Tally`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..allocator import keeps_freed
from ..camera import importance, project
from ..lights.emission import EmitterPoints
from ..materials.bsdf import IMPORTANCE, RADIANCE
from ..rows import at_least_tiny, divide_rows, norms, scaled
from ..scene import VIS_CAMERA, VIS_SHADOW
from .common import bends_normals, finite_rows, max_component, nonzero_rows, take_rows
from .lambert_vertices import LambertVertices, all_lambert, gatherer
from .mis_densities import (Near, connection_weight, direct_weight, splat_weight,
                            splat_weights)
from .mis_sums import RunningSums, summable
from .subpaths import Gathered, dot, take_params, to_area
from .transparent_passes import connection_budget, has_passes, transmitted

# Connections joined per batch of array operations (see _in_pieces). Each of a piece's
# NumPy calls has a fixed cost of about a microsecond: 32,768-row pieces made the stage 4-11 %
# cheaper per camera sample than 8,192-row ones where freed batch memory is kept for reuse (as
# renders do, core.allocator), at 0.8 MB per (m, 3) column (65,536 rows: slower again on a
# worker thread); where it is not kept, large arrays fault fresh pages in and SMALL_PIECE is
# faster (docs/BENCHMARKS.md, eighth round).
PIECE = 1 << 15
SMALL_PIECE = 1 << 13


class Fresh(NamedTuple):
    """Points on emitters for strategy ``s = 1`` (fresh samples, or the light subpaths' first
    vertices: ``bdpt.LIGHT_POINTS``), one per connection: the camera
    vertex ``zj (m,)`` of subpath ``row (m,)`` each is joined to, and the points
    (:class:`core.lights.emission.EmitterPoints` of ``m`` rows)."""

    zj: np.ndarray
    row: np.ndarray
    points: object


class _Joined(NamedTuple):
    """Connections that passed their shadow rays: strategies, rows, values and the densities
    their MIS weights need besides the stored ones (the columns of a :class:`Near`)."""

    s: np.ndarray
    t: np.ndarray
    row: np.ndarray
    value: np.ndarray
    light_0: np.ndarray
    light_s: np.ndarray
    light_s1: np.ndarray
    camera_s1: np.ndarray
    camera_s2: np.ndarray
    delta_light: np.ndarray


def connect_all(ctx, L, C, fresh, out):
    """Strategies ``s >= 1, t >= 2`` of every path length, in one batch each for ``s = 1``
    (the points ``fresh``, a :class:`Fresh`) and ``s >= 2`` (light vertex ``s - 1`` joined to
    camera vertex ``t - 1`` by a shadow ray): one gather per vertex, one BSDF evaluation,
    one batch of shadow rays for all of them. MIS weights and contributions follow strategy by
    strategy, by ``t`` then ``s`` (the order of a loop over strategies)."""
    gather = gatherer(ctx, L, C)
    parts = [*_connect_emitters(ctx, L, C, fresh, gather), *_connect_vertices(ctx, L, C, gather)]
    if not parts:
        return
    runs = _strategy_runs(parts)
    weights = _connection_weights(ctx, L, C, parts, runs)
    for s, t, i, e in runs:
        out.add(s, t, parts[i].row[e], parts[i].value[e], weights[i][e])


def _strategy_runs(parts):
    """``(s, t, i, e)`` of every run ``e`` (a slice) of one strategy in piece ``parts[i]``
    (each piece is in strategy order already: the emitters' by ``t``, the vertex pairs' by
    ``t`` then ``s``), all in strategy order: no sort or gather of the pieces' rows. A
    strategy's runs may come from several pieces; each adds to distinct camera samples, so
    the sums are those of one run per strategy."""
    runs = []
    for i, p in enumerate(parts):
        runs += [(int(p.s[e.start]), int(p.t[e.start]), i, e)
                 for e in _runs(p.t * (int(p.s.max()) + 1) + p.s)]
    runs.sort(key=lambda r: (r[1], r[0], r[2]))
    return runs


def _connection_weights(ctx, L, C, parts, runs):
    """MIS weights of the connections of ``parts`` (a list of :class:`_Joined`; one ``(m,)``
    array each): by the subpaths' running sums in one pass over them all (:mod:`.mis_sums`),
    or strategy by strategy (the ``runs`` of :func:`_strategy_runs`) for the heuristics that
    compare with the largest density."""
    if summable(ctx.mis):
        # Piece by piece: the weights are row-wise (the same values); joining the pieces' nine
        # columns first copied them all for a fifth of the stage's time.
        sums = RunningSums(ctx.mis, L, C, ctx.light_points.delta_light)
        return [sums.weights(L, C, p.s, p.t, p.row, _near(p)) for p in parts]
    weights = [np.empty(p.row.size) for p in parts]
    for s, t, i, e in runs:
        weights[i][e] = connection_weight(ctx.mis, L, C, s, t, parts[i].row[e],
                                          Near(*(c[e] for c in _near(parts[i]))))
    return weights


def _near(part):
    """The :class:`Near` densities of a :class:`_Joined` piece, in float64 (float32 Lambert
    ends form some in float32; the weights read them beside the subpaths' float64 tables, and
    operations on mixed types cost more than on either)."""
    return Near(*(c.astype(np.float64) if c.dtype == np.float32 else c for c in part[4:]))


def _vertex_pairs(depth):
    """``(zj, yj)`` of every strategy ``s = yj + 1 >= 2, t = zj + 1 >= 2`` of paths up to
    ``depth`` segments, by ``t`` then ``s``."""
    return np.array([(zj, yj) for zj in range(1, depth) for yj in range(1, depth - zj)],
                    np.int64).reshape(-1, 2)


def _connect_vertices(ctx, L, C, gather):
    """Strategies ``s >= 2, t >= 2``: every connectible light vertex joined to every
    connectible camera vertex of its sample (paths of at most ``depth`` segments), their ends
    gathered by ``gather`` (:func:`.lambert_vertices.gatherer`); a list of :class:`_Joined`
    pieces."""
    pairs = _vertex_pairs(C.valid.shape[0])
    both = (C.valid & C.connectible)[pairs[:, 0]] & (L.valid & L.connectible)[pairs[:, 1]]
    pair, row = nonzero_rows(both)
    return _in_pieces(lambda e: _join_vertices(ctx, L, C, pairs[pair[e], 0], pairs[pair[e], 1],
                                               row[e], gather), row.size)


def _in_pieces(join, m):
    """``join(e)`` of the connections ``e`` (a slice), ``PIECE`` at a time (``SMALL_PIECE``
    unless :func:`core.allocator.keeps_freed`): the list of the :class:`_Joined` pieces, in
    order (pieces bound the stage's memory; fewer, larger pieces make fewer NumPy calls)."""
    piece = PIECE if keeps_freed() else SMALL_PIECE
    parts = [join(slice(a, min(a + piece, m))) for a in range(0, m, piece)]
    return [p for p in parts if p is not None]


def _join_vertices(ctx, L, C, zj, yj, row, gather):
    """Light vertices ``yj (m,)`` joined to camera vertices ``zj (m,)`` of samples ``row``."""
    n = C.valid.shape[1]
    at_z, at_y = zj * n + row, yj * n + row
    z = take_rows(C.flat("p"), at_z)
    w = take_rows(L.flat("p"), at_y) - z
    dist = norms(w)
    np.divide(w, at_least_tiny(dist)[:, None], out=w)  # z -> y (float32 positions: float32)
    zv = gather(C, at_z, RADIANCE)
    w_z = zv.local(w)
    f_z, toward_z, back_z = zv.values(w, w_z)
    # Where the camera vertex scatters nothing toward y the path has no value (zero, or NaN,
    # which is dropped as well): its light side is not gathered.
    e = np.nonzero(max_component(f_z) > 0)[0]
    at_y, dist_e = at_y[e], dist[e]
    w_y = take_rows(w, e)
    np.negative(w_y, out=w_y)  # y -> z
    yv = gather(L, at_y, IMPORTANCE)
    w_yl = yv.local(w_y)
    f_y, toward_y, back_y = yv.values(w_y, w_yl)
    value = take_rows(L.flat("beta"), at_y)
    value *= f_y
    value *= take_rows(f_z, e)
    value *= take_rows(C.flat("beta"), at_z[e])
    scaled(value, 1.0 / at_least_tiny(dist_e ** 2), out=value)
    budget = (connection_budget(ctx.settings.transparent_max_bounces,
                                C.flat("passed")[at_z[e]], L.flat("passed")[at_y])
              if has_passes(ctx.prep) else None)  # not read where all is opaque
    kept = _unblocked(ctx, C, at_z, z, zv.ng, w, dist, yv.ng, value, dist_e > 0, budget, e,
                      _thinner(ctx, value, row, zj, yj, e))
    if kept.size == 0:
        return None
    keep = e[kept]
    d2 = np.square(dist[keep])
    # The cosines at both ends (of y -> z at y: the densities take their absolute values).
    cos_z, cos_y = zv.cos_ng(w, w_z, keep), yv.cos_ng(w_y, w_yl, kept)
    yj, zj, row, at_y = yj[keep], zj[keep], row[keep], at_y[kept]
    return _Joined(yj + 1, zj + 1, row, take_rows(value, kept), L.pdf_fwd[0].take(row),
                   _finite_area(toward_y[kept], cos_z, d2),
                   _reverse_at_z(C, back_z[keep], zj, row),
                   _finite_area(toward_z[keep], cos_y, d2),
                   to_area(back_y[kept], L.cos_prev.take(at_y), L.d_prev.take(at_y)),
                   ctx.light_points.delta_light[row])


def _thinner(ctx, value, row, zj, yj=None, e=None):
    """``thin(cand)`` for :func:`_unblocked`: the Connection Roulette
    (:mod:`.connection_roulette`) of the connections whose values are ``value (m, 3)``,
    camera vertex ``zj`` joined to light vertex ``yj`` (None: a fresh emitter point, ``s =
    1``) of samples ``row``, those arrays' rows ``e`` (None: all); None where it is off."""
    roulette = ctx.roulette
    if roulette is None:
        return None
    if e is not None:
        row, zj, yj = row[e], zj[e], yj[e]
    keys = (zj + 1) * 1024 + (1 if yj is None else yj + 1)  # one code per strategy (s, t)
    return lambda cand: roulette.thin(value, cand, row[cand], keys[cand])


def _finite_area(pdf_sa, cos_at, d2):
    """:func:`.subpaths.to_area` of a finite distance whose square is ``d2`` (the same
    values, without its tests for infinite ones)."""
    return pdf_sa * np.abs(cos_at) / at_least_tiny(d2)


def _connect_emitters(ctx, L, C, fresh, gather):
    """Strategy ``s = 1``: the fresh points on emitters joined to their camera vertices (a
    list of :class:`_Joined` pieces)."""
    if fresh is None:
        return []
    return _in_pieces(lambda e: _join_emitters(
        ctx, L, C, fresh.zj[e], fresh.row[e], EmitterPoints(*(a[e] for a in fresh.points)),
        gather), fresh.row.size)


def _join_emitters(ctx, L, C, zj, row, pts, gather):
    """Points ``pts`` on emitters joined to camera vertices ``zj (m,)`` of samples ``row``."""
    em = ctx.emission
    n = C.valid.shape[1]
    at_z = zj * n + row
    z = take_rows(C.flat("p"), at_z)
    infinite = pts.infinite
    zv = gather(C, at_z, RADIANCE)
    f32 = zv.ng.dtype == np.float32 and not infinite.any()
    if f32:  # float32 Lambert ends (.lambert_vertices) toward points: the values in float32
        pts = pts._replace(p=pts.p.astype(np.float32), normal=pts.normal.astype(np.float32))
    w, dist, y_normal, g = _toward_emitters(pts, z)
    w_z = zv.local(w)
    le = em.radiance(pts.index, pts.p, pts.normal, -w, z)
    point = pts.delta_light & ~infinite
    cos_y = np.where(infinite | point, 1.0, np.abs(dot(pts.normal, w)))
    beta_y = 1.0 / np.where(pts.pdf_origin > 0, pts.pdf_origin, np.inf)
    if f32:
        le, beta_y = le.astype(np.float32), beta_y.astype(np.float32)
    f_z, toward_z, back_z = zv.values(w, w_z)
    value = scaled(le, cos_y) * f_z * take_rows(C.flat("beta"), at_z)
    scaled(value, beta_y, out=value)
    scaled(value, g, out=value)
    budget = (connection_budget(ctx.settings.transparent_max_bounces, C.flat("passed")[at_z])
              if has_passes(ctx.prep) else None)  # not read where all is opaque
    keep = _unblocked(ctx, C, at_z, z, zv.ng, w, dist, y_normal, value, dist > 0, budget,
                      thin=_thinner(ctx, value, row, zj))
    if keep.size == 0:
        return None
    cos_z = np.abs(zv.cos_ng(w, w_z, keep))
    w, dist = take_rows(w, keep), dist[keep]
    zj, row = zj[keep], row[keep]
    infinite, cos_y, index = infinite[keep], cos_y[keep], pts.index[keep]
    pdf_dir = em.pdf_direction(index, take_rows(y_normal, keep), -w)
    pdf_zy = toward_z[keep]
    return _Joined(np.ones(keep.size, np.int64), zj + 1, row, take_rows(value, keep),
                   pts.pdf_origin[keep],
                   np.where(infinite, pdf_dir * cos_z, to_area(pdf_dir, cos_z, dist)),
                   _reverse_at_z(C, back_z[keep], zj, row),
                   np.where(infinite, pdf_zy, to_area(pdf_zy, cos_y, dist)),
                   np.ones(keep.size), pts.delta_light[keep])


def _toward_emitters(pts, z):
    """From camera vertices ``z (m, 3)`` toward the emitter points ``pts``: unit directions
    ``(m, 3)``, distances ``(m,)`` (inf toward infinite emitters), the points' normals
    ``(m, 3)`` (zero at infinite emitters) and the geometry's ``1 / d^2`` ``(m,)`` (one toward
    infinite emitters). Where no point is on an infinite emitter, the general form's values
    in fewer operations."""
    infinite = pts.infinite
    if not infinite.any():
        w = pts.p - z
        dist = norms(w)
        np.divide(w, at_least_tiny(dist)[:, None], out=w)
        return w, dist, pts.normal, 1.0 / at_least_tiny(dist ** 2)
    to_y = np.where(infinite[:, None], -pts.w_inf, pts.p - z)
    dist = np.where(infinite, np.inf, norms(to_y))
    w = to_y / np.where(infinite, 1.0, np.maximum(dist, 1e-300))[:, None]  # z -> y
    g = np.where(infinite, 1.0, 1.0 / np.maximum(np.where(infinite, 1.0, dist) ** 2, 1e-300))
    return w, dist, np.where(infinite[:, None], 0.0, pts.normal), g


def _reverse_at_z(C, back_z, zj, row):
    """The light side's area density of ``z_{t-2}``, sampled at ``z = z_{t-1}`` from the
    solid-angle density ``back_z (m,)`` (``t >= 3``; unused, and one, for ``t = 2``)."""
    at = zj * C.valid.shape[1] + row  # flat takes: the values of C.cos_prev[zj, row]
    return np.where(zj >= 2, to_area(back_z, C.cos_prev.take(at), C.d_prev.take(at)),
                    1.0)


def _unblocked(ctx, C, at_z, z, z_ng, w, dist, y_normal, value, ok, budget, ends=None,
               thin=None):
    """Connections ``(k,)`` (indices) with a contribution whose shadow ray gets through
    (through at most ``budget (k,)`` transparent surfaces, whose transparency then scales
    their rows of ``value (k, 3)`` in place, :mod:`.transparent_passes`; None where every
    surface is opaque). Connection ``i`` leaves camera end ``ends[i]`` (None: ``i``): the
    rows of ``at_z``, ``z``, its geometric normals ``z_ng``, the directions ``w`` and the
    distances ``dist``, which are gathered here for the rays only. ``thin(cand)``: the
    survivors of the Connection Roulette among the candidates (:func:`_thinner`; None: all)."""
    ok = ok & (max_component(value) > 0) & finite_rows(value)
    cand = ok.nonzero()[0]
    if thin is not None:
        cand = thin(cand)
    if cand.size == 0:
        return cand
    end = cand if ends is None else ends[cand]
    through, transmit = transmitted(ctx, *ctx.prep.accel.shadow_rays(
        take_rows(z, end), take_rows(z_ng, end), C.flat("prim")[at_z[end]], take_rows(w, end),
        dist[end], take_rows(y_normal, cand)), None if budget is None else budget[cand],
        VIS_SHADOW)
    ctx.counters.rays += cand.size
    if transmit is not None:
        value[cand[through]] *= transmit
    return cand[through]


def connect_camera(ctx, L, s, out):
    """Strategy ``t = 1``: light vertex ``s - 1`` seen by the pinhole, splatted."""
    yj = s - 1
    rows = np.nonzero(L.valid[yj] & L.connectible[yj])[0]
    if rows.size == 0:
        return
    splat_vertices(ctx, s, rows, take_rows(L.p[yj], rows), L.prim[yj, rows],
                   _light_vertex_gather(ctx, L, yj, rows),
                   lambda seen: take_rows(L.beta[yj], rows[seen]), out, L,
                   connection_budget(ctx.settings.transparent_max_bounces, L.passed[yj, rows]))


def connect_cameras(ctx, L, out):
    """Strategy ``t = 1`` for every light vertex ``s - 1 >= 1`` of the stored subpaths ``L``
    at once: one projection, one gather, one batch of shadow rays for every depth (MIS weights
    and splats depth by depth). The same splats, in the same order, as :func:`connect_camera`
    for ``s = 2, 3, ...``; where some depths hold only plain Lambert vertices and others do
    not (their vertices are gathered differently), it is that loop."""
    depth, n = L.valid.shape
    reach = L.valid[1:] & L.connectible[1:]
    lambert = [all_lambert(ctx.smooth, (L,), yj) for yj in range(1, depth)]
    if any(lambert) and not all(lambert):
        for s in range(2, depth + 1):
            connect_camera(ctx, L, s, out)
        return
    level, rows = nonzero_rows(reach)  # depth-major: the loop's order
    if rows.size == 0:
        return
    at = (level + 1) * n + rows
    # The rows ``seen`` of ``at`` for the gather and the throughputs: ``at`` itself where
    # every vertex is seen (no copies).
    at_seen = lambda seen: at if seen.size == at.size else at[seen]  # noqa: E731
    if lambert[0]:
        gather = lambda seen: LambertVertices.at(L, at_seen(seen))  # noqa: E731
    else:
        gather = lambda seen: Gathered.at(ctx, L, at_seen(seen), IMPORTANCE)  # noqa: E731
    splat_vertices(ctx, level + 2, rows, take_rows(L.flat("p"), at), L.flat("prim")[at],
                   gather, lambda seen: take_rows(L.flat("beta"), at_seen(seen)), out, L,
                   connection_budget(ctx.settings.transparent_max_bounces, L.flat("passed")[at])
                   if has_passes(ctx.prep) else 0)  # not read where all is opaque


def _light_vertex_gather(ctx, L, yj, rows):
    """``gather(seen)`` of :func:`splat_vertices` for light vertex ``yj`` of subpaths
    ``rows (m,)``: plain Lambert vertices as connect_all gathers them
    (:mod:`.lambert_vertices`) where every vertex at that depth is one, else
    :class:`.subpaths.Gathered`."""
    if all_lambert(ctx.smooth, (L,), yj):
        at = yj * L.valid.shape[1] + rows
        return lambda seen: LambertVertices.at(L, at[seen])
    return lambda seen: Gathered(ctx, L, yj, rows[seen], IMPORTANCE)


def camera_splatter(ctx, out):
    """``on_vertex`` of a light walk that stores nothing (light tracing): strategy ``t = 1`` for
    each light vertex as it is made, unweighted (the vertex is ``s - 1 = j``)."""

    def handle(j, rows, si, frame, wo_l, params, delta_only, beta):
        ok = np.nonzero(~delta_only)[0]
        if ok.size == 0:
            return

        def gather(seen):
            idx = ok[seen]
            lambert = ctx.prep.lambert_only
            return Gathered.of(ctx.smooth, IMPORTANCE, take_params(params, idx, lambert),
                               [take_rows(a, idx) for a in frame],
                               take_rows(si.wo, idx) if ctx.smooth else None,
                               take_rows(wo_l, idx), take_rows(si.ng, idx),
                               None if si.nm is None else take_rows(si.nm, idx), lambert,
                               bends_normals(ctx.prep.scene, si.prim[idx])
                               if ctx.smooth else None)

        passed = ctx.vertex_passes
        budget = connection_budget(ctx.settings.transparent_max_bounces,
                                   0 if passed is None else passed[ok])
        splat_vertices(ctx, j + 1, rows[ok], take_rows(si.p, ok), si.prim[ok], gather,
                       lambda seen: take_rows(beta, ok[seen]), out, budget=budget)

    return handle


def splat_vertices(ctx, s, rows, y, prim, gather, beta_of, out, L=None, budget=0):
    """Strategy ``t = 1`` for the light vertices ``y (m, 3)`` (vertex ``s - 1`` of the light
    subpaths ``rows (m,)``, on triangles ``prim (m,)``): those the pinhole sees are splatted.

    ``gather(seen)`` gives the :class:`.subpaths.Gathered` vertices of the rows ``seen`` of
    ``rows``, ``beta_of(seen)`` their throughputs: only vertices in the film's view are
    gathered. ``L`` (the stored light subpaths) is needed for MIS weights (BDPT) only.
    ``budget (m,)``: transparent surfaces each connection may cross
    (:mod:`.transparent_passes`).
    """
    cam = ctx.cam
    budget = np.broadcast_to(budget, rows.shape)
    film_xy, visible, cos_theta, dist = project(cam, y, ctx.film_margin, ctx.window)
    seen = visible.nonzero()[0]
    if seen.size == 0:
        return
    rows, film_xy, cos_theta, dist, y, prim, budget = _taken(
        seen, (rows, film_xy, cos_theta, dist, y, prim, budget))
    if np.ndim(s):
        s = s[seen]
    w = divide_rows(ctx.cam_pos - y, np.maximum(dist, 1e-300))  # y -> camera
    yv = gather(seen)
    # Float32 Lambert ends (.lambert_vertices): the value and the shadow rays in float32 (the
    # film positions and the MIS densities stay float64).
    f32 = yv.ng.dtype == np.float32
    w_end, dist_end = (w.astype(np.float32), dist.astype(np.float32)) if f32 else (w, dist)
    w_y = yv.local(w_end)
    we = importance(cam, cos_theta)
    # (beta f) scaled by We / d^2 in place, column by column: the values of combine_rows'
    # broadcast, 272 -> 131 us on 39 k rows.
    value = beta_of(seen) * yv.f(w_end, w_y)
    g = we / np.maximum(dist * dist, 1e-300)
    scaled(value, g.astype(np.float32) if f32 else g, out=value)
    ok = (max_component(value) > 0) & finite_rows(value)
    cand = ok.nonzero()[0]
    if cand.size == 0:
        return
    o, dirs, tmax = ctx.prep.accel.shadow_rays(
        take_rows(y, cand), take_rows(yv.ng, cand), prim[cand], take_rows(w_end, cand),
        dist_end[cand], None)
    if f32:
        w_y = w_y.astype(np.float64)  # the densities beside the subpaths' float64 tables
    ctx.counters.rays += cand.size
    # Through transparent surfaces, as the path tracer's shadow rays (:mod:`.shadows`).
    through, transmit = transmitted(ctx, o, dirs, tmax, budget[cand], VIS_CAMERA)
    keep = cand[through]
    value = take_rows(value, keep)
    if transmit is not None:
        value = value * transmit.astype(value.dtype)
    if keep.size == 0:
        return
    film_xy = take_rows(film_xy, keep)
    if np.ndim(s):  # several strategies (connect_cameras): weights and splats per strategy
        s = s[keep]
        weights = (splat_weights(ctx, L, s, rows[keep], yv.for_densities(keep),
                                 take_rows(w, keep), take_rows(w_y, keep), dist[keep],
                                 cos_theta[keep])
                   if ctx.weighs and summable(ctx.mis) else None)
        for g in _runs(s):
            k, s_g = keep[g], int(s[g.start])
            weight = (weights[g] if weights is not None else
                      splat_weight(ctx, L, s_g, rows[k], yv.for_densities(k), take_rows(w, k),
                                   take_rows(w_y, k), dist[k], cos_theta[k])
                      if ctx.weighs else np.ones(k.size))
            out.splat(s_g, film_xy[g], value[g], weight)
        return
    if not ctx.weighs:
        weight = np.ones(keep.size)
    else:
        weight = splat_weight(ctx, L, s, rows[keep], yv.for_densities(keep),
                              take_rows(w, keep), take_rows(w_y, keep), dist[keep],
                              cos_theta[keep])
    out.splat(s, film_xy, value, weight)


def _runs(values):
    """Slices of the runs of equal entries of ``values (m,)`` (sorted), in order."""
    cut = np.concatenate([[0], np.flatnonzero(values[1:] != values[:-1]) + 1, [values.size]])
    return [slice(a, b) for a, b in zip(cut[:-1], cut[1:])]


def _taken(idx, arrays):
    """The rows ``idx (k,)`` (increasing, as ``np.nonzero`` gives them) of each of ``arrays``
    (``(m,)`` or ``(m, c)``): the arrays themselves where that is every row (on the bench box
    every emitter point of a unit is seen and unblocked: 0.5 ms of copies per 16 k rows)."""
    if idx.size == arrays[0].shape[0]:
        return arrays
    return tuple(a.take(idx, axis=0) for a in arrays)


def connect_emitter_to_camera(ctx, L, out):
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
    p = take_rows(pts.p, rows)
    film_xy, visible, cos_theta, dist = project(cam, p, ctx.film_margin, ctx.window)
    seen = visible.nonzero()[0]
    if seen.size == 0:
        return
    rows, p, film_xy, cos_theta, dist = _taken(seen, (rows, p, film_xy, cos_theta, dist))
    w = divide_rows(ctx.cam_pos - p, np.maximum(dist, 1e-300))  # emitter -> camera
    normal = take_rows(pts.normal, rows)
    le = em.radiance(pts.index[rows], p, normal, w, np.broadcast_to(ctx.cam_pos, p.shape))
    cos_l = np.abs(dot(normal, w))
    g = importance(cam, cos_theta) * cos_l / np.maximum(dist * dist, 1e-300)
    value = scaled(le, g / pts.pdf_origin[rows])
    ok = np.nonzero((max_component(value) > 0) & finite_rows(value))[0]
    if ok.size == 0:
        return
    rows, w, dist, value, film_xy, cos_theta, cos_l = _taken(
        ok, (rows, w, dist, value, film_xy, cos_theta, cos_l))
    # From the pinhole toward the point, stopping just short of it (emissive triangles are
    # geometry; lamps are not).
    origins = np.broadcast_to(ctx.cam_pos, (rows.size, 3)).copy()
    keep, transmit = transmitted(ctx, origins, -w, dist * (1.0 - 1e-5),
                                 ctx.settings.transparent_max_bounces, VIS_CAMERA)
    ctx.counters.rays += rows.size
    if keep.size == 0:
        return
    rows, dist, value, film_xy, cos_theta, cos_l = _taken(
        keep, (rows, dist, value, film_xy, cos_theta, cos_l))
    if transmit is not None:  # through transparent surfaces (:mod:`.transparent_passes`)
        value = value * transmit
    weight = direct_weight(ctx, rows, cos_theta, cos_l, dist)
    out.splat(1, film_xy, value, weight)
