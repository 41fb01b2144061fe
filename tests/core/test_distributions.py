"""Discrete distributions: PiecewiseConstant1D and AliasTable choose bins by their pmf, never
choose empty bins, and hand back a remapped u that is uniform inside the chosen bin."""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core.sampling.distributions import AliasTable, PiecewiseConstant1D
from tests.helpers import chi_square_test, ks_uniform_test

DISTRIBUTIONS = [PiecewiseConstant1D, AliasTable]
N = 200_000
ONE_MINUS = np.nextafter(1.0, 0.0)


def _weights_with_zeros():
    """Leading, interior and trailing zero bins around uneven weights."""
    w = np.random.default_rng(0).random(30) ** 2
    w[[0, 1, 7, 8, 9, 15, 27, 28, 29]] = 0.0
    return w


def _hard_u(dist):
    """u at and next to every CDF or alias-column boundary, plus the ends of [0, 1)."""
    n = len(dist)
    edges = np.arange(n + 1) / n
    if isinstance(dist, PiecewiseConstant1D):
        edges = np.concatenate([edges, dist.cdf])
    else:
        edges = np.concatenate([edges, (np.arange(n) + dist.prob) / n])
    u = np.concatenate([edges, np.nextafter(edges, 0.0), np.nextafter(edges, 1.0),
                        [0.0, ONE_MINUS]])
    return u[(u >= 0.0) & (u < 1.0)]


@pytest.mark.parametrize("cls", DISTRIBUTIONS)
def test_sampled_bins_match_pmf(cls):
    w = _weights_with_zeros()
    dist = cls(w)
    index, pmf, _ = dist.sample(np.random.default_rng(1).random(N))
    np.testing.assert_allclose(dist.pmf_table, w / w.sum(), rtol=1e-12)
    chi_square_test(index, w / w.sum(), what=cls.__name__)
    np.testing.assert_array_equal(pmf, dist.pmf(index))


@pytest.mark.parametrize("cls", DISTRIBUTIONS)
def test_many_small_bins_match_pmf(cls):
    # Heavy-tailed weights: most bins expect < 5 samples, exercising the pooling of small cells.
    rng = np.random.default_rng(2)
    w = rng.pareto(1.0, 5000) * (rng.random(5000) < 0.8)
    dist = cls(w)
    index, _, _ = dist.sample(rng.random(N))
    chi_square_test(index, w / w.sum(), what=cls.__name__)


@pytest.mark.parametrize("cls", DISTRIBUTIONS)
def test_zero_weight_bins_are_never_chosen_even_at_bin_boundaries(cls):
    w = _weights_with_zeros()
    dist = cls(w)
    for u in (np.random.default_rng(3).random(N), _hard_u(dist)):
        index, pmf, _ = dist.sample(u)
        assert np.all(w[index] > 0), np.unique(index[w[index] == 0])
        assert np.all(pmf > 0)


@pytest.mark.parametrize("cls", DISTRIBUTIONS)
def test_trailing_zero_bins_are_never_chosen_despite_rounding(cls):
    # Regression: PiecewiseConstant1D summed normalised pmfs and forced cdf[-1] = 1, so rounding
    # could leave [cdf[k], 1) to a trailing empty bin (pmf 0) or make the CDF non-monotone.
    rng = np.random.default_rng(4)
    for _ in range(300):
        k = int(rng.integers(2, 20))
        w = rng.random(k) * (rng.random(k) < 0.7)
        w[-int(rng.integers(1, 3)):] = 0.0
        if w.sum() == 0:
            continue
        dist = cls(w)
        index, pmf, _ = dist.sample(_hard_u(dist))
        assert np.all(w[index] > 0) and np.all(pmf > 0), w
        if cls is PiecewiseConstant1D:
            assert np.all(np.diff(dist.cdf) >= 0) and dist.cdf[-1] == 1.0
            assert dist.cdf[np.flatnonzero(w)[-1] + 1] == 1.0


@pytest.mark.parametrize("cls", DISTRIBUTIONS)
def test_single_bin_is_always_chosen_with_pmf_one_and_u_unchanged(cls):
    dist = cls([3.5])
    u = np.concatenate([np.random.default_rng(5).random(1000), [0.0, ONE_MINUS]])
    index, pmf, u_remapped = dist.sample(u)
    assert np.all(index == 0) and np.all(pmf == 1.0)
    np.testing.assert_allclose(u_remapped, u, rtol=0, atol=1e-15)


