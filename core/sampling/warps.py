"""Warps from the unit square to geometric domains, as sample / pdf / invert triples.

Every ``sample_*`` maps ``u : (n, 2)`` uniform in [0, 1)^2 to points of the domain; the matching
``*_pdf`` gives the density with respect to the domain's natural measure (solid angle for
directions, area for surfaces); ``invert_*`` maps a point back to ``u`` so that samplers and
Metropolis mutations can work in primary sample space.
"""

from __future__ import annotations

import numpy as np

INV_PI = 1.0 / np.pi


def sample_uniform_disk_concentric(u):
    """Shirley-Chiu concentric map of the square onto the unit disk.

    Parameters
    ----------
    u : (n, 2) float
    Returns
    -------
    (n, 2) float64
    """
    a = 2.0 * u[:, 0] - 1.0
    b = 2.0 * u[:, 1] - 1.0
    use_a = np.abs(a) > np.abs(b)
    r = np.where(use_a, a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        theta = np.where(use_a, (np.pi / 4) * (b / a), np.pi / 2 - (np.pi / 4) * (a / b))
    theta = np.where((a == 0) & (b == 0), 0.0, theta)
    return np.stack([r * np.cos(theta), r * np.sin(theta)], axis=-1)


def uniform_disk_pdf(p):
    """Density of :func:`sample_uniform_disk_concentric` per unit area: 1/pi."""
    return np.full(p.shape[0], INV_PI)


def invert_uniform_disk_concentric(p):
    """Inverse of :func:`sample_uniform_disk_concentric`. ``p : (n, 2)`` on the unit disk."""
    x, y = p[:, 0], p[:, 1]
    r = np.hypot(x, y)
    phi = np.arctan2(y, x)
    # Rotate phi into [-pi/4, 7pi/4) so each wedge of the concentric map is one interval.
    phi = np.where(phi < -np.pi / 4, phi + 2 * np.pi, phi)
    a = np.empty_like(r)
    b = np.empty_like(r)
    w0 = phi < np.pi / 4
    w1 = (phi >= np.pi / 4) & (phi < 3 * np.pi / 4)
    w2 = (phi >= 3 * np.pi / 4) & (phi < 5 * np.pi / 4)
    w3 = phi >= 5 * np.pi / 4
    a[w0] = r[w0]
    b[w0] = phi[w0] * a[w0] / (np.pi / 4)
    b[w1] = r[w1]
    a[w1] = (np.pi / 2 - phi[w1]) * b[w1] / (np.pi / 4)
    a[w2] = -r[w2]
    b[w2] = (phi[w2] - np.pi) * a[w2] / (np.pi / 4)
    b[w3] = -r[w3]
    a[w3] = (3 * np.pi / 2 - phi[w3]) * b[w3] / (np.pi / 4)
    return np.stack([(a + 1) / 2, (b + 1) / 2], axis=-1)


def sample_cosine_hemisphere(u):
    """Cosine-weighted directions on the +Z hemisphere (Malley's method).

    Parameters
    ----------
    u : (n, 2) float
    Returns
    -------
    (n, 3) float64 unit vectors with z >= 0.
    """
    d = sample_uniform_disk_concentric(u)
    z = np.sqrt(np.maximum(0.0, 1.0 - d[:, 0] ** 2 - d[:, 1] ** 2))
    return np.concatenate([d, z[:, None]], axis=-1)


def cosine_hemisphere_pdf(cos_theta):
    """Solid-angle density of :func:`sample_cosine_hemisphere`: max(cos, 0) / pi. ``(n,)``."""
    return np.maximum(cos_theta, 0.0) * INV_PI


def invert_cosine_hemisphere_sample(w):
    """Inverse of :func:`sample_cosine_hemisphere`. ``w : (n, 3)`` with z >= 0."""
    return invert_uniform_disk_concentric(w[:, :2])


def sample_uniform_sphere(u):
    """Uniform directions on the unit sphere. ``u : (n, 2)`` -> ``(n, 3)``."""
    z = 1.0 - 2.0 * u[:, 0]
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def uniform_sphere_pdf(n):
    """Solid-angle density of :func:`sample_uniform_sphere`: 1/(4 pi), shape ``(n,)``."""
    return np.full(n, 0.25 * INV_PI)


def invert_uniform_sphere_sample(w):
    """Inverse of :func:`sample_uniform_sphere`. ``w : (n, 3)`` -> ``(n, 2)``."""
    phi = np.arctan2(w[:, 1], w[:, 0])
    phi = np.where(phi < 0, phi + 2 * np.pi, phi)
    return np.stack([(1.0 - w[:, 2]) / 2.0, phi / (2 * np.pi)], axis=-1)


def sample_uniform_cone(u, cos_max):
    """Uniform directions in the cone of half-angle acos(cos_max) around +Z.

    Parameters
    ----------
    u : (n, 2) float
    cos_max : (n,) or float
    Returns
    -------
    (n, 3) float64
    """
    cos_t = 1.0 - u[:, 0] * (1.0 - cos_max)
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)


