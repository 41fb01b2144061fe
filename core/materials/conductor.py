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
- Single scattering: light that bounces between microfacets is lost. White-furnace albedo with
  F0 = 1, at cos theta_o = 1 / 0.5 / 0.05: 0.998 / 0.996 / 0.89 at roughness 0.2,
  0.92 / 0.86 / 0.93 at roughness 0.5, and 0.31 / 0.45 / 0.85 at roughness 1 (unless
  ``multiscatter``, below).
- Two-sided: below the surface both directions are mirrored to the upper hemisphere.
- Rows with ``alpha <= ALPHA_SMOOTH`` are perfect mirrors (:mod:`.mirror`).

Multiscatter GGX
    Blender's default distribution of the Glossy and Principled BSDFs. With ``multiscatter``
    the lobe is scaled as Cycles' ``microfacet_ggx_preserve_energy`` (``kernel/closure/
    bsdf_microfacet.h``) scales it, after Kulla and Conty 2017 (:mod:`.multiscatter`)::

        f = f_ss (1 + F_ms (1 - E(mu_o)) / E(mu_o)),  F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg))

    with ``E`` and ``E_avg`` the directional and average albedo of the lobe with ``F = 1``
    (tables computed from this very lobe) and ``F_ss = F0 + (1 - F0) / 21`` the hemispherical
    average of Schlick's Fresnel (Cycles' value for the Principled metal's F82-tint Fresnel
    with a white Specular Tint). A white conductor then reflects everything at every roughness,
    up to the tables' interpolation error, which is Cycles' own (same grid): ``E / E_table - 1``
    is below 2e-3 for ``cos theta_o >= 0.1``, 1.2 % at worst at roughness 1, and up to 9 % at
    grazing angles (``cos theta_o < 0.05``) and low roughness. A coloured conductor keeps the
    darker, more saturated light of repeated Fresnel reflections. Sampling and the pdf are
    unchanged; the sample weight is scaled. The factor depends on ``wo`` only, so the lobe is
    not reciprocal: ``mode='importance'`` evaluates the adjoint (the factor at ``wi``). Smooth
    rows (perfect mirrors) lose nothing and are not scaled (Cycles' tables scale them by at
    most 1.1 %, at grazing angles).
    Not compensated (the exporter reports it): Multiscatter GGX on glass and on the
    Principled BSDF's specular and coat layers. Cycles' Glossy BSDF has no Fresnel (a constant
    tint, ``F_ss`` = its colour), where this lobe uses Schlick with ``F0`` = the colour.
