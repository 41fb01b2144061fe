"""BDPT's MIS weights of the connection strategies ``s >= 1, t >= 2`` by running sums along
the subpaths: ``O(1)`` array operations per connection instead of ``O(s + t)`` per strategy.

The weight of strategy ``s`` of a path ``x_0 .. x_k`` (``k = s + t - 1``) is, for the balance
(``h(r) = r``), power (``h(r) = r^beta``) and 'none' (``h(r) = [r > 0]``) heuristics,

    ``w = 1 / (1 + sum_{s' < s} h(r_s') + sum_{s' > s} h(r_s'))``,

over the strategies ``s'`` that can make the path (no delta vertex at either end of their
connection; ``s' = 0`` not for delta lights), with ``r_s'`` the ratio of strategy ``s'``'s
density to strategy ``s``'s (Veach 1997, sec. 10.2). The ratios are products of per-vertex
density ratios; on the light side ``r_s' = prod_{i = s'}^{s - 1} p_camera(x_i) / p_light(x_i)``.
As ``h`` of a product is the product of ``h`` of its factors, the sum over ``s' < s`` is a
recurrence along the light subpath (Georgiev et al. 2012, "Light transport simulation with
vertex connection and merging", sec. 4 and its technical report; SmallVCM's BPT mode; here on
the densities the subpaths already store, as pbrt-v4's ``MISWeight`` reads them):

    ``G[j] = h(pdf_rev[j] / pdf_fwd[j]) * (possible(j) + G[j - 1])``

holds the strategies connecting at or before light vertex ``j`` whose factors are all stored;
a connection to light vertex ``y = x_{s-1}`` finishes the sum with its two factors that the
connection itself makes (the camera side's densities of ``y`` and ``x_{s-2}``). The camera side
is the same along the camera subpath. :class:`RunningSums` builds both tables once per batch
(``depth`` operations over the batch) and :meth:`RunningSums.weights` weighs every connection
of the batch, of every strategy, in one pass.

The 'maximum' and 'cutoff' heuristics compare each ratio with the largest one: not a sum, so
they keep the per-strategy weights of :func:`.mis_densities.connection_weight` (the reference
these sums are tested against, ``tests/core/test_mis_sums.py``).
"""

from __future__ import annotations

import numpy as np

from ..quiet import quiet

# Heuristics whose weight is 1 / (1 + sum of h(ratio)) over the possible strategies.
SUMMED = ("balance", "power", "none")


def summable(mis):
    """Whether the weights of ``mis`` (a :class:`core.sampling.mis.MIS`) are running sums."""
    return mis.setting in SUMMED


def _ratio(num, den):
    """``num / den`` where ``den > 0``, else zero (a strategy with a zero density)."""
    return np.divide(num, den, out=np.zeros(np.shape(den)), where=den > 0)


