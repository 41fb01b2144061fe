"""Stratified and low-discrepancy samplers keep the properties their manual pages promise.

Stratification is exact, so it is checked exactly, after all per-pixel scrambling: one point per
stratum (stratified, multi-jittered), Latin hypercube (multi-jittered), every elementary interval
of area 1/N (Sobol, PMJ02, Hammersley: (0, m, 2)-nets), every power-of-two prefix (Sobol, PMJ02),
the first b^k points in base b (Halton). Unbiasedness, the variance gain and the decorrelation of
slots and pixels are statistical (confidence intervals and chi-square tests from
``tests.helpers`` at stated false-failure probabilities), each shown to reject a sampler that is
wrong in the way it guards against (a regular grid, a duplicated sequence).

The generic determinism and uniformity tests of every sampler are in ``test_samplers.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.render import RenderSettings, render
from sampling_lab.core.sampling import lowdiscrepancy as ld
from sampling_lab.core.sampling.samplers import make_sampler, sampler_class
from sampling_lab.core.sampling.samplers import pmj02
from sampling_lab.core.sampling.samplers.multijitter import cmj_grid
from sampling_lab.core.sampling.samplers.stratified import grid_shape
from tests.helpers import (
    assert_estimates_agree, assert_mean_within_ci, block_estimates, chi_square_uniform_square,
    ks_uniform_test, uniform_bounces,
)

QMC = ["stratified", "multijitter", "halton", "hammersley", "sobol", "pmj02"]
PIXELS = np.array([0, 1, 4097, 123_456, 2**33 + 5])  # incl. a pixel index above 2^32
SLOTS_2D = [0, 3, 5, 11, 21]  # where the path tracer's 2-D slots start (filter, light, BSDF)
SLOTS_1D = [2, 7, 10]  # light selection, roulette


def slot_values(name, spp, pixels, dimension, count, seed=0, first=0, n=None, sampler_spp=-1):
    """Samples ``first .. first + n - 1`` of each pixel in one slot: ``(pixels, n, count)``."""
    n = spp if n is None else n
    sampler = make_sampler(name, seed=seed, spp=spp if sampler_spp == -1 else sampler_spp)
    pixels = np.asarray(pixels, np.int64)
    pix = np.repeat(pixels, n)
    smp = np.tile(np.arange(first, first + n, dtype=np.int64), pixels.size)
    return sampler.stream(pix, smp).sample(dimension, count).reshape(pixels.size, n, count)


def assert_one_per_stratum(u, n, what):
    """Each of the n intervals [k/n, (k+1)/n) holds exactly one of the n values ``u``."""
    strata = np.sort(np.floor(u * n).astype(np.int64))
    assert np.array_equal(strata, np.arange(n)), f"{what}: strata {strata.tolist()}"


def assert_net(points, m, what):
    """Every elementary interval 2^-a x 2^-(m-a) holds exactly one of the 2^m points."""
    p = np.asarray(points, np.float64)
    assert p.shape == (1 << m, 2)
    for a in range(m + 1):
        ix = np.floor(p[:, 0] * (1 << a)).astype(np.int64)
        iy = np.floor(p[:, 1] * (1 << (m - a))).astype(np.int64)
        counts = np.bincount(ix * (1 << (m - a)) + iy, minlength=1 << m)
        assert (counts == 1).all(), (
            f"{what}: intervals 2^-{a} x 2^-{m - a} hold {counts.min()}..{counts.max()} points")


def assert_net_u32(xy, m, what):
    """:func:`assert_net` for 32-bit fixed-point points (exact)."""
    x = np.asarray(xy[:, 0], np.uint64)
    y = np.asarray(xy[:, 1], np.uint64)
    for a in range(m + 1):
        cell = ((x >> np.uint64(32 - a)) << np.uint64(m - a)) | (y >> np.uint64(32 - (m - a)))
        counts = np.bincount(cell.astype(np.int64), minlength=1 << m)
        assert (counts == 1).all(), f"{what}: intervals 2^-{a} x 2^-{m - a} not one each"


# --------------------------------------------------------------------------------------------
# Stratified and multi-jittered: one point per stratum, for square and non-square counts
# --------------------------------------------------------------------------------------------


def test_grid_shape_is_near_square_with_few_empty_cells():
    table = {1: (1, 1), 2: (2, 1), 3: (2, 2), 7: (4, 2), 8: (4, 2), 12: (4, 3), 13: (5, 3),
             16: (4, 4), 64: (8, 8), 100: (10, 10)}
    for n, shape in table.items():
        assert grid_shape(n) == shape, n
    for n in range(1, 400):
        nx, ny = grid_shape(n)
        assert nx * ny >= n and ny <= nx <= 2 * ny and nx * ny - n < ny, n


@pytest.mark.parametrize("spp", [16, 64, 12, 7, 13, 2, 1])
def test_stratified_puts_one_sample_in_each_stratum_and_grid_cell(spp):
    nx, ny = grid_shape(spp)
    for d in SLOTS_1D:
        u = slot_values("stratified", spp, PIXELS, d, 1, seed=3)
        for p in range(PIXELS.size):
            assert_one_per_stratum(u[p, :, 0], spp, f"pixel {PIXELS[p]} dimension {d}")
    for d in SLOTS_2D:
        u = slot_values("stratified", spp, PIXELS, d, 2, seed=3)
        cells = np.floor(u[..., 0] * nx).astype(np.int64) * ny + np.floor(u[..., 1] * ny)
        for p in range(PIXELS.size):
            counts = np.bincount(cells[p].astype(np.int64), minlength=nx * ny)
            # Padded grids (nx ny > N) leave nx ny - N cells empty, never two points in one.
            assert counts.max() == 1 and counts.sum() == spp, f"pixel {p} slot {d}: {counts}"


@pytest.mark.parametrize("spp", [16, 64, 12, 7, 10, 2, 1])
def test_multijitter_is_a_latin_hypercube_with_one_point_per_grid_cell(spp):
    m, rows, r = cmj_grid(spp)
    assert (rows - 1) * m + r == spp and 1 <= r <= m and m * m <= spp
    # Column t holds `rows` points for t < r, else rows - 1: its x strata start here.
    starts = np.array([t * (rows - 1) + min(t, r) for t in range(m)])
    for d in SLOTS_2D:
        u = slot_values("multijitter", spp, PIXELS, d, 2, seed=4)
        for p in range(PIXELS.size):
            what = f"pixel {PIXELS[p]} slot {d}"
            assert_one_per_stratum(u[p, :, 0], spp, what + " x")
            assert_one_per_stratum(u[p, :, 1], spp, what + " y")
            xs = np.floor(u[p, :, 0] * spp).astype(np.int64)
            ys = np.floor(u[p, :, 1] * spp).astype(np.int64)
            cells = (np.searchsorted(starts, xs, side="right") - 1) * rows + ys // m
            assert np.unique(cells).size == spp, what + ": two points share a grid cell"
    for d in SLOTS_1D:
        u = slot_values("multijitter", spp, PIXELS, d, 1, seed=4)
        for p in range(PIXELS.size):
            assert_one_per_stratum(u[p, :, 0], spp, f"pixel {PIXELS[p]} dimension {d}")


def test_square_multijitter_cells_are_the_regular_grid():
    u = slot_values("multijitter", 16, PIXELS, 3, 2, seed=5)
    cells = np.floor(u[..., 0] * 4).astype(np.int64) * 4 + np.floor(u[..., 1] * 4)
    for p in range(PIXELS.size):
        assert np.unique(cells[p]).size == 16


@pytest.mark.parametrize("name", ["stratified", "multijitter"])
def test_without_a_sample_count_sets_of_64_are_stratified(name):
    """Time-limited renders (spp None): every block of 64 samples is a stratified set."""
    sampler = make_sampler(name, seed=6, spp=None)
    assert not sampler.needs_spp
    for first in (0, 64, 640):
        u = slot_values(name, 64, PIXELS, 3, 2, seed=6, first=first, sampler_spp=None)
        for p in range(PIXELS.size):
            if name == "stratified":
                cells = np.floor(u[p, :, 0] * 8) * 8 + np.floor(u[p, :, 1] * 8)
                assert np.unique(cells).size == 64
            else:
                assert_one_per_stratum(u[p, :, 0], 64, f"{name} block at {first}")
                assert_one_per_stratum(u[p, :, 1], 64, f"{name} block at {first}")
    a = slot_values(name, 64, PIXELS, 3, 2, seed=6, first=0, sampler_spp=None)
    b = slot_values(name, 64, PIXELS, 3, 2, seed=6, first=64, sampler_spp=None)
    assert not np.array_equal(np.sort(a[..., 0], axis=1), np.sort(b[..., 0], axis=1))


# --------------------------------------------------------------------------------------------
# Base-2 nets: Sobol, PMJ02, Hammersley
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["sobol", "pmj02", "hammersley"])
@pytest.mark.parametrize("m", [4, 6, 8])
def test_base2_samplers_are_02_nets_in_every_slot_after_scrambling(name, m):
    n = 1 << m
    for d in SLOTS_2D:
        u = slot_values(name, n, PIXELS, d, 2, seed=7)
        for p in range(PIXELS.size):
            assert_net(u[p], m, f"{name} pixel {PIXELS[p]} slot {d}")
    for d in SLOTS_1D:
        u = slot_values(name, n, PIXELS, d, 1, seed=7)
        for p in range(PIXELS.size):
            assert_one_per_stratum(u[p, :, 0], n, f"{name} pixel {PIXELS[p]} dimension {d}")


@pytest.mark.parametrize("name", ["sobol", "pmj02"])
def test_progressive_samplers_keep_every_power_of_two_prefix_a_net(name):
    for d in (0, 5, 19):
        u = slot_values(name, 256, PIXELS, d, 2, seed=8, sampler_spp=None)
        for p in range(PIXELS.size):
            for m in range(9):
                assert_net(u[p, :1 << m], m, f"{name} pixel {PIXELS[p]} slot {d} prefix 2^{m}")


def test_sobol_blocks_past_the_first_prefix_are_nets_too():
    """Burley's shuffle maps aligned blocks to aligned blocks: samples 64..127 are a net."""
    u = slot_values("sobol", 64, PIXELS, 3, 2, seed=9, first=64, sampler_spp=None)
    for p in range(PIXELS.size):
        assert_net(u[p], 6, f"sobol pixel {PIXELS[p]} samples 64..127")


