"""Transparent surfaces on the bidirectional subpaths: a pass straight through is not a vertex.

A surface with transparent components (Transparent BSDF, a Principled BSDF's Alpha, a Mix with
a Transparent BSDF; per hit where the alpha is a texture, :mod:`core.alpha`) is, for light
tracing and BDPT, a *null interface*, as pbrt-v4's walks skip interface surfaces:

- **Walks** (camera and light subpaths, :func:`.subpaths.walk`): at such a hit the walk chooses
  a mixture component as every vertex does (probability its weight,
  :meth:`core.prepare.PreparedScene.choose_material`). If it is the pass-through (a smooth
  dielectric of IOR 1) the ray goes on straight from the hit, its throughput times the
  component's colour, and *no vertex is stored*: the next vertex keeps the densities of the
  ray from the vertex before the surface (its distance is the whole way from there).
  Otherwise the hit is a vertex as before, shaded by the chosen component. A purely
  transparent surface passes every ray, with its colour. The choices chain on one lobe
  number (the remapped number of one choice is uniform again and independent of it), so a
  subpath draws no more numbers than before.
- **Connections** (``s >= 1, t >= 2``, ``t = 1`` to the pinhole, ``s = 1, t = 1``): the
  connecting ray goes through such surfaces, its contribution times their transparency
  ``sum_c w_c color_c`` (:func:`.shadows.shadow_transmittance`), as the path tracer's shadow
  rays do.
- **The Transparent limit** ``T`` counts a path's passes wherever they are made: the camera
  subpath's ``k_c`` before a vertex, the light subpath's ``k_l`` and the connection's, which may
  cross ``T - k_c - k_l`` more. A walk ends at a pass beyond ``T``. Every strategy can then
  make exactly the paths of at most ``T`` passes, whichever side crosses which surface.
  The path tracer ends a camera path at the surface after its ``T``-th pass (Cycles' rule,
  :mod:`.bounces`); the two agree on every path that stays within ``T - 1`` passes, and a
  limit of 0 shows an emitter behind one sheet in the path tracer but not here.

Why the MIS weights need no null vertices
    A pass through a transparent surface of pass-through weight ``w`` and colour ``c`` is a
    factor ``w c`` of the path's contribution. A walk samples it with probability ``w`` and
    weighs ``c``; a connection crosses it with probability one and weighs ``w c``. So the
    strategies' true densities of one path differ by the products of the ``w`` of the passes
    each one samples. The MIS weights compare *pseudo-densities* without these factors: the
    product of the area densities of the path's scattering vertices, each from the previous
    scattering vertex along the straight line through the passes. Every strategy ``(s, t)``
    that can make a path computes these same numbers for it (they depend on the vertices and
    the BSDFs only, not on which side crossed a surface), so for any heuristic the weights of
    the strategies that can make it still sum to one (Veach 1997, sec. 9.2: any weights that
    sum to one keep the combination unbiased; they are no longer the exact balance weights, so
    the variance may be a little higher than with the true densities). A path is made by a
    strategy only if every one of its passes has ``w > 0``, and then by all of them (a
    connection's transparency is ``> 0`` exactly when a walk's pass probability is), within the
    same limit ``T`` (above): no strategy is weighed for a path it cannot make.
    Had a pass been a vertex (a delta lobe, the old way), a connection through the surface
    would make the same path as the strategy with the pass as a vertex, twice counted; so
    connections had to stop at transparent surfaces, and light that reaches a surface only
    through a transparent one from a delta light (a sun through a leaf) was lost.
"""

from __future__ import annotations

import copy

import numpy as np

from ..accel import Hits
from ..prepare import passes_straight
from .common import intersect_by_class, max_component, surface_hits, take_rows
from .shadows import shadow_transmittance


def has_passes(prep):
    """Whether any material passes rays straight through (else walks and connections skip
    this module's work: every surface is opaque)."""
    return prep.material_transparency is not None


def connection_budget(limit, *passed):
    """Transparent surfaces a connection may cross ``(m,)``: the Transparent ``limit`` minus
    the passes ``passed`` (arrays ``(m,)``) its two subpaths made before its ends, at least 0."""
    left = np.asarray(limit, np.int64)
    for p in passed:
        left = left - np.asarray(p, np.int64)
    return np.maximum(left, 0)


def transmitted(ctx, origins, directions, tmax, budget, mask):
    """Connection rays ``(m,)`` that get through: their indices ``(k,)`` and ``(k, 3)``
    transmittance (None where every surface is opaque: then it is one).

    Parameters
    ----------
    ctx : the bidirectional chunk's context (``prep``, ``counters``)
    origins, directions : (m, 3) float64
        Rays as :meth:`core.accel.Accel.shadow_rays` makes them.
    tmax : (m,) float64
    budget : (m,) int or int
        Transparent surfaces each ray may cross (:func:`connection_budget`).
    mask : int
        Visibility class of the rays (``VIS_SHADOW``, ``VIS_CAMERA``).
    """
    prep = ctx.prep
    if not has_passes(prep):
        return np.nonzero(~prep.accel.occluded(origins, directions, tmax, mask))[0], None
    value = shadow_transmittance(prep, origins, directions, tmax, budget, ctx.counters, mask)
    through = np.nonzero(max_component(value) > 0)[0]
    return through, take_rows(value, through)


