"""PMJ02 sampler: progressive multi-jittered (0, 2) sequences (Christensen et al. 2018).

What it is
    A pmj02 sequence is a sequence of 2-D points of which every prefix of 2^m points is a
    (0, m, 2)-net: one point in every elementary interval 2^-k x 2^-(m-k) (the 1 x N, N x 1
    strata of multi-jittering, the square grid for even m, and every shape between). It is
    built by progressive subdivision ("Progressive Multi-Jittered Sample Sequences", EGSR 2018,
    section 5): starting from one random point, with n = 4^k points one per cell of a
    2^k x 2^k grid, each cell is split into four sub-quadrants; the n new points first go to
    the sub-quadrants diagonally opposite the old ones (n -> 2n), then to one of the two still
    empty sub-quadrants of each cell, picked at random, and finally to the last one (2n -> 4n).
    Inside its sub-quadrant each new point takes a random x stratum and a random y stratum among
    those whose elementary intervals are still empty at the new count; Pharr's observation
    ("Efficient Generation of Points that Satisfy Two-Dimensional Elementary Intervals", JCGT
    2019) that the valid positions factor into valid x strata times valid y strata, found by
    descending the interval shapes from the cell, makes each step a short search
    (:func:`generate_pmj02`). We skip the paper's optional best-candidate and balancing steps.
Tables
    Generation is sequential (each point depends on the intervals the earlier ones occupy), so
    ``SETS`` = 4 sequences of ``POINTS`` = 4096 points are generated once, deterministically
    from fixed keys, and stored in the data module :mod:`.pmj02_tables` (16-bit fixed point,
    64 kB). Regenerate with ``python -m sampling_lab.core.sampling.samplers.pmj02``: about
    0.15 s per set of 4096 points in pure Python (0.5 s for 16384, 2.7 s for 65536); a test
    checks that the generator still reproduces the tables.
Randomisation (per pixel, slot and seed)
    A hash of (pixel, first dimension of the slot, seed) picks one of the sets, permutes the
    sample indices inside every octave [2^k, 2^(k+1)) (so the first 2^m samples are still the
    table's first 2^m points, a net, while different slots see them in unrelated orders), and
    Owen-scrambles both coordinates in base 2 (elementary intervals map onto elementary
    intervals, values become uniform: unbiased). A 1-D slot is the x coordinate of its 2-D point.
Convergence
    Progressive, like Owen-scrambled Sobol: per 2-D slot at N = 2^m, RMS error about N^-1.5
    for smooth integrands (the paper's Gaussian) and N^-0.75 with edges (the paper's disk).
    Between powers of two the points added so far are spread by construction: during a step
    each new point lands in a different cell of the current grid, in random cell order. Across
    slots Monte Carlo's N^-1/2.
When to use it
    Progressive renders up to a few thousand samples per pixel, as an alternative to Sobol
    with the same stratification and a different (table-driven, multi-jittered) construction;
    the family of sequences Pixar's RenderMan samples with.
When it fails
    Past ``POINTS`` = 4096 samples per pixel a new block starts with another set and scramble:
    blocks are independent nets, so the error falls only as Monte Carlo's beyond 4096. Only
    prefixes (and octaves) are guaranteed nets, not every aligned block, hence the octave-wise
    index permutation instead of Sobol's full shuffle. Four sets are few: two slots of a pixel
    share a set one time in four, and are then decorrelated only by the permutation and scramble.
Parameters
    ``seed``; ``spp`` is not needed (powers of two are best).
"""

from __future__ import annotations

import base64
import sys

import numpy as np

from ..lowdiscrepancy import (
    hash_combine, owen_scramble, permutation_element, sub_key, unit_from_u32,
)
from .padded import PaddedStream, split_epochs

SETS = 4
POINTS = 4096
GENERATOR_KEYS = (0x2545F491, 0x9E3779B9, 0x7F4A7C15, 0xD1B54A32)  # one per set


# --------------------------------------------------------------------------------------------
# Generation (offline: a Python loop over points, run once to write pmj02_tables.py)
# --------------------------------------------------------------------------------------------


def _hash32(x):
    """Scalar ``lowbias32`` (the same hash as :func:`core.sampling.stream.hash_u32`)."""
    x &= 0xFFFFFFFF
    x ^= x >> 16
    x = (x * 0x7FEB352D) & 0xFFFFFFFF
    x ^= x >> 15
    x = (x * 0x846CA68B) & 0xFFFFFFFF
    x ^= x >> 16
    return x


class _Rng:
    """Counter-based random numbers: reproducible on every platform and NumPy version."""

    def __init__(self, key):
        self.key = _hash32(key)
        self.counter = 0

    def u32(self):
        self.counter += 1
        return _hash32(_hash32(self.counter) ^ self.key)

    def below(self, n):
        return (self.u32() * n) >> 32


