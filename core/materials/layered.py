"""A dielectric specular coat over a diffuse base: the Principled BSDF's non-metallic, opaque
lobe (Specular IOR Level over Base Color), and Blender's "plastic".

Model (Cycles' *albedo scaling* layering, radiance mode)::

    f(wo, wi) = F_t(wo.h) D G / (4 cos_o) + albedo / pi * (1 - max_c E_t(mu_o))

- The specular lobe is single-scattering GGX with Cycles' *generalized Schlick* Fresnel of the
  Principled specular layer (:func:`tinted_fresnel`): ``F_t = f0 + (1 - f0) s``,
  ``f0 = tint F0(eta)``, ``s = (F - F0) / (1 - F0)`` the exact dielectric Fresnel
  ``F(wo.h, eta)`` remapped to [0, 1]; ``eta`` the layer's index (Principled: the IOR adjusted
  by Specular IOR Level, see :func:`.fresnel.adjust_ior_for_specular_level`), ``tint`` the
  Specular Tint in [0, 1]. A white tint gives the exact Fresnel; any tint turns white at
  grazing angles, as in Cycles.
- ``E_t(mu_o) = int f_spec cos_i dwi`` is the lobe's directional albedo per channel
  (:func:`specular_albedo`): ``F(mu_o)``-based exactly for a smooth lobe; for a rough one it
  combines a precomputed table of the exact-Fresnel albedo ``E`` (the data module
  ``coat_albedo_table.py``, the quadrature :func:`coat_albedo` over ``(mu, roughness, eta)``,
  interpolated trilinearly) with the ``F = 1`` albedo of :mod:`.multiscatter`, using that
  ``F_t`` is linear in ``F``.
- The diffuse base is attenuated by the energy the lobe reflects in its brightest channel (as
  Cycles' ``closure_layering_weight``), so the directional albedo is
  ``E_t(mu_o) + albedo (1 - max_c E_t(mu_o)) <= 1``: **energy-bounded, and
  energy-conserving for a white albedo and tint**, up to the table's error (for IOR 1 to 3:
  below 2e-3 for ``mu_o >= 0.2``, and 1.1e-2 at worst, at grazing ``wo`` and roughness near
  0.1; checked by the tests).
- Why this form: it is the structure of Cycles' Principled BSDF (a flat Lambert base scaled by
  ``1 - E(wo)``), so a white furnace and the base's angular response match Cycles; the
  reciprocal variant ``(1 - E(mu_o)) (1 - E(mu_i)) / (1 - E_avg)`` would brighten the base
  by ~5 % at normal incidence relative to Cycles.
- Multiscatter GGX (``multiscatter=True``, Blender's Principled default): the specular lobe
  is scaled by Cycles' compensation factor of ``wo`` (:func:`multiscatter_factor`, Kulla and
  Conty 2017 as in :mod:`.multiscatter`, with the tinted Fresnel's hemispherical average) and
  the base is attenuated by the compensated lobe's albedo, as Cycles' layering does; a white
  layer over a white base then still conserves energy.
- Limits: the base's light is not refracted by the layer nor
  internally reflected (no darkening and saturation of a real varnished surface); the diffuse
  attenuation depends on ``wo`` only, which makes the BSDF **non-reciprocal**. The adjoint
  ``f*(wo, wi) = f(wi, wo)``, i.e. ``(1 - max_c E_t(mu_i))``, is what ``mode='importance'``
  evaluates: light paths (BDPT, photons) must use it.
- Two-sided like every reflection-only BSDF: directions are mirrored to ``wo``'s side.

Sampling picks the specular lobe with probability ``p = s / (s + d)``, ``s = mean_c E_t(mu_o)``,
``d = mean(albedo) (1 - max_c E_t(mu_o))`` (the lobes' albedos), then samples visible normals
(rough lobe) or reflects perfectly (smooth lobe: a delta sample with ``pdf = p``), or the cosine
hemisphere. For rough lobes the pdf is the mixture ``p pdf_spec + (1 - p) cos / pi``; for smooth
ones ``eval`` and ``pdf`` hold the diffuse part only (``(1 - p) cos / pi``), the delta lobe
appears only through ``sample``.

A *base normal* (:func:`base_normal_eval`, :func:`base_normal_pdf`,
:func:`base_normal_sample`) turns the diffuse base around its own unit normal ``n_d`` (local
coordinates) while the specular lobe keeps +Z: Cycles bends the specular closure's normal
for a valid reflection under Bump Map Correction but keeps the diffuse closure's
(``svm/closure.h``). The base lobe is then ``albedo (1 - max_c E_t(mu_o)) max(n_d . wi, 0) /
pi`` (zero where ``wo`` is below +Z, like the rest), sampled around ``n_d``.

Regenerate the table with ``python -m sampling_lab.core.materials.layered``.
"""

