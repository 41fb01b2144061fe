"""Halton sampler: radical inverses in prime bases, scrambled per pixel by nested random
affine digit permutations (an Owen-style scramble).

What it is
    Dimension d of sample i is the radical inverse of i in the d-th prime base b_d (2, 3, 5,
    7, 11, ...): the base-b digits of i mirrored about the radix point. The primes are generated
    in code (a sieve), as many as the path needs. Each (pixel, dimension, seed) gets its own
    nested scrambling in base b_d (:func:`..lowdiscrepancy.owen_scrambled_radical_inverse`:
    every digit permuted by a random *affine* permutation ``d -> (a d + c) mod b`` chosen by a
    hash of the digits below it; full Owen scrambling would draw uniformly random
    permutations, which agree with these on every pair of digits), which keeps the
    stratification, makes every value uniform (so the estimate is unbiased) and decorrelates
    pixels. A 2-D slot at dimension d is the pair (b_d, b_{d+1}) of the Halton sequence.
Pixels
    pbrt-v4 lays one Halton sequence over the whole image (the first two dimensions pick the
    pixel); that needs the image resolution and gives every pixel the same digit permutations.
    Here every pixel walks the sequence from index 0 with its own scramble: a stream needs only
    (pixel, sample index, dimension, seed), and neighbouring pixels' errors are independent.
Convergence
    Progressive: no sample count needed, and every prefix is good. The first b^k samples put one
    point in each interval [j / b^k, (j + 1) / b^k) of dimension d, and the first b1^k1 b2^k2
    samples one point in each box of the b1^k1 x b2^k2 grid of a 2-D slot. Deterministic QMC
    error is O((log N)^2 / N) per 2-D slot for integrands of bounded (Hardy-Krause) variation
    (Koksma-Hlawka), and scrambling keeps the variance below Monte Carlo's (o(1/N)) for every
    square-integrable integrand. Measured per 2-D slot: smooth integrands about N^-2 (up to
    N^-2.4 at counts that complete the strata, 6^k for bases 2 and 3), about 6x lower for bases
    2, 3 than for 13, 17; edges about N^-1.5. So it beats the jittered grid but not the base-2
    nets (Sobol, PMJ02: N^-3 on smooth integrands). Across slots: Monte Carlo's N^-1/2.
When it fails
    Unscrambled, dimensions of large neighbouring primes are strongly correlated at small N
    (points on a few lines: primes 29 and 31 for N < 29 * 31); scrambling removes the lines
    but large bases still stratify only at N ~ b^k, so deep bounces (dimension 40 is base 179)
    gain little over random numbers. It is slower than the base-2 samplers: one hash per base-b
    digit (16 digits in base 3, 4 in base 179, down to a resolution of 2^-24).
When to use it
    Progressive renders at counts that are not powers of two (its strata complete at 2^a 3^b
    for the pixel filter, with no power-of-two steps), and as the classic low-discrepancy
    reference of the lecture. Sobol or PMJ02 are faster and stratify deep bounces better.
Parameters
    ``seed``; ``spp`` is not needed.
"""

from __future__ import annotations

import numpy as np

from ..lowdiscrepancy import owen_scrambled_radical_inverse, primes, slot_keys
from .padded import PaddedStream


class HaltonStream(PaddedStream):
    salt = 0xA54FF53A
    _primes = primes(64)

    @classmethod
    def base(cls, dimension):
        """Prime base of ``dimension`` (the list grows as deeper dimensions are asked for)."""
        if dimension >= cls._primes.size:
            cls._primes = primes(2 * dimension + 2)
        return int(cls._primes[dimension])

    def _sample_1d(self, key, dimension):
        return owen_scrambled_radical_inverse(self.base(dimension), self.sample_index, key)

    def _sample_2d(self, key, dimension):
        # Each dimension keeps its own key: a 2-D slot at d is the same numbers as 1-D slots
        # at d and d + 1.
        out = np.empty((len(self), 2))
        out[:, 0] = self._sample_1d(key, dimension)
        out[:, 1] = self._sample_1d(slot_keys(self._key, dimension + 1), dimension + 1)
        return out


class HaltonSampler:
    """Makes :class:`HaltonStream` batches. ``spp`` is accepted and not needed."""

    name = "halton"
    label = "Halton"
    description = ("Halton low-discrepancy sequence: radical inverses in prime bases 2, 3, 5, "
                   "..., scrambled per pixel by nested random digit permutations (a random "
                   "affine permutation per digit, chosen by a hash of the digits below it: "
                   "Owen-style, not fully random permutations). Progressive; error near 1/N "
                   "on smooth integrands, less gain in deep bounces (large bases)")
    needs_spp = False
    # Samples depend on the pixel index alone, not on where the pixel is on the screen.
    screen_space = False

    def __init__(self, seed=0, spp=None):
        self.seed = int(seed)
        self.spp = spp

    def stream(self, pixel, sample_index):
        return HaltonStream(pixel, sample_index, self.seed)
