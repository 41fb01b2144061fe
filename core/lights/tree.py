"""A light tree over the finite emitters: bounds, importance, traversal and the exact pmf.

The method of Conty Estevez and Kulla (2018), "Importance Sampling of Many Lights With Adaptive
Tree Splitting", as pbrt-v4's ``BVHLightSampler`` and Cycles' light tree use it (without the
adaptive splitting: one emitter per traversal). Every node bounds its emitters by

- an axis-aligned box (position),
- an orientation cone: an ``axis``, ``theta_o`` bounding the angle between the axis and every
  emitter's normal (pi for omnidirectional or two-sided emitters), and ``theta_e``, the angle
  beyond the normal cone in which they still emit (pi / 2 for a cosine emitter, 0 for a delta
  spot),
- and their total power.

From a receiving point ``p`` (and optionally its shading normal ``n``) a node's *importance* is
``power * cos(theta') / d^2`` (pbrt-v4's ``LightBounds::Importance``): ``d`` the distance to the
box centre (at least the box's half diagonal), ``theta'`` the angle between the cone and the
direction to ``p`` reduced by the cone's ``theta_o`` and the angle ``theta_b`` the box subtends
(zero where ``theta' >= theta_e``: ``p`` behind every emitter of the node); with ``n``, times
``cos`` of the angle to the normal reduced by ``theta_b`` (two-sided, as the receiver may
transmit). The bounds are conservative, so an emitter that can light ``p`` always has a
positive probability; where both children of a node have importance zero the choice falls back
to their power, so the pmf sums to one for every ``(p, n)``.

The tree is built once per render by median splits of the emitters' centroids along the
widest axis, all nodes of a level at once, so it is balanced and its depth is
``ceil(log2 emitters)``. Traversal moves all receiving points one level per step; the pmf of a
given emitter walks its stored root path with the same arithmetic, so :meth:`LightTree.pmf`
equals the pmf :meth:`LightTree.choose` returns bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene import LIGHT_DISK, LIGHT_POINT, LIGHT_RECT
from ..quiet import quiet

PI = np.pi
HALF_PI = 0.5 * np.pi
# Below this squared distance a receiving point sits on a zero-size emitter's bounds.
MIN_DIST2 = 1e-30


def _dot(a, b):
    """Row-wise dot products ``(m,)`` of ``a, b (m, 3)``, summed in a fixed order."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


@dataclass
class EmitterBounds:
    """Bounds of finite emitters, one row per emitter.

    Attributes
    ----------
    index : (m,) int64
        Emitter rows (of :class:`.sampler.LightSampler`'s table).
    lo, hi : (m, 3) float64
        Axis-aligned box.
    axis : (m, 3) float64
        Unit axis of the normal cone.
    theta_o, theta_e : (m,) float64
        Normal-cone and emission half-angles (radians).
    power : (m,) float64
        Estimated power (positive).
    """

    index: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    axis: np.ndarray
    theta_o: np.ndarray
    theta_e: np.ndarray
    power: np.ndarray

    @staticmethod
    def concatenate(parts):
        """One table of the rows of ``parts``."""
        return EmitterBounds(*(np.concatenate([getattr(b, f) for b in parts])
                               for f in ("index", "lo", "hi", "axis", "theta_o", "theta_e",
                                         "power")))

    def select(self, rows):
        """The bounds of ``rows``."""
        return EmitterBounds(self.index[rows], self.lo[rows], self.hi[rows], self.axis[rows],
                             self.theta_o[rows], self.theta_e[rows], self.power[rows])

    def alike(self):
        """Whether every row has the same box and cone (the axis counts only where the cone is
        narrower than the whole sphere): then every node of a tree over them has the same
        bounds, its importance is its power times one factor for all nodes, and the tree
        chooses in proportion to power from every receiving point. The two triangles of an
        emissive quad share their box, and two-sided triangles the whole sphere of normals."""
        if self.index.size < 2:
            return True
        same = [np.all(x == x[0]) for x in (self.lo, self.hi, self.theta_o, self.theta_e)]
        narrow = self.theta_o < PI
        return bool(all(same) and (not narrow.any() or np.all(self.axis == self.axis[0])))


