"""Anisotropic GGX: the Glossy BSDF's Anisotropy and the Principled BSDF's Anisotropic and
Anisotropic Rotation on its metallic lobe and its specular layer.

The GGX of :mod:`.microfacet` with two roughnesses, ``alpha_x`` along the tangent and
``alpha_y`` along the bitangent (Heitz 2014, "Understanding the Masking-Shadowing Function in
Microfacet-Based BRDFs"; visible normals: Heitz 2018), in the local frame whose x axis is the
shading tangent (:func:`.frame.shading_frame` with a tangent) turned by the rotation about the
normal:

- ``D(m) = 1 / (pi ax ay (mx^2 / ax^2 + my^2 / ay^2 + mz^2)^2)``;
- ``a(w) = sqrt(wz^2 + ax^2 wx^2 + ay^2 wy^2) = |wz| (1 + 2 Lambda(w))``: masking, the
  height-correlated ``G2`` and the projected area ``(|wz| + a(w)) / 2`` keep the finite forms of
  :mod:`.microfacet` with this ``a``;
- visible normals: :func:`.microfacet.sample_ggx_visible` with ``alpha_y``.

With ``ax = ay`` every term is the isotropic one (the tests check it to rounding).

Roughness mapping (Cycles' ``svm_closure.h``), ``alpha = roughness^2`` and ``ax = alpha k``,
``ay = alpha / k`` (:func:`principled_scale`, :func:`glossy_scale`), then clamped to at most 1
as Cycles' ``bsdf_microfacet_ggx_setup`` clamps them:

- Principled: ``k = 1 / sqrt(1 - 0.9 Anisotropic)``, Anisotropic in [0, 1];
- Glossy: ``k = 1 - a`` for an Anisotropy ``a >= 0``, ``1 / (1 + a)`` below, ``a`` clamped to
  [-0.99, 0.99].

Multiscatter GGX: as Cycles (``microfacet_ggx_preserve_energy`` reads its albedo tables at
``sqrt(sqrt(ax ay))``), the isotropic compensation of :mod:`.conductor` at the geometric mean
``alpha = sqrt(ax ay)``; smooth (a perfect mirror) when ``ax ay <= 1e-7``, Cycles' test. The
Principled specular layer (:mod:`.layered` with ``alpha_y``) reads its albedo tables at the
same mean. Only rows whose ``aniso_scale`` differs from 1 or whose rotation is non-zero pay
for any of this (:func:`aniso_rows`); :mod:`.families` routes them here.
"""

from __future__ import annotations

import numpy as np

from . import conductor
from . import microfacet as mf
from .dielectric import RADIANCE
from .frame import dot, flip_to_upper, normalize, reflect, side_of
from .fresnel import fresnel_schlick
from .mirror import sample_mirror

__all__ = ["principled_scale", "glossy_scale", "alphas", "aniso_rows", "ggx_d_aniso",
           "ggx_a_aniso", "projected_area", "visibility", "aniso_visible_pdf",
           "eval_conductor_aniso", "pdf_conductor_aniso", "sample_conductor_aniso", "rotate",
           "anisotropic_part", "mean_alpha"]


def principled_scale(anisotropic):
    """``k`` of the Principled BSDF's Anisotropic (clamped to [0, 1]). ``(k,)``."""
    a = np.clip(np.nan_to_num(np.asarray(anisotropic, np.float64)), 0.0, 1.0)
    return 1.0 / np.sqrt(1.0 - 0.9 * a)


def glossy_scale(anisotropy):
    """``k`` of the Glossy BSDF's Anisotropy (clamped to [-0.99, 0.99]). ``(k,)``."""
    a = np.clip(np.nan_to_num(np.asarray(anisotropy, np.float64)), -0.99, 0.99)
    return np.where(a >= 0.0, 1.0 - a, 1.0 / (1.0 + a))


def alphas(alpha, scale):
    """``(ax, ay)`` ``(k,)`` each: ``alpha k`` and ``alpha / k`` in [``ALPHA_MIN``, 1]."""
    return (np.clip(alpha * scale, mf.ALPHA_MIN, 1.0),
            np.clip(alpha / scale, mf.ALPHA_MIN, 1.0))


def aniso_rows(p):
    """Rows of ``p`` with an anisotropic lobe: ``(j,)`` int64, often empty."""
    if p.aniso_scale is None:
        return np.zeros(0, np.int64)
    return np.nonzero((p.aniso_scale != 1.0) | (p.aniso_rotation != 0.0))[0]


def ggx_a_aniso(w, ax, ay):
    """``a(w) = sqrt(wz^2 + ax^2 wx^2 + ay^2 wy^2)`` ``(k,)``."""
    return np.sqrt(w[:, 2] ** 2 + (ax * w[:, 0]) ** 2 + (ay * w[:, 1]) ** 2)


def ggx_d_aniso(m, ax, ay):
    """``D(m)`` ``(k,)``, zero for ``m.z <= 0``."""
    t = (m[:, 0] / ax) ** 2 + (m[:, 1] / ay) ** 2 + m[:, 2] ** 2
    up = m[:, 2] > 0.0
    return np.where(up, 1.0 / (np.pi * ax * ay * np.where(up, t * t, 1.0)), 0.0)


def projected_area(w, ax, ay):
    """``(|w.z| + a(w)) / 2``, positive for unit ``w``; 1 for a zero vector (a failed row)."""
    area = 0.5 * (np.abs(w[:, 2]) + ggx_a_aniso(w, ax, ay))
    return np.where(area > 0.0, area, 1.0)