class _Strata:
    """Which elementary intervals of 2^level points are occupied.

    Shape s (0..level) has 2^(level - s) columns and 2^s rows; interval (xi, yi) of shape s is
    ``occ[s][yi << (level - s) | xi]``.
    """

    def __init__(self, level, xs, ys, count):
        self.level = level
        self.occ = [bytearray(1 << level) for _ in range(level + 1)]
        for p in range(count):
            self.mark(xs[p], ys[p])

    def mark(self, x, y):
        lv = self.level
        for s in range(lv + 1):
            self.occ[s][((y >> (32 - s)) << (lv - s)) | (x >> (32 - (lv - s)))] = 1

    def x_strata(self, s, xi, yi, out):
        """Free N x 1 strata below interval (xi, yi) of shape s, descending to finer x."""
        if self.occ[s][(yi << (self.level - s)) | xi]:
            return
        if s == 0:
            out.append(xi)
            return
        self.x_strata(s - 1, 2 * xi, yi >> 1, out)
        self.x_strata(s - 1, 2 * xi + 1, yi >> 1, out)

    def y_strata(self, s, xi, yi, out):
        """Free 1 x N strata below interval (xi, yi) of shape s, descending to finer y."""
        if self.occ[s][(yi << (self.level - s)) | xi]:
            return
        if s == self.level:
            out.append(yi)
            return
        self.y_strata(s + 1, xi >> 1, 2 * yi, out)
        self.y_strata(s + 1, xi >> 1, 2 * yi + 1, out)


