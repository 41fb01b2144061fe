"""Error metrics, confidence intervals and convergence fits for renders and estimators.

Everything here is plain NumPy (no SciPy): the add-on ships inside Blender, and the few special
functions a confidence interval or a goodness-of-fit test needs (normal and Student-t quantiles,
the chi-square tail) are small enough to carry, with their accuracy checked against tabulated
values in ``tests/core/test_metrics.py``.

Conventions: images are ``(h, w, c)`` float arrays, row 0 at the bottom as in Blender; metrics
reduce over pixels *and* channels and return Python floats in float64 precision.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "mse",
    "rel_mse",
    "mean_and_ci",
    "block_means",
    "convergence_slope",
    "normal_quantile",
    "student_t_quantile",
    "chi2_sf",
]


# --------------------------------------------------------------------------------------------
# Image error metrics
# --------------------------------------------------------------------------------------------


def mse(img, ref):
    """Mean squared error over pixels and channels.

    Parameters
    ----------
    img, ref : (h, w, c) float
        Estimate and reference, same shape.

    Returns
    -------
    float
    """
    img, ref = _same_shape(img, ref)
    return float(np.mean((img - ref) ** 2))


def rel_mse(img, ref, eps=1e-2):
    """Relative MSE: mean of ``(img - ref)**2 / (ref**2 + eps)`` over pixels and channels.

    The denoising literature's metric (Rousselle et al. 2011, Bako et al. 2017): errors in dark
    regions count as much as in bright ones, and ``eps`` keeps black pixels finite.

    Parameters
    ----------
    img, ref : (h, w, c) float
        Estimate and reference, same shape.
    eps : float
        Positive regulariser added to ``ref**2``.

    Returns
    -------
    float
    """
    if not eps > 0:
        raise ValueError("rel_mse needs eps > 0")
    img, ref = _same_shape(img, ref)
    return float(np.mean((img - ref) ** 2 / (ref * ref + eps)))


def block_means(img, block=8):
    """Means over non-overlapping ``block`` x ``block`` pixel tiles.

    Block means of a Monte Carlo image are nearly independent and nearly normal, which makes them
    the unit for comparing two renders within confidence intervals. The remainder rows and
    columns that do not fill a block are cropped (from the top and right, i.e. the high indices).

    Parameters
    ----------
    img : (h, w, c) or (h, w) float
    block : int
        Tile size in pixels, >= 1.

    Returns
    -------
    (h // block, w // block, c) or (h // block, w // block) float64
    """
    img = np.asarray(img, np.float64)
    block = int(block)
    if block < 1:
        raise ValueError("block must be >= 1")
    if img.ndim not in (2, 3):
        raise ValueError(f"expected an (h, w) or (h, w, c) image, got shape {img.shape}")
    flat = img.ndim == 2
    if flat:
        img = img[:, :, None]
    bh, bw = img.shape[0] // block, img.shape[1] // block
    if bh == 0 or bw == 0:
        raise ValueError(f"image {img.shape[:2]} is smaller than one {block}x{block} block")
    tiles = img[: bh * block, : bw * block].reshape(bh, block, bw, block, img.shape[2])
    out = tiles.mean(axis=(1, 3))
    return out[:, :, 0] if flat else out


# --------------------------------------------------------------------------------------------
# Confidence intervals and convergence
# --------------------------------------------------------------------------------------------


def mean_and_ci(samples, confidence=0.95, axis=0, method="t"):
    """Sample mean and the half-width of its two-sided confidence interval.

    The interval is ``mean +- q * s / sqrt(n)`` with ``s`` the sample standard deviation
    (``ddof=1``) and ``q`` the Student-t quantile with ``n - 1`` degrees of freedom
    (``method="t"``, exact for normal samples) or the standard normal quantile
    (``method="normal"``, the large-n limit). Both rely on the central limit theorem for
    non-normal samples, so heavy-tailed estimators need many samples (or block means).

    Parameters
    ----------
    samples : (n, ...) float
        Independent samples along ``axis``.
    confidence : float
        Two-sided coverage in (0, 1), e.g. 0.95 or 0.9999.
    axis : int
        Axis holding the samples.
    method : {"t", "normal"}

    Returns
    -------
    mean : float or (...) float64
    half_width : float or (...) float64
        ``inf`` with fewer than two samples.
    """
    if not 0.0 < confidence < 1.0:
        raise ValueError("confidence must be in (0, 1)")
    if method not in ("t", "normal"):
        raise ValueError(f"unknown method {method!r}")
    x = np.asarray(samples, np.float64)
    n = x.shape[axis]
    if n == 0:
        raise ValueError("mean_and_ci needs at least one sample")
    mean = x.mean(axis=axis)
    tail = 0.5 * (1.0 - confidence)
    if n < 2:
        half = np.full_like(mean, np.inf)
    else:
        if method == "t":
            q = -student_t_quantile(tail, n - 1)
        else:
            q = -normal_quantile(tail)
        half = q * x.std(axis=axis, ddof=1) / math.sqrt(n)
    if np.ndim(mean) == 0:
        return float(mean), float(half)
    return mean, half


def convergence_slope(ns, variances):
    """Least-squares slope of ``log(variance)`` against ``log(n)``, with its standard error.

    Plain Monte Carlo converges with slope -1 (variance ~ 1/n); stratified and low-discrepancy
    samplers on smooth integrands do better (down to -2 or -3 in low dimension). The standard
    error is the ordinary-least-squares one, ``sqrt(SSR / (k - 2) / Sxx)``, which treats the
    scatter of the points about the line as noise.

    Parameters
    ----------
    ns : (k,) float
        Sample counts (or any positive cost), k >= 3.
    variances : (k,) float
        Positive variances (or MSEs) measured at those counts.

    Returns
    -------
    slope : float
    stderr : float
    """
    x = np.log(np.asarray(ns, np.float64).reshape(-1))
    y_raw = np.asarray(variances, np.float64).reshape(-1)
    if x.size != y_raw.size:
        raise ValueError("ns and variances differ in length")
    if x.size < 3:
        raise ValueError("a slope with a standard error needs at least three points")
    if not (np.all(np.isfinite(x)) and np.all(y_raw > 0) and np.all(np.isfinite(y_raw))):
        raise ValueError("ns and variances must be positive and finite")
    y = np.log(y_raw)
    xc = x - x.mean()
    sxx = float(xc @ xc)
    if sxx == 0.0:
        raise ValueError("ns must not all be equal")
    slope = float(xc @ (y - y.mean())) / sxx
    resid = y - y.mean() - slope * xc
    stderr = math.sqrt(float(resid @ resid) / (x.size - 2) / sxx)
    return slope, stderr


# --------------------------------------------------------------------------------------------
# Special functions (scalar; accurate to ~1e-12 relative over the ranges statistics uses)
# --------------------------------------------------------------------------------------------

# Acklam's rational approximation of the normal quantile (relative error < 1.2e-9), refined
# below by one Halley step on erfc to full double precision.
_A = (-3.969683028665376e01, 2.209460984245205e02, -2.759285104469687e02,
      1.383577518672690e02, -3.066479806614716e01, 2.506628277459239e00)
_B = (-5.447609879822406e01, 1.615858368580409e02, -1.556989798598866e02,
      6.680131188771972e01, -1.328068155288572e01)
_C = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e00,
      -2.549732539343734e00, 4.374664141464968e00, 2.938163982698783e00)
_D = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e00,
      3.754408661907416e00)


def normal_quantile(p):
    """Standard normal quantile (inverse CDF) ``Phi^-1(p)``.

    Use the lower tail for small probabilities (``-normal_quantile(alpha / 2)``) rather than
    ``normal_quantile(1 - alpha / 2)``, which loses digits to the subtraction.

    Parameters
    ----------
    p : float in (0, 1)

    Returns
    -------
    float
    """
    p = float(p)
    if not 0.0 < p < 1.0:
        if p == 0.0:
            return -math.inf
        if p == 1.0:
            return math.inf
        raise ValueError("normal_quantile needs p in [0, 1]")
    if p < 0.02425:
        q = math.sqrt(-2.0 * math.log(p))
        x = (((((_C[0] * q + _C[1]) * q + _C[2]) * q + _C[3]) * q + _C[4]) * q + _C[5]) / (
            (((_D[0] * q + _D[1]) * q + _D[2]) * q + _D[3]) * q + 1.0)
    elif p > 1.0 - 0.02425:
        q = math.sqrt(-2.0 * math.log1p(-p))
        x = -(((((_C[0] * q + _C[1]) * q + _C[2]) * q + _C[3]) * q + _C[4]) * q + _C[5]) / (
            (((_D[0] * q + _D[1]) * q + _D[2]) * q + _D[3]) * q + 1.0)
    else:
        q = p - 0.5
        r = q * q
        x = (((((_A[0] * r + _A[1]) * r + _A[2]) * r + _A[3]) * r + _A[4]) * r + _A[5]) * q / (
            ((((_B[0] * r + _B[1]) * r + _B[2]) * r + _B[3]) * r + _B[4]) * r + 1.0)
    # Halley refinement against the exact CDF, computed on the side where it is small.
    if x < 0:
        e = 0.5 * math.erfc(-x / math.sqrt(2.0)) - p
    else:
        e = (1.0 - p) - 0.5 * math.erfc(x / math.sqrt(2.0))
    u = e * math.sqrt(2.0 * math.pi) * math.exp(0.5 * x * x)
    return x - u / (1.0 + 0.5 * x * u)


def _betacf(a, b, x):
    """Continued fraction of the incomplete beta function (modified Lentz)."""
    tiny = 1e-300
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c = 1.0
    d = 1.0 - qab * x / qap
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 10_000):
        m2 = 2 * m
        aa = m * (b - m) * x / ((qam + m2) * (a + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > tiny else tiny)
        c = 1.0 + aa / c
        c = c if abs(c) > tiny else tiny
        h *= d * c
        aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > tiny else tiny)
        c = 1.0 + aa / c
        c = c if abs(c) > tiny else tiny
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < 1e-15:
            break
    return h


def _betainc(a, b, x):
    """Regularised incomplete beta ``I_x(a, b)``."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    ln_front = (math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b)
                + a * math.log(x) + b * math.log1p(-x))
    if x < (a + 1.0) / (a + b + 2.0):
        return math.exp(ln_front) * _betacf(a, b, x) / a
    return 1.0 - math.exp(ln_front) * _betacf(b, a, 1.0 - x) / b


