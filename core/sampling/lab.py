"""Sampler lab: every sampler's points, spectrum, discrepancy and variance, measured side by side.

The measures only; ``tools/sampler_lab.py`` writes them as CSV files, plots and a markdown table
(``python -m sampling_lab samplers``, and Blender's "Sampler Lab" operator in a source checkout).
:func:`measure_sampler` takes one sampler through all of them, with the sizes of :data:`QUICK`
or :data:`FULL`:

Points
    The first N 2-D points of pixel 0, dimension 0 (``stream.sample(0, 2)`` for sample indices
    ``0 .. N-1``, the sampler made with ``spp = N``): :func:`sample_points`.
Spectrum
    The radially averaged periodogram ``P(k) = |sum_j exp(-2 pi i k . x_j)|^2 / N`` over integer
    frequencies ``k`` (:func:`periodogram`, :func:`radial_average`), averaged over
    ``realizations`` pixels (independent randomizations of the sampler), with its standard
    error. White noise has ``E[P(k)] = 1`` for every ``k != 0``; blue noise is below 1 at low
    frequencies (:func:`low_frequency_power`, the band ``0 < |k| <= sqrt(N) / 2``). A sampler
    whose set is only shifted from pixel to pixel (the blue-noise samplers) has the same
    periodogram in every pixel: its average shows one set's spectrum and its spread is zero.
Star discrepancy
    Exact, of the N points (pixel 0, and the mean over realizations): :func:`star_discrepancy`.
Checkerboard variance
    The variance of a pixel's estimate of the checkerboard integral (:func:`checkerboard`)
    against the sample count n, over ``pixels`` independent pixels for each n (a different
    seed for each n, so the points of one n are independent of the others'), with log-log
    slopes fitted over n >= 16 (:func:`checkerboard_study`, :func:`fit_slope`).

The checkerboard integrand
    The lecture's example, ``f = 1`` where ``floor(x) + floor(y)`` is even, tilted: here
    ``f(u, v) = 1`` where ``floor(3u + v) + floor(3v - u)`` is even, on the unit square. That
    is a checkerboard of 10 squares of side ``1/sqrt(10)`` turned by ``atan(1/3)`` (18.4
    degrees); it is periodic on the torus and shifting it by ``(3/10, 1/10)`` swaps black and
    white, so its integral is exactly 1/2 and independent sampling has variance ``1/(4n)``.
    The tilt is the lecture's warning made concrete: Koksma-Hlawka's bound holds for
    axis-aligned boxes only, and edges that no sampler's strata line up with are what a
    renderer meets. (An axis-aligned board with dyadic edges is integrated exactly by
    (0, 2)-nets at n = 4, 16, ..., which says nothing about edges in general.)
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..metrics import convergence_slope
from .samplers import make_sampler, sampler_class

CHECKERBOARD_INTEGRAL = 0.5
STAR_MAX_POINTS = 8192
LOW_BAND = 0.5  # the low-frequency band is 0 < |k| <= LOW_BAND * sqrt(N)


# ---------------------------------------------------------------------------------------------
# Measures
# ---------------------------------------------------------------------------------------------


def checkerboard(u):
    """The tilted checkerboard (module docstring): ``(n, 2)`` points -> ``(n,)`` float64 in {0, 1}.

    Its integral over the unit square is :data:`CHECKERBOARD_INTEGRAL` = 1/2.
    """
    u = np.asarray(u, np.float64)
    a = np.floor(3.0 * u[:, 0] + u[:, 1])
    b = np.floor(3.0 * u[:, 1] - u[:, 0])
    return ((a + b) % 2 == 0).astype(np.float64)


def periodogram(points, k_max):
    """Periodogram ``|sum_j exp(-2 pi i k . x_j)|^2 / N`` on the integer grid ``|k_x|, |k_y| <= k_max``.

    Parameters
    ----------
    points : (N, 2) or (r, N, 2) float
        One point set or ``r`` of them.
    k_max : int

    Returns
    -------
    (2 k_max + 1, 2 k_max + 1) or (r, 2 k_max + 1, 2 k_max + 1) float64
        Indexed ``[k_y + k_max, k_x + k_max]``; the centre is ``k = 0`` (where the value is N).
    """
    p = np.asarray(points, np.float64)
    single = p.ndim == 2
    p = p.reshape((-1,) + p.shape[-2:])
    k = np.arange(-int(k_max), int(k_max) + 1, dtype=np.float64)
    out = np.empty((p.shape[0], k.size, k.size))
    for r in range(p.shape[0]):
        # The 2-D sum factorises per point: S[ky, kx] = sum_j ey[ky, j] ex[kx, j], a matrix product.
        ex = np.exp(-2j * np.pi * np.outer(k, p[r, :, 0]))
        ey = np.exp(-2j * np.pi * np.outer(k, p[r, :, 1]))
        s = ey @ ex.T
        out[r] = (s.real ** 2 + s.imag ** 2) / p.shape[1]
    return out[0] if single else out


def _radius_grid(k_max):
    k = np.arange(-int(k_max), int(k_max) + 1)
    return np.hypot(k[:, None], k[None, :])


def radial_average(power, k_max):
    """Mean of ``power`` over rings ``|k|`` in ``[r - 1/2, r + 1/2)``, ``r = 1 .. k_max``.

    Parameters
    ----------
    power : (..., 2 k_max + 1, 2 k_max + 1) float
        From :func:`periodogram`.

    Returns
    -------
    radius : (k_max,) float64
    mean : (..., k_max) float64
    count : (k_max,) int64
        Frequencies per ring.
    """
    rad = _radius_grid(k_max)
    ring = np.rint(rad).astype(np.int64)
    radius = np.arange(1, int(k_max) + 1)
    p = np.asarray(power, np.float64)
    flat = p.reshape(p.shape[:-2] + (-1,))
    mean = np.empty(p.shape[:-2] + (radius.size,))
    count = np.empty(radius.size, np.int64)
    for i, r in enumerate(radius):
        sel = (ring == r).ravel()
        count[i] = sel.sum()
        mean[..., i] = flat[..., sel].mean(axis=-1)
    return radius.astype(np.float64), mean, count


def low_frequency_power(power, n, band=LOW_BAND):
    """Mean periodogram over ``0 < |k| <= band * sqrt(n)`` (at least the ring ``|k| = 1``).

    Parameters
    ----------
    power : (..., 2 k_max + 1, 2 k_max + 1) float
    n : int
        Points per set.

    Returns
    -------
    float or (...) float64
    """
    p = np.asarray(power, np.float64)
    k_max = (p.shape[-1] - 1) // 2
    rad = _radius_grid(k_max)
    limit = max(band * math.sqrt(n), 1.0)
    if limit > k_max:
        raise ValueError(f"the periodogram reaches |k| = {k_max}; the band needs {limit:.1f}")
    sel = ((rad > 0) & (rad <= limit)).ravel()
    out = p.reshape(p.shape[:-2] + (-1,))[..., sel].mean(axis=-1)
    return float(out) if np.ndim(out) == 0 else out


def star_discrepancy(points, block=512):
    """Exact star discrepancy ``sup_{a, b} |#{x < a, y < b} / N - a b|`` of 2-D points.

    The supremum over anchored boxes is reached at corners on the grid of the points'
    coordinates (plus 1): approached from above with closed boxes (count ``#{x <= a, y <= b}``,
    excess points) and from below with open ones (count ``#{x < a, y < b}``, missing points).
    Both counts come from one 2-D cumulative histogram over coordinate ranks, built in blocks
    of ``block`` rows: ``O(N^2)`` time, ``O(block N)`` memory. Up to :data:`STAR_MAX_POINTS`
    points (0.05 s at 1024 points, 3 s at 8192).

    Parameters
    ----------
    points : (N, 2) float in [0, 1)

    Returns
    -------
    float
    """
    p = np.asarray(points, np.float64)
    n = p.shape[0]
    if n == 0:
        return 0.0
    if n > STAR_MAX_POINTS:
        raise ValueError(f"exact star discrepancy is limited to {STAR_MAX_POINTS} points, got {n}")
    if p.min() < 0 or p.max() >= 1:
        raise ValueError("points must lie in [0, 1)^2")
    xs = np.unique(np.concatenate([p[:, 0], [1.0]]))
    ys = np.unique(np.concatenate([p[:, 1], [1.0]]))
    rx = np.searchsorted(xs, p[:, 0])
    ry = np.searchsorted(ys, p[:, 1])
    # Row cumulative counts for each y rank, built block by block with a running carry.
    order = np.argsort(ry, kind="stable")
    rx, ry = rx[order], ry[order]
    carry = np.zeros(xs.size, np.int64)  # closed counts of the previous row: #{x <= xs[k], y <= ys[l-1]}
    upper = lower = 0.0
    starts = np.searchsorted(ry, np.arange(0, ys.size + block, block))
    for b, l0 in enumerate(range(0, ys.size, block)):
        l1 = min(l0 + block, ys.size)
        sel = slice(starts[b], starts[b + 1])
        hist = np.bincount((ry[sel] - l0) * xs.size + rx[sel],
                           minlength=(l1 - l0) * xs.size).reshape(l1 - l0, xs.size)
        closed = np.cumsum(np.cumsum(hist, axis=1), axis=0) + carry[None, :]
        vol = ys[l0:l1, None] * xs[None, :]
        upper = max(upper, float((closed / n - vol).max()))
        # Open box [0, xs[k]) x [0, ys[l]): closed count at (k - 1, l - 1).
        prev = np.concatenate([carry[None, :], closed[:-1]], axis=0)
        opened = np.concatenate([np.zeros((l1 - l0, 1), np.int64), prev[:, :-1]], axis=1)
        lower = max(lower, float((vol - opened / n).max()))
        carry = closed[-1]
    return max(upper, lower)


def sample_points(name, n, pixels, seed=0, dimension=0, spp=None):
    """The first ``n`` 2-D points of each of ``pixels`` pixels: ``(len(pixels), n, 2)``.

    The sampler is made with ``spp = n`` (or ``spp``) and asked for dimensions
    ``dimension, dimension + 1`` of sample indices ``0 .. n-1``.
    """
    pixels = np.asarray(pixels, np.int64)
    sampler = make_sampler(name, seed=seed, spp=n if spp is None else spp)
    stream = sampler.stream(np.repeat(pixels, n), np.tile(np.arange(n, dtype=np.int64), pixels.size))
    return stream.sample(dimension, 2).reshape(pixels.size, n, 2)


def variance_and_se(estimates):
    """Sample variance (``ddof=1``) of independent estimates and its standard error.

    The standard error uses the sample fourth central moment,
    ``Var(s^2) ~ (m4 - s^4 (P - 3) / (P - 1)) / P``, so it holds for the skewed, discrete
    estimates of a 0/1 integrand too.
    """
    x = np.asarray(estimates, np.float64)
    p = x.size
    s2 = float(x.var(ddof=1))
    m4 = float(np.mean((x - x.mean()) ** 4))
    se = math.sqrt(max(m4 - s2 * s2 * (p - 3) / (p - 1), 0.0) / p)
    return s2, se


def checkerboard_estimates(name, n, pixels, seed=0, max_batch=1 << 20):
    """Estimates of the checkerboard integral, one per pixel ``0 .. pixels-1``, with ``n``
    samples each (sampler made with ``spp = n``, dimensions 0-1): ``(pixels,)`` float64."""
    sampler = make_sampler(name, seed=seed, spp=n)
    out = np.empty(int(pixels))
    step = max(1, max_batch // n)
    idx = np.arange(n, dtype=np.int64)
    for a in range(0, int(pixels), step):
        pix = np.arange(a, min(a + step, int(pixels)), dtype=np.int64)
        u = sampler.stream(np.repeat(pix, n), np.tile(idx, pix.size)).sample(0, 2)
        out[a:a + pix.size] = checkerboard(u).reshape(pix.size, n).mean(axis=1)
    return out


def fit_slope(ns, variances, variance_se):
    """Log-log slope of variance against n with two standard errors.

    Returns
    -------
    slope : float
    se_fit : float
        :func:`core.metrics.convergence_slope`'s (scatter about the line; includes curvature).
    se_sampling : float
        Propagated from each variance's own standard error (independent across n): how far the
        slope can move from sampling noise alone.
    """
    x = np.log(np.asarray(ns, np.float64))
    v = np.asarray(variances, np.float64)
    slope, se_fit = convergence_slope(ns, v)
    c = (x - x.mean()) / float(((x - x.mean()) ** 2).sum())
    rel = np.asarray(variance_se, np.float64) / v
    return slope, se_fit, float(math.sqrt(float(np.sum((c * rel) ** 2))))


def checkerboard_study(name, ns, pixels, seed=0, fit_from=16):
    """Variance of the checkerboard estimate for each n: list of dict rows, and the slope fit.

    Each n uses its own seed (``seed + 7919 i``), so the variances are independent. The slope
    (:func:`fit_slope`) is fitted over ``n >= fit_from`` (all n if fewer than three qualify):
    below 16 samples the strata are as large as the board's cells and near-regular patterns
    alias with it, which says nothing about the convergence rate.
    """
    rows = []
    for i, n in enumerate(ns):
        est = checkerboard_estimates(name, int(n), pixels, seed=seed + 7919 * i)
        var, se = variance_and_se(est)
        rows.append({"sampler": name, "n": int(n), "pixels": int(pixels),
                     "mean": float(est.mean()), "variance": var, "variance_se": se,
                     "independent_variance": CHECKERBOARD_INTEGRAL * (1 - CHECKERBOARD_INTEGRAL) / n})
    good = [r for r in rows if r["variance"] > 0 and r["n"] >= fit_from]
    if len(good) < 3:
        good = [r for r in rows if r["variance"] > 0]
    fit = (math.nan, math.nan, math.nan)
    if len(good) >= 3:
        fit = fit_slope([r["n"] for r in good], [r["variance"] for r in good],
                        [r["variance_se"] for r in good])
    return rows, fit


# ---------------------------------------------------------------------------------------------
# One sampler, every measure
# ---------------------------------------------------------------------------------------------

QUICK = {"n": 64, "realizations": 8, "star_realizations": 4, "pixels": 256,
         "ns": (4, 16, 64, 256), "progressive_ns": ()}
FULL = {"n": 256, "realizations": 64, "star_realizations": 16, "pixels": 1024,
        "ns": (4, 16, 64, 256, 1024), "progressive_ns": (4096,)}


def _label(name):
    try:
        return getattr(sampler_class(name), "label", name.replace("_", " ").title())
    except ValueError:
        return name


def measure_sampler(name, cfg, seed=0):
    """All measures of one sampler (a dict); see :func:`run`."""
    n = cfg["n"]
    t0 = time.perf_counter()
    pts = sample_points(name, n, np.arange(cfg["realizations"]), seed=seed)
    k_max = max(int(math.ceil(3 * math.sqrt(n))), 4)
    power = periodogram(pts, k_max)
    radius, radial, count = radial_average(power, k_max)
    low = low_frequency_power(power, n)
    r = cfg["realizations"]
    star = [star_discrepancy(pts[i]) for i in range(min(cfg["star_realizations"], r))]
    try:
        progressive = not sampler_class(name).needs_spp
    except (ValueError, AttributeError):
        progressive = False
    ns = tuple(cfg["ns"]) + (tuple(cfg["progressive_ns"]) if progressive else ())
    rows, fit = checkerboard_study(name, ns, cfg["pixels"], seed=seed + 1)
    return {
        "name": name, "label": _label(name), "n": n, "points": pts[0],
        "power_mean": power.mean(axis=0), "k_max": k_max, "radius": radius,
        "radial_mean": radial.mean(axis=0),
        "radial_se": radial.std(axis=0, ddof=1) / math.sqrt(r) if r > 1 else np.zeros_like(radius),
        "ring_count": count,
        "low_power": float(np.mean(low)),
        "low_power_se": float(np.std(low, ddof=1) / math.sqrt(r)) if r > 1 else 0.0,
        "star_pixel0": star[0], "star_mean": float(np.mean(star)),
        "star_se": float(np.std(star, ddof=1) / math.sqrt(len(star))) if len(star) > 1 else 0.0,
        "checkerboard": rows, "slope": fit[0], "slope_se": fit[1], "slope_se_sampling": fit[2],
        "seconds": time.perf_counter() - t0,
    }
