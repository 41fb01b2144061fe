"""Connection strategies of the bidirectional estimators: a light vertex joined to a camera
vertex (``s >= 1, t >= 2``, :func:`connect`), a light vertex seen by the pinhole and splatted
(``t = 1``, :func:`connect_camera`), and a point on an emitter seen by the pinhole
(``s = 1, t = 1``, :func:`connect_emitter_to_camera`). Each traces its shadow rays and adds
its MIS-weighted contributions to the batch's :class:`.strategy_views.Tally`.
"""

from __future__ import annotations

import numpy as np

from ..camera import importance, project
from ..materials.bsdf import IMPORTANCE, RADIANCE
from ..scene import VIS_CAMERA, VIS_SHADOW
from .common import max_component, take_rows
from .mis_densities import connection_weight, direct_weight, splat_weight
from .subpaths import Gathered, dot, take_params


def connect(ctx, L, C, s, t, out, fresh=None):
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
    z = take_rows(C.p[zj], rows)
    if s == 1:
        infinite = fresh.infinite[rows]
        index = fresh.index[rows]
        y = fresh.p[rows]
        to_y = np.where(infinite[:, None], -fresh.w_inf[rows], y - z)
    else:
        y = take_rows(L.p[s - 1], rows)
        infinite = np.zeros(rows.size, bool)
        to_y = y - z
    dist = np.where(infinite, np.inf, np.linalg.norm(to_y, axis=1))
    ok = (dist > 0)
    w = to_y / np.where(infinite, 1.0, np.maximum(dist, 1e-300))[:, None]  # z -> y
    zv = Gathered(ctx, C, zj, rows, RADIANCE)
    w_z = zv.local(w)
    f_z = zv.f(w, w_z)
    yv = w_y = None
    if s == 1:
        normal = fresh.normal[rows]
        le = em.radiance(index, y, normal, -w, z)
        point = fresh.delta_light[rows] & ~infinite
        cos_y = np.where(infinite | point, 1.0, np.abs(dot(normal, w)))
        f_y = le * cos_y[:, None]
        beta_y = 1.0 / np.where(fresh.pdf_origin[rows] > 0, fresh.pdf_origin[rows], np.inf)
        value = f_y * f_z * take_rows(C.beta[zj], rows) * beta_y[:, None]
    else:
        yv = Gathered(ctx, L, s - 1, rows, IMPORTANCE)
        w_y = yv.local(-w)
        f_y = yv.f(-w, w_y)
        value = take_rows(L.beta[s - 1], rows) * f_y * f_z * take_rows(C.beta[zj], rows)
    g = np.where(infinite, 1.0, 1.0 / np.maximum(np.where(infinite, 1.0, dist) ** 2, 1e-300))
    value = value * g[:, None]
    ok &= (max_component(value) > 0) & np.isfinite(value).all(axis=1)
    cand = np.nonzero(ok)[0]
    if cand.size == 0:
        return
    if s == 1:
        y_normal = np.where(infinite[cand, None], 0.0, fresh.normal[rows[cand]])
    else:
        y_normal = take_rows(L.ng[s - 1], rows[cand])
    blocked = prep.accel.occluded(*prep.accel.shadow_rays(
        z[cand], take_rows(C.ng[zj], rows[cand]), C.prim[zj, rows[cand]], w[cand], dist[cand],
        y_normal),
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
    weight = connection_weight(ctx, L, C, s, t, rows[keep], conn, fresh)
    out.add(s, t, rows[keep], value[keep], weight)


def connect_camera(ctx, L, s, out):
    """Strategy ``t = 1``: light vertex ``s - 1`` seen by the pinhole, splatted."""
    yj = s - 1
    rows = np.nonzero(L.valid[yj] & L.connectible[yj])[0]
    if rows.size == 0:
        return
    splat_vertices(ctx, s, rows, take_rows(L.p[yj], rows), L.prim[yj, rows],
                   lambda seen: Gathered(ctx, L, yj, rows[seen], IMPORTANCE),
                   lambda seen: take_rows(L.beta[yj], rows[seen]), out, L)


def camera_splatter(ctx, out):
    """``on_vertex`` of a light walk that stores nothing (light tracing): strategy ``t = 1`` for
    each light vertex as it is made, unweighted (the vertex is ``s - 1 = j``)."""

    def handle(j, rows, si, frame, wo_l, params, delta_only, beta):
        ok = np.nonzero(~delta_only)[0]
        if ok.size == 0:
            return

        def gather(seen):
            idx = ok[seen]
            return Gathered.of(ctx.smooth, IMPORTANCE, take_params(params, idx),
                               [take_rows(a, idx) for a in frame], take_rows(si.wo, idx),
                               take_rows(wo_l, idx), take_rows(si.ng, idx))

        splat_vertices(ctx, j + 1, rows[ok], take_rows(si.p, ok), si.prim[ok], gather,
                       lambda seen: take_rows(beta, ok[seen]), out)

    return handle


def splat_vertices(ctx, s, rows, y, prim, gather, beta_of, out, L=None):
    """Strategy ``t = 1`` for the light vertices ``y (m, 3)`` (vertex ``s - 1`` of the light
    subpaths ``rows (m,)``, on triangles ``prim (m,)``): those the pinhole sees are splatted.

    ``gather(seen)`` gives the :class:`.subpaths.Gathered` vertices of the rows ``seen`` of
    ``rows``, ``beta_of(seen)`` their throughputs: only vertices in the film's view are
    gathered. ``L`` (the stored light subpaths) is needed for MIS weights (BDPT) only.
    """
    cam = ctx.cam
    film_xy, visible, cos_theta, dist = project(cam, y, ctx.film_margin, ctx.window)
    seen = np.nonzero(visible)[0]
    if seen.size == 0:
        return
    rows, film_xy, cos_theta, dist, y, prim = (rows[seen], film_xy[seen], cos_theta[seen],
                                               dist[seen], y[seen], prim[seen])
    w = (ctx.cam_pos - y) / np.maximum(dist, 1e-300)[:, None]  # y -> camera
    yv = gather(seen)
    w_y = yv.local(w)
    we = importance(cam, cos_theta)
    value = beta_of(seen) * yv.f(w, w_y) * (we / np.maximum(dist * dist, 1e-300))[:, None]
    ok = (max_component(value) > 0) & np.isfinite(value).all(axis=1)
    cand = np.nonzero(ok)[0]
    if cand.size == 0:
        return
    o, dirs, tmax = ctx.prep.accel.shadow_rays(y[cand], yv.ng[cand], prim[cand], w[cand],
                                               dist[cand], np.zeros((cand.size, 3)))
    blocked = ctx.prep.accel.occluded(o, dirs, tmax, VIS_CAMERA)
    ctx.counters.rays += cand.size
    keep = cand[~blocked]
    if keep.size == 0:
        return
    rows, w, w_y, dist, value, film_xy, cos_theta = (rows[keep], w[keep], w_y[keep], dist[keep],
                                                     value[keep], film_xy[keep], cos_theta[keep])
    if not ctx.weighs:
        weight = np.ones(rows.size)
    else:
        weight = splat_weight(ctx, L, s, rows, yv.take(keep), w, w_y, dist, cos_theta)
    out.splat(s, film_xy, value, weight)


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
    cos_l = np.abs(dot(normal, w))
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
    weight = direct_weight(ctx, rows, cos_theta, cos_l, dist)
    out.splat(1, film_xy, value, weight)
