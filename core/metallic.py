"""Metallic from an Image Texture: a Principled mixture re-weighted at every hit.

A Principled BSDF is a mixture (see ``addon/export/materials.py``): metal ``a m``, glass
``a (1 - m) t``, the opaque dielectric ``a (1 - m)(1 - t)`` and the transparent pass-through
``1 - a``. When Metallic comes from a texture the exporter lays the mixture out for
``m0 = Materials.metallic`` (0.5, so that both the metal and the non-metal components exist),
and each hit scales the metal components by ``m / m0`` and the non-metal ones by
``(1 - m) / (1 - m0)``, ``m`` the texture's luminance clipped to [0, 1] (Non-Color data used
as stored, as Blender converts a colour to a float socket). The weights still sum to one; a
component is then chosen with probability its weight, as for every mixture, which keeps the
estimate unbiased.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .materials.bsdf import KIND_DIELECTRIC
from .textures import LUMINANCE, material_texture_values

# How a component's weight follows the metallic value.
FIXED, NON_METAL, METAL = -1, 0, 1


@dataclass
class MetallicTextures:
    """What re-weighting needs, per material row.

    Attributes
    ----------
    weights : (m, c) float64
        Mixing weights as exported (for ``m0``).
    classes : (m, c) int8
        ``METAL``, ``NON_METAL`` or ``FIXED`` per component.
    m0 : (m,) float64
        The metallic value the weights were laid out for.
    """

    weights: np.ndarray
    classes: np.ndarray
    m0: np.ndarray


def metallic_textures(materials, bsdf, mix_rows, mix_weights):
    """The :class:`MetallicTextures` of a material table, or None when no row has one."""
    if not np.any(materials.metallic_texture >= 0):
        return None
    metal = np.asarray(materials.metallic, np.float64)[mix_rows] >= 1.0
    passes = ((bsdf.kind == KIND_DIELECTRIC) & (bsdf.eta == 1.0))[mix_rows]
    classes = np.where(metal, METAL, np.where(passes, FIXED, NON_METAL)).astype(np.int8)
    m0 = np.clip(np.asarray(materials.metallic, np.float64), 1e-6, 1.0 - 1e-6)
    return MetallicTextures(np.asarray(mix_weights, np.float64), classes, m0)


def choose_metallic(textures, scene, mix_rows, rows, prim, u, v, u_lobe, material, u_out):
    """Re-choose the component of hits on metallic-textured rows.

    Parameters
    ----------
    textures : MetallicTextures
    mix_rows : (m, c) int
        Component rows of every material.
    rows : (k,) int
        Each hit's triangle material row; ``prim, u, v (k,)`` the hits.
    u_lobe : (k,) float
        The hits' original lobe numbers in [0, 1).
    material, u_out : (k,) arrays
        The choice made without the texture, overwritten (in place) on the textured hits with
        the chosen component row and the remapped lobe number.
    """
    hit, color = material_texture_values(scene, scene.materials.metallic_texture, rows, prim,
                                         u, v)
    if hit.size == 0:
        return
    m = np.clip(color @ LUMINANCE, 0.0, 1.0)[:, None]
    r = rows[hit]
    m0 = textures.m0[r][:, None]
    cls = textures.classes[r]
    factor = np.where(cls == METAL, m / m0, np.where(cls == NON_METAL, (1 - m) / (1 - m0), 1.0))
    w = textures.weights[r] * factor
    cdf = np.cumsum(w, axis=1)
    total = np.maximum(cdf[:, -1], 1e-300)
    x = u_lobe[hit] * total
    j = np.minimum((cdf <= x[:, None]).sum(axis=1), w.shape[1] - 1)
    # Never a component of weight zero (x can equal a CDF step only at its left end).
    j = np.where(w[np.arange(j.size), j] > 0, j, np.argmax(w > 0, axis=1))
    lo = np.take_along_axis(cdf, j[:, None], 1)[:, 0] - w[np.arange(j.size), j]
    material[hit] = mix_rows[r, j]
    u_out[hit] = np.clip((x - lo) / np.maximum(w[np.arange(j.size), j], 1e-300), 0.0,
                         np.nextafter(1.0, 0.0))
