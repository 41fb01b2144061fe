"""Ray tests against lamp shapes: the one implementation of each, shared by next-event
estimation, BSDF-sampled rays that find lamps (path tracing) and BDPT's lamp vertices.

Lamps are not scene geometry (Embree never sees them, and they never block light), so rays meet
them here, analytically, up to the distance ``tmax`` of the first surface.
"""

from __future__ import annotations

import numpy as np

from .base import dot, length_and_direction
from ..quiet import quiet
from ..rows import scaled


def sphere_roots(b, cc):
    """Distances along unit directions to a sphere: roots of ``t^2 - 2 b t + cc = 0``.

    Parameters
    ----------
    b : (n,) float64
        ``dot(d, c - o)``: the direction against the vector from the origin to the centre.
    cc : (n,) float64
        ``|c - o|^2 - r^2`` (positive outside the sphere).

    Returns
    -------
    disc : (n,) float64
        The discriminant ``b^2 - cc`` (the ray misses where it is negative).
    near, far : (n,) float64
        ``b -/+ sqrt(max(disc, 0))``: where the ray enters and leaves the sphere.
    """
    disc = b * b - cc
    root = np.sqrt(np.maximum(disc, 0.0))
    return disc, b - root, b + root


def ray_sphere(o, d, center, radius, tmax):
    """Where rays ``o + t d`` meet a sphere's surface in ``(0, tmax)``: from outside its near
    side, from inside its far wall.

    Parameters
    ----------
    o, d : (n, 3) float64
        Origins and unit directions.
    center : (3,) float64
    radius : float
    tmax : (n,) float64

    Returns
    -------
    rows : (m,) int64
        Rays that meet the surface.
    t : (n,) float64
        Distance to it (meaningful on ``rows``).
    outside : (n,) bool
        Whether the origin is outside the sphere.
    to_c : (n, 3) float64
        ``center - o``.
    """
    to_c = center - o
    cc = dot(to_c, to_c) - radius * radius
    disc, near, far = sphere_roots(dot(to_c, d), cc)
    outside = cc > 0
    t = np.where(outside, near, far)
    rows = np.nonzero((disc > 0) & (t > 0) & (t < tmax))[0]
    return rows, t, outside, to_c


def ray_facing_disk(o, d, center, radius, tmax):
    """Where rays meet the disk of ``radius`` about ``center`` that faces each ray's origin
    (a Soft Falloff point light as seen from there), before ``tmax``.

    Returns
    -------
    rows : (m,) int64
    t : (n,) float64
    denom : (n,) float64
        Cosine between the ray and the disk's normal (negative on ``rows``).
    """
    oc = o - center
    d_o, light_n = length_and_direction(oc)
    denom = dot(d, light_n)
    with quiet("divide", "invalid"):
        t = -d_o / denom
    hit = (denom < 0) & (t > 0) & (t < tmax) & (d_o > 0)
    h = oc + d * np.where(hit, t, 0.0)[:, None]
    rows = np.nonzero(hit & (dot(h, h) <= radius * radius))[0]
    return rows, t, denom


def dual_basis(axis_x, axis_y):
    """The vectors ``(dx, dy)`` in the plane of ``axis_x, axis_y`` with ``dot(dx, axis_x) = 1,
    dot(dx, axis_y) = 0`` and ``dot(dy, axis_y) = 1, dot(dy, axis_x) = 0``, or None if the axes
    span no area.

    The in-plane coordinates of a point ``p = x axis_x + y axis_y`` are then ``dot(p, dx)`` and
    ``dot(p, dy)``: the inverse of the 2 x 2 Gram matrix written out, because
    ``np.linalg.solve`` on many right-hand sides wakes OpenBLAS's thread pool, whose threads
    then spin on the CPU cores the render's workers need.

    Parameters
    ----------
    axis_x, axis_y : (3,) float64

    Returns
    -------
    (dx, dy) : two (3,) float64, or None
    """
    a, b, c = float(axis_x @ axis_x), float(axis_x @ axis_y), float(axis_y @ axis_y)
    det = a * c - b * b
    if not det > 0:
        return None
    return (c * axis_x - b * axis_y) / det, (a * axis_y - b * axis_x) / det


def dot_vector(a, v, origin=None, negate=True):
    """Row-wise dot products ``(k,)`` of rows ``a (k, 3)`` with one vector ``v (3,)``, or of
    ``origin - a`` (``negate``) or ``a - origin`` with it, for a point ``origin (3,)``.

    Column by column: ``np.einsum("ij,j->i")`` costs about twice as much, and ``a @ v`` would
    wake OpenBLAS's threads (see :func:`dual_basis`).
    """
    out = np.empty(a.shape[0])
    for c in range(3):
        column = a[:, c]
        if origin is not None:
            column = origin[c] - column if negate else column - origin[c]
        if c == 0:
            np.multiply(column, v[0], out=out)
        else:
            out += column * v[c]
    return out


def ray_parallelogram(o, d, position, normal, axis_x, axis_y, tmax, disk):
    """Where rays meet the emitting face of an area light before ``tmax``.

    The light is the parallelogram ``position + x axis_x + y axis_y``, ``|x|, |y| <= 1/2``
    (``disk``: the ellipse ``x^2 + y^2 <= 1/4`` inscribed in it), emitting toward ``normal``:
    one-sided, a ray must travel against ``normal``. The in-plane coordinates come from the
    dual basis, so sheared lights are hit where area sampling puts their points.

    Returns
    -------
    None for a light of zero size, else
    rows : (m,) int64
    t : (n,) float64
    denom : (n,) float64
        ``dot(d, normal)`` (negative on ``rows``).
    q : (m, 3) float64
        Where the rays ``rows`` meet the light.
    """
    denom = dot_vector(d, normal)
    with quiet("divide", "invalid"):
        t = dot_vector(o, normal, position) / denom
    dual = dual_basis(axis_x, axis_y)
    if dual is None:
        return None
    # Only rays that reach the plane in time need its coordinates.
    rows = np.nonzero((denom < 0) & (t > 0) & (t < tmax))[0]
    q = scaled(d.take(rows, axis=0), t[rows])
    q += o.take(rows, axis=0)
    x = dot_vector(q, dual[0], position, negate=False)
    y = dot_vector(q, dual[1], position, negate=False)
    inside = x * x + y * y <= 0.25 if disk else (np.abs(x) <= 0.5) & (np.abs(y) <= 0.5)
    return rows[inside], t, denom, q[inside]