def _student_t_lower_tail(t, df):
    """``P(T <= t)`` for ``t <= 0``, computed without cancellation."""
    return 0.5 * _betainc(0.5 * df, 0.5, df / (df + t * t))


def student_t_quantile(p, df):
    """Quantile of Student's t distribution with ``df`` degrees of freedom.

    Parameters
    ----------
    p : float in (0, 1)
    df : float > 0

    Returns
    -------
    float
    """
    p, df = float(p), float(df)
    if not df > 0:
        raise ValueError("student_t_quantile needs df > 0")
    if not 0.0 < p < 1.0:
        raise ValueError("student_t_quantile needs p in (0, 1)")
    if p == 0.5:
        return 0.0
    if p > 0.5:
        return -student_t_quantile(1.0 - p, df)
    # Bracket the lower-tail quantile, then bisect in t (monotone, so always converges).
    lo = min(normal_quantile(p), -1.0)
    while _student_t_lower_tail(lo, df) > p:
        lo *= 2.0
        if lo < -1e300:
            return -math.inf
    hi = 0.0
    for _ in range(2000):
        mid = 0.5 * (lo + hi)
        if _student_t_lower_tail(mid, df) > p:
            hi = mid
        else:
            lo = mid
        if hi - lo <= 1e-15 * max(1.0, abs(lo)):
            break
    return 0.5 * (lo + hi)


