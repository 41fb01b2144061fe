"""Image textures on surfaces: the base colour of a material looked up at the hit's UV.

Only what Cycles' Image Texture node computes with its defaults: the active UV map, Linear
(bilinear) interpolation between texel centres and Repeat extension. The lookup is the one of
the world's Environment Texture (:func:`core.lights.environment_lookup`).
"""

from __future__ import annotations

import numpy as np

from .lights import environment_lookup


def texture_lookup(image, uv):
    """Colour of ``image (h, w, 3)`` (row 0 at v = 0) at ``uv (n, 2)``: ``(n, 3)`` float64.

    Bilinear between texel centres, wrapping on both axes (Cycles' Linear, Repeat).
    """
    return environment_lookup(image, np.asarray(uv, np.float64).reshape(-1, 2))


def hit_uv(corner_uvs, prim, u, v):
    """UV at barycentrics ``u, v (k,)`` (Embree's: weights of corners 1 and 2) of ``prim``."""
    c = corner_uvs[prim].astype(np.float64)
    u = np.asarray(u, np.float64)[:, None]
    v = np.asarray(v, np.float64)[:, None]
    return (1.0 - u - v) * c[:, 0] + u * c[:, 1] + v * c[:, 2]


def textured_base_color(scene, tri_material, prim, u, v):
    """Base colours of the hits on textured materials.

    Parameters
    ----------
    scene : core.scene.Scene
    tri_material : (t,) int
        Material row per triangle.
    prim : (k,) int
        Hit triangles; ``u, v (k,)`` their barycentrics.

    Returns
    -------
    rows : (j,) int64
        Entries of ``prim`` on textured materials (empty when the scene has no textures).
    color : (j, 3) float64
        Their base colours, clipped to [0, 1] as every material colour is.
    """
    if not scene.textures or prim.size == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3))
    tex = scene.materials.texture[tri_material[prim]]
    rows = np.nonzero(tex >= 0)[0]
    color = np.zeros((rows.size, 3))
    if rows.size == 0:
        return rows, color
    uv = hit_uv(scene.corner_uvs, prim[rows], u[rows], v[rows])
    # One lookup per texture used by this batch (bounded by the scene's texture count).
    for index in np.unique(tex[rows]):
        sel = np.nonzero(tex[rows] == index)[0]
        color[sel] = texture_lookup(scene.textures[index], uv[sel])
    return rows, np.clip(color, 0.0, 1.0)