from __future__ import annotations

import base64
import sys

import numpy as np

from ..sampling import warps
from . import anisotropic as aniso
from . import microfacet as mf
from .dielectric import RADIANCE, _check_mode
from .frame import dot, flip_to_upper, normalize, reflect, reflect_z, side_of
from .fresnel import f0_from_ior, fresnel_dielectric
from .multiscatter import albedo_lookup, compensation, ggx_albedo

# Table resolution: nodes uniform in sqrt(mu), in roughness = sqrt(alpha), and in
# sqrt((eta - 1) / (eta + 1)) (= F0^(1/4)), which puts them where E changes fastest: at grazing
# angles, low roughness and indices near one.
N_MU = 32
N_ROUGHNESS = 32
N_ETA = 32
QUADRATURE = 48


# --------------------------------------------------------------------------------------------
# The coat's directional albedo
# --------------------------------------------------------------------------------------------


def coat_albedo(mu, alpha, eta, n=QUADRATURE):
    """Directional albedo ``E(mu) = int f_coat(wo, wi) cos_i dwi`` of the GGX dielectric coat:
    :func:`.multiscatter.ggx_albedo` with the dielectric Fresnel of ``eta``; ``n = 48`` nodes per
    dimension are accurate to about 2e-4.

    Parameters
    ----------
    mu, alpha, eta : (k,) float
        ``cos theta_o`` in (0, 1], GGX alpha, coat index (>= 1).
    n : int
        Nodes per dimension.

    Returns
    -------
    (k,) float64
    """
    return ggx_albedo(mu, alpha, eta, n)


def _table_nodes():
    """Node values ``(mu, alpha, eta)`` of the table axes."""
    mu = np.maximum(np.linspace(0.0, 1.0, N_MU) ** 2, 1e-6)
    alpha = np.maximum(np.linspace(0.0, 1.0, N_ROUGHNESS) ** 2, mf.ALPHA_MIN)
    x = np.minimum(np.linspace(0.0, 1.0, N_ETA) ** 2, 1.0 - 1e-9)
    eta = (1.0 + x) / (1.0 - x)
    return mu, alpha, eta


def compute_table(n=QUADRATURE):
    """The table ``E[mu, roughness, eta]`` ``(N_MU, N_ROUGHNESS, N_ETA)``; roughness 0 is F."""
    mu, alpha, eta = _table_nodes()
    m, a, e = (v.reshape(-1) for v in np.meshgrid(mu, alpha, eta, indexing="ij"))
    table = coat_albedo(m, a, e, n)
    # The smooth limit is the Fresnel reflectance itself.
    smooth = a <= mf.ALPHA_MIN
    table[smooth] = fresnel_dielectric(m[smooth], e[smooth])
    return np.clip(table, 0.0, 1.0).reshape(N_MU, N_ROUGHNESS, N_ETA)


def encode_table(table):
    """Table -> base64 text lines of little-endian uint16 ``round(E * 65535)``."""
    q = np.round(np.clip(table, 0.0, 1.0) * 65535.0).astype("<u2")
    raw = base64.b64encode(np.ascontiguousarray(q).tobytes()).decode("ascii")
    return [raw[i:i + 92] for i in range(0, len(raw), 92)]