def uniform_cone_pdf(cos_max):
    """Solid-angle density of :func:`sample_uniform_cone`: 1 / (2 pi (1 - cos_max))."""
    return 1.0 / (2.0 * np.pi * (1.0 - np.asarray(cos_max, np.float64)))


def invert_uniform_cone_sample(w, cos_max):
    """Inverse of :func:`sample_uniform_cone`. ``w : (n, 3)`` inside the cone."""
    phi = np.arctan2(w[:, 1], w[:, 0])
    phi = np.where(phi < 0, phi + 2 * np.pi, phi)
    return np.stack([(1.0 - w[:, 2]) / (1.0 - cos_max), phi / (2 * np.pi)], axis=-1)


def sample_uniform_triangle(u):
    """Uniform barycentrics on a triangle (Heitz 2019 low-distortion map).

    Parameters
    ----------
    u : (n, 2) float
    Returns
    -------
    (n, 3) float64 barycentrics (b0, b1, b2) summing to one.
    """
    u0 = u[:, 0].astype(np.float64)
    u1 = u[:, 1].astype(np.float64)
    lower = u0 < u1
    b0 = np.where(lower, u0 / 2, u0 - u1 / 2)
    b1 = np.where(lower, u1 - u0 / 2, u1 / 2)
    return np.stack([b0, b1, 1.0 - b0 - b1], axis=-1)


def uniform_triangle_pdf(area):
    """Area density of :func:`sample_uniform_triangle` on a triangle of ``area``: 1/area."""
    return 1.0 / np.asarray(area, np.float64)


def invert_uniform_triangle_sample(b):
    """Inverse of :func:`sample_uniform_triangle`. ``b : (n, 3)`` barycentrics."""
    b0, b1 = b[:, 0], b[:, 1]
    lower = b0 < b1
    # In the lower half u0 < u1: u0 = 2 b0, u1 = b1 + b0. Otherwise u1 = 2 b1, u0 = b0 + b1.
    u0 = np.where(lower, 2 * b0, b0 + b1)
    u1 = np.where(lower, b1 + b0, 2 * b1)
    return np.stack([u0, u1], axis=-1)


def frame_from_normal(n):
    """Orthonormal tangent frames around unit normals (Duff et al. 2017).

    Parameters
    ----------
    n : (k, 3) float64 unit vectors
    Returns
    -------
    s, t : (k, 3) float64 such that (s, t, n) is right-handed.
    """
    sign = np.where(n[:, 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    s = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=-1)
    t = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=-1)
    return s, t


def to_world(local, s, t, n):
    """Express local ``(k, 3)`` vectors in the frame (s, t, n)."""
    return local[:, 0:1] * s + local[:, 1:2] * t + local[:, 2:3] * n
