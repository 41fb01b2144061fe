"""Metrics: error measures, confidence intervals that cover at their stated rate, convergence fits,
the special functions behind them, and the shared CI and chi-square checkers built on them."""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core import metrics as M
from tests.helpers import (
    assert_estimates_agree,
    assert_mean_within_ci,
    assert_samples_agree,
    block_estimates,
    chi_square_counts,
    z_for_false_failure,
)

# Reference values from SciPy 1.17 (scipy.stats.norm.ppf, t.ppf, chi2.ppf / chi2.sf).
NORMAL_PPF = [(0.975, 1.959963984540054), (0.5e-4, -3.890591886413094),
              (0.5e-6, -4.891638475698591), (1e-10, -6.361340902404056)]
T_PPF = [(0.975, 1, 12.706204736174694), (0.975, 10, 2.228138851986274),
         (0.995, 30, 2.7499956535672254), (0.025, 4, -2.7764451051977943),
         (0.9999, 2.5, 34.867969321116306)]
CHI2_SF = [(3.841458820694124, 1, 0.05), (18.307038053275146, 10, 0.05),
           (124.34211340400407, 100, 0.05), (50.0, 20, 0.0002214766382487835),
           (0.1, 3, 0.9918374237318764), (1500.0, 1000, 1.0454640385980825e-22)]


# --------------------------------------------------------------------------------------------
# Error metrics and blocks
# --------------------------------------------------------------------------------------------


def test_mse_is_the_mean_of_squared_differences_over_pixels_and_channels():
    ref = np.zeros((2, 2, 3))
    img = ref.copy()
    img[0, 0, 0] = 2.0
    img[1, 1, 2] = -1.0
    assert M.mse(img, ref) == pytest.approx((4 + 1) / 12)
    assert M.mse(ref, ref) == 0.0


def test_rel_mse_divides_each_squared_error_by_ref_squared_plus_eps():
    ref = np.array([[[0.0, 1.0, 10.0]]])
    img = np.array([[[0.1, 1.5, 9.0]]])
    want = np.mean([0.01 / (0 + 0.01), 0.25 / (1 + 0.01), 1.0 / (100 + 0.01)])
    assert M.rel_mse(img, ref) == pytest.approx(want, rel=1e-14)
    assert M.rel_mse(img, ref, eps=1.0) == pytest.approx(np.mean([0.01, 0.125, 1 / 101]))


def test_rel_mse_is_nearly_scale_invariant_for_bright_images():
    rng = np.random.default_rng(0)
    ref = rng.uniform(1, 2, (8, 8, 3))
    img = ref * (1 + 0.1 * rng.normal(size=ref.shape))
    assert M.rel_mse(1000 * img, 1000 * ref) == pytest.approx(M.rel_mse(img, ref), rel=1e-2)


@pytest.mark.parametrize("fn", [M.mse, M.rel_mse])
def test_metrics_reject_mismatched_shapes(fn):
    with pytest.raises(ValueError):
        fn(np.zeros((2, 2, 3)), np.zeros((2, 3, 3)))


def test_block_means_average_tiles_and_crop_the_remainder():
    h, w, c, b = 10, 13, 2, 4
    img = np.random.default_rng(1).random((h, w, c))
    out = M.block_means(img, b)
    assert out.shape == (2, 3, c)
    # Reference by explicit reduction over each tile's rows and columns.
    rows = np.add.reduceat(img[:8, :12], np.arange(0, 8, b), axis=0)
    tiles = np.add.reduceat(rows, np.arange(0, 12, b), axis=1) / (b * b)
    np.testing.assert_allclose(out, tiles, rtol=1e-14)
    np.testing.assert_allclose(M.block_means(img[:, :, 0], b), tiles[:, :, 0], rtol=1e-14)
    np.testing.assert_array_equal(M.block_means(img, 1), img)
    with pytest.raises(ValueError):
        M.block_means(img, 11)


# --------------------------------------------------------------------------------------------
# Special functions
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("p, want", NORMAL_PPF)
def test_normal_quantile_matches_reference_values(p, want):
    assert M.normal_quantile(p) == pytest.approx(want, rel=1e-13)
    # 1 - p itself is rounded (by ~1e-17 absolute), which moves far-tail quantiles by ~1e-8.
    assert M.normal_quantile(1 - p) == pytest.approx(-want, rel=1e-6)


