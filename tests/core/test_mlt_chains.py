"""Primary sample space (``core/sampling/primary_space.py``): Kelemen's small step is a
symmetric warp that stays in [0, 1); Metropolis chains over a toy integrand of known shape
visit it in proportion to ``f / integral f``; the bootstrap normalisation ``b`` is unbiased; and
the whole estimator (bootstrap, resampled starts, chains, expected-value splats) averages to
the integral over seeds."""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core.sampling import primary_space as ps
from tests.helpers import assert_mean_within_ci, chi_square_2d, chi_square_counts

DIMS = 4  # the toy's vectors: two numbers it reads, two it ignores (as paths ignore theirs)
INTEGRAL = 1.5


def toy_f(u):
    """``(0.5 + x) g``, ``x = u_0``: ``g = 1 + 2 [u_3 < 1/4]`` where ``x > 1/2`` (such "paths"
    read dimension 3), ``g = 1.5`` (its mean) elsewhere (they end before it); integral 1.5."""
    x = u[:, 0]
    g = np.full(x.shape, 1.5)
    far = x > 0.5
    g[far] = 1.0 + 2.0 * (u[far, 3] < 0.25)
    return (0.5 + x) * g


def toy_density(xy):
    """Density of ``(u_0, u_3)`` under ``f / 1.5``."""
    return toy_f(np.stack([xy[:, 0], xy[:, 0], xy[:, 0], xy[:, 1]], axis=1)) / INTEGRAL


def toy_evaluate(u, grow=None, bins=4):
    """Grey contribution ``f`` (luminance ``f``) and its cell in a ``bins x bins`` grid of
    ``(u_0, u_3)``. Vectors with fewer than four dimensions grow when a row reads dimension 3
    (as paths grow them when they bounce further than any path before)."""
    if u.shape[1] < DIMS and (u[:, 0] > 0.5).any():
        u = grow(DIMS)
    y = u[:, 3] if u.shape[1] >= DIMS else np.zeros(len(u))
    f = toy_f(np.stack([u[:, 0], u[:, 0], u[:, 0], y], axis=1))
    cell = (np.minimum((u[:, 0] * bins).astype(np.int64), bins - 1) * bins
            + np.minimum((y * bins).astype(np.int64), bins - 1))
    return np.repeat(f[:, None], 3, axis=1), cell


def cell_integrals(bins=4, fine=64):
    """``integral of f`` over each cell of :func:`toy_evaluate`: midpoints of a 64 x 64 grid,
    exact (f is linear in x and constant in y between grid lines)."""
    mid = (np.arange(fine) + 0.5) / fine
    xy = np.stack(np.meshgrid(mid, mid, indexing="ij"), axis=-1).reshape(-1, 2)
    f = toy_density(xy) * INTEGRAL / fine ** 2
    cell = (xy[:, 0] * bins).astype(int) * bins + (xy[:, 1] * bins).astype(int)
    return np.bincount(cell, f, minlength=bins * bins)


def test_small_step_density_is_exactly_symmetric_and_steps_stay_in_the_unit_interval():
    """Exact: ``pdf(u -> v) == pdf(v -> u)`` bit for bit, on random pairs within a step and
    across the wrap-around, and every step of the extreme inputs lands in [0, 1)."""
    rng = np.random.default_rng(1)
    u = np.concatenate([rng.random(20000), [0.0, 1e-300, 0.5, np.nextafter(1.0, 0.0)]])
    v = ps._wrap(u + rng.uniform(-1.5 * ps.S2, 1.5 * ps.S2, u.size))
    forward, backward = ps.small_step_pdf(u, v), ps.small_step_pdf(v, u)
    assert np.array_equal(forward, backward)
    assert (forward > 0).mean() > 0.5  # most pairs are reachable: the check is not vacuous
    extremes = np.array([0.0, 5e-324, 1e-17, ps.S1, 0.5, 1.0 - ps.S2, 1.0 - 1e-17,
                         np.nextafter(1.0, 0.0)])
    xis = np.array([0.0, 1e-17, 0.25, np.nextafter(0.5, 0.0), 0.5, 0.75,
                    np.nextafter(1.0, 0.0)])
    uu, xx = np.meshgrid(extremes, xis)
    moved = ps.sample_small_step(uu, xx)
    assert ((moved >= 0.0) & (moved < 1.0)).all()
    moved = ps.sample_small_step(u, rng.random(u.size))
    assert ((moved >= 0.0) & (moved < 1.0)).all()


def test_small_step_sample_matches_its_pdf_and_inverts():
    """Chi-square of the signed move against :func:`small_step_pdf` (64 cells of the move
    ``[-s2, s2]``, 200,000 steps, alpha 1e-3: a step-size law off by about 2 % of the mass of a
    busy cell fails), and sample -> invert returns the uniform number it came from."""
    rng = np.random.default_rng(2)
    n = 200_000
    u = rng.random(n)
    xi = rng.random(n)
    v = ps.sample_small_step(u, xi)
    move = v - u
    move = np.where(move > 0.5, move - 1.0, np.where(move < -0.5, move + 1.0, move))
    edges = np.linspace(-ps.S2, ps.S2, 65)
    counts, _ = np.histogram(move, edges)
    fine = np.linspace(-ps.S2, ps.S2, 64 * 512 + 1)
    mid = 0.5 * (fine[1:] + fine[:-1])
    mass = (ps.small_step_pdf(0.5, 0.5 + mid) * np.diff(fine)).reshape(64, 512).sum(axis=1)
    assert abs(mass.sum() - 1.0) < 2e-3
    chi_square_counts(counts, n * mass / mass.sum(), what="small-step moves")
    back = ps.invert_small_step(u, v)
    np.testing.assert_allclose(back, xi, atol=1e-9)


