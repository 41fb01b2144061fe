"""Hierarchical radiosity (Hanrahan, Salzman & Aupperle 1991).

Every scene triangle is the root of a quadtree of elements: an element splits at its edge
midpoints into four, down to the leaves, the uniform mesh's patches at ``2^L`` segments per
edge (``build_mesh(..., power_of_two=True)``). Light is exchanged along *links* between element
sides, each made at the coarsest level where the pair's form factor is small:

1. **Refine** (breadth first, over arrays of candidate pairs): the oracle estimates a pair's
   form factor both ways from each element's centroid to the other's polygon (unoccluded,
   :func:`.form_factors.point_polygon_form_factor`). Below ``epsilon`` both ways, or with both
   elements leaves, the pair becomes a link; otherwise the larger element (that is not a leaf)
   is split and its four children paired with the other. Starting from all pairs of root sides
   that face each other, the number of links grows about linearly with the leaves (HSA91's
   O(n) argument), instead of the ``n^2`` pairs of the dense matrix.
2. **Link form factors** by the same estimator as the dense matrix
   (:func:`.form_factors.pair_form_factors`, visibility by Embree); a link between two leaves
   uses the patch numbers as its random keys, so with ``epsilon = 0`` every link is a leaf
   pair and the system is exactly the dense one.
3. **Solve** by Jacobi sweeps over the hierarchy: each element side gathers ``H = sum F B``
   over its links; *push* adds every element's gathered irradiance to its descendants; leaves
   set ``B = E + rho H``; *pull* makes every parent the area-weighted mean of its children.

Bias: on top of the uniform mesh's, a link approximates the form factor between every pair of
descendants by the coarse one, an error that ``epsilon`` bounds (it shrinks with it).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import RenderRefused
from . import form_factors as ff
from .mesh import build_mesh, local_index

# Root pairs (all input triangles' sides against each other) are formed in blocks of this many.
ROOT_BLOCK = 1 << 20
# Input triangles beyond which linking every pair of roots would take too long.
MAX_ROOTS = 4_000


@dataclass
class Elements:
    """The quadtrees of all scene triangles, one row per element (sides are ``2 e + s``).

    ``corners``, ``sub_normal`` and ``sub_tri`` have the names :class:`.mesh.PatchMesh` uses,
    so the form-factor routines take an ``Elements`` as a mesh.
    """

    corners: np.ndarray      # (e, 3, 3)
    sub_normal: np.ndarray   # (e, 3)
    sub_tri: np.ndarray      # (e,)
    area: np.ndarray         # (e,)
    level: np.ndarray        # (e,)
    parent: np.ndarray       # (e,), -1 for roots
    children: np.ndarray     # (e, 4), -1 for leaves
    patch_sub: np.ndarray    # (e,), the mesh's sub-triangle of a leaf, -1 otherwise

    @property
    def n(self):
        return self.area.shape[0]


def build_elements(prep, mesh):
    """The quadtrees over ``prep``'s triangles whose leaves are ``mesh``'s sub-triangles
    (a mesh built with ``power_of_two=True``)."""
    n = mesh.segments
    levels = np.where(n > 0, np.log2(np.maximum(n, 1)).round().astype(np.int64), -1)
    count = np.where(levels >= 0, (4 ** (levels + 1) - 1) // 3, 0)
    start = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    total = int(count.sum())
    corners = np.zeros((total, 3, 3))
    tri, lev = np.zeros(total, np.int64), np.zeros(total, np.int64)
    parent, children = np.full(total, -1, np.int64), np.full((total, 4), -1, np.int64)
    patch_sub = np.full(total, -1, np.int64)
    for level in range(int(levels.max()) + 1 if levels.size else 0):
        tris = np.nonzero(levels >= level)[0]
        side = 1 << level
        i, j, down = _cells(side)
        ids = (start[tris][:, None] + (4 ** level - 1) // 3 + np.arange(side * side)[None])
        gi = np.stack([np.where(down, i + 1, i), np.where(down, i, i + 1),
                       np.where(down, i + 1, i)], axis=1)
        gj = np.stack([np.where(down, j + 1, j), np.where(down, j + 1, j),
                       np.where(down, j, j + 1)], axis=1)
        pos = (prep.tri_v0[tris][:, None, None, :]
               + (gi / side)[None, :, :, None] * prep.tri_e1[tris][:, None, None, :]
               + (gj / side)[None, :, :, None] * prep.tri_e2[tris][:, None, None, :])
        flat = ids.reshape(-1)
        corners[flat] = pos.reshape(-1, 3, 3)
        tri[flat], lev[flat] = np.repeat(tris, side * side), level
        leaf = levels[tris] == level
        if leaf.any():
            patch_sub[ids[leaf].reshape(-1)] = (mesh.first[tris[leaf]][:, None]
                                                + np.arange(side * side)[None]).reshape(-1)
        inner = ~leaf
        if inner.any():
            kids = _child_cells(i, j, down, side)  # (side^2, 4) local ids at level + 1
            child_ids = (start[tris[inner]][:, None, None] + (4 ** (level + 1) - 1) // 3
                         + kids[None])
            children[ids[inner].reshape(-1)] = child_ids.reshape(-1, 4)
            parent[child_ids.reshape(-1)] = np.repeat(ids[inner].reshape(-1), 4)
    e1 = corners[:, 1] - corners[:, 0]
    e2 = corners[:, 2] - corners[:, 0]
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
    return Elements(corners, prep.tri_normal[tri], tri, area, lev, parent, children, patch_sub)


def _cells(side):
    """``i, j, down`` of every sub-triangle of a ``side``-segment grid, in mesh order."""
    up = [(i, j, False) for i in range(side) for j in range(side - i)]
    dn = [(i, j, True) for i in range(side - 1) for j in range(side - 1 - i)]
    cells = np.array(up + dn, dtype=np.int64).reshape(-1, 3)
    return cells[:, 0], cells[:, 1], cells[:, 2].astype(bool)


def _child_cells(i, j, down, side):
    """Local numbers ``(k, 4)`` at the next level of the four children of cells ``i, j, down``."""
    n2 = np.full(i.size, 2 * side)
    up_kids = [(2 * i, 2 * j, False), (2 * i + 1, 2 * j, False), (2 * i, 2 * j + 1, False),
               (2 * i, 2 * j, True)]
    down_kids = [(2 * i + 1, 2 * j + 1, True), (2 * i, 2 * j + 1, True),
                 (2 * i + 1, 2 * j, True), (2 * i + 1, 2 * j + 1, False)]
    out = []
    for (ui, uj, ud), (di, dj, dd) in zip(up_kids, down_kids):
        ci, cj = np.where(down, di, ui), np.where(down, dj, uj)
        cd = np.where(down, dd, ud)
        out.append(local_index(ci, cj, cd, n2))
    return np.stack(out, axis=1)


def _sides(el, es):
    """Unit normals ``(k, 3)`` of element sides ``es``."""
    return np.where((es % 2 == 0)[:, None], 1.0, -1.0) * el.sub_normal[es // 2]


def oracle(el, p, q):
    """Unoccluded form factor estimates ``(k,)`` of element-side pairs, the larger of the two
    directions, each from one element's centroid to the other's (clipped) polygon."""
    out = np.zeros(p.size)
    for a, b in ((p, q), (q, p)):
        na = _sides(el, a)
        centre = el.corners[a // 2].mean(axis=1)
        poly = ff.clip_to_plane(el.corners[b // 2], centre, na)
        out = np.maximum(out, ff.point_polygon_form_factor(centre, na, poly))
    return out


def refine(el, epsilon, check=None):
    """Links ``(receiver, source)`` of element sides (module docstring, step 1)."""
    roots = np.nonzero(el.parent < 0)[0]
    root_sides = np.concatenate([2 * roots, 2 * roots + 1])
    eps_plane = ff.plane_eps(el)
    none = np.zeros(0, np.int64)
    links = [(none, none)]
    frontier = [(none, none)]
    step = max(1, ROOT_BLOCK // max(root_sides.size, 1))
    for a in range(0, root_sides.size, step):
        p = np.repeat(root_sides[a:a + step], root_sides.size)
        q = np.tile(root_sides, min(step, root_sides.size - a))
        keep = (p != q) & ff.facing(el, p, q, eps_plane)
        frontier.append((p[keep], q[keep]))
    p = np.concatenate([f[0] for f in frontier])
    q = np.concatenate([f[1] for f in frontier])
    round_ = 0
    while p.size:
        round_ += 1
        if check is not None and check(min(0.3, 0.05 * round_)):
            return None
        leaf_p = el.children[p // 2, 0] < 0
        leaf_q = el.children[q // 2, 0] < 0
        small = oracle(el, p, q) <= epsilon
        done = small | (leaf_p & leaf_q)
        links.append((p[done], q[done]))
        p, q, leaf_p, leaf_q = p[~done], q[~done], leaf_p[~done], leaf_q[~done]
        split_p = ~leaf_p & (leaf_q | (el.area[p // 2] >= el.area[q // 2]))
        new_p, new_q = _split(el, p[split_p], q[split_p])
        new_q2, new_p2 = _split(el, q[~split_p], p[~split_p])
        p = np.concatenate([new_p, new_p2])
        q = np.concatenate([new_q, new_q2])
        keep = ff.facing(el, p, q, eps_plane)
        p, q = p[keep], q[keep]
    return (np.concatenate([lk[0] for lk in links]), np.concatenate([lk[1] for lk in links]))


def _split(el, a, b):
    """Pairs of the four children of element sides ``a`` (same side) with ``b``."""
    kids = el.children[a // 2]  # (k, 4)
    child_sides = 2 * kids + (a % 2)[:, None]
    return child_sides.reshape(-1), np.repeat(b, 4)


def gather_solve(el, links, F, E_leaf, rho_leaf, leaf_sides, tol, max_iterations=500,
                 check=None):
    """Jacobi sweeps with push-pull over the hierarchy (module docstring, step 3).

    Returns ``B`` of every element side ``(2 e, 3)``, sweeps, residual and whether cancelled.
    """
    m = 2 * el.n
    B = np.zeros((m, 3))
    B[leaf_sides] = E_leaf
    _pull(el, B)
    recv, src = links
    target = tol * max(float(np.abs(E_leaf).max()), 1e-300)
    by_level = [np.nonzero((el.level == lv) & (el.parent >= 0))[0]
                for lv in range(1, int(el.level.max()) + 1 if el.n else 1)]
    residual = np.inf
    for k in range(1, max_iterations + 1):
        H = np.stack([np.bincount(recv, F * B[src, c], minlength=m) for c in range(3)], axis=1)
        for rows in by_level:  # push, parents before children
            for s in (0, 1):
                H[2 * rows + s] += H[2 * el.parent[rows] + s]
        new_leaf = E_leaf + rho_leaf * H[leaf_sides]
        residual = float(np.abs(new_leaf - B[leaf_sides]).max())
        B[leaf_sides] = new_leaf
        _pull(el, B)
        if residual <= target:
            return B, k, residual, False
        if check is not None and check(min(1.0, 0.7 + 0.3 * k / 50)):
            return B, k, residual, True
    return B, max_iterations, residual, False


def _pull(el, B):
    """Every inner element side's ``B`` := its children's area-weighted mean (deepest first)."""
    inner = np.nonzero(el.children[:, 0] >= 0)[0]
    for level in sorted(np.unique(el.level[inner]), reverse=True):
        rows = inner[el.level[inner] == level]
        kids = el.children[rows]
        w = el.area[kids] / el.area[rows][:, None]
        for s in (0, 1):
            B[2 * rows + s] = np.einsum("kc,kcl->kl", w, B[2 * kids + s])


def solve_hierarchical(prep, params, progress=None, cancel=None):
    """Hierarchical radiosity of ``prep`` (see :func:`.system.solve_scene`)."""
    from .system import BIAS_NOTE, MAX_PATCHES, RadiositySolution, progress_check, source_term

    t0 = time.perf_counter()
    if prep.scene.n_triangles > MAX_ROOTS:
        raise RenderRefused(f"radiosity: hierarchical radiosity links every pair of input "
                            f"triangles first; {prep.scene.n_triangles:,} are more than "
                            f"{MAX_ROOTS:,}: choose the Progressive solver")
    mesh = build_mesh(prep, params.patch_size, MAX_PATCHES, power_of_two=True)
    el = build_elements(prep, mesh)
    check = progress_check(progress, cancel, 0.0, 1.0, "hierarchical")
    E, lamp_se = source_term(mesh, prep, params, check)
    leaves = np.nonzero(el.patch_sub >= 0)[0]
    leaf_sides = np.concatenate([2 * leaves, 2 * leaves + 1])
    patch_of = np.concatenate([2 * el.patch_sub[leaves], 2 * el.patch_sub[leaves] + 1])
    stats = {"radiosity_patch_count": mesh.n_patches, "radiosity_solver": "hierarchical",
             "radiosity_elements": el.n, "radiosity_bias": BIAS_NOTE}
    links = refine(el, params.epsilon, check)
    t_refine = time.perf_counter()
    if links is None:
        return RadiositySolution(mesh, E, mesh.emission, mesh.corner_values(E), stats, True)
    F = _link_form_factors(el, prep, links, params, check)
    t_ff = time.perf_counter()
    if F is None:
        return RadiositySolution(mesh, E, mesh.emission, mesh.corner_values(E), stats, True)
    B_el, sweeps, residual, cancelled = gather_solve(
        el, links, F, E[patch_of], mesh.albedo[patch_of], leaf_sides, params.tolerance,
        check=check)
    B = np.zeros_like(E)
    B[patch_of] = B_el[leaf_sides]
    stats.update({"radiosity_links": int(links[0].size), "radiosity_iterations": sweeps,
                  "radiosity_residual": residual, "radiosity_refine_s": t_refine - t0,
                  "radiosity_form_factor_s": t_ff - t_refine,
                  "radiosity_solve_s": time.perf_counter() - t_ff,
                  "radiosity_lamp_se": float(lamp_se.max()) if lamp_se.size else 0.0})
    return RadiositySolution(mesh, B, mesh.emission, mesh.corner_values(B), stats, cancelled)


def _link_form_factors(el, prep, links, params, check):
    """Form factors ``(l,)`` of the links, in blocks (None if cancelled)."""
    recv, src = links
    # Leaf elements hash as their patch numbers: the dense matrix's numbers.
    key = np.full(2 * el.n, -1, np.int64)
    leaves = np.nonzero(el.patch_sub >= 0)[0]
    key[2 * leaves], key[2 * leaves + 1] = 2 * el.patch_sub[leaves], 2 * el.patch_sub[leaves] + 1
    inner = key < 0
    key[inner] = (1 << 30) + np.nonzero(inner)[0]
    F = np.zeros(recv.size)
    block = max(1, ff.RAYS_PER_BATCH // params.form_factor_samples)
    for a in range(0, recv.size, block):
        part = slice(a, a + block)
        F[part] = ff.pair_form_factors(el, prep.accel, recv[part], src[part],
                                       params.form_factor_samples, params.seed,
                                       keys=(key[recv[part]], key[src[part]]))[0]
        if check is not None and check(0.3 + 0.4 * min(1.0, (a + block) / recv.size)):
            return None
    return F
