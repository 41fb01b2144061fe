"""Dielectrics: smooth (delta) and rough (GGX, Walter et al. 2007) reflection plus refraction.

Blender's Glass BSDF and the transmission lobe of the Principled BSDF.

Sides and indices
    ``eta`` is the material's index, interior over exterior. The local frame's +Z is the
    surface normal as stored (pointing to the exterior, *not* flipped toward the viewer), so
    ``wo.z > 0`` means the viewer is outside and ``wo.z < 0`` inside. ``etap`` is the index on
    the side of ``wi`` over the index on the side of ``wo``: ``eta`` for a ray entering from
    outside, ``1 / eta`` for one leaving.
Lobes
    Reflection ``F D G2 / (4 |cos_o cos_i|)`` and transmission (Walter et al. 2007, eq. 21, in
    pbrt-v4's form) with the exact unpolarised dielectric Fresnel at the microfacet,
    ``F(wo.m)``, height-correlated Smith ``G2`` and the generalized half vector
    ``m = +-(etap wi + wo) / |...|``. Total internal reflection is ``F = 1``. Reflection is
    tinted by ``reflect_tint``, transmission by ``transmit_tint`` (Glass BSDF: both the Color;
    Principled: specular tint and base color).
Sampling
    Visible normals from ``wo`` (Heitz 2018), then reflection with probability ``F(wo.m)`` and
    refraction otherwise. The pdf of a direction is the sum over both lobes of lobe probability
    times Jacobian-transformed visible-normal density; it integrates to the probability that a
    sample is valid (directions scattered to the wrong side are lost, as single-scattering
    microfacet models lose them). The sample weight is ``G2 / G1(wo)`` times the tint (and
    ``1 / etap^2`` for radiance transmission), never larger than one in importance mode.
    Cycles differs: its sampler keeps refractions that turn back into ``wo``'s hemisphere, and
    its eval does not reject pairs whose microfacet faces away from ``wo`` or ``wi``, so its
    rough glass is brighter at high roughness (``tests/core/test_rough_glass.py``).
Transport mode
    ``RADIANCE`` (camera paths: ``wo`` points toward the camera, ``wi`` toward the light) scales
    transmitted radiance by ``1 / etap^2`` (radiance is compressed into a smaller solid angle
    entering a denser medium: ``L / n^2`` is invariant, Veach 1997 sec. 5.2). ``IMPORTANCE``
    (light paths, BDPT light subpaths, photons: ``wo`` points toward the light) omits it. With
    this convention ``eval(wo, wi, RADIANCE) / n(wo)^2 == eval(wi, wo, RADIANCE) / n(wi)^2``
    (generalized reciprocity) and ``f_IMPORTANCE(wo, wi) = f_RADIANCE(wi, wo)``.
    Cycles does not apply the ``1 / eta^2`` factor (its glass is our importance mode on camera
    paths); the two agree whenever camera and lights are outside closed dielectric objects, as
    the factors of entering and leaving cancel along every path.
Smooth variant
    Rows with ``alpha <= ALPHA_SMOOTH`` (Cycles' threshold) or ``|eta - 1| < ETA_SMOOTH``
    (Cycles: an index-matched interface is treated as specular) are delta BSDFs: ``eval`` and
    ``pdf`` are zero, and ``sample`` picks reflection with probability ``F(cos_o)`` (``pdf = F``,
    weight = reflect tint) or refraction (``pdf = 1 - F``, weight = transmit tint, times
    ``1 / etap^2`` in radiance mode), with ``delta = True``. ``eta == 1`` transmits straight
    through (``wi = -wo``) and never reflects.
"""

from __future__ import annotations

import numpy as np

from . import microfacet as mf
from .frame import dot, normalize, reflect, reflect_z, refract
from .fresnel import fresnel_dielectric

RADIANCE = "radiance"
IMPORTANCE = "importance"
TRANSPORT_MODES = (RADIANCE, IMPORTANCE)

# Cycles treats |ior - 1| < 1e-4 as a specular (index-matched) interface.
ETA_SMOOTH = 1e-4

_Z = np.array([0.0, 0.0, 1.0])


def _check_mode(mode):
    if mode not in TRANSPORT_MODES:
        raise ValueError(f"transport mode must be one of {TRANSPORT_MODES}, got {mode!r}")


def is_smooth_dielectric(eta, alpha):
    """Rows handled as the delta (smooth) dielectric. ``(k,)`` bool."""
    return mf.is_smooth(alpha) | (np.abs(np.asarray(eta) - 1.0) < ETA_SMOOTH)