def decode_table(text):
    """Inverse of :func:`encode_table`: ``(N_MU, N_ROUGHNESS, N_ETA)`` float64."""
    q = np.frombuffer(base64.b64decode("".join(text)), "<u2")
    return q.astype(np.float64).reshape(N_MU, N_ROUGHNESS, N_ETA) / 65535.0


def write_table(path):
    """Compute the table and write the data module ``coat_albedo_table.py`` to ``path``."""
    lines = encode_table(compute_table())
    with open(path, "w", encoding="ascii") as f:
        f.write('"""Directional albedo of the GGX dielectric coat, generated by\n'
                '``python -m sampling_lab.core.materials.layered``: do not edit.\n\n'
                f"E[mu, roughness, eta] on {N_MU} x {N_ROUGHNESS} x {N_ETA} nodes uniform in "
                "sqrt(mu), roughness and\nsqrt((eta - 1) / (eta + 1)) "
                f"(:func:`.layered.coat_albedo`, {QUADRATURE} x {QUADRATURE} nodes), as\n"
                "little-endian uint16 E * 65535, base64.\n"
                '"""\n\n')
        f.write(f"N_MU = {N_MU}\nN_ROUGHNESS = {N_ROUGHNESS}\nN_ETA = {N_ETA}\n\n")
        f.write("DATA = (\n")
        for line in lines:
            f.write(f'    "{line}"\n')
        f.write(")\n")


_TABLE = None


def albedo_table():
    """The stored table ``(N_MU, N_ROUGHNESS, N_ETA)`` float64 (decoded on first use)."""
    global _TABLE
    if _TABLE is None:
        from . import coat_albedo_table as t
        if (t.N_MU, t.N_ROUGHNESS, t.N_ETA) != (N_MU, N_ROUGHNESS, N_ETA):
            raise RuntimeError("coat_albedo_table.py is stale: regenerate it")
        _TABLE = decode_table(t.DATA)
    return _TABLE


def coat_albedo_lookup(mu, alpha, eta):
    """``E(mu)`` of the coat: exact Fresnel for smooth rows, the table otherwise. ``(k,)``.

    Parameters
    ----------
    mu : (k,) float
        ``|cos theta|``; clipped to [0, 1].
    alpha, eta : (k,) float
        GGX alpha and coat index (below one, its reciprocal is used).
    """
    mu = np.clip(np.abs(mu), 0.0, 1.0)
    eta = np.asarray(eta, np.float64)
    eta = np.where(eta < 1.0, 1.0 / np.maximum(eta, 1e-12), eta)
    table = albedo_table()
    x = np.clip((eta - 1.0) / (eta + 1.0), 0.0, 1.0)
    coords = (np.sqrt(mu) * (N_MU - 1),
              np.clip(np.sqrt(alpha), 0.0, 1.0) * (N_ROUGHNESS - 1),
              np.sqrt(x) * (N_ETA - 1))
    idx, frac = [], []
    for c, n in zip(coords, table.shape):
        i = np.clip(np.floor(c).astype(np.int64), 0, n - 2)
        idx.append(i)
        frac.append(np.clip(c - i, 0.0, 1.0))
    e = np.zeros(mu.shape)
    for dm in (0, 1):
        wm_ = frac[0] if dm else 1.0 - frac[0]
        for dr in (0, 1):
            wr = frac[1] if dr else 1.0 - frac[1]
            for dx in (0, 1):
                wx = frac[2] if dx else 1.0 - frac[2]
                e += wm_ * wr * wx * table[idx[0] + dm, idx[1] + dr, idx[2] + dx]
    smooth = mf.is_smooth(alpha)
    return np.where(smooth, fresnel_dielectric(mu, eta), e)


# --------------------------------------------------------------------------------------------
# The BSDF
# --------------------------------------------------------------------------------------------