@pytest.mark.parametrize("cls", DISTRIBUTIONS)
@pytest.mark.parametrize("weights", [np.zeros(7), [0.0], np.full(4, np.nan)],
                         ids=["zeros", "one", "nan"])
def test_all_zero_weights_give_the_uniform_distribution(cls, weights):
    dist = cls(weights)
    k = len(weights)
    np.testing.assert_allclose(dist.pmf(np.arange(k)), 1.0 / k, rtol=1e-15)
    index, _, _ = dist.sample(np.random.default_rng(6).random(50_000))
    chi_square_test(index, np.full(k, 1.0 / k), what=f"{cls.__name__} all-zero")


@pytest.mark.parametrize("cls", DISTRIBUTIONS)
def test_empty_input_is_rejected(cls):
    with pytest.raises(ValueError):
        cls([])


@pytest.mark.parametrize("cls", DISTRIBUTIONS)
def test_u_remapped_is_uniform_and_in_unit_interval(cls):
    dist = cls(_weights_with_zeros())
    _, _, u_remapped = dist.sample(np.random.default_rng(7).random(N))
    ks_uniform_test(u_remapped, what=f"{cls.__name__} u_remapped")
    _, _, edge_remapped = dist.sample(_hard_u(dist))
    assert np.all((edge_remapped >= 0.0) & (edge_remapped < 1.0))


@pytest.mark.parametrize("cls", DISTRIBUTIONS)
def test_u_remapped_is_uniform_within_each_chosen_bin(cls):
    # Joint test over (bin, 8 sub-intervals of u_remapped): expected pmf[i] / 8 per cell, which
    # checks the bin choice and the conditional uniformity of u_remapped in one go.
    w = _weights_with_zeros()
    dist = cls(w)
    index, _, u_remapped = dist.sample(np.random.default_rng(8).random(N))
    sub = 8
    cell = index * sub + np.minimum((u_remapped * sub).astype(np.int64), sub - 1)
    chi_square_test(cell, np.repeat(w / w.sum(), sub) / sub, what=f"{cls.__name__} (bin, u')")


def test_piecewise_u_remapped_is_the_position_of_u_inside_its_cdf_interval():
    dist = PiecewiseConstant1D(_weights_with_zeros())
    u = np.concatenate([np.random.default_rng(9).random(10_000), _hard_u(dist)])
    index, _, u_remapped = dist.sample(u)
    lo, hi = dist.cdf[index], dist.cdf[index + 1]
    assert np.all((lo <= u) & (u < hi))
    np.testing.assert_allclose(lo + u_remapped * (hi - lo), u, rtol=0, atol=1e-15)


def test_piecewise_integral_is_the_mean_of_the_function():
    w = _weights_with_zeros()
    assert PiecewiseConstant1D(w).integral == pytest.approx(w.mean(), rel=1e-14)


def test_alias_table_columns_hold_exactly_the_pmf():
    # P(i) = (prob[i] + sum over columns j aliased to i of (1 - prob[j])) / n, exactly.
    rng = np.random.default_rng(10)
    for k in (1, 2, 3, 17, 1000):
        w = rng.random(k) ** 3 * (rng.random(k) < 0.7)
        dist = AliasTable(w)
        recovered = dist.prob / k
        np.add.at(recovered, dist.alias, (1.0 - dist.prob) / k)
        np.testing.assert_allclose(recovered, dist.pmf_table, rtol=0, atol=1e-14)
        assert np.all((dist.prob >= 0) & (dist.prob <= 1))
        assert np.all(dist.prob[dist.pmf_table == 0] == 0)


@pytest.mark.parametrize("cls", DISTRIBUTIONS)
def test_chi_square_detects_a_five_percent_pmf_error(cls):
    # The checker has the power to see small errors at this sample count: a 5 % error in the
    # heaviest bin (pmf ~0.1) shifts its count by ~6 standard deviations.
    w = _weights_with_zeros()
    wrong = w.copy()
    wrong[np.argmax(w)] *= 1.05
    index, _, _ = cls(w).sample(np.random.default_rng(11).random(N))
    with pytest.raises(AssertionError, match="chi-square"):
        chi_square_test(index, wrong / wrong.sum())


def test_ks_check_rejects_non_uniform_values():
    x = np.random.default_rng(12).random(N) ** 1.02
    with pytest.raises(AssertionError, match="KS"):
        ks_uniform_test(x)