def lamp_bounds(lights, rows, power):
    """Bounds of the finite lamps ``rows (m,)`` of ``lights`` (point, spot, sphere, area).

    Points and spheres emit in every direction (``theta_o = pi``); a spot's cone is its half
    angle (``theta_e = 0`` for a delta spot, ``pi / 2`` with a radius, whose sphere or facing
    disk widens it); an area lamp emits from one side toward ``direction`` (``theta_o = 0``,
    ``theta_e = pi / 2``).

    Parameters
    ----------
    lights : core.scene.Lights
    rows : (m,) int64
    power : (m,) float64
    """
    kind = lights.kind[rows]
    pos = lights.position[rows].astype(np.float64)
    radius = np.where(kind == LIGHT_POINT, lights.radius[rows], 0.0)
    area = (kind == LIGHT_RECT) | (kind == LIGHT_DISK)
    # Half extent of a parallelogram (the bound of its inscribed disk or ellipse too).
    half = 0.5 * (np.abs(lights.axis_x[rows]) + np.abs(lights.axis_y[rows]))
    ext = np.where(area[:, None], half, radius[:, None])
    spot = (kind == LIGHT_POINT) & (lights.spot_cos_half[rows] > -1)
    theta_o = np.where(area, 0.0, np.where(spot, np.arccos(np.clip(lights.spot_cos_half[rows],
                                                                   -1, 1)), PI))
    theta_e = np.where(spot & (radius == 0), 0.0, HALF_PI)
    axis = np.where((area | spot)[:, None], lights.direction[rows], [0.0, 0.0, 1.0])
    return EmitterBounds(np.asarray(rows, np.int64), pos - ext, pos + ext,
                         axis.astype(np.float64), theta_o, theta_e,
                         np.asarray(power, np.float64))


def triangle_bounds(triangles, first_row, power):
    """Bounds of the emissive triangles (two-sided: ``theta_o = pi``).

    Parameters
    ----------
    triangles : core.lights.triangles.EmissiveTriangles
    first_row : int
        Emitter row of the first emissive triangle.
    power : (e,) float64
    """
    v0 = triangles.emit_v0
    v1, v2 = v0 + triangles.emit_e1, v0 + triangles.emit_e2
    e = v0.shape[0]
    return EmitterBounds(first_row + np.arange(e, dtype=np.int64),
                         np.minimum(np.minimum(v0, v1), v2), np.maximum(np.maximum(v0, v1), v2),
                         triangles.emit_normal.astype(np.float64), np.full(e, PI),
                         np.full(e, HALF_PI), np.asarray(power, np.float64))


def _range_reduce(ufunc, values, lo, hi):
    """``ufunc`` over ``values[lo[i]:hi[i]]`` for every node ``i`` (non-empty ranges)."""
    padded = np.concatenate([values, values[:1]])
    idx = np.empty(2 * lo.size, np.int64)
    idx[0::2], idx[1::2] = lo, hi
    return ufunc.reduceat(padded, idx, axis=0)[0::2]


