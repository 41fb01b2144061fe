"""Surface compatibility of a photon with a visible point: a disk-shaped lookup.

A density estimate that counts every photon within a *sphere* of radius ``r`` also counts
photons on other surfaces near the point: the wall beside a floor point at a corner, the
underside of a thin shelf, the far side of an edge. Jensen's photon maps (Realistic Image
Synthesis Using Photon Mapping, 2001, ch. 7) drop such photons; so does this test. A photon is
*compatible* with a visible point when

- the surfaces face alike: ``|n_p . n_x| >= cos(theta)`` (geometric normals, either side), and
- it lies near the point's tangent plane: ``|(x_p - x) . n_x| <= r tan(theta / 2)``,

with ``theta`` = :data:`MAX_ANGLE`. The two bounds agree on curved surfaces: on a sphere of
radius ``R`` a photon whose normal is ``theta`` from the point's lies ``R (1 - cos theta) =
d tan(theta / 2)`` off the tangent plane at tangential distance ``d``. So on a smooth surface
every photon within ``r`` passes both once ``r <= R sin(theta)``, and as ``r`` shrinks the
test removes only photons of other surfaces: the estimator stays consistent, and the blur
across edges and between surfaces, one source of its bias, goes.

On a flat surface it changes nothing; it does not help where the blur is *within* one surface
(a bright caustic beside a shadow on the same floor).
"""

from __future__ import annotations

import numpy as np

# Largest angle between a photon's surface normal and the visible point's.
MAX_ANGLE = np.radians(37.0)
MIN_COS = float(np.cos(MAX_ANGLE))
PLANE_SLACK = float(np.tan(0.5 * MAX_ANGLE))


def compatible(point_p, point_n, photon_p, photon_n, radius):
    """Which (point, photon) pairs pass the surface-compatibility test.

    Parameters
    ----------
    point_p, point_n : (m, 3) float
        Position and unit geometric normal of the visible point of every pair.
    photon_p, photon_n : (m, 3) float
        Position and unit geometric normal of the photon of every pair.
    radius : (m,) float
        Lookup radius of every pair.

    Returns
    -------
    (m,) bool
    """
    point_p = np.asarray(point_p, np.float64)
    point_n = np.asarray(point_n, np.float64)
    facing = np.abs(np.einsum("ij,ij->i", point_n, np.asarray(photon_n, np.float64)))
    offset = np.abs(np.einsum("ij,ij->i", point_n,
                              np.asarray(photon_p, np.float64) - point_p))
    return (facing >= MIN_COS) & (offset <= PLANE_SLACK * np.asarray(radius, np.float64))
