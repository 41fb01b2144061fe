"""Chi-square tests of direction samplers (BSDFs, lobes) against their pdfs, for lobes anywhere.

Method (after the chi-square tests of Mitsuba 3 and pbrt-v4, with cells that follow the lobe):

- **Bands.** The sphere is cut into theta bands at the horizon and, for a dielectric, at the cone
  ``wi.z = -wo.z / etap`` where the generalized half vector crosses the tangent plane (the
  microfacet pdf jumps there), so that no cell straddles those discontinuities.
- **Lobe grids.** Inside a band, theta and phi are warped cubically toward the pdf's largest
  value, found over the *whole band* (a scan in theta and phi, the sampler's own directions as
  extra candidates, then a local zoom), not only on the plane of incidence: a sharp lobe
  anywhere (an anisotropic highlight, a tilted coat, a view at any azimuth) spans many cells.
- **Expected counts.** The mass of every cell is an adaptive cubature of the pdf: a 4 x 4
  Gauss-Legendre rule on a square, compared with the sum of the rule on its four quarters;
  squares whose two estimates differ by more than ``RTOL`` of their mass are split again, up
  to ``MAX_LEVEL`` times, unless their differences fit in an absolute budget of ``ATOL`` of
  the sphere's total mass. The rule is exact for polynomials of degree 7 in each coordinate,
  so the error estimate is conservative on a smooth pdf; across a discontinuity that cuts
  cells (a tilted coat's horizon) it is not (on a spherical cap it measured 2.8 times too
  small: the mass came out 7.8e-5 too high, 8 of 1e5 samples spread over the rim's cells).
  Each cell keeps its error estimate, and the test refuses to run if the errors could move
  the statistic, ``n sum(err^2 / mass)``, by more than ``MAX_QUAD_CHI2`` (a kink or
  singularity the cubature could not resolve): a statistic of hundreds of dof does not notice
  that much.
- **Pooling.** Cells expected to hold fewer than 5 samples are pooled
  (:func:`tests.helpers.chi_square_counts`); a sample in a cell of probability zero fails.
- **Significance.** Every chi-square test of the suite that uses this module gets
  ``ALPHA = SUITE_ALPHA / CHI_TESTS`` (Bonferroni): with at most ``CHI_TESTS`` such tests, a
  correct implementation fails any of them with probability below ``SUITE_ALPHA`` for a fresh
  set of seeds (about 170 tests use it today).

Power: ``tests/core/test_chi2_power.py`` feeds the checker wrong samplers (a pdf off by a
factor in one region, a lobe rotated slightly, a missing component, a slightly different
roughness) and states the smallest error each detects at ``N_CHI`` samples.
"""

from __future__ import annotations

import numpy as np

from tests.helpers import chi_square_counts, histogram_2d

N_CHI = 100_000
RES = (24, 24)          # (theta, phi) cells per band
POWER = 3               # warp exponent of the lobe grids
SUITE_ALPHA = 0.01      # chance that a correct implementation fails any chi-square test
CHI_TESTS = 400         # bound on the number of chi-square tests that use ALPHA
ALPHA = SUITE_ALPHA / CHI_TESTS
RTOL = 1e-3             # relative cubature tolerance of a square (chi-square cells)
MASS_RTOL = 1e-5        # the same for integrals of a whole pdf
ATOL = 1e-6             # absolute tolerance, as a fraction of the total mass over the domain
MAX_LEVEL = 8           # deepest rectangle: a cell side / 2^8
MAX_QUAD_CHI2 = 1.0     # largest share of the statistic the cubature's error may explain
HALF_PI = 0.5 * np.pi
TWO_PI = 2.0 * np.pi

_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)
_GL_X = 0.5 * (_GL_X + 1.0)
_GL_W = 0.5 * _GL_W
_NODES = np.stack(np.meshgrid(_GL_X, _GL_X, indexing="ij"), axis=-1).reshape(-1, 2)
_WEIGHTS = np.outer(_GL_W, _GL_W).reshape(-1)
_QUARTERS = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, 0.5], [0.5, 0.5]])


# --------------------------------------------------------------------------------------------
# Adaptive cubature over the cells of [0, 1]^2
# --------------------------------------------------------------------------------------------


def _rule(density, corner, size):
    """Gauss-Legendre 4 x 4 estimates over squares ``corner : (m, 2)``, ``size : (m,)``, and
    whether each square has a node where the density is positive and one where it is zero."""
    pts = corner[:, None, :] + size[:, None, None] * _NODES[None]
    values = np.asarray(density(pts.reshape(-1, 2)), np.float64).reshape(len(corner), -1)
    return (values @ _WEIGHTS) * size**2, np.any(values > 0, axis=1), np.any(values <= 0, axis=1)