def tinted_fresnel(f, eta, tint):
    """Cycles' generalized Schlick Fresnel of the Principled specular layer, ``(k, 3)``:
    ``f0 + (1 - f0) s`` with ``f0 = tint F0(eta)`` and ``s = (F - F0) / (1 - F0)`` the exact
    Fresnel ``f (k,)`` remapped to [0, 1] (white ``tint``: ``f`` itself; grazing: white)."""
    f0 = f0_from_ior(eta)
    s = np.clip((f - f0) / np.maximum(1.0 - f0, 1e-12), 0.0, 1.0)
    f0t = tint * f0[:, None]
    return f0t + (1.0 - f0t) * s[:, None]


def fresnel_average(eta, n=32):
    """Hemispherical average ``2 int_0^1 F(mu, eta) mu dmu`` of the exact dielectric Fresnel
    (Gauss-Legendre in ``sqrt(mu)``, ``n`` nodes: ~1e-6 accurate). ``(k,)``."""
    x, w = np.polynomial.legendre.leggauss(n)
    t = 0.5 * (x + 1.0)                       # sqrt(mu) in (0, 1)
    mu = t * t
    # A batch holds few distinct indices (one per material): integrate each once.
    eta, inverse = np.unique(np.asarray(eta, np.float64), return_inverse=True)
    f = fresnel_dielectric(mu[None, :], eta[:, None])
    # 2 int F mu dmu = 2 int F t^2 2 t dt, dt = dx / 2.
    return np.sum(f * (2.0 * mu * 2.0 * t * 0.5 * w)[None, :], axis=1)[inverse.reshape(-1)]


def multiscatter_factor(mu, alpha, eta, tint):
    """Cycles' Multiscatter GGX factor ``(k, 3)`` of the tinted specular lobe at ``|cos| = mu``
    (:func:`.multiscatter.compensation`), with ``F_ss`` the hemispherical average of
    :func:`tinted_fresnel`: ``f0 + (1 - f0) s_avg``, ``s_avg`` the remapped average of the
    exact Fresnel (Cycles' ``bsdf_microfacet_setup_fresnel_generalized_schlick``)."""
    f0 = f0_from_ior(eta)
    s_avg = np.clip((fresnel_average(eta) - f0) / np.maximum(1.0 - f0, 1e-12), 0.0, 1.0)
    f0t = tint * f0[:, None]
    return compensation(f0t + (1.0 - f0t) * s_avg[:, None], mu, alpha)


def specular_albedo(mu, alpha, eta, tint, multiscatter=False):
    """Directional albedo ``(k, 3)`` of the tinted specular lobe: ``f0 E_1 + (1 - f0) E_s``
    with ``E_1`` the GGX albedo for ``F = 1`` (:func:`.multiscatter.albedo_lookup`) and
    ``E_s = (E(mu) - F0 E_1) / (1 - F0)`` the albedo of the remapped Fresnel (linear in
    ``F``), ``E(mu)`` from :func:`coat_albedo_lookup`; exactly ``E(mu)`` for a white tint.
    With ``multiscatter``, times :func:`multiscatter_factor` (Cycles' estimate of the
    compensated lobe's albedo)."""
    e = coat_albedo_lookup(mu, alpha, eta)
    e1 = np.where(mf.is_smooth(alpha), 1.0, albedo_lookup(np.abs(mu), alpha)[0])
    f0 = f0_from_ior(eta)
    e_s = np.clip((e - f0 * e1) / np.maximum(1.0 - f0, 1e-12), 0.0, 1.0)
    f0t = tint * f0[:, None]
    e_t = f0t * e1[:, None] + (1.0 - f0t) * e_s[:, None]
    if multiscatter:
        e_t = e_t * multiscatter_factor(mu, alpha, eta, tint)
    return np.clip(e_t, 0.0, 1.0)


def _lobe_albedos(albedo, e_spec):
    """Coat and diffuse directional albedos (channel means) and the diffuse scale."""
    diffuse_scale = np.maximum(0.0, 1.0 - np.max(e_spec, axis=1))
    s = np.mean(e_spec, axis=1)
    d = np.mean(albedo, axis=1) * diffuse_scale
    return s, d, diffuse_scale


