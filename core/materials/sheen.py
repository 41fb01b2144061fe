"""Microfiber sheen over any BSDF: the Principled BSDF's *Sheen* layer and the Sheen BSDF node.

Model (Zeltner, Burley and Chiang 2022, "Practical Multiple-Scattering Sheen Using Linearly
Transformed Cosines", the sheen Cycles 4.x/5.x renders; its layering learnt from Cycles'
``bsdf_sheen.h`` and the Principled BSDF in ``svm_closure.h``; radiance mode)::

    f(wo, wi) cos_i = S(mu_o) D_o(wi) + (1 - max_c S_c(mu_o)) f_below(wo, wi) cos_i
    S(mu)           = color R(mu, r),    color = Sheen Weight x Sheen Tint

- ``D_o`` is a *linearly transformed cosine*: the clamped cosine distribution ``cos / pi``
  mapped by ``M`` whose inverse is ``M^-1 = [[A, 0, B], [0, A, 0], [0, 0, 1]]`` in the frame
  whose x axis is ``wo`` projected on the tangent plane. It is a normalised density of
  directions above the surface, so sampling it is exact and ``S`` is the layer's albedo.
  ``A``, ``B`` and the albedo ``R`` are the authors' fit to a volumetric layer of fibers
  (:mod:`.sheen_ltc_table`), read at ``(cos theta_o, roughness)`` with bilinear interpolation
  on the 32 x 32 nodes as Cycles reads it; roughness is clamped to [1e-3, 1] as Cycles does.
- ``f_below`` is the rest of the material (coat over base, :mod:`.coat`); it is attenuated by
  the sheen's albedo in its brightest channel, Cycles' ``closure_layering_weight``. With a
  white base the directional albedo is ``S + (1 - S) = 1``: energy-conserving.
- ``S`` depends on ``wo`` only and the LTC is fitted per ``wo``: the BSDF is **not
  reciprocal**. Importance mode (light paths) evaluates the adjoint ``f*(wo, wi) = f(wi, wo)``.
- Two-sided like the other reflection lobes: the sheen reflects on ``wo``'s side only.
- Sampled lobes are labelled diffuse reflection, as Cycles labels them.

Sampling picks the sheen with probability ``p = s / (s + d)``, ``s = mean_c S(mu_o)``,
``d = (1 - max_c S) a_below`` (``a_below`` the mean colour of diffuse and layered bases, 1 for
others), then samples the LTC exactly, or the layers below with the remapped lobe number.
Non-delta samples get the mixture pdf ``p D_o + (1 - p) pdf_below``; a delta sample from below
has ``pdf = (1 - p) pdf_below`` and weight ``(1 - max_c S) weight_below / (1 - p)``.

Only rows with a sheen (``sheen_color > 0``) pay for any of this (:func:`sheen_rows`).

The sheen's normal: Cycles turns the sheen to ``normalize(mix(N, coat normal, Coat Weight))``
(``svm_closure.h``; behaviour matched). Rows with a ``coat_normal`` (:mod:`.coat`) evaluate,
sample and weigh the sheen in a frame around that mix (:func:`sheen_frame`), with the real view
where :mod:`.lower_view` mirrored it (``coat_flip``).
"""

from __future__ import annotations

import base64

import numpy as np

from ..sampling import warps
from ..sampling.warps import remap_after_choice
from .dielectric import RADIANCE
from .families import LOBE_DIFFUSE, LOBE_REFLECT
from ..sampling.warps import frame_from_normal
from .coat import from_layer_frame, in_layer_frame, layer_view
from .frame import flip_to_upper, normalize, side_of

__all__ = ["sheen_rows", "sheen_ltc", "sample_sheen_lobe", "sheen_lobe_pdf",
           "invert_sheen_lobe_sample", "sheen_albedo", "sheen_attenuation", "sheen_probability",
           "eval_sheened", "pdf_sheened", "sample_sheened", "ROUGHNESS_RANGE",
           "DEFAULT_SHEEN_ROUGHNESS"]

# Cycles clamps the sheen roughness to this range; Blender's default Sheen Roughness.
ROUGHNESS_RANGE = (1e-3, 1.0)
DEFAULT_SHEEN_ROUGHNESS = 0.5

_TABLE = None


