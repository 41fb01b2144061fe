"""Radiance estimates from a photon map: kernel density estimation over photon positions.

The light reflected at a point ``x`` toward ``wo`` is estimated from the photons near it as

``L(x, wo) ~= sum_p K(|x - x_p| / r) / r^2 * f(x, wo, wi_p) * power_p / N``

with ``N`` the photons emitted and ``K`` a kernel normalised over the unit disk
(:mod:`.kernels`). The radius is either fixed or, for the ``k`` nearest photons, the distance
to the ``k``-th one (Jensen). With the uniform kernel the ``k``-th photon, on the disk's rim,
weighs zero: the estimate ``(k - 1) / (pi r_k^2)`` is the one that is unbiased for photons
spread uniformly (a Poisson process). Either way the estimate is **biased**: it averages the
incident light over the disk (and catches photons on nearby surfaces); it is consistent when
the photon count grows while the radius (or ``k / N``) shrinks.
"""

from __future__ import annotations

import numpy as np

from .compatible import compatible
from .kernels import kernel_weight
from .lookup import QUERY_CHUNK, PhotonTree

LOOKUP_PAIRS = 1 << 17
"""(point, photon) pairs per step of a k-nearest estimate (``LOOKUP_PAIRS // k`` points, 2,621
at k = 50): a step cannot stop half-way, so this bounds the work between two polls of cancel
(8,192 gather points with k = 50 took up to 1.9 s in one step on a loaded 2-core machine; a
step of this size took at most 0.36 s at load 19). Smaller steps cost time: at 1 << 15 a
320 x 180 Cornell box pass took 18 % more CPU time (docs/PHOTONS.md)."""


class PhotonMap:
    """Photons with a kd-tree over their positions.

    Parameters
    ----------
    photons : core.photons.tracing.Photons
    emitted : int
        Photons emitted to make them (the estimate's denominator).
    """

    def __init__(self, photons, emitted):
        self.photons = photons
        self.emitted = int(emitted)
        self.tree = PhotonTree(photons.p, origin=np.zeros(3))

    def __len__(self):
        return len(self.photons)

    def neighbours(self, points, lookup, k, radius):
        """Pairs ``(point, photon)`` of the lookup and the radius of every point.

        Returns
        -------
        i, j : (m,) int64
        dist : (m,) float64
        r : (n,) float64
            Fixed ``radius``, or the distance to the ``k``-th nearest photon (the farthest found
            when the map holds fewer).
        """
        n = points.shape[0]
        if lookup == "radius":
            r = np.full(n, float(radius))
            i, j, dist = self.tree.pairs_within(points, r)
            return i, j, dist, r
        dist, idx = self.tree.nearest(points, k)
        found = np.isfinite(dist)
        r = np.where(found, dist, 0.0).max(axis=1)
        i, slot = np.nonzero(found)
        return i, idx[i, slot], dist[i, slot], r

    def radiance(self, points, max_hit, lookup="knn", k=50, radius=0.01, kernel="uniform",
                 min_hit=1, skip_caustic=False, surface_test=False, poll=None):
        """Reflected radiance ``(n, 3)`` at visible points from the photons of this map.

        Parameters
        ----------
        points : core.photons.visible.VisiblePoints
            Where (and with which BSDF) to estimate; their ``beta`` is not applied.
        max_hit : (n,) int
            Largest photon hit number each point may use (keeps paths within the bounce
            limit); photons beyond it are left out of the sum.
        lookup : str
            ``'knn'`` or ``'radius'``.
        k : int
        radius : float
        kernel : str
        min_hit : int
            Smallest photon hit number used (2: indirect light only).
        skip_caustic : bool
            Leave out caustic photons (when a caustic map estimates them).
        surface_test : bool
            Keep only photons on surfaces compatible with the point's
            (:func:`.compatible.compatible`).
        poll : callable or None
            Called before every step of at most ``LOOKUP_PAIRS // k`` points (``knn``) or
            :data:`QUERY_CHUNK` points (``radius``); it raises to stop (cancel). Each point's
            estimate is its own, so the steps do not change it.
        """
        n = points.rows.size
        out = np.zeros((n, 3))
        if n == 0 or len(self) == 0:
            return out
        step = max(64, LOOKUP_PAIRS // max(int(k), 1)) if lookup == "knn" else QUERY_CHUNK
        for start in range(0, n, step):
            if poll is not None:
                poll()
            rows = slice(start, min(start + step, n))
            out[rows] = self._radiance(points.take(rows), max_hit[rows], lookup, k, radius,
                                       kernel, min_hit, skip_caustic, surface_test)
        return out

    def _radiance(self, points, max_hit, lookup, k, radius, kernel, min_hit, skip_caustic,
                  surface_test):
        """:meth:`radiance` in one step."""
        n = points.rows.size
        out = np.zeros((n, 3))
        i, j, dist, r = self.neighbours(points.p, lookup, k, radius)
        ph = self.photons
        keep = (ph.hit[j] <= max_hit[i]) & (ph.hit[j] >= min_hit) & (r[i] > 0)
        if skip_caustic:
            keep &= ~ph.caustic[j]
        i, j, dist = i[keep], j[keep], dist[keep]
        if surface_test:  # on the pairs left only: its gathers are a large part of a step
            ok = compatible(points.p[i], points.ng[i], ph.p[j], ph.n[j], r[i])
            i, j, dist = i[ok], j[ok], dist[ok]
        w = kernel_weight(kernel, dist / r[i]) / (r[i] ** 2 * self.emitted)
        contrib = (points.f(i, ph.wi[j].astype(np.float64)) * ph.power[j].astype(np.float64)
                   * w[:, None])
        for c in range(3):
            out[:, c] = np.bincount(i, contrib[:, c], minlength=n)
        return out