def aniso_visible_pdf(wo, wm, ax, ay):
    """Density of visible normals ``max(0, wo.m) D(m) / A(wo)`` (``wo.z >= 0``). ``(k,)``."""
    return np.maximum(0.0, dot(wo, wm)) * ggx_d_aniso(wm, ax, ay) / projected_area(wo, ax, ay)


def visibility(wo, wi, ax, ay):
    """``G2 / (4 |cos_o| |cos_i|) = 1 / (2 (a_o |cos_i| + a_i |cos_o|))``."""
    den = ggx_a_aniso(wo, ax, ay) * np.abs(wi[:, 2]) + ggx_a_aniso(wi, ax, ay) * np.abs(wo[:, 2])
    return np.where(den > 0.0, 0.5 / np.where(den > 0.0, den, 1.0), 0.0)


def _smooth(ax, ay):
    return ax * ay <= mf.ALPHA_SMOOTH ** 2


def eval_conductor_aniso(f0, ax, ay, wo, wi, multiscatter=False, mode=RADIANCE):
    """``f |cos theta_i|`` ``(k, 3)`` of the anisotropic conductor, directions in the
    (rotated) tangent frame; zero on smooth rows. As :func:`.conductor.eval_conductor`."""
    side = side_of(wo)
    wo_, wi_ = flip_to_upper(wo, side), flip_to_upper(wi, side)
    co, ci = wo_[:, 2], wi_[:, 2]
    h, ok = normalize(wo_ + wi_)
    ok &= (co > 0.0) & (ci > 0.0) & ~_smooth(ax, ay)
    val = ggx_d_aniso(h, ax, ay) * visibility(wo_, wi_, ax, ay) * ci
    f = fresnel_schlick(f0, dot(wo_, h)) * val[:, None]
    if multiscatter:
        f = f * conductor.multiscatter_factor(f0, np.sqrt(ax * ay), wo_, wi_, mode)
    return np.where(ok[:, None], f, 0.0)


def pdf_conductor_aniso(ax, ay, wo, wi):
    """Density ``D(h) / (4 A(wo))`` ``(k,)`` of :func:`sample_conductor_aniso`."""
    side = side_of(wo)
    wo_, wi_ = flip_to_upper(wo, side), flip_to_upper(wi, side)
    h, ok = normalize(wo_ + wi_)
    ok &= (wo_[:, 2] > 0.0) & (wi_[:, 2] > 0.0) & ~_smooth(ax, ay)
    pdf = ggx_d_aniso(h, ax, ay) / (4.0 * projected_area(wo_, ax, ay))
    return np.where(ok, pdf, 0.0)


def sample_conductor_aniso(f0, ax, ay, wo, u, multiscatter=False, mode=RADIANCE):
    """Visible-normal sample of the anisotropic conductor; smooth rows reflect perfectly.

    Returns ``(wi, weight, pdf, delta)`` as :func:`.conductor.sample_conductor`, the weight
    ``F(wo.h) G2 / G1(wo)``.
    """
    side = side_of(wo)
    wo_ = flip_to_upper(wo, side)
    co = wo_[:, 2]
    wm = mf.sample_ggx_visible(wo_, ax, u, alpha_y=ay)
    wi_ = reflect(wo_, wm)
    ci = wi_[:, 2]
    ok = (co > 0.0) & (ci > 0.0)
    a_o, a_i = ggx_a_aniso(wo_, ax, ay), ggx_a_aniso(wi_, ax, ay)
    den = a_o * np.abs(ci) + a_i * co
    g2_g1 = np.where(den > 0.0, (a_o + co) * np.abs(ci) / np.where(den > 0.0, den, 1.0), 0.0)
    weight = fresnel_schlick(f0, dot(wo_, wm)) * g2_g1[:, None]
    if multiscatter:
        weight = weight * conductor.multiscatter_factor(f0, np.sqrt(ax * ay), wo_, wi_, mode)
    pdf = ggx_d_aniso(wm, ax, ay) / (4.0 * projected_area(wo_, ax, ay))
    wi = flip_to_upper(wi_, side)

    delta = _smooth(ax, ay)
    wi_d, weight_d, pdf_d, _ = sample_mirror(f0, wo)
    wi = np.where(delta[:, None], wi_d, np.where(ok[:, None], wi, 0.0))
    weight = np.where(delta[:, None], weight_d, np.where(ok[:, None], weight, 0.0))
    pdf = np.where(delta, pdf_d, np.where(ok, pdf, 0.0))
    return wi, weight, pdf, delta


def rotate(w, angle):
    """``w (k, 3)`` in the frame turned by ``angle (k,)`` about +Z (``-angle``: back)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * w[:, 0] + s * w[:, 1], -s * w[:, 0] + c * w[:, 1], w[:, 2]], axis=-1)


def anisotropic_part(p):
    """``(rows, q, ax, ay, angle)``: the anisotropic rows of ``p`` (:func:`aniso_rows`), their
    parameters, alphas and rotation; all but ``rows`` None when there are none."""
    rows = aniso_rows(p)
    if not rows.size:
        return rows, None, None, None, None
    q = p.take(rows)
    ax, ay = alphas(q.alpha, q.aniso_scale)
    return rows, q, ax, ay, q.aniso_rotation


def mean_alpha(p):
    """``(k,)`` the alpha of each row's albedo tables: ``sqrt(ax ay)`` on anisotropic rows."""
    rows, q, ax, ay, _ = anisotropic_part(p)
    if q is None:
        return p.alpha
    out = p.alpha.copy()
    out[rows] = np.sqrt(ax * ay)
    return out
