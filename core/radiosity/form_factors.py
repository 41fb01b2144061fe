"""Form factors between patches: the analytic point-to-polygon form factor times visibility
found by Embree shadow rays, vectorised over many patch pairs.

For a pair ``(i, j)`` the patch-to-patch form factor is ``F_ij = (1 / A_i) int_i F(x -> j) dA``,
where ``F(x -> j)`` is the differential-area-to-polygon form factor (Lambert's formula, exact
for the part of ``j`` above ``x``'s tangent plane: :func:`point_polygon_form_factor`). It is
estimated with ``samples`` points ``x_s`` stratified over ``i``; each is tested for visibility
against one point ``y_s`` on ``j`` by a shadow ray:

    F_ij ~ (1 / S) sum_s F(x_s -> j) V(x_s, y_s).

Where ``j`` is wholly visible from ``i`` (or wholly hidden) this is exact but for the
integration over ``i`` (a smooth integrand: stratified sampling converges fast); under partial
occlusion it weighs ``F(x -> j)`` by the visible fraction of ``j``'s *area*, not of its form
factor (Hanrahan, Salzman & Aupperle 1991 estimate visibility the same way): a bias that
vanishes as patches shrink, one of the reasons radiosity is biased unless the mesh refines.

The random numbers of a pair are a hash of ``(i, j, seed)``, so a form factor has one value
whichever solver asks for it, in whatever batch: Jacobi's stored matrix and progressive
refinement's columns computed on the fly are the same numbers.
"""

from __future__ import annotations

import numpy as np

from ..sampling.stream import hash_u32, u32_to_unit_float
from ..sampling.warps import sample_uniform_triangle
from ..scene import VIS_SHADOW

# Shadow rays per batch of pairs: bounds the memory of one batch (about 1 KB a ray).
RAYS_PER_BATCH = 1 << 16


def point_polygon_form_factor(x, n, poly):
    """Form factor from differential areas at ``x (k, 3)`` with unit normal ``n (k, 3)`` to
    polygons ``poly (k, v, 3)`` (Lambert; Baum, Rushmeier & Winget 1989):

        F = (1 / 2 pi) | sum_e  gamma_e  n . (r_e x r_{e+1}) / |r_e x r_{e+1}| |,

    with ``r_e`` the unit vectors from ``x`` to the vertices and ``gamma_e`` the angle between
    consecutive ones. Exact for polygons wholly on the front side of ``x``'s tangent plane
    (clip them first, :func:`clip_to_plane`); repeated vertices (padding) add nothing.

    Returns
    -------
    (k,) float64
    """
    r = poly - x[:, None, :]
    r /= np.maximum(np.linalg.norm(r, axis=2, keepdims=True), 1e-300)
    r_next = np.roll(r, -1, axis=1)
    c = np.cross(r, r_next)
    length = np.linalg.norm(c, axis=2)
    gamma = np.arctan2(length, np.einsum("kvi,kvi->kv", r, r_next))
    term = gamma * np.einsum("kvi,ki->kv", c, n) / np.maximum(length, 1e-300)
    return np.abs(term.sum(axis=1)) / (2.0 * np.pi)


def clip_to_plane(tri, point, normal):
    """Clip triangles ``tri (k, 3, 3)`` to the half-spaces in front of planes through ``point
    (k, 3)`` with ``normal (k, 3)`` (Sutherland-Hodgman).

    Returns
    -------
    (k, 4, 3) float64
        The clipped polygons, padded by repeating their last vertex (all vertices on the
        plane where nothing is in front).
    """
    k = tri.shape[0]
    d = np.einsum("kvi,ki->kv", tri - point[:, None, :], normal)
    candidates = np.zeros((k, 6, 3))
    keep = np.zeros((k, 6), bool)
    for e in range(3):
        a, b = tri[:, e], tri[:, (e + 1) % 3]
        da, db = d[:, e], d[:, (e + 1) % 3]
        candidates[:, 2 * e] = a
        keep[:, 2 * e] = da >= 0
        t = da / np.where(da - db != 0, da - db, 1.0)
        candidates[:, 2 * e + 1] = a + t[:, None] * (b - a)
        keep[:, 2 * e + 1] = (da > 0) & (db < 0) | (da < 0) & (db > 0)
    # Compact the kept vertices to the front (stable), pad with the last kept one.
    order = np.argsort(~keep, axis=1, kind="stable")[:, :4]
    count = np.minimum(keep.sum(axis=1), 4)
    slot = np.minimum(np.arange(4)[None, :], np.maximum(count - 1, 0)[:, None])
    chosen = np.take_along_axis(order, slot, axis=1)
    out = np.take_along_axis(candidates, chosen[:, :, None], axis=1)
    out[count == 0] = point[count == 0, None, :]
    return out


