"""A clear dielectric coat over any base BSDF: the Principled BSDF's *Coat* layer.

Model (Cycles' Principled v2 closure layering, learnt from its ``svm_closure.h`` and
``bsdf_microfacet.h``; radiance mode)::

    f(wo, wi) = w f_coat(wo, wi) + A(mu_o) f_base(wo, wi)
    A(mu)     = (1 - w E(max(mu, 0))) (1 - w + w tint^(1 / cos_t(mu))),
    cos_t(mu) = sqrt(1 - (1 - mu^2) / eta_c^2)

- ``w`` is the Coat Weight, ``f_coat`` single-scattering GGX reflection of alpha =
  Coat Roughness^2 with the exact dielectric Fresnel ``F(wo.h, eta_c)`` (Coat IOR) and no tint
  (Cycles' coat is plain GGX whatever the node's distribution).
- The base is attenuated by the coat's albedo *as Cycles estimates it*: ``E(mu_o)``, the
  directional albedo of the rough coat lobe with the exact dielectric Fresnel
  (:func:`.layered.coat_albedo_lookup`; ``F(mu_o, eta_c)`` for a smooth coat), read at the
  view's cosine with the coat's normal clamped to [0, 1] (Cycles 5.0's
  ``closure_layering_weight`` with ``bsdf_microfacet_estimate_albedo``, which reads its
  dielectric GGX albedo table ``ggx_gen_schlick_ior_s`` so; a view below the coat's normal
  reads the grazing row). The smooth Fresnel used before made rough coats near grazing up to
  40 % too opaque (``F = 0.75`` against ``E = 0.52`` at ``mu = 0.05``, roughness 0.2).
- Coat Tint is an absorption of the base's light along the refracted path through a coat of
  unit thickness (Beer's law, ``tint`` at normal incidence), faded in with the weight.
- The attenuation depends on ``wo`` only, so the BSDF is **not reciprocal**: importance mode
  (light paths) evaluates the adjoint, ``A(mu_i)``.
- Two-sided like the other reflection lobes: the coat reflects on ``wo``'s side; light the
  base transmits (glass under a coat) is attenuated by ``A`` but not reflected by the coat on
  the far side.

Sampling picks the coat with probability ``p = s / (s + d)``, ``s = w E_c(mu_o)`` (the rough
coat's directional albedo, :func:`.layered.coat_albedo_lookup`) and ``d = mean(A) a_base``
(``a_base`` the mean colour of diffuse and layered bases, 1 for others), then samples visible
normals (rough coat) or reflects perfectly (smooth coat: a delta sample of ``pdf = p``), or the
base with the remapped lobe number. Non-delta samples get the mixture pdf
``p pdf_coat + (1 - p) pdf_base``; a delta base sample has ``pdf = (1 - p) pdf_base``.

Only rows with ``w > 0`` pay for any of this (:func:`coat_rows`).

The coat's own normal: Cycles' coat closure has its own normal, the node's Coat Normal input
or, unlinked, the smooth interpolated normal, *not* the Normal input (``svm_closure.h``,
``node_principled_bsdf.osl``; behaviour matched). A row with a ``coat_normal`` (its unit
normal in the row's local frame, the ``"coatn"`` group of :class:`.bsdf.BSDFParams`; zero:
+Z) evaluates, samples and weighs the coat lobe, and the attenuation ``A`` of the layers
below, around that normal: every direction is first expressed in a frame around it
(:func:`coat_frame`). The row's side (``wo``'s side of the row's +Z) still decides which
side the coat is on; a view below the coat normal on that side gets no coat lobe and the
albedo of ``A`` at grazing, as Cycles clamps the cosine. Where :mod:`.lower_view` mirrored
the view (a view below the row's normal but above the coat's), ``coat_flip`` rows give the
coat the real view back.
"""

from __future__ import annotations

import numpy as np