@pytest.mark.parametrize("p, df, want", T_PPF)
def test_student_t_quantile_matches_reference_values(p, df, want):
    assert M.student_t_quantile(p, df) == pytest.approx(want, rel=1e-9)


def test_student_t_quantile_approaches_the_normal_for_many_dof():
    assert M.student_t_quantile(0.975, 1e7) == pytest.approx(1.959963984540054, rel=1e-6)


@pytest.mark.parametrize("x, dof, want", CHI2_SF)
def test_chi2_sf_matches_reference_values(x, dof, want):
    assert M.chi2_sf(x, dof) == pytest.approx(want, rel=1e-9)


def test_chi2_sf_limits():
    assert M.chi2_sf(0.0, 5) == 1.0
    assert M.chi2_sf(np.inf, 5) == 0.0
    # Two degrees of freedom: the tail is exactly exp(-x / 2).
    for x in (0.5, 3.0, 40.0):
        assert M.chi2_sf(x, 2) == pytest.approx(np.exp(-x / 2), rel=1e-12)


# --------------------------------------------------------------------------------------------
# Confidence intervals cover at their stated rate
# --------------------------------------------------------------------------------------------


def _coverage(method, n, confidence, trials=20_000, seed=2):
    x = np.random.default_rng(seed).normal(3.0, 2.0, (n, trials))
    mean, half = M.mean_and_ci(x, confidence, axis=0, method=method)
    return (np.abs(mean - 3.0) <= half).astype(np.float64)


@pytest.mark.parametrize("n", [3, 10, 100])
def test_student_t_interval_covers_at_its_confidence(n):
    # Coverage of 20 000 independent intervals is a binomial proportion; check it within its CI.
    assert_mean_within_ci(_coverage("t", n, 0.95), 0.95, what=f"t coverage n={n}")


def test_normal_interval_undercovers_for_few_samples():
    # The checker above can fail: the normal interval with n = 3 covers only ~80 %.
    with pytest.raises(AssertionError):
        assert_mean_within_ci(_coverage("normal", 3, 0.95), 0.95)


def test_mean_and_ci_matches_the_textbook_formula():
    x = np.array([1.0, 2.0, 4.0, 7.0, 11.0])
    mean, half = M.mean_and_ci(x, 0.95)
    assert mean == pytest.approx(5.0)
    assert half == pytest.approx(2.7764451051977943 * x.std(ddof=1) / np.sqrt(5), rel=1e-9)
    _, half_n = M.mean_and_ci(x, 0.95, method="normal")
    assert half_n == pytest.approx(1.959963984540054 * x.std(ddof=1) / np.sqrt(5), rel=1e-12)
    assert M.mean_and_ci([3.0], 0.95) == (3.0, np.inf)
    with pytest.raises(ValueError):
        M.mean_and_ci(x, 1.5)


# --------------------------------------------------------------------------------------------
# Convergence fits
# --------------------------------------------------------------------------------------------


def test_convergence_slope_recovers_an_exact_power_law():
    ns = 2.0 ** np.arange(4, 14)
    slope, stderr = M.convergence_slope(ns, 3.0 * ns ** -1.5)
    assert slope == pytest.approx(-1.5, abs=1e-12)
    assert stderr == pytest.approx(0.0, abs=1e-12)


def test_convergence_slope_stderr_covers_the_true_slope_at_its_rate():
    # Log-normal scatter about variance ~ n^-1: (slope + 1) / stderr follows t with k - 2 dof,
    # so the 95 % t-interval must cover -1 in 95 % of 4000 independent fits.
    rng = np.random.default_rng(3)
    ns = 2.0 ** np.arange(3, 12)
    q = -M.student_t_quantile(0.025, ns.size - 2)
    hits = []
    for _ in range(4000):
        slope, stderr = M.convergence_slope(ns, np.exp(rng.normal(0.0, 0.2, ns.size)) / ns)
        hits.append(abs(slope + 1.0) <= q * stderr)
    assert_mean_within_ci(np.array(hits, np.float64), 0.95, what="slope CI coverage")