def pair_uniforms(i, j, seed, samples, dim):
    """``(k, samples)`` numbers in [0, 1) of pairs ``(i, j) (k,)``, dimension ``dim``."""
    salt = np.uint32((int(seed) * 0x85EBCA6B + dim * 0x68E31DA4) & 0xFFFFFFFF)
    s = np.arange(samples, dtype=np.uint32)
    with np.errstate(over="ignore"):
        h = hash_u32(np.asarray(i, np.uint32) * np.uint32(0x9E3779B1)
                     ^ hash_u32(np.asarray(j, np.uint32) ^ salt))
        return u32_to_unit_float(hash_u32(h[:, None] ^ (s[None, :] * np.uint32(0x27D4EB2F))))


def stratified_points(i, j, seed, samples):
    """``(k, samples, 2)`` points in the unit square, stratified: a Hammersley set of
    ``samples`` points shifted (mod 1) by a per-pair offset."""
    s = np.arange(samples)
    bits = s.astype(np.uint32)
    bits = ((bits & 0x55555555) << 1) | ((bits >> 1) & 0x55555555)
    bits = ((bits & 0x33333333) << 2) | ((bits >> 2) & 0x33333333)
    bits = ((bits & 0x0F0F0F0F) << 4) | ((bits >> 4) & 0x0F0F0F0F)
    bits = ((bits & 0x00FF00FF) << 8) | ((bits >> 8) & 0x00FF00FF)
    bits = (bits << 16) | (bits >> 16)
    base = np.stack([(s + 0.5) / samples, bits.astype(np.float64) / 2.0**32], axis=1)
    shift = pair_uniforms(i, j, seed, 1, 0)[:, 0], pair_uniforms(i, j, seed, 1, 1)[:, 0]
    return (base[None] + np.stack(shift, axis=1)[:, None, :]) % 1.0


