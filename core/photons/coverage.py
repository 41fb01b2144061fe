"""Disk coverage: the share of a lookup disk that lies on the looked-up surface.

A density estimate divides the photons' power by the disk's area ``pi r^2``. Where the disk
reaches past the surface's edge (the floor ending in empty space, a table's rim) no photon can
land on that part, and the estimate is too dark by the share missing: a bias that fades as
``r`` shrinks, slowly. Dividing by the area of the disk that *is* on a compatible surface
(:mod:`.compatible`) instead removes most of it.

That share is estimated with :data:`PROBES` short rays per point: at fixed points of the disk
in the tangent plane (a Vogel spiral: even coverage, no randomness), from ``h = r tan(theta/2)``
above the plane (the compatibility test's slack) down to ``h`` below it; a probe counts if it
meets a surface whose normal is compatible with the point's. Deterministic, so it adds no
noise; its quadrature error at an edge is about one probe (1/16 of the disk), and it averages
out as the visible point moves within its pixel from pass to pass. Inside a surface every probe
hits, the share is one and nothing changes; as ``r -> 0`` every interior point reaches that
state, so the estimator stays consistent.
"""

from __future__ import annotations

import numpy as np

from ..materials.frame import shading_frame
from ..scene import VIS_SHADOW
from .compatible import MIN_COS, PLANE_SLACK

PROBES = 16
GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


def disk_pattern(k=PROBES):
    """``(k, 2)`` points of the unit disk, each standing for an equal share of its area (a
    Vogel spiral: radius ``sqrt((i + 1/2) / k)``, angle ``i`` golden angles)."""
    i = np.arange(k)
    rho = np.sqrt((i + 0.5) / k)
    return np.c_[rho * np.cos(i * GOLDEN_ANGLE), rho * np.sin(i * GOLDEN_ANGLE)]


def disk_coverage(prep, p, ng, radius):
    """Share of the disk of radius ``radius`` around each point, in its tangent plane, that a
    compatible surface covers, at least ``1 / PROBES``.

    Parameters
    ----------
    prep : core.prepare.PreparedScene
    p, ng : (n, 3) float64
        Points and their unit geometric normals.
    radius : (n,) float64

    Returns
    -------
    (n,) float64
    """
    n = p.shape[0]
    if n == 0:
        return np.ones(0)
    s, t, nrm = shading_frame(ng)
    uv = disk_pattern()
    r = np.asarray(radius, np.float64)[:, None, None]
    h = PLANE_SLACK * r
    o = (p[:, None, :] + r * (uv[None, :, :1] * s[:, None, :] + uv[None, :, 1:] * t[:, None, :])
         + h * nrm[:, None, :]).reshape(-1, 3)
    d = np.repeat(-nrm, PROBES, axis=0)
    hits = prep.accel.intersect(o, d, np.repeat(2.0 * h.ravel(), PROBES), VIS_SHADOW)
    prim = np.maximum(hits.prim, 0)
    facing = np.abs(np.einsum("ij,ij->i", prep.tri_normal[prim], d))
    covered = (hits.prim >= 0) & (facing >= MIN_COS)
    return np.maximum(covered.reshape(n, PROBES).mean(axis=1), 1.0 / PROBES)