class LightTree:
    """A balanced binary tree over finite emitters, traversed per receiving point.

    Parameters
    ----------
    bounds : EmitterBounds
        At least one emitter, every power positive.

    Attributes
    ----------
    left, right : (nodes,) int64
        Children (-1 at leaves); node 0 is the root.
    leaf_emitter : (nodes,) int64
        Emitter row of each leaf (-1 at inner nodes).
    center, radius2 : (nodes, 3), (nodes,) float64
        Box centre and squared half diagonal.
    axis, theta_o, theta_e, power : node cones and powers
    path_node : (leaves, depth) int64
        Inner nodes from the root to each leaf (-1 past it), leaves in emitter order.
    path_left : (leaves, depth) bool
        Whether the path goes left at each of them.
    depth : int
        Number of inner levels (the bound of every traversal loop).
    """

    def __init__(self, bounds: EmitterBounds):
        m = bounds.index.size
        centroid = 0.5 * (bounds.lo + bounds.hi)
        perm = np.arange(m)
        node_lo, node_hi = np.array([0]), np.array([m])
        left, right, parent = np.array([-1]), np.array([-1]), np.array([-1])
        level = np.array([0])
        while True:
            L, H = node_lo[level], node_hi[level]
            split = (H - L) >= 2
            if not split.any():
                break
            s, L, H = level[split], L[split], H[split]
            count = H - L
            starts = np.cumsum(count) - count
            # Sort each node's emitters by centroid along the node's widest axis, then halve.
            seg = np.repeat(np.arange(s.size), count)
            pos = L[seg] + np.arange(seg.size) - starts[seg]
            c = centroid[perm[pos]]
            ext = np.maximum.reduceat(c, starts, axis=0) - np.minimum.reduceat(c, starts, axis=0)
            ax = np.argmax(ext, axis=1)
            order = np.lexsort((c[np.arange(seg.size), ax[seg]], seg))
            perm[pos] = perm[pos[order]]
            mid = L + count // 2
            kids = left.size + np.arange(2 * s.size)
            node_lo = np.concatenate([node_lo, np.stack([L, mid], axis=1).ravel()])
            node_hi = np.concatenate([node_hi, np.stack([mid, H], axis=1).ravel()])
            left = np.concatenate([left, np.full(kids.size, -1)])
            right = np.concatenate([right, np.full(kids.size, -1)])
            parent = np.concatenate([parent, np.repeat(s, 2)])
            left[s], right[s] = kids[0::2], kids[1::2]
            level = kids
        n_nodes = left.size
        self.left, self.right = left, right
        leaf = self.left < 0
        self.leaf_emitter = np.where(leaf, bounds.index[perm[np.minimum(node_lo, m - 1)]], -1)

        # Node bounds straight from each node's range of the final order.
        b = bounds.select(perm)
        box_lo = _range_reduce(np.minimum, b.lo, node_lo, node_hi)
        box_hi = _range_reduce(np.maximum, b.hi, node_lo, node_hi)
        self.center = 0.5 * (box_lo + box_hi)
        self.radius2 = 0.25 * _dot(box_hi - box_lo, box_hi - box_lo)
        self.power = _range_reduce(np.add, b.power, node_lo, node_hi)
        self.theta_e = _range_reduce(np.maximum, b.theta_e, node_lo, node_hi)
        # Cone axis: power-weighted mean of the directional emitters' axes.
        directional = (b.theta_o < PI)[:, None] * b.power[:, None]
        axis = _range_reduce(np.add, b.axis * directional, node_lo, node_hi)
        norm = np.sqrt(_dot(axis, axis))
        ok = norm > 1e-12 * np.maximum(self.power, 1e-300)
        self.axis = np.where(ok[:, None], axis / np.where(ok, norm, 1.0)[:, None], [0.0, 0, 1])
        # theta_o: the widest emitter cone around the node's axis.
        count = node_hi - node_lo
        seg = np.repeat(np.arange(node_lo.size), count)
        pos = node_lo[seg] + np.arange(seg.size) - np.repeat(np.cumsum(count) - count, count)
        cos_ax = np.clip(_dot(self.axis[seg], b.axis[pos]), -1.0, 1.0)
        spread = np.minimum(np.arccos(cos_ax) + b.theta_o[pos], PI)
        self.theta_o = np.where(ok, np.maximum.reduceat(spread, np.cumsum(count) - count), PI)
        self.cos_o, self.sin_o = np.cos(self.theta_o), np.sin(self.theta_o)
        self.cos_e = np.cos(self.theta_e)
        self.packed_t = np.ascontiguousarray(np.column_stack([
            self.center, self.axis, self.radius2, self.power, self.cos_o, self.sin_o,
            self.cos_e]).T.astype(np.float32))
        # Two-sided triangles and point lights only: no orientation term to evaluate.
        self.omni = bool(np.all(self.theta_o >= PI))
        self.packed_omni = np.ascontiguousarray(self.packed_t[[0, 1, 2, 6, 7]])
        self.children = np.stack([self.left, self.right])
        self.child_pairs = self.children.T.ravel()
        # Where both children are dark, go by power (at inner nodes; 0.5 elsewhere, unused).
        inner = self.left >= 0
        pw_l = np.where(inner, self.power[np.maximum(self.left, 0)], 1.0)
        pw_r = np.where(inner, self.power[np.maximum(self.right, 0)], 1.0)
        self.fallback_left = pw_l / (pw_l + pw_r)

        # Root paths, leaves in emitter order: walk up from every leaf one level per step.
        leaves = leaf.nonzero()[0]
        order = np.argsort(self.leaf_emitter[leaves])
        self.leaf_rows = self.leaf_emitter[leaves][order]
        node = leaves[order]
        steps = []
        for _ in range(n_nodes):
            par = parent[node]
            if (par < 0).all():
                break
            steps.append((np.where(par >= 0, par, -1),
                          np.where(par >= 0, self.left[np.maximum(par, 0)] == node, False)))
            node = np.where(par >= 0, par, node)
        self.depth = len(steps)
        self.path_node = np.full((leaves.size, self.depth), -1, np.int64)
        self.path_left = np.zeros((leaves.size, self.depth), bool)
        for d, (par, is_left) in enumerate(steps):
            # Ancestors were found bottom-up: shift each leaf's path to start at the root.
            self.path_node[:, d], self.path_left[:, d] = par, is_left
        lengths = (self.path_node >= 0).sum(axis=1)
        col = (lengths[:, None] - 1 - np.arange(self.depth)[None, :])
        valid = col >= 0
        rows = np.arange(leaves.size)[:, None]
        src = np.where(valid, col, 0)
        self.path_node = np.where(valid, self.path_node[rows, src], -1)
        self.path_left = np.where(valid, self.path_left[rows, src], False)
        self.n_nodes = n_nodes

    # ------------------------------------------------------------------ importance
    def importance(self, node, p, n=None):
        """Importance of nodes ``node`` for receiving points ``p`` with shading normals ``n``
        (or None: no receiver term); see the module docstring.

        Parameters
        ----------
        node : (..., m) int64
        p : (3, m) float32
            Receiving points by component (see :meth:`_components`).
        n : (3, m) float32 or None

        Returns
        -------
        (..., m) float32

        Angle differences are taken on cosines and sines (``cos(a - b)``), as pbrt-v4 does,
        and in float32 on component arrays: the importance only steers the choice, and the pmf
        is whatever this function gives, the same in :meth:`choose` and :meth:`pmf`.
        """
        # One gather of every node field: centre (3), axis (3), r^2, power, cos_o, sin_o,
        # cos_e, each a contiguous (..., m) array.
        if self.omni:
            # No cone to evaluate: gather only centre, r^2 and power.
            cx, cy, cz, r2, power = self.packed_omni[:, node]
        else:
            cx, cy, cz, ax, ay, az, r2, power, cos_o, sin_o, cos_e = self.packed_t[:, node]
        vx, vy, vz = p[0] - cx, p[1] - cy, p[2] - cz
        d2 = np.maximum(vx * vx + vy * vy + vz * vz, MIN_DIST2)
        if self.omni and n is None:
            # Every emitter lights every direction and there is no receiver term: the
            # orientation factor is one.
            return (power / np.maximum(d2, r2)).astype(np.float32, copy=False)
        inv_d = 1.0 / np.sqrt(d2)
        inside = d2 <= r2
        # The bounding sphere subtends theta_b (sin^2 = r^2 / d^2), pi from inside it.
        sin2_b = np.minimum(r2 / d2, 1.0)
        if inside.any():
            cos_b = np.where(inside, -1.0, np.sqrt(1.0 - sin2_b)).astype(np.float32)
            sin_b = np.where(inside, 0.0, np.sqrt(sin2_b)).astype(np.float32)
        else:
            # Every point outside every bounding sphere (the usual case): no selection.
            cos_b = np.sqrt(1.0 - sin2_b).astype(np.float32, copy=False)
            sin_b = np.sqrt(sin2_b).astype(np.float32, copy=False)
        if self.omni:
            imp = power / np.maximum(d2, r2)
        else:
            cos_w = np.clip((ax * vx + ay * vy + az * vz) * inv_d, -1.0, 1.0)
            sin_w = np.sqrt(1.0 - cos_w * cos_w)
            # theta_x = max(theta_w - theta_o, 0), then theta_p = max(theta_x - theta_b, 0).
            past_o = cos_w < cos_o
            cos_x = np.where(past_o, cos_w * cos_o + sin_w * sin_o, 1.0)
            sin_x = np.where(past_o, sin_w * cos_o - cos_w * sin_o, 0.0)
            past_b = cos_x < cos_b
            cos_p = np.where(past_b, cos_x * cos_b + sin_x * sin_b, 1.0)
            emits = ~past_b | (cos_p > cos_e)
            imp = np.where(emits, power * np.maximum(cos_p, 0.0) / np.maximum(d2, r2), 0.0)
        if n is not None:
            cos_i = np.minimum(np.abs(n[0] * vx + n[1] * vy + n[2] * vz) * inv_d, 1.0)
            sin_i = np.sqrt(1.0 - cos_i * cos_i)
            cos_ip = np.where(cos_i < cos_b, cos_i * cos_b + sin_i * sin_b, 1.0)
            imp = imp * np.maximum(cos_ip, 0.0)
        return imp.astype(np.float32, copy=False)

    @staticmethod
    def _components(a):
        """``(3, m)`` float32 components of points or normals ``a (m, 3)`` (None stays None)."""
        return None if a is None else np.ascontiguousarray(np.asarray(a, np.float32).T)

    def _p_left(self, node, p, n):
        """Probability ``(m,)`` float64 of going left at inner nodes ``node (m,)``, or at the
        one inner node ``node`` (an int: the root, where every descent starts): the children's
        importance share, their power share where both are zero. ``p, n`` as in
        :meth:`importance`."""
        # One node for all points: its children's fields broadcast, nothing is gathered.
        kids = self.children[:, [node]] if np.ndim(node) == 0 else self.children[:, node]
        il, ir = self.importance(kids, p, n)
        tot = il.astype(np.float64) + ir
        with quiet("divide", "invalid"):
            return np.where(tot > 0, il / tot, self.fallback_left[node])

    # ------------------------------------------------------------------ sampling
    def choose(self, u, p, n=None):
        """Descend from the root for every receiving point.

        Parameters
        ----------
        u : (m,) float64
            Uniform in [0, 1), remapped at each level.
        p : (m, 3) float64
        n : (m, 3) float64 or None

        Returns
        -------
        index : (m,) int64
            Emitter rows.
        pmf : (m,) float64
            Probability of each within the tree.
        """
        m = u.shape[0]
        node = np.zeros(m, np.int64)
        pmf = np.ones(m)
        u = np.array(u, np.float64)
        pc, nc = self._components(p), self._components(n)
        for level in range(self.depth):
            act = np.nonzero(self.left[node] >= 0)[0]
            if not act.size:
                break
            full = act.size == m
            # While every point is still inside the tree, work on whole arrays (no gathers).
            nd = node if full else node[act]
            ua = u if full else u[act]
            pl = (self._p_left(0 if level == 0 else nd, pc, nc) if full else
                  self._p_left(nd, pc[:, act], None if nc is None else nc[:, act]))
            go_right = ua >= pl
            prob = np.where(go_right, 1.0 - pl, pl)
            # Remap u to [0, 1) within the chosen side for the next level.
            with quiet("divide", "invalid"):
                ua = np.minimum((ua - go_right * pl) / prob, 1.0 - 2.0**-53)
            nd = self.child_pairs[2 * nd + go_right]
            if full:
                u, pmf, node = ua, pmf * prob, nd
            else:
                u[act], pmf[act], node[act] = ua, pmf[act] * prob, nd
        return self.leaf_emitter[node], pmf

    def pmf(self, index, p, n=None):
        """Probability ``(m,)`` that :meth:`choose` from ``p (m, 3)``, ``n`` returns emitter rows
        ``index (m,)`` (0 for rows not in the tree)."""
        leaf = np.searchsorted(self.leaf_rows, index)
        leaf = np.minimum(leaf, self.leaf_rows.size - 1)
        inside = self.leaf_rows[leaf] == index
        out = inside.astype(np.float64)
        pc, nc = self._components(p), self._components(n)
        for d in range(self.depth):
            act = np.nonzero(inside & (self.path_node[leaf, d] >= 0))[0]
            if not act.size:
                break
            nd = 0 if d == 0 else self.path_node[leaf[act], d]  # every path starts at the root
            if act.size == out.size:
                pl = self._p_left(nd, pc, nc)
            else:
                pl = self._p_left(nd, pc[:, act], None if nc is None else nc[:, act])
            prob = np.where(self.path_left[leaf[act], d], pl, 1.0 - pl)
            out[act] = out[act] * prob
        return out