def _rough_terms(eta, alpha, wo, wi):
    """Shared geometry of :func:`eval_dielectric` and :func:`pdf_dielectric`.

    Returns validity, reflection mask, etap, the microfacet normal's D, the dot products with
    it, and the Fresnel.
    """
    co, ci = wo[:, 2], wi[:, 2]
    refl = co * ci > 0.0
    etap = np.where(refl, 1.0, np.where(co > 0.0, eta, 1.0 / eta))
    wm, ok = normalize(wi * etap[:, None] + wo)
    # Face the microfacet normal to the exterior.
    wm = np.where((wm[:, 2] < 0.0)[:, None], -wm, wm)
    dwo, dwi = dot(wo, wm), dot(wi, wm)
    # Microfacets seen from the back by either direction scatter nothing.
    ok &= (co != 0.0) & (ci != 0.0) & (wm[:, 2] > 0.0) & (dwo * co > 0.0) & (dwi * ci > 0.0)
    ok &= ~is_smooth_dielectric(eta, alpha)
    d = mf.ggx_d(wm[:, 2], alpha)
    f = fresnel_dielectric(dwo, eta)
    return ok, refl, etap, d, dwo, dwi, f


def multiscatter_factor(eta, alpha, transmit_tint, wo, wi, mode=RADIANCE):
    """Cycles' Multiscatter GGX factor ``(k, 3)`` of the rough dielectric
    (:func:`.glass_albedo.compensation`, ``F_ss`` = the transmission tint): at ``wo`` with the
    index seen from ``wo``'s side (radiance), at ``wi`` for the adjoint (importance)."""
    from .glass_albedo import compensation
    w = wo if mode == RADIANCE else wi
    side_eta = np.where(w[:, 2] >= 0.0, eta, 1.0 / np.maximum(eta, 1e-12))
    return compensation(w[:, 2], alpha, side_eta, transmit_tint)


def eval_dielectric(eta, alpha, reflect_tint, transmit_tint, wo, wi, mode=RADIANCE,
                    multiscatter=False):
    """``f(wo, wi) |cos theta_i|`` of the rough dielectric (zero on smooth rows).

    Parameters
    ----------
    eta : (k,) float
        Interior over exterior index.
    alpha : (k,) float
    reflect_tint, transmit_tint : (k, 3) float
    wo, wi : (k, 3) float
        Unit directions in the local frame (+Z to the exterior).
    mode : {'radiance', 'importance'}
    multiscatter : bool
        Scale by the Multiscatter GGX factor (:func:`multiscatter_factor`).

    Returns
    -------
    (k, 3) float64
    """
    _check_mode(mode)
    ok, refl, etap, d, dwo, dwi, f = _rough_terms(eta, alpha, wo, wi)
    co, ci = wo[:, 2], wi[:, 2]
    vis = mf.ggx_visibility(co, ci, alpha)
    aci = np.abs(ci)
    r = d * vis * f * aci
    # Transmission: D G2 (1 - F) |wi.m wo.m| / (|cos_o| (wi.m + wo.m / etap)^2), with
    # G2 / |cos_o| = 4 V |cos_i| to stay finite at grazing wo.
    den2 = (dwi + dwo / etap) ** 2
    ok &= refl | (den2 > 0.0)
    den2 = np.where(ok & ~refl, den2, 1.0)
    t = d * 4.0 * vis * aci * (1.0 - f) * np.abs(dwi * dwo) / den2
    if mode == RADIANCE:
        t = t / (etap * etap)
    out = np.where(refl[:, None], reflect_tint * r[:, None], transmit_tint * t[:, None])
    if multiscatter:
        out = out * multiscatter_factor(eta, alpha, transmit_tint, wo, wi, mode)
    return np.where(ok[:, None], out, 0.0)


def pdf_dielectric(eta, alpha, wo, wi):
    """Solid-angle density of :func:`sample_dielectric` at ``wi`` (zero on smooth rows). ``(k,)``.

    Reflection: ``F D_wo(m) / (4 |wo.m|)``; transmission:
    ``(1 - F) D_wo(m) |wi.m| / (wi.m + wo.m / etap)^2``.
    """
    ok, refl, etap, d, dwo, dwi, f = _rough_terms(eta, alpha, wo, wi)
    co = wo[:, 2]
    area = mf.ggx_projected_area(co, alpha)
    den2 = (dwi + dwo / etap) ** 2
    ok &= refl | (den2 > 0.0)
    den2 = np.where(ok & ~refl, den2, 1.0)
    # Visible-normal density D_wo(m) = |wo.m| D(m) / A(wo), times each lobe's Jacobian.
    p_r = f * d / (4.0 * area)
    p_t = (1.0 - f) * np.abs(dwo) * d / area * np.abs(dwi) / den2
    return np.where(ok, np.where(refl, p_r, p_t), 0.0)