def ltc_table():
    """The fitted ``(A, B, R)`` per node, ``(32, 32, 3)`` float64 indexed [roughness, mu]."""
    global _TABLE
    if _TABLE is None:
        from . import sheen_ltc_table as t
        raw = np.frombuffer(base64.b64decode("".join(t.DATA)), "<f4")
        _TABLE = raw.astype(np.float64).reshape(t.N_ROUGHNESS, t.N_MU, 3)
    return _TABLE


def _lerp_index(x, n):
    """Lower node, upper node and weight of ``x`` in [0, 1] on ``n`` uniform nodes."""
    x = np.clip(x, 0.0, 1.0) * (n - 1)
    i = np.minimum(x.astype(np.int64), n - 1)
    return i, np.minimum(i + 1, n - 1), x - i


def sheen_ltc(mu, roughness):
    """``A, B, R`` ``(k,)`` each at ``cos theta_o = mu (k,)`` and ``roughness (k,)``.

    Bilinear on the table's nodes (as Cycles' ``lookup_table_read_2D``); roughness clamped to
    :data:`ROUGHNESS_RANGE`, ``mu`` to [0, 1].
    """
    table = ltc_table()
    r = np.clip(np.nan_to_num(roughness, nan=DEFAULT_SHEEN_ROUGHNESS), *ROUGHNESS_RANGE)
    i0, i1, ti = _lerp_index(r, table.shape[0])
    j0, j1, tj = _lerp_index(np.abs(mu), table.shape[1])
    ti, tj = ti[:, None], tj[:, None]
    v = ((table[i0, j0] * (1.0 - tj) + table[i0, j1] * tj) * (1.0 - ti)
         + (table[i1, j0] * (1.0 - tj) + table[i1, j1] * tj) * ti)
    return v[:, 0], v[:, 1], np.maximum(v[:, 2], 0.0)


def _tangent(wo):
    """Unit x axis ``(k, 2)`` of the LTC frame: ``wo`` projected on the tangent plane."""
    xy = wo[:, :2]
    length = np.sqrt(np.einsum("ij,ij->i", xy, xy))
    ok = length > 1e-12
    t = xy / np.where(ok, length, 1.0)[:, None]
    return np.where(ok[:, None], t, np.array([1.0, 0.0]))


def _to_ltc_frame(t, w):
    """``w (k, 3)`` in the frame (t, n x t, n) of :func:`_tangent` ``t (k, 2)``."""
    x = t[:, 0] * w[:, 0] + t[:, 1] * w[:, 1]
    y = -t[:, 1] * w[:, 0] + t[:, 0] * w[:, 1]
    return np.stack([x, y, w[:, 2]], axis=-1)


def _from_ltc_frame(t, w):
    """Inverse of :func:`_to_ltc_frame`."""
    x = t[:, 0] * w[:, 0] - t[:, 1] * w[:, 1]
    y = t[:, 1] * w[:, 0] + t[:, 0] * w[:, 1]
    return np.stack([x, y, w[:, 2]], axis=-1)


def _ltc_over_cos(a, b, w):
    """``D(w) / w.z = A^2 / (pi |M^-1 w|^4)`` in the LTC frame (zero below). ``(k,)``."""
    len2 = (a * w[:, 0] + b * w[:, 2]) ** 2 + (a * w[:, 1]) ** 2 + w[:, 2] ** 2
    good = (w[:, 2] > 0.0) & (len2 > 0.0)
    val = (a / np.where(good, len2, 1.0)) ** 2 * warps.INV_PI
    return np.where(good, val, 0.0)


def sheen_lobe_pdf(a, b, wo, wi):
    """Density ``D_o(wi)`` ``(k,)`` of the LTC lobe of ``wo`` (upper side; zero below)."""
    local = _to_ltc_frame(_tangent(wo), wi)
    return np.maximum(local[:, 2], 0.0) * _ltc_over_cos(a, b, local)


def sample_sheen_lobe(a, b, wo, u):
    """Directions ``(k, 3)`` of density :func:`sheen_lobe_pdf`: a cosine sample mapped by ``M``.

    Parameters
    ----------
    a, b : (k,) float
        ``A > 0`` and ``B`` of :func:`sheen_ltc`.
    wo : (k, 3) float
        Unit directions, ``wo.z >= 0``.
    u : (k, 2) float in [0, 1)^2
    """
    c = warps.sample_cosine_hemisphere(u)
    a_ = np.maximum(a, 1e-12)
    local = np.stack([(c[:, 0] - c[:, 2] * b) / a_, c[:, 1] / a_, c[:, 2]], axis=-1)
    local /= np.linalg.norm(local, axis=1, keepdims=True)
    return _from_ltc_frame(_tangent(wo), local)