def test_sobol_generator_matrices_match_the_sequence():
    """Columns are the points 2^j; word-level evaluation equals the matrix-vector product."""
    i = np.arange(8)
    x0 = ld.reverse_bits(ld.sobol_reversed(0, i)) / 2**32
    x1 = ld.reverse_bits(ld.sobol_reversed(1, i)) / 2**32
    np.testing.assert_array_equal(x0, [0, .5, .25, .75, .125, .625, .375, .875])
    np.testing.assert_array_equal(x1, [0, .5, .75, .25, .625, .125, .375, .875])
    idx = np.random.default_rng(0).integers(0, 2**32, 4000).astype(np.uint32)
    for dim in (0, 1):
        cols = ld.sobol_columns(dim)
        ref = np.zeros_like(idx)
        for j in range(32):
            ref ^= np.where((idx >> np.uint32(j)) & np.uint32(1), cols[j], 0).astype(np.uint32)
        np.testing.assert_array_equal(ld.reverse_bits(ref), ld.sobol_reversed(dim, idx))
        # Every aligned block of 2^m unscrambled points is a net: a (0, 2)-sequence.
    for m in (3, 5):
        for q in (0, 1, 7):
            i = np.arange(q << m, (q + 1) << m)
            pts = np.stack([ld.reverse_bits(ld.sobol_reversed(c, i)) for c in (0, 1)], axis=1)
            assert_net_u32(pts, m, f"Sobol block {q} of 2^{m}")