def _coat_probability(albedo, e_spec):
    s, d, _ = _lobe_albedos(albedo, e_spec)
    total = s + d
    return np.where(total > 0.0, s / np.where(total > 0.0, total, 1.0), 0.5)


def coat_probability(albedo, alpha, eta, tint, wo, multiscatter=False):
    """Probability ``p (k,)`` with which :func:`sample_layered` samples the coat: a sample with
    ``u_lobe < p`` is a coat (glossy or mirror) sample, the others diffuse."""
    return _coat_probability(albedo, specular_albedo(wo[:, 2], alpha, eta, tint, multiscatter))


def _mean_alpha(alpha, alpha_y):
    """The alpha the albedo tables and the smooth test read: ``sqrt(ax ay)`` (Cycles)."""
    return alpha if alpha_y is None else np.sqrt(alpha * alpha_y)


def _lobe_parts(eta, alpha, wo_, wi_, alpha_y=None):
    """``D G cos_i`` and the exact Fresnel ``F(wo.h)`` of the rough lobe, upper hemisphere;
    anisotropic (:mod:`.anisotropic`, ``alpha`` along x) when ``alpha_y`` is given."""
    co, ci = wo_[:, 2], wi_[:, 2]
    h, ok = normalize(wo_ + wi_)
    ok &= (co > 0.0) & (ci > 0.0) & ~mf.is_smooth(_mean_alpha(alpha, alpha_y))
    if alpha_y is None:
        dg = mf.ggx_d(h[:, 2], alpha) * mf.ggx_visibility(co, ci, alpha) * ci
    else:
        dg = aniso.ggx_d_aniso(h, alpha, alpha_y) * aniso.visibility(wo_, wi_, alpha,
                                                                      alpha_y) * ci
    return np.where(ok, dg, 0.0), fresnel_dielectric(dot(wo_, h), eta)


def coat_lobe_eval(eta, alpha, wo_, wi_):
    """``f_coat cos_i`` (white tint) for directions already in the upper hemisphere."""
    dg, f = _lobe_parts(eta, alpha, wo_, wi_)
    return dg * f


def coat_lobe_pdf(alpha, wo_, wi_, alpha_y=None):
    """Visible-normal sampling density of the rough coat lobe (upper-hemisphere directions);
    anisotropic when ``alpha_y`` is given."""
    co, ci = wo_[:, 2], wi_[:, 2]
    h, ok = normalize(wo_ + wi_)
    ok &= (co > 0.0) & (ci > 0.0) & ~mf.is_smooth(_mean_alpha(alpha, alpha_y))
    if alpha_y is not None:
        return np.where(ok, aniso.ggx_d_aniso(h, alpha, alpha_y)
                        / (4.0 * aniso.projected_area(wo_, alpha, alpha_y)), 0.0)
    return np.where(ok, mf.ggx_d(h[:, 2], alpha) / (4.0 * mf.ggx_projected_area(co, alpha)), 0.0)


def eval_layered(albedo, alpha, eta, tint, wo, wi, mode=RADIANCE, multiscatter=False,
                 alpha_y=None):
    """``f(wo, wi) |cos theta_i|`` (the non-delta part for smooth coats).

    Parameters
    ----------
    albedo : (k, 3) float
        Diffuse base colour.
    alpha : (k,) float
        Coat GGX alpha.
    eta : (k,) float
        Coat index (>= 1).
    tint : (k, 3) float
        Coat (specular) tint.
    wo, wi : (k, 3) float
    mode : {'radiance', 'importance'}
        Importance mode evaluates the adjoint (diffuse attenuation by ``E(mu_i)``).
    multiscatter : bool
        Blender's Multiscatter GGX: the specular lobe scaled by :func:`multiscatter_factor` at
        ``mu_o`` (``mu_i`` for the adjoint), the base attenuated by that lobe's albedo.
    alpha_y : (k,) float, optional
        An anisotropic specular lobe (``alpha`` along x, :mod:`.anisotropic`); its albedo and
        compensation are read at ``sqrt(alpha alpha_y)``, as Cycles reads them.

    Returns
    -------
    (k, 3) float64
    """
    _check_mode(mode)
    side = side_of(wo)
    wo_, wi_ = flip_to_upper(wo, side), flip_to_upper(wi, side)
    co, ci = wo_[:, 2], wi_[:, 2]
    ok = (co > 0.0) & (ci > 0.0)
    mu = co if mode == RADIANCE else ci
    mean = _mean_alpha(alpha, alpha_y)
    diffuse_scale = np.maximum(0.0, 1.0 - np.max(
        specular_albedo(mu, mean, eta, tint, multiscatter), axis=1))
    dg, fresnel = _lobe_parts(eta, alpha, wo_, wi_, alpha_y)
    spec = tinted_fresnel(fresnel, eta, tint) * dg[:, None]
    if multiscatter:
        spec = spec * multiscatter_factor(mu, mean, eta, tint)
    f = spec + albedo * (diffuse_scale * ci * warps.INV_PI)[:, None]
    return np.where(ok[:, None], f, 0.0)