def invert_sheen_lobe_sample(a, b, wo, wi):
    """``u (k, 2)`` that :func:`sample_sheen_lobe` maps to ``wi`` (upper side)."""
    local = _to_ltc_frame(_tangent(wo), wi)
    c = np.stack([a * local[:, 0] + b * local[:, 2], a * local[:, 1], local[:, 2]], axis=-1)
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    return warps.invert_cosine_hemisphere_sample(c)


def sheen_rows(params):
    """Rows of ``params`` with a sheen (any ``sheen_color > 0``): ``(j,)`` int64, often empty."""
    if params.sheen_color is None:
        return np.zeros(0, np.int64)
    return np.nonzero(np.any(params.sheen_color > 0.0, axis=1))[0]


def sheen_albedo(color, roughness, mu):
    """``S(mu) = color R(mu) (k, 3)``, the sheen layer's directional albedo."""
    return color * sheen_ltc(mu, roughness)[2][:, None]


def sheen_attenuation(color, roughness, mu):
    """``1 - max_c S_c(mu)`` clamped to [0, 1] ``(k,)``: what the layers below keep."""
    return np.clip(1.0 - np.max(sheen_albedo(color, roughness, mu), axis=1), 0.0, 1.0)


def sheen_frame(p):
    """Frames ``(s, t, n)`` ``(k, 3)`` each around ``normalize(mix(+Z, coat_normal, coat
    weight))`` in the row's local frame (+Z where a row has no coat normal); None when ``p``
    has no ``coat_normal`` column."""
    n = getattr(p, "coat_normal", None)
    if n is None or p.coat_weight is None:
        return None
    up = np.array([0.0, 0.0, 1.0])
    own = np.any(n != 0.0, axis=1)
    w = np.clip(p.coat_weight, 0.0, 1.0)[:, None]
    m, ok = normalize(np.where(own[:, None], (1.0 - w) * up + w * n, up))
    m = np.where(ok[:, None], m, up)
    s, t = frame_from_normal(m)
    return s, t, m


def _in_sheen_frame(p, wo, *ws):
    """The view (the real one, :func:`.coat.layer_view`) and ``ws``, on ``wo``'s side, in
    :func:`sheen_frame` (unchanged when there is none)."""
    return in_layer_frame(sheen_frame(p), side_of(wo), layer_view(p, wo), *ws)


def _below_albedo_guess(p):
    """Mean colour of diffuse (0) and layered (3) bases, 1 for the others. ``(k,)``."""
    lambertian = (p.kind == 0) | (p.kind == 3)
    return np.where(lambertian, np.mean(p.color, axis=1), 1.0)


def sheen_probability(p, wo):
    """Probability ``(k,)`` with which :func:`sample_sheened` samples the sheen at ``wo``."""
    (wo_,) = _in_sheen_frame(p, wo)
    mu = np.clip(wo_[:, 2], 0.0, 1.0)
    albedo = sheen_albedo(p.sheen_color, p.sheen_roughness, mu)
    s = np.mean(albedo, axis=1)
    d = np.clip(1.0 - np.max(albedo, axis=1), 0.0, 1.0) * _below_albedo_guess(p)
    total = s + d
    return np.where(total > 0.0, s / np.where(total > 0.0, total, 1.0), 0.5)


def _sheen_lobe(p, wo, wi, mode):
    """``S D cos``-part of the sheen ``(k, 3)`` and the lobe's own pdf ``(k,)``, on ``wo``'s
    side; importance mode gives the adjoint ``S(mu_i) D_i(wo) cos_i / cos_o``."""
    wo_, wi_ = _in_sheen_frame(p, wo, wi)
    ok = (wo_[:, 2] > 0.0) & (wi_[:, 2] > 0.0)
    a, b, r = sheen_ltc(np.clip(wo_[:, 2], 0.0, 1.0), p.sheen_roughness)
    pdf = np.where(ok, sheen_lobe_pdf(a, b, wo_, wi_), 0.0)
    if mode == RADIANCE:
        f = p.sheen_color * (r * pdf)[:, None]
    else:
        a_i, b_i, r_i = sheen_ltc(wi_[:, 2], p.sheen_roughness)
        local = _to_ltc_frame(_tangent(wi_), wo_)
        f = p.sheen_color * (r_i * wi_[:, 2] * _ltc_over_cos(a_i, b_i, local))[:, None]
    return np.where(ok[:, None], f, 0.0), pdf


