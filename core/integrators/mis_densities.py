"""MIS densities of bidirectional path tracing: for a path made by strategy ``(s, t)``, the
densities with which every other strategy ``(s', t')`` would make it, from the subpaths' stored
per-vertex densities (Veach 1997, sec. 10.2; pbrt-v4's ``MISWeight``).

Each function here builds the per-vertex density lists of one kind of strategy and hands them
to :func:`strategy_weight`, which forms the stack of strategy densities (as ratios to the
sampling strategy's) and asks the render's :class:`core.sampling.mis.MIS` for the weight: BDPT
is the ``k``-strategy case of the same weight the path tracer uses for two.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..camera import camera_pdf
from .mis_sums import heuristic
from .subpaths import dot, to_area
from ..quiet import quiet


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
    with quiet("divide", "invalid", "over"):
        for sp in range(s - 1, -1, -1):
            ratio[sp] = _step(ratio[sp + 1], p_camera[sp], p_light[sp])
        for sp in range(s + 1, k + 1):
            ratio[sp] = _step(ratio[sp - 1], p_light[sp - 1], p_camera[sp - 1])
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
        # Ratios are >= 0, inf or NaN (0 x inf): NaN counts as zero.
        ok_r = ok & (ratio[sp] > 0)
        valid.append(ok_r)
        terms.append(np.where(ok_r, ratio[sp], 0.0))
    w = mis.weight(terms, s, valid)
    return np.where(np.isfinite(w), w, 0.0)


def _step(ratio, num, den):
    """``ratio * num / den`` where ``den > 0``, else zero (one step of the ratio recurrence;
    the same products and quotients as ``np.where``, in two array operations)."""
    return np.divide(ratio * num, den, out=np.zeros(den.shape), where=den > 0)


def camera_hit_weight(ctx, cam, j, r, index, q, normal, t, w_travel, pdf_prev, prev_delta):
    """MIS weight of emitters found by the camera subpath's segment from ``z_{j-1}``."""
    em = ctx.emission
    k = j
    m = r.size
    infinite = em.is_infinite(index)
    p_light = [None] * (k + 1)
    p_camera = [None] * (k + 1)
    delta = [np.zeros(m, bool)] * (k + 1)  # read only; entries are replaced, not written
    p_light[0] = em.pdf_origin(index, w_travel)
    cos_l = np.where(infinite, 1.0, np.abs(dot(normal, w_travel)))
    p_camera[0] = np.where(prev_delta, 1.0, to_area(pdf_prev, cos_l, t))
    # The emitter makes z_{j-1} by its direction density.
    cos_z = np.abs(dot(cam.normals(j - 1, r), w_travel))
    pdf_dir = em.pdf_direction(index, normal, w_travel)
    p_light[1] = np.where(infinite, pdf_dir * cos_z, to_area(pdf_dir, cos_z, t))
    for i in range(1, k + 1):
        zi = k - i
        p_camera[i] = cam.pdf_fwd[zi, r] if zi > 0 else np.ones(m)
        if i >= 2:
            p_light[i] = cam.pdf_rev[zi, r] if zi > 0 else np.ones(m)
        if 0 < zi:
            delta[i] = cam.delta[zi, r]
    delta_light = np.zeros(m, bool)
    return strategy_weight(ctx.mis, p_light, p_camera, delta, 0, delta_light, direct=~infinite)


class Near(NamedTuple):
    """Densities at the two ends of connections ``y = x_{s-1}`` -> ``z = x_s`` of one
    strategy (arrays ``(m,)``, one per connection) that the subpaths did not store.

    Attributes
    ----------
    light_0 : density of ``x_0`` on its emitter (the fresh point's for ``s = 1``).
    light_s : the light side's density of ``z``, sampled from ``y``.
    light_s1 : the light side's density of ``z_{t-2}``, sampled from ``z`` (used for
        ``t >= 3``).
    camera_s1 : the camera side's density of ``y``, sampled from ``z``.
    camera_s2 : the camera side's density of ``y_{s-2}``, sampled from ``y`` (``s >= 2``).
    delta_light : (m,) bool, ``x_0`` is a delta light.
    """

    light_0: np.ndarray
    light_s: np.ndarray
    light_s1: np.ndarray
    camera_s1: np.ndarray
    camera_s2: np.ndarray
    delta_light: np.ndarray