def test_pmj02_tables_are_progressive_02_sequences():
    table = pmj02.tables()
    assert table.shape == (pmj02.SETS, pmj02.POINTS, 2)
    for s in range(pmj02.SETS):
        for m in range(13):
            assert_net_u32(table[s, :1 << m], m, f"pmj02 set {s} prefix 2^{m}")
    # The sets differ from each other.
    assert len({table[s].tobytes() for s in range(pmj02.SETS)}) == pmj02.SETS


def test_pmj02_tables_are_what_the_generator_makes():
    """The data module is reproducible from the code (and prefixes don't depend on length)."""
    table = pmj02.tables()
    for s, key in enumerate(pmj02.GENERATOR_KEYS):
        pts = pmj02.generate_pmj02(pmj02.POINTS, key)
        np.testing.assert_array_equal(pts >> np.uint32(16), table[s] >> np.uint32(16))
    short = pmj02.generate_pmj02(256, pmj02.GENERATOR_KEYS[1])
    np.testing.assert_array_equal(short >> np.uint32(16), table[1, :256] >> np.uint32(16))
    with pytest.raises(ValueError, match="power of two"):
        pmj02.generate_pmj02(100, 1)


def test_pmj02_octave_shuffle_keeps_prefixes():
    j = np.arange(1024)
    for key in (0, 1, 0xDEADBEEF):
        shuffled = pmj02.octave_shuffle(np.full(1024, key, np.uint32), j)
        for m in range(11):
            assert np.array_equal(np.sort(shuffled[:1 << m]), np.arange(1 << m))
        assert not np.array_equal(shuffled, j)


