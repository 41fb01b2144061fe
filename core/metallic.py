"""Metallic from an Image Texture: a Principled mixture re-weighted at every hit.

A Principled BSDF is a mixture (see ``addon/export/materials.py``): metal ``a m``, glass
``a (1 - m) t``, the opaque dielectric ``a (1 - m)(1 - t)`` and the transparent pass-through
``1 - a``. When Metallic comes from a texture the exporter lays the mixture out for
``m0 = Materials.metallic`` (0.5, so that both the metal and the non-metal components exist),
and each hit scales the metal components by ``m / m0`` and the non-metal ones by
``(1 - m) / (1 - m0)``, ``m`` the texture's luminance clipped to [0, 1] (Non-Color data used
as stored, as Blender converts a colour to a float socket). The weights still sum to one; a
component is then chosen with probability its weight (:mod:`core.reweighting`), as for every
mixture, which keeps the estimate unbiased.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .materials.bsdf import KIND_DIELECTRIC
from .textures import luminance, material_texture_values

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

    def factors(self, scene, rows, prim, u, v):
        """Per-component weight factors at hits ``prim, u, v (k,)`` of triangle material rows
        ``rows (k,)``: ``hit (j,)`` (the hits on metallic-textured rows) and ``(j, c)``
        factors ``m / m0`` (metal), ``(1 - m) / (1 - m0)`` (non-metal) or 1."""
        hit, color = material_texture_values(scene, scene.materials.metallic_texture, rows,
                                             prim, u, v)
        if hit.size == 0:
            return hit, np.ones((0, self.weights.shape[1]))
        m = np.clip(luminance(color), 0.0, 1.0)[:, None]
        r = rows[hit]
        m0 = self.m0[r][:, None]
        cls = self.classes[r]
        return hit, np.where(cls == METAL, m / m0,
                             np.where(cls == NON_METAL, (1 - m) / (1 - m0), 1.0))


def metallic_textures(materials, bsdf, mix_rows, mix_weights):
    """The :class:`MetallicTextures` of a material table, or None when no row has one."""
    if not np.any(materials.metallic_texture >= 0):
        return None
    metal = np.asarray(materials.metallic, np.float64)[mix_rows] >= 1.0
    passes = ((bsdf.kind == KIND_DIELECTRIC) & (bsdf.eta == 1.0))[mix_rows]
    classes = np.where(metal, METAL, np.where(passes, FIXED, NON_METAL)).astype(np.int8)
    m0 = np.clip(np.asarray(materials.metallic, np.float64), 1e-6, 1.0 - 1e-6)
    return MetallicTextures(np.asarray(mix_weights, np.float64), classes, m0)
