"""Lambertian (ideal diffuse) reflection, two-sided as Blender's Diffuse BSDF at roughness 0.

f(wo, wi) = albedo / pi for wi on the shading side, sampled by cosine-weighted hemisphere
directions, so that ``f cos / pdf = albedo`` exactly. Directions are in world space; ``n`` is the
shading normal already flipped toward ``wo``.
"""

from __future__ import annotations

import numpy as np

from ..rows import dots, scaled
from ..sampling import warps


def eval_lambert(albedo, n, wi):
    """``f * cos(theta_i)`` for ``albedo (k, 3)``, normals ``n (k, 3)``, ``wi (k, 3)`` -> ``(k, 3)``."""
    cos = dots(n, wi)
    return scaled(albedo, np.maximum(cos, 0.0) * warps.INV_PI)


def pdf_lambert(n, wi):
    """Solid-angle pdf of :func:`sample_lambert` ``(k,)``."""
    return warps.cosine_hemisphere_pdf(dots(n, wi))


def sample_lambert(albedo, n, u):
    """Sample ``wi`` around ``n (k, 3)`` with ``u (k, 2)``.

    Returns
    -------
    wi : (k, 3) float64
    weight : (k, 3) float64
        ``f cos / pdf`` (the albedo; zero where the pdf vanishes). It may be ``albedo`` itself:
        callers must not change it in place.
    pdf : (k,) float64
    """
    local = warps.sample_cosine_hemisphere(u)
    wi = warps.to_world_around(local, n)
    pdf = warps.cosine_hemisphere_pdf(local[:, 2])
    ok = pdf > 0
    # Directions on the horizon (pdf 0) carry nothing; elsewhere the weight is the albedo itself.
    weight = albedo if ok.all() else np.where(ok[:, None], albedo, 0.0)
    return wi, weight, pdf