# --------------------------------------------------------------------------------------------
# Halton and Hammersley
# --------------------------------------------------------------------------------------------


def test_halton_first_b_to_the_k_points_are_stratified_in_each_dimension():
    bases = ld.primes(12)
    for d, b in enumerate(bases):
        b = int(b)
        k = int(np.floor(np.log(1000) / np.log(b)))
        n = b**k
        u = slot_values("halton", n, PIXELS[:3], d, 1, seed=10)
        for p in range(3):
            assert_one_per_stratum(u[p, :, 0], n, f"halton base {b} pixel {PIXELS[p]}")


def test_halton_two_d_slots_are_stratified_in_mixed_boxes():
    """The first b1^k1 b2^k2 points put one point in each box of the b1^k1 x b2^k2 grid."""
    for d, (nx, ny) in ((0, (8, 9)), (3, (7, 11)), (5, (13, 17))):
        u = slot_values("halton", nx * ny, PIXELS[:3], d, 2, seed=11)
        for p in range(3):
            boxes = np.floor(u[p, :, 0] * nx).astype(np.int64) * ny + np.floor(u[p, :, 1] * ny)
            assert np.unique(boxes).size == nx * ny, f"halton slot {d} pixel {p}"


def test_halton_bases_are_the_primes_in_order():
    assert ld.primes(10).tolist() == [2, 3, 5, 7, 11, 13, 17, 19, 23, 29]
    p = ld.primes(2000)
    assert p[-1] == 17389 and np.all(np.diff(p) > 0)
    halton = sampler_class("halton")
    stream = halton().stream(np.zeros(1, np.int64), np.zeros(1, np.int64))
    assert [stream.base(d) for d in (0, 1, 2, 40, 300)] == [2, 3, 5, 179, 1993]


def test_hammersley_refuses_to_run_without_a_sample_count():
    cls = sampler_class("hammersley")
    assert cls.needs_spp
    with pytest.raises(ValueError, match="sample count") as info:
        make_sampler("hammersley", seed=0, spp=None)
    assert "i/N" in str(info.value) and "Halton/Sobol" in str(info.value)
    for name in ("halton", "sobol", "pmj02", "stratified", "multijitter"):
        assert not sampler_class(name).needs_spp
        make_sampler(name, seed=0, spp=None)


def test_hammersley_past_n_starts_a_new_scrambled_set():
    a = slot_values("hammersley", 16, PIXELS, 3, 2, seed=12)
    b = slot_values("hammersley", 16, PIXELS, 3, 2, seed=12, first=16)
    for p in range(PIXELS.size):
        assert_net(a[p], 4, "first set")
        assert_net(b[p], 4, "second set")
        assert not np.array_equal(np.sort(a[p, :, 0]), np.sort(b[p, :, 0]))


def test_hammersley_keeps_the_dyadic_counts_of_i_over_n_for_any_n():
    """For N not a power of two the x coordinates are the scrambled {i / N}: every dyadic
    interval of length 2^-k holds floor or ceil of N 2^-k of them."""
    for n in (7, 12, 100):
        u = slot_values("hammersley", n, PIXELS[:2], 5, 1, seed=13)
        for p in range(2):
            for k in range(1, 5):
                counts = np.bincount(np.floor(u[p, :, 0] * 2**k).astype(np.int64),
                                     minlength=2**k)
                assert counts.min() >= n // 2**k and counts.max() <= -(-n // 2**k)


