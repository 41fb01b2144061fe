"""Multiple importance sampling weights (Veach 1997, ch. 9).

``mis_weight(pdf_a, pdf_b)`` is the weight of a sample drawn by strategy A (density ``pdf_a``)
when strategy B could have drawn the same point with density ``pdf_b``, one sample each. For each
heuristic the weights of A and B at the same point sum to one, which keeps the combination
unbiased.

The path tracer combines two strategies for direct light: light sampling (next-event estimation,
NEE) and BSDF sampling (a scattered ray that hits an emitter). :func:`light_weight` and
:func:`bsdf_weight` give their weights for every setting of ``MIS_SETTINGS``:

- ``'balance'``, ``'power'`` (exponent ``beta``), ``'maximum'``, ``'cutoff'`` (``alpha``): Veach's
  heuristics;
- ``'none'``: both strategies, each with the constant weight 1/2 where both can make the sample:
  the unweighted average of two unbiased estimates; unbiased, but without the variance
  reduction of MIS (each strategy's bad cases are only halved);
- ``'bsdf'``: BSDF sampling only (no next-event estimation); an emitter found by a ray gets
  weight one. Delta lights (points, spots, suns of angle 0) cannot be hit by a ray, so they
  contribute nothing: the image misses their light, by definition of the strategy;
- ``'light'``: light sampling only: NEE with weight one; an emitter hit by a ray after a
  scattering vertex gets weight zero wherever NEE could have sampled it (one where it could
  not, so no light goes missing). Emitters seen directly by the camera still count.

For every setting ``light_weight(a, b) + bsdf_weight(b, a) == 1`` wherever both densities are
positive, and the weight of a strategy is one where the other cannot make the sample, so every
setting is unbiased (``'bsdf'`` apart from delta lights, which it cannot see).
"""

from __future__ import annotations

import numpy as np

HEURISTICS = ("balance", "power", "maximum", "cutoff", "none")
SINGLE_STRATEGIES = ("bsdf", "light")
MIS_SETTINGS = HEURISTICS + SINGLE_STRATEGIES


def mis_weight(pdf_a, pdf_b, heuristic="power", beta=2.0, alpha=0.1):
    """Weight ``(n,)`` of strategy A's samples.

    Parameters
    ----------
    pdf_a, pdf_b : (n,) float64
        Densities of the two strategies at the sampled point (same measure).
    heuristic : str
        ``'balance'``, ``'power'`` (exponent ``beta``), ``'maximum'``, ``'cutoff'``
        (strategies below ``alpha`` times the largest density get weight zero), or ``'none'``
        (1/2 each: the plain average of the two strategies).
    beta : float
        Exponent of the power heuristic (2 is Veach's recommendation; 1 is the balance
        heuristic).
    alpha : float
        Cutoff fraction in [0, 1].
    """
    a = np.asarray(pdf_a, np.float64)
    b = np.asarray(pdf_b, np.float64)
    # Work with ratios to the larger density, so that no sum or power can overflow.
    m = np.maximum(a, b)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        ra = np.where(np.isinf(m), np.where(np.isinf(a), 1.0, 0.0), a / m)
        rb = np.where(np.isinf(m), np.where(np.isinf(b), 1.0, 0.0), b / m)
        if heuristic == "balance":
            w = ra / (ra + rb)
        elif heuristic == "power":
            w = ra**beta / (ra**beta + rb**beta)
        elif heuristic == "maximum":
            w = np.where(ra > rb, 1.0, np.where(ra == rb, 0.5, 0.0))
        elif heuristic == "none":
            w = np.full(np.broadcast(ra, rb).shape, 0.5)
        elif heuristic == "cutoff":
            keep_a = ra >= alpha
            keep_b = rb >= alpha
            w = np.where(keep_a, ra / (ra + np.where(keep_b, rb, 0.0)), 0.0)
        else:
            raise ValueError(f"unknown MIS heuristic {heuristic!r}")
    # Where A cannot produce the sample at all, or B cannot, the answer is exact.
    w = np.where(a <= 0, 0.0, np.where(b <= 0, 1.0, w))
    return np.nan_to_num(w, nan=0.0)


def light_weight(pdf_light, pdf_bsdf, setting="power", beta=2.0, alpha=0.1):
    """MIS weight ``(n,)`` of next-event (light) samples.

    Parameters
    ----------
    pdf_light : (n,) float64
        Density of the light sample under light sampling (selection included).
    pdf_bsdf : (n,) float64
        Density of the same direction under BSDF sampling.
    setting : str
        One of ``MIS_SETTINGS``.
    beta, alpha : float
        As in :func:`mis_weight`.
    """
    if setting == "light":
        return np.where(np.asarray(pdf_light) > 0, 1.0, 0.0)
    if setting == "bsdf":
        return np.zeros(np.shape(pdf_light))
    return mis_weight(pdf_light, pdf_bsdf, setting, beta, alpha)


def bsdf_weight(pdf_bsdf, pdf_light, setting="power", beta=2.0, alpha=0.1):
    """MIS weight ``(n,)`` of emitters found by BSDF-sampled rays.

    Parameters
    ----------
    pdf_bsdf : (n,) float64
        Density of the ray's direction under BSDF sampling.
    pdf_light : (n,) float64
        Density with which next-event estimation picks the same point (zero where it cannot).
    setting, beta, alpha
        As in :func:`light_weight`.
    """
    if setting == "light":
        # Light sampling owns every emitter it can reach; rays keep the rest (none is lost).
        return np.where(np.asarray(pdf_light) > 0, 0.0, 1.0)
    if setting == "bsdf":
        return np.where(np.asarray(pdf_bsdf) > 0, 1.0, 0.0)
    return mis_weight(pdf_bsdf, pdf_light, setting, beta, alpha)