def sample_smooth_dielectric(eta, reflect_tint, transmit_tint, wo, u_lobe, mode=RADIANCE):
    """Delta reflection or refraction at a smooth interface, chosen by Fresnel.

    Parameters
    ----------
    eta : (k,) float
    reflect_tint, transmit_tint : (k, 3) float
    wo : (k, 3) float
    u_lobe : (k,) float
    mode : {'radiance', 'importance'}

    Returns
    -------
    wi, weight, pdf, delta
        As :func:`sample_dielectric`; ``pdf`` is the chosen lobe's probability.
    """
    _check_mode(mode)
    co = wo[:, 2]
    f = fresnel_dielectric(co, eta)
    choose_r = u_lobe < f
    wt, ok_t, etap = refract(wo, np.broadcast_to(_Z, wo.shape), eta)
    # An index-matched interface does not deflect: keep the direction exactly.
    wt = np.where((etap == 1.0)[:, None], -wo, wt)
    scale = 1.0 / (etap * etap) if mode == RADIANCE else np.ones_like(etap)
    wi = np.where(choose_r[:, None], reflect_z(wo), wt)
    weight = np.where(choose_r[:, None], reflect_tint, transmit_tint * scale[:, None])
    pdf = np.where(choose_r, f, 1.0 - f)
    ok = (co != 0.0) & (choose_r | ok_t) & (pdf > 0.0)
    return (np.where(ok[:, None], wi, 0.0), np.where(ok[:, None], weight, 0.0),
            np.where(ok, pdf, 0.0), np.ones(wo.shape[0], bool))


def sample_dielectric(eta, alpha, reflect_tint, transmit_tint, wo, u_lobe, u, mode=RADIANCE,
                      multiscatter=False):
    """Sample reflection or refraction; smooth rows take the delta path.

    Parameters
    ----------
    eta : (k,) float
    alpha : (k,) float
    reflect_tint, transmit_tint : (k, 3) float
    wo : (k, 3) float
    u_lobe : (k,) float
        Chooses reflection (``u_lobe < F``) or refraction.
    u : (k, 2) float
        Picks the visible microfacet normal.
    mode : {'radiance', 'importance'}
    multiscatter : bool
        Scale rough samples' weights by :func:`multiscatter_factor`.

    Returns
    -------
    wi : (k, 3) float64
        Zero where the sample failed.
    weight : (k, 3) float64
        ``f |cos theta_i| / pdf``.
    pdf : (k,) float64
        Solid-angle density (lobe probability included); the lobe probability on delta rows.
    delta : (k,) bool
    """
    _check_mode(mode)
    delta = is_smooth_dielectric(eta, alpha)
    if delta.all():
        # Smooth glass only (the usual case): the rough lobe below would be thrown away.
        return sample_smooth_dielectric(eta, reflect_tint, transmit_tint, wo, u_lobe, mode)
    co = wo[:, 2]
    wm = mf.sample_ggx_visible(wo, alpha, u)
    dwo = dot(wo, wm)
    f = fresnel_dielectric(dwo, eta)
    choose_r = u_lobe < f
    wr = reflect(wo, wm)
    wt, ok_t, etap = refract(wo, wm, eta)
    wi = np.where(choose_r[:, None], wr, wt)
    ci = wi[:, 2]
    ok = np.where(choose_r, ci * co > 0.0, ok_t & (ci * co < 0.0)) & (co != 0.0)
    ok &= np.where(choose_r, f > 0.0, f < 1.0)
    etap = np.where(choose_r, 1.0, etap)
    g = mf.ggx_g2_over_g1(co, ci, alpha)
    scale = 1.0 / (etap * etap) if mode == RADIANCE else np.ones_like(etap)
    weight = np.where(choose_r[:, None], reflect_tint, transmit_tint * scale[:, None]) * g[:, None]
    if multiscatter:
        weight = weight * multiscatter_factor(eta, alpha, transmit_tint, wo, wi, mode)
    # Density from the sampled normal (no recomputed half vector): D_wo(m) times the Jacobian.
    d = mf.ggx_d(wm[:, 2], alpha)
    area = mf.ggx_projected_area(co, alpha)
    dwi = dot(wi, wm)
    den2 = (dwi + dwo / etap) ** 2
    ok &= choose_r | (den2 > 0.0)
    den2 = np.where(ok & ~choose_r, den2, 1.0)
    p_r = f * d / (4.0 * area)
    p_t = (1.0 - f) * np.abs(dwo) * d / area * np.abs(dwi) / den2
    pdf = np.where(choose_r, p_r, p_t)
    ok &= pdf > 0.0

    wi_d, weight_d, pdf_d, _ = sample_smooth_dielectric(eta, reflect_tint, transmit_tint, wo,
                                                        u_lobe, mode)
    wi = np.where(delta[:, None], wi_d, np.where(ok[:, None], wi, 0.0))
    weight = np.where(delta[:, None], weight_d, np.where(ok[:, None], weight, 0.0))
    pdf = np.where(delta, pdf_d, np.where(ok, pdf, 0.0))
    return wi, weight, pdf, delta
