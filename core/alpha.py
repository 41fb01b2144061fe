"""Alpha from an Image Texture: a surface's transparency looked up per hit.

Two node setups make a surface partly transparent by a texture, as Cycles evaluates them per
shading point: an Image Texture into a Principled BSDF's Alpha (the transparent pass-through
weighs ``1 - a``, every other component is scaled by ``a``), and an Image Texture into the Fac
of a Mix Shader with a Transparent BSDF on one side (that side weighs ``fac`` or ``1 - fac``).
Either way the surface is a mixture whose components split into a *clear* side
(``Materials.alpha_clear``) and an opaque side, and the opacity ``a`` of a hit is the lookup
of ``Materials.alpha_texture`` at its UV (its luminance for a colour image, its value for an
Alpha channel), clipped to [0, 1] (one minus it with ``Materials.alpha_invert``).

The exporter lays the mixture out for an opacity ``a0`` (0.5, so that both sides exist; here
``a0`` is the summed weight of the opaque side). Each hit then scales the opaque side's weights
by ``a / a0`` and the clear side's by ``(1 - a) / (1 - a0)``: the weights of the node tree at
that hit. Every integrator sees this in the two places it reads a surface's transparency:

- choosing a mixture component at a path vertex (camera paths, light paths, BDPT, photons):
  :func:`core.reweighting.choose_reweighted` draws with the hit's weights;
- shadow rays and light tracing's and BDPT's connections that pass through transparent surfaces
  (:mod:`core.integrators.shadows`): :meth:`AlphaTextures.transparency` gives the hit's
  ``sum_c w_c(hit) color_c`` over the pass-through components.

Both are the node tree's value at the hit, so the estimates stay unbiased. The alpha image is
stored once per image node, one float32 channel (``Scene.textures``), not per triangle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .textures import luminance, material_texture_values


@dataclass
class AlphaTextures:
    """What per-hit alpha needs, per material row.

    Attributes
    ----------
    weights : (m, c) float64
        Mixing weights as exported.
    clear : (m, c) bool
        Components on the clear side of the row's textured alpha.
    a0 : (m,) float64
        The opacity the weights were laid out for (the opaque side's summed weight), kept
        inside (0, 1).
    passes : (m, c, 3) float64
        Each component's colour if it passes rays straight through (zero otherwise), as in
        :func:`core.prepare.transparency_table`.
    """

    weights: np.ndarray
    clear: np.ndarray
    a0: np.ndarray
    passes: np.ndarray

    def opacity(self, scene, rows, prim, u, v):
        """Opacity at hits ``prim, u, v (k,)`` of triangle material rows ``rows (k,)``:
        ``hit (j,)`` (the hits on alpha-textured rows) and their ``(j,)`` opacity in [0, 1]."""
        mats = scene.materials
        hit, color = material_texture_values(scene, mats.alpha_texture, rows, prim, u, v)
        # A NaN texel reads as transparent (the exporter zeroes non-finite pixels already).
        a = np.clip(np.nan_to_num(luminance(color), nan=0.0), 0.0, 1.0)
        return hit, np.where(mats.alpha_invert[rows[hit]], 1.0 - a, a)

    def factors(self, scene, rows, prim, u, v):
        """Per-component weight factors at the hits (see :mod:`core.reweighting`): ``hit
        (j,)`` and ``(j, c)`` factors ``a / a0`` (opaque side) or ``(1 - a) / (1 - a0)``
        (clear side)."""
        hit, a = self.opacity(scene, rows, prim, u, v)
        r = rows[hit]
        a, a0 = a[:, None], self.a0[r][:, None]
        return hit, np.where(self.clear[r], (1.0 - a) / (1.0 - a0), a / a0)

    def transparency(self, scene, rows, prim, u, v):
        """What a shadow ray keeps crossing hits ``prim, u, v (k,)`` of triangle material rows
        ``rows (k,)``: ``hit (j,)`` (the hits on alpha-textured rows) and their ``(j, 3)``
        transparency ``sum_c w_c(hit) color_c`` over the pass-through components."""
        hit, factor = self.factors(scene, rows, prim, u, v)
        r = rows[hit]
        w = self.weights[r] * factor
        w = w / np.maximum(w.sum(axis=1, keepdims=True), 1e-300)
        return hit, np.einsum("jc,jcx->jx", w, self.passes[r])


def alpha_textures(materials, mix_rows, mix_weights, passes):
    """The :class:`AlphaTextures` of a material table, or None when no row has one.

    ``mix_rows, mix_weights (m, c)`` are the prepared mixture table, ``passes (m, 3)`` each
    row's pass-through colour (zero for rows that do not pass rays straight through)."""
    if not np.any(materials.alpha_texture >= 0):
        return None
    weights = np.asarray(mix_weights, np.float64)
    clear = np.asarray(materials.alpha_clear, bool)[mix_rows] & (weights > 0)
    a0 = np.clip(np.where(clear, 0.0, weights).sum(axis=1), 1e-6, 1.0 - 1e-6)
    return AlphaTextures(weights, clear, a0, np.asarray(passes, np.float64)[mix_rows])
