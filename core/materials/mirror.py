"""Perfect specular reflection (a delta BSDF): Blender's Glossy BSDF at roughness 0.

``f(wo, wi) = F(wo) delta(wi - reflect(wo)) / |cos theta_i|`` with Schlick's Fresnel and
``F0 = base color`` (a white F0 is a perfect mirror). Two-sided, like every reflection-only BSDF:
``wi = (-wo.x, -wo.y, wo.z)`` on whichever side ``wo`` is. Also the smooth limit of the GGX
conductor (:mod:`.conductor` uses it for rows with ``alpha <= ALPHA_SMOOTH``).

Being a delta distribution it has no density: :func:`eval_mirror` and :func:`pdf_mirror` are
zero for every pair of directions, and only :func:`sample_mirror` produces light transport.
"""

from __future__ import annotations

import numpy as np

from .frame import reflect_z
from .fresnel import fresnel_schlick


def eval_mirror(f0, wo, wi):
    """``f * |cos theta_i|`` of the non-delta part: zero. ``(k, 3)``."""
    return np.zeros((wo.shape[0], 3))


def pdf_mirror(wo, wi):
    """Solid-angle density of the non-delta part: zero. ``(k,)``."""
    return np.zeros(wo.shape[0])


def sample_mirror(f0, wo):
    """Reflect ``wo`` about the normal.

    Parameters
    ----------
    f0 : (k, 3) float
        Reflectance at normal incidence.
    wo : (k, 3) float
        Unit directions in the local frame, either side.

    Returns
    -------
    wi : (k, 3) float64
        The mirror direction; zero where ``wo`` lies in the tangent plane (no reflection).
    weight : (k, 3) float64
        ``F(|cos theta_o|)``, Schlick.
    pdf : (k,) float64
        1 (the probability of the only lobe); 0 where the sample failed.
    delta : (k,) bool
        True.
    """
    ok = wo[:, 2] != 0.0
    wi = np.where(ok[:, None], reflect_z(wo), 0.0)
    weight = np.where(ok[:, None], fresnel_schlick(f0, wo[:, 2]), 0.0)
    return wi, weight, ok.astype(np.float64), np.ones(wo.shape[0], bool)
