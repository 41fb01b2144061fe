"""Lloyd sampler: random points relaxed toward the centroids of their Voronoi cells.

What it is
    One 2-D set of ``N`` points on the unit torus, dealt out to pixels and dimensions as
    :mod:`.bluenoise` describes (per pixel a hashed permutation and a Cranley-Patterson rotation
    read from a blue-noise mask; 1-D requests use the first coordinate).
How the set is made
    ``N`` uniform random points, then ``ITERATIONS`` = 20 Lloyd steps: every site moves to the
    centroid of its toroidal Voronoi cell. Centroids are estimated from ``16 N`` probes on a
    jittered grid, drawn afresh each step (so no probe pattern imprints on the sites; the
    stratified probes make the estimate far less noisy than random probes). Nearest sites come
    from a uniform grid of about one site per cell, checked in the 3 x 3 cells around each probe
    and certified (a probe whose nearest candidate is farther than a cell width is searched by
    brute force), so the assignment is exact. Cost: ``O(iterations * 16 N * 9 k)`` for ``k``
    sites per cell: about 0.1 s for N = 256, 0.3 s for 1024, 2 s for 4096 (the cap), once per N
    (then cached; see :mod:`.bluenoise`).
Convergence
    Lloyd's method removes the clumps of random points quickly: the periodogram's low-frequency
    band (``|k| < sqrt(N) / 2``) drops to about 0.03 of white noise, below the Poisson disk
    set's 0.1, and the pixel variance of the lab's checkerboard falls faster than 1/n while the
    set is small (slope about -1.3 from n = 16 to 256).
When it fails
    * Run to convergence, Lloyd's method crystallises into patches of a hexagonal lattice: the
      spectrum grows peaks (the radial average reaches about 3 at the spacing frequency after
      20 steps, more after 50), which aliases with regular image content. 20 steps is the
      compromise; the set is not a converged CVT (each step still moves the sites by about
      2 % of the spacing).
    * Lloyd's method is slow to converge (the lecture's words) where it matters most for
      large sets: a step only moves sites toward their neighbours, so density fluctuations of
      wavelength L relax in about ``(L sqrt(N))^2`` steps. After 20 steps the longest
      wavelengths keep much of their random-point power for N >= 1024 (measured at N = 1024:
      0.66, 0.28 and 0.12 of white noise in the rings ``|k|`` = 1, 2, 3; CVT: below 0.001), so
      integrands with large features (the lab's ten-cell checkerboard) converge at nearly the
      1/n rate from n of about 256 on (lab slope over n = 16 to 1024: about -1.1). More steps
      cost linearly and crystallise the set (first point); a jittered-grid start removes the
      long waves but leaves the grid in the set (spectral peaks of 5 to 7). Prefer the CVT
      sampler for large N.
    * Small sets (N of about 16 or fewer) settle into a near-square grid aligned with the torus
      axes: the 1-D projections clump into ``sqrt(N)`` groups, so 1-D requests and axis-aligned
      edges see few distinct values (the lecture's regular-grid problem). Prefer more samples or
      another sampler for very low sample counts.
    * Beyond ``N`` samples, the cycles of :mod:`.bluenoise` ("the loss"); only pairs of
      dimensions are stratified jointly.
Parameters
    ``seed`` (permutations and rotations), ``spp`` (set size ``N``), ``set_seed`` (another set
    for the same N), ``width`` (image width for the screen-space mask).
"""

from __future__ import annotations

import math
import time

import numpy as np

from .bluenoise import BlueNoiseSampler, nearest_site, torus_delta, wrap

ITERATIONS = 20
PROBES_PER_SITE = 16


def generate(n, seed=0, iterations=ITERATIONS, probes_per_site=PROBES_PER_SITE):
    """Lloyd-relaxed set of ``n`` points on the torus.

    Returns
    -------
    points : (n, 2) float64
    info : dict
        ``iterations``, ``probes``, ``seconds``, ``last_move`` (RMS step of the last iteration,
        in units of the mean spacing ``1 / sqrt(n)``).
    """
    t0 = time.perf_counter()
    n = int(n)
    rng = np.random.default_rng([int(seed), n, 0x110D])
    sites = rng.random((n, 2))
    res = int(math.ceil(math.sqrt(probes_per_site * n)))
    ij = np.stack(np.meshgrid(np.arange(res), np.arange(res), indexing="xy"), -1).reshape(-1, 2)
    last = 0.0
    for _ in range(int(iterations)):
        # Freshly jittered probes each iteration: centroids are not quantized to a probe grid.
        probes = wrap((ij + rng.random(ij.shape)) / res)
        idx, _ = nearest_site(probes, sites)
        delta = torus_delta(probes, sites[idx])
        cnt = np.bincount(idx, minlength=n).astype(np.float64)
        move = np.stack([np.bincount(idx, delta[:, k], minlength=n) for k in (0, 1)], -1)
        move = np.where(cnt[:, None] > 0, move / np.maximum(cnt, 1.0)[:, None], 0.0)
        sites = wrap(sites + move)
        last = math.sqrt(float(np.mean(np.sum(move * move, axis=1)))) * math.sqrt(n)
    return sites, {"iterations": float(iterations), "probes": float(res * res),
                   "last_move": last, "seconds": time.perf_counter() - t0}


class LloydSampler(BlueNoiseSampler):
    """Blue-noise sampler over a Lloyd-relaxed set (module docstring)."""

    name = "lloyd"
    label = "Lloyd Relaxation"
    description = ("Blue noise: random points relaxed toward their Voronoi centroids (20 Lloyd "
                   "steps), N = spp per pixel, rotated by a screen-space blue-noise mask")
    kind = "lloyd"
    version = 2
    default_points = 256
    max_points = 4096

    @classmethod
    def generate(cls, n, seed):
        return generate(n, seed)
