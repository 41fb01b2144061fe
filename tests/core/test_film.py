"""Film: Cycles' pixel filters, exact per-pixel statistics, splats, and Blender's row order.

The filter reference is Cycles' ``filter_func_blackman_harris`` (``intern/cycles/scene/film.cpp``)
with the width doubling that Cycles' ``filter_table`` applies, transcribed here independently of
``core.film``; its integral is in closed form, so expected bin masses are exact. Statistical
tolerances are chi-square / Kolmogorov-Smirnov levels (alpha = 1e-3) and confidence intervals;
arithmetic identities (means, variances, counts) are checked to rounding.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core.film import Film, PixelFilter, UnitPixels, unit_sums
from sampling_lab.core.render import render
from sampling_lab.core.scene import Camera, Lights, Materials, Scene
from sampling_lab.core.scenes import look_at
from tests.helpers import (assert_mean_within_ci, chi_square_2d, chi_square_test,
                           ks_uniform_test, plain_settings)

N = 200_000
EPS = np.finfo(np.float64).eps

# Cycles: 0.35875 - 0.48829 cos(v) + 0.14128 cos(2v) - 0.01168 cos(3v), v = 2 pi (x / W + 1/2).
BH = (0.35875, 0.48829, 0.14128, 0.01168)


def bh_window(x, support):
    v = 2 * np.pi * (np.asarray(x, np.float64) / support + 0.5)
    return BH[0] - BH[1] * np.cos(v) + BH[2] * np.cos(2 * v) - BH[3] * np.cos(3 * v)


def bh_cdf(x, support):
    """CDF of the normalised window on [-support/2, support/2] (closed-form integral)."""
    x = np.clip(np.asarray(x, np.float64), -0.5 * support, 0.5 * support)
    v = 2 * np.pi * (x / support + 0.5)
    antiderivative = BH[0] * v - BH[1] * np.sin(v) + BH[2] * np.sin(2 * v) / 2 \
        - BH[3] * np.sin(3 * v) / 3
    return antiderivative / (2 * np.pi * BH[0])


def bh_density(x, support):
    return bh_window(x, support) / (BH[0] * support)


def filter_offsets(kind, width, seed, n=N):
    u = np.random.default_rng(seed).random((n, 2))
    return PixelFilter(kind, width).sample(u)


# --------------------------------------------------------------------------------------------
# Pixel filters
# --------------------------------------------------------------------------------------------


def test_blackman_harris_reference_is_a_normalised_density():
    # Guards the transcription: the closed-form CDF is the integral of the window.
    x = np.linspace(-1.5, 1.5, 300_001)
    f = bh_density(x, 3.0)
    trapezoid = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * (x[1] - x[0]))])
    np.testing.assert_allclose(trapezoid, bh_cdf(x, 3.0), atol=1e-9)
    assert bh_cdf(1.5, 3.0) == pytest.approx(1.0, abs=1e-15)


@pytest.mark.parametrize("width", [1.5, 1.0])
def test_blackman_harris_offsets_follow_the_window_cdf_with_doubled_width(width):
    """KS per axis against the window over 2 x width pixels (Cycles doubles the width)."""
    xy = filter_offsets("BLACKMAN_HARRIS", width, seed=1)
    assert np.all(np.abs(xy) <= width + 1e-12), "offsets outside the filter's support"
    for axis in (0, 1):
        # The CDF maps offsets to uniforms; clip the top so that x = +support maps below 1.
        ks_uniform_test(np.minimum(bh_cdf(xy[:, axis], 2 * width), 1 - 1e-16), alpha=1e-3,
                        what=f"Blackman-Harris width {width} axis {axis}")


def test_blackman_harris_ks_rejects_the_undoubled_width():
    xy = filter_offsets("BLACKMAN_HARRIS", 1.5, seed=1, n=20_000)
    with pytest.raises(AssertionError, match="KS"):
        ks_uniform_test(np.minimum(bh_cdf(xy[:, 0], 1.5), 1 - 1e-16))


def test_blackman_harris_offsets_follow_the_normalised_window_per_axis():
    xy = filter_offsets("BLACKMAN_HARRIS", 1.5, seed=2)
    edges = np.linspace(-1.5, 1.5, 61)
    probs = np.diff(bh_cdf(edges, 3.0))
    for axis in (0, 1):
        idx = np.clip(np.searchsorted(edges, xy[:, axis], side="right") - 1, 0, 59)
        chi_square_test(idx, probs, what=f"Blackman-Harris offsets axis {axis}")


def test_blackman_harris_axes_are_independent():
    """2-D chi-square against the product of the marginals.

    The cells are 3/8 px wide, so this checks how the axes pair; the per-axis test checks tails.
    """
    xy = filter_offsets("BLACKMAN_HARRIS", 1.5, seed=3)
    chi_square_2d(xy, lambda p: bh_density(p[:, 0], 3.0) * bh_density(p[:, 1], 3.0),
                  ((-1.5, 1.5), (-1.5, 1.5)), res=(8, 8), subdiv=16,
                  what="Blackman-Harris 2-D")


@pytest.mark.parametrize("width", [1.0, 2.5])
def test_box_filter_offsets_are_uniform_on_its_width(width):
    xy = filter_offsets("BOX", width, seed=4)
    assert np.all(np.abs(xy) <= 0.5 * width), "box offsets outside [-w/2, w/2]"
    for axis in (0, 1):
        ks_uniform_test(xy[:, axis] / width + 0.5, what=f"box width {width} axis {axis}")
    chi_square_2d(xy / width + 0.5, lambda p: np.ones(len(p)), ((0, 1), (0, 1)), res=(16, 16),
                  subdiv=1, what="box 2-D")


def test_unknown_filter_is_rejected():
    with pytest.raises(ValueError, match="filter"):
        PixelFilter("MITCHELL", 1.5)


# --------------------------------------------------------------------------------------------
# Accumulation: mean, variance of the mean, sample count
# --------------------------------------------------------------------------------------------


def _random_batches(film, seed, n_batches=4):
    """Add batches of samples to random pixels; return every (pixel, radiance) added."""
    rng = np.random.default_rng(seed)
    pix, rad = [], []
    for _ in range(n_batches):
        k = int(rng.integers(200, 2000))
        p = rng.integers(0, film.n_pixels, k)
        r = rng.gamma(2.0, 1.0, (k, 3)) * np.array([1.0, 0.5, 2.0])
        film.add_samples(p, r)
        pix.append(p)
        rad.append(r)
    return np.concatenate(pix), np.concatenate(rad)


def test_add_samples_mean_variance_and_count_equal_numpy():
    film = Film(7, 5)
    pix, rad = _random_batches(film, seed=5)
    mean, var, count = film.mean(), film.variance(), film.sample_count()
    assert mean.shape == (5, 7, 3) and var.shape == (5, 7, 3) and count.shape == (5, 7)
    for p in range(film.n_pixels):
        y, x = divmod(p, film.width)
        x_p = rad[pix == p]
        n = len(x_p)
        assert count[y, x] == n
        if n == 0:
            assert np.all(mean[y, x] == 0) and np.all(var[y, x] == 0)
            continue
        # Gamma(2) samples have mean/sd ~ 1.4, so the sum-of-squares formula loses < 10 ulps.
        np.testing.assert_allclose(mean[y, x], x_p.mean(axis=0), rtol=64 * n * EPS)
        if n > 1:
            np.testing.assert_allclose(var[y, x], x_p.var(axis=0, ddof=1) / n, rtol=1e-10)
    assert count.dtype == np.float32 and count.sum() == len(pix)


def test_add_samples_of_a_unit_span_sum_exactly_into_those_pixels():
    """A work unit's samples cover a span of pixels away from pixel 0 (add_samples sums over
    that span only): every sum equals a per-pixel sum in the samples' order, bit for bit
    (rows in float32 too), and no pixel outside the span changes. An offset of the span by
    one pixel, or a lost sample, fails the exact comparison."""
    film = Film(9, 8)
    rng = np.random.default_rng(21)
    for lo, hi, dtype in ((17, 30, np.float64), (40, 41, np.float32), (3, 70, np.float64)):
        pix = rng.integers(lo, hi, 500)
        pix[[0, -1]] = lo, hi - 1
        rad = rng.gamma(2.0, 1.0, (pix.size, 3)).astype(dtype)
        before = film.sum.copy(), film.sum_sq.copy(), film.count.copy()
        film.add_samples(pix, rad, transparency=rng.random(pix.size))
        for p in range(film.n_pixels):
            mine = rad[pix == p].astype(np.float64)
            total, squares = np.zeros(3), np.zeros(3)
            for r in mine:  # in order, as the film adds them
                total, squares = total + r, squares + np.asarray(r ** 2, np.float64)
            assert np.array_equal(film.sum[p], before[0][p] + total)
            assert np.array_equal(film.count[p], before[2][p] + mine.shape[0])
            if mine.shape[0] == 0:
                assert np.array_equal(film.sum_sq[p], before[1][p])
    film.add_samples(np.zeros(0, np.int64), np.zeros((0, 3)))  # an empty batch adds nothing
    assert film.count.sum() == 1500


def test_pixels_with_zero_or_one_sample_have_finite_zero_variance():
    film = Film(3, 1)
    film.add_samples(np.array([1]), np.array([[5.0, 6.0, 7.0]]))
    var = film.variance()
    assert np.all(np.isfinite(var)) and np.all(var == 0)
    np.testing.assert_array_equal(film.mean()[0, 1], [5.0, 6.0, 7.0])
    np.testing.assert_array_equal(film.mean()[0, [0, 2]], 0.0)


def test_variance_estimates_the_variance_of_the_pixel_mean():
    """Over many pixels, the reported variance averages to sigma^2 / n (it is unbiased)."""
    film = Film(64, 64)
    rng = np.random.default_rng(6)
    n = 16
    pix = np.repeat(np.arange(film.n_pixels), n)
    film.add_samples(pix, rng.exponential(1.0, (pix.size, 3)))  # sigma^2 = 1
    var = film.variance().reshape(-1, 3)
    assert_mean_within_ci(var, 1.0 / n, what="mean reported variance")
    # And the spread of the pixel means themselves is that variance (chi-square dof n-1 aside).
    means = film.mean().reshape(-1, 3)
    assert_mean_within_ci((means - 1.0) ** 2, 1.0 / n, what="squared error of the means")


def test_samples_land_in_their_own_pixel_only():
    film = Film(4, 3)
    film.add_samples(np.array([5, 5]), np.array([[1.0, 1.0, 1.0], [3.0, 3.0, 3.0]]))
    mean = film.mean()
    np.testing.assert_array_equal(mean[1, 1], 2.0)
    assert np.count_nonzero(mean.sum(axis=2)) == 1


# --------------------------------------------------------------------------------------------
# Splats (light paths)
# --------------------------------------------------------------------------------------------


def test_splats_are_divided_by_splat_paths_and_add_to_camera_mean():
    film = Film(4, 3)
    film.add_samples(np.array([0, 0]), np.array([[1.0, 1.0, 1.0], [3.0, 3.0, 3.0]]))
    film.splat(np.array([[0.2, 0.7], [0.9, 0.1], [3.5, 2.5]]),
               np.array([[4.0, 8.0, 12.0], [2.0, 2.0, 2.0], [10.0, 0.0, 0.0]]))
    film.add_splat_paths(100)
    film.splat(np.array([[3.1, 2.9]]), np.array([[5.0, 5.0, 5.0]]))
    film.add_splat_paths(150)
    mean = film.mean()
    np.testing.assert_allclose(mean[0, 0], 2.0 + np.array([6.0, 10.0, 14.0]) / 250, rtol=1e-15)
    np.testing.assert_allclose(mean[2, 3], np.array([15.0, 5.0, 5.0]) / 250, rtol=1e-15)
    mean[0, 0] = mean[2, 3] = 0
    assert np.all(mean == 0)


def test_splats_outside_the_image_or_not_finite_are_dropped():
    film = Film(4, 3)
    film.splat(np.array([[-0.01, 1.0], [4.0, 1.0], [1.0, -0.5], [1.0, 3.0], [1.5, 1.5]]),
               np.array([[1.0, 1.0, 1.0]] * 4 + [[np.nan, 1.0, 1.0]]))
    film.add_splat_paths(10)
    assert np.all(film.mean() == 0) and np.all(np.isfinite(film.variance()))


def test_splat_variance_is_the_variance_of_the_mean_over_light_paths():
    """Each light path contributes its splat (or zero) to a pixel: var = var(X) / paths."""
    rng = np.random.default_rng(7)
    film = Film(5, 4)
    m = 3000
    per_path = np.zeros((m, film.n_pixels, 3))
    xy = rng.random((m, 2)) * [film.width, film.height]
    value = rng.gamma(2.0, 1.0, (m, 3))
    pixel = np.floor(xy[:, 1]).astype(int) * film.width + np.floor(xy[:, 0]).astype(int)
    per_path[np.arange(m), pixel] = value
    for chunk in np.array_split(np.arange(m), 3):
        film.splat(xy[chunk], value[chunk])
        film.add_splat_paths(len(chunk))
    expected_mean = per_path.mean(axis=0).reshape(film.height, film.width, 3)
    expected_var = (per_path.var(axis=0, ddof=1) / m).reshape(film.height, film.width, 3)
    np.testing.assert_allclose(film.mean(), expected_mean, rtol=1e-12)
    np.testing.assert_allclose(film.variance(), expected_var, rtol=1e-9)


# --------------------------------------------------------------------------------------------
# Output layout: Combined alpha, row 0 at the bottom
# --------------------------------------------------------------------------------------------


def test_combined_is_float32_rgba_with_alpha_one():
    film = Film(6, 4)
    _random_batches(film, seed=8, n_batches=1)
    rgba = film.combined()
    assert rgba.shape == (4, 6, 4) and rgba.dtype == np.float32
    assert np.all(rgba[..., 3] == 1.0)
    np.testing.assert_array_equal(rgba[..., :3], film.mean().astype(np.float32))


def test_row_zero_is_the_bottom_row_of_pixel_indices_and_film_positions():
    film = Film(5, 4)
    x, y = 3, 0
    film.add_samples(np.array([y * film.width + x]), np.array([[1.0, 2.0, 3.0]]))
    film.splat(np.array([[1.5, 0.25]]), np.array([[7.0, 7.0, 7.0]]))  # film y from the bottom
    film.add_splat_paths(1)
    np.testing.assert_array_equal(film.mean()[0, 3], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(film.mean()[0, 1], [7.0, 7.0, 7.0])
    assert film.sample_count()[0, 3] == 1 and film.sample_count().sum() == 1
    assert np.all(film.mean()[1:] == 0)


def test_rendered_image_has_the_ground_in_row_zero():
    """End to end: an emitter below the view axis lights the bottom rows of the image."""
    le = (1.0, 2.0, 3.0)
    v = np.array([[-20, 5, -20], [20, 5, -20], [20, 5, 0.1], [-20, 5, 0.1]], np.float64)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    mats = Materials.from_lists(["Ground"], [(0.0, 0.0, 0.0)], [le])
    cam = Camera(look_at((0, 0, 0), (0, 1, 0)), 8, 6, lens=50.0, sensor_width=36.0)
    scene = Scene(v, f, np.zeros(2, np.int32), mats, Lights.empty(), cam)
    img = render(scene, plain_settings(spp=4, threads=1)).combined()
    # The emitter's top edge (tan 0.02, half height tan 0.27) is at film y = 3.22 of 6: row 0's
    # filter footprint (film y in [-1.5, 2.5]) sees only the emitter, the top row's
    # ([4, 7]) only the black world.
    np.testing.assert_allclose(img[0, :, :3], np.broadcast_to(le, (8, 3)), rtol=1e-6)
    assert np.all(img[-1, :, :3] == 0)


@pytest.mark.parametrize("kind,width", [("BOX", 1.0), ("BOX", 2.0), ("BLACKMAN_HARRIS", 1.5)])
def test_filter_density_integrates_to_one_and_matches_its_samples(kind, width):
    f = PixelFilter(kind, width)
    x = np.linspace(-3, 3, 600001)
    assert abs(np.trapz(f.pdf_1d(x), x) - 1.0) < 1e-4
    # The sampled offsets follow pdf_1d: compare histogram and density on 30 bins.
    u = (np.arange(200000) + 0.5) / 200000
    s = f.sample(np.stack([u, u], axis=-1))[:, 0]
    counts, edges = np.histogram(s, bins=30, range=(-0.5 * f.support, 0.5 * f.support))
    centres = 0.5 * (edges[1:] + edges[:-1])
    expected = np.array([np.trapz(f.pdf_1d(np.linspace(a, b, 201)), np.linspace(a, b, 201))
                         for a, b in zip(edges[:-1], edges[1:])])
    np.testing.assert_allclose(counts / s.size, expected, atol=2e-4, err_msg=str(centres[:3]))


def test_filtered_splat_spreads_a_value_over_the_pixels_whose_filter_covers_it():
    f = PixelFilter("BLACKMAN_HARRIS", 1.5)
    film = Film(8, 8)
    film.splat(np.array([[4.3, 3.6]]), np.array([[2.0, 4.0, 8.0]]), f)
    film.add_splat_paths(1)
    img = film.mean()
    # Each pixel gets the value times its filter's density at the splat (the weights need not
    # sum to one: Blackman-Harris is no partition of unity, and the camera samples of each
    # pixel weigh the same film positions the same way).
    np.testing.assert_allclose(img[..., 1], 2 * img[..., 0])
    w = img[..., 0] / 2.0
    expected = f.pdf_1d(4.3 - (np.arange(8) + 0.5))[None, :] * f.pdf_1d(
        3.6 - (np.arange(8) + 0.5))[:, None]
    np.testing.assert_allclose(w, expected, atol=1e-12)


@pytest.mark.parametrize("kind, width", [("BLACKMAN_HARRIS", 1.5), ("BOX", 1.0),
                                         ("BLACKMAN_HARRIS", 3.0)])
def test_splats_reach_every_pixel_the_filter_covers_and_no_other(kind, width):
    """Film.splat against a plain sum over every pixel of the frame (filter density at the
    splat times its value): splats near the edges, on a window film, outside the window. The
    film skips taps the filter cannot reach; a skipped tap that the filter does reach would
    show here. The tolerance is float rounding (sums in another order)."""
    f = PixelFilter(kind, width)
    rng = np.random.default_rng(11)
    xy = np.concatenate([rng.uniform(-2.0, 14.0, (300, 2)), [[0.01, 0.99], [11.99, 0.5]]])
    value = rng.uniform(0.0, 1.0, (xy.shape[0], 3))
    film = Film(9, 7, x0=2, y0=1)  # a window of a 12 x 10 frame
    film.splat(xy, value, f)
    px, py = np.arange(2, 11) + 0.5, np.arange(1, 8) + 0.5
    w = (f.pdf_1d(xy[:, 0, None] - px[None, :])[:, None, :]
         * f.pdf_1d(xy[:, 1, None] - py[None, :])[:, :, None])  # (k, rows, columns)
    expected = np.einsum("kyx,kc->yxc", w, value).reshape(-1, 3)
    np.testing.assert_allclose(film.splat_sum, expected, rtol=1e-12, atol=1e-15)
    assert film.splat_sum.any()


@pytest.mark.parametrize("kind, width", [("BLACKMAN_HARRIS", 1.5), ("BOX", 1.0),
                                         ("BLACKMAN_HARRIS", 3.0), ("GAUSSIAN", 1.5)])
def test_filter_reach_holds_every_tap_the_filter_covers(kind, width):
    """Splats visit only the offsets of PixelFilter.reach: every offset at which the filter
    has weight, from positions all over a pixel (its edges included), must be in it; an
    offset it leaves out would lose light at that distance."""
    f = PixelFilter(kind, width)
    frac = np.concatenate([np.linspace(0.0, 1.0, 4001)[:-1], [np.nextafter(1.0, 0.0)]])
    taps = f.taps()
    weight = f.pdf_1d(frac[None, :] - (taps[:, None] + 0.5))
    covered = taps[(weight > 0).any(axis=1)]
    assert set(covered) <= set(f.reach()) and set(f.reach()) <= set(taps)
    assert 0 in covered


def test_a_film_larger_than_half_the_memory_is_refused_before_allocation():
    from sampling_lab.core.film import FILM_BYTES_PER_PIXEL, check_film_memory

    gb = 2 ** 30
    fits = int((0.5 * gb / FILM_BYTES_PER_PIXEL) ** 0.5)  # the largest square that fits
    check_film_memory(fits, fits, memory=gb)
    with pytest.raises(ValueError, match=r"a 100000 x 100000 image needs about \d+ GB"):
        check_film_memory(100_000, 100_000, memory=gb)
    with pytest.raises(ValueError):
        check_film_memory(fits + 1, fits + 1, memory=gb)
    # Only a render region's pixels are kept.
    check_film_memory(100_000, 100_000, region=(0, 0, 100, 100), memory=gb)


def test_sums_beyond_float32_become_its_largest_value_not_inf():
    from sampling_lab.core.film import FLOAT32_MAX, to_float32

    out = to_float32(np.array([1e300, -1e300, 1.0]))
    assert out.dtype == np.float32 and np.isfinite(out).all()
    assert out[0] == np.float32(FLOAT32_MAX) and out[1] == -np.float32(FLOAT32_MAX)


@pytest.mark.parametrize("k", [1, 3, 64])
def test_a_units_pixel_layout_adds_the_same_sums_as_its_pixel_array(k):
    # Property: a work unit's samples summed per pixel by its layout (unit_sums, no array; what
    # a worker sends) and added by Film.add_unit_sums give the same sums, squares, counts and
    # transparency as Film.add_samples of the pixels it stands for, bit for bit.
    # Smallest error detected: any difference in any bit.
    rng = np.random.default_rng(k)
    unit = UnitPixels(7, 7 + 50, k)
    n = 50 * k
    radiance = rng.random((n, 3)) * 10.0 ** rng.uniform(-8, 8, (n, 1))
    alpha = rng.random(n)
    films = [Film(10, 10), Film(10, 10)]
    for values, alphas in ((radiance, alpha), (radiance[::-1].copy(), alpha[::-1].copy())):
        films[0].add_unit_sums(unit_sums(unit, values, alphas))
        films[1].add_samples(unit.array(), values, alphas)
    for name in ("sum", "sum_sq", "count", "transparency"):
        np.testing.assert_array_equal(getattr(films[0], name), getattr(films[1], name))
