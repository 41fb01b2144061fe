"""Multiple importance sampling weights (Veach 1997, ch. 9).

``mis_weight(pdf_a, pdf_b)`` is the weight of a sample drawn by strategy A (density ``pdf_a``)
when strategy B could have drawn the same point with density ``pdf_b``, one sample each. For each
heuristic the weights of A and B at the same point sum to one, which keeps the combination
unbiased.
"""

from __future__ import annotations

import numpy as np

HEURISTICS = ("balance", "power", "maximum", "cutoff")


def mis_weight(pdf_a, pdf_b, heuristic="power", beta=2.0, alpha=0.1):
    """Weight ``(n,)`` of strategy A's samples.

    Parameters
    ----------
    pdf_a, pdf_b : (n,) float64
        Densities of the two strategies at the sampled point (same measure).
    heuristic : str
        ``'balance'``, ``'power'`` (exponent ``beta``), ``'maximum'``, or ``'cutoff'``
        (strategies below ``alpha`` times the largest density get weight zero).
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
        elif heuristic == "cutoff":
            keep_a = ra >= alpha
            keep_b = rb >= alpha
            w = np.where(keep_a, ra / (ra + np.where(keep_b, rb, 0.0)), 0.0)
        else:
            raise ValueError(f"unknown MIS heuristic {heuristic!r}")
    # Where A cannot produce the sample at all, or B cannot, the answer is exact.
    w = np.where(a <= 0, 0.0, np.where(b <= 0, 1.0, w))
    return np.nan_to_num(w, nan=0.0)