from . import microfacet as mf
from ..sampling.warps import remap_after_choice
from .dielectric import RADIANCE
from .families import LOBE_GLOSSY, LOBE_REFLECT, LOBE_SINGULAR
from ..sampling.warps import frame_from_normal
from .frame import flip_to_upper, reflect, reflect_z, side_of, to_local, to_world
from .fresnel import fresnel_dielectric
from .layered import coat_albedo_lookup, coat_lobe_eval, coat_lobe_pdf

__all__ = ["coat_rows", "coat_frame", "in_layer_frame", "from_layer_frame", "layer_view",
           "coat_attenuation", "coat_probability", "eval_coated", "pdf_coated",
           "sample_coated", "DEFAULT_COAT_ROUGHNESS", "DEFAULT_COAT_IOR"]

# Blender's defaults for the Principled BSDF's coat inputs.
DEFAULT_COAT_ROUGHNESS = 0.03
DEFAULT_COAT_IOR = 1.5

_REFLECT, _GLOSSY, _SINGULAR = LOBE_REFLECT, LOBE_GLOSSY, LOBE_SINGULAR


def coat_rows(params):
    """Rows of ``params`` with a coat (``coat_weight > 0``): ``(j,)`` int64, often empty."""
    if params.coat_weight is None:
        return np.zeros(0, np.int64)
    return np.nonzero(params.coat_weight > 0.0)[0]


def coat_frame(p):
    """Frames ``(s, t, n)`` ``(k, 3)`` each around the rows' coat normals (+Z where ``p``
    has no ``coat_normal`` or its row is zero), in the row's local frame; None when ``p`` has
    no ``coat_normal`` column."""
    n = getattr(p, "coat_normal", None)
    if n is None:
        return None
    n = np.where(np.any(n != 0.0, axis=1)[:, None], n, np.array([0.0, 0.0, 1.0]))
    s, t = frame_from_normal(n)
    return s, t, n


def layer_view(p, wo):
    """The view ``(k, 3)`` the coat sees: ``wo`` mirrored back through the tangent plane on
    the rows whose view :mod:`.lower_view` mirrored (``coat_flip``), ``wo`` elsewhere."""
    flip = getattr(p, "coat_flip", None)
    if flip is None or not np.any(flip):
        return wo
    return np.where((flip != 0.0)[:, None], wo * np.array([1.0, 1.0, -1.0]), wo)


def in_layer_frame(frame, side, *ws):
    """``ws`` mirrored to the row's upper side (``side (k,)``) and expressed in the coat
    ``frame`` (unchanged frame when None)."""
    out = []
    for w in ws:
        w = flip_to_upper(w, side)
        out.append(w if frame is None else to_local(w, *frame))
    return out


def from_layer_frame(frame, side, w):
    """Inverse of :func:`in_layer_frame` for one ``w (k, 3)``."""
    return flip_to_upper(w if frame is None else to_world(w, *frame), side)


def _coat_mu(p, wo, wi, mode=RADIANCE):
    """Cosine ``(k,)`` the attenuation is judged at: ``wo``'s (``wi``'s in importance mode)
    with the coat normal, on the row's side of ``wo``; negative where that direction lies below
    a coat normal of its own (``|cos|`` on rows without one)."""
    w = layer_view(p, wo) if mode == RADIANCE else wi
    frame = coat_frame(p)
    if frame is None:
        return np.abs(w[:, 2])
    (w_,) = in_layer_frame(frame, side_of(wo), w)
    return np.clip(w_[:, 2], -1.0, 1.0)