def pair_form_factors(mesh, accel, i, j, samples=16, seed=0, keys=None):
    """Form factors ``F_ij (k,)`` of patch pairs ``i, j (k,)`` (module docstring).

    Parameters
    ----------
    mesh : core.radiosity.mesh.PatchMesh
    accel : core.accel.Accel
        The scene's Embree scenes, for shadow rays (``VIS_SHADOW`` class).
    i, j : (k,) int64
        Patches (both sides count: a pair of sides facing away gets 0).
    samples : int
        Points on ``i`` per pair (and shadow rays).
    seed : int
    keys : tuple of two (k,) arrays or None
        What the pairs' random numbers are hashed from (default ``i, j``): hierarchical
        radiosity passes the patch numbers of its leaf elements, so a leaf link has the very
        form factor the dense matrix has.

    Returns
    -------
    F : (k,) float64
    se : (k,) float64
        Standard error of each estimate (from the spread of its samples).
    """
    i, j = np.asarray(i, np.int64), np.asarray(j, np.int64)
    ki, kj = (i, j) if keys is None else (np.asarray(keys[0]), np.asarray(keys[1]))
    out, se = np.zeros(i.size), np.zeros(i.size)
    step = max(1, RAYS_PER_BATCH // samples)
    for a in range(0, i.size, step):
        part = slice(a, a + step)
        out[part], se[part] = _pairs(mesh, accel, i[part], j[part], samples, seed,
                                     ki[part], kj[part])
    return out, se


def _pairs(mesh, accel, i, j, samples, seed, ki, kj):
    k = i.size
    ni = np.where((i % 2 == 0)[:, None], 1.0, -1.0) * mesh.sub_normal[i // 2]
    nj = np.where((j % 2 == 0)[:, None], 1.0, -1.0) * mesh.sub_normal[j // 2]
    ti, tj = mesh.corners[i // 2], mesh.corners[j // 2]
    poly = clip_to_plane(tj, ti[:, 0], ni)
    # Points on i (stratified) and on j (independent), as barycentrics.
    u_i = stratified_points(ki, kj, seed, samples).reshape(-1, 2)
    u_j = np.stack([pair_uniforms(ki, kj, seed, samples, 2),
                    pair_uniforms(ki, kj, seed, samples, 3)], axis=2).reshape(-1, 2)
    x = np.einsum("nv,nvi->ni", sample_uniform_triangle(u_i), np.repeat(ti, samples, axis=0))
    y = np.einsum("nv,nvi->ni", sample_uniform_triangle(u_j), np.repeat(tj, samples, axis=0))
    ni_s, nj_s = np.repeat(ni, samples, axis=0), np.repeat(nj, samples, axis=0)
    f = point_polygon_form_factor(x, ni_s, np.repeat(poly, samples, axis=0))
    # A sample sees j's own side only from in front of it (j may straddle i's plane or the
    # reverse; then part of the pair sees the other side).
    f *= np.einsum("ni,ni->n", x - y, nj_s) > 0
    live = np.nonzero(f > 0)[0]
    if live.size:
        prim_i = mesh.sub_tri[np.repeat(i // 2, samples)[live]]
        to_y = y[live] - x[live]
        dist = np.linalg.norm(to_y, axis=1)
        wi = to_y / np.maximum(dist, 1e-300)[:, None]
        o, d, tmax = accel.shadow_rays(x[live], ni_s[live], prim_i, wi, dist, nj_s[live])
        f[live[accel.occluded(o, d, tmax, VIS_SHADOW)]] = 0.0
    f = f.reshape(k, samples)
    se = f.std(axis=1, ddof=1) / np.sqrt(samples) if samples > 1 else np.zeros(k)
    return f.mean(axis=1), se


def facing(mesh, i, j, eps):
    """Whether patches ``i (k,)`` and ``j (k,)`` can exchange light: some corner of each lies
    more than ``eps`` in front of the other's side."""
    ni = np.where((i % 2 == 0)[:, None], 1.0, -1.0) * mesh.sub_normal[i // 2]
    nj = np.where((j % 2 == 0)[:, None], 1.0, -1.0) * mesh.sub_normal[j // 2]
    ti, tj = mesh.corners[i // 2], mesh.corners[j // 2]
    front_j = np.einsum("kvi,ki->kv", tj - ti[:, :1], ni).max(axis=1) > eps
    front_i = np.einsum("kvi,ki->kv", ti - tj[:, :1], nj).max(axis=1) > eps
    return front_j & front_i


def plane_eps(mesh):
    """Distance below which a corner counts as on a plane: 1e-6 of the scene's extent."""
    if not mesh.corners.size:
        return 0.0
    return 1e-6 * float(np.ptp(mesh.corners.reshape(-1, 3), axis=0).max() + 1e-30)


def form_factor_rows(mesh, accel, rows, samples=16, seed=0):
    """Dense rows ``F[rows, :] (r, p)`` of the form-factor matrix (pairs that cannot see each
    other are 0 without tracing)."""
    p = mesh.n_patches
    rows = np.asarray(rows, np.int64)
    ii = np.repeat(rows, p)
    jj = np.tile(np.arange(p), rows.size)
    ok = facing(mesh, ii, jj, plane_eps(mesh))
    out = np.zeros(rows.size * p)
    out[ok] = pair_form_factors(mesh, accel, ii[ok], jj[ok], samples, seed)[0]
    return out.reshape(rows.size, p)


def form_factor_column(mesh, accel, col, samples=16, seed=0):
    """Column ``F[:, col] (p,)``: what every patch receives from patch ``col`` (the shooting
    step of progressive refinement), the same numbers as :func:`form_factor_rows` gives."""
    p = mesh.n_patches
    ii = np.arange(p)
    jj = np.full(p, int(col))
    ok = facing(mesh, ii, jj, plane_eps(mesh))
    out = np.zeros(p)
    out[ok] = pair_form_factors(mesh, accel, ii[ok], jj[ok], samples, seed)[0]
    return out


def form_factor_matrix(mesh, accel, samples=16, seed=0, check=None):
    """The dense ``(p, p)`` form-factor matrix, in blocks of rows.

    ``check()`` (or None) is called after every block (at most about :data:`RAYS_PER_BATCH`
    rays, a fraction of a second) with the fraction done; it returns True to stop (then None is
    returned).
    """
    p = mesh.n_patches
    F = np.zeros((p, p))
    step = max(1, RAYS_PER_BATCH // max(p * samples, 1))
    for a in range(0, p, step):
        rows = np.arange(a, min(a + step, p))
        F[rows] = form_factor_rows(mesh, accel, rows, samples, seed)
        if check is not None and check(min(a + step, p) / p):
            return None
    return F
