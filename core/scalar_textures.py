"""Specular IOR Level and Coat Weight from Image Textures: BSDF parameters replaced per hit.

As the roughness (:func:`core.textures.material_roughness`), each is the luminance of the
lookup at the hit's UV, clipped to [0, 1] (Non-Color data used as stored, as Blender converts a
colour to a float socket), on the component row it belongs to:

- Specular IOR Level re-folds the row's IOR into the specular layer's index, as
  :func:`core.materials.bsdf.make_params` does for a constant level (layered rows only; the
  exporter reports a level on transmission);
- Coat Weight replaces the coat's weight (the exporter gives a textured row a coat of weight 1,
  so that the coat's columns exist and its other inputs are read).

Both are parameters of the BSDF evaluated at the hit, exactly as Cycles evaluates its node
tree per shading point, so no estimator changes.
"""

from __future__ import annotations

import numpy as np

from .materials.bsdf import ETA_RANGE
from .materials.families import KIND_LAYERED, KIND_LAYERED_MS
from .materials.fresnel import adjust_ior_for_specular_level
from .textures import material_scalar


def apply_scalar_textures(scene, params, material, prim, u, v):
    """Overwrite (in place) the Specular IOR Level and Coat Weight of ``params (k rows)`` at
    hits ``prim, u, v (k,)`` whose chosen row ``material (k,)`` has such a texture."""
    mats = scene.materials
    rows, level = material_scalar(scene, mats.specular_level_texture, material, prim, u, v)
    if rows.size:
        layered = np.isin(params.kind[rows], (KIND_LAYERED, KIND_LAYERED_MS))
        ior = np.clip(np.asarray(mats.ior, np.float64)[material[rows]], *ETA_RANGE)
        eta = np.clip(adjust_ior_for_specular_level(ior, level), *ETA_RANGE)
        params.eta[rows] = np.where(layered, eta, params.eta[rows])
    rows, weight = material_scalar(scene, mats.coat_weight_texture, material, prim, u, v)
    if rows.size and params.coat_weight is not None:
        params.coat_weight[rows] = weight