"""

from __future__ import annotations

import numpy as np

from . import microfacet as mf
from .dielectric import RADIANCE, _check_mode
from .frame import dot, flip_to_upper, normalize, reflect, side_of
from .fresnel import fresnel_schlick
from .mirror import sample_mirror
from .multiscatter import compensation, schlick_average


def multiscatter_factor(f0, alpha, wo_, wi_, mode=RADIANCE):
    """Cycles' Multiscatter GGX factor ``(k, 3)`` of the lobe (:mod:`.multiscatter`), for
    directions already mirrored to the upper hemisphere: at ``wo`` in radiance mode, at ``wi``
    (the adjoint) in importance mode; 1 on smooth rows."""
    _check_mode(mode)
    mu = wo_[:, 2] if mode == RADIANCE else wi_[:, 2]
    return compensation(schlick_average(f0), np.clip(mu, 0.0, 1.0), alpha)


def eval_conductor(f0, alpha, wo, wi, multiscatter=False, mode=RADIANCE):
    """``f(wo, wi) |cos theta_i|`` of the rough lobe (zero on smooth rows).

    Parameters
    ----------
    f0 : (k, 3) float
    alpha : (k,) float
        GGX alpha (``roughness^2``).
    wo, wi : (k, 3) float
        Unit directions in the local frame.
    multiscatter : bool
        Scale by the Multiscatter GGX factor (:func:`multiscatter_factor`).
    mode : {'radiance', 'importance'}
        Matters only with ``multiscatter`` (the single-scattering lobe is reciprocal).

    Returns
    -------
    (k, 3) float64
    """
    smooth = mf.is_smooth(alpha)
    if smooth.all():  # perfect mirrors only: nothing off the delta lobe
        return np.zeros((wo.shape[0], 3))
    side = side_of(wo)
    wo_, wi_ = flip_to_upper(wo, side), flip_to_upper(wi, side)
    co, ci = wo_[:, 2], wi_[:, 2]
    h, ok = normalize(wo_ + wi_)
    ok &= (co > 0.0) & (ci > 0.0) & ~smooth
    val = mf.ggx_d(h[:, 2], alpha) * mf.ggx_visibility(co, ci, alpha) * ci
    f = fresnel_schlick(f0, dot(wo_, h)) * val[:, None]
    if multiscatter:
        f = f * multiscatter_factor(f0, alpha, wo_, wi_, mode)
    return np.where(ok[:, None], f, 0.0)


def pdf_conductor(alpha, wo, wi):
    """Solid-angle density of :func:`sample_conductor` at ``wi`` (zero on smooth rows). ``(k,)``.

    ``D_wo(h) / (4 wo.h) = D(h) / (4 A(wo))`` with ``A`` the projected microsurface area
    (:func:`.microfacet.ggx_projected_area`).
    """
    smooth = mf.is_smooth(alpha)
    if smooth.all():  # perfect mirrors only: no density off the delta lobe
        return np.zeros(wo.shape[0])
    side = side_of(wo)
    wo_, wi_ = flip_to_upper(wo, side), flip_to_upper(wi, side)
    co, ci = wo_[:, 2], wi_[:, 2]
    h, ok = normalize(wo_ + wi_)
    ok &= (co > 0.0) & (ci > 0.0) & ~smooth
    pdf = mf.ggx_d(h[:, 2], alpha) / (4.0 * mf.ggx_projected_area(co, alpha))
    return np.where(ok, pdf, 0.0)


def sample_conductor(f0, alpha, wo, u, multiscatter=False, mode=RADIANCE):
    """Sample ``wi`` by visible normals; smooth rows reflect perfectly.

    Parameters
    ----------
    f0 : (k, 3) float
    alpha : (k,) float
    wo : (k, 3) float
    u : (k, 2) float
    multiscatter : bool
        Scale the weight by the Multiscatter GGX factor (the pdf is unchanged).
    mode : {'radiance', 'importance'}

    Returns
    -------
    wi : (k, 3) float64
        Zero where the sample failed (reflected below the surface, or ``wo`` tangent).
    weight : (k, 3) float64
        ``f |cos theta_i| / pdf = F(wo.h) G2 / G1(wo)`` (times the Multiscatter GGX factor);
        the Fresnel for delta rows.
    pdf : (k,) float64
        Solid-angle density; 1 on delta rows; 0 where failed.
    delta : (k,) bool
        Smooth rows.
    """
    delta = mf.is_smooth(alpha)
    if delta.all():  # perfect mirrors only (the rough lobe below would be discarded)
        wi_d, weight_d, pdf_d, _ = sample_mirror(f0, wo)
        return wi_d, weight_d, pdf_d, delta
    side = side_of(wo)
    wo_ = flip_to_upper(wo, side)
    co = wo_[:, 2]
    wm = mf.sample_ggx_visible(wo_, alpha, u)
    wi_ = reflect(wo_, wm)
    ci = wi_[:, 2]
    ok = (co > 0.0) & (ci > 0.0)
    weight = fresnel_schlick(f0, dot(wo_, wm)) * mf.ggx_g2_over_g1(co, ci, alpha)[:, None]
    if multiscatter:
        weight = weight * multiscatter_factor(f0, alpha, wo_, wi_, mode)
    pdf = mf.ggx_d(wm[:, 2], alpha) / (4.0 * mf.ggx_projected_area(co, alpha))
    wi = flip_to_upper(wi_, side)

    wi_d, weight_d, pdf_d, _ = sample_mirror(f0, wo)
    wi = np.where(delta[:, None], wi_d, np.where(ok[:, None], wi, 0.0))
    weight = np.where(delta[:, None], weight_d, np.where(ok[:, None], weight, 0.0))
    pdf = np.where(delta, pdf_d, np.where(ok, pdf, 0.0))
    return wi, weight, pdf, delta