# --------------------------------------------------------------------------------------------
# Every QMC sampler: consistency, range, decorrelation, unbiasedness, variance
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["multijitter", "halton", "hammersley", "sobol", "pmj02"])
def test_a_1d_slot_is_the_first_coordinate_of_the_2d_slot(name):
    one = slot_values(name, 16, PIXELS, 7, 1, seed=14)
    two = slot_values(name, 16, PIXELS, 7, 2, seed=14)
    np.testing.assert_array_equal(one[..., 0], two[..., 0])


@pytest.mark.parametrize("name", ["halton", "sobol", "pmj02"])
def test_progressive_samplers_ignore_the_sample_count(name):
    a = slot_values(name, 32, PIXELS, 3, 2, seed=15, sampler_spp=None)
    b = slot_values(name, 32, PIXELS, 3, 2, seed=15, sampler_spp=7)
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("name", QMC)
def test_values_stay_below_one_even_in_float32(name):
    u = slot_values(name, 64, np.arange(2000), 3, 2, seed=16)
    assert u.min() >= 0.0 and np.float32(u.max()) < 1.0


@pytest.mark.parametrize("name", QMC)
def test_pixels_and_slots_get_different_point_sets(name):
    """Not the same set in another order: the sorted values differ."""
    u = slot_values(name, 16, np.arange(50), 3, 2, seed=17)
    v = slot_values(name, 16, np.arange(50), 5, 2, seed=17)
    su, sv = np.sort(u, axis=1), np.sort(v, axis=1)
    for p in range(49):
        assert not np.array_equal(su[p], su[p + 1]), f"pixels {p}, {p + 1}"
        assert not np.array_equal(su[p], sv[p]), f"slots 3 and 5 of pixel {p}"


def _f_smooth(x, y):
    return np.exp(x) * (1.0 + y * y)


F_SMOOTH_MEAN = (np.e - 1.0) * 4.0 / 3.0


def _per_pixel_estimates(u):
    return _f_smooth(u[..., 0], u[..., 1]).mean(axis=1)


@pytest.mark.parametrize("name", QMC)
def test_smooth_integrand_is_unbiased_over_pixels(name):
    """Each pixel's N-sample estimate is an independent unbiased estimate (CI over pixels)."""
    for spp, slot in ((16, 3), (12, 0)):
        u = slot_values(name, spp, np.arange(4000), slot, 2, seed=18)
        assert_mean_within_ci(_per_pixel_estimates(u), F_SMOOTH_MEAN, p_false=1e-4,
                              what=f"{name} spp {spp} slot {slot}")
    w = slot_values(name, 16, np.arange(4000), 7, 1, seed=18)[..., 0]
    assert_mean_within_ci((w * w).mean(axis=1), 1.0 / 3.0, p_false=1e-4, what=f"{name} 1-D")


def test_unbiasedness_check_rejects_a_regular_grid():
    """The lecture's non-jittered grid: every pixel gives the same, biased midpoint estimate."""
    c = (np.arange(4) + 0.5) / 4
    grid = np.stack(np.meshgrid(c, c, indexing="ij"), axis=-1).reshape(1, 16, 2)
    est = _per_pixel_estimates(np.repeat(grid, 4000, axis=0))
    with pytest.raises(AssertionError, match="outside the interval"):
        assert_mean_within_ci(est, F_SMOOTH_MEAN, p_false=1e-4)


@pytest.mark.parametrize("name", QMC)
def test_estimates_beat_independent_sampling_on_a_smooth_integrand(name):
    """Variance of a pixel's 64-sample estimate: far below Monte Carlo's sigma^2 / N.

    Smooth 2-D integrands get O(N^-2) or better from every stratified or QMC sampler, i.e.
    >= 10x less than sigma^2 / N at N = 64; we ask for 4x. The variance over 2000 pixels has a
    relative standard error of sqrt(2 / 2000) ~ 3%, and the independent sampler (the control)
    lands within 25% of sigma^2 / N.
    """
    rng = np.random.default_rng(0)
    ref = _f_smooth(*rng.random((2, 1_000_000)))
    mc_var = ref.var() / 64
    for sampler in (name, "independent"):
        u = slot_values(sampler, 64, np.arange(2000), 5, 2, seed=19)
        ratio = _per_pixel_estimates(u).var(ddof=1) / mc_var
        if sampler == "independent":
            assert 0.8 < ratio < 1.25, ratio
        else:
            assert ratio < 0.25, f"{name}: variance {ratio:.3f} x Monte Carlo's"