class RunningSums:
    """The light and camera subpaths' running sums of one batch, for the heuristic ``mis``.

    Parameters
    ----------
    mis : core.sampling.mis.MIS
        The render's heuristic, one of :data:`SUMMED`.
    L, C : core.integrators.subpaths.Subpath
        The light and camera subpaths, ``(depth, n)`` vertices.
    delta_light : (n,) bool
        The light subpath's emitter is a delta light (strategy ``s' = 0`` is impossible).

    Attributes
    ----------
    light : (depth, n) float64
        ``light[y]``: for a connection at light vertex ``y = s - 1``, the sum over strategies
        ``s' <= y - 2`` of ``h`` of their factors stored on the light subpath
        (``pdf_rev / pdf_fwd`` of vertices ``s' .. y - 2``); zero for ``y <= 1``.
    camera : (depth, n) float64
        ``camera[z]``: the same for a connection at camera vertex ``z = t - 1`` and the
        strategies connecting at camera vertices ``0 .. z - 3`` (camera vertex ``c`` is path
        vertex ``x_{k - c}``); zero for ``z <= 2``.
    """

    def __init__(self, mis, L, C, delta_light):
        self.mis = mis
        self.light = self._table(L, ~delta_light)
        self.camera = self._table(C, None)

    def h(self, r):
        """The heuristic's function of a density ratio ``r >= 0`` (:func:`heuristic`)."""
        return heuristic(self.mis, r)

    def _table(self, sub, first_possible):
        """``out[j + 2] = G[j]`` of the recurrence along ``sub`` (``out[0] = out[1] = 0``).

        ``first_possible``: whether the strategy connecting at vertex 0 can (light side:
        not a delta light). None (camera side): no strategy connects at the pinhole with a
        ratio of two stored densities (that ratio is the connection's own, ``t = 2``), and
        ``G[0] = 0``.

        ``G[j]`` is formed only for the subpaths that have vertex ``j + 2``: only connections
        there and ``G[j + 1]`` read it (elsewhere the table stays zero, unread). Deep vertices
        are few (Russian roulette), so most rows of the deep levels are skipped; each row's
        value is the same."""
        depth, n = sub.valid.shape
        out = np.zeros((depth, n))
        with quiet("invalid", "over"):  # one context for the loop (each costs about 0.4 us)
            for j in range(0 if first_possible is not None else 1, depth - 2):
                rows = np.flatnonzero(sub.valid[j + 2])
                if j == 0:
                    possible = first_possible[rows]
                else:
                    possible = ~(sub.delta[j - 1].take(rows) | sub.delta[j].take(rows))
                factor = self.h(_ratio(sub.pdf_rev[j].take(rows), sub.pdf_fwd[j].take(rows)))
                # G[j] = factor * (possible + G[j - 1]); G[j - 1] of these rows is in the
                # table's row j + 1 (they have vertex j + 1 too), zero before the first.
                g = np.add(possible, out[j + 1].take(rows))
                g *= factor
                out[j + 2][rows] = g
        return out

    def weights(self, L, C, s, t, row, near):
        """MIS weights ``(m,)`` of connections of any strategies ``s (m,) >= 1``,
        ``t (m,) >= 2``, of the subpaths ``row (m,)``, with the densities ``near`` (a
        :class:`.mis_densities.Near` of ``(m,)`` columns) that the connections made; equal to
        :func:`.mis_densities.connection_weight` strategy by strategy, to rounding."""
        n = C.valid.shape[1]
        with quiet("invalid", "over", "divide"):
            total = (1.0 + self._light_side(L, s, row, near, n)
                     + self._camera_side(C, t, row, near, n))
            w = 1.0 / total
        return np.where(np.isfinite(w), w, 0.0)

    def _light_side(self, L, s, row, near, n):
        """Sum over ``s' < s``: strategy ``s - 1`` (factor ``a1``), ``s - 2`` (``a1 a2``) and
        the stored rest (``a1 a2 light[s - 1]``). ``n``: subpaths of the batch."""
        h = self.h
        one, two = s == 1, s == 2
        y = s - 1
        # Rows of the (depth, n) tables as flat indices (np.take gathers them faster than
        # two-index fancy indexing, same values).
        at_y = y * n + row
        at_back = np.maximum(y - 1, 0) * n + row
        a1 = _ratio(near.camera_s1, np.where(one, near.light_0, L.pdf_fwd.take(at_y)))
        # Strategy s - 1 connects x_{s-2} (impossible where it is delta) to y (never counted
        # delta: the connection evaluates its BSDF). Vertex 0's flag is never set (false).
        delta_back = L.delta.take(at_back)
        p1 = np.where(one, ~near.delta_light, ~delta_back)
        a2 = _ratio(near.camera_s2, np.where(two, near.light_0, L.pdf_fwd.take(at_back)))
        p2 = np.where(two, ~near.delta_light,
                      ~L.delta.take(np.maximum(y - 2, 0) * n + row) & ~delta_back)
        rest = h(a2) * (p2 + self.light.take(at_y))
        return h(a1) * (p1 + np.where(one, 0.0, rest))

    def _camera_side(self, C, t, row, near, n):
        """Sum over ``s' > s``: strategy ``s + 1`` (factor ``b1``), ``s + 2`` (``b1 b2``) and
        the stored rest (``b1 b2 camera[t - 1]``). ``n``: subpaths of the batch."""
        h = self.h
        z = t - 1
        at_z, at_prev = z * n + row, (z - 1) * n + row
        b1 = _ratio(near.light_s, C.pdf_fwd.take(at_z))
        # Strategy s + 1 connects z = x_s (never counted delta) to z_{t-2} (impossible where
        # it is delta; the pinhole z_0's flag is never set).
        p1 = ~C.delta.take(at_prev)
        b2 = _ratio(near.light_s1, C.pdf_fwd.take(at_prev))
        p2 = ~C.delta.take(np.maximum(z - 2, 0) * n + row) & p1
        rest = h(b2) * (p2 + self.camera.take(at_z))
        return h(b1) * (p1 + np.where(t == 2, 0.0, rest))


def heuristic(mis, r):
    """The summed heuristic's function of density ratios ``r >= 0``: ``r`` (balance),
    ``r ** beta`` (power), ``[r > 0]`` as float64 ('none': count the strategies that can)."""
    if mis.setting == "balance":
        return r
    if mis.setting == "power":
        with quiet("over"):
            return r ** mis.beta
    return (r > 0).astype(np.float64)
