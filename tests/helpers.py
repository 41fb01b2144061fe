"""Shared statistical checkers for the test suite.

Every tolerance here comes from a stated false-failure probability, never from tuning until a
test passes:

- chi-square goodness-of-fit tests (:func:`chi_square_test`, :func:`chi_square_2d`,
  :func:`chi_square_directions`) fail when the p-value is at most ``alpha``; cells with small
  expected counts are pooled (as pbrt's and Mitsuba's ``chi2`` tests do) so the chi-square
  approximation holds, and a sample in a cell of expected count zero fails at once;
- confidence-interval checks (:func:`assert_mean_within_ci`, :func:`assert_estimates_agree`)
  fail when any of ``m`` compared means lies outside its interval, where the interval's
  quantile is chosen so that all ``m`` pass with probability at least ``1 - p_false`` when the
  estimator is right (Bonferroni: each comparison gets ``p_false / m``).

All tests seed their generators, so a run is reproducible; ``alpha`` / ``p_false`` is the chance
that a *correct* implementation fails for a fresh seed. Tests that use a checker should also
show that it can fail (a wrong pdf must be rejected at the same sample count).

The image checkers (:func:`assert_images_agree`, :func:`assert_two_images_agree`,
:func:`assert_replicates_agree`) also bound the other error, a *wrong* image that passes: from
the standard errors of the comparison they compute the smallest scale error that they detect
with probability :data:`POWER` (99 %), for the image mean (every channel) and for each 8 x 8
block (its RGB scaled; blocks darker than :data:`DARK_BLOCK` of the image are left out of the
figure, though still compared), and fail a test whose images cannot detect the errors it
asks for (``detect=(image_mean, block)``, by default :data:`DETECT`: 2 % and 5 %). So an
agreement test states the smallest error it detects, and a change of scene or sample count that
makes it blind fails instead of passing quietly. ``tests/core/test_checkers.py`` feeds every
checker wrong images (scaled by 1.02, 1.05, 1.10, a missing bounce, a shifted image).

The special functions (chi-square tail, normal and t quantiles) come from
:mod:`sampling_lab.core.metrics`, so the suite does not need SciPy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from sampling_lab.core.metrics import block_means, chi2_sf, normal_quantile, student_t_quantile
from sampling_lab.core.render import RenderSettings

# Render settings whose pixel samples are independent: the independent sampler (a pixel's
# variance then estimates the error of its mean, which the confidence intervals below rely on;
# a low-discrepancy sampler's samples are correlated) and power light selection (the tests
# written before the light tree became the default keep the estimator they were written for).
PLAIN = dict(sampler="independent", light_selection="power")

# Bounce limits the tests were written for: 8 in all, every per-kind limit (diffuse, glossy,
# transmission, transparent) equal to the total, as tools/blender_scene.configure_cycles sets
# Cycles up. The closed forms count every bounce alike; the per-kind limits have tests of their
# own (tests/core/test_bounce_limits.py).
TEST_BOUNCES = 8
PER_KIND_BOUNCES = ("diffuse_bounces", "glossy_bounces", "transmission_bounces",
                    "transparent_max_bounces")


def uniform_bounces(kw):
    """``kw`` with ``max_bounces`` (default :data:`TEST_BOUNCES`) and every per-kind limit it
    does not set equal to that total."""
    kw = dict(kw)
    total = kw.setdefault("max_bounces", TEST_BOUNCES)
    for name in PER_KIND_BOUNCES:
        kw.setdefault(name, total)
    return kw


def plain_settings(**kw):
    """``RenderSettings`` with :data:`PLAIN` and :func:`uniform_bounces` unless ``kw`` says
    otherwise."""
    return RenderSettings(**uniform_bounces({**PLAIN, **kw}))

TWO_PI = 2.0 * np.pi

POWER = 0.99
"""Probability with which an agreement check must detect the errors it is sized for."""

DETECT = (0.02, 0.05)
"""Default ``(image_mean, block)`` relative errors every image agreement check must detect."""

DARK_BLOCK = 0.05
"""Blocks whose mean (summed over channels) is below this fraction of the image's are not held
to the block target: 5 % of such a block is under 0.25 % of the image mean."""


# --------------------------------------------------------------------------------------------
# Chi-square goodness of fit
# --------------------------------------------------------------------------------------------


def chi_square_counts(observed, expected, min_expected=5.0, alpha=1e-3, what="samples"):
    """Chi-square test of observed cell counts against expected counts; assert ``p > alpha``.

    Cells with ``expected == 0`` must be empty. Cells with ``expected < min_expected`` are
    pooled, smallest first, into one cell; the pool also takes the next smallest cells until its
    expectation reaches ``min_expected`` (Mitsuba's and pbrt's rule).

    Parameters
    ----------
    observed : (k,) int
        Counts per cell.
    expected : (k,) float
        Expected counts per cell (``n * probability``).
    min_expected : float
        Smallest expected count a cell may have on its own.
    alpha : float
        Significance level: the probability that a correct sampler fails this test.
    what : str
        Name of the tested thing, for the failure message.

    Returns
    -------
    p_value : float
    """
    observed = np.asarray(observed, np.float64).reshape(-1)
    expected = np.asarray(expected, np.float64).reshape(-1)
    if observed.shape != expected.shape:
        raise ValueError("observed and expected differ in length")
    if np.any(expected < 0) or not np.all(np.isfinite(expected)):
        raise ValueError("expected counts must be finite and non-negative")
    impossible = (expected == 0) & (observed > 0)
    assert not np.any(impossible), (
        f"{what}: {int(observed[impossible].sum())} samples fell in "
        f"{int(impossible.sum())} cells of probability zero, e.g. cells "
        f"{np.flatnonzero(impossible)[:8].tolist()}"
    )
    live = np.flatnonzero(expected > 0)
    order = live[np.argsort(expected[live], kind="stable")]
    e = expected[order]
    o = observed[order]
    n_small = int(np.count_nonzero(e < min_expected))
    if n_small:
        # Pool all small cells, plus as many next-smallest as the pool needs to reach the minimum.
        running = np.cumsum(e)
        need = max(n_small, int(np.searchsorted(running, min_expected, side="left")) + 1)
        if need > e.size:
            raise ValueError(
                f"{what}: total expected count {running[-1]:.3g} is below min_expected; "
                "use more samples"
            )
        e = np.concatenate([[running[need - 1]], e[need:]])
        o = np.concatenate([[o[:need].sum()], o[need:]])
    dof = e.size - 1
    if dof == 0:
        return 1.0
    stat = float(np.sum((o - e) ** 2 / e))
    p = chi2_sf(stat, dof)
    if not p > alpha:
        contrib = np.zeros_like(expected)
        contrib[live] = (observed[live] - expected[live]) ** 2 / expected[live]
        worst = np.argsort(contrib)[::-1][:6]
        cells = ", ".join(
            f"#{i}: observed {observed[i]:.0f} expected {expected[i]:.1f}" for i in worst
        )
        raise AssertionError(
            f"{what}: chi-square {stat:.1f} with {dof} dof, p = {p:.3g} <= alpha = {alpha:g}; "
            f"largest deviations {cells}"
        )
    return p


def chi_square_test(samples_idx, expected_probs, min_expected=5.0, alpha=1e-3, mass_tol=1e-9,
                    what="samples"):
    """Chi-square test of sampled cell indices against their probabilities; assert ``p > alpha``.

    Parameters
    ----------
    samples_idx : (n,) int
        Chosen cells, each in ``[0, k)``.
    expected_probs : (k,) float
        Probability of each cell; must sum to one within ``mass_tol``.
    min_expected, alpha, what
        As in :func:`chi_square_counts`.
    mass_tol : float
        Allowed ``|sum(expected_probs) - 1|``.

    Returns
    -------
    p_value : float
    """
    probs = np.asarray(expected_probs, np.float64).reshape(-1)
    idx = np.asarray(samples_idx).reshape(-1)
    if not np.issubdtype(idx.dtype, np.integer):
        raise TypeError(f"samples_idx must be integers, got {idx.dtype}")
    assert np.all(probs >= 0), f"{what}: negative probabilities"
    assert abs(probs.sum() - 1.0) <= mass_tol, f"{what}: probabilities sum to {probs.sum()!r}"
    assert idx.size > 0 and idx.min() >= 0 and idx.max() < probs.size, (
        f"{what}: sampled indices outside [0, {probs.size})"
    )
    observed = np.bincount(idx, minlength=probs.size)
    return chi_square_counts(observed, idx.size * probs, min_expected, alpha, what)


def histogram_2d(points, bounds, res, edge_tol=1e-12):
    """Counts of 2-D points in a regular grid of cells.

    Parameters
    ----------
    points : (n, 2) float
    bounds : ((x0, x1), (y0, y1))
        Closed domain; points within ``edge_tol`` (relative to the extent) outside it are
        counted in the edge cells, to forgive rounding.
    res : (nx, ny)

    Returns
    -------
    counts : (nx, ny) int64
    outside : int
        Number of points outside the domain.
    """
    pts = np.asarray(points, np.float64)
    (x0, x1), (y0, y1) = bounds
    nx, ny = res
    fx = (pts[:, 0] - x0) / (x1 - x0)
    fy = (pts[:, 1] - y0) / (y1 - y0)
    inside = (fx >= -edge_tol) & (fx <= 1 + edge_tol) & (fy >= -edge_tol) & (fy <= 1 + edge_tol)
    ix = np.clip((fx[inside] * nx).astype(np.int64), 0, nx - 1)
    iy = np.clip((fy[inside] * ny).astype(np.int64), 0, ny - 1)
    counts = np.bincount(ix * ny + iy, minlength=nx * ny).reshape(nx, ny)
    return counts, int(np.count_nonzero(~inside))


def integrate_density_2d(density_fn, bounds, res, subdiv=8):
    """Integral of a density over each cell of a regular grid (midpoint rule on a sub-grid).

    Parameters
    ----------
    density_fn : callable, (m, 2) float -> (m,) float
        Density with respect to ``dx dy`` of the grid's coordinates.
    bounds : ((x0, x1), (y0, y1))
    res : (nx, ny)
    subdiv : int
        Sub-cells per cell side.

    Returns
    -------
    (nx, ny) float64
        Probability mass of each cell.
    """
    (x0, x1), (y0, y1) = bounds
    nx, ny = res
    mx, my = nx * subdiv, ny * subdiv
    xs = x0 + (np.arange(mx) + 0.5) * ((x1 - x0) / mx)
    ys = y0 + (np.arange(my) + 0.5) * ((y1 - y0) / my)
    grid = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)
    dens = np.asarray(density_fn(grid), np.float64).reshape(mx, my)
    cell = (x1 - x0) * (y1 - y0) / (mx * my)
    return dens.reshape(nx, subdiv, ny, subdiv).sum(axis=(1, 3)) * cell


def chi_square_2d(points, density_fn, bounds, res=(16, 16), subdiv=8, min_expected=5.0,
                  alpha=1e-3, mass_tol=1e-3, what="samples"):
    """Chi-square test of 2-D points against a density over a rectangular domain.

    Parameters
    ----------
    points : (n, 2) float
        Samples; all must lie in ``bounds``.
    density_fn : callable, (m, 2) float -> (m,) float
        The claimed density with respect to ``dx dy``; it must integrate to one over
        ``bounds`` within ``mass_tol`` (a wrong normalisation fails here).
    bounds : ((x0, x1), (y0, y1))
    res : (nx, ny)
        Histogram cells.
    subdiv : int
        Quadrature sub-cells per cell side (see :func:`integrate_density_2d`).
    min_expected, alpha, what
        As in :func:`chi_square_counts`.
    mass_tol : float
        Allowed deviation of the density's total mass from one (quadrature error).

    Returns
    -------
    p_value : float
    """
    pts = np.asarray(points, np.float64)
    assert np.all(np.isfinite(pts)), f"{what}: non-finite samples"
    counts, outside = histogram_2d(pts, bounds, res)
    assert outside == 0, f"{what}: {outside} of {len(pts)} samples outside the domain {bounds}"
    mass = integrate_density_2d(density_fn, bounds, res, subdiv)
    assert np.all(np.isfinite(mass)) and np.all(mass >= 0), f"{what}: invalid density values"
    assert abs(mass.sum() - 1.0) <= mass_tol, (
        f"{what}: density integrates to {mass.sum():.6f} over the domain, not 1"
    )
    return chi_square_counts(counts.reshape(-1), len(pts) * mass.reshape(-1), min_expected,
                             alpha, what)


def directions_from_z_phi(zp):
    """Unit vectors from ``(cos theta, phi)`` pairs. ``zp : (m, 2)`` -> ``(m, 3)``."""
    z = np.clip(zp[:, 0], -1.0, 1.0)
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    return np.stack([r * np.cos(zp[:, 1]), r * np.sin(zp[:, 1]), z], axis=-1)


def z_phi_from_directions(w):
    """``(cos theta, phi in [0, 2 pi))`` of unit vectors. ``w : (n, 3)`` -> ``(n, 2)``."""
    phi = np.arctan2(w[:, 1], w[:, 0])
    phi = np.where(phi < 0, phi + TWO_PI, phi)
    return np.stack([w[:, 2], phi], axis=-1)


def integrate_solid_angle(pdf_fn, z_range=(-1.0, 1.0), res=(256, 256)):
    """Integral of a solid-angle density over a zone ``z0 <= cos theta <= z1`` of the sphere.

    Midpoint rule in ``(cos theta, phi)``, where ``d omega = d(cos theta) d phi``.

    Parameters
    ----------
    pdf_fn : callable, (m, 3) float -> (m,) float
    z_range : (z0, z1)
    res : (nz, nphi)

    Returns
    -------
    float
    """
    mass = integrate_density_2d(lambda zp: pdf_fn(directions_from_z_phi(zp)),
                                (z_range, (0.0, TWO_PI)), res, subdiv=1)
    return float(mass.sum())


def chi_square_directions(sample_fn, pdf_fn, n=200_000, res=(16, 32), z_range=(-1.0, 1.0),
                          subdiv=8, seed=0, min_expected=5.0, alpha=1e-3, mass_tol=1e-3,
                          what="directions"):
    """Chi-square test of a direction sampler against its solid-angle pdf (Mitsuba's ``chi2``).

    Draws ``u`` uniform in [0, 1)^2, maps it with ``sample_fn``, and histograms the directions
    in ``(cos theta, phi)`` cells, whose solid angle is ``d(cos theta) d phi``, so the expected
    count of a cell is ``n`` times the integral of ``pdf_fn`` over it (midpoint rule on a
    ``subdiv`` x ``subdiv`` sub-grid). Equal-width ``cos theta`` bins have equal solid angle.

    Parameters
    ----------
    sample_fn : callable, (n, 2) float -> (n, 3) float
        The warp; must return unit vectors.
    pdf_fn : callable, (m, 3) float -> (m,) float
        Its claimed density per steradian (zero outside the support).
    n : int
        Sample count.
    res : (nz, nphi)
        Cells in ``cos theta`` and ``phi``.
    z_range : (z0, z1)
        The zone of the sphere that holds the support (a cone uses ``(cos_max, 1)`` for
        resolution); every sample must lie in it.
    subdiv, min_expected, alpha, mass_tol, what
        As in :func:`chi_square_2d`.
    seed : int

    Returns
    -------
    p_value : float
    """
    rng = np.random.default_rng(seed)
    w = np.asarray(sample_fn(rng.random((n, 2))), np.float64)
    assert w.shape == (n, 3), f"{what}: sampler returned shape {w.shape}, expected {(n, 3)}"
    assert np.all(np.isfinite(w)), f"{what}: non-finite directions"
    length_err = np.abs(np.linalg.norm(w, axis=1) - 1.0).max()
    assert length_err < 1e-6, f"{what}: directions not unit length (error {length_err:.2g})"
    return chi_square_2d(
        z_phi_from_directions(w),
        lambda zp: pdf_fn(directions_from_z_phi(zp)),
        (tuple(z_range), (0.0, TWO_PI)),
        res, subdiv, min_expected, alpha, mass_tol, what,
    )


def chi_square_uniform_square(u, res=(16, 16), alpha=1e-3, what="points"):
    """Chi-square test that 2-D points are uniform on the unit square. ``u : (n, 2)``."""
    return chi_square_2d(u, lambda p: np.ones(len(p)), ((0.0, 1.0), (0.0, 1.0)), res,
                         subdiv=1, alpha=alpha, what=what)


def ks_uniform_test(x, alpha=1e-3, what="values"):
    """One-sample Kolmogorov-Smirnov test that ``x`` is uniform on [0, 1); assert ``p > alpha``.

    The p-value uses Stephens' finite-n correction of the Kolmogorov distribution,
    ``Q_KS((sqrt(n) + 0.12 + 0.11 / sqrt(n)) D)``, accurate for n >= 35 or so.

    Parameters
    ----------
    x : (n,) float

    Returns
    -------
    p_value : float
    """
    x = np.sort(np.asarray(x, np.float64).reshape(-1))
    n = x.size
    assert n > 0 and x[0] >= 0.0 and x[-1] < 1.0, f"{what}: values outside [0, 1)"
    i = np.arange(1, n + 1)
    d = float(max(np.max(i / n - x), np.max(x - (i - 1) / n)))
    sn = math.sqrt(n)
    p = _kolmogorov_q((sn + 0.12 + 0.11 / sn) * d)
    assert p > alpha, f"{what}: KS statistic D = {d:.4g} (n = {n}), p = {p:.3g} <= {alpha:g}"
    return p


def _kolmogorov_q(lam):
    """Complementary CDF of the Kolmogorov distribution, ``P(K > lam)``."""
    if lam <= 0:
        return 1.0
    j = np.arange(1, 101, dtype=np.float64)
    if lam < 1.18:
        # Jacobi-theta form converges fast for small lambda.
        s = np.sum(np.exp(-((2 * j - 1) ** 2) * np.pi**2 / (8 * lam * lam)))
        return float(min(1.0, max(0.0, 1.0 - math.sqrt(2 * math.pi) / lam * s)))
    s = np.sum((-1.0) ** (j - 1) * np.exp(-2.0 * j * j * lam * lam))
    return float(min(1.0, max(0.0, 2.0 * s)))


# --------------------------------------------------------------------------------------------
# Confidence intervals
# --------------------------------------------------------------------------------------------


def z_for_false_failure(p_false=1e-4, comparisons=1):
    """Two-sided normal quantile for ``comparisons`` simultaneous checks (Bonferroni).

    With this ``z``, ``comparisons`` correct estimates all fall within ``z`` standard errors with
    probability at least ``1 - p_false``. E.g. ``p_false=1e-4, comparisons=1`` gives 3.89.

    Parameters
    ----------
    p_false : float
        Allowed probability that a correct implementation fails.
    comparisons : int
        Number of means checked together.

    Returns
    -------
    float
    """
    if not 0 < p_false < 1 or comparisons < 1:
        raise ValueError("need 0 < p_false < 1 and comparisons >= 1")
    return -normal_quantile(0.5 * p_false / comparisons)


def assert_mean_within_ci(samples, expected, p_false=1e-4, comparisons=None, axis=0,
                          rtol=1e-12, atol=0.0, what="mean"):
    """Assert that sample means match ``expected`` within confidence intervals.

    The interval is ``q * s / sqrt(n)`` with ``s`` the sample standard deviation and ``q`` the
    Student-t quantile (``n - 1`` dof) at two-sided level ``p_false / comparisons``. That is exact
    for normal samples and relies on the central limit theorem otherwise, so use many samples
    (or block means) for skewed or heavy-tailed estimators. ``rtol`` only absorbs floating-point
    rounding when the samples are constant.

    Parameters
    ----------
    samples : (n, ...) float
        Independent samples along ``axis``; n >= 2.
    expected : float or (...) float
        Exact values, broadcast against the means.
    p_false : float
        Allowed probability that a correct estimator fails this call.
    comparisons : int, optional
        Number of simultaneous comparisons for the Bonferroni correction; default the number of
        means checked in this call.
    axis : int
    rtol, atol : float
        Rounding slack added to the interval.

    Returns
    -------
    mean, stderr : float or (...) float64
    """
    x = np.asarray(samples, np.float64)
    n = x.shape[axis]
    if n < 2:
        raise ValueError("a confidence interval needs at least two samples")
    mean = x.mean(axis=axis)
    se = x.std(axis=axis, ddof=1) / math.sqrt(n)
    exp = np.broadcast_to(np.asarray(expected, np.float64), mean.shape)
    m = int(comparisons) if comparisons is not None else max(1, mean.size)
    q = -student_t_quantile(0.5 * p_false / m, n - 1)
    _assert_within(mean, exp, q * se, rtol, atol, what, f"t={q:.3g}, n={n}, m={m}")
    return (float(mean), float(se)) if mean.ndim == 0 else (mean, se)


def assert_estimates_agree(mean_a, se_a, mean_b, se_b, p_false=1e-4, comparisons=None,
                           rtol=1e-12, atol=0.0, what="estimates"):
    """Assert that two independent estimates agree within their combined standard error.

    ``|a - b| <= z * sqrt(se_a**2 + se_b**2)`` elementwise, ``z`` from
    :func:`z_for_false_failure` over all compared elements (normal approximation: the standard
    errors should come from many samples, e.g. block means of two renders).

    Parameters
    ----------
    mean_a, se_a, mean_b, se_b : float or (...) float
        Estimates and their standard errors (broadcast together).
    p_false, comparisons, rtol, atol, what
        As in :func:`assert_mean_within_ci`.

    Returns
    -------
    z_scores : (...) float64
        ``(a - b) / sqrt(se_a**2 + se_b**2)``.
    """
    a, sa, b, sb = np.broadcast_arrays(*(np.asarray(v, np.float64)
                                         for v in (mean_a, se_a, mean_b, se_b)))
    if np.any(sa < 0) or np.any(sb < 0):
        raise ValueError("standard errors must be non-negative")
    se = np.sqrt(sa * sa + sb * sb)
    m = int(comparisons) if comparisons is not None else max(1, a.size)
    z = z_for_false_failure(p_false, m)
    _assert_within(a, b, z * se, rtol, atol, what, f"z={z:.3g}, m={m}")
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(se > 0, (a - b) / se, 0.0)


def assert_samples_agree(samples_a, samples_b, p_false=1e-4, comparisons=None, axis=0,
                         what="samples"):
    """Assert that two independent sample sets have the same means (Welch-style z test).

    Parameters
    ----------
    samples_a : (n_a, ...) float
    samples_b : (n_b, ...) float
        Independent samples along ``axis``; the other axes must match.
    p_false, comparisons, axis, what
        As in :func:`assert_mean_within_ci`.

    Returns
    -------
    z_scores : (...) float64
    """
    a = np.asarray(samples_a, np.float64)
    b = np.asarray(samples_b, np.float64)
    sa = a.std(axis=axis, ddof=1) / math.sqrt(a.shape[axis])
    sb = b.std(axis=axis, ddof=1) / math.sqrt(b.shape[axis])
    return assert_estimates_agree(a.mean(axis=axis), sa, b.mean(axis=axis), sb, p_false,
                                  comparisons, what=what)


def block_estimates(img, var_of_mean, block=8):
    """Block means of an image and their standard errors, assuming independent pixels.

    Parameters
    ----------
    img : (h, w, c) float
        Per-pixel Monte Carlo means.
    var_of_mean : (h, w, c) float
        Variance of each pixel's mean (sample variance / sample count).
    block : int

    Returns
    -------
    means, stderrs : (h // block, w // block, c) float64
    """
    return block_means(img, block), np.sqrt(block_means(var_of_mean, block) / (block * block))


# --------------------------------------------------------------------------------------------
# Power: the smallest error an agreement check detects
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Detectable:
    """Smallest relative scale errors that a comparison detects with probability :data:`POWER`.

    Attributes
    ----------
    image_mean : float
        Of the whole image (the worst channel).
    block : float
        Of one block's RGB (each block's most precise channel, the worst block; blocks below
        :data:`DARK_BLOCK` of the image left out).
    """

    image_mean: float
    block: float


@dataclass(frozen=True)
class Agreement:
    """What an image agreement check found: the image-mean ratio and its power.

    Attributes
    ----------
    ratio : (c,) float64
        Image mean of A over image mean of B, per channel.
    detectable : Detectable
    """

    ratio: np.ndarray
    detectable: Detectable


@dataclass(frozen=True)
class Tier:
    """Size of an agreement test: the default run, or the full-power run of the slow tier.

    The default run states what it detects next to the test (and the checker asserts it); the
    slow tier (``pytest -m slow``) multiplies the test's sample counts (by the square of the
    ratio of its stated block error to 5 %) and must detect :data:`DETECT`.
    """

    full: bool


def power_tiers():
    """``pytest.param`` list: the default size, and the slow tier at full power."""
    return [pytest.param(Tier(False), id="fast"),
            pytest.param(Tier(True), id="full", marks=pytest.mark.slow)]


def smallest_detectable(se, reference, critical, power_quantile):
    """Relative shift ``d`` at which a two-sided test sees ``d * |reference|`` with the power.

    A test that flags ``|difference| > critical * se`` sees a shift ``delta`` with probability at
    least ``P(Z > critical - delta / se)``; that is the power whose quantile is
    ``power_quantile`` when ``delta = (critical + power_quantile) * se``.

    Parameters
    ----------
    se, reference : (...) float
        Standard error of the difference and the value it is relative to.
    critical : float
        The test's threshold in standard errors.
    power_quantile : float
        Quantile of the power (2.33 for 99 % under the normal approximation).

    Returns
    -------
    (...) float64
        ``inf`` where the reference is zero (no relative error is defined there).
    """
    se, ref = np.broadcast_arrays(np.asarray(se, np.float64), np.asarray(reference, np.float64))
    out = np.full(ref.shape, np.inf)
    np.divide((critical + power_quantile) * se, np.abs(ref), out=out, where=ref != 0)
    return out


def detectable_errors(se_image, ref_image, critical_image, q_image, se_blocks, ref_blocks,
                      critical_blocks, q_blocks):
    """:class:`Detectable` of an image comparison.

    Parameters
    ----------
    se_image, ref_image : (c,) float
        Standard error of the image-mean difference and the reference image mean.
    critical_image, q_image : float
        Threshold and power quantile of the image-mean test; the threshold may include a
        relative slack, added to the result by the caller.
    se_blocks, ref_blocks : (..., c) float
        The same per block.
    critical_blocks, q_blocks : float
    """
    ref_blocks = np.asarray(ref_blocks, np.float64)
    image = smallest_detectable(se_image, ref_image, critical_image, q_image).max()
    per_block = smallest_detectable(se_blocks, ref_blocks, critical_blocks, q_blocks).min(axis=-1)
    bright = np.abs(ref_blocks).sum(axis=-1) >= DARK_BLOCK * np.abs(np.sum(ref_image))
    block = per_block[bright].max() if bright.any() else 0.0
    return Detectable(float(image), float(block))


def require_detectable(found, detect, what, block=8):
    """Print what a comparison detects; assert it meets ``detect = (image_mean, block)``.

    ``detect=None`` only prints (for comparisons that are not agreement certificates).
    """
    print(f"{what}: detects {found.image_mean:.2%} image-mean and {found.block:.2%} "
          f"{block}x{block}-block errors with probability {POWER:.0%}")
    if detect is None:
        return found
    want_image, want_block = detect
    assert found.image_mean <= want_image and found.block <= want_block, (
        f"{what}: too few samples for this check to detect a {want_image:.0%} image-mean error "
        f"and a {want_block:.0%} error in a {block}x{block} block with probability {POWER:.0%}; "
        f"it detects {found.image_mean:.2%} and {found.block:.2%}: render more samples")
    return found


def _assert_within(value, target, half_width, rtol, atol, what, detail):
    tol = half_width + atol + rtol * np.abs(target)
    err = np.abs(value - target)
    bad = ~(err <= tol)
    if np.any(bad):
        flat = np.flatnonzero(bad.reshape(-1))
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = (err / np.where(tol > 0, tol, np.nan)).reshape(-1)
        worst = flat[np.argsort(np.nan_to_num(ratio[flat], nan=np.inf))[::-1][:5]]
        v, t, h = value.reshape(-1), target.reshape(-1), tol.reshape(-1)
        cells = "; ".join(f"[{i}] {v[i]:.6g} vs {t[i]:.6g} (+-{h[i]:.3g})" for i in worst)
        raise AssertionError(f"{what}: {flat.size} of {bad.size} outside the interval ({detail}): "
                             f"{cells}")


def assert_images_agree(mean_a, var_a, replicates_b, block=8, p_false=1e-4, mean_rtol=0.005,
                        detect=DETECT, what="images", block_rtol=1e-5):
    """Assert that two renderers' images of one scene agree: overall and block by block.

    Renderer A reports each pixel's estimate and the variance of that estimate (our Variance
    pass); renderer B (e.g. Cycles, which reports no variance) is rendered ``m`` times with
    different seeds. Checks

    1. the image mean per channel: ``|A - B| <= mean_rtol * |B|`` plus its confidence interval;
    2. every ``block x block`` block mean per channel: ``|A - B|`` within the confidence interval
       of the difference, Bonferroni-corrected over all blocks and channels.

    B's block variance is estimated from its replicates, pooled over blocks through the ratio to
    A's variance (B's and A's noise have the same shape when both are path tracers), and never
    taken below the block's own replicate estimate, which only widens the interval.

    The image means may differ by ``mean_rtol`` of B's beyond their interval: Cycles and we
    round differently in float32 (measured agreement 0.1-0.3 %), so a pure interval on a very
    precise image mean would flag rounding. The detectable image-mean error includes it.

    Parameters
    ----------
    mean_a, var_a : (h, w, c) float
    replicates_b : (m, h, w, c) float
        m >= 2 independent renders of B.
    detect : (float, float) or None
        Relative image-mean and block errors the comparison must detect (see
        :func:`require_detectable`).
    block_rtol : float
        Relative difference a block may show beyond its interval: by default float32
        rounding; a test that allows more states why (the detectable block error includes it).

    Returns
    -------
    Agreement
    """
    a = np.asarray(mean_a, np.float64)
    va = np.asarray(var_a, np.float64)
    reps = np.asarray(replicates_b, np.float64)
    m = reps.shape[0]
    if m < 2:
        raise ValueError("B needs at least two independent renders")
    h, w, c = a.shape
    hb, wb = h // block, w // block

    def blocks(img):
        img = img[..., : hb * block, : wb * block, :]
        shape = img.shape[:-3] + (hb, block, wb, block, c)
        return img.reshape(shape).mean(axis=(-4, -2))

    a_b = blocks(a)
    va_b = blocks(va) / block**2  # the mean of block^2 independent pixel estimates
    rep_b = blocks(reps)
    b_b = rep_b.mean(axis=0)
    vb_rep = rep_b.var(axis=0, ddof=1) / m
    ratio = vb_rep.sum(axis=(0, 1)) / np.maximum(va_b.sum(axis=(0, 1)), 1e-300)
    vb_b = np.maximum(ratio * va_b, vb_rep)

    # 1. Image means: B's variance of the image mean from its replicates' image means.
    img_a = a.mean(axis=(0, 1))
    img_b_reps = reps.mean(axis=(1, 2))
    img_b = img_b_reps.mean(axis=0)
    se = np.sqrt(va.sum(axis=(0, 1)) / (h * w) ** 2 + img_b_reps.var(axis=0, ddof=1) / m)
    z_image = z_for_false_failure(p_false, comparisons=c)
    tol = mean_rtol * np.abs(img_b) + z_image * se
    err = np.abs(img_a - img_b)
    assert (err <= tol).all(), (
        f"{what}: image means differ: A {img_a} vs B {img_b} (tolerance {tol}, of which "
        f"{mean_rtol:.1%} relative and {z_image:.2f} standard errors {se})")

    # 2. Block means.
    z = z_for_false_failure(p_false, comparisons=hb * wb * c)
    diff = np.abs(a_b - b_b)
    # Noise-free blocks (sky only) still differ by float32 accumulation rounding in both renderers.
    half = z * np.sqrt(va_b + vb_b) + block_rtol * np.abs(b_b)
    bad = diff > half
    if bad.any():
        i = np.unravel_index(np.argmax(diff / np.maximum(half, 1e-300)), diff.shape)
        raise AssertionError(
            f"{what}: {int(bad.sum())} of {bad.size} {block}x{block} block means outside their "
            f"intervals (z={z:.2f}); worst block {i[:2]} channel {i[2]}: A {a_b[i]:.5g} vs B "
            f"{b_b[i]:.5g} +- {half[i]:.3g}")
    q = -normal_quantile(1.0 - POWER)
    found = detectable_errors(se, img_b, z_image, q, np.sqrt(va_b + vb_b), b_b, z, q)
    found = Detectable(found.image_mean + mean_rtol, found.block + block_rtol)
    require_detectable(found, detect, what, block)
    return Agreement(img_a / img_b, found)


def assert_two_images_agree(mean_a, var_a, mean_b, var_b, block=8, p_false=1e-4,
                            detect=DETECT, what="images"):
    """Assert that two independent renders with variance passes agree, block by block.

    Both renderers report each pixel's estimate and the variance of that estimate (our Variance
    pass), and their noise is independent (different seeds). Every ``block x block`` block mean
    per channel, and the image mean per channel, must agree within the confidence interval of
    the difference (:func:`assert_estimates_agree`, Bonferroni over all blocks, channels and the
    image means). Pixel estimates are treated as independent, which they are for a pixel filter
    that is importance sampled (each sample lands in one pixel).

    Parameters
    ----------
    mean_a, var_a, mean_b, var_b : (h, w, c) float
    detect : (float, float) or None
        As in :func:`assert_images_agree`.

    Returns
    -------
    Agreement
    """
    ma, sa = block_estimates(np.asarray(mean_a, np.float64), np.asarray(var_a, np.float64), block)
    mb, sb = block_estimates(np.asarray(mean_b, np.float64), np.asarray(var_b, np.float64), block)
    h, w, c = np.shape(mean_a)
    comparisons = ma.size + c
    img_a = np.mean(mean_a, axis=(0, 1))
    img_b = np.mean(mean_b, axis=(0, 1))
    se_a = np.sqrt(np.sum(var_a, axis=(0, 1))) / (h * w)
    se_b = np.sqrt(np.sum(var_b, axis=(0, 1))) / (h * w)
    assert_estimates_agree(img_a, se_a, img_b, se_b, p_false, comparisons,
                           what=f"{what}: image means")
    assert_estimates_agree(ma, sa, mb, sb, p_false, comparisons,
                           what=f"{what}: {block}x{block} block means")
    z = z_for_false_failure(p_false, comparisons)
    q = -normal_quantile(1.0 - POWER)
    found = detectable_errors(np.hypot(se_a, se_b), img_b, z, q, np.hypot(sa, sb), mb, z, q)
    require_detectable(found, detect, what, block)
    return Agreement(img_a / img_b, found)


def replicate_block_means(imgs, block, mask=None):
    """Per-replicate block means ``(runs, m)`` over channels, plus the image mean per channel;
    pixels outside ``mask (h, w)`` are left out (blocks with none are dropped)."""
    r, h, w, c = imgs.shape
    if mask is None:
        mask = np.ones((h, w), bool)
    cols = []
    for y in range(0, h - block + 1, block):
        for x in range(0, w - block + 1, block):
            m = mask[y:y + block, x:x + block]
            if m.sum() == 0:
                continue
            cols.append(imgs[:, y:y + block, x:x + block][:, m].mean(axis=1))
    cols.append(imgs[:, mask].mean(axis=1))
    return np.concatenate(cols, axis=1)


def assert_replicates_agree(a, b, block=8, mask=None, p_false=1e-4, detect=DETECT,
                            what="images"):
    """Assert that two sets of independent replicate renders agree, block by block.

    For renderers whose pixel estimates are correlated (light paths splat into many pixels),
    a pixel variance pass understates a block's variance; replicates do not. Every block mean
    per channel and the image mean per channel (over ``mask``) must agree within the Welch t
    interval of the difference, Bonferroni-corrected over all of them. The degrees of freedom
    are Welch-Satterthwaite's, the smallest over all compared means (conservative); they grow
    with the replicate count, so many cheap replicates make a sharper test than a few long ones
    (with 4 replicates a side the interval is ~100 standard errors wide, with 32 about 6).

    Parameters
    ----------
    a, b : (runs, h, w, c) float
        Replicates with different seeds; at least two each.
    mask : (h, w) bool or None
        Pixels compared (all by default).
    detect : (float, float) or None
        As in :func:`assert_images_agree`.

    Returns
    -------
    Agreement
    """
    ba, bb = replicate_block_means(a, block, mask), replicate_block_means(b, block, mask)
    ma, mb = ba.mean(0), bb.mean(0)
    va, vb = ba.var(0, ddof=1) / len(a), bb.var(0, ddof=1) / len(b)
    se = np.sqrt(va + vb)
    with np.errstate(divide="ignore", invalid="ignore"):
        welch = (va + vb) ** 2 / (va**2 / (len(a) - 1) + vb**2 / (len(b) - 1))
    dof = max(min(len(a), len(b)) - 1, float(np.nanmin(welch, initial=np.inf)))
    dof = min(dof, len(a) + len(b) - 2)
    q = -student_t_quantile(0.5 * p_false / ma.size, dof)
    bad = np.abs(ma - mb) > q * se + 1e-12 * np.abs(mb)
    assert not bad.any(), (f"{what}: {bad.sum()} of {ma.size} block means differ beyond "
                           f"t={q:.3g} ({dof:.1f} dof): {ma[bad][:4]} vs {mb[bad][:4]} "
                           f"(se {se[bad][:4]})")
    c = a.shape[-1]
    q_power = -student_t_quantile(1.0 - POWER, dof)
    found = detectable_errors(se[-c:], mb[-c:], q, q_power, se[:-c].reshape(-1, c),
                              mb[:-c].reshape(-1, c), q, q_power)
    require_detectable(found, detect, what, block)
    return Agreement(ma[-c:] / mb[-c:], found)


def random_rigid(seed, scale=(1.0, 1.0, 1.0), spread=5.0):
    """A random rotation (scaled per axis by ``scale``) with a translation of normal components
    times ``spread``, as a (4, 4) object matrix (the same matrix for the same arguments)."""
    rng = np.random.default_rng(seed)
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    m = np.eye(4)
    m[:3, :3] = q * np.asarray(scale)
    m[:3, 3] = rng.normal(size=3) * spread
    return m