def test_convergence_slope_rejects_bad_input():
    with pytest.raises(ValueError):
        M.convergence_slope([1, 2], [1.0, 0.5])
    with pytest.raises(ValueError):
        M.convergence_slope([1, 2, 4], [1.0, 0.0, 0.25])


# --------------------------------------------------------------------------------------------
# The shared checkers in tests/helpers.py
# --------------------------------------------------------------------------------------------


def test_z_for_false_failure_applies_bonferroni():
    assert z_for_false_failure(1e-4) == pytest.approx(3.890591886413094, rel=1e-12)
    assert z_for_false_failure(1e-4, comparisons=100) == pytest.approx(4.891638475698591,
                                                                       rel=1e-12)


def test_mean_checker_accepts_a_correct_estimator_and_rejects_a_small_bias():
    x = np.random.default_rng(4).exponential(2.0, (100_000, 3))
    assert_mean_within_ci(x, [2.0, 2.0, 2.0])
    # A 2 % bias is ~3.2 standard errors per column: detected across the three.
    with pytest.raises(AssertionError, match="outside the interval"):
        assert_mean_within_ci(x, 2.0 * 1.02)


def test_mean_checker_accepts_constant_samples_equal_to_the_expectation():
    assert_mean_within_ci(np.full(10, 0.1), 0.1)
    with pytest.raises(AssertionError):
        assert_mean_within_ci(np.full(10, 0.1), 0.1000001)


def test_block_estimates_of_two_independent_renders_agree_and_detect_bias():
    # Two "renders" of a gradient with per-pixel noise of known variance of the mean.
    rng = np.random.default_rng(5)
    h, w, spp = 64, 96, 256
    truth = np.linspace(0.1, 2.0, w)[None, :, None] * np.ones((h, w, 3))
    sigma = 0.5 * truth  # per-sample standard deviation

    def render(bias=1.0):
        img = bias * truth + sigma / np.sqrt(spp) * rng.normal(size=truth.shape)
        return block_estimates(img, sigma**2 / spp, block=8)

    a, b = render(), render()
    assert_estimates_agree(a[0], a[1], b[0], b[1])
    # A 3 % bias is ~5.4 combined standard errors per 8x8 block, above the Bonferroni z of
    # ~4.6 for 288 blocks: most blocks flag it.
    c = render(bias=1.03)
    with pytest.raises(AssertionError):
        assert_estimates_agree(a[0], a[1], c[0], c[1])


def test_sample_sets_checker_compares_means_with_welch_errors():
    rng = np.random.default_rng(6)
    assert_samples_agree(rng.normal(1.0, 1.0, 50_000), rng.normal(1.0, 3.0, 20_000))
    with pytest.raises(AssertionError):
        assert_samples_agree(rng.normal(1.0, 1.0, 50_000), rng.normal(1.05, 1.0, 50_000))


def test_chi_square_checker_has_its_stated_false_failure_rate():
    # Under the null, p-values are uniform: P(p <= 0.05) = 0.05 over 2000 multinomial draws.
    rng = np.random.default_rng(7)
    probs = rng.random(40) + 0.05
    probs /= probs.sum()
    n = 4000
    counts = rng.multinomial(n, probs, size=2000)
    p_values = np.array([chi_square_counts(c, n * probs, alpha=0.0) for c in counts])
    assert_mean_within_ci((p_values <= 0.05).astype(np.float64), 0.05, what="chi2 size")


def test_chi_square_checker_pools_small_cells_and_rejects_impossible_ones():
    expected = np.array([0.5, 0.5, 1.0, 3.0, 100.0, 100.0, 0.0])
    observed = np.array([1, 0, 1, 3, 98, 102, 0])
    assert 0 < chi_square_counts(observed, expected) <= 1
    with pytest.raises(AssertionError, match="probability zero"):
        chi_square_counts(observed + np.eye(7, dtype=int)[6], expected)
    with pytest.raises(ValueError, match="more samples"):
        chi_square_counts([1, 1], [1.0, 1.0])
