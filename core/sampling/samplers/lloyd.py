"""Lloyd sampler: random points relaxed toward the centroids of their Voronoi cells.

(manual page: see the bottom of this docstring for parameters)
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
    kind = "lloyd"
    version = 2
    default_points = 256
    max_points = 4096

    @classmethod
    def generate(cls, n, seed):
        return generate(n, seed)