def _quarters(corner, size):
    half = 0.5 * size
    kids = corner[:, None, :] + half[:, None, None] * 2 * _QUARTERS[None]
    return kids.reshape(-1, 2), np.repeat(half, 4)


def _cells(res):
    """Corners and sizes of the square cells of a ``res`` grid on [0, 1]^2."""
    nx, ny = res
    assert nx == ny, "cells are squares"
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    return np.stack([ix.reshape(-1), iy.reshape(-1)], axis=-1) / nx, np.full(nx * ny, 1.0 / nx)


def _edge_cells(positive, zero, res):
    """Cells where the support of the density may end: some nodes zero and some positive, or
    all zero next to a cell (phi wraps around) with a positive node."""
    pos = positive.reshape(res)
    near = pos.copy()
    near[1:] |= pos[:-1]
    near[:-1] |= pos[1:]
    near = near | np.roll(near, 1, axis=1) | np.roll(near, -1, axis=1)
    return ((positive & zero) | (zero & ~positive & near.reshape(-1)))


def integrate_cells(density, res, rtol=RTOL, atol=None):
    """Mass of ``density`` (per ``dx dy``) over each cell of a ``res`` grid on [0, 1]^2.

    Cells where the density's support may end (:func:`_edge_cells`) start as 4 x 4 squares,
    so that a sliver of support that no node of the cell sees is still found; every square is
    then split in four until its estimate and its quarters' agree to ``rtol``, or until their
    differences fit in the absolute budget ``atol`` (by default ``ATOL`` of the total; each
    level may accept its smallest differences up to half of what is left), at most
    ``MAX_LEVEL`` times. (Where the density jumps or kinks across a square, the error
    estimate is not a bound: see the module docstring.)

    Returns
    -------
    mass : (res[0] * res[1],) float64
    error : (res[0] * res[1],) float64
        Estimated absolute error of each cell's mass: the sum over its final squares of
        ``|Q(quarters) - Q(square)|``, the error of the coarser estimate (a bound on the
        returned one wherever the rule converges).
    """
    nx, ny = res
    corner, size = _cells(res)
    cell = np.arange(nx * ny)
    coarse, positive, zero = _rule(density, corner, size)
    if atol is None:
        atol = ATOL * max(abs(coarse.sum()), 1e-300)
    edge = _edge_cells(positive, zero, res)
    if edge.any():
        e_corner, e_size = _quarters(*_quarters(corner[edge], size[edge]))
        corner = np.concatenate([corner[~edge], e_corner])
        size = np.concatenate([size[~edge], e_size])
        cell = np.concatenate([cell[~edge], np.repeat(cell[edge], 16)])
        coarse = np.concatenate([coarse[~edge], _rule(density, e_corner, e_size)[0]])
    mass = np.zeros(nx * ny)
    error = np.zeros(nx * ny)
    budget_used = 0.0
    for level in range(MAX_LEVEL + 1):
        kids_corner, kids_size = _quarters(corner, size)
        kids = _rule(density, kids_corner, kids_size)[0].reshape(-1, 4)
        fine = kids.sum(axis=1)
        diff = np.abs(fine - coarse)
        done = diff <= rtol * np.abs(fine)
        # The absolute budget: each level may spend half of what is left on its smallest
        # errors (a discontinuity across squares never meets a per-area share).
        order = np.flatnonzero(~done)[np.argsort(diff[~done], kind="stable")]
        spend = np.cumsum(diff[order]) <= 0.5 * (atol - budget_used)
        done[order[spend]] = True
        budget_used += float(diff[order[spend]].sum())
        if level == MAX_LEVEL:
            done[:] = True
        np.add.at(mass, cell[done], fine[done])
        np.add.at(error, cell[done], diff[done])
        keep = np.repeat(~done, 4)
        corner, size = kids_corner[keep], kids_size[keep]
        coarse, cell = kids.reshape(-1)[keep], np.repeat(cell, 4)[keep]
        if not len(cell):
            break
    return mass, error


# --------------------------------------------------------------------------------------------
# Lobe grids
# --------------------------------------------------------------------------------------------


def directions(theta, phi):
    st = np.sin(theta)
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=-1)


def angles(w):
    theta = np.arctan2(np.hypot(w[:, 0], w[:, 1]), w[:, 2])
    return theta, np.mod(np.arctan2(w[:, 1], w[:, 0]), TWO_PI)


