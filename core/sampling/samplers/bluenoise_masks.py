"""Screen-space masks of the blue-noise samplers: a 64 x 64 void-and-cluster threshold mask
(1-D offsets) and a vector mask (2-D offsets), each generated once and cached
(:mod:`.bluenoise_cache`). How the stream reads them: :mod:`.bluenoise`."""

from __future__ import annotations

import numpy as np

from .bluenoise_cache import cached_table

MASK_SIZE = 64
MASK_SIGMA = 1.5
MASK_VERSION = 1
VECTOR_MASK_BATCHES = 600


def void_and_cluster(size=MASK_SIZE, sigma=MASK_SIGMA, seed=0):
    """A ``size x size`` toroidal blue-noise threshold mask (Ulichney's void-and-cluster).

    Every cell gets a distinct rank; thresholding the ranks at any level gives a blue-noise
    binary pattern. Energies are a toroidal Gaussian of width ``sigma`` pixels, updated
    incrementally (one shifted kernel per step, ``O(size^4)`` in total: about 0.2 s for 64 x 64).

    Returns
    -------
    (size, size) float64
        ``(rank + 0.5) / size^2``: every value of the stratified set appears once.
    """
    size = int(size)
    n = size * size
    d = np.minimum(np.arange(size), size - np.arange(size)).astype(np.float64)
    k1 = np.exp(-d * d / (2.0 * sigma * sigma))
    kernel = np.outer(k1, k1)
    big = np.tile(kernel, (2, 2))

    def shifted(flat_index):
        # The kernel centred on cell (y, x), as a view into the doubled kernel.
        y, x = divmod(int(flat_index), size)
        return big[size - y:2 * size - y, size - x:2 * size - x]

    def energy(binary):
        return np.real(np.fft.ifft2(np.fft.fft2(binary.astype(np.float64)) * np.fft.fft2(kernel)))

    rng = np.random.default_rng(seed)
    ones = max(1, n // 10)
    pattern = np.zeros((size, size), bool)
    pattern.flat[rng.choice(n, ones, replace=False)] = True
    e = energy(pattern)
    # Initial pattern: move the tightest cluster into the largest void until they coincide.
    for _ in range(4 * n):
        c = int(np.argmax(np.where(pattern, e, -np.inf)))
        pattern.flat[c] = False
        e -= shifted(c)
        v = int(np.argmin(np.where(pattern, np.inf, e)))
        pattern.flat[v] = True
        e += shifted(v)
        if v == c:
            break
    rank = np.empty(n, np.int64)
    # Phase 1: rank the initial ones by removing tightest clusters.
    p, e1 = pattern.copy(), e.copy()
    for r in range(ones - 1, -1, -1):
        c = int(np.argmax(np.where(p, e1, -np.inf)))
        p.flat[c] = False
        e1 -= shifted(c)
        rank[c] = r
    # Phase 2: fill the largest voids up to half.
    p, e2 = pattern.copy(), e.copy()
    for r in range(ones, n // 2):
        v = int(np.argmin(np.where(p, np.inf, e2)))
        p.flat[v] = True
        e2 += shifted(v)
        rank[v] = r
    # Phase 3: the zeros are now the minority: fill their tightest clusters.
    ez = energy(~p)
    for r in range(n // 2, n):
        c = int(np.argmax(np.where(p, -np.inf, ez)))
        p.flat[c] = True
        ez -= shifted(c)
        rank[c] = r
    return ((rank + 0.5) / n).reshape(size, size)


def vector_mask(mask_x, batches=VECTOR_MASK_BATCHES, swaps=1024, seed=0):
    """A mask of 2-D values whose screen neighbours are far apart in the plane and per axis.

    The first component is the void-and-cluster mask ``mask_x`` itself; the second starts as
    the same mask at another placement (so each component alone is an optimal 1-D blue-noise
    mask) and is then permuted among pixels to make the *pairs* blue as well: swaps of second
    components are kept when they lower the energy (Georgiev and Fajardo 2016)

        ``E = sum_{i != j} exp(-|p_i - p_j|^2 / 2.1^2)
              (exp(-|v_i - v_j|^2 / 0.2^2) + 0.3 exp(-(v_iy - v_jy)^2 / 0.1^2))``

    over pixels within 3 of each other (toroidal distances in screen ``p`` and value ``v``).
    The first term spreads neighbours' 2-D values; the second keeps the second component's own
    stratification (a pair of independent 1-D masks is blue per component only: products such
    as ``sin(2 pi x) cos(2 pi y)`` of two blue images are not blue). Their Gaussian value kernel
    replaces Georgiev and Fajardo's ``exp(-|v_i - v_j|)``, which leaves the error images of
    localized integrands (a small bump) white. Swaps come in batches of ``swaps`` disjoint pairs
    (half within 6 pixels of each other) kept when they lower the energy (greedy descent);
    ``batches`` = 600 take about 1.5 s for 64 x 64. Both components keep their value sets, so
    each stays exactly stratified over the tile.

    Parameters
    ----------
    mask_x : (size, size) float
        A 1-D blue-noise mask (:func:`void_and_cluster`).

    Returns
    -------
    (size, size, 2) float64 in (0, 1)
    """
    mask_x = np.asarray(mask_x, np.float64)
    size = mask_x.shape[0]
    n = size * size
    rng = np.random.default_rng([int(seed), size, 0x6F3])
    second = np.roll(mask_x, (size // 2 - 3, size // 2 + 5), (0, 1))
    v = np.stack([mask_x.ravel(), second.ravel()], 1)
    k = np.arange(n)
    off = np.array([(dx, dy) for dy in range(-3, 4) for dx in range(-3, 4) if (dx, dy) != (0, 0)])
    w_screen = np.exp(-(off ** 2).sum(1) / 2.1 ** 2)
    px, py = k % size, k // size
    nbr = ((py[:, None] + off[None, :, 1]) % size) * size + (px[:, None] + off[None, :, 0]) % size

    def energy(centre, around):
        d = around - centre[:, None, :]
        d -= np.rint(d)
        d *= d
        e = np.exp(-(d[..., 0] + d[..., 1]) / 0.2 ** 2) + 0.3 * np.exp(-d[..., 1] / 0.1 ** 2)
        return (e * w_screen).sum(-1)

    local = swaps // 2
    for _ in range(int(batches)):
        a = rng.integers(0, n, swaps)
        b = np.empty(swaps, np.int64)
        dx, dy = rng.integers(-6, 7, (2, local))
        b[:local] = ((py[a[:local]] + dy) % size) * size + (px[a[:local]] + dx) % size
        b[local:] = rng.integers(0, n, swaps - local)
        # Keep pairs that share no pixel with another pair (swaps of one batch are disjoint).
        uniq, counts = np.unique(np.concatenate([a, b]), return_counts=True)
        shared = uniq[counts > 1]
        ok = ~(np.isin(a, shared) | np.isin(b, shared))
        a, b = a[ok], b[ok]
        va, vb = v[a], v[b]
        na, nb = v[nbr[a]], v[nbr[b]]
        va_new = np.stack([va[:, 0], vb[:, 1]], 1)
        vb_new = np.stack([vb[:, 0], va[:, 1]], 1)
        gain = energy(va, na) - energy(va_new, na) + energy(vb, nb) - energy(vb_new, nb)
        take = gain > 0
        v[a[take], 1], v[b[take], 1] = vb[take, 1], va[take, 1]
    return v.reshape(size, size, 2)


def mask(seed=0):
    """The cached 64 x 64 void-and-cluster mask ``(64, 64)`` float64 in ``(0, 1)`` (1-D offsets)."""
    data, _ = cached_table("mask", MASK_SIZE, seed, MASK_VERSION, (MASK_SIZE, MASK_SIZE),
                           lambda: (void_and_cluster(MASK_SIZE, MASK_SIGMA, seed), {}))
    return data


def mask2(seed=0):
    """The cached 64 x 64 vector mask ``(64, 64, 2)`` float64 in ``(0, 1)`` (2-D offsets)."""
    data, _ = cached_table("mask2", MASK_SIZE, seed, MASK_VERSION, (MASK_SIZE, MASK_SIZE, 2),
                           lambda: (vector_mask(mask(seed), seed=seed), {}))
    return data