def eval_sheened(p, wo, wi, below_f, mode=RADIANCE):
    """``f cos_i (k, 3)`` of rows with a sheen, given the layers below ``below_f (k, 3)``."""
    keep = sheen_attenuation(p.sheen_color, p.sheen_roughness, _sheen_mu(p, wo, wi, mode))
    return keep[:, None] * below_f + _sheen_lobe(p, wo, wi, mode)[0]


def _sheen_mu(p, wo, wi, mode):
    """``|cos| (k,)`` of the view (radiance) or ``wi`` (importance) with the sheen's normal."""
    if sheen_frame(p) is None:
        return np.abs((wo if mode == RADIANCE else wi)[:, 2])
    wo_, wi_ = _in_sheen_frame(p, wo, wi)
    return np.clip((wo_ if mode == RADIANCE else wi_)[:, 2], 0.0, 1.0)


def pdf_sheened(p, wo, wi, below_pdf):
    """Mixture density ``(k,)`` of rows with a sheen, given the layers below' ``below_pdf``."""
    prob = sheen_probability(p, wo)
    return prob * _sheen_lobe(p, wo, wi, RADIANCE)[1] + (1.0 - prob) * below_pdf



def sample_sheened(params, rows, wo, u_lobe, u, mode, sample_below, eval_fn, pdf_fn):
    """Sample every row of ``params``, those in ``rows`` (:func:`sheen_rows`) with their sheen.

    ``sample_below(params, wo, u_lobe, u, mode) -> BSDFSample`` samples the layers below the
    sheen; ``eval_fn`` and ``pdf_fn`` are the full :func:`.bsdf.eval_bsdf` and
    :func:`.bsdf.pdf_bsdf`. Returns the fields ``(wi, weight, pdf, delta, lobe)``.
    """
    p = params.take(rows)
    wo_s = wo[rows]
    prob = sheen_probability(p, wo_s)
    chosen = u_lobe[rows] < prob
    u_below = u_lobe.copy()
    u_below[rows] = remap_after_choice(u_lobe[rows], prob, chosen)
    below = sample_below(params, wo, u_below, u, mode)
    wi, weight, pdf = below.wi.copy(), below.weight.copy(), below.pdf.copy()
    delta, lobe = below.delta.copy(), below.lobe.copy()

    frame = sheen_frame(p)
    (wo_,) = _in_sheen_frame(p, wo_s)
    up = np.where(wo_[:, 2:3] > 0.0, wo_, [0.0, 0.0, 1.0])
    a, b, _ = sheen_ltc(up[:, 2], p.sheen_roughness)
    wi_sheen = from_layer_frame(frame, side_of(wo_s), sample_sheen_lobe(a, b, up, u[rows]))
    wi_c = np.where(chosen[:, None], wi_sheen, below.wi[rows])
    delta_below = ~chosen & below.delta[rows]
    ok = np.where(chosen, (wo_[:, 2] > 0.0) & (a > 0.0), below.pdf[rows] > 0.0)

    # Non-delta samples: the full f cos over the full mixture pdf at the sampled direction.
    f = eval_fn(p, wo_s, wi_c, mode)
    pdf_c = pdf_fn(p, wo_s, wi_c)
    w_c = f / np.where(pdf_c > 0.0, pdf_c, 1.0)[:, None]
    # Delta samples from below: their weight, attenuated by the sheen, over 1 - p.
    keep = sheen_attenuation(p.sheen_color, p.sheen_roughness, _sheen_mu(p, wo_s, wi_c, mode))
    rest = np.where(prob < 1.0, 1.0 - prob, 1.0)
    w_c = np.where(delta_below[:, None], keep[:, None] * below.weight[rows] / rest[:, None], w_c)
    pdf_c = np.where(delta_below, (1.0 - prob) * below.pdf[rows], pdf_c)
    good = ok & (pdf_c > 0.0)

    lobe_c = np.where(chosen, LOBE_DIFFUSE | LOBE_REFLECT, below.lobe[rows])
    wi[rows] = np.where(good[:, None], wi_c, 0.0)
    weight[rows] = np.where(good[:, None], w_c, 0.0)
    pdf[rows] = np.where(good, pdf_c, 0.0)
    delta[rows] = delta_below & good
    lobe[rows] = np.where(good, lobe_c, 0)
    return wi, weight, pdf, delta, lobe