class LobeGrid:
    """Cells ``(t, v)`` in [0, 1]^2 of the band ``a <= theta <= b``, dense near ``(c, phic)``.

    ``theta = c -+ span * s^3`` with ``s`` linear in ``t`` on each side of ``t_c``, and
    ``phi = phic + pi * sign(2v - 1) |2v - 1|^3``.
    """

    def __init__(self, a, b, c, phic):
        self.a, self.b, self.phic = a, b, phic
        self.c = float(np.clip(c, a, b))
        # Each side of the peak gets at least 15 % of the cells, so that a side that is narrow
        # in theta but carries mass (a peak next to a band edge) is still resolved.
        frac = (self.c - a) / (b - a)
        self.tc = 0.0 if frac <= 1e-9 else 1.0 if frac >= 1 - 1e-9 else min(max(frac, 0.15),
                                                                                0.85)

    def _sides(self):
        return max(self.tc, 1e-300), max(1.0 - self.tc, 1e-300)

    def theta(self, t):
        left_w, right_w = self._sides()
        left = t < self.tc
        s = np.where(left, (self.tc - t) / left_w, (t - self.tc) / right_w)
        span = np.where(left, self.c - self.a, self.b - self.c)
        theta = np.where(left, self.c - span * s**POWER, self.c + span * s**POWER)
        jac = span / np.where(left, left_w, right_w) * POWER * s ** (POWER - 1)
        return theta, jac

    def t_of(self, theta):
        sl = np.cbrt(np.clip((self.c - theta) / max(self.c - self.a, 1e-300), 0.0, 1.0))
        sr = np.cbrt(np.clip((theta - self.c) / max(self.b - self.c, 1e-300), 0.0, 1.0))
        return np.where(theta < self.c, self.tc * (1.0 - sl), self.tc + (1.0 - self.tc) * sr)

    def phi(self, v):
        s = 2.0 * v - 1.0
        phi = np.mod(self.phic + np.pi * np.sign(s) * np.abs(s) ** POWER, TWO_PI)
        return phi, TWO_PI * POWER * np.abs(s) ** (POWER - 1)

    def v_of(self, phi):
        x = np.mod(phi - self.phic + np.pi, TWO_PI) - np.pi
        return 0.5 * (1.0 + np.cbrt(x / np.pi))

    def density(self, fn):
        """``fn`` per steradian -> density per ``dt dv``."""
        def dens(tv):
            theta, jt = self.theta(tv[:, 0])
            phi, jp = self.phi(tv[:, 1])
            return fn(directions(theta, phi)) * np.sin(theta) * jt * jp
        return dens


def bands(wo_z, eta):
    """Theta intervals free of pdf discontinuities: split at the horizon and, for a dielectric,
    where ``etap wi + wo`` crosses the tangent plane (``wi.z = -wo.z / etap``)."""
    edges = {0.0, HALF_PI, np.pi}
    if eta is not None:
        etap = eta if wo_z > 0 else 1.0 / eta
        zf = -wo_z / etap
        if abs(zf) < 1.0:
            edges.add(float(np.arccos(zf)))
    edges = sorted(edges)
    return list(zip(edges[:-1], edges[1:]))


def _peak(fn, a, b, candidates):
    """``(theta, phi)`` of ``fn``'s largest value in the band ``a < theta < b``: the best of a
    129 x 128 scan and the candidate directions, refined by three zooms of 17 x 17."""
    theta = np.linspace(a, b, 131)[1:-1]
    phi = np.linspace(0.0, TWO_PI, 128, endpoint=False)
    tt, pp = (x.reshape(-1) for x in np.meshgrid(theta, phi, indexing="ij"))
    if len(candidates):
        ct, cp = angles(candidates)
        inside = (ct > a) & (ct < b)
        tt, pp = np.concatenate([tt, ct[inside]]), np.concatenate([pp, cp[inside]])
    values = fn(directions(tt, pp))
    i = int(np.argmax(values))
    best_t, best_p, best = tt[i], pp[i], values[i]
    dt, dp = (b - a) / 65, np.pi / 32
    for _ in range(3):
        t1 = np.clip(best_t + np.linspace(-dt, dt, 17), a, b)
        p1 = best_p + np.linspace(-dp, dp, 17)
        tt, pp = (x.reshape(-1) for x in np.meshgrid(t1, p1, indexing="ij"))
        values = fn(directions(tt, pp))
        i = int(np.argmax(values))
        if values[i] > best:
            best_t, best_p, best = tt[i], pp[i], values[i]
        dt, dp = dt / 6, dp / 6
    return best_t, float(np.mod(best_p, TWO_PI))


def lobe_grids(fn, wo_z, eta=None, candidates=()):
    """One :class:`LobeGrid` per band, dense at ``fn``'s largest value in the band.

    ``candidates : (m, 3)`` are extra directions to look at (a sampler's own directions find a
    lobe narrower than the scan's spacing)."""
    candidates = np.asarray(candidates, np.float64).reshape(-1, 3)
    return [LobeGrid(a, b, *_peak(fn, a, b, candidates)) for a, b in bands(wo_z, eta)]


