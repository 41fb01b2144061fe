"""Density-estimation kernels of photon mapping, normalised over the disk of radius one.

A photon estimate of reflected radiance is ``sum_p K(d_p / r) / r^2 * beta_p f(wo, wi_p) / N``
over the photons ``p`` at distance ``d_p < r`` (``N`` photons emitted): ``K(t) / r^2`` must
integrate to one over the disk of radius ``r``, i.e. ``int_0^1 K(t) 2 pi t dt = 1``. Each kernel
below is its shape divided by that integral:

- ``uniform``: ``1 / pi`` (Jensen's plain density estimate);
- ``cone``: ``3 (1 - t) / pi`` (Jensen's cone filter with ``k = 1``: nearer photons weigh more,
  sharper caustic edges, a little more noise);
- ``epanechnikov``: ``2 (1 - t^2) / pi`` (the kernel of least mean integrated squared error).
"""

from __future__ import annotations

import numpy as np

KERNELS = ("uniform", "cone", "epanechnikov")


def kernel_weight(kind, t):
    """Kernel value ``K(t)`` at normalised distances ``t (k,)`` (zero for ``t >= 1``).

    Parameters
    ----------
    kind : str
        One of :data:`KERNELS`.
    t : (k,) float
        Distance over radius, ``>= 0``.

    Returns
    -------
    (k,) float64
    """
    t = np.asarray(t, np.float64)
    inside = t < 1.0
    if kind == "uniform":
        w = np.full(t.shape, 1.0 / np.pi)
    elif kind == "cone":
        w = 3.0 * (1.0 - t) / np.pi
    elif kind == "epanechnikov":
        w = 2.0 * (1.0 - t * t) / np.pi
    else:
        raise ValueError(f"unknown kernel {kind!r}: choose from {', '.join(KERNELS)}")
    return np.where(inside, w, 0.0)
