"""Independent sampler: every dimension of every sample is a fresh uniform random number.

What it is
    Uniform random numbers from an integer hash of (pixel, sample index, dimension, seed); no
    correlation between samples, dimensions or pixels.
Convergence
    Monte Carlo's O(n^-1/2) error (variance ~ 1/n) on every integrand, smooth or not.
When to use it
    As the baseline that every other sampler is measured against, and for Metropolis and
    debugging, where independence is what you want.
When it fails
    It never fails outright, but clumps and gaps leave visible noise that stratified and
    low-discrepancy samplers remove at the same sample count.
Parameters
    ``seed`` only.
"""

from __future__ import annotations

import numpy as np

from ..stream import SampleStream, hash_u32, u32_to_unit_float


class IndependentStream(SampleStream):
    def __init__(self, pixel, sample_index, seed):
        super().__init__(pixel, sample_index, seed)
        self._key = self._path_key()

    def _path_key(self):
        seed_key = hash_u32(np.uint32(self.seed & 0xFFFFFFFF) ^ np.uint32(0x9E3779B9))
        k = hash_u32((self.sample_index & 0xFFFFFFFF).astype(np.uint32) ^ seed_key)
        hi = (self.pixel >> 32).astype(np.uint32)
        k = hash_u32(k ^ hi ^ np.uint32(0x85EBCA6B))
        return hash_u32(k ^ (self.pixel & 0xFFFFFFFF).astype(np.uint32))

    def _compact_state(self, keep):
        self._key = self._key[keep]

    def sample(self, dimension, count):
        out = np.empty((len(self), count))
        for j in range(count):
            dim_key = hash_u32(np.uint32((dimension + j) * 0x27D4EB2F & 0xFFFFFFFF))
            out[:, j] = u32_to_unit_float(hash_u32(self._key ^ dim_key))
        return out


class IndependentSampler:
    """Makes :class:`IndependentStream` batches. ``spp`` is accepted and unused."""

    name = "independent"
    label = "Independent"
    description = "Uniform random numbers, independent across samples, dimensions and pixels"
    needs_spp = False
    # Samples depend on the pixel index alone, not on where the pixel is on the screen.
    screen_space = False

    def __init__(self, seed=0, spp=None):
        self.seed = int(seed)

    def stream(self, pixel, sample_index):
        return IndependentStream(pixel, sample_index, self.seed)
