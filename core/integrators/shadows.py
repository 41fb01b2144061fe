"""Shadow rays through transparent surfaces (Cycles' transparent shadows).

A shadow ray that meets a surface with transparent components (Transparent BSDF, a Principled
BSDF's Alpha, a Mix with a Transparent BSDF) goes on through it, its throughput multiplied by
the surface's transparency ``sum_c w_c color_c`` (:func:`core.prepare.transparency_table`;
per hit where the alpha is a texture, :mod:`core.alpha`), as
Cycles' shadow rays do with the weight of the transparent closures. An opaque surface, or one
more transparent surface than the ray's budget (the Transparent bounce limit minus the
transparent surfaces its path passed, see :mod:`.bounces`), blocks it.

This is the same transport as the path's own pass through such a surface (choose the transparent
component with probability ``w_c``, keep going with weight ``color_c``), taken in expectation, so
next-event estimation and the paths that pass through transparent surfaces to an emitter estimate
the same light and their MIS weights stay complementary.
"""

from __future__ import annotations

import numpy as np

from ..scene import VIS_SHADOW
from .common import take_rows


def shadow_transmittance(prep, origins, directions, tmax, budget, counters=None,
                         mask=VIS_SHADOW):
    """Fraction of light that reaches along each shadow segment ``(n, 3)``.

    Parameters
    ----------
    prep : core.prepare.PreparedScene
    origins, directions : (n, 3) float64
        Shadow rays (as :meth:`core.accel.Accel.shadow_rays` makes them), unit directions.
    tmax : (n,) float64
        Segment lengths (inf toward the sun or the world).
    budget : (n,) int or int
        Transparent surfaces each ray may cross; one more blocks it.
    counters : core.integrators.base.Counters or None
        Rays traced beyond the first query are added to ``counters.rays``.
    mask : int
        Object visibility class of the rays.

    Returns
    -------
    (n, 3) float64
        1 where nothing is in the way, 0 where something opaque is, the product of the crossed
        surfaces' transparencies otherwise.
    """
    n = origins.shape[0]
    blocked = prep.accel.occluded(origins, directions, tmax, mask)
    out = np.where(blocked, 0.0, 1.0)[:, None] * np.ones((1, 3))
    rows = blocked.nonzero()[0]
    if prep.material_transparency is None or rows.size == 0:
        return out
    budget = np.broadcast_to(np.asarray(budget, np.int64), (n,))
    o, d = take_rows(origins, rows), take_rows(directions, rows)
    t_left = tmax[rows].astype(np.float64)
    end = o + d * np.where(np.isfinite(t_left), t_left, 0.0)[:, None]
    left = budget[rows].copy()
    value = np.ones((rows.size, 3))
    # Each round either ends a ray (it reaches the light, or meets an opaque surface or one
    # transparent surface too many) or crosses one surface of its budget: max + 1 rounds.
    for _ in range(int(left.max()) + 1):
        hits = prep.accel.intersect(o, d, t_left, mask)
        if counters is not None:
            counters.rays += rows.size
        hit = hits.hit
        passes = np.zeros((rows.size, 3))
        prim = hits.prim[hit]
        # Per hit: a textured alpha makes the transparency vary over a surface.
        passes[hit] = (prep.transparency(prim, hits.u[hit], hits.v[hit])
                       * (prep.tri_area[prim] > 0)[:, None])
        passes[left <= 0] = 0.0
        value = value * np.where(hit[:, None], passes, 1.0)
        # The occlusion query and a closest hit may disagree at a grazing edge: a ray that
        # finds nothing now reaches the light.
        go = hit & (passes.max(axis=1) > 0)
        out[rows[~go]] = value[~go]
        keep = go.nonzero()[0]
        if keep.size == 0:
            break
        rows, d, end, value, left = rows[keep], d[keep], end[keep], value[keep], left[keep] - 1
        prim = hits.prim[keep]
        p = o[keep] + d * hits.t[keep][:, None]
        o = prep.accel.offset_origin(p, take_rows(prep.tri_normal, prim), prim, d)
        finite = np.isfinite(t_left[keep])
        t_left = np.where(finite, np.maximum(np.einsum("ij,ij->i", end - o, d), 0.0), np.inf)
    return out