def connection_weight(mis, L, C, s, t, rows, near):
    """MIS weight ``(m,)`` of strategy ``(s, t)``, ``s >= 1, t >= 2``: light vertex
    ``y = x_{s-1}`` (a fresh emitter point for ``s = 1``) joined to camera vertex
    ``z = x_s = z_{t-1}`` of the subpaths ``rows (m,)``; ``near`` (a :class:`Near`) holds the
    densities the subpaths did not store."""
    k = s + t - 1
    m = rows.size
    p_light = [None] * (k + 1)
    p_camera = [None] * (k + 1)
    delta = [np.zeros(m, bool)] * (k + 1)  # read only; entries are replaced, not written
    # Light side: stored densities up to y, then y -> z, then z -> z_{t-2}.
    p_light[0] = near.light_0
    for i in range(1, s):
        p_light[i] = L.pdf_fwd[i, rows]
        if i < s - 1:
            delta[i] = L.delta[i, rows]
    p_light[s] = near.light_s
    if t >= 3:
        p_light[s + 1] = near.light_s1
    for i in range(s + 2, k + 1):
        zi = k - i
        p_light[i] = C.pdf_rev[zi, rows] if zi > 0 else np.ones(m)
    # Camera side: stored densities down to z, then z -> y, then y -> y_{s-2}.
    for i in range(s, k + 1):
        zi = k - i
        p_camera[i] = C.pdf_fwd[zi, rows] if zi > 0 else np.ones(m)
        if s < i < k:
            delta[i] = C.delta[zi, rows]
    p_camera[s - 1] = near.camera_s1
    if s >= 2:
        p_camera[s - 2] = near.camera_s2
        for i in range(s - 2):
            p_camera[i] = L.pdf_rev[i, rows]
    return strategy_weight(mis, p_light, p_camera, delta, s, near.delta_light)


def splat_weight(ctx, L, s, rows, yv, w, w_y, dist, cos_theta):
    """MIS weight of strategy ``t = 1``: light vertex ``y = x_{s-1}`` (gathered as ``yv``, with
    ``w`` toward the pinhole, ``w_y`` in its frame, ``dist`` away, at ``cos_theta`` to the view
    axis) seen by the pinhole."""
    yj = s - 1
    k = s
    m = rows.size
    p_light = [L.pdf_fwd[i, rows] for i in range(s)] + [np.ones(m)]
    delta = [np.zeros(m, bool)] + [L.delta[i, rows] for i in range(1, s - 1)] + [
        np.zeros(m, bool), np.zeros(m, bool)]
    p_camera = [None] * (k + 1)
    p_camera[k] = np.ones(m)
    pdf_cam = camera_pdf(ctx.cam, cos_theta, ctx.film_pixels)
    p_camera[s - 1] = to_area(pdf_cam, np.abs(dot(yv.ng, w)), dist)
    p_camera[s - 2] = to_area(yv.pdf_back(w_y), L.cos_prev[yj, rows], L.d_prev[yj, rows])
    for i in range(s - 2):
        p_camera[i] = L.pdf_rev[i, rows]
    return strategy_weight(ctx.mis, p_light, p_camera, delta, s,
                           ctx.light_points.delta_light[rows])


def direct_weight(ctx, rows, cos_theta, cos_l, dist):
    """MIS weight of strategy ``s = 1, t = 1``: the light subpaths' points ``rows`` on finite
    emitters (cosine ``cos_l`` there, ``dist`` away, at ``cos_theta`` to the view axis) seen
    by the pinhole, against the camera ray that hits them."""
    m = rows.size
    p_camera = [to_area(camera_pdf(ctx.cam, cos_theta, ctx.film_pixels), cos_l, dist), np.ones(m)]
    p_light = [ctx.light_points.pdf_origin[rows], np.ones(m)]
    return strategy_weight(ctx.mis, p_light, p_camera, [np.zeros(m, bool)] * 2, 1,
                           np.zeros(m, bool), direct=np.ones(m, bool))


