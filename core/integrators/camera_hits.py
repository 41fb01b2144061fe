"""Strategy ``s = 0`` of the bidirectional estimators: emitters the camera subpath finds.

Every segment of the camera walk looks for the world (escaped rays), suns of finite angle,
lamp shapes before the hit (:meth:`core.lights.LightSampler.lamp_points`) and emissive
triangles hit; BDPT weighs what it finds against the strategies that connect
(:func:`.mis_densities.camera_hit_weight`), light tracing counts it alone.

On a transparent film (Film > Transparent) the camera rays (``j = 1``, also after transparent
passes) that escape do not add the world: they add the mean of their throughput to the
sample's transparency instead (the alpha, as the path tracer's camera rays). No other strategy
makes a path from the pinhole straight to the world (a light vertex on the world is never
joined to the pinhole), so nothing else must be dropped; the world still lights the scene.
"""

from __future__ import annotations

import numpy as np

from .common import max_component, take_rows
from .mis_densities import camera_hit_weight


def camera_emission(ctx, cam_sub, out):
    """``on_segment`` of the camera walk: emitters along the segment from vertex ``j - 1``
    (strategy ``s = 0, t = j + 1``), MIS-weighted against the strategies that connect. After
    transparent passes (:mod:`.transparent_passes`) the segment starts ``t0 (k,)`` along the
    ray from vertex ``j - 1``."""
    prep, em = ctx.prep, ctx.emission
    ls = prep.lights
    clear_film = prep.scene.film_transparent

    def handle(j, rows, o, d, hits, beta, pdf_prev, prev_delta, t0=None):
        found = []  # (local rows, emitter index, point, normal, distance)
        n = rows.size
        escaped = np.nonzero(~hits.hit)[0]
        clear = clear_film and j == 1  # camera rays on a transparent film
        if clear:
            out.add_transparency(rows[escaped], take_rows(beta, escaped).mean(axis=1))
        if escaped.size:
            if ls.has_world and not clear:
                found.append((escaped, np.full(escaped.size, ls.world_index),
                              np.zeros((escaped.size, 3)), np.zeros((escaped.size, 3)),
                              np.full(escaped.size, np.inf)))
            for li in ls.infinite_lamps(camera=j == 1):
                found.append((escaped, np.full(escaped.size, li), np.zeros((escaped.size, 3)),
                              np.zeros((escaped.size, 3)), np.full(escaped.size, np.inf)))
        found += ls.lamp_points(o, d, hits.t, j == 1)
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
            receiver = take_rows(cam_sub.p[j - 1], r)
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
                elif t0 is not None:  # after transparent passes: from z_{j-1}, not the pass
                    t = t + t0[lr]
                weight = camera_hit_weight(ctx, cam_sub, j, r, index, q, normal, t, -d[lr],
                                           pdf_prev[lr], prev_delta[lr])
            out.add(0, j + 1, r, value, weight)

    return handle
