"""Rough conductor: GGX microfacet reflection with Schlick's Fresnel, ``F0 = base color``.

The metallic lobe of Blender's Principled BSDF and the Glossy BSDF (GGX):

``f(wo, wi) = F(wo.h) D(h) G2(wo, wi) / (4 |cos theta_o| |cos theta_i|)``,
``h = (wo + wi) / |wo + wi|``

- Fresnel: Schlick with ``F0 = base color``. Cycles' Principled metallic lobe uses the F82-tint
  model (Schlick minus ``b mu (1 - mu)^6``, with ``b`` chosen so that ``F(1/7)`` is the Specular
  Tint times Schlick's value there); with the default white Specular Tint ``b = 0`` and it is
  exactly this Schlick Fresnel. Coloured specular tints are not modelled.
- Masking-shadowing: height-correlated Smith ``G2`` (:mod:`.microfacet`).
- Sampling: visible normals from ``wo`` (Heitz 2018), reflected about the sampled normal;
  ``pdf = D_wo(h) / (4 |wo.h|)``. Reflections that land below the surface are lost: the sample
  fails (pdf 0, weight 0), so the pdf integrates to the probability of a valid sample, < 1.
- Single scattering only: light that would bounce between microfacets is lost (Cycles' default
  *Multiscatter GGX* keeps it). White-furnace albedo with F0 = 1, at cos theta_o = 1 / 0.5 /
  0.05: 0.998 / 0.996 / 0.89 at roughness 0.2, 0.92 / 0.86 / 0.93 at roughness 0.5, and
  0.31 / 0.45 / 0.85 at roughness 1.
- Two-sided: below the surface both directions are mirrored to the upper hemisphere.
- Rows with ``alpha <= ALPHA_SMOOTH`` are perfect mirrors (:mod:`.mirror`).
"""

from __future__ import annotations

import numpy as np

from . import microfacet as mf
from .frame import dot, flip_to_upper, normalize, reflect, side_of
from .fresnel import fresnel_schlick
from .mirror import sample_mirror


def eval_conductor(f0, alpha, wo, wi):
    """``f(wo, wi) |cos theta_i|`` of the rough lobe (zero on smooth rows).

    Parameters
    ----------
    f0 : (k, 3) float
    alpha : (k,) float
        GGX alpha (``roughness^2``).
    wo, wi : (k, 3) float
        Unit directions in the local frame.

    Returns
    -------
    (k, 3) float64
    """
    side = side_of(wo)
    wo_, wi_ = flip_to_upper(wo, side), flip_to_upper(wi, side)
    co, ci = wo_[:, 2], wi_[:, 2]
    h, ok = normalize(wo_ + wi_)
    ok &= (co > 0.0) & (ci > 0.0) & ~mf.is_smooth(alpha)
    val = mf.ggx_d(h[:, 2], alpha) * mf.ggx_visibility(co, ci, alpha) * ci
    f = fresnel_schlick(f0, dot(wo_, h)) * val[:, None]
    return np.where(ok[:, None], f, 0.0)


def pdf_conductor(alpha, wo, wi):
    """Solid-angle density of :func:`sample_conductor` at ``wi`` (zero on smooth rows). ``(k,)``.

    ``D_wo(h) / (4 wo.h) = D(h) / (4 A(wo))`` with ``A`` the projected microsurface area
    (:func:`.microfacet.ggx_projected_area`).
    """
    side = side_of(wo)
    wo_, wi_ = flip_to_upper(wo, side), flip_to_upper(wi, side)
    co, ci = wo_[:, 2], wi_[:, 2]
    h, ok = normalize(wo_ + wi_)
    ok &= (co > 0.0) & (ci > 0.0) & ~mf.is_smooth(alpha)
    pdf = mf.ggx_d(h[:, 2], alpha) / (4.0 * mf.ggx_projected_area(co, alpha))
    return np.where(ok, pdf, 0.0)


def sample_conductor(f0, alpha, wo, u):
    """Sample ``wi`` by visible normals; smooth rows reflect perfectly.

    Parameters
    ----------
    f0 : (k, 3) float
    alpha : (k,) float
    wo : (k, 3) float
    u : (k, 2) float

    Returns
    -------
    wi : (k, 3) float64
        Zero where the sample failed (reflected below the surface, or ``wo`` tangent).
    weight : (k, 3) float64
        ``f |cos theta_i| / pdf = F(wo.h) G2 / G1(wo)``; the Fresnel for delta rows.
    pdf : (k,) float64
        Solid-angle density; 1 on delta rows; 0 where failed.
    delta : (k,) bool
        Smooth rows.
    """
    side = side_of(wo)
    wo_ = flip_to_upper(wo, side)
    co = wo_[:, 2]
    wm = mf.sample_ggx_visible(wo_, alpha, u)
    wi_ = reflect(wo_, wm)
    ci = wi_[:, 2]
    ok = (co > 0.0) & (ci > 0.0)
    weight = fresnel_schlick(f0, dot(wo_, wm)) * mf.ggx_g2_over_g1(co, ci, alpha)[:, None]
    pdf = mf.ggx_d(wm[:, 2], alpha) / (4.0 * mf.ggx_projected_area(co, alpha))
    wi = flip_to_upper(wi_, side)

    delta = mf.is_smooth(alpha)
    wi_d, weight_d, pdf_d, _ = sample_mirror(f0, wo)
    wi = np.where(delta[:, None], wi_d, np.where(ok[:, None], wi, 0.0))
    weight = np.where(delta[:, None], weight_d, np.where(ok[:, None], weight, 0.0))
    pdf = np.where(delta, pdf_d, np.where(ok, pdf, 0.0))
    return wi, weight, pdf, delta