def cell_masses(fn, grids, rtol=RTOL):
    """Integral of ``fn`` (per steradian) over every cell, and its error estimate:
    two ``(bands * RES[0] * RES[1],)`` arrays."""
    # One absolute tolerance for all bands, from the whole sphere's mass: a band that holds
    # little (a sliver below the horizon) is not refined to a precision nobody can see.
    total = sum(float(np.sum(_rule(g.density(fn), *_cells(RES))[0])) for g in grids)
    atol = ATOL * max(abs(total), 1e-300)
    parts = [integrate_cells(g.density(fn), RES, rtol, atol) for g in grids]
    return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]))


def cell_counts(w, grids):
    theta, phi = angles(w)
    counts = []
    for i, g in enumerate(grids):
        last = i == len(grids) - 1
        inside = (theta >= g.a) & ((theta < g.b) | last)
        tv = np.stack([g.t_of(theta[inside]), g.v_of(phi[inside])], axis=-1)
        c, outside = histogram_2d(tv, ((0, 1), (0, 1)), RES)
        assert outside == 0
        counts.append(c.reshape(-1))
    return np.concatenate(counts)


def integrate_sphere(fn, grids):
    """``int fn dw`` over the sphere and the cubature's error estimate (a bound on a smooth
    ``fn``; at a kink across cells, such as the visible-normal pdf's ``wo . m = 0``, it is not,
    so totals are computed to ``MASS_RTOL``, which leaves errors of a few 1e-8 there)."""
    mass, error = cell_masses(fn, grids, MASS_RTOL)
    return float(mass.sum()), float(error.sum()) + 1e-12 * abs(float(mass.sum()))


def chi_square_bsdf(sample_fn, pdf_fn, wo_z, eta=None, n=N_CHI, seed=0, what="bsdf",
                    alpha=ALPHA):
    """Chi-square test that the non-delta samples of ``sample_fn`` have the shape of
    ``pdf_fn``; cells of zero probability must stay empty. Returns the p-value.

    ``sample_fn(u_lobe (n,), u (n, 2)) -> (wi (n, 3), pdf (n,), delta (n,) bool)``;
    ``pdf_fn(wi (m, 3)) -> (m,)`` per steradian. The grids' dense spots are placed from the pdf
    and from 4096 extra samples drawn with their own seed, so the counted samples do not choose
    their own cells.
    """
    rng = np.random.default_rng(seed)
    wi, pdf, delta = sample_fn(rng.random(n), rng.random((n, 2)))
    live = (pdf > 0) & ~delta
    assert live.sum() > 1000, f"{what}: only {live.sum()} non-delta samples"
    w = wi[live]
    assert np.all(np.isfinite(w))
    np.testing.assert_allclose(np.linalg.norm(w, axis=1), 1.0, atol=1e-9)
    scout = np.random.default_rng([seed, 1])
    s_wi, s_pdf, s_delta = sample_fn(scout.random(4096), scout.random((4096, 2)))
    grids = lobe_grids(pdf_fn, wo_z, eta, s_wi[(s_pdf > 0) & ~s_delta])
    mass, error = cell_masses(pdf_fn, grids)
    total = mass.sum()
    assert total > 0
    # What the cubature's error could add to the statistic: n sum(err^2 / mass).
    cells = mass > 0
    quad_chi2 = live.sum() * float(np.sum(error[cells] ** 2 / mass[cells])) / total
    assert quad_chi2 <= MAX_QUAD_CHI2 and error.sum() <= 0.5 * total, (
        f"{what}: the pdf's cubature did not converge (its error could add {quad_chi2:.2f} "
        "to the chi-square statistic)")
    return chi_square_counts(cell_counts(w, grids), live.sum() * mass / total, alpha=alpha,
                             what=what)


def chi_square_bsdf_rows(params, wo, eta=None, seed=0, what="bsdf", alpha=ALPHA):
    """:func:`chi_square_bsdf` of the BSDF ``params(k)`` (a :class:`BSDFParams` of ``k``
    identical rows) seen from ``wo (3,)`` in its local frame. Returns the p-value."""
    from sampling_lab.core.materials import bsdf as B

    def sample(u_lobe, u):
        k = len(u_lobe)
        s = B.sample_bsdf(params(k), np.tile(wo, (k, 1)), u_lobe, u)
        return s.wi, s.pdf, s.delta

    def pdf(w):
        return B.pdf_bsdf(params(len(w)), np.tile(wo, (len(w), 1)), w)

    return chi_square_bsdf(sample, pdf, float(wo[2]), eta, seed=seed, what=what, alpha=alpha)
