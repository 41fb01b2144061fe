"""Adaptive SPPM radius: nested disks per pixel and Lepski's rule between them.

SPPM's one radius per pixel blurs light over its disk. Where the disk reaches into a caustic
much brighter than the pixel's own surface (the end of a focused caustic line, the shadow
beside it), the blur adds light the pixel does not receive. Each pixel here also accumulates
its photons within ``r / 2^s`` for ``s = 1 .. SCALES - 1`` (``r`` its current radius), with the
same progressive rescaling as SPPM's own flux and count, and after every pass picks the
largest of these radii whose estimate agrees with every smaller one's within their noise
(Lepski's rule for adaptive bandwidths; Kaplanyan and Dachsbacher 2013 choose SPPM's radius
per pixel from estimates of the radiance's Laplacian and variance instead). A pixel whose
disk disagrees with a smaller one switches to it: its radius, flux and count become the
smaller disk's, an SPPM state with the radius sequence ``r_k / 2^s`` of every pass so far.

Bias and consistency: every state is SPPM's with some radius sequence, which only ever gets
smaller than plain SPPM's, and a pixel halves its radius at most ``SCALES - 1`` times, after
which it is plain SPPM (``alpha`` keeps the convergence conditions). So the estimate stays
biased but consistent. The rule itself is a heuristic: what it decides changes the error, not
the limit.
"""

from __future__ import annotations

import numpy as np

# Nested disks per pixel: radii r / 2^s, s < SCALES (so at most SCALES - 1 halvings in all).
SCALES = 4
# Two estimates disagree when they differ by more than KAPPA times the sum of their deviations.
KAPPA = 3.0


def scale_sums(i, d, contrib, radii, n):
    """Flux and photon count of every point within ``radii / 2^s``, ``s = 1 .. SCALES - 1``.

    Parameters
    ----------
    i : (m,) int
        Point of each (point, photon) pair within the point's radius.
    d : (m,) float
        Their distances.
    contrib : (m, 3) float
        Their contributions (BSDF times photon power).
    radii : (n,) float
        Each point's radius.
    n : int
        Number of points.

    Returns
    -------
    phi : (n, SCALES - 1, 3) float64
    m : (n, SCALES - 1) float64
    """
    phi, m = np.zeros((n, SCALES - 1, 3)), np.zeros((n, SCALES - 1))
    for s in range(1, SCALES):
        inside = d < radii[i] * 0.5 ** s
        k = i[inside]
        m[:, s - 1] = np.bincount(k, minlength=n)
        for c in range(3):
            phi[:, s - 1, c] = np.bincount(k, contrib[inside, c], minlength=n)
    return phi, m


def lepski_choice(tau, count, allowed):
    """Index ``s`` of the disk each pixel should use: the largest radius whose estimate agrees
    with the estimates of every smaller allowed one.

    Parameters
    ----------
    tau : (n, S, 3) float
        Accumulated flux within ``r / 2^s`` (``s = 0``: the pixel's own disk).
    count : (n, S) float
        Accumulated (progressively rescaled) photon counts of the same disks.
    allowed : (n,) int
        Largest ``s`` each pixel may switch to.

    Returns
    -------
    (n,) int64
        Chosen ``s`` (0: keep the radius).

    Notes
    -----
    The estimate of disk ``s`` is ``tau_s 4^s`` (flux per area, up to the common ``1 / pi r^2``).
    Its deviation is a Poisson one, ``cbar sqrt(count_s + 1) 4^s``, with ``cbar`` the mean
    contribution of a photon in the pixel's own disk: the extra one keeps an empty small disk
    from counting as certain.
    """
    n, scales = count.shape
    area = 4.0 ** np.arange(scales)
    est = tau.mean(axis=2) * area
    cbar = est[:, 0] / np.maximum(count[:, 0], 1e-12)
    dev = cbar[:, None] * np.sqrt(count + 1.0) * area
    ok = np.ones((n, scales), bool)
    for s in range(scales):
        for t in range(s + 1, scales):
            differ = np.abs(est[:, s] - est[:, t]) > KAPPA * (dev[:, s] + dev[:, t])
            ok[:, s] &= ~(differ & (t <= allowed))
    ok[np.arange(n), np.minimum(allowed, scales - 1)] = True
    ok &= np.arange(scales)[None, :] <= allowed[:, None]
    return np.argmax(ok, axis=1)


class NestedDisks:
    """The accumulated flux and count of each pixel's nested disks ``r / 2^s`` (``s >= 1``)
    and how often it has halved its radius.

    Parameters
    ----------
    n : int
        Number of pixels.
    """

    def __init__(self, n):
        self.tau = np.zeros((n, SCALES - 1, 3))
        self.count = np.zeros((n, SCALES - 1))
        self.halvings = np.zeros(n, np.int64)

    def add(self, pixels, phi, m, ratio2):
        """Add a pass's sums ``phi (k, SCALES - 1, 3)``, ``m (k, SCALES - 1)`` of the pixels
        ``pixels (k,)`` and rescale by their ``(r' / r)^2 (k,)``, as SPPM's own flux."""
        self.tau[pixels] = (self.tau[pixels] + phi) * ratio2[:, None, None]
        self.count[pixels] = (self.count[pixels] + m) * ratio2[:, None]

    def switch(self, state, pixels):
        """Lepski's rule on the pixels ``pixels`` of SPPM's ``state`` (``r``, ``N``, ``tau``):
        a pixel that picks disk ``s > 0`` takes its radius, flux and count. Returns the
        number of pixels that switched."""
        tau = np.concatenate([state["tau"][pixels][:, None], self.tau[pixels]], axis=1)
        count = np.concatenate([state["N"][pixels][:, None], self.count[pixels]], axis=1)
        s = lepski_choice(tau, count, SCALES - 1 - self.halvings[pixels])
        go = s > 0
        px, s = pixels[go], s[go]
        rows = np.arange(px.size)
        state["tau"][px] = tau[go][rows, s]
        state["N"][px] = count[go][rows, s]
        state["r"][px] = state["r"][px] * 0.5 ** s
        self.halvings[px] += s
        # Disk s + t becomes disk t; the disks beyond the old smallest start empty.
        old_tau, old_count = self.tau[px].copy(), self.count[px].copy()
        self.tau[px], self.count[px] = 0.0, 0.0
        for t in range(1, SCALES):
            src = s + t
            has = src < SCALES
            self.tau[px[has], t - 1] = old_tau[has, src[has] - 1]
            self.count[px[has], t - 1] = old_count[has, src[has] - 1]
        return int(px.size)