def _on_transparent(prep, hits):
    """The rows ``(k,)`` of ``hits`` on a surface whose material has a transparent component
    (a textured alpha may still make a hit opaque: the component choice decides)."""
    live = surface_hits(prep, hits)
    clear = prep.material_transparency.max(axis=1) > 0
    return live[clear[prep.tri_material[hits.prim[live]]]]


def _is_pass(prep, material):
    """Whether the material rows ``material (k,)`` pass rays straight through
    (:func:`core.prepare.passes_straight`)."""
    return passes_straight(prep.material_bsdf)[material]


class Passes:
    """One walk's pass bookkeeping across its vertices (struct-of-arrays over its live rows).

    Attributes
    ----------
    passed : (m,) int32
        Transparent surfaces each subpath passed since its endpoint.
    """

    def __init__(self, m):
        self.passed = np.zeros(m, np.int32)

    def take(self, rows):
        """Keep the subpaths ``rows (k,)`` (index compaction)."""
        self.passed = self.passed[rows]

    def resolve(self, ctx, j, rows, o, d, tmax, hits, beta, vis, stream, dim, on_segment,
                pdf_prev, prev_delta):
        """Stage *pass transparent surfaces* of step ``j`` of a walk: follow the rays ``o, d
        (m, 3)`` of the subpaths ``rows (m,)`` (their first ``hits`` already traced and handed
        to ``on_segment``) straight through every surface where they choose the pass-through,
        to the first surface that scatters them.

        Parameters
        ----------
        tmax : (m,) float64 or None
            The rays' lengths (None: unbounded).
        beta : (m, 3) float64
            Throughputs; the returned ones carry the passes' colours.
        vis : (m,) int
            Visibility classes of the rays (kept through the passes).
        stream : SampleStream
            The walk's uncompacted stream; the lobe numbers of dimension ``dim`` are drawn
            from a copy (the same numbers as the walk's own draw of that dimension).
        on_segment : callable or None
            Called as ``on_segment(j, rows, o, d, hits, beta, pdf_prev, prev_delta, t0)`` for
            every segment after a pass, ``t0 (k,)`` the distance its origin lies along the ray
            from the vertex.

        Returns
        -------
        hits : core.accel.Hits
            The hits the rays end on, ``t`` from the original origins; paths that met a pass
            beyond the Transparent limit, or one of colour zero, end (no hit).
        beta : (m, 3) float64
        u_lobe : (m,) float64 or None
            The lobe number entering the component choice of each final hit, NaN where the
            walk's own draw is that number (no surface with a transparent component on the
            way); None if no ray passed a surface.
        """
        prep = ctx.prep
        limit = int(ctx.settings.transparent_max_bounces)
        live = _on_transparent(prep, hits)
        if live.size == 0:
            return hits, beta, None
        # Only hits on materials with a transparent component draw here (the others keep NaN:
        # the walk's own draw of the same dimension).
        u_lobe = np.full(rows.size, np.nan)
        draw = copy.copy(stream)
        draw.compact(rows[live])
        draw.skip_to(dim)
        u_lobe[live] = draw.next_1d()
        hits = Hits(hits.prim.copy(), hits.t.copy(), hits.u.copy(), hits.v.copy())
        beta = np.array(beta, np.float64)
        moved = False
        cur, cur_hits, cur_o = np.arange(rows.size), hits, o
        # Each round passes one more surface or ends a path: at most limit + 1 rounds.
        for _ in range(limit + 2):
            lc = _on_transparent(prep, cur_hits)
            at = cur[lc]
            prim, hu, hv = cur_hits.prim[lc], cur_hits.u[lc], cur_hits.v[lc]
            material, u_after = prep.choose_material(prim, u_lobe[at], hu, hv)
            through = np.nonzero(_is_pass(prep, material))[0]
            if through.size == 0:
                break
            moved = True
            idx, lc, prim = at[through], lc[through], prim[through]
            # The component's colour, as shadow rays read it (core.prepare.pass_colors).
            beta[idx] *= prep.material_bsdf.color[material[through]]
            go = (self.passed[idx] < limit) & (max_component(beta[idx]) > 0)
            ended = idx[~go]
            hits.prim[ended], hits.t[ended] = -1, np.inf
            idx, lc, prim = idx[go], lc[go], prim[go]
            if idx.size == 0:
                break
            self.passed[idx] += 1
            u_lobe[idx] = u_after[through][go]
            dirs = take_rows(d, idx)
            p = take_rows(cur_o, lc) + dirs * cur_hits.t[lc][:, None]
            start = prep.accel.offset_origin(p, take_rows(prep.tri_normal, prim), prim, dirs)
            t0 = np.einsum("ij,ij->i", start - take_rows(o, idx), dirs)
            left = None if tmax is None else np.maximum(tmax[idx] - t0, 0.0)
            nxt = intersect_by_class(prep.accel, start, dirs, left, vis[idx])
            ctx.counters.rays += idx.size
            if on_segment is not None:
                on_segment(j, rows[idx], start, dirs, nxt, take_rows(beta, idx), pdf_prev[idx],
                           prev_delta[idx], t0)
            hits.prim[idx], hits.t[idx] = nxt.prim, t0 + nxt.t
            hits.u[idx], hits.v[idx] = nxt.u, nxt.v
            cur, cur_hits, cur_o = idx, nxt, start
        return hits, beta, (u_lobe if moved else None)