def _run_chains(n_chains, steps, seed):
    """Chains from starts with ``u_0 < 1/2`` (which read two dimensions: the chains store
    two), ``steps`` mutations each; their final states ``(n, 2)`` of ``(u_0, u_3)``. The
    first proposal past ``u_0 = 1/2`` grows every chain to four dimensions
    (:meth:`Chains.proposal_columns`), so the growth is checked too."""
    rng = np.random.default_rng(seed)
    u = rng.random((n_chains, 2)) * [0.5, 1.0]
    L, cell = toy_evaluate(u)
    chains = ps.Chains(u, L, cell)
    for _ in range(steps):
        ps.metropolis_step(chains, toy_evaluate, rng, 0.3)
    assert chains.width == DIMS
    return chains.u[:, [0, 3]]


def test_chain_states_are_distributed_as_f_over_its_integral(monkeypatch):
    """20,000 independent chains, 120 mutations each from starts in the left half: their final
    states are independent draws, and after 120 steps their law is ``f / 1.5`` up to
    0.9^120 < 1e-5 (a large step is accepted with probability >= 0.3 x 1.5 / 4.5 from any
    state). Chi-square
    on 16 x 16 cells, alpha 1e-3. The same checker rejects chains that accept with
    ``sqrt(f' / f)`` (stationary law ``sqrt f``): a relative error of 10-30 % per cell."""
    points = _run_chains(20_000, 120, seed=3)
    chi_square_2d(points, toy_density, ((0, 1), (0, 1)), what="chain states")
    monkeypatch.setattr(ps, "acceptance",
                        lambda f, g: np.minimum(1.0, np.sqrt(g / np.maximum(f, 1e-300))))
    wrong = _run_chains(20_000, 120, seed=3)
    with pytest.raises(AssertionError):
        chi_square_2d(wrong, toy_density, ((0, 1), (0, 1)), what="sqrt-acceptance chains")


def test_bootstrap_normalisation_is_unbiased():
    """``b`` of 400 seeds of 500 uniform vectors each, against ``integral f = 1.5``: mean within
    its Student-t interval (p_false 1e-4). The standard error of that mean is 0.13 % of b: a
    bias of 0.8 % fails with 99 % power. The reported standard error matches the spread of b
    over seeds (within 20 %, far outside the fluctuation of 400 samples' spread, about 4 %).
    """
    bs, ses = [], []
    for seed in range(400):
        f = toy_f(ps.uniform_vectors(seed, np.arange(500), DIMS))
        b, se = ps.normalisation(f)
        bs.append(b)
        ses.append(se)
    assert_mean_within_ci(np.array(bs), INTEGRAL, what="bootstrap b")
    spread = np.std(bs, ddof=1)
    assert 0.8 < np.mean(ses) / spread < 1.25


def _estimate(seed, n_boot=400, n_chains=64, steps=20):
    """One run of the whole estimator on the toy, as MLT runs it (bootstrap vectors stored
    with two dimensions and grown by their hash when read further, chains rebuilt from the
    picks' indices): per-cell ``b * splats / mutations``."""
    index = np.arange(n_boot)
    vectors = [ps.uniform_vectors(seed, index, 2)]

    def grow(w):
        vectors.append(np.concatenate(
            [vectors[-1], ps.uniform_vectors(seed, index, w - 2, first=2)], axis=1))
        return vectors[-1]

    L, cell = toy_evaluate(vectors[0], grow)
    f = ps.luminance(L)
    b, _ = ps.normalisation(f)
    picks = ps.resample(f, n_chains, ps.chain_random(seed, 7))
    width = vectors[-1].shape[1]
    chains = ps.Chains(ps.uniform_vectors(seed, picks, width), L[picks], cell[picks])
    rng = ps.chain_random(seed, 8)
    sums = np.zeros(16)
    for _ in range(steps):
        keys, values = ps.metropolis_step(chains, toy_evaluate, rng, 0.3)
        sums += np.bincount(keys, values[:, 1], minlength=16)
    return b * sums / (n_chains * steps)


def test_bootstrap_started_chains_estimate_each_cell_without_bias():
    """The estimator as MLT runs it (b and the resampled starts from one bootstrap of 400,
    64 chains x 20 mutations, expected-value splats): over 300 seeds every cell's mean, and
    their total, is its integral within Student-t intervals (Bonferroni over 17 means,
    p_false 1e-4). Standard errors: 1.2-1.8 % per cell, 0.17 % for the total, so a bias of
    9-13 % in one cell fails with 99 % power, and a b off by 1.2 % (every cell at once, seen
    in the total) too; the b off by 5 % below must fail."""
    runs = np.array([_estimate(seed) for seed in range(300)])
    runs = np.concatenate([runs, runs.sum(axis=1, keepdims=True)], axis=1)
    expected = np.append(cell_integrals(), INTEGRAL)
    assert_mean_within_ci(runs, expected, what="toy MLT cells")
    with pytest.raises(AssertionError):
        assert_mean_within_ci(runs * 1.05, expected, what="b off by 5 %")
