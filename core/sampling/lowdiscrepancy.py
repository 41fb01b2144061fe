"""Building blocks of the stratified and low-discrepancy samplers: keys, scrambles, Sobol, Halton.

Everything works on whole arrays of 32-bit unsigned integers with wrapping arithmetic; the only
loops are over digit positions or bit groups (a few dozen at most) and the bounded cycle-walking
rounds of the hashed permutation, never over samples or pixels.

- Keys: :func:`path_keys` and :func:`slot_keys` turn (pixel, seed) and (pixel, dimension, seed)
  into well-mixed 32-bit keys, from which every scramble seed is hashed. A key never depends on
  the sample index: the samples of one pixel share their scramble, which is what keeps them
  stratified against each other.
- Base 2: :func:`reverse_bits` (van der Corput), :func:`owen_scramble` (Laine-Karras style
  nested scrambling: the bit of weight 2^-k is flipped by a hashed function of the bits above it,
  so every dyadic interval is mapped onto a dyadic interval of the same size and every
  (t, m, s)-net stays a net), :func:`shuffle_index` (Burley 2020: the same scramble applied to
  the index with its bits reversed, which permutes aligned power-of-two blocks of a sequence
  among themselves and the points inside each block).
- Sobol: :func:`sobol_columns` generates the 32 x 32 generator matrices of the first two Sobol
  dimensions in code (the identity, i.e. van der Corput, and the Pascal matrix mod 2 of the
  primitive polynomial x + 1); together they form a (0, 2)-sequence in base 2.
  :func:`sobol_reversed` evaluates them with a few word operations.
- Any base: :func:`primes` (sieve), :func:`permutation_element` (Kensler 2013's hashed
  permutation of {0, ..., l - 1}, any l, with cycle walking), and
  :func:`owen_scrambled_radical_inverse` (Owen scrambling in base b: the k-th digit is permuted
  by a random affine permutation chosen by a hash of the k lower digits of the index; pbrt-v4's
  ``OwenScrambledRadicalInverse`` instead permutes each digit by Kensler's hashed permutation).

Sources are listed in ``docs/REFERENCES.md``.

Values leave as doubles in [0, 1 - 2^-24]: the largest is below one also after a cast to
float32 (as :func:`core.sampling.stream.u32_to_unit_float` guarantees for the independent
sampler).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .stream import hash_u32

# The largest value a sampler returns: exactly representable in float32 and below one.
ONE_MINUS_EPSILON = 1.0 - 2.0**-24

_U32 = np.uint32


# --------------------------------------------------------------------------------------------
# Keys
# --------------------------------------------------------------------------------------------


def _u32(x):
    return np.uint32(int(x) & 0xFFFFFFFF)


def hash_combine(key, value):
    """Hash ``value`` into ``key``: ``(n,)`` uint32 (either may be a scalar)."""
    v = hash_u32(np.asarray(value, np.uint32) ^ _U32(0x9E3779B9))
    return hash_u32(np.asarray(key, np.uint32) ^ v)


def path_keys(pixel, seed, salt):
    """Key of each path's pixel and the seed: ``(n,)`` uint32, independent of the sample index.

    Parameters
    ----------
    pixel : (n,) int64
        Pixel index; its high 32 bits count too.
    seed : int
    salt : int
        Separates the keys of different samplers.
    """
    pixel = np.asarray(pixel, np.int64)
    seed_key = hash_u32(_u32(seed) ^ hash_u32(_u32(seed >> 32) ^ _u32(salt)))
    lo = (pixel & 0xFFFFFFFF).astype(np.uint32)
    hi = (pixel >> 32).astype(np.uint32)
    return hash_combine(hash_u32(lo ^ seed_key), hi)


@functools.lru_cache(maxsize=4096)
def _combine_word(value):
    """The word :func:`hash_combine` mixes into a key for the scalar ``value`` (cached: slot
    keys and sub-keys ask for the same few values in every batch)."""
    return hash_u32(_u32(value) ^ _U32(0x9E3779B9))


@functools.lru_cache(maxsize=4096)
def _scalar_hash(value):
    """``hash_u32`` of the scalar ``value`` (cached)."""
    return hash_u32(_u32(value))


def slot_keys(path_key, dimension, extra=None):
    """Key of each path's (pixel, dimension, seed): ``(n,)`` uint32.

    ``extra`` (e.g. the epoch of a finite point set, ``(n,)``) is hashed in when given.
    """
    k = hash_u32(np.asarray(path_key, np.uint32) ^ slot_word(dimension))
    if extra is not None:
        k = hash_combine(k, np.asarray(extra).astype(np.uint32))
    return k


def slot_word(dimension):
    """The word :func:`slot_keys` hashes into a path key for ``dimension``: uint32."""
    # hash_combine(path_key, hash(dimension) + constant), its scalar half cached.
    return _combine_word((int(_scalar_hash(int(dimension))) + 0x632BE5AB) & 0xFFFFFFFF)


def salt_word(salt):
    """The word :func:`sub_key` hashes into a key for ``salt``: uint32."""
    return _scalar_hash(int(salt))


def sub_key(key, salt):
    """An independent key derived from ``key`` for another use (index shuffle, x, y, ...)."""
    return hash_u32(np.asarray(key, np.uint32) ^ _scalar_hash(int(salt)))


def sub_keys(key, count):
    """``sub_key(key, s)`` for s = 0 .. count - 1 in one hash: ``(count, n)`` uint32."""
    words = np.array([salt_word(s) for s in range(count)], np.uint32)
    return hash_u32(np.asarray(key, np.uint32)[None, :] ^ words[:, None])


def unit_from_u32_into(x, out):
    """:func:`unit_from_u32` of uint32 ``x`` written into the float64 array ``out`` (any
    strides, ``x``'s shape); ``x`` is overwritten (shifted right by 8)."""
    np.right_shift(x, _U32(8), out=x)
    np.multiply(x, 1.0 / (1 << 24), out=out)


def unit_from_u32(x):
    """Fixed-point ``x / 2^32`` to doubles with 24 bits (exactly representable, below one)."""
    return (np.asarray(x, np.uint32) >> _U32(8)).astype(np.float64) * (1.0 / (1 << 24))


def jitter(key, index):
    """A uniform number in [0, 1) per (key, index), 24 bits: ``(n,)`` float64."""
    return unit_from_u32(hash_combine(key, np.asarray(index).astype(np.uint32)))


# --------------------------------------------------------------------------------------------
# Base 2: bit reversal, Owen scrambling, index shuffling
# --------------------------------------------------------------------------------------------


def reverse_bits(x):
    """Reverse the 32 bits of each element: the base-2 radical inverse in fixed point."""
    # Reverse the byte order (one copy), then swap ever larger groups of bits within each
    # byte, in place: this runs several times a slot.
    x = np.asarray(x, np.uint32).byteswap()
    t = np.empty_like(x)
    for s, m in ((1, 0x55555555), (2, 0x33333333), (4, 0x0F0F0F0F)):
        np.right_shift(x, _U32(s), out=t)
        t &= _U32(m)
        x &= _U32(m)
        x <<= _U32(s)
        x |= t
    return x


def laine_karras_permutation(x, seed):
    """Nested scramble of bit-reversed values: bit k is flipped by a function of bits < k.

    Nathan Vegdahl's improvement of the Laine-Karras hash ("Building a Better LK Hash",
    psychopath.io, 2021; its five operations and constants are the published hash, also used by
    pbrt-v4's ``FastOwenScrambler`` and Cycles). Every step (adding the seed, multiplying by an odd number,
    xor with a multiple by an even number) changes bit k only through bits 0..k-1, so on the
    reversed value it is an Owen-style nested scramble: exact stratification, and the flips are
    pseudo-random functions of the seed.

    Parameters
    ----------
    x : (n,) uint32
        Bit-reversed fixed-point values (the most significant digit in bit 0).
    seed : (n,) or scalar uint32
    """
    x = np.array(x, np.uint32)  # a copy: updated in place below
    seed = np.asarray(seed, np.uint32)
    t = np.empty_like(x)
    np.multiply(x, _U32(0x3D20ADEA), out=t)
    x ^= t
    x += seed
    factor = seed >> _U32(16)
    factor |= _U32(1)
    x *= factor
    for multiplier in (0x05526C56, 0x53A22864):
        np.multiply(x, _U32(multiplier), out=t)
        x ^= t
    return x


def owen_scramble(v, seed):
    """Owen-scramble fixed-point values ``v / 2^32`` in base 2: ``(n,)`` uint32.

    Maps every dyadic interval [a 2^-k, (a + 1) 2^-k) onto one of the same length, so the
    number of points in each elementary interval is kept, and each value becomes uniform in
    [0, 1) (its digits below the last significant one are filled in at random).
    """
    return reverse_bits(laine_karras_permutation(reverse_bits(v), seed))


def shuffle_index(index, seed):
    """Burley's shuffle of sample indices: a nested uniform scramble of the index bits.

    Bit k of the result depends on bits >= k of ``index``, so every aligned block
    [q 2^k, (q + 1) 2^k) of indices is mapped onto another aligned block of the same size. The
    first 2^k shuffled indices of a (0, 2)-sequence are therefore an aligned block of it, which
    is again a (0, k, 2)-net: shuffling keeps every power-of-two prefix stratified while giving
    each (pixel, dimension) its own order.
    """
    return reverse_bits(laine_karras_permutation(reverse_bits(index), seed))


# --------------------------------------------------------------------------------------------
# Sobol generator matrices
# --------------------------------------------------------------------------------------------


def sobol_columns(dimension):
    """The 32 columns of Sobol dimension 0 or 1 as uint32 (most significant digit in bit 31).

    Column j is the point of index 2^j. Dimension 0 is the identity (van der Corput: digit j of
    the point is bit j of the index); dimension 1 comes from the primitive polynomial x + 1 with
    initial direction number m_1 = 1, whose generator matrix is Pascal's triangle mod 2: digit i
    of column j is binom(j, i) mod 2, which by Lucas' theorem is 1 exactly when i's bits are a
    subset of j's. The two matrices generate a (0, 2)-sequence in base 2.
    """
    if dimension == 0:
        return np.array([1 << (31 - j) for j in range(32)], np.uint32)
    if dimension == 1:
        cols = []
        for j in range(32):
            c = 0
            for i in range(j + 1):
                if (i & j) == i:
                    c |= 1 << (31 - i)
            cols.append(c)
        return np.array(cols, np.uint32)
    raise ValueError("only Sobol dimensions 0 and 1 are generated (padded 2-D sampling)")


def sobol_reversed(dimension, index):
    """Sobol dimension 0 or 1 of ``index``, bit-reversed (first digit in bit 0): ``(n,)`` uint32.

    Equal to ``reverse_bits(xor of sobol_columns(dimension)[j] over the set bits j of index)``.
    Dimension 0 is the index itself. For dimension 1, digit i is the parity of the index bits j
    whose bit pattern contains i's (Lucas), a superset sum over GF(2) that five butterfly steps
    compute on the whole word: no table, no loop over the 32 bits.
    """
    x = np.array(index, np.uint32)
    if dimension == 0:
        return x
    if dimension != 1:
        raise ValueError("only Sobol dimensions 0 and 1 are generated (padded 2-D sampling)")
    for s, m in ((1, 0x55555555), (2, 0x33333333), (4, 0x0F0F0F0F), (8, 0x00FF00FF),
                 (16, 0x0000FFFF)):
        x ^= (x >> _U32(s)) & _U32(m)
    return x


# --------------------------------------------------------------------------------------------
# Any base: primes, hashed permutations, scrambled radical inverses
# --------------------------------------------------------------------------------------------


def primes(count):
    """The first ``count`` primes (sieve of Eratosthenes): ``(count,)`` int64."""
    if count <= 0:
        return np.zeros(0, np.int64)
    # p_n < n (ln n + ln ln n) for n >= 6
    limit = 15 if count < 6 else int(count * (math.log(count) + math.log(math.log(count)))) + 1
    sieve = np.ones(limit + 1, bool)
    sieve[:2] = False
    for p in range(2, int(limit**0.5) + 1):
        if sieve[p]:
            sieve[p * p::p] = False
    return np.flatnonzero(sieve)[:count].astype(np.int64)


def permutation_element(i, length, key):
    """Element ``i`` of a pseudo-random permutation of {0, ..., length - 1} chosen by ``key``.

    Kensler's hashed permutation ("Correlated Multi-Jittered Sampling", Pixar 2013): an
    invertible hash on the smallest power-of-two range covering ``length``, applied again while
    the result falls outside the range (cycle walking, on average fewer than two rounds). Every
    argument may be an array (``length`` may differ per element).

    Parameters
    ----------
    i : (n,) integer, each in [0, length)
    length : (n,) or scalar integer >= 1
    key : (n,) or scalar uint32

    Returns
    -------
    (n,) int64
    """
    i = np.asarray(i).astype(np.uint32)
    n = i.shape[0]
    # Re-hash the key: nearby keys would otherwise give shifted copies of one permutation.
    key = hash_u32(np.broadcast_to(np.asarray(key, np.uint32), (n,)))
    length = np.asarray(length)
    if length.ndim and n and length.min() == length.max():
        length = length.reshape(-1)[0]
    scalar = length.ndim == 0
    length = length.astype(np.uint32)
    w = length - _U32(1)
    for s in (1, 2, 4, 8, 16):
        w = w | (w >> _U32(s))
    # The hash is a bijection of [0, w]: the walk from i returns to [0, length) within
    # w + 2 - length rounds, so the loop is bounded.
    max_rounds = int(np.max(w, initial=0)) + 2
    x = _kensler_round(i, key, w)
    done = x < length
    if done.all():
        return ((x + key) % length).astype(np.int64)
    out = np.where(done, (x + key) % length, 0).astype(np.int64)
    todo = np.flatnonzero(~done)
    x = x[todo]
    for _ in range(max_rounds):
        p = key[todo]
        wm, lt = (w, length) if scalar else (w[todo], length[todo])
        x = _kensler_round(x, p, wm)
        done = x < lt
        out[todo[done]] = (x[done] + p[done]) % (lt if scalar else lt[done])
        if done.all():
            break
        todo = todo[~done]
        x = x[~done]
    return out


def _kensler_round(x, p, w):
    """One round of Kensler's permutation hash on the bits ``w`` (returns a new array)."""
    x = x ^ p
    x *= _U32(0xE170893D)
    x ^= p >> _U32(16)
    x ^= (x & w) >> _U32(4)
    x ^= p >> _U32(8)
    x *= _U32(0x0929EB3F)
    x ^= p >> _U32(23)
    x ^= (x & w) >> _U32(1)
    x *= _U32(1) | (p >> _U32(27))
    x *= _U32(0x6935FA69)
    x ^= (x & w) >> _U32(11)
    x *= _U32(0x74DCB303)
    x ^= (x & w) >> _U32(2)
    x *= _U32(0x9E501CC3)
    x ^= (x & w) >> _U32(2)
    x *= _U32(0xC860A3DF)
    x &= w
    x ^= x >> _U32(5)
    return x


def radical_inverse_digits(base, bits=24):
    """Digits of base ``base`` for a resolution of 2^-bits: smallest m with b^m >= 2^bits."""
    m = 1
    while base**m < (1 << bits):
        m += 1
    return m


def owen_scrambled_radical_inverse(base, index, key):
    """Owen-scrambled radical inverse of ``index`` in a prime ``base``: ``(n,)`` float64.

    Digit k of the index (least significant first) becomes digit k + 1 after the radix point,
    permuted by a permutation of {0..b-1} chosen by a hash of ``key``, the level k and the k
    lower digits of the index (nested scrambling: the permutation of a digit depends on every
    digit above it in the result). The first m digits, b^m >= 2^24, are permuted one by one
    (also the index's leading zeros, which is what keeps the first b^k points stratified for
    every b^k <= b^m); below them a uniform number hashed from the same node stands for the
    infinitely many remaining scrambled digits. Any set of indices keeps its count in every
    b-adic interval [a b^-k, (a + 1) b^-k), k <= m, and each value is uniform in [0, 1).

    The permutations are random affine maps ``d -> (a d + c) mod b`` with ``a`` in [1, b) and
    ``c`` in [0, b) (Matousek 1998): for a prime base they send any two distinct digits to a
    uniformly random pair of distinct digits, like uniformly random permutations, and that
    pairwise property is all the variance of Owen scrambling depends on. Base 2 takes the
    binary path (:func:`owen_scramble` of the bit-reversed index).

    Parameters
    ----------
    base : int, a prime
    index : (n,) int64, in [0, 2^32)
    key : (n,) uint32
    """
    index = np.asarray(index, np.int64)
    key = np.asarray(key, np.uint32)
    if base == 2:
        return np.minimum(unit_from_u32(owen_scramble(reverse_bits(index.astype(np.uint32)),
                                                      key)), ONE_MINUS_EPSILON)
    m = radical_inverse_digits(base)
    b = _U32(base)
    rest = index.astype(np.uint32)
    prefix = np.zeros(index.shape, np.uint32)  # the k lower digits of the index (mod 2^32)
    scale = 1
    acc = np.zeros(index.shape)  # the permuted digits so far, as an integer (< b^m < 2^53)
    with np.errstate(over="ignore"):
        for k in range(m + 1):
            # One hash per node of the digit tree: (level k, the k lower digits).
            h = hash_u32(key ^ (prefix * _U32(0x2C1B3C6D) + hash_u32(_u32(k * 0x9E3779B1 + base))))
            if k == m:
                break
            digit = rest % b
            rest //= b
            a = _U32(1) + h % (b - _U32(1))
            acc = acc * base + (a * digit + (h >> _U32(16)) % b) % b
            prefix += digit * _U32(scale & 0xFFFFFFFF)
            scale *= base
    x = (acc + unit_from_u32(h)) / float(base) ** m
    return np.minimum(x, ONE_MINUS_EPSILON)
