"""Bump node on an image: the shading normal tilted by the gradient of a height texture.

Cycles' ``svm_node_set_bump`` (``kernel/svm/displace.h``; behaviour matched, the code is ours)
evaluates the height ``h`` at the hit and at the hit moved along the ray differentials
``dPdx``, ``dPdy`` (scaled by the node's filter width), and tilts the input normal ``n``::

    Rx = dPdy x n,   Ry = n x dPdx,   det = dPdx . Rx,
    g  = (h_x - h) Rx + (h_y - h) Ry,
    N  = normalize(|det| n - d sign(det) g)          (d = Distance, negated by Invert)
    N  = normalize(k N + (1 - k) n)                  (k = max(Strength, 0))

To first order the differentials cancel (``h_x - h`` and ``det`` both scale with them), so any
two tangent vectors give the same normal. We have no ray differentials and use the surface's
own parametrisation instead: ``dPdx = dP/du``, ``dPdy = dP/dv`` of the triangle (from its
corners' positions and UVs) and ``h_x - h = dh/du``, ``h_y - h = dh/dv``, finite differences
of the bilinear image lookup over a hundredth of a texel. This is the limit of Cycles' result
for a footprint small against a texel (the usual case of a magnified texture); where a pixel
covers many texels, Cycles' finite difference averages the height over the footprint and ours
does not (no filtering), and on Closest interpolation our gradient is zero inside a texel.
"""

from __future__ import annotations

import numpy as np

from .textures import luminance, hit_uv, texture_lookup

# Finite-difference step of the height lookup, in texels.
STEP_TEXELS = 0.01


def triangle_uv_tangents(vertices, triangles, corner_uvs, prim):
    """``dP/du`` and ``dP/dv`` of triangles ``prim (k,)``: two ``(k, 3)`` float64 arrays (zero
    where the UVs are degenerate)."""
    p = vertices.astype(np.float64)[triangles[prim]]
    uv = corner_uvs[prim].astype(np.float64)
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    du1, dv1 = uv[:, 1, 0] - uv[:, 0, 0], uv[:, 1, 1] - uv[:, 0, 1]
    du2, dv2 = uv[:, 2, 0] - uv[:, 0, 0], uv[:, 2, 1] - uv[:, 0, 1]
    det = du1 * dv2 - du2 * dv1
    ok = np.abs(det) > 1e-20
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
    dpdu = (dv2[:, None] * e1 - dv1[:, None] * e2) * inv
    dpdv = (du1[:, None] * e2 - du2[:, None] * e1) * inv
    return dpdu, dpdv


def bumped_normals(n, dpdu, dpdv, dh_du, dh_dv, distance, strength):
    """Cycles' bump construction (module docstring) for unit normals ``n (k, 3)``.

    ``dh_du, dh_dv, distance, strength`` are ``(k,)``. Rows where the result vanishes keep
    ``n``.
    """
    rx = np.cross(dpdv, n)
    ry = np.cross(n, dpdu)
    det = np.einsum("ij,ij->i", dpdu, rx)
    grad = dh_du[:, None] * rx + dh_dv[:, None] * ry
    out = np.abs(det)[:, None] * n - (distance * np.sign(det))[:, None] * grad
    length = np.linalg.norm(out, axis=1)
    good = length > 1e-300
    out = out / np.where(good, length, 1.0)[:, None]
    k = np.maximum(strength, 0.0)[:, None]
    mixed = k * out + (1.0 - k) * n
    mixed /= np.maximum(np.linalg.norm(mixed, axis=1), 1e-300)[:, None]
    return np.where(good[:, None], mixed, n)


def _height_gradient(scene, index, uv):
    """``dh/du, dh/dv (j,)`` of height texture ``index`` (its luminance) at ``uv (j, 2)``."""
    image = scene.textures[index]
    h, w = image.shape[:2]
    du, dv = STEP_TEXELS / w, STEP_TEXELS / h
    modes = scene.texture_interpolation[index], scene.texture_extension[index]

    def height(offset):
        return luminance(texture_lookup(image, uv + offset, *modes))

    h0 = height(np.zeros(2))
    return (height(np.array([du, 0.0])) - h0) / du, (height(np.array([0.0, dv])) - h0) / dv


def bump_mapped(scene, prim, u, v, ns):
    """Shading normals ``ns (k, 3)`` of hits ``prim, u, v (k,)`` with their materials' Bump
    nodes applied (``materials.bump_texture``, ``bump_distance``, ``bump_strength``); ``ns``
    itself when the scene has none."""
    column = scene.materials.bump_texture
    if prim.size == 0 or not np.any(column >= 0):
        return ns
    material = scene.material[prim]
    tex = column[material]
    rows = np.nonzero(tex >= 0)[0]
    if rows.size == 0:
        return ns
    uv = hit_uv(scene.corner_uvs, prim[rows], u[rows], v[rows])
    dh_du, dh_dv = np.zeros(rows.size), np.zeros(rows.size)
    # One pass per height texture used by this batch (bounded by the scene's texture count).
    for index in np.unique(tex[rows]):
        sel = np.nonzero(tex[rows] == index)[0]
        dh_du[sel], dh_dv[sel] = _height_gradient(scene, int(index), uv[sel])
    dpdu, dpdv = triangle_uv_tangents(scene.vertices, scene.triangles, scene.corner_uvs,
                                      prim[rows])
    m, row_material = scene.materials, material[rows]
    out = ns.copy()
    out[rows] = bumped_normals(ns[rows], dpdu, dpdv, dh_du, dh_dv,
                               m.bump_distance[row_material].astype(np.float64),
                               m.bump_strength[row_material].astype(np.float64))
    return out
