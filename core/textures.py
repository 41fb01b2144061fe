"""Image textures on surfaces: the base colour, roughness, Specular IOR Level and Coat Weight
of a material looked up at the hit's UV.

What Cycles' Image Texture node computes (``kernel/device/cpu/image.h``) on the active UV map:
Linear (bilinear between texel centres) or Closest (the texel containing the point)
interpolation, and the four extensions: Repeat (wrap), Extend (clamp to the edge texels), Clip
(transparent black outside the image; bilinear lookups blend with black across the border)
and Mirror (reflect at every edge). Linear + Repeat is the lookup of the world's Environment
Texture (:func:`core.lights.environment_lookup`).
"""

from __future__ import annotations

import numpy as np


def _wrap(i, n, extension):
    """Texel indices ``i (k,) int64`` on an axis of ``n`` texels, and whether each is inside
    the image (always, except for Clip), as Cycles' ``wrap_*`` functions."""
    if extension == "REPEAT":
        return np.mod(i, n), None
    if extension == "EXTEND":
        return np.clip(i, 0, n - 1), None
    if extension == "MIRROR":
        m = np.mod(np.abs(i + (i < 0)), 2 * n)
        return np.where(m >= n, 2 * n - m - 1, m), None
    if extension == "CLIP":
        inside = (i >= 0) & (i < n)
        return np.clip(i, 0, n - 1), inside
    raise ValueError(f"unknown texture extension {extension!r}")


def _texels(image, ix, iy, extension):
    """``image[iy, ix]`` with the extension applied: ``(k, 3)`` float64."""
    h, w = image.shape[:2]
    x, in_x = _wrap(ix, w, extension)
    y, in_y = _wrap(iy, h, extension)
    c = image[y, x].astype(np.float64)
    if in_x is not None:
        c *= (in_x & in_y)[:, None]
    return c


def texture_lookup(image, uv, interpolation="Linear", extension="REPEAT"):
    """Colour of ``image (h, w, 3)`` (row 0 at v = 0) at ``uv (n, 2)``: ``(n, 3)`` float64.

    ``interpolation`` is ``'Linear'`` (bilinear between texel centres) or ``'Closest'``;
    ``extension`` is ``'REPEAT' | 'EXTEND' | 'CLIP' | 'MIRROR'`` (see the module docstring).
    """
    image = np.asarray(image)
    h, w = image.shape[:2]
    uv = np.nan_to_num(np.asarray(uv, np.float64).reshape(-1, 2))
    # Far outside the image every extension repeats, saturates or is black: keep ints small.
    uv = np.clip(uv, -1e6, 1e6)
    if interpolation == "Closest":
        ix = np.floor(uv[:, 0] * w).astype(np.int64)
        iy = np.floor(uv[:, 1] * h).astype(np.int64)
        return _texels(image, ix, iy, extension)
    if interpolation != "Linear":
        raise ValueError(f"unknown texture interpolation {interpolation!r}")
    x = uv[:, 0] * w - 0.5
    y = uv[:, 1] * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    ix, iy = x0.astype(np.int64), y0.astype(np.int64)
    bottom = (1 - fx) * _texels(image, ix, iy, extension) + fx * _texels(image, ix + 1, iy,
                                                                          extension)
    top = (1 - fx) * _texels(image, ix, iy + 1, extension) + fx * _texels(image, ix + 1, iy + 1,
                                                                           extension)
    return (1 - fy) * bottom + fy * top


def hit_uv(corner_uvs, prim, u, v):
    """UV at barycentrics ``u, v (k,)`` (Embree's: weights of corners 1 and 2) of ``prim``."""
    c = corner_uvs[prim].astype(np.float64)
    u = np.asarray(u, np.float64)[:, None]
    v = np.asarray(v, np.float64)[:, None]
    return (1.0 - u - v) * c[:, 0] + u * c[:, 1] + v * c[:, 2]


def textured_base_color(scene, tri_material, prim, u, v):
    """Base colours of the hits on textured materials (the triangles' own rows), see
    :func:`material_base_color`."""
    return material_base_color(scene, tri_material[prim], prim, u, v)


# Blender's colour -> float socket conversion: the luminance of linear Rec.709.
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def luminance(rgb):
    """Luminance ``(k,)`` of colours ``rgb (k, 3)``. By ``einsum``, not ``rgb @ LUMINANCE``: a
    ``(k, 3) x (3,)`` product goes to multi-threaded BLAS, whose threads then spin on the other
    cores while the render's own workers need them (see :mod:`core.camera`)."""
    return np.einsum("ij,j->i", rgb, LUMINANCE)


def material_texture_values(scene, column, material, prim, u, v):
    """Lookups of the texture column ``column (m,)`` (an index into ``scene.textures`` per
    material row, -1 for none) for the hits of ``material (k,)`` rows on ``prim, u, v (k,)``:
    ``rows (j,)`` into the hits that have one, and their ``(j, 3)`` colours (unclipped)."""
    if not scene.textures or prim.size == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3))
    tex = column[material]
    rows = np.nonzero(tex >= 0)[0]
    color = np.zeros((rows.size, 3))
    if rows.size == 0:
        return rows, color
    uv = hit_uv(scene.corner_uvs, prim[rows], u[rows], v[rows])
    # One lookup per texture used by this batch (bounded by the scene's texture count).
    for index in np.unique(tex[rows]):
        sel = np.nonzero(tex[rows] == index)[0]
        color[sel] = texture_lookup(scene.textures[index], uv[sel],
                                    scene.texture_interpolation[index],
                                    scene.texture_extension[index])
    return rows, color


def material_scalar(scene, column, material, prim, u, v):
    """A scalar input of the hits whose material row has a texture in ``column (m,)``:
    ``rows (j,)`` into ``prim`` and the luminance of the lookup ``(j,)``, clipped to [0, 1]
    (see :func:`material_base_color` for the parameters)."""
    rows, color = material_texture_values(scene, column, material, prim, u, v)
    # A NaN texel reads as 0 (the exporter zeroes non-finite pixels already).
    return rows, np.clip(np.nan_to_num(luminance(color), nan=0.0), 0.0, 1.0)


def material_roughness(scene, material, prim, u, v):
    """Roughness of the hits whose material row has a roughness texture (see
    :func:`material_scalar`)."""
    return material_scalar(scene, scene.materials.roughness_texture, material, prim, u, v)


def material_base_color(scene, material, prim, u, v):
    """Base colours of the hits whose material row is textured.

    Parameters
    ----------
    scene : core.scene.Scene
    material : (k,) int
        Material row shading each hit (a mixture's chosen component, or the triangle's row).
    prim : (k,) int
        Hit triangles; ``u, v (k,)`` their barycentrics.

    Returns
    -------
    rows : (j,) int64
        Entries of ``prim`` on textured materials (empty when the scene has no textures).
    color : (j, 3) float64
        Their base colours, clipped to [0, 1] as every material colour is.
    """
    rows, color = material_texture_values(scene, scene.materials.texture, material, prim, u, v)
    return rows, np.clip(color, 0.0, 1.0)
