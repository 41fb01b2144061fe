"""Stratified (jittered) sampler: one random point in each stratum of a grid.

What it is
    For a render of N samples per pixel, every 1-D slot (light selection, Russian roulette) is
    cut into N equal intervals and every 2-D slot (pixel filter, light sample, BSDF sample) into
    an nx x ny grid of cells; each sample of the pixel gets its own stratum and a uniformly
    random ("jittered") position inside it. Which sample gets which stratum is a hashed
    permutation (Kensler 2013) chosen per (pixel, dimension, seed), so slots and pixels are
    decorrelated (padding, see :mod:`.padded`) while a pixel's samples stay stratified.
Grid shape
    The grid is the most square nx x ny >= N with at most a 2:1 aspect ratio and the fewest empty
    cells: 16 -> 4 x 4, 12 -> 4 x 3, 8 -> 4 x 2, 7 -> 4 x 2 (one empty cell), 13 -> 5 x 3 (two
    empty cells). When nx * ny > N the N samples take a random subset of the cells. Cost of the
    padding: which cells stay empty is random, which adds a variance term
    sigma^2 (M - N) / (N (M - 1)) for M = nx ny cells (sigma^2 the variance of the cell means,
    about the integrand's variance); since M - N < ny <= sqrt(N), that term falls only as
    N^-1.5. Prefer sample counts with a near-square factorisation (squares, 2 k^2, k (k + 1)).
Convergence
    Unbiased for every N. Per 2-D slot, with f smooth: variance O(N^-2) (error N^-1); with
    discontinuities such as edges or a checkerboard: variance O(N^-1.5). Per 1-D slot: O(N^-3)
    smooth, O(N^-2) with a jump. Across slots (the parts of the integrand that couple the light
    sample with the BSDF sample, or one bounce with the next) the error stays Monte Carlo's
    O(N^-1/2): the gain is largest where one slot dominates (pixel antialiasing, direct light
    from an area light).
When to use it
    Renders of a known sample count where a simple, robust gain over independent sampling is
    wanted (antialiasing, soft shadows, glossy reflections at moderate counts), and as the
    lecture's baseline for stratification. Multi-jittered sampling is the same idea with better
    1-D projections; the low-discrepancy samplers do not need the count.
When it fails
    The lecture's regular grid without jitter puts every sample at a fixed place (cell centres):
    it aliases and is biased; this sampler always jitters. A full d-dimensional grid would need
    N = k^d samples (curse of dimensionality), which is why slots are stratified separately.
    Stopping before N samples leaves a random subset of strata: unbiased, but only partly
    stratified. The 1-D and 2-D versions of a dimension differ (a dimension drawn inside a 2-D
    slot is stratified into nx columns only).
Parameters
    ``seed``; ``spp``: the number N of strata. Without a sample count (time-limited renders) the
    sampler stratifies into sets of ``DEFAULT_COUNT`` = 64 samples (an 8 x 8 grid); sample
    indices past N (or past 64) start a new, independently permuted and jittered set of N.
"""

from __future__ import annotations

import numpy as np

from ..lowdiscrepancy import ONE_MINUS_EPSILON, hash_combine, jitter, permutation_element, sub_key
from .padded import PaddedStream, sample_set_size, split_epochs

DEFAULT_COUNT = 64


def grid_shape(n):
    """``(nx, ny)`` of the 2-D grid for ``n`` samples: the most square grid with nx * ny >= n,
    nx >= ny, nx <= 2 ny, and the fewest empty cells (ties: the squarer one)."""
    if n < 1:
        raise ValueError("the sample count must be at least 1")
    if n == 1:
        return 1, 1
    best = None
    for ny in range(1, int(np.sqrt(n)) + 2):
        nx = -(-n // ny)  # ceil
        if nx < ny or nx > 2 * ny:
            continue
        cand = (nx * ny - n, nx - ny, nx, ny)
        if best is None or cand < best:
            best = cand
    return best[2], best[3]


def jittered_strata_1d(key, j, n):
    """Sample ``j`` of a stratified 1-D set of ``n`` points chosen by ``key``: ``(n,)`` float64."""
    stratum = permutation_element(j, n, sub_key(key, 1))
    u = (stratum + jitter(sub_key(key, 2), j)) / n
    return np.minimum(u, ONE_MINUS_EPSILON)


class StratifiedStream(PaddedStream):
    salt = 0x5747A7F1

    def __init__(self, pixel, sample_index, seed, count, shape):
        super().__init__(pixel, sample_index, seed)
        self.count = int(count)
        self.nx, self.ny = shape

    def _set(self, key):
        epoch, j = split_epochs(self.sample_index, self.count)
        return hash_combine(key, epoch.astype(np.uint32)), j

    def _sample_1d(self, key, dimension):
        key, j = self._set(key)
        return jittered_strata_1d(key, j, self.count)

    def _sample_2d(self, key, dimension):
        key, j = self._set(key)
        # The first N entries of a permutation of all M cells: a random subset when M > N.
        cell = permutation_element(j, self.nx * self.ny, sub_key(key, 3))
        cx, cy = cell % self.nx, cell // self.nx
        out = np.empty((j.shape[0], 2))
        out[:, 0] = (cx + jitter(sub_key(key, 4), j)) / self.nx
        out[:, 1] = (cy + jitter(sub_key(key, 5), j)) / self.ny
        return np.minimum(out, ONE_MINUS_EPSILON)


class StratifiedSampler:
    """Makes :class:`StratifiedStream` batches for renders of ``spp`` samples per pixel."""

    name = "stratified"
    label = "Stratified"
    description = ("Jittered strata: each sample of a pixel in its own interval or grid cell, "
                   "randomly placed in it. Variance falls as N^-2 per 2-D slot on smooth "
                   "integrands; needs the sample count (otherwise sets of 64)")
    needs_spp = False
    # Samples depend on the pixel index alone, not on where the pixel is on the screen.
    screen_space = False

    def __init__(self, seed=0, spp=None):
        self.seed = int(seed)
        self.spp = None if spp is None else int(spp)
        self.count = sample_set_size(spp, DEFAULT_COUNT)
        self.shape = grid_shape(self.count)

    def stream(self, pixel, sample_index):
        return StratifiedStream(pixel, sample_index, self.seed, self.count, self.shape)
