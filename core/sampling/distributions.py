"""Discrete and piecewise-constant distributions over arrays.

Each has ``sample(u) -> (index, pmf, u_remapped)``: ``u`` is uniform in [0, 1), ``index`` the
chosen bin, ``pmf`` its probability (for a continuous distribution, the bin's probability; the
density is ``pmf * n`` on [0, 1)), and ``u_remapped`` the position of ``u`` inside the bin, again
uniform in [0, 1), so one random number can drive a choice and then a continuous sample.
"""

from __future__ import annotations

import numpy as np


class PiecewiseConstant1D:
    """Inverse-CDF sampling by binary search: O(n) build, O(log n) per sample.

    Parameters
    ----------
    func : (n,) float
        Non-negative weights. All zero gives the uniform distribution.
    """

    def __init__(self, func):
        func = np.abs(np.asarray(func, np.float64)).reshape(-1)
        if func.size == 0:
            raise ValueError("PiecewiseConstant1D needs at least one bin")
        running = np.cumsum(func)
        total = running[-1]
        if not np.isfinite(total) or total <= 0:
            func = np.ones_like(func)
            running = np.cumsum(func)
            total = running[-1]
        self.func = func
        self.integral = total / func.size
        self.pmf_table = func / total
        # Normalise the running sum itself rather than summing normalised pmfs: a cumulative sum
        # of non-negative terms is monotone, and total / total is exactly 1, so the CDF is
        # non-decreasing and every bin after the last non-zero one ends at exactly 1.0. (Forcing
        # cdf[-1] = 1 after summing pmfs could overshoot 1 mid-table, or leave a sliver below 1
        # that mapped u to a trailing zero-weight bin with pmf 0.)
        self.cdf = np.concatenate([[0.0], running / total])

    def __len__(self):
        return self.func.size

    def sample(self, u):
        """Choose bins. ``u : (k,)`` -> ``index (k,) int64, pmf (k,), u_remapped (k,)``."""
        u = np.asarray(u, np.float64)
        # side="right" puts a u equal to a run of equal CDF values (zero-mass bins) in the last
        # bin of the run, which is the next bin with mass: empty bins are never chosen.
        index = np.searchsorted(self.cdf, u, side="right") - 1
        index = np.clip(index, 0, self.func.size - 1)
        pmf = self.pmf_table[index]
        lo = self.cdf[index]
        # Remap by the bin's width in the CDF actually searched, so u_remapped spans [0, 1).
        width = self.cdf[index + 1] - lo
        with np.errstate(divide="ignore", invalid="ignore"):
            u_remapped = np.where(width > 0, (u - lo) / width, 0.0)
        return index, pmf, np.clip(u_remapped, 0.0, np.nextafter(1.0, 0.0))

    def pmf(self, index):
        """Probability of choosing ``index (k,)``."""
        return self.pmf_table[index]


class AliasTable:
    """Walker/Vose alias method: O(n) build, O(1) per sample.

    Parameters
    ----------
    func : (n,) float
        Non-negative weights. All zero gives the uniform distribution.
    """

    def __init__(self, func):
        func = np.abs(np.asarray(func, np.float64)).reshape(-1)
        n = func.size
        if n == 0:
            raise ValueError("AliasTable needs at least one bin")
        total = func.sum()
        if not np.isfinite(total) or total <= 0:
            func = np.ones_like(func)
            total = n
        self.pmf_table = func / total
        scaled = self.pmf_table * n
        prob = np.ones(n)
        alias = np.arange(n)
        small = [i for i in range(n) if scaled[i] < 1.0]
        large = [i for i in range(n) if scaled[i] >= 1.0]
        # Vose's pairing: each under-full bin is topped up by one over-full bin.
        while small and large:
            s = small.pop()
            g = large.pop()
            prob[s] = scaled[s]
            alias[s] = g
            scaled[g] = scaled[g] + scaled[s] - 1.0
            (small if scaled[g] < 1.0 else large).append(g)
        self.prob = prob
        self.alias = alias

    def __len__(self):
        return self.prob.size

    def sample(self, u):
        """Choose bins. ``u : (k,)`` -> ``index (k,) int64, pmf (k,), u_remapped (k,)``."""
        u = np.asarray(u, np.float64)
        n = self.prob.size
        x = u * n
        column = np.minimum(x.astype(np.int64), n - 1)
        up = x - column
        keep = up < self.prob[column]
        index = np.where(keep, column, self.alias[column])
        with np.errstate(divide="ignore", invalid="ignore"):
            u_remapped = np.where(
                keep, up / self.prob[column], (up - self.prob[column]) / (1.0 - self.prob[column])
            )
        u_remapped = np.clip(np.nan_to_num(u_remapped), 0.0, np.nextafter(1.0, 0.0))
        return index, self.pmf_table[index], u_remapped

    def pmf(self, index):
        """Probability of choosing ``index (k,)``."""
        return self.pmf_table[index]
