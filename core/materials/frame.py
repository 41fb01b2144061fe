"""Local shading frames and the vector algebra of scattering: reflect, refract, half vectors.

Every BSDF in :mod:`core.materials` works in a *local frame* whose +Z axis is the surface's
shading normal **as stored in the mesh** (not flipped toward the viewer), so that the sign of
``wo.z`` says on which side of the surface the viewer is: ``wo.z > 0`` is the front (outside of
a dielectric), ``wo.z < 0`` the back (inside). Directions ``wo`` and ``wi`` both point away from
the surface and are unit vectors.

All functions take and return float64 struct-of-arrays batches: ``(k, 3)`` vectors and ``(k,)``
scalars, one row per shading point.
"""

from __future__ import annotations

import numpy as np

from ..rows import dots
from ..sampling import warps


def dot(a, b):
    """Row-wise dot products of ``a, b : (k, 3)`` -> ``(k,)`` (:func:`core.rows.dots`)."""
    return dots(a, b)


def shading_frame(n, tangent=None):
    """Orthonormal frames ``(s, t, n)`` around unit normals ``n : (k, 3)``.

    Parameters
    ----------
    n : (k, 3) float
    tangent : (k, 3) float, optional
        Tangents (any length) for anisotropic BSDFs: ``s`` is the tangent projected on the
        plane of ``n`` and normalised, ``t = n x s`` (Cycles' ``make_orthonormals_tangent``).
        Rows whose tangent is (nearly) parallel to ``n`` or zero get the default frame.

    Returns
    -------
    s, t, n : (k, 3) float64
        Right-handed; ``n`` is passed through (as float64).
    """
    n = np.asarray(n, np.float64)
    s, t = warps.frame_from_normal(n)
    if tangent is not None:
        tangent = np.asarray(tangent, np.float64)
        proj = tangent - dot(tangent, n)[:, None] * n
        length = np.sqrt(dot(proj, proj))
        ok = (length > 1e-9 * np.sqrt(dot(tangent, tangent))) & (length > 1e-30)
        s = np.where(ok[:, None], proj / np.where(ok, length, 1.0)[:, None], s)
        t = np.where(ok[:, None], np.cross(n, s), t)
    return s, t, n


def to_local(v, s, t, n):
    """World vectors ``v : (k, 3)`` in the frames ``(s, t, n)`` -> local ``(k, 3)``."""
    out = np.empty((v.shape[0], 3), np.result_type(v, s, t, n))
    for column, axis in enumerate((s, t, n)):  # each dot product straight into its column
        dots(v, axis, out=out[:, column])
    return out


def to_world(v, s, t, n):
    """Local vectors ``v : (k, 3)`` -> world ``(k, 3)`` (inverse of :func:`to_local`)."""
    return warps.to_world(v, s, t, n)


def normalize(v):
    """Unit vectors and a validity mask; zero-length (or non-finite) rows give ``0`` and False.

    Parameters
    ----------
    v : (k, 3) float

    Returns
    -------
    unit : (k, 3) float64
    ok : (k,) bool
    """
    length = np.sqrt(dot(v, v))
    ok = (length > 1e-30) & np.isfinite(length)
    unit = v / np.where(ok, length, 1.0)[:, None]
    return np.where(ok[:, None], unit, 0.0), ok


def flip_to_upper(w, side):
    """Mirror ``w : (k, 3)`` through the tangent plane where ``side (k,)`` is negative.

    Reflection-only BSDFs are two-sided (Cycles flips the normal toward the viewer): they are
    evaluated with both directions mirrored so that ``wo`` lies in the upper hemisphere.
    """
    out = w.copy()
    out[:, 2] = w[:, 2] * side
    return out


def side_of(w):
    """``+1`` where ``w.z >= 0``, ``-1`` below: the side of the surface ``w : (k, 3)`` is on."""
    return np.where(w[:, 2] >= 0.0, 1.0, -1.0)


def reflect(w, m):
    """Mirror reflection of ``w`` about the (micro)normal ``m``: ``2 (w.m) m - w``, ``(k, 3)``."""
    return 2.0 * dot(w, m)[:, None] * m - w


def reflect_z(w):
    """Mirror reflection about the local normal +Z: ``(-x, -y, z)``."""
    return w * np.array([-1.0, -1.0, 1.0])


def refract(w, m, eta):
    """Refraction of ``w`` through a (micro)surface with normal ``m`` (Snell's law).

    ``eta (k,)`` is the relative index of refraction of the material: index on the side ``m``
    points away from (the interior) over the index on the side ``m`` points to (the exterior).
    ``w`` may lie on either side of the surface; from the interior the ratio is inverted.

    Parameters
    ----------
    w : (k, 3) float
        Unit direction pointing away from the surface, on the incident side.
    m : (k, 3) float
        Unit normal.
    eta : (k,) float

    Returns
    -------
    wt : (k, 3) float64
        Unit refracted direction on the other side; zero where invalid.
    ok : (k,) bool
        False for total internal reflection and for ``w`` in the tangent plane.
    etap : (k,) float64
        Index on the transmitted side over index on the incident side.
    """
    cos_i = dot(w, m)
    inside = cos_i < 0.0
    etap = np.where(inside, 1.0 / eta, eta)
    mm = np.where(inside[:, None], -m, m)
    cos_i = np.abs(cos_i)
    sin2_t = np.maximum(0.0, 1.0 - cos_i * cos_i) / (etap * etap)
    ok = (sin2_t < 1.0) & (cos_i > 0.0)
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    wt = -w / etap[:, None] + (cos_i / etap - cos_t)[:, None] * mm
    wt, unit_ok = normalize(np.where(ok[:, None], wt, 0.0))
    return wt, ok & unit_ok, etap
