"""Multiple importance sampling weights (Veach 1997, ch. 9), as one value object.

A render builds one :class:`MIS` from its settings (:meth:`MIS.from_settings`) and hands it to
the integrator; every weight of the render comes from it. Its one weight computation,
:meth:`MIS.weight`, takes a stack of the densities with which ``k`` strategies make the same
samples and returns the weight of one of them. The path tracer is its two-strategy case
(:meth:`MIS.pair_weight`, and :meth:`MIS.light_weight` / :meth:`MIS.bsdf_weight` for next-event
estimation against BSDF sampling); bidirectional path tracing is its ``k``-strategy case (one
strategy per way of splitting a path into a light and a camera subpath, see
:mod:`core.integrators.mis_densities`).

Settings (``MIS_SETTINGS``):

- ``'balance'``, ``'power'`` (exponent ``beta``), ``'maximum'``, ``'cutoff'`` (``alpha``): Veach's
  heuristics;
- ``'none'``: every strategy that can make the sample gets the same weight: the unweighted
  average of unbiased estimates; unbiased, but without the variance reduction of MIS (each
  strategy's bad cases are only divided by the number of strategies);
- ``'bsdf'`` (path tracer only): BSDF sampling only (no next-event estimation); an emitter found
  by a ray gets weight one. Delta lights (points, spots, suns of angle 0) cannot be hit by a ray,
  so they contribute nothing: the image misses their light, by definition of the strategy;
- ``'light'`` (path tracer only): light sampling only: NEE with weight one; an emitter hit by a
  ray after a scattering vertex gets weight zero wherever NEE could have sampled it (one where it
  could not, so no light goes missing). Emitters seen directly by the camera still count.

For every heuristic the weights of all strategies that can make a sample sum to one, which keeps
the combination unbiased; for the single strategies ``light_weight(a, b) + bsdf_weight(b, a) ==
1`` wherever both densities are positive, and the weight of a strategy is one where the other
cannot make the sample (``'bsdf'`` apart from delta lights, which it cannot see).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..quiet import quiet

HEURISTICS = ("balance", "power", "maximum", "cutoff", "none")
SINGLE_STRATEGIES = ("bsdf", "light")
MIS_SETTINGS = HEURISTICS + SINGLE_STRATEGIES


@dataclass(frozen=True)
class MIS:
    """How a render combines its sampling strategies.

    Parameters
    ----------
    setting : str
        One of ``MIS_SETTINGS``.
    beta : float
        Exponent of the power heuristic (2 is Veach's recommendation; 1 is the balance
        heuristic).
    alpha : float
        Cutoff fraction in [0, 1]: strategies below ``alpha`` times the largest density get
        weight zero.
    """

    setting: str = "power"
    beta: float = 2.0
    alpha: float = 0.1

    def __post_init__(self):
        if self.setting not in MIS_SETTINGS:
            raise ValueError(f"unknown MIS heuristic {self.setting!r}; choose from "
                             f"{', '.join(MIS_SETTINGS)}")

    @classmethod
    def from_settings(cls, settings):
        """The MIS of a render: ``settings.mis_heuristic``, ``mis_beta``, ``mis_alpha``."""
        return cls(settings.mis_heuristic, settings.mis_beta, settings.mis_alpha)

    @property
    def samples_lights(self):
        """Whether next-event estimation runs (``'bsdf'`` never samples lights)."""
        return self.setting != "bsdf"

    def weight(self, densities, s, possible=None):
        """Weight ``(m,)`` of strategy ``s`` among the ``k`` strategies of ``densities``.

        Parameters
        ----------
        densities : sequence of k arrays (m,) float64
            Density with which each strategy makes each sample, in one common measure and any
            common scale (ratios to one of them are enough); zero for a strategy that cannot make
            the sample; finite or ``inf``, never NaN where a weight is wanted.
        s : int
            The strategy that made the samples.
        possible : sequence of k arrays (m,) bool, or None
            Which strategies can make each sample (counted by ``'none'`` and in the ties of
            ``'maximum'``); None: all of them.

        Notes
        -----
        Sums run over the strategies in order (``((r_0 + r_1) + r_2) + ...``), one vectorised
        operation per strategy: no stacked copies of the densities.
        """
        r = densities
        h = self.setting
        with quiet("invalid", "divide", "over"):
            if h == "balance":
                return r[s] / _total(r)
            if h == "power":
                rb = [x ** self.beta for x in r]
                return rb[s] / _total(rb)
            if h == "none":
                if possible is None:
                    return np.full(np.broadcast_shapes(*(np.shape(x) for x in r)), 1.0 / len(r))
                return possible[s] / _count(possible)
            top = functools.reduce(np.maximum, r)
            if h == "maximum":
                best = [x >= top for x in r]
                if possible is not None:
                    best = [p & b for p, b in zip(possible, best)]
                return np.where(r[s] >= top, 1.0 / np.maximum(_count(best), 1), 0.0)
            if h == "cutoff":
                floor = self.alpha * top
                keep = [x >= floor for x in r]
                if possible is not None:
                    keep = [p & k for p, k in zip(possible, keep)]
                kept = _total([np.where(k, x, 0.0) for k, x in zip(keep, r)])
                return np.where(r[s] >= floor, r[s] / kept, 0.0)
        raise ValueError(f"the MIS setting {h!r} is a single strategy, not a heuristic "
                         f"that weighs several: choose from {', '.join(HEURISTICS)}")

    def pair_weight(self, pdf_a, pdf_b):
        """Weight ``(n,)`` of strategy A's samples when strategy B could make the same point,
        one sample each: :meth:`weight` of a stack of two (a heuristic setting).

        Parameters
        ----------
        pdf_a, pdf_b : (n,) float64
            Densities of the two strategies at the sampled point (same measure).
        """
        a = np.asarray(pdf_a, np.float64)
        b = np.asarray(pdf_b, np.float64)
        # Work with ratios to the larger density, so that no sum or power can overflow.
        m = np.maximum(a, b)
        if np.isfinite(m).all() and (a > 0).all() and (b > 0).all():
            # The common case: both strategies can make every sample. The ratios are then in
            # (0, 1] and one of each pair is 1: what the general case below computes.
            with quiet("invalid", "divide", "over"):
                return self.weight((a / m, b / m), 0)
        with quiet("invalid", "divide", "over"):
            ra = np.where(np.isinf(m), np.where(np.isinf(a), 1.0, 0.0), a / m)
            rb = np.where(np.isinf(m), np.where(np.isinf(b), 1.0, 0.0), b / m)
        w = self.weight((ra, rb), 0)
        # Where A cannot produce the sample at all, or B cannot, the answer is exact.
        w = np.where(a <= 0, 0.0, np.where(b <= 0, 1.0, w))
        return np.nan_to_num(w, nan=0.0)

    def light_weight(self, pdf_light, pdf_bsdf):
        """Weight ``(n,)`` of next-event (light) samples.

        Parameters
        ----------
        pdf_light : (n,) float64
            Density of the light sample under light sampling (selection included).
        pdf_bsdf : (n,) float64
            Density of the same direction under BSDF sampling.
        """
        if self.setting == "light":
            return np.where(np.asarray(pdf_light) > 0, 1.0, 0.0)
        if self.setting == "bsdf":
            return np.zeros(np.shape(pdf_light))
        return self.pair_weight(pdf_light, pdf_bsdf)

    def bsdf_weight(self, pdf_bsdf, pdf_light):
        """Weight ``(n,)`` of emitters found by BSDF-sampled rays.

        Parameters
        ----------
        pdf_bsdf : (n,) float64
            Density of the ray's direction under BSDF sampling.
        pdf_light : (n,) float64
            Density with which next-event estimation picks the same point (zero where it
            cannot).
        """
        if self.setting == "light":
            # Light sampling owns every emitter it can reach; rays keep the rest (none is lost).
            return np.where(np.asarray(pdf_light) > 0, 0.0, 1.0)
        if self.setting == "bsdf":
            return np.where(np.asarray(pdf_bsdf) > 0, 1.0, 0.0)
        return self.pair_weight(pdf_bsdf, pdf_light)


def _total(arrays):
    """Sum of the ``arrays``, added in order."""
    return functools.reduce(np.add, arrays)


def _count(masks):
    """How many of the boolean ``masks`` are true, per element (int64)."""
    return functools.reduce(np.add, masks[1:], np.asarray(masks[0], np.int64))


def mis_weight(pdf_a, pdf_b, heuristic="power", beta=2.0, alpha=0.1):
    """``MIS(heuristic, beta, alpha).pair_weight(pdf_a, pdf_b)``, for one-off use (plots,
    tests); a render builds its :class:`MIS` once."""
    return MIS(heuristic, beta, alpha).pair_weight(pdf_a, pdf_b)


def light_weight(pdf_light, pdf_bsdf, setting="power", beta=2.0, alpha=0.1):
    """``MIS(setting, beta, alpha).light_weight(pdf_light, pdf_bsdf)``, for one-off use."""
    return MIS(setting, beta, alpha).light_weight(pdf_light, pdf_bsdf)


def bsdf_weight(pdf_bsdf, pdf_light, setting="power", beta=2.0, alpha=0.1):
    """``MIS(setting, beta, alpha).bsdf_weight(pdf_bsdf, pdf_light)``, for one-off use."""
    return MIS(setting, beta, alpha).bsdf_weight(pdf_bsdf, pdf_light)
