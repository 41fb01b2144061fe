"""Cycles' Bump Map Correction: a shadowing factor on the diffuse lobes of normal-mapped and
bumped surfaces (a material setting, ``material.cycles.use_bump_map_correction``, on by
default in Blender).

Method (Conty Estevez, Lecocq and Stein, "A Microfacet-Based Shadowing Function to Solve the
Bump Terminator Problem", Ray Tracing Gems 2019; as Cycles' ``bump_shadowing_term`` in
``intern/cycles/kernel/closure/bsdf.h``, Blender 5.0): the deviation of the closure's normal
``N`` (the mapped one, the +Z of the local frame) from the smooth, unmapped normal ``Ns`` is
read as the roughness of a GGX surface, ``alpha^2 = clamp(tan^2(theta_d) / 8, 0, 1)`` with
``cos theta_d = |Ns . N|``, and the diffuse lobe is multiplied by that GGX's Smith masking
``G1 = 2 / (1 + sqrt(1 + alpha^2 tan^2 theta_i))`` of the *light-side* direction, ``cos
theta_i = |Ns . w|`` (0 below ``cos theta_i = 1e-6``; 1 where ``N == Ns``). Only diffuse
closures get it (Cycles' ``CLOSURE_IS_BSDF_DIFFUSE``: here the diffuse kind, the diffuse
base of the layered kinds and the microfiber sheen; not the microfacet lobes), in evaluation
and in the sampled weight (``weight = eval / pdf``: the pdf is unchanged, as Cycles
multiplies ``eval`` only).

The factor depends on the light-side direction only, so the corrected BSDF is not
reciprocal: camera paths (``mode='radiance'``) apply it to ``wi``; light paths
(``mode='importance'``, where ``wo`` points back toward the light) apply it to ``wo``, so
that light tracing and BDPT estimate the same image as path tracing (the adjoint, as the
coat's non-reciprocity in :mod:`.coat`).

Rows carry the smooth normal in their local frame as ``BSDFParams.bump_normal (k, 3)``; a
zero row means "no correction" (the group's neutral value).
"""

from __future__ import annotations

import numpy as np

from .dielectric import RADIANCE
from .families import KIND_DIFFUSE, KIND_LAYERED, KIND_LAYERED_MS

# Cycles' constants: the GGX alpha^2 per tan^2 of the normals' deviation, and the grazing
# cosine below which the light is fully shadowed.
ALPHA2_PER_TAN2 = 0.125
COS_MIN = 1e-6


def shadowing(bump_normal, w, closure_normal=None):
    """The shadowing factor ``G1 (k,)`` in [0, 1] for light-side directions ``w``.

    Parameters
    ----------
    bump_normal : (k, 3) float
        The unit smooth (unmapped) normal in the local frame of the mapped normal; zero rows
        get 1 (no correction).
    w : (k, 3) float
        Unit local light-side directions.
    closure_normal : (k, 3) float, optional
        The diffuse closure's own unit normal in the local frame where it is not +Z (a
        layered row's base normal, :mod:`.layered`); zero rows and None mean +Z.

    Returns
    -------
    (k,) float64
    """
    n = np.asarray(bump_normal, np.float64)
    active = np.einsum("ij,ij->i", n, n) > 0.0
    cos_d = np.abs(n[:, 2])
    if closure_normal is not None:
        c = np.asarray(closure_normal, np.float64)
        own = np.any(c != 0.0, axis=1)
        cos_d = np.where(own, np.abs(np.einsum("ij,ij->i", n, c)), cos_d)
    cos_d = np.minimum(cos_d, 1.0)
    cos_i = np.minimum(np.abs(np.einsum("ij,ij->i", n, w)), 1.0)
    tan2_d = 1.0 / np.maximum(cos_d * cos_d, 1e-300) - 1.0
    alpha2 = np.clip(ALPHA2_PER_TAN2 * tan2_d, 0.0, 1.0)
    tan2_i = 1.0 / np.maximum(cos_i * cos_i, COS_MIN * COS_MIN) - 1.0
    g = 2.0 / (1.0 + np.sqrt(1.0 + alpha2 * tan2_i))
    g = np.where(cos_i < COS_MIN, 0.0, g)
    return np.where(active & (cos_d < 1.0) & (cos_i < 1.0), g, 1.0)


def bumped_rows(params):
    """Row indices ``(j,)`` with a non-zero ``bump_normal`` (any kind)."""
    if params.bump_normal is None:
        return np.zeros(0, np.int64)
    return np.nonzero(np.any(params.bump_normal != 0.0, axis=1))[0]


def corrected_rows(params):
    """Row indices ``(j,)`` whose kind's diffuse part the correction scales (diffuse and
    layered kinds with a non-zero ``bump_normal``)."""
    rows = bumped_rows(params)
    return rows[np.isin(params.kind[rows], (KIND_DIFFUSE, KIND_LAYERED, KIND_LAYERED_MS))]


def correct_sheen(params, wo, wi, mode, out, lobe):
    """``out (k, 3)`` of rows with a sheen whose sheen ``lobe (k, 3)`` (its ``f cos``) is
    scaled by :func:`shadowing` (the sheen is a diffuse closure in Cycles)."""
    g = shadowing(params.bump_normal, wi if mode == RADIANCE else wo)
    return np.maximum(out - (1.0 - g)[:, None] * lobe, 0.0)


def correct_eval(params, wo, wi, mode, out, eval_kinds):
    """``out (k, 3)``, the kinds' ``f |cos theta_i|`` (below any coat and sheen), with the
    diffuse part of the corrected rows scaled by :func:`shadowing`.

    The diffuse part of a layered row is ``out`` minus the same row evaluated with a black
    base (``eval_kinds(params, wo, wi, mode)`` evaluates the kinds); a diffuse row is all
    diffuse.
    """
    rows = corrected_rows(params)
    if rows.size == 0:
        return out
    p = params.take(rows)
    g = shadowing(p.bump_normal, (wi if mode == RADIANCE else wo)[rows], p.base_normal)
    diffuse = out[rows]
    layered = p.kind != KIND_DIFFUSE
    if layered.any():
        black = p.take(layered)
        black.color = np.zeros_like(black.color)
        sub = rows[layered]
        diffuse[layered] -= eval_kinds(black, wo[sub], wi[sub], mode)
    out = out.copy()
    out[rows] -= (1.0 - g)[:, None] * np.maximum(diffuse, 0.0)
    return np.maximum(out, 0.0)