def coat_attenuation(weight, eta, tint, mu, alpha):
    """``A(mu) (k, 3)``: what the coat leaves of the base's light seen at cosine ``mu``.

    ``A = (1 - w E(max(mu, 0))) (1 - w + w tint^(1 / cos_t(|mu|)))`` with ``E`` the rough
    coat's directional albedo (:func:`.layered.coat_albedo_lookup`; the exact Fresnel for a
    smooth coat): Cycles' ``closure_layering_weight`` of the coat's
    ``bsdf_microfacet_estimate_albedo``, which reads its dielectric-Fresnel GGX albedo table at
    the view's cosine clamped to [0, 1] (a view below the coat's normal reads the grazing row),
    and its tint's path length from ``cos^2``.

    Parameters
    ----------
    weight : (k,) float
        Coat Weight in [0, 1].
    eta : (k,) float
        Coat IOR (>= 1).
    tint : (k, 3) float
        Coat Tint (transmittance at normal incidence through the coat), >= 0.
    mu : (k,) float
        Cosine of the direction the layering is judged from (``wo``; ``wi`` for the adjoint)
        with the coat's normal; negative below it.
    alpha : (k,) float
        The coat's GGX alpha (Coat Roughness squared).
    """
    mu = np.clip(mu, -1.0, 1.0)
    albedo = coat_albedo_lookup(np.maximum(mu, 0.0), alpha, eta)
    reflected = np.clip(1.0 - weight * albedo, 0.0, 1.0)
    cos_t = np.sqrt(np.maximum(1.0 - (1.0 - mu * mu) / (eta * eta), 0.0))
    # tint^(1 / cos_t); a black tint stays black, cos_t = 0 only for an IOR of one at grazing.
    depth = 1.0 / np.maximum(cos_t, 1e-6)
    absorbed = np.power(np.maximum(tint, 0.0), depth[:, None])
    return reflected[:, None] * ((1.0 - weight)[:, None] + weight[:, None] * absorbed)


def _base_albedo_guess(p):
    """Mean colour of diffuse (0) and layered (3) bases, 1 for the others. ``(k,)``."""
    lambertian = (p.kind == 0) | (p.kind == 3)
    return np.where(lambertian, np.mean(p.color, axis=1), 1.0)


def coat_probability(p, wo):
    """Probability ``(k,)`` with which :func:`sample_coated` samples the coat at ``wo``."""
    mu = _coat_mu(p, wo, wo)
    s = p.coat_weight * coat_albedo_lookup(np.maximum(mu, 0.0), p.coat_alpha, p.coat_eta)
    a = coat_attenuation(p.coat_weight, p.coat_eta, p.coat_tint, mu, p.coat_alpha)
    d = np.mean(a, axis=1) * _base_albedo_guess(p)
    total = s + d
    return np.where(total > 0.0, s / np.where(total > 0.0, total, 1.0), 0.5)


def _coat_lobe(p, wo, wi):
    """``w f_coat cos_i`` and the coat lobe's own pdf, on ``wo``'s side. ``(k,)`` each."""
    wo_, wi_ = in_layer_frame(coat_frame(p), side_of(wo), layer_view(p, wo), wi)
    return (p.coat_weight * coat_lobe_eval(p.coat_eta, p.coat_alpha, wo_, wi_),
            coat_lobe_pdf(p.coat_alpha, wo_, wi_))


def eval_coated(p, wo, wi, base_f, mode=RADIANCE):
    """``f cos_i (k, 3)`` of coated rows, given the base's ``base_f (k, 3)`` (same mode)."""
    a = coat_attenuation(p.coat_weight, p.coat_eta, p.coat_tint, _coat_mu(p, wo, wi, mode),
                         p.coat_alpha)
    coat_f, _ = _coat_lobe(p, wo, wi)
    return a * base_f + coat_f[:, None]


def pdf_coated(p, wo, wi, base_pdf):
    """Mixture density ``(k,)`` of coated rows, given the base's ``base_pdf (k,)``."""
    prob = coat_probability(p, wo)
    _, coat_pdf = _coat_lobe(p, wo, wi)
    return prob * coat_pdf + (1.0 - prob) * base_pdf



