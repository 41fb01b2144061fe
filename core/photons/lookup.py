"""Neighbour queries over photon positions: a kd-tree from ``scipy.spatial.cKDTree``.

Positions are kept in float32 relative to an origin (float64), so that a scene far from the
world origin keeps the precision of one near it; queries subtract the same origin in float64
before the tree sees them. Two queries, both vectorised (no Python loop per point):

- :meth:`PhotonTree.pairs_within`: every (query, photon) pair closer than the query's own
  radius (SPPM's per-pixel radii, fixed-radius photon mapping), through one
  ``sparse_distance_matrix`` between a tree of the queries and the photons' tree;
- :meth:`PhotonTree.nearest`: the ``k`` nearest photons of every query (Jensen's k-nearest
  density estimate).
"""

from __future__ import annotations

import importlib.util

import numpy as np

from ..errors import RenderRefused

QUERY_CHUNK = 4096
"""Query points per lookup task: a task cannot stop half-way, so this bounds the work between
two polls of cancel (4096 SPPM visible points: at most 0.05 s on a loaded 2-core machine,
0.28 s for the 32 k points of a whole chunk of camera paths)."""


def require_scipy():
    """Raise ``RenderRefused`` naming the missing module unless scipy can be imported (it is
    imported lazily: the add-on and the other integrators work without it)."""
    if importlib.util.find_spec("scipy") is None:
        raise RenderRefused("Photon Mapping and SPPM need the Python module scipy (its kd-tree, "
                         "scipy.spatial.cKDTree), which is not installed; install the extension "
                         "build that bundles it, or pip install scipy==1.14.1 into Blender's "
                         "Python")


def _kdtree(points, **kw):
    from scipy.spatial import cKDTree

    return cKDTree(points, **kw)


class PhotonTree:
    """A kd-tree over photon positions.

    Parameters
    ----------
    positions : (m, 3) float
        Photon positions (any float type; stored as float32 offsets from ``origin``).
    origin : (3,) float64 or None
        Local origin; None: the positions' bounding-box centre.
    leafsize : int
        Points per kd-tree leaf.
    """

    def __init__(self, positions, origin=None, leafsize=16):
        positions = np.asarray(positions)
        if origin is None:
            origin = (0.5 * (positions.min(axis=0) + positions.max(axis=0))
                      if len(positions) else np.zeros(3))
        self.origin = np.asarray(origin, np.float64)
        self.local = (positions.astype(np.float64) - self.origin).astype(np.float32)
        self.tree = _kdtree(self.local, leafsize=leafsize, balanced_tree=False,
                            compact_nodes=False)

    def __len__(self):
        return self.local.shape[0]

    def _queries(self, points):
        return np.asarray(points, np.float64) - self.origin

    def pairs_within(self, points, radii):
        """Pairs ``(query, photon)`` with ``|photon - query| < radii[query]``.

        Parameters
        ----------
        points : (n, 3) float
        radii : (n,) float
            Per-query radius (``> 0``).

        Returns
        -------
        query, photon : (k,) int64
        dist : (k,) float64
        """
        radii = np.asarray(radii, np.float64)
        if len(self) == 0 or len(radii) == 0:
            empty = np.zeros(0, np.int64)
            return empty, empty, np.zeros(0)
        queries = _kdtree(self._queries(points))
        found = queries.sparse_distance_matrix(self.tree, float(radii.max()),
                                               output_type="ndarray")
        i, j, d = (found["i"].astype(np.int64), found["j"].astype(np.int64),
                   found["v"].astype(np.float64))
        keep = d < radii[i]
        return i[keep], j[keep], d[keep]

    def nearest(self, points, k, max_radius=np.inf):
        """The ``k`` nearest photons of every query point, within ``max_radius``.

        Returns
        -------
        dist : (n, k) float64
            Distances, ascending; ``inf`` where fewer than ``k`` photons are that close.
        photon : (n, k) int64
            Photon indices; ``len(self)`` where ``dist`` is inf.
        """
        k = int(min(k, max(len(self), 1)))
        dist, idx = self.tree.query(self._queries(points), k=k,
                                    distance_upper_bound=max_radius)
        dist, idx = np.asarray(dist, np.float64), np.asarray(idx, np.int64)
        if dist.ndim == 1:
            dist, idx = dist[:, None], idx[:, None]
        return dist, idx
