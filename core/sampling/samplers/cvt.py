"""CVT sampler: capacity-constrained Voronoi tessellation (Balzer, Schloemer, Deussen 2009).

What it is
    One 2-D set of ``N`` points on the unit torus whose (discrete) Voronoi cells all have the
    same area and whose points are their cells' centroids, dealt out to pixels and dimensions as
    :mod:`.bluenoise` describes (per pixel a hashed permutation and a Cranley-Patterson rotation
    read from a blue-noise mask; 1-D requests use the first coordinate).
How the set is made
    The density is ``CAPACITY`` = 32 discrete points per site (a jittered grid of ``32 N``
    points). Every site owns exactly 32 of them. An iteration visits pairs of neighbouring sites
    (each site's ``NEIGHBOURS`` = 8 nearest, found on a grid) and swaps points between the two
    while a swap lowers ``sum |x - s|^2`` (sort both sides by the gain of moving, swap the prefix
    whose summed gains are positive: the paper's heap loop, vectorized); then every site moves
    to its points' centroid. The pairs of an iteration are split into matchings (a greedy edge
    colouring) so that each matching's swaps run as one vectorized step over disjoint pairs.
    It stops when an iteration swaps nothing (the paper's stability criterion; typically 15 to
    30 iterations) or after ``MAX_ITERATIONS`` = 100 (``info["stable"]`` says which).
    The start: random sites; along a randomly shifted Hilbert curve the k-th site gets the k-th
    run of 32 points, which gives compact cells without imprinting the curve's quadtree on the
    result (starting from the runs' centroids would: they lie on a grid).
    Differences from the paper: swaps between Voronoi neighbours only (the paper visits all
    pairs, ``O(N^2)`` per iteration; Li et al. 2010 restrict to neighbours too), a capacity of
    32 rather than 1024 (cost), and jittered rather than random density points, which lowers
    the sites' low-frequency power about fivefold at that capacity (the sites inherit the
    points' noise divided by the capacity).
    Cost: about 0.2 s for N = 256, 0.7 s for N = 1024 and 4 s for N = 4096 (the cap), once per
    N (then cached; see :mod:`.bluenoise`).
Convergence
    The most uniform of the three blue-noise sets without Lloyd's crystallisation: the
    periodogram's low-frequency band (``|k| < sqrt(N) / 2``) is about 0.01 of white noise and
    the peak at the spacing frequency stays below 2 (Lloyd: about 3). Pixel variance falls
    faster than 1/n up to ``n = N`` (the lab's checkerboard: slope about -1.6).
When it fails
    * Small sets (N of about 16 or fewer) come out close to a square grid whose 1-D projections
      clump, as Lloyd's do (see :mod:`.lloyd`).
    * Beyond ``N`` samples, the cycles of :mod:`.bluenoise` ("the loss"); only pairs of
      dimensions are stratified jointly; time-limited renders get ``N = 256``.
    * The slowest set to generate; sets above 4096 points are refused.
Parameters
    ``seed`` (permutations and rotations), ``spp`` (set size ``N``), ``set_seed`` (another set
    for the same N), ``width`` (image width for the screen-space mask).
"""

from __future__ import annotations

import math
import time

import numpy as np

from .bluenoise import BlueNoiseSampler, torus_delta, torus_distance2, wrap

CAPACITY = 32
NEIGHBOURS = 8
MAX_ITERATIONS = 100


def hilbert_index(x, y, order):
    """Index along the Hilbert curve of the integer cells ``(x, y)`` of a ``2^order`` grid."""
    n = 1 << order
    x = np.asarray(x, np.int64).copy()
    y = np.asarray(y, np.int64).copy()
    d = np.zeros_like(x)
    s = n >> 1
    while s > 0:
        rx = (x & s) > 0
        ry = (y & s) > 0
        d += s * s * ((3 * rx.astype(np.int64)) ^ ry.astype(np.int64))
        # Rotate the quadrant so the sub-curve has the standard orientation.
        flip = ~ry & rx
        x = np.where(flip, n - 1 - x, x)
        y = np.where(flip, n - 1 - y, y)
        swap = ~ry
        x, y = np.where(swap, y, x), np.where(swap, x, y)
        s >>= 1
    return d


def _matchings(edges, n, rng):
    """Split undirected ``edges (e, 2)`` into matchings (greedy edge colouring, random order)."""
    order = rng.permutation(edges.shape[0])
    used = [0] * n
    colour = np.empty(edges.shape[0], np.int64)
    for e, (a, b) in zip(order.tolist(), edges[order].tolist()):
        taken = used[a] | used[b]
        c = ((~taken) & (taken + 1)).bit_length() - 1
        colour[e] = c
        used[a] |= 1 << c
        used[b] |= 1 << c
    return [edges[colour == c] for c in range(int(colour.max()) + 1)]