def sample_coated(params, rows, wo, u_lobe, u, mode, sample_base, eval_fn, pdf_fn):
    """Sample every row of ``params``, those in ``rows`` (:func:`coat_rows`) with their coat.

    ``sample_base(params, wo, u_lobe, u, mode) -> BSDFSample`` samples the bases; ``eval_fn``
    and ``pdf_fn`` are the full (coated) :func:`.bsdf.eval_bsdf` and :func:`.bsdf.pdf_bsdf`.
    Returns the fields ``(wi, weight, pdf, delta, lobe)`` of a ``BSDFSample``.
    """
    p = params.take(rows)
    wo_c = wo[rows]
    prob = coat_probability(p, wo_c)
    chosen = u_lobe[rows] < prob
    u_base = u_lobe.copy()
    u_base[rows] = remap_after_choice(u_lobe[rows], prob, chosen)
    base = sample_base(params, wo, u_base, u, mode)
    wi, weight, pdf = base.wi.copy(), base.weight.copy(), base.pdf.copy()
    delta, lobe = base.delta.copy(), base.lobe.copy()

    side = side_of(wo_c)
    frame = coat_frame(p)
    (wo_,) = in_layer_frame(frame, side, layer_view(p, wo_c))
    smooth = mf.is_smooth(p.coat_alpha)
    wm = mf.sample_ggx_visible(np.where(wo_[:, 2:3] > 0.0, wo_, [0.0, 0.0, 1.0]), p.coat_alpha,
                               u[rows])
    wi_up = np.where(smooth[:, None], reflect_z(wo_), reflect(wo_, wm))
    wi_coat = from_layer_frame(frame, side, wi_up)
    coat_ok = chosen & (wo_[:, 2] > 0.0) & (wi_up[:, 2] > 0.0)
    wi_c = np.where(chosen[:, None], wi_coat, base.wi[rows])
    delta_coat = chosen & smooth
    delta_base = ~chosen & base.delta[rows]
    ok = np.where(chosen, coat_ok, base.pdf[rows] > 0.0)

    # Non-delta samples: the coated f cos over the mixture pdf, at the sampled direction.
    f = eval_fn(p, wo_c, wi_c, mode)
    pdf_c = pdf_fn(p, wo_c, wi_c)
    w_c = f / np.where(pdf_c > 0.0, pdf_c, 1.0)[:, None]
    good = ok & (pdf_c > 0.0)
    # Delta samples: the coat's mirror (weight F / p), or the base's delta lobe scaled by A.
    mu_c = np.maximum(_coat_mu(p, wo_c, wo_c), 0.0)
    f_mirror = p.coat_weight * fresnel_dielectric(mu_c, p.coat_eta)
    w_mirror = (f_mirror / np.where(prob > 0.0, prob, 1.0))[:, None] * np.ones((1, 3))
    a = coat_attenuation(p.coat_weight, p.coat_eta, p.coat_tint,
                         _coat_mu(p, wo_c, wi_c, mode), p.coat_alpha)
    rest = np.where(prob < 1.0, 1.0 - prob, 1.0)
    w_base = a * base.weight[rows] / rest[:, None]
    w_c = np.where(delta_coat[:, None], w_mirror, np.where(delta_base[:, None], w_base, w_c))
    pdf_c = np.where(delta_coat, prob, np.where(delta_base, (1.0 - prob) * base.pdf[rows],
                                                pdf_c))
    good = np.where(delta_coat | delta_base, ok & (pdf_c > 0.0), good)

    coat_label = np.where(smooth, _SINGULAR, _GLOSSY) | _REFLECT
    lobe_c = np.where(chosen, coat_label, base.lobe[rows])
    wi[rows] = np.where(good[:, None], wi_c, 0.0)
    weight[rows] = np.where(good[:, None], w_c, 0.0)
    pdf[rows] = np.where(good, pdf_c, 0.0)
    delta[rows] = (delta_coat | delta_base) & good
    lobe[rows] = np.where(good, lobe_c, 0)
    return wi, weight, pdf, delta, lobe
