"""A uniform grid over query points, pbrt-v4's alternative to the kd-tree for SPPM's lookups.

pbrt-v4's SPPM hashes its visible points into a grid and lets every photon look up the points
of its cell. :class:`PointGrid` does the same with NumPy: cells of side ``h`` (the largest
query radius), the points sorted by cell key, and for each photon the points of the 27 cells
around its own found by binary search (``searchsorted``) and expanded into candidate pairs
without a Python loop; pairs farther apart than the point's own radius are dropped. It gives
exactly :meth:`.lookup.PhotonTree.pairs_within`'s pairs (same float32 photon offsets); which
of the two is faster is measured by ``tools/photons.py`` (:func:`tools.photons.lookup_timing`).
"""

from __future__ import annotations

import numpy as np

# Offsets of a cell's 27 neighbours (itself included).
_NEIGHBOURS = np.array([(x, y, z) for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1)])


class PointGrid:
    """Query points (with their radii) in a uniform grid.

    Parameters
    ----------
    points : (n, 3) float
        Query points (SPPM's visible points), in the photons' frame.
    radii : (n,) float
        Their lookup radii (> 0).
    """

    def __init__(self, points, radii):
        self.points = np.asarray(points, np.float64)
        self.radii = np.asarray(radii, np.float64)
        self.h = float(self.radii.max()) if self.radii.size else 1.0
        cells = np.floor(self.points / self.h).astype(np.int64)
        self.lo = cells.min(axis=0) - 1 if cells.size else np.zeros(3, np.int64)
        self.shape = (cells.max(axis=0) + 2 - self.lo) if cells.size else np.ones(3, np.int64)
        keys = self._key(cells)
        self.order = np.argsort(keys, kind="stable")
        self.sorted_keys = keys[self.order]

    def _key(self, cells):
        """Linear cell index; -1 outside the grid's box."""
        c = cells - self.lo
        inside = ((c >= 0) & (c < self.shape)).all(axis=1)
        key = (c[:, 0] * self.shape[1] + c[:, 1]) * self.shape[2] + c[:, 2]
        return np.where(inside, key, -1)

    def pairs_within(self, photons):
        """Pairs ``(point, photon)`` with ``|photon - point| < radii[point]``.

        Parameters
        ----------
        photons : (m, 3) float
            Photon positions, in the points' frame.

        Returns
        -------
        point, photon : (k,) int64
        dist : (k,) float64
        """
        photons = np.asarray(photons, np.float64)
        cells = np.floor(photons / self.h).astype(np.int64)
        found_i, found_j = [], []
        for offset in _NEIGHBOURS:
            keys = self._key(cells + offset)
            start = np.searchsorted(self.sorted_keys, keys, side="left")
            stop = np.searchsorted(self.sorted_keys, keys, side="right")
            counts = np.where(keys >= 0, stop - start, 0)
            total = int(counts.sum())
            if total == 0:
                continue
            # Expand the ranges [start, stop) of every photon into one index array.
            first = np.cumsum(counts) - counts
            slots = np.arange(total) - np.repeat(first - start, counts)
            found_i.append(self.order[slots])
            found_j.append(np.repeat(np.arange(photons.shape[0]), counts))
        if not found_i:
            empty = np.zeros(0, np.int64)
            return empty, empty, np.zeros(0)
        i, j = np.concatenate(found_i), np.concatenate(found_j)
        dist = np.linalg.norm(photons[j] - self.points[i], axis=1)
        keep = dist < self.radii[i]
        return i[keep], j[keep], dist[keep]