def _knn_edges(sites, k):
    """Undirected edges between every site and (about) its ``k`` nearest: ``(e, 2)`` int64.

    Candidates come from the 5 x 5 cells of a grid of about one site per cell around each site
    (all sites when there are few): the pairs the swaps need are Voronoi neighbours, which for
    these well-spread sets lie well inside that block.
    """
    n = sites.shape[0]
    k = min(k, n - 1)
    g = int(math.floor(math.sqrt(n)))
    if g < 6:
        cand = np.broadcast_to(np.arange(n), (n, n))
    else:
        cell = np.minimum((sites * g).astype(np.int64), g - 1)
        cid = cell[:, 1] * g + cell[:, 0]
        order = np.argsort(cid, kind="stable")
        counts = np.bincount(cid, minlength=g * g)
        start = np.concatenate([[0], np.cumsum(counts)[:-1]])
        table = np.full((g * g, int(counts.max())), n, np.int64)
        table[cid[order], np.arange(n) - start[cid[order]]] = order
        off = np.array([(dx, dy) for dy in range(-2, 3) for dx in range(-2, 3)], np.int64)
        nx = (cell[:, None, 0] + off[None, :, 0]) % g
        ny = (cell[:, None, 1] + off[None, :, 1]) % g
        cand = table[ny * g + nx].reshape(n, -1)
    pad = np.concatenate([sites, [[np.nan, np.nan]]])
    d2 = torus_distance2(sites[:, None, :], pad[cand])
    d2[(cand == np.arange(n)[:, None]) | (cand == n)] = np.inf
    k = min(k, int(np.isfinite(d2).sum(axis=1).min()))
    nbr = np.take_along_axis(cand, np.argpartition(d2, k - 1, axis=1)[:, :k], axis=1)
    i = np.repeat(np.arange(n), k)
    j = nbr.ravel()
    e = np.stack([np.minimum(i, j), np.maximum(i, j)], 1)
    return np.unique(e, axis=0)


def generate(n, seed=0, capacity=CAPACITY, neighbours=NEIGHBOURS, max_iterations=MAX_ITERATIONS):
    """Capacity-constrained Voronoi set of ``n`` points on the torus.

    Returns
    -------
    points : (n, 2) float64
    info : dict
        ``iterations``, ``stable`` (1 if an iteration made no swap), ``swaps`` (in the last
        iteration), ``capacity``, ``seconds``.
    """
    t0 = time.perf_counter()
    n, capacity = int(n), int(capacity)
    rng = np.random.default_rng([int(seed), n, 0xCC57])
    if n == 1:
        return rng.random((1, 2)), {"iterations": 0.0, "stable": 1.0, "swaps": 0.0,
                                    "capacity": float(capacity), "seconds": 0.0}
    # The discrete density: a jittered grid with random cells left out (m of res^2 kept). The
    # sites inherit the points' low-frequency noise divided by the capacity, so stratified
    # points give them about five times less low-frequency power than uniform random ones.
    m = n * capacity
    res = int(math.ceil(math.sqrt(m)))
    keep = np.sort(rng.permutation(res * res)[:m])
    pts = (np.stack([keep % res, keep // res], 1) + rng.random((m, 2))) / res
    # Random sites; the k-th site along a (randomly shifted) Hilbert curve gets the k-th run of
    # `capacity` points along it: compact cells to start from, without imprinting the curve's
    # quadtree on the sites (runs' centroids would lie on a grid).
    shift = rng.random(2)
    bits = 16

    def hilbert(p):
        c = np.minimum((wrap(p + shift) * (1 << bits)).astype(np.int64), (1 << bits) - 1)
        return hilbert_index(c[:, 0], c[:, 1], bits)

    sites = rng.random((n, 2))
    assign = np.empty((n, capacity), np.int64)
    assign[np.argsort(hilbert(sites), kind="stable")] = np.argsort(
        hilbert(pts), kind="stable").reshape(n, capacity)
    iterations, swaps, stable = 0, 0, False
    for it in range(int(max_iterations)):
        iterations = it + 1
        swaps = 0
        for pair in _matchings(_knn_edges(sites, neighbours), n, rng):
            a, b = pair[:, 0], pair[:, 1]
            pa, pb = pts[assign[a]], pts[assign[b]]
            sa, sb = sites[a][:, None, :], sites[b][:, None, :]
            # Gain of moving each point to the other site of the pair (energy sum |x - s|^2).
            ha = torus_distance2(pa, sa) - torus_distance2(pa, sb)
            hb = torus_distance2(pb, sb) - torus_distance2(pb, sa)
            ia = np.argsort(-ha, axis=1)
            ib = np.argsort(-hb, axis=1)
            gain = np.take_along_axis(ha, ia, 1) + np.take_along_axis(hb, ib, 1)
            # Both sorted descending, so the pairs worth swapping form a prefix.
            row, col = np.nonzero(gain > 0)
            if row.size == 0:
                continue
            swaps += row.size
            ca, cb = ia[row, col], ib[row, col]
            moving = assign[a[row], ca].copy()
            assign[a[row], ca] = assign[b[row], cb]
            assign[b[row], cb] = moving
        sites = wrap(sites + torus_delta(pts[assign], sites[:, None, :]).mean(axis=1))
        if swaps == 0:
            stable = True
            break
    return sites, {"iterations": float(iterations), "stable": float(stable), "swaps": float(swaps),
                   "capacity": float(capacity), "seconds": time.perf_counter() - t0}


class CVTSampler(BlueNoiseSampler):
    """Blue-noise sampler over a capacity-constrained Voronoi set (module docstring)."""

    name = "cvt"
    label = "Capacity-Constrained Voronoi"
    description = ("Blue noise: capacity-constrained Voronoi set (equal-area cells, sites at their "
                   "centroids), N = spp per pixel, rotated by a screen-space blue-noise mask")
    kind = "cvt"
    version = 1
    default_points = 256
    max_points = 4096

    @classmethod
    def generate(cls, n, seed):
        return generate(n, seed)