def splat_weights(ctx, L, s, rows, yv, w, w_y, dist, cos_theta):
    """:func:`splat_weight` of splats of several strategies at once: ``s (m,) >= 2`` sorted
    (each strategy's splats in one run), the other arguments as there for all ``m`` splats.
    Only for the heuristics summed over strategies (:func:`.mis_sums.summable`): the same
    weights to the last bit, as each splat's ratios, terms and sums are formed by the same
    operations in the same order, each over the splats whose strategy has that term (a
    suffix of the sorted rows)."""
    top = int(s[-1])
    # first[q]: the first splat of a strategy >= q (first[q]: first[q + 1] is strategy q's run).
    first = np.searchsorted(s, np.arange(top + 3)).tolist()
    pdf_cam = camera_pdf(ctx.cam, cos_theta, ctx.film_pixels)
    at_y = (s - 1) * L.valid.shape[1] + rows
    near = (to_area(pdf_cam, np.abs(dot(yv.ng, w)), dist),  # p_camera[s - 1]
            to_area(yv.pdf_back(w_y), L.cos_prev.take(at_y), L.d_prev.take(at_y)))
    ratios = _suffix_ratios(L, rows, first, top, near)
    return _summed_weight(ctx, L, rows, first, top, ratios)


def _suffix_ratios(L, rows, first, top, near):
    """``ratios[sp] (m - first[sp + 1],)``: the density ratio of strategy ``sp`` to the
    splats' own for the splats of strategies above ``sp`` (the recurrence of
    :func:`strategy_weight`, from each splat's own strategy down)."""
    cur = np.empty(rows.size)
    ratios = [None] * top
    # Rows of the (depth, n) tables by ndarray.take of one row (not [sp, rows], the slower
    # two-axis fancy index); each step written into ``cur`` and copied once.
    with quiet("divide", "invalid", "over"):
        for sp in range(top - 1, -1, -1):
            a, b, c = first[sp + 1], first[sp + 2], first[sp + 3]
            cur[a:b] = 1.0  # strategy sp + 1's own ratio
            num = np.concatenate([near[0][a:b], near[1][b:c], L.pdf_rev[sp].take(rows[c:])])
            den = L.pdf_fwd[sp].take(rows[a:])
            tail = cur[a:]
            num *= tail
            tail.fill(0.0)  # _step: zero where den is not positive
            np.divide(num, den, out=tail, where=den > 0)
            ratios[sp] = tail.copy()
    return ratios


def _summed_weight(ctx, L, rows, first, top, ratios):
    """``1 / (sum of h(term))`` per splat over its strategies ``0 .. s``, in that order
    (:meth:`core.sampling.mis.MIS.weight`; the splat's own term is one)."""
    mis, m = ctx.mis, rows.size
    delta_light = ctx.light_points.delta_light[rows]
    none = mis.setting == "none"
    total = np.zeros(m, np.int64 if none else np.float64)
    # A splat's own term: the heuristic of a ratio of one is one for every summed heuristic
    # (balance 1, power 1 ** beta, 'none' [1 > 0]).
    own = 1 if none else 1.0
    with quiet("divide", "invalid", "over"):
        for sp in range(top + 1):
            a = first[sp + 1]
            if sp > 0:  # splats of strategy sp: their own term
                total[first[sp]:a] += own
            if sp == top:
                break
            r = rows[a:]
            if sp == 0:
                ok = ~delta_light[a:]
            else:
                # Vertex sp - 1's flags were gathered for strategy sp - 1 over rows[a_prev:],
                # masked there at splats of strategy sp only (before a): reused.
                here = _not_delta(L, sp, r, first, a)
                ok = here if sp == 1 else prev[a - a_prev:] & here
                prev, a_prev = here, a
            valid = ok & (ratios[sp] > 0)
            total[a:] += valid if none else heuristic(mis, np.where(valid, ratios[sp], 0.0))
        w = 1.0 / total
    return np.where(np.isfinite(w), w, 0.0)


def _not_delta(L, i, r, first, a):
    """Not ``delta[i]`` of :func:`splat_weight`'s lists for the splats ``r`` (from ``a``):
    vertex ``i``'s flag, false at vertex 0 and at each splat's own vertex ``s - 1``."""
    if i == 0:
        return np.ones(r.size, bool)
    flag = L.delta[i, r]
    flag[:first[i + 2] - a] = False  # strategy i + 1: vertex i is the splat's own
    return ~flag

