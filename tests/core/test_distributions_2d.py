"""2-D and segmented distributions, the vectorized alias build, and the CDF/alias factory.

PiecewiseConstant2D (marginal over rows times a conditional per row) must sample cells by their
pmf, points by its density (which integrates to one), and report the density of what it samples;
both construction methods ('cdf' and 'alias') are checked the same way. The alias tables are
built without a Python loop; their columns must reproduce the pmf to rounding (1e-12 absolute on
bins of pmf up to 1) for a million bins and for thousands of rows at once.

Tolerances: chi-square tests at alpha = 1e-3 (tests/helpers.py); exactness checks at 1e-12.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core.sampling.distributions import (
    DISTRIBUTION_METHODS,
    AliasTable,
    PiecewiseConstant1D,
    PiecewiseConstant2D,
    Segmented1D,
    build_alias_segments,
    make_distribution,
    search_right,
)
from tests.helpers import chi_square_2d, chi_square_test, integrate_density_2d, ks_uniform_test

N = 200_000
METHODS = list(DISTRIBUTION_METHODS)


def _image(nv=12, nu=20, seed=0):
    """Uneven weights with an empty row, an empty column and scattered empty cells."""
    rng = np.random.default_rng(seed)
    f = rng.random((nv, nu)) ** 3 * (rng.random((nv, nu)) < 0.8)
    f[nv // 3] = 0.0
    f[:, nu // 3] = 0.0
    f[nv // 2, 2] = 40.0  # one bright cell, as a sun in an environment map
    return f


def _reconstructed_pmf(prob, alias, seg_len):
    """Bin probabilities that alias columns give: own part plus the parts aliased to it."""
    out = prob / seg_len
    np.add.at(out, alias, (1.0 - prob) / seg_len)
    return out


# --------------------------------------------------------------------------------------------
# PiecewiseConstant2D
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("method", METHODS)
def test_pdf_integrates_to_one_and_matches_the_normalised_function(method):
    f = _image()
    dist = PiecewiseConstant2D(f, method)
    np.testing.assert_allclose(dist.pmf_table, f / f.sum(), rtol=1e-12, atol=1e-15)
    assert abs(dist.pmf_table.sum() - 1.0) < 1e-12
    # The density is piecewise constant on the cells: a midpoint rule on a sub-grid is exact.
    mass = integrate_density_2d(dist.pdf, ((0.0, 1.0), (0.0, 1.0)), (f.shape[1], f.shape[0]), 4)
    assert abs(mass.sum() - 1.0) < 1e-12
    np.testing.assert_allclose(mass.T, f / f.sum(), rtol=1e-10, atol=1e-15)
    assert dist.integral == pytest.approx(f.mean(), rel=1e-14)


@pytest.mark.parametrize("method", METHODS)
def test_sampled_cells_match_the_pmf(method):
    f = _image()
    dist = PiecewiseConstant2D(f, method)
    index, pmf, _ = dist.sample(np.random.default_rng(1).random((N, 2)))
    chi_square_test(index, (f / f.sum()).ravel(), what=f"2-D {method} cells")
    np.testing.assert_array_equal(pmf, dist.pmf(index))
    assert np.all(f.ravel()[index] > 0), "a cell of weight zero was chosen"


@pytest.mark.parametrize("method", METHODS)
def test_continuous_samples_follow_the_pdf(method):
    f = _image()
    dist = PiecewiseConstant2D(f, method)
    points, pdf = dist.sample_continuous(np.random.default_rng(2).random((N, 2)))
    assert np.all((points >= 0.0) & (points < 1.0))
    # Two histogram cells per distribution cell and direction, so the test sees inside cells.
    chi_square_2d(points, dist.pdf, ((0.0, 1.0), (0.0, 1.0)), res=(2 * f.shape[1], 2 * f.shape[0]),
                  subdiv=2, what=f"2-D {method} points")
    np.testing.assert_array_equal(pdf, dist.pdf(points))
    assert np.all(pdf > 0)


@pytest.mark.parametrize("method", METHODS)
def test_remapped_u_is_uniform_inside_the_chosen_cell(method):
    # Joint test over (cell, 3 x 3 sub-cells of u_remapped): each expects pmf / 9.
    f = _image(6, 5, seed=3)
    dist = PiecewiseConstant2D(f, method)
    index, _, ur = dist.sample(np.random.default_rng(4).random((N, 2)))
    sub = np.minimum((ur * 3).astype(np.int64), 2)
    cell = index * 9 + sub[:, 1] * 3 + sub[:, 0]
    chi_square_test(cell, np.repeat((f / f.sum()).ravel(), 9) / 9, what=f"{method} (cell, u')")
    for k in range(2):
        ks_uniform_test(ur[:, k], what=f"{method} u_remapped[{k}]")


@pytest.mark.parametrize("method", METHODS)
def test_all_zero_function_gives_the_uniform_density(method):
    dist = PiecewiseConstant2D(np.zeros((4, 6)), method)
    np.testing.assert_allclose(dist.pmf_table, 1.0 / 24, rtol=1e-15)
    points, pdf = dist.sample_continuous(np.random.default_rng(5).random((1000, 2)))
    np.testing.assert_allclose(pdf, 1.0, rtol=1e-15)


def test_cdf_method_keeps_stratified_u_stratified_over_rows():
    # Inversion is monotone: u[:, 1] stratified in n strata of a uniform marginal gives each row
    # exactly its share; an alias table permutes columns and gives no such guarantee.
    dist = PiecewiseConstant2D(np.ones((8, 3)), "cdf")
    n = 800
    u = np.stack([np.full(n, 0.5), (np.arange(n) + 0.5) / n], axis=-1)
    index, _, _ = dist.sample(u)
    np.testing.assert_array_equal(np.bincount(index // 3, minlength=8), n // 8)


def test_invalid_2d_input_is_rejected():
    with pytest.raises(ValueError):
        PiecewiseConstant2D(np.ones(5))
    with pytest.raises(ValueError):
        PiecewiseConstant2D(np.ones((0, 3)))


# --------------------------------------------------------------------------------------------
# Alias tables: vectorized build, exactness
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["uniform01", "sparse_cubed", "pareto", "lognormal", "equal"])
def test_vectorized_alias_build_reproduces_the_pmf_for_a_million_bins(kind):
    rng = np.random.default_rng(6)
    n = 1_000_000
    w = {"uniform01": lambda: rng.random(n),
         "sparse_cubed": lambda: rng.random(n) ** 3 * (rng.random(n) < 0.7),
         "pareto": lambda: rng.pareto(1.0, n),
         "lognormal": lambda: np.exp(rng.normal(0.0, 5.0, n)),
         "equal": lambda: np.ones(n)}[kind]()
    dist = AliasTable(w)
    np.testing.assert_allclose(dist.pmf_table, w / w.sum(), rtol=1e-12)
    rec = _reconstructed_pmf(dist.prob, dist.alias, n)
    np.testing.assert_allclose(rec, dist.pmf_table, rtol=0, atol=1e-12)
    assert np.all((dist.prob >= 0) & (dist.prob <= 1))
    assert np.all(dist.prob[w == 0] == 0), "a zero-weight bin keeps part of its column"
    assert np.all(w[dist.alias] > 0), "a column is aliased to a zero-weight bin"


@pytest.mark.parametrize("weights", [[1.0, 1.0, 1.0, 3.0], [3.0, 1.0, 1.0, 1.0],
                                     [2.0, 0.0, 2.0, 0.0, 0.0, 2.0], [5.0, 1.0, 1.0, 1.0, 0.0]],
                         ids=["heavy_last", "heavy_first", "ties", "exact_multiples"])
def test_alias_build_is_exact_when_surpluses_end_exactly_on_deficits(weights):
    # Integer-like weights make running sums of surpluses and deficits tie exactly: the sweep
    # must then alias the next light bin to the next heavy bin (no overshoot is invented).
    w = np.asarray(weights)
    dist = AliasTable(w)
    np.testing.assert_allclose(_reconstructed_pmf(dist.prob, dist.alias, w.size), w / w.sum(),
                               rtol=0, atol=1e-15)


def test_alias_rows_are_built_at_once_and_stay_inside_their_rows():
    rng = np.random.default_rng(7)
    lengths = rng.integers(1, 300, 2000)
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    w = rng.pareto(1.5, offsets[-1]) * (rng.random(offsets[-1]) < 0.8)
    w[offsets[5]:offsets[6]] = 0.0  # an empty segment: uniform
    prob, alias, pmf = build_alias_segments(w, offsets)
    seg = np.repeat(np.arange(lengths.size), lengths)
    assert np.all(seg[alias] == seg), "an alias points into another segment"
    rec = _reconstructed_pmf(prob, alias, lengths[seg].astype(np.float64))
    np.testing.assert_allclose(rec, pmf, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.add.reduceat(pmf, offsets[:-1]), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(pmf[offsets[5]:offsets[6]], 1.0 / lengths[5], rtol=1e-15)


def test_alias_build_handles_scaled_weights_that_all_round_below_one():
    # Weights whose scaled values are 1 - eps everywhere: no bin is heavy by comparison.
    w = np.full(7, 1.0 / 7.0)
    dist = AliasTable(w)
    np.testing.assert_allclose(_reconstructed_pmf(dist.prob, dist.alias, 7), 1.0 / 7.0,
                               rtol=0, atol=1e-15)


# --------------------------------------------------------------------------------------------
# Segmented distributions and the factory
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("method", METHODS)
def test_segmented_choices_stay_in_their_segment_and_follow_its_pmf(method):
    rng = np.random.default_rng(8)
    offsets = np.array([0, 1, 10, 11, 60, 200])
    w = rng.random(200) ** 2 * (rng.random(200) < 0.6)
    w[[0, 10]] = [2.0, 3.0]  # the single-element segments have mass
    dist = Segmented1D(w, offsets, method)
    segment = rng.integers(0, offsets.size - 1, N)
    index, pmf, ur = dist.sample(segment, rng.random(N))
    assert np.all((index >= offsets[segment]) & (index < offsets[segment + 1]))
    np.testing.assert_array_equal(pmf, dist.pmf(index))
    for s in range(offsets.size - 1):
        sel = segment == s
        local = w[offsets[s]:offsets[s + 1]]
        chi_square_test(index[sel] - offsets[s], local / local.sum(),
                        what=f"{method} segment {s}")
    ks_uniform_test(ur, what=f"{method} segmented u_remapped")


def test_segmented_cdf_never_chooses_empty_elements_even_at_cdf_boundaries():
    w = np.array([0.0, 1.0, 0.0, 0.0, 2.0, 0.0, 3.0, 1.0, 0.0])
    offsets = np.array([0, 6, 9])
    dist = Segmented1D(w, offsets, "cdf")
    seg = np.repeat([0, 1], dist.cdf.size)
    u = np.concatenate([dist.cdf, dist.cdf])
    u = np.concatenate([u, np.nextafter(u, 0.0), np.nextafter(u, 1.0)])
    seg = np.tile(seg, 3)
    ok = (u >= 0.0) & (u < 1.0)
    index, pmf, _ = dist.sample(seg[ok], u[ok])
    assert np.all(w[index] > 0) and np.all(pmf > 0)


def test_one_segment_samples_exactly_as_the_bisection_of_many_segments():
    """A one-segment Segmented1D (one emissive mesh) searches with np.searchsorted; the same
    weights as segment 0 of a two-segment one (searched by bisection) must give the same
    index, pmf and remapped u, bit for bit, at CDF boundaries and next to them too."""
    w = np.array([0.0, 1.0, 0.0, 0.0, 2.0, 0.0, 3.0, 1e-9, 0.0, 5.0])
    one = Segmented1D(w, np.array([0, w.size]), "cdf")
    two = Segmented1D(np.concatenate([w, [1.0, 2.0]]), np.array([0, w.size, w.size + 2]), "cdf")
    u = np.concatenate([one.cdf, np.nextafter(one.cdf, 0.0), np.nextafter(one.cdf, 1.0),
                        np.random.default_rng(3).random(5000)])
    u = u[(u >= 0.0) & (u < 1.0)]
    zeros = np.zeros(u.size, np.int64)
    for a, b in zip(one.sample(zeros, u), two.sample(zeros, u)):
        np.testing.assert_array_equal(a, b)
    assert one.sample(zeros, u)[0].max() == w.size - 1


def test_search_right_is_a_batched_searchsorted():
    rng = np.random.default_rng(9)
    values = np.sort(rng.integers(0, 20, 500)).astype(np.float64)
    lo = rng.integers(0, 500, 2000)
    hi = np.minimum(lo + rng.integers(0, 80, 2000), 500)
    x = rng.uniform(-1, 21, 2000)
    expected = np.array([l + np.searchsorted(values[l:h], v, side="right")
                         for l, h, v in zip(lo, hi, x)])
    np.testing.assert_array_equal(search_right(values, lo, hi, x), expected)


def test_make_distribution_builds_each_method_and_rejects_unknown_ones():
    w = np.array([1.0, 0.0, 3.0])
    assert isinstance(make_distribution(w, "cdf"), PiecewiseConstant1D)
    assert isinstance(make_distribution(w, "alias"), AliasTable)
    for method in METHODS:
        np.testing.assert_allclose(make_distribution(w, method).pmf_table, [0.25, 0.0, 0.75])
    with pytest.raises(ValueError, match="distribution method"):
        make_distribution(w, "inversion")
    with pytest.raises(ValueError):
        Segmented1D(w, [0, 0, 3])
