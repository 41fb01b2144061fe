"""Meshing a prepared scene into radiosity patches, and reading the solution back at hits.

Every scene triangle is cut into ``n x n`` congruent sub-triangles, ``n = ceil(longest edge /
patch_size)`` (uniform subdivision to a target edge length). Each sub-triangle is two
*patches*, one per side: patch ``2 s`` is the front of sub-triangle ``s`` (the side its
geometric normal points to), patch ``2 s + 1`` its back. Surfaces here are two-sided, as in
Cycles (emission leaves both faces, both faces reflect), so the radiosity system needs both;
a side that sees nothing costs only its row of zeros.

Sub-triangles of triangle ``t`` are numbered from ``first[t]``: the "up" triangles ``(i, j)``
(grid corners ``(i, j), (i + 1, j), (i, j + 1)``, ``i + j <= n - 1``) row by row, then the
"down" ones (corners ``(i + 1, j + 1), (i, j + 1), (i + 1, j)``, ``i + j <= n - 2``), where grid
point ``(i, j)`` is ``v0 + (i / n) e1 + (j / n) e2``. A hit at Embree's barycentrics ``(u, v)``
falls in the grid cell ``(floor(u n), floor(v n))``, so :meth:`PatchMesh.locate` finds its patch
without a search.

Gouraud display: each patch corner gets the area-weighted mean radiosity of the patches that
share that point and face within :data:`CREASE_DEGREES` of the same way (so a wall corner is
not blurred into the floor, but a tessellated sphere is smooth), and a hit interpolates its
patch's three corners.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import RenderRefused

# Patches meeting at a point are averaged for Gouraud display when their normals differ by less.
CREASE_DEGREES = 30.0


def grid_triangles(n):
    """Local sub-triangles of an ``n``-segment triangle grid, in :mod:`mesh` order.

    Returns
    -------
    (n * n, 3, 2) int64
        Grid coordinates ``(i, j)`` of each sub-triangle's three corners.
    """
    up = [((i, j), (i + 1, j), (i, j + 1)) for i in range(n) for j in range(n - i)]
    down = [((i + 1, j + 1), (i, j + 1), (i + 1, j)) for i in range(n - 1)
            for j in range(n - 1 - i)]
    return np.array(up + down, np.int64).reshape(-1, 3, 2)


def local_index(i, j, down, n):
    """Sub-triangle number within its triangle of the grid cell ``(i, j)`` (arrays), up or
    ``down`` half, for ``n (k,)`` segments (see the module docstring)."""
    up_count = n * (n + 1) // 2
    up = i * n - i * (i - 1) // 2 + j
    dn = up_count + i * (n - 1) - i * (i - 1) // 2 + j
    return np.where(down, dn, up)


@dataclass
class PatchMesh:
    """Patches of a scene (both sides of every sub-triangle).

    Attributes
    ----------
    corners : (m, 3, 3) float64
        Corner positions of the ``m`` sub-triangles (same orientation as their triangle).
    sub_area : (m,) float64
    sub_normal : (m, 3) float64
        Unit geometric normal of each sub-triangle (its front side).
    sub_tri : (m,) int64
        Scene triangle of each sub-triangle.
    segments : (t,) int64
        ``n`` of every scene triangle (0 for degenerate ones, which have no patches).
    first : (t,) int64
        First sub-triangle of every scene triangle.
    albedo : (2 m, 3) float64
        Diffuse albedo of each patch (both sides of a sub-triangle alike).
    emission : (2 m, 3) float64
        Emitted radiosity ``E = pi Le`` (W / m^2) of each patch.
    corner_rows, corner_weights
        Gouraud averaging (see :meth:`corner_values`).
    node_children, node_leaf, base_node
        Adaptive refinement (:mod:`.adaptive`), or None for a uniform mesh: a quadtree below
        every grid sub-triangle, ``base_node (b,)`` its root node, ``node_children (k, 4)``
        (-1 at leaves; children in the parent's own frame: corner 0, 1, 2, middle) and
        ``node_leaf (k,)`` the sub-triangle of a leaf node.
    """

    corners: np.ndarray
    sub_area: np.ndarray
    sub_normal: np.ndarray
    sub_tri: np.ndarray
    segments: np.ndarray
    first: np.ndarray
    albedo: np.ndarray
    emission: np.ndarray
    corner_indptr: np.ndarray = None
    corner_rows: np.ndarray = None
    corner_weights: np.ndarray = None
    node_children: np.ndarray = None
    node_leaf: np.ndarray = None
    base_node: np.ndarray = None

    @property
    def n_patches(self):
        """Number of patches (unknowns): two per sub-triangle."""
        return 2 * self.sub_area.shape[0]

    @property
    def area(self):
        """``(p,)`` area of every patch."""
        return np.repeat(self.sub_area, 2)

    @property
    def normal(self):
        """``(p, 3)`` unit normal of every patch's own side."""
        n = np.repeat(self.sub_normal, 2, axis=0)
        n[1::2] *= -1.0
        return n

    def patch_corners(self, patches):
        """``(k, 3, 3)`` corner positions of ``patches (k,)``."""
        return self.corners[np.asarray(patches) // 2]

    def locate(self, prim, u, v, back):
        """Patches under hits on scene triangles ``prim (k,)`` at Embree's ``u, v (k,)``, seen
        from the ``back (k,) bool`` side; and the hit's weights of the patch's three corners.

        Returns
        -------
        patch : (k,) int64
        weights : (k, 3) float64
        """
        n = self.segments[prim]
        nf = n.astype(np.float64)
        gu, gv = np.asarray(u, np.float64) * nf, np.asarray(v, np.float64) * nf
        i = np.clip(np.floor(gu).astype(np.int64), 0, np.maximum(n - 1, 0))
        j = np.clip(np.floor(gv).astype(np.int64), 0, np.maximum(n - 1 - i, 0))
        fu, fv = gu - i, gv - j
        down = (fu + fv > 1.0) & (i + j <= n - 2)
        sub = self.first[prim] + local_index(i, j, down, n)
        # Coordinates in the sub-triangle's own frame (weights of its corners 1 and 2).
        a, b = np.where(down, 1.0 - fu, fu), np.where(down, 1.0 - fv, fv)
        if self.node_children is not None:
            sub, a, b = self._descend(sub, a, b)
        weights = np.clip(np.stack([1.0 - a - b, a, b], axis=1), 0.0, 1.0)
        weights /= np.maximum(weights.sum(axis=1, keepdims=True), 1e-300)
        return 2 * sub + np.asarray(back, np.int64), weights

    def _descend(self, base, a, b):
        """Leaf sub-triangles and own-frame coordinates below grid sub-triangles ``base``."""
        node = self.base_node[base]
        while True:
            inner = np.nonzero(self.node_children[node, 0] >= 0)[0]
            if inner.size == 0:
                return self.node_leaf[node], a, b
            ai, bi = a[inner], b[inner]
            child = np.where(ai >= 0.5, 1, np.where(bi >= 0.5, 2,
                                                    np.where(ai + bi < 0.5, 0, 3)))
            a = a.copy()
            b = b.copy()
            a[inner] = np.select([child == 0, child == 1, child == 2], [2 * ai, 2 * ai - 1, 2 * ai],
                                 1 - 2 * ai)
            b[inner] = np.select([child == 0, child == 1, child == 2], [2 * bi, 2 * bi, 2 * bi - 1],
                                 1 - 2 * bi)
            node = node.copy()
            node[inner] = self.node_children[node[inner], child]

    def corner_values(self, values):
        """Gouraud corner values ``(p, 3, c)`` of per-patch ``values (p, c)``: at each corner,
        the area-weighted mean over the patches that share the point and face the same way
        (within :data:`CREASE_DEGREES`)."""
        values = np.asarray(values, np.float64)
        gathered = values[self.corner_rows] * self.corner_weights[:, None]
        sums = np.add.reduceat(gathered, self.corner_indptr[:-1], axis=0)
        return sums.reshape(self.n_patches, 3, values.shape[1])


def build_mesh(prep, patch_size, max_patches=None, power_of_two=False):
    """Patches of the prepared scene ``prep``'s triangles at edge length about ``patch_size``.

    Parameters
    ----------
    prep : core.prepare.PreparedScene
    patch_size : float
        Target edge length (Blender units); every triangle is cut into ``n^2`` sub-triangles
        with ``n = ceil(longest edge / patch_size)``.
    max_patches : int or None
        Raise ``ValueError`` (with the count and what to change) if the mesh would have more.
    power_of_two : bool
        Round every ``n`` up to a power of two (the leaves of hierarchical radiosity's
        quadtrees, :mod:`.hierarchical`).

    Returns
    -------
    PatchMesh
    """
    if not patch_size > 0:
        raise RenderRefused(f"radiosity patch size must be positive, got {patch_size!r}")
    e1, e2 = prep.tri_e1, prep.tri_e2
    longest = np.sqrt(np.max([np.einsum("ij,ij->i", e, e) for e in (e1, e2, e2 - e1)], axis=0))
    n = np.where(prep.tri_area > 0, np.ceil(longest / patch_size - 1e-9), 0).astype(np.int64)
    n = np.maximum(n, (prep.tri_area > 0).astype(np.int64))
    if power_of_two:
        n = np.where(n > 0, 1 << np.ceil(np.log2(np.maximum(n, 1))).astype(np.int64), 0)
    count = int(2 * np.sum(n * n))
    if max_patches is not None and count > max_patches:
        raise RenderRefused(f"radiosity: a patch size of {patch_size:g} gives {count:,} "
                            f"patches, more than the {max_patches:,} this solver can hold; "
                            f"raise the patch size or choose the Progressive or Hierarchical "
                            f"solver")
    first = np.concatenate([[0], np.cumsum(n * n)[:-1]]).astype(np.int64)
    m = int(np.sum(n * n))
    corners = np.zeros((m, 3, 3))
    sub_tri = np.zeros(m, np.int64)
    for k in np.unique(n[n > 0]):
        tris = np.nonzero(n == k)[0]
        grid = grid_triangles(int(k)).astype(np.float64) / k  # (k^2, 3, 2)
        rows = (first[tris][:, None] + np.arange(k * k)[None, :]).reshape(-1)
        pos = (prep.tri_v0[tris][:, None, None, :]
               + grid[None, :, :, 0:1] * e1[tris][:, None, None, :]
               + grid[None, :, :, 1:2] * e2[tris][:, None, None, :])
        corners[rows] = pos.reshape(-1, 3, 3)
        sub_tri[rows] = np.repeat(tris, k * k)
    normal = prep.tri_normal[sub_tri]
    area = prep.tri_area[sub_tri] / (n[sub_tri] ** 2).astype(np.float64)
    albedo = np.repeat(prep.tri_albedo[sub_tri], 2, axis=0)
    emission = np.pi * np.repeat(prep.tri_emission[sub_tri], 2, axis=0)
    mesh = PatchMesh(corners, area, normal, sub_tri, n, first, albedo, emission)
    _gouraud_table(mesh)
    return mesh


def _gouraud_table(mesh):
    """Fill ``mesh.corner_indptr / corner_rows / corner_weights``: for every patch corner (row
    ``3 p + c``) the patches averaged there and their normalised area weights."""
    p = mesh.n_patches
    pos = np.repeat(mesh.corners, 2, axis=0).reshape(-1, 3)  # (3 p, 3)
    patch = np.repeat(np.arange(p), 3)
    normal = mesh.normal[patch]
    area = mesh.area[patch]
    scale = max(float(np.abs(pos).max()) if pos.size else 1.0, 1e-30)
    key = np.round(pos / (scale * 1e-6)).astype(np.int64)
    _, group = np.unique(key, axis=0, return_inverse=True)
    group = group.reshape(-1)
    order = np.argsort(group, kind="stable")
    sizes = np.bincount(group)
    start = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    cos_crease = np.cos(np.radians(CREASE_DEGREES))
    rows, cols, weights = [], [], []
    g_of = group[order]
    base = start[g_of]
    size = sizes[g_of]
    for d in range(int(sizes.max()) if sizes.size else 0):
        has = d < size
        me = order[has]
        other = order[(base + d)[has]]
        same_way = np.einsum("ij,ij->i", normal[me], normal[other]) >= cos_crease
        rows.append(me[same_way])
        cols.append(patch[other[same_way]])
        weights.append(area[other[same_way]])
    rows = np.concatenate(rows) if rows else np.zeros(0, np.int64)
    cols = np.concatenate(cols) if cols else np.zeros(0, np.int64)
    weights = np.concatenate(weights) if weights else np.zeros(0)
    sort = np.argsort(rows, kind="stable")
    rows, cols, weights = rows[sort], cols[sort], weights[sort]
    total = np.bincount(rows, weights, minlength=3 * p)
    mesh.corner_indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=3 * p))])
    mesh.corner_rows = cols
    mesh.corner_weights = weights / total[rows]
