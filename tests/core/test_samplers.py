"""Samplers: a stream is a deterministic function of (pixel, sample index, dimension, seed).

Determinism is checked exactly (bit-identical values whatever the batch). Uniformity and
independence are statistical: chi-square and Kolmogorov-Smirnov tests at alpha = 1e-3 on
n = 2e5 values (``tests.helpers``), 2-D chi-square on pairs of values that must be independent
(consecutive dimensions, consecutive sample indices of one pixel, neighbouring pixels, seeds).
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core.sampling.samplers import available, make_sampler
from tests.helpers import chi_square_test, chi_square_uniform_square, ks_uniform_test

N = 200_000
SAMPLER_NAMES = available()


PATTERN = (2, 2, 1) * 22  # how an integrator consumes dimensions: 2-D, 2-D, 1-D, ...


def draw(stream, groups):
    """Consume ``groups`` (1 = ``next_1d``, 2 = ``next_2d``) from ``stream``: ``(n, sum)``."""
    cols = [stream.next_2d() if g == 2 else stream.next_1d()[:, None] for g in groups]
    return np.concatenate(cols, axis=1)


def groups_for(dims):
    """The leading groups of ``PATTERN`` that cover ``dims`` dimensions."""
    k = int(np.searchsorted(np.cumsum(PATTERN), dims)) + 1
    return PATTERN[:k]


def values(sampler, pixel, sample_index, dims=8):
    """``(n, dims)`` values of dimensions 0..dims-1, consumed as ``PATTERN`` says."""
    s = sampler.stream(np.asarray(pixel, np.int64), np.asarray(sample_index, np.int64))
    return draw(s, groups_for(dims))[:, :dims]


def grid(n_pixels, spp):
    return np.repeat(np.arange(n_pixels), spp), np.tile(np.arange(spp), n_pixels)


# --------------------------------------------------------------------------------------------
# Determinism
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", SAMPLER_NAMES)
def test_values_do_not_depend_on_batch_order_or_composition(name):
    sampler = make_sampler(name, seed=7, spp=64)
    pix, smp = grid(300, 64)
    full = values(sampler, pix, smp)
    rng = np.random.default_rng(0)
    perm = rng.permutation(len(pix))
    np.testing.assert_array_equal(values(sampler, pix[perm], smp[perm]), full[perm])
    # Split into uneven batches, each mixed with unrelated paths.
    for part in np.array_split(perm, 7):
        extra_pix = rng.integers(10_000, 20_000, 50)
        extra_smp = rng.integers(0, 64, 50)
        mixed = values(sampler, np.concatenate([extra_pix, pix[part]]),
                       np.concatenate([extra_smp, smp[part]]))
        np.testing.assert_array_equal(mixed[50:], full[part])


@pytest.mark.parametrize("name", SAMPLER_NAMES)
def test_same_inputs_give_the_same_values_in_a_new_sampler(name):
    pix, smp = grid(50, 16)
    a = values(make_sampler(name, seed=3, spp=16), pix, smp)
    b = values(make_sampler(name, seed=3, spp=16), pix, smp)
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("name", SAMPLER_NAMES)
@pytest.mark.parametrize("mask_kind", ["bool", "index"])
def test_compact_keeps_each_survivor_on_its_own_sequence(name, mask_kind):
    sampler = make_sampler(name, seed=1, spp=32)
    pix, smp = grid(200, 32)
    groups = PATTERN[:6]
    full = draw(sampler.stream(pix, smp), groups)
    s = sampler.stream(pix, smp)
    rng = np.random.default_rng(2)
    alive = np.arange(len(pix))
    got = []
    for g in groups:
        got.append(draw(s, [g]))
        # Paths terminate between bounces: the survivors must continue their own sequences.
        keep = rng.random(len(alive)) < 0.7
        s.compact(keep if mask_kind == "bool" else np.nonzero(keep)[0])
        alive = alive[keep]
        got = [x[keep] for x in got]
    np.testing.assert_array_equal(np.concatenate(got, axis=1), full[alive])
    assert len(s) == len(alive) > 0


@pytest.mark.parametrize("name", SAMPLER_NAMES)
def test_skip_to_and_sample_address_dimensions_directly(name):
    sampler = make_sampler(name, seed=5, spp=16)
    pix, smp = grid(100, 16)
    full = values(sampler, pix, smp, dims=10)  # groups: 0-1, 2-3, 4, 5-6, 7-8, 9
    s = sampler.stream(pix, smp)
    s.skip_to(5)
    np.testing.assert_array_equal(s.next_2d(), full[:, 5:7])
    s.skip_to(4)
    np.testing.assert_array_equal(s.next_1d(), full[:, 4])
    np.testing.assert_array_equal(s.sample(2, 2), full[:, 2:4])


@pytest.mark.parametrize("name", SAMPLER_NAMES)
def test_different_seeds_pixels_samples_and_dimensions_give_different_values(name):
    """Changing any input changes (almost) every value.

    Values are 24-bit, so two independent ones coincide with probability 2^-24; among the
    4e5 compared pairs the number of coincidences is Poisson with mean 0.024, and 4 or more
    happen with probability < 2e-8.
    """
    pix, smp = grid(2000, 100)
    base = values(make_sampler(name, seed=0, spp=100), pix, smp, dims=2)
    variants = {
        "seed": values(make_sampler(name, seed=1, spp=100), pix, smp, dims=2),
        "pixel": values(make_sampler(name, seed=0, spp=100), pix + 1, smp, dims=2),
        # Same low 32 bits: the high bits of a pixel index (huge images) count too.
        "pixel's high bits": values(make_sampler(name, seed=0, spp=100), pix + 2**32, smp,
                                    dims=2),
        "sample": values(make_sampler(name, seed=0, spp=100), pix, smp + 1, dims=2),
    }
    for what, other in variants.items():
        assert np.count_nonzero(base == other) < 4, f"changing the {what} kept values"
    assert np.count_nonzero(base[:, 0] == base[:, 1]) < 4, "dimensions 0 and 1 coincide"


# --------------------------------------------------------------------------------------------
# Uniformity (every sampler) and independence (the independent sampler: stratified and
# low-discrepancy samplers correlate successive samples on purpose)
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", SAMPLER_NAMES)
def test_values_are_uniform_in_unit_interval(name):
    pix, smp = grid(N // 100, 100)
    u = values(make_sampler(name, seed=11, spp=100), pix, smp, dims=6)
    assert u.min() >= 0.0 and u.max() < 1.0
    for k in range(u.shape[1]):
        ks_uniform_test(u[:, k], what=f"{name} dimension {k}")
        idx = np.minimum((u[:, k] * 64).astype(np.int64), 63)
        chi_square_test(idx, np.full(64, 1 / 64), what=f"{name} dimension {k} histogram")


@pytest.mark.parametrize("name", ["independent"])
def test_consecutive_dimensions_are_jointly_uniform(name):
    pix, smp = grid(N // 100, 100)
    u = values(make_sampler(name, seed=12, spp=100), pix, smp, dims=8)
    for k in range(u.shape[1] - 1):
        chi_square_uniform_square(u[:, k:k + 2], res=(32, 32),
                                  what=f"{name} dimensions {k}, {k + 1}")


@pytest.mark.parametrize("name", ["independent"])
def test_successive_samples_of_a_pixel_are_jointly_uniform(name):
    sampler = make_sampler(name, seed=13, spp=N + 1)
    u = values(sampler, np.full(N + 1, 12345), np.arange(N + 1), dims=2)
    for k in (0, 1):
        chi_square_uniform_square(np.stack([u[:-1, k], u[1:, k]], axis=1), res=(32, 32),
                                  what=f"{name} samples s, s+1 of dimension {k}")


@pytest.mark.parametrize("name", ["independent"])
def test_neighbouring_pixels_and_seeds_are_jointly_uniform(name):
    pix = np.arange(N + 1)
    smp = np.zeros(N + 1, np.int64)
    u = values(make_sampler(name, seed=14, spp=1), pix, smp, dims=1)[:, 0]
    chi_square_uniform_square(np.stack([u[:-1], u[1:]], axis=1), res=(32, 32),
                              what=f"{name} pixels p, p+1")
    v = values(make_sampler(name, seed=15, spp=1), pix, smp, dims=1)[:, 0]
    chi_square_uniform_square(np.stack([u, v], axis=1), res=(32, 32),
                              what=f"{name} seeds 14, 15")


@pytest.mark.parametrize("name", SAMPLER_NAMES)
def test_many_dimensions_are_each_uniform(name):
    """Dimensions far into a path (64 of them) keep their distribution: (dimension, value) cells.

    Blue-noise samplers dither pixels with a 64 x 64 mask on purpose, so neighbouring pixels'
    offsets are anti-correlated rather than independent and only a whole mask tile of pixels has
    the uniform marginal; for them the check covers exactly one tile (4096 pixels).
    """
    sampler = make_sampler(name, seed=16, spp=16)
    n_pixels = 64 * 64 if hasattr(sampler, "mask_1d") else N // 64 // 16
    if hasattr(sampler, "mask_1d"):
        sampler.width = 64
    pix, smp = grid(n_pixels, 16)
    u = values(sampler, pix, smp, dims=64)
    cell = np.arange(64)[None, :] * 16 + np.minimum((u * 16).astype(np.int64), 15)
    chi_square_test(cell.ravel(), np.full(64 * 16, 1 / (64 * 16)), what=f"{name} 64 dims")


def test_uniformity_check_rejects_a_correlated_pair():
    rng = np.random.default_rng(0)
    x = rng.random(N)
    with pytest.raises(AssertionError, match="chi-square"):
        chi_square_uniform_square(np.stack([x, (x + 0.1 * rng.random(N)) % 1.0], axis=1),
                                  res=(32, 32))


def test_unknown_sampler_is_rejected():
    with pytest.raises(ValueError, match="unknown sampler"):
        make_sampler("no-such-sampler")


@pytest.mark.parametrize("name", SAMPLER_NAMES)
def test_skipping_a_number_leaves_every_other_dimension_unchanged(name):
    """Integrators skip numbers nothing reads (``next_1d_if``: the lobe number of a
    Lambert-only scene, the roulette number before roulette starts); the numbers drawn after
    a skip must be those a stream that drew everything gives, bit for bit."""
    from sampling_lab.core.integrators.common import next_1d_if

    pix = np.repeat(np.arange(40, dtype=np.int64), 16)
    smp = np.tile(np.arange(16, dtype=np.int64), 40)
    sampler = make_sampler(name, seed=9, spp=16, width=8)
    full = draw(sampler.stream(pix, smp), (1, 2, 1, 2, 1, 1, 2))
    s = sampler.stream(pix, smp)
    u0, u1 = s.next_1d(), s.next_2d()
    assert next_1d_if(s, False) is None
    u3 = s.next_2d()
    u5 = next_1d_if(s, True)
    assert next_1d_if(s, False) is None and s.dimension == full.shape[1] - 2
    u7 = s.next_2d()
    np.testing.assert_array_equal(np.column_stack([u0, u1, u3, u5, u7]),
                                  full[:, [0, 1, 2, 4, 5, 6, 8, 9]])