def pdf_layered(albedo, alpha, eta, tint, wo, wi, multiscatter=False, alpha_y=None):
    """Solid-angle density of :func:`sample_layered` (non-delta part). ``(k,)``."""
    side = side_of(wo)
    wo_, wi_ = flip_to_upper(wo, side), flip_to_upper(wi, side)
    co, ci = wo_[:, 2], wi_[:, 2]
    ok = (co > 0.0) & (ci > 0.0)
    p = _coat_probability(albedo, specular_albedo(co, _mean_alpha(alpha, alpha_y), eta, tint,
                                                  multiscatter))
    pdf = p * coat_lobe_pdf(alpha, wo_, wi_, alpha_y) + (1.0 - p) * ci * warps.INV_PI
    return np.where(ok, pdf, 0.0)


def sample_layered(albedo, alpha, eta, tint, wo, u_lobe, u, mode=RADIANCE, multiscatter=False,
                   alpha_y=None):
    """Sample the coat (visible normals or delta) or the diffuse base.

    Parameters
    ----------
    albedo, alpha, eta, tint, wo, mode, multiscatter, alpha_y
        As :func:`eval_layered`.
    u_lobe : (k,) float
        Chooses the coat (``u_lobe < p``) or the base.
    u : (k, 2) float

    Returns
    -------
    wi : (k, 3) float64
    weight : (k, 3) float64
        ``f |cos| / pdf`` with the mixture pdf; for the delta lobe ``F_t(mu_o) / p``.
    pdf : (k,) float64
        Mixture solid-angle density; ``p`` for a delta coat sample; 0 if the sample failed.
    delta : (k,) bool
        A smooth coat's mirror reflection was sampled.
    """
    _check_mode(mode)
    side = side_of(wo)
    wo_ = flip_to_upper(wo, side)
    co = wo_[:, 2]
    mean = _mean_alpha(alpha, alpha_y)
    p = _coat_probability(albedo, specular_albedo(co, mean, eta, tint, multiscatter))
    smooth = mf.is_smooth(mean)
    choose_coat = u_lobe < p

    wm = mf.sample_ggx_visible(wo_, alpha, u, alpha_y)
    wi_coat = np.where(smooth[:, None], reflect_z(wo_), reflect(wo_, wm))
    wi_diff = warps.sample_cosine_hemisphere(u)
    wi_ = np.where(choose_coat[:, None], wi_coat, wi_diff)
    ci = wi_[:, 2]
    delta = choose_coat & smooth
    ok = (co > 0.0) & (ci > 0.0)

    # Non-delta samples: weight = f cos / (mixture pdf), evaluated at the sampled direction.
    wi = flip_to_upper(wi_, side)
    f = eval_layered(albedo, alpha, eta, tint, wo, wi, mode, multiscatter, alpha_y)
    pdf = pdf_layered(albedo, alpha, eta, tint, wo, wi, multiscatter, alpha_y)
    good = ok & (pdf > 0.0)
    weight = f / np.where(good, pdf, 1.0)[:, None]

    # Delta coat samples: the tinted F(mu_o) / p.
    f_delta = tinted_fresnel(fresnel_dielectric(co, eta), eta, tint)
    weight = np.where(delta[:, None], f_delta / np.where(p > 0.0, p, 1.0)[:, None], weight)
    pdf = np.where(delta, p, pdf)
    good = np.where(delta, ok & (p > 0.0), good)
    return (np.where(good[:, None], wi, 0.0), np.where(good[:, None], weight, 0.0),
            np.where(good, pdf, 0.0), delta & good)


