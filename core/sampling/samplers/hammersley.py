"""Hammersley sampler: the 2-D Hammersley point set (i / N, radical inverse of i in base 2).

What it is
    For a render of N samples per pixel, sample i of a 2-D slot is the Hammersley point
    (i / N, phi_2(i)), phi_2 the base-2 radical inverse (van der Corput); a 1-D slot takes the
    first coordinate i / N. Each (pixel, slot, seed) gets a hashed permutation of the N indices
    (Kensler 2013) and an Owen scrambling of both coordinates in base 2, which keeps the counts
    of points in every dyadic interval, makes every value uniform (unbiased) and decorrelates
    slots and pixels (padding, see :mod:`.padded`; the multi-dimensional Hammersley set would
    continue with Halton's bases 3, 5, 7, ... instead).
Convergence
    For N = 2^m the set is a (0, m, 2)-net in base 2 (one point in every elementary interval of
    area 1/N), like the first N Sobol points: per 2-D slot, variance O(N^-3 log N) for smooth
    integrands after scrambling (RMS error about N^-1.5), O(N^-1.5) with edges; deterministic
    error O(log N / N), one log better than a sequence. For other N, i / N is still evenly spaced
    and every dyadic interval of x or y holds floor or ceil of its share of points, without the
    exact net property. Across slots Monte Carlo's N^-1/2.
When to use it
    Renders of a fixed power-of-two sample count when the best 2-D point set of exactly that size
    is wanted, and for comparing point sets with sequences (Hammersley against Sobol at the same
    N shows what being progressive costs).
When it fails
    It needs N before the render starts (the first coordinate is i / N): there is no
    Hammersley sampler for a time limit without a sample count, and the constructor refuses
    ``spp=None``. The set is not progressive: stopping early (cancel) keeps a random subset of
    the N points (the index permutation keeps it unbiased, but unstratified). Sample indices
    past N start a new, independently scrambled set of N points (so ``sample_index >= spp``
    never wraps onto the first set's points). Use a power of two.
Parameters
    ``seed``; ``spp``: N, required.
"""

from __future__ import annotations

import numpy as np

from ...errors import RenderRefused
from ..lowdiscrepancy import (
    hash_combine, owen_scramble, permutation_element, reverse_bits, sub_key, unit_from_u32,
)
from .padded import PaddedStream, split_epochs


def hammersley_u32(key, j, count, coords):
    """Scrambled Hammersley point ``j`` of ``count`` as fixed point: ``(k, coords)`` uint32."""
    i = permutation_element(j, count, sub_key(key, 0)).astype(np.uint64)
    out = np.empty((i.shape[0], coords), np.uint32)
    out[:, 0] = owen_scramble(((i << np.uint64(32)) // np.uint64(count)).astype(np.uint32),
                              sub_key(key, 1))
    if coords == 2:
        out[:, 1] = owen_scramble(reverse_bits(i.astype(np.uint32)), sub_key(key, 2))
    return out


class HammersleyStream(PaddedStream):
    salt = 0x9B05688C

    def __init__(self, pixel, sample_index, seed, count):
        super().__init__(pixel, sample_index, seed)
        self.count = int(count)

    def _points(self, key, coords):
        epoch, j = split_epochs(self.sample_index, self.count)
        return unit_from_u32(hammersley_u32(hash_combine(key, epoch.astype(np.uint32)), j,
                                            self.count, coords))

    def _sample_1d(self, key, dimension):
        return self._points(key, 1)[:, 0]

    def _sample_2d(self, key, dimension):
        return self._points(key, 2)


class HammersleySampler:
    """Makes :class:`HammersleyStream` batches for renders of exactly ``spp`` samples per pixel."""

    name = "hammersley"
    label = "Hammersley"
    description = ("Hammersley point set (i/N, radical inverse of i), scrambled per pixel by a "
                   "hash-based approximation of Owen scrambling (Laine-Karras permutation): "
                   "a (0,2)-net for N a power of two. Needs the sample count; not for "
                   "time-limited renders")
    needs_spp = True
    # Samples depend on the pixel index alone, not on where the pixel is on the screen.
    screen_space = False

    def __init__(self, seed=0, spp=None):
        if spp is None or int(spp) < 1:
            raise RenderRefused(
                "Hammersley points are defined for a known sample count N (the first coordinate "
                "is i/N), so the sampler cannot be used without one (a render that only stops at "
                "a time limit): set a sample count or choose Halton/Sobol")
        self.seed = int(seed)
        self.spp = int(spp)

    def stream(self, pixel, sample_index):
        return HammersleyStream(pixel, sample_index, self.seed, self.spp)