CROSS_PAIRS = [(3, 5), (0, 3), (4, 6), (2, 7), (1, 11), (5, 11), (10, 12)]


def _cross_slot_points(name, seed=20, n_pixels=2000, spp=64):
    """Dimensions 0..12 drawn as the path tracer draws them: ``(n_pixels * spp, 13)``.

    Camera 0-1, bounce 0: 2 (light selection), 3-4 (light), 5-6 (BSDF), 7 (roulette); bounce 1
    from 10 on. Dimensions 8 and 9 are not drawn (NaN).
    """
    sampler = make_sampler(name, seed=seed, spp=spp)
    pix = np.repeat(np.arange(n_pixels, dtype=np.int64), spp)
    smp = np.tile(np.arange(spp, dtype=np.int64), n_pixels)
    s = sampler.stream(pix, smp)
    u = np.full((pix.size, 13), np.nan)
    u[:, 0:2] = s.next_2d()
    for start in (2, 10):
        s.skip_to(start)
        d = start
        for g in (1, 2, 2, 1):
            if d + g > 13:
                break
            u[:, d:d + g] = s.next_2d() if g == 2 else s.next_1d()[:, None]
            d += g
    return u


@pytest.mark.parametrize("name", QMC)
def test_slots_are_jointly_uniform_across_pairs(name):
    """Dimensions of different slots are independent: no duplicated or correlated sequences."""
    u = _cross_slot_points(name)
    for a, b in CROSS_PAIRS:
        chi_square_uniform_square(u[:, [a, b]], res=(16, 16), what=f"{name} dims {a}, {b}")


def test_cross_slot_check_rejects_duplicated_sequences():
    """What padding guards against: the same (shifted) sequence in two slots, or a fixed grid."""
    n_pixels, spp = 2000, 64
    i = np.tile(np.arange(spp, dtype=np.uint32), n_pixels)
    pix = np.repeat(np.arange(n_pixels, dtype=np.uint32), spp)
    # Unscrambled van der Corput in both slots, each with its own random digital shift per pixel.
    vdc = ld.reverse_bits(i)
    a = ld.unit_from_u32(vdc ^ ld.hash_combine(pix, 1))
    b = ld.unit_from_u32(vdc ^ ld.hash_combine(pix, 2))
    with pytest.raises(AssertionError, match="chi-square"):
        chi_square_uniform_square(np.stack([a, b], axis=1), res=(16, 16))
    # A regular grid, the same in every pixel: cell centres of 8 x 8 in one slot, of 64 x 1 in
    # the next, matched in the same order.
    c = (i % 8 + 0.5) / 8
    d = (i + 0.5) / 64
    with pytest.raises(AssertionError, match="chi-square"):
        chi_square_uniform_square(np.stack([c, d], axis=1), res=(16, 16))


# --------------------------------------------------------------------------------------------
# End to end: the path tracer with every sampler
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", QMC)
def test_furnace_is_unbiased_with_every_sampler(name):
    """All slots of all bounces in use: the furnace's closed form within a CI over pixels."""
    rho, bounces = 0.5, 6
    scene = scenes.furnace(emission=1.0, albedo=rho, width=24, height=24)
    res = render(scene, RenderSettings(spp=16, seed=21, sampler=name,
                                       **uniform_bounces(dict(max_bounces=bounces))))
    expected = (1 - rho ** (bounces + 2)) / (1 - rho)
    assert_mean_within_ci(res.combined()[..., 0].ravel().astype(np.float64), expected,
                          what=f"{name} furnace")


