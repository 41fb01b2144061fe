"""Sobol sampler: padded 2-D Sobol points (pbrt-v4's ``PaddedSobolSampler``) with a hash-based
approximation of Owen scrambling.

What it is
    Every 2-D slot (pixel filter, light sample, BSDF sample) takes Sobol dimensions 0 and 1: the
    van der Corput sequence and the dimension of the primitive polynomial x + 1. Their 32 x 32
    generator matrices (the identity and Pascal's triangle mod 2) are generated in code
    (:func:`..lowdiscrepancy.sobol_columns`; :func:`..lowdiscrepancy.sobol_reversed` evaluates
    them with word operations). The two dimensions form a (0, 2)-sequence in base 2: every
    aligned block of 2^m consecutive points is a (0, m, 2)-net, i.e. puts exactly one point in
    every elementary interval [a 2^-k, (a + 1) 2^-k) x [b 2^-(m-k), (b + 1) 2^-(m-k)). A 1-D
    slot takes the first coordinate of the same construction (van der Corput).
Randomisation (per pixel, slot and seed)
    A hash-based approximation of Owen scrambling (Laine-Karras / Burley 2020,
    :func:`..lowdiscrepancy.owen_scramble`: nested, exact in stratification, but the flips of
    a bit are a hash of the bits above it rather than independent random bits) of each
    coordinate, and Burley's nested shuffle of the sample index
    (:func:`..lowdiscrepancy.shuffle_index`), each seeded by a hash of (pixel, first dimension of
    the slot, seed). The shuffle maps the first 2^m sample indices onto an aligned block of 2^m
    Sobol indices, which is again a (0, m, 2)-net, and Owen scrambling maps elementary intervals
    onto elementary intervals, so every power-of-two prefix of a pixel's samples keeps the
    (0, m, 2) property in every slot while each value is uniform (unbiased).
Why padding, and what it loses
    Higher Sobol dimensions are worse in pairs (their 2-D projections are not (0, 2)-nets), so
    instead of using dimensions 2k, 2k + 1 for the k-th slot, every slot reuses the best pair
    and is decorrelated from the others by its own index shuffle and scramble. Within a slot the
    (0, 2) property holds exactly; across slots there is no joint stratification: the samples of
    two slots are matched by unrelated pseudo-random orders, like Latin hypercube sampling.
Convergence
    Progressive (no sample count needed). Per 2-D slot at N = 2^m: variance O(N^-3 log N) for
    smooth integrands (Owen 1997: RMS error about N^-1.5), O(N^-1.5) with edges such as a
    checkerboard (RMS N^-0.75); the deterministic bound is O((log N)^2 / N). Across slots
    (light against BSDF sample, bounce against bounce) Monte Carlo's N^-1/2.
When to use it
    The default low-discrepancy sampler: progressive (time-limited renders, cancel at any time),
    the cheapest of the stratified samplers per value, and exact (0, 2) stratification in every
    slot at 16, 32, 64, ... samples.
When it fails
    Counts that are not powers of two: a prefix of 2^m + r samples is a net plus r points of the
    next block, which stratifies less evenly (still unbiased and better than random, but the
    error curve has steps; use 16, 64, 256, ...). Indices beyond 2^32 wrap.
Parameters
    ``seed``; ``spp`` is not needed (a power of two is best).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np

from ..lowdiscrepancy import (
    laine_karras_permutation, reverse_bits, salt_word, slot_keys, slot_word, sobol_reversed,
    sub_keys, unit_from_u32, unit_from_u32_into,
)
from ..stream import hash_u32
from .padded import PaddedStream


def sobol_2d_u32(key, index, count, reversed_index=None):
    """Scrambled, shuffled Sobol coordinates as fixed point: ``(n, count)`` uint32, count 1 or 2.

    Coordinate c is ``owen_scramble(sobol_c(shuffle_index(index, k0)), k_c)`` with the keys
    k0, k1, k2 derived from ``key``; both scrambles work on bit-reversed values, which is the
    form :func:`..lowdiscrepancy.sobol_reversed` returns. ``reversed_index`` may give
    ``reverse_bits(index)`` (a stream keeps it, as it is the same in every slot).
    """
    if reversed_index is None:
        reversed_index = reverse_bits(np.asarray(index).astype(np.uint32))  # past 2^32 wraps
    return _scrambled_rows(key, reversed_index, count).T


def _scrambled_rows(key, reversed_index, count):
    """The coordinates of :func:`sobol_2d_u32` as rows: ``(count, n)`` uint32.

    Written for few NumPy calls per slot: the sub-keys in one hash, both coordinates'
    scrambles in one call on the ``(count, n)`` rows, both back from bit-reversed form in one
    pass.
    """
    keys = sub_keys(key, 1 + count)
    shuffled = reverse_bits(laine_karras_permutation(reversed_index, keys[0]))
    rows = np.empty((count, shuffled.shape[0]), np.uint32)
    rows[:] = shuffled  # dimension 0 in bit-reversed form is the index itself
    if count == 2:
        rows[1] = sobol_reversed(1, shuffled)
    return reverse_bits(laine_karras_permutation(rows, keys[1:]))


# Most paths for which SobolStream draws several slots in one go (measured crossover: one
# bounce's five slots took 61 against 106 ns per path at 4 k paths, 48 against 50 at 16 k,
# 50 against 44 at 32 k).
BATCH_PATHS = 16384


class _Layout(NamedTuple):
    """Row indices of :meth:`SobolStream._draw_slots` for one sequence of slot sizes."""

    row_slot: np.ndarray  # slot of each sub-key row (1 + size rows per slot)
    row_word: np.ndarray  # the salt word of each sub-key row (salt 0: the index shuffle)
    first: np.ndarray  # the sub-key row of each slot's shuffle
    coord_slot: np.ndarray  # slot of each coordinate row
    second: np.ndarray  # the coordinate rows of Sobol dimension 1
    coord_row: np.ndarray  # the sub-key row scrambling each coordinate row
    starts: tuple  # (first coordinate row, size) of each slot


@functools.lru_cache(maxsize=64)
def _slot_layout(sizes):
    per_slot = [1 + size for size in sizes]
    first = np.cumsum([0] + per_slot[:-1])
    coord_slot = np.repeat(np.arange(len(sizes)), sizes)
    coord = np.concatenate([np.arange(size) for size in sizes])
    row_salt = np.concatenate([np.arange(n) for n in per_slot])
    starts = np.cumsum([0] + list(sizes[:-1]))
    return _Layout(np.repeat(np.arange(len(sizes)), per_slot),
                   np.array([salt_word(s) for s in row_salt], np.uint32), first, coord_slot,
                   np.nonzero(coord == 1)[0], first[coord_slot] + 1 + coord,
                   tuple(zip(starts.tolist(), sizes)))


def _slot_coordinates(keys, reversed_index, layout):
    """The scrambled Sobol coordinates ``(rows, paths)`` uint32 of the slots whose keys are
    ``keys (slots, paths)`` (:func:`_slot_layout`'s ``layout``), every path from its
    bit-reversed sample index ``reversed_index (paths,)``: one hash for the sub-keys, one
    scramble for the index shuffles and one for the coordinates, one bit reversal each."""
    sub = hash_u32(keys[layout.row_slot] ^ layout.row_word[:, None])
    index = np.broadcast_to(reversed_index, keys.shape)
    shuffled = reverse_bits(laine_karras_permutation(index, sub[layout.first]))
    rows = shuffled[layout.coord_slot]
    rows[layout.second] = sobol_reversed(1, rows[layout.second])
    return reverse_bits(laine_karras_permutation(rows, sub[layout.coord_row]))


def _distinct(dimensions):
    """``np.unique(dimensions, return_inverse=True)`` of dimensions ``(m,)`` (small
    non-negative integers) by counting instead of sorting: the distinct ones ascending and
    each one's place among them ``(m,)``."""
    present = np.bincount(dimensions) > 0
    return np.flatnonzero(present), (np.cumsum(present) - 1).take(dimensions)


class SobolStream(PaddedStream):
    salt = 0x510E527F

    def __init__(self, pixel, sample_index, seed):
        super().__init__(pixel, sample_index, seed)
        # The bit-reversed sample index every slot starts from (indices past 2^32 wrap).
        self._reversed_index = reverse_bits(self.sample_index.astype(np.uint32))

    def _compact_state(self, keep):
        super()._compact_state(keep)
        self._reversed_index = self._reversed_index[keep]

    def sample(self, dimension, count):
        # The padded slots of PaddedStream.sample, each converted straight into ``out``.
        out = np.empty((len(self), count))
        for d in range(0, count, 2):
            c = min(2, count - d)
            rows = _scrambled_rows(slot_keys(self._key, dimension + d), self._reversed_index, c)
            unit_from_u32_into(rows, out[:, d:d + c].T)
        return out

    def _draw_slots(self, slots):
        # Every slot of the call at once, as rows of 2-D arrays: one hash for the slot keys,
        # one for their sub-keys, one scramble for the index shuffles and one for the
        # coordinates, one bit reversal each, one conversion (bit for bit the slots' values).
        # Fewer NumPy calls, but arrays of rows x paths: past BATCH_PATHS paths they leave
        # the core's cache and slot by slot is faster (tools/stream_cost.py).
        if not slots or len(self) > BATCH_PATHS:
            return super()._draw_slots(slots)
        layout = _slot_layout(tuple(size for _, size in slots))
        words = np.array([slot_word(d) for d, _ in slots], np.uint32)
        keys = hash_u32(self._key[None, :] ^ words[:, None])
        rows = _slot_coordinates(keys, self._reversed_index, layout)
        out = np.empty(rows.shape)
        unit_from_u32_into(rows, out)
        return [out[a] if size == 1 else out[a:a + 2].T for a, size in layout.starts]

    def slots_of_rows(self, rows, dimensions, sizes):
        # As _draw_slots, with each row's own slot keys: the word of each row's dimension
        # is hashed into its path key, the rest is row-wise (bit for bit the values of the
        # base class's copies per dimension), in batches of at most BATCH_PATHS rows.
        self.check_abort()
        layout = _slot_layout(tuple(sizes))
        starts = np.cumsum([0] + list(sizes[:-1]))
        uniq, which = _distinct(dimensions)
        table = np.array([[slot_word(d + a) for d in uniq.tolist()] for a in starts.tolist()],
                         np.uint32).reshape(len(sizes), uniq.size)
        out = np.empty((sum(sizes), rows.size))
        for lo in range(0, rows.size, BATCH_PATHS):
            part = slice(lo, min(lo + BATCH_PATHS, rows.size))
            r = rows[part]
            keys = hash_u32(self._key.take(r)[None, :] ^ table[:, which[part]])
            unit_from_u32_into(_slot_coordinates(keys, self._reversed_index.take(r), layout),
                               out[:, part])
        return [out[a] if size == 1 else out[a:a + 2].T for a, size in layout.starts]

    def _sample_1d(self, key, dimension):
        return unit_from_u32(sobol_2d_u32(key, None, 1, self._reversed_index)[:, 0])

    def _sample_2d(self, key, dimension):
        return unit_from_u32(sobol_2d_u32(key, None, 2, self._reversed_index))


class SobolSampler:
    """Makes :class:`SobolStream` batches. ``spp`` is accepted and not needed."""

    name = "sobol"
    label = "Sobol (hashed Owen)"
    description = ("Sobol (0,2)-sequence in every 2-D slot (padded, as pbrt-v4), scrambled per "
                   "pixel by a hash-based approximation of Owen scrambling (Laine-Karras "
                   "permutation with Vegdahl's hash: nested, stratification kept exactly). "
                   "Progressive; error near N^-1.5 on smooth integrands at powers of two: "
                   "use 16, 64, 256, ... samples")
    needs_spp = False
    # Samples depend on the pixel index alone, not on where the pixel is on the screen.
    screen_space = False

    def __init__(self, seed=0, spp=None):
        self.seed = int(seed)
        self.spp = spp

    def stream(self, pixel, sample_index):
        return SobolStream(pixel, sample_index, self.seed)