def _place(strata, rng, cx, cy, cell_bits):
    """A new point in cell (cx, cy) of the 2^cell_bits grid, in free elementary intervals only."""
    lv = strata.level
    xs_free, ys_free = [], []
    if lv % 2 == 0:  # square cells are elementary intervals (shape lv / 2)
        strata.x_strata(lv // 2, cx, cy, xs_free)
        strata.y_strata(lv // 2, cx, cy, ys_free)
    else:  # cells are half an interval: start from the 2 : 1 and 1 : 2 shapes around them
        k = (lv - 1) // 2
        strata.x_strata(k, cx, cy >> 1, xs_free)
        strata.y_strata(k + 1, cx >> 1, cy, ys_free)
    if not xs_free or not ys_free:
        raise RuntimeError("pmj02: no free elementary interval in the chosen sub-quadrant")
    sx = xs_free[rng.below(len(xs_free))]
    sy = ys_free[rng.below(len(ys_free))]
    low = 32 - lv
    mask = (1 << low) - 1
    x = (sx << low) | (rng.u32() & mask)
    y = (sy << low) | (rng.u32() & mask)
    strata.mark(x, y)
    return x, y


def generate_pmj02(n_points, key):
    """A pmj02 sequence of ``n_points`` (a power of two) points in 32-bit fixed point.

    Parameters
    ----------
    n_points : int
    key : int
        Seed of the counter-based random numbers; a prefix of a longer sequence with the same
        key is the shorter sequence.

    Returns
    -------
    (n_points, 2) uint32
        ``x / 2^32, y / 2^32``: every prefix of 2^m points is a (0, m, 2)-net.
    """
    if n_points < 1 or n_points & (n_points - 1):
        raise ValueError("the number of points must be a power of two")
    rng = _Rng(key)
    xs = [0] * n_points
    ys = [0] * n_points
    xs[0], ys[0] = rng.u32(), rng.u32()
    n, k = 1, 0  # n = 4^k points, one per cell of the 2^k x 2^k grid
    while n < n_points:
        cell_bits = k + 1  # sub-quadrants: cells of the 2^(k+1) grid
        shift = 32 - cell_bits
        order = list(range(n))
        for i in range(n - 1, 0, -1):  # Fisher-Yates: visit the old points in random order
            j = rng.below(i + 1)
            order[i], order[j] = order[j], order[i]

        # Even step, n -> 2n: the sub-quadrant diagonally opposite each old point.
        strata = _Strata(2 * k + 1, xs, ys, n)
        for idx, p in enumerate(order):
            xs[n + idx], ys[n + idx] = _place(strata, rng, (xs[p] >> shift) ^ 1,
                                              (ys[p] >> shift) ^ 1, cell_bits)
        if 2 * n >= n_points:
            break

        # Odd step, 2n -> 4n: one of the two empty sub-quadrants of each cell, then the other.
        strata = _Strata(2 * k + 2, xs, ys, 2 * n)
        other = []
        for idx, p in enumerate(order):
            cx, cy = xs[p] >> shift, ys[p] >> shift
            if rng.u32() & 1:
                first, second = (cx ^ 1, cy), (cx, cy ^ 1)
            else:
                first, second = (cx, cy ^ 1), (cx ^ 1, cy)
            other.append(second)
            xs[2 * n + idx], ys[2 * n + idx] = _place(strata, rng, *first, cell_bits)
        for idx, (cx, cy) in enumerate(other):
            xs[3 * n + idx], ys[3 * n + idx] = _place(strata, rng, cx, cy, cell_bits)
        n, k = 4 * n, k + 1
    return np.stack([np.array(xs, np.uint32), np.array(ys, np.uint32)], axis=1)


def encode_tables(sets):
    """``(SETS, POINTS, 2)`` uint32 -> base64 text lines of the top 16 bits (little-endian).

    16 bits keep the 12 bits of the finest strata and 4 of jitter; the Owen scrambling at
    render time fills in the bits below at random, so storing more would change nothing.
    """
    top = (np.asarray(sets, np.uint32) >> np.uint32(16)).astype("<u2")
    raw = base64.b64encode(np.ascontiguousarray(top).tobytes()).decode("ascii")
    return [raw[i:i + 92] for i in range(0, len(raw), 92)]


def decode_tables(text, sets=SETS, points=POINTS):
    """Inverse of :func:`encode_tables`: ``(sets, points, 2)`` uint32, low 16 bits zero."""
    raw = base64.b64decode("".join(text))
    top = np.frombuffer(raw, "<u2").astype(np.uint32).reshape(sets, points, 2)
    return top << np.uint32(16)


def write_tables(path):
    """Generate the sets and write the data module ``pmj02_tables.py`` to ``path``."""
    sets = np.stack([generate_pmj02(POINTS, k) for k in GENERATOR_KEYS])
    lines = encode_tables(sets)
    with open(path, "w", encoding="ascii") as f:
        f.write('"""PMJ02 point sets, generated by\n``python -m sampling_lab.core.sampling.samplers'
                '.pmj02``: do not edit.\n\n'
                f"{SETS} progressive multi-jittered (0, 2) sequences of {POINTS} points\n"
                "(:func:`.pmj02.generate_pmj02` with the keys ``GENERATOR_KEYS``): the top 16 "
                "bits of x and y\nin fixed point (value / 2^16), little-endian uint16 pairs, "
                "base64.\n"
                '"""\n\n')
        f.write(f"SETS = {SETS}\nPOINTS = {POINTS}\n")
        f.write("GENERATOR_KEYS = (" + ", ".join(f"0x{k:08X}" for k in GENERATOR_KEYS) + ")\n\n")
        f.write("DATA = (\n")
        for line in lines:
            f.write(f'    "{line}"\n')
        f.write(")\n")


_TABLE = None


def tables():
    """The stored sets: ``(SETS, POINTS, 2)`` uint32 (decoded on first use)."""
    global _TABLE
    if _TABLE is None:
        from . import pmj02_tables
        if (pmj02_tables.SETS, pmj02_tables.POINTS) != (SETS, POINTS):
            raise RuntimeError("pmj02_tables.py is stale: regenerate it")
        _TABLE = decode_tables(pmj02_tables.DATA)
    return _TABLE


# --------------------------------------------------------------------------------------------
# Sampling
# --------------------------------------------------------------------------------------------


def octave_shuffle(key, j):
    """Permute ``j`` within its octave [2^k, 2^(k+1)) by a hashed permutation per (key, k).

    Prefixes of 2^m indices are mapped onto themselves, so they stay the table's nets.
    """
    j = np.asarray(j, np.int64)
    k = np.frexp(np.maximum(j, 1).astype(np.float64))[1].astype(np.int64) - 1
    start = np.int64(1) << k
    t = permutation_element(j - start, start, hash_combine(key, k.astype(np.uint32)))
    return np.where(j == 0, 0, start + t)


def pmj02_u32(key, sample_index):
    """Point ``sample_index`` of the scrambled pmj02 sequence of ``key``: ``(n, 2)`` uint32."""
    table = tables()
    epoch, j = split_epochs(sample_index, POINTS)
    key = hash_combine(key, epoch.astype(np.uint32))
    which = (sub_key(key, 0) % np.uint32(SETS)).astype(np.int64)
    pts = table[which, octave_shuffle(sub_key(key, 1), j)]
    out = np.empty_like(pts)
    out[:, 0] = owen_scramble(pts[:, 0], sub_key(key, 2))
    out[:, 1] = owen_scramble(pts[:, 1], sub_key(key, 3))
    return out


class PMJ02Stream(PaddedStream):
    salt = 0x1F83D9AB

    def _sample_1d(self, key, dimension):
        return unit_from_u32(pmj02_u32(key, self.sample_index)[:, 0])

    def _sample_2d(self, key, dimension):
        return unit_from_u32(pmj02_u32(key, self.sample_index))


class PMJ02Sampler:
    """Makes :class:`PMJ02Stream` batches. ``spp`` is accepted and not needed."""

    name = "pmj02"
    label = "PMJ02"
    description = ("Progressive multi-jittered (0,2) sequences (Christensen et al. 2018), "
                   "scrambled per pixel by a hash-based approximation of Owen scrambling "
                   "(Laine-Karras permutation): every power-of-two prefix stratified in all "
                   "elementary intervals. Progressive; best up to 4096 samples")
    needs_spp = False
    # Samples depend on the pixel index alone, not on where the pixel is on the screen.
    screen_space = False

    def __init__(self, seed=0, spp=None):
        self.seed = int(seed)
        self.spp = spp
        tables()

    def stream(self, pixel, sample_index):
        return PMJ02Stream(pixel, sample_index, self.seed)


if __name__ == "__main__":
    import os
    import time

    t0 = time.perf_counter()
    target = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__),
                                                               "pmj02_tables.py")
    write_tables(target)
    print(f"wrote {target} in {time.perf_counter() - t0:.1f} s")