def _gamma_p_series(a, x):
    total = term = 1.0 / a
    ap = a
    for _ in range(100_000):
        ap += 1.0
        term *= x / ap
        total += term
        if abs(term) < abs(total) * 1e-16:
            break
    return total * math.exp(-x + a * math.log(x) - math.lgamma(a))


def _gamma_q_cf(a, x):
    tiny = 1e-300
    b = x + 1.0 - a
    c = 1.0 / tiny
    d = 1.0 / b
    h = d
    for i in range(1, 100_000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = 1.0 / (d if abs(d) > tiny else tiny)
        c = b + an / c
        c = c if abs(c) > tiny else tiny
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < 1e-16:
            break
    return math.exp(-x + a * math.log(x) - math.lgamma(a)) * h


def chi2_sf(x, dof):
    """Upper tail ``P(X >= x)`` of the chi-square distribution with ``dof`` degrees of freedom.

    The regularised upper incomplete gamma ``Q(dof / 2, x / 2)`` (series below ``a + 1``,
    continued fraction above, as in Numerical Recipes' ``gammq``).

    Parameters
    ----------
    x : float >= 0
    dof : float > 0

    Returns
    -------
    float
    """
    x, dof = float(x), float(dof)
    if not dof > 0:
        raise ValueError("chi2_sf needs dof > 0")
    if math.isnan(x):
        return math.nan
    if x <= 0.0:
        return 1.0
    if math.isinf(x):
        return 0.0
    a, h = 0.5 * dof, 0.5 * x
    if h < a + 1.0:
        return max(0.0, 1.0 - _gamma_p_series(a, h))
    return _gamma_q_cf(a, h)


def _same_shape(img, ref):
    img = np.asarray(img, np.float64)
    ref = np.asarray(ref, np.float64)
    if img.shape != ref.shape:
        raise ValueError(f"image {img.shape} and reference {ref.shape} differ in shape")
    return img, ref
