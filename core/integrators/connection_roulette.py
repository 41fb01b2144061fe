"""Russian roulette of BDPT's connections before their shadow rays (the Connection Roulette
option; off by default).

A connection with contribution ``c > 0`` (the largest channel of its unweighted, unoccluded
value) survives with probability ``q = min(1, c / (factor * mean c))``, the mean over the
connections that would trace a shadow ray in the same batch, and a survivor's value is divided
by ``q``: for any ``q > 0`` chosen independently of the decision's random number,
``E[value / q * [u < q]] = value``, so the estimator stays unbiased; it trades a little
variance for fewer shadow rays (appleseed's Low Light Threshold skips shadow rays of
insignificant contribution outright, a biased cut-off; this is an unbiased roulette).
``factor`` is the setting: 0 turns it off; 0.3 skips about a quarter of the connections'
shadow rays on the bench's Cornell box (``docs/BENCHMARKS.md``, eighth round, and
``tools/roulette_probe.py``).

The decision's random number of connection ``key`` (a strategy's ``(s, t)`` code) of camera
sample ``(pixel, sample_index)`` is a hash of those and the render's seed, so renders stay
reproducible whatever the threads and batch sizes, and independent of the sampler's numbers.
"""

from __future__ import annotations

import numpy as np

from ..rows import put_rows
from ..sampling.stream import hash_u32, u32_to_unit_float
from .common import max_component, take_rows

# Odd constants that spread the hash's inputs over the word before its one hash.
_PIXEL, _SAMPLE, _KEY = np.uint32(0x9E3779B9), np.uint32(0x85EBCA6B), np.uint32(0xC2B2AE35)


def survival(contribution, factor):
    """Survival probabilities ``(k,)`` of connections with contributions ``(k,) > 0``: one
    at or above ``factor`` times their mean, proportional to the contribution below."""
    threshold = factor * contribution.mean()
    return np.minimum(1.0, contribution / threshold)


def uniforms(seed, pixel, sample_index, key):
    """Numbers in [0, 1) ``(k,)``, one hash of ``(seed, pixel (k,), sample_index (k,),
    key (k,))`` mixed into one word: one per connection and camera sample, the same in every
    run. (Two inputs that mix to the same word share a number: their decisions are then
    correlated, which moves the variance a little but not the expected value.)"""
    x = np.asarray(pixel).astype(np.uint32) * _PIXEL
    x ^= np.asarray(sample_index).astype(np.uint32) * _SAMPLE
    x ^= np.asarray(key).astype(np.uint32) * _KEY
    x ^= np.uint32(seed & 0xFFFFFFFF)
    return u32_to_unit_float(hash_u32(x))


class ConnectionRoulette:
    """The roulette of one batch's connections.

    Parameters
    ----------
    factor : float > 0
        The Connection Roulette setting.
    seed : int
        The render's seed.
    pixel, sample_index : (n,) int64
        The batch's camera samples (the rows of its subpaths).
    """

    def __init__(self, factor, seed, pixel, sample_index):
        self.factor, self.seed = float(factor), int(seed)
        self.pixel, self.sample_index = pixel, sample_index

    def thin(self, value, cand, rows, keys):
        """The survivors among connections ``cand (k,)`` (indices of ``value``'s rows, each
        with a finite contribution > 0), in order; their rows of ``value (m, 3)`` are
        divided by their survival probability in place. ``rows (k,)``: their camera
        samples; ``keys (k,)``: their strategies' codes."""
        if cand.size == 0:
            return cand
        q = survival(max_component(take_rows(value, cand)), self.factor)
        u = uniforms(self.seed, self.pixel[rows], self.sample_index[rows], keys)
        live = np.nonzero(u < q)[0]
        kept = cand[live]
        put_rows(value, kept, take_rows(value, kept) / q[live][:, None])
        return kept


def for_batch(settings, stream):
    """The :class:`ConnectionRoulette` of a batch drawn from ``stream`` (a
    :class:`core.sampling.stream.SampleStream`), or None where the setting is off."""
    factor = settings.connection_roulette
    if not factor > 0:
        return None
    return ConnectionRoulette(factor, stream.seed, stream.pixel, stream.sample_index)