@pytest.mark.parametrize("name", QMC)
def test_cornell_box_agrees_with_the_independent_sampler(name):
    """8 x 8 block means against an independent render; the Variance pass (sample variance / N)
    overstates a stratified estimate's variance, so the intervals are conservative."""
    scene = scenes.cornell_box(32, 32)
    a = render(scene, RenderSettings(spp=16, seed=22, sampler=name))
    b = render(scene, RenderSettings(spp=32, seed=23, sampler="independent"))
    ma, sa = block_estimates(a.film.mean(), a.film.variance())
    mb, sb = block_estimates(b.film.mean(), b.film.variance())
    assert_estimates_agree(ma, sa, mb, sb, p_false=1e-4, what=f"{name} vs independent")


# --------------------------------------------------------------------------------------------
# Building blocks
# --------------------------------------------------------------------------------------------


def test_permutation_element_is_a_bijection_for_any_length():
    rng = np.random.default_rng(1)
    for length in (1, 2, 3, 5, 12, 16, 17, 100, 1000, 4096):
        for key in rng.integers(0, 2**32, 3):
            p = ld.permutation_element(np.arange(length), length, np.uint32(key))
            assert np.array_equal(np.sort(p), np.arange(length)), length
    # Per-element lengths: two permutations at once.
    lengths = np.array([7] * 7 + [9] * 9)
    i = np.concatenate([np.arange(7), np.arange(9)])
    p = ld.permutation_element(i, lengths, np.uint32(5))
    assert np.array_equal(np.sort(p[:7]), np.arange(7)) and np.array_equal(np.sort(p[7:]),
                                                                           np.arange(9))
    # Different keys give different permutations (not shifted copies).
    a = ld.permutation_element(np.arange(64), 64, np.uint32(10))
    b = ld.permutation_element(np.arange(64), 64, np.uint32(11))
    assert np.unique((b - a) % 64).size > 8


def test_sobol_slot_is_the_scrambled_sobol_point_of_the_shuffled_index():
    """The fused evaluation equals its definition: Owen(Sobol_c(shuffle(i)))."""
    from sampling_lab.core.sampling.samplers.sobol import sobol_2d_u32
    rng = np.random.default_rng(3)
    key = rng.integers(0, 2**32, 5000).astype(np.uint32)
    index = rng.integers(0, 2**20, 5000)
    got = sobol_2d_u32(key, index, 2)
    shuffled = ld.shuffle_index(index.astype(np.uint32), ld.sub_key(key, 0))
    for c in (0, 1):
        point = ld.reverse_bits(ld.sobol_reversed(c, shuffled))
        np.testing.assert_array_equal(got[:, c], ld.owen_scramble(point, ld.sub_key(key, 1 + c)))


def test_owen_scramble_keeps_dyadic_intervals_and_is_uniform():
    rng = np.random.default_rng(2)
    v = (np.arange(256, dtype=np.uint32) << np.uint32(24))  # 256 strata of width 2^-8
    for key in rng.integers(0, 2**32, 20).astype(np.uint32):
        s = ld.owen_scramble(v, key)
        assert np.unique(s >> np.uint32(24)).size == 256
    # One value scrambled with many keys is uniform (what makes the samplers unbiased).
    keys = rng.integers(0, 2**32, 100_000).astype(np.uint32)
    for value in (0, 0x12345678, 0xFFFFFFFF):
        u = ld.unit_from_u32(ld.owen_scramble(np.full(keys.size, value, np.uint32), keys))
        ks_uniform_test(u, what=f"Owen scramble of {value:#x}")


def test_reverse_bits_reverses_all_32_bits_of_every_element():
    """The byte-swap form of ``reverse_bits`` against Python's string reversal, on edge values
    and random words, for 1-D and 2-D arrays (the Sobol stream reverses both coordinates of a
    slot in one (2, n) call)."""
    rng = np.random.default_rng(12)
    x = np.concatenate([np.array([0, 1, 0x80000000, 0xFFFFFFFF, 0x12345678], np.uint32),
                        rng.integers(0, 2**32, 2000, dtype=np.uint64).astype(np.uint32)])
    want = np.array([int(f"{int(v):032b}"[::-1], 2) for v in x], np.uint32)
    np.testing.assert_array_equal(ld.reverse_bits(x), want)
    np.testing.assert_array_equal(ld.reverse_bits(x.reshape(-1, 5)), want.reshape(-1, 5))
    np.testing.assert_array_equal(ld.reverse_bits(ld.reverse_bits(x)), x)