def _base_parts(albedo, alpha, eta, tint, wo, wi, mode, multiscatter, n):
    """``(diffuse f cos (k, 3), its pdf share (k,))`` of the base around the local normal
    ``n (k, 3)`` (+Z when None), two-sided like the rest (mirrored to ``wo``'s side)."""
    side = side_of(wo)
    wo_, wi_ = flip_to_upper(wo, side), flip_to_upper(wi, side)
    co = wo_[:, 2]
    cos = wi_[:, 2] if n is None else dot(flip_to_upper(n, side), wi_)
    up = co > 0.0
    if n is None:
        up &= cos > 0.0
    cos = np.where(up, np.maximum(cos, 0.0), 0.0)
    mu = co if mode == RADIANCE else wi_[:, 2]
    e = specular_albedo(mu, alpha, eta, tint, multiscatter)
    scale = np.maximum(0.0, 1.0 - np.max(e, axis=1))
    p = _coat_probability(albedo, specular_albedo(co, alpha, eta, tint, multiscatter))
    return albedo * (scale * cos * warps.INV_PI)[:, None], (1.0 - p) * cos * warps.INV_PI


def base_normal_eval(f, albedo, alpha, eta, tint, wo, wi, n, mode=RADIANCE,
                     multiscatter=False):
    """:func:`eval_layered`'s ``f (k, 3)`` with the base turned to the local normal ``n``.

    ``alpha`` is the mean alpha (``sqrt(ax ay)``), the other parameters as
    :func:`eval_layered`; rows whose ``n`` is +Z are unchanged up to rounding.
    """
    old, _ = _base_parts(albedo, alpha, eta, tint, wo, wi, mode, multiscatter, None)
    new, _ = _base_parts(albedo, alpha, eta, tint, wo, wi, mode, multiscatter, n)
    return np.maximum(f - old, 0.0) + new


def base_normal_pdf(pdf, albedo, alpha, eta, tint, wo, wi, n, multiscatter=False):
    """:func:`pdf_layered`'s ``pdf (k,)`` with the base sampled around the local normal ``n``."""
    _, old = _base_parts(albedo, alpha, eta, tint, wo, wi, RADIANCE, multiscatter, None)
    _, new = _base_parts(albedo, alpha, eta, tint, wo, wi, RADIANCE, multiscatter, n)
    return np.maximum(pdf - old, 0.0) + new


def base_normal_sample(wi, albedo, alpha, eta, tint, wo, u_lobe, u, n, multiscatter=False):
    """Directions ``(k, 3)``: :func:`sample_layered`'s ``wi`` where it chose the coat, and a
    cosine-distributed direction around the local normal ``n`` (mirrored to ``wo``'s side)
    where it chose the base (``u_lobe >= p``, the same choice). The caller recomputes weights
    and pdfs of the non-delta samples from :func:`base_normal_eval` and
    :func:`base_normal_pdf`."""
    side = side_of(wo)
    co = flip_to_upper(wo, side)[:, 2]
    p = _coat_probability(albedo, specular_albedo(co, alpha, eta, tint, multiscatter))
    nd = flip_to_upper(n, side)
    base = flip_to_upper(warps.to_world_around(warps.sample_cosine_hemisphere(u), nd), side)
    return np.where((u_lobe >= p)[:, None], base, wi)


if __name__ == "__main__":
    import os
    import time

    t0 = time.perf_counter()
    target = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__),
                                                               "coat_albedo_table.py")
    write_table(target)
    print(f"wrote {target} in {time.perf_counter() - t0:.1f} s")
