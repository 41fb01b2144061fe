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


def _dimension_key(dimension):
    """The hashed key of sample dimension ``dimension`` (an int), xored into the path keys."""
    return hash_u32(np.uint32(dimension * 0x27D4EB2F & 0xFFFFFFFF))


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
            out[:, j] = u32_to_unit_float(hash_u32(self._key ^ _dimension_key(dimension + j)))
        return out

    def slots_of_rows(self, rows, dimensions, sizes):
        # Each row's path key with its own dimension's key: one hash per slot column for all
        # rows (bit for bit the values of the base class's copies per dimension, whose
        # compare, gather and scatter per distinct dimension cost more than the hashes).
        self.check_abort()
        key = self._key.take(rows)
        uniq, which = np.unique(dimensions, return_inverse=True)
        out, offset = [], 0
        for size in sizes:
            cols = [u32_to_unit_float(hash_u32(key ^ np.array(
                        [_dimension_key(d + offset + j) for d in uniq.tolist()],
                        np.uint32).take(which)))
                    for j in range(size)]
            out.append(cols[0] if size == 1 else np.stack(cols, axis=1))
            offset += max(size, 1)
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
