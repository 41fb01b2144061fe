"""The hard-scenes benchmark's reference (:mod:`.hard_scenes`): independent chunks, their noise,
and our reference averaged with Cycles' when the two agree.

Each renderer renders its reference as ``k`` independent chunks (other seeds). The chunk mean
is an unbiased image, and the spread of the chunks gives an unbiased estimate of its per-pixel
variance for any sampler (Sobol's randomisations with different seeds are independent), so the
noise of a reference is measured rather than taken from a per-pixel sample variance that
correlated samplers make wrong.

Both references are unbiased estimates of the same image when the renderers agree; then their
average, weighted by the inverse of their noise (one weight per scene, so the average stays
unbiased), is a reference quieter than either. Whether they agree is tested on the excess of
their difference over what their noise alone gives (an estimate of the squared bias between the
renderers, on the relMSE scale).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .common import EPS

# Independent chunks per reference: 3 degrees of freedom per pixel for its variance.
CHUNKS = 4
# A row's figure is flagged when the reference's noise exceeds this fraction of it.
NOISE_FLAG = 0.3
# The references agree when the excess of their difference over their noise is below this many
# standard errors (or below the combined reference's own noise).
AGREEMENT_SIGMAS = 3.0


def chunk_mean(images, counts):
    """Sample-count-weighted mean of independent chunk images and the variance of that mean.

    Parameters
    ----------
    images : sequence of (h, w, 3) float
        ``k >= 2`` independent estimates of the same image (different seeds).
    counts : sequence of float
        Samples per pixel of each chunk; chunk ``i`` has variance ``sigma^2 / counts[i]``.

    Returns
    -------
    mean : (h, w, 3) float64
    variance : (h, w, 3) float64
        Unbiased estimate of the per-pixel variance of ``mean``:
        ``sum_i n_i (x_i - mean)^2 / ((k - 1) N)`` with ``N = sum_i n_i``.
    """
    n = np.asarray(counts, dtype=np.float64)
    if n.size < 2 or not np.all(n > 0):
        raise ValueError(f"need at least two chunks with samples, got counts {counts}")
    stack = np.stack([np.asarray(im, dtype=np.float64)[..., :3] for im in images])
    total = n.sum()
    mean = np.tensordot(n, stack, axes=1) / total
    spread = np.tensordot(n, (stack - mean) ** 2, axes=1) / (n.size - 1)
    return mean, spread / total


def noise(variance, ref):
    """The relMSE a reference's noise adds: mean of ``variance / (ref^2 + EPS)``."""
    return float(np.mean(variance / (ref * ref + EPS)))


@dataclass
class Reference:
    """The reference every render is judged against.

    ``image`` and ``variance`` are ``(h, w, 3)`` float64; ``floor`` is :func:`noise` of it;
    ``weight_ours`` the weight of our reference in it (1: ours alone); the remaining fields
    describe the agreement of the two renderers' references (NaN without Cycles).
    """

    image: np.ndarray
    variance: np.ndarray
    floor: float
    weight_ours: float = 1.0
    agree: bool = False
    between: float = float("nan")
    noise_alone: float = float("nan")
    excess: float = float("nan")
    excess_se: float = float("nan")
    cycles_floor: float = float("nan")

    def error(self, img):
        """relMSE of ``img`` against the converged image: against this reference, minus its
        noise (unbiased), and the raw relMSE."""
        raw = float(np.mean((img - self.image) ** 2 / (self.image ** 2 + EPS)))
        return raw - self.floor, raw


def combine(ours, ours_var, cycles=None, cycles_var=None):
    """Our reference alone, or averaged with Cycles' when they agree (:class:`Reference`)."""
    own = Reference(ours, ours_var, noise(ours_var, ours))
    if cycles is None:
        return own
    den = (0.5 * (ours + cycles)) ** 2 + EPS
    n_ours, n_cy = float(np.mean(ours_var / den)), float(np.mean(cycles_var / den))
    w = n_cy / (n_ours + n_cy) if n_ours + n_cy > 0 else 0.5
    # Per pixel and channel: squared difference beyond the noise = the squared bias.
    excess = ((ours - cycles) ** 2 - ours_var - cycles_var) / den
    image = w * ours + (1 - w) * cycles
    variance = w * w * ours_var + (1 - w) ** 2 * cycles_var
    both = Reference(image, variance, noise(variance, image), w)
    stats = dict(between=float(np.mean((cycles - ours) ** 2 / (ours ** 2 + EPS))),
                 noise_alone=float(np.mean((ours_var + cycles_var) / (ours ** 2 + EPS))),
                 excess=float(excess.mean()),
                 excess_se=float(excess.std() / np.sqrt(excess.size)),
                 cycles_floor=noise(cycles_var, cycles))
    agree = stats["excess"] <= max(AGREEMENT_SIGMAS * stats["excess_se"], both.floor)
    out = both if agree else own
    for key, value in stats.items():
        setattr(out, key, value)
    out.agree = agree
    return out


def flagged(ref_floor, error):
    """Whether the reference's noise is too large (over :data:`NOISE_FLAG` of the error) for
    ``error`` to be trusted."""
    return not (np.isfinite(error) and ref_floor <= NOISE_FLAG * error)
