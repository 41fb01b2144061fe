"""Padded sample streams: a sample vector as a run of separately stratified 1-D and 2-D slots.

A path consumes its dimensions as slots: ``next_2d`` takes a 2-D slot (the pixel filter, a
light sample, a BSDF sample), ``next_1d`` a 1-D slot (light selection, Russian roulette). The
stratified and low-discrepancy samplers stratify each slot on its own and *pad* the slots into
one vector by giving every slot its own pseudo-random order of the pixel's samples (pbrt's
padding, as in its ``StratifiedSampler`` and ``PaddedSobolSampler``). The order and every
scramble come from a key hashed from (pixel, first dimension of the slot, seed), never from the
sample index, so a pixel's samples are stratified against each other within each slot, and
different slots or pixels are decorrelated.

What padding gives: each 1-D or 2-D slot is as well stratified as the sampler can make it. What
it does not give: joint stratification of two slots (the light sample against the BSDF sample
is a random matching of two stratified sets, like Latin hypercube sampling across slots), so the
part of the integrand that couples slots converges at the Monte Carlo rate.

A slot is addressed by the dimension it starts at; ``sample(d, count)`` splits ``count`` into
2-D slots ``(d, d + 1), (d + 2, d + 3), ...`` and a final 1-D slot when ``count`` is odd.
"""

from __future__ import annotations

import numpy as np

from ..lowdiscrepancy import path_keys, slot_keys
from ..stream import SampleStream


class PaddedStream(SampleStream):
    """Base class: subclasses implement ``_sample_1d(key, dimension)`` and
    ``_sample_2d(key, dimension)`` for the current paths, where ``key`` is the ``(n,)``
    uint32 key of (pixel, dimension, seed) and ``self.sample_index`` the sample indices."""

    salt = 0  # separates the keys of different samplers

    def __init__(self, pixel, sample_index, seed):
        super().__init__(pixel, sample_index, seed)
        if self.sample_index.size and self.sample_index.min() < 0:
            raise ValueError("sample indices must be non-negative")
        self._key = path_keys(self.pixel, self.seed, self.salt)

    def _compact_state(self, keep):
        self._key = self._key[keep]

    def sample(self, dimension, count):
        out = np.empty((len(self), count))
        d = 0
        while d < count:
            key = slot_keys(self._key, dimension + d)
            if count - d >= 2:
                out[:, d:d + 2] = self._sample_2d(key, dimension + d)
                d += 2
            else:
                out[:, d] = self._sample_1d(key, dimension + d)
                d += 1
        return out

    def _sample_1d(self, key, dimension):
        raise NotImplementedError

    def _sample_2d(self, key, dimension):
        raise NotImplementedError


def sample_set_size(spp, default):
    """Samples per pixel a fixed-count pattern is built for: ``spp``, or ``default`` when the
    render has no sample count (time-limited), in which case the pattern repeats in sets."""
    if spp is None:
        return default
    if int(spp) < 1:
        raise ValueError("the sample count must be at least 1")
    return int(spp)


def split_epochs(sample_index, count):
    """Split sample indices into (epoch, index within a point set of ``count`` points).

    Samplers built on a finite point set of ``count`` points (stratified, multi-jittered,
    Hammersley, a finite table) continue past its end with a fresh, independently scrambled set
    for every further block of ``count`` samples: each block is stratified on its own.
    """
    sample_index = np.asarray(sample_index, np.int64)
    return sample_index // count, sample_index % count
