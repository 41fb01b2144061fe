"""Warps from the unit square to geometric domains, as sample / pdf / invert triples.

Every ``sample_*`` maps ``u : (n, 2)`` uniform in [0, 1)^2 to points of the domain; the matching
``*_pdf`` gives the density with respect to the domain's natural measure (solid angle for
directions, area for surfaces); ``invert_*`` maps a point back to ``u`` so that samplers and
Metropolis mutations can work in primary sample space.
"""

from __future__ import annotations

import numpy as np

from ..rows import combine_rows
from ..quiet import quiet

INV_PI = 1.0 / np.pi
_ONE_MINUS = np.nextafter(1.0, 0.0)


def remap_after_choice(u, prob, chosen):
    """The number ``u (n,)`` left uniform in [0, 1) after it chose ``chosen (n,) bool`` as
    ``u < prob (n,)``: ``u / prob`` if chosen, else ``(u - prob) / (1 - prob)`` (so one random
    number picks a layer and then samples it)."""
    out = np.where(chosen, u / np.where(prob > 0.0, prob, 1.0),
                   (u - prob) / np.where(prob < 1.0, 1.0 - prob, 1.0))
    return np.clip(out, 0.0, _ONE_MINUS)


def sample_uniform_disk_concentric(u):
    """Shirley-Chiu concentric map of the square onto the unit disk.

    Parameters
    ----------
    u : (n, 2) float
    Returns
    -------
    (n, 2) float64
    """
    out = np.empty((u.shape[0], 2))
    _concentric(u, out)
    return out


def _concentric(u, out):
    """The concentric map of ``u (n, 2)`` written into ``out (n, >= 2)`` (columns 0 and 1).

    Computed in float32, at half the cost of float64 (float64 ``cos`` and ``sin`` alone cost
    more than the rest): the points are within about 1.5e-7 of the exact map, finer than the
    float32 rays Embree traces, and every caller derives its density from the point it got,
    not from ``u``. Sampler values (24-bit fractions) are exact in float32, and so is the
    point's radius, which is returned: ``(n,)`` float32 (the error is only along the circle).
    """
    f32 = np.float32
    a = u[:, 0].astype(f32)
    a *= f32(2.0)
    a -= f32(1.0)
    b = u[:, 1].astype(f32)
    b *= f32(2.0)
    b -= f32(1.0)
    use_a = np.abs(a) > np.abs(b)
    # r is the larger of |a|, |b| with its sign; the angle within the wedge is pi/4 times the
    # smaller over the larger (one division; r is zero only at a = b = 0, the centre).
    r = np.where(use_a, a, b)
    with quiet("divide", "invalid"):
        q = np.where(use_a, b, a) / r
    q[r == 0] = 0.0
    q *= f32(np.pi / 4)
    c = np.cos(q)
    c *= r
    s = np.sin(q)
    s *= r
    # Wedges of a (|a| > |b|): (r cos q, r sin q); wedges of b: (r sin q, r cos q).
    out[:, 0] = np.where(use_a, c, s)
    out[:, 1] = np.where(use_a, s, c)
    return np.abs(r)


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
    out = np.empty((u.shape[0], 3))
    r = _concentric(u, out).astype(np.float64)
    # z from the exact radius: grazing directions do not amplify the angle's float32 rounding.
    np.sqrt(np.maximum(0.0, 1.0 - r * r), out=out[:, 2])
    return out


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
    return np.stack(uniform_triangle_barycentrics(u), axis=-1)


def uniform_triangle_barycentrics(u):
    """:func:`sample_uniform_triangle`'s barycentrics as three ``(n,)`` arrays ``b0, b1, b2``
    (no stacking, no copies of float64 ``u``)."""
    u0 = np.asarray(u[:, 0], np.float64)
    u1 = np.asarray(u[:, 1], np.float64)
    # Halving is exact (u * 0.5 is u / 2 to the last bit): each half formed once.
    h0, h1 = u0 * 0.5, u1 * 0.5
    # Below the diagonal (u0 < u1) b0 = u0 / 2 and b1 = u1 - u0 / 2, above it b0 = u0 - u1 / 2
    # and b1 = u1 / 2: on each side the chosen value is the larger of the two, so a maximum
    # picks it (the same bits as a select on u0 < u1, without its mispredicted branches on a
    # random mask: a third of the time).
    b0 = np.maximum(h0, u0 - h1)
    b1 = np.maximum(u1 - h0, h1)
    return b0, b1, 1.0 - b0 - b1


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


def to_world_around(local, n):
    """``to_world(local, *frame_from_normal(n), n)``: local ``(k, 3)`` vectors in the frame
    :func:`frame_from_normal` makes around unit normals ``n (k, 3)``, to world ``(k, 3)``.

    The same frame, written out per world axis on contiguous columns instead of building
    ``s`` and ``t`` (equal to :func:`to_world` up to rounding, and about half its cost at 32 k
    rows).
    """
    nx, ny, nz = (np.ascontiguousarray(n[:, i], np.float64) for i in range(3))
    x, y, z = (np.ascontiguousarray(local[:, i], np.float64) for i in range(3))
    sign = np.where(nz >= 0, 1.0, -1.0)
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    sx = sign * x
    # s = (1 + sign nx^2 a, sign b, -sign nx), t = (b, sign + ny^2 a, -ny): world = x s + y t + z n.
    wx = x * (1.0 + sign * nx * nx * a)
    wx += y * b
    wx += z * nx
    wy = sx * b
    wy += y * (sign + ny * ny * a)
    wy += z * ny
    wz = z * nz
    wz -= sx * nx
    wz -= y * ny
    return np.stack((wx, wy, wz), axis=-1)


def to_world(local, s, t, n):
    """Express local ``(k, 3)`` vectors in the frame (s, t, n)."""
    return combine_rows(((local[:, 0], s), (local[:, 1], t), (local[:, 2], n)))


# --------------------------------------------------------------------------------------------
# Solid-angle sampling of spherical polygons
# --------------------------------------------------------------------------------------------

# Below this solid angle (sr) the spherical warps lose precision and a light is sampled by area
# instead; above MAX_SPHERICAL_SOLID_ANGLE (near a hemisphere, a point almost on the light's
# plane) the warps are ill-conditioned too. pbrt-v4 uses the same bounds.
MIN_SPHERICAL_SOLID_ANGLE = 3e-4
MAX_SPHERICAL_SOLID_ANGLE = 6.22


def _dot(a, b):
    return np.einsum("ij,ij->i", a, b)


def _norm(v):
    return np.sqrt(np.einsum("ij,ij->i", v, v))


def _cross(a, b):
    """Row-wise cross products of ``(n, 3)`` arrays (np.cross is slower on narrow rows)."""
    out = np.empty(np.broadcast_shapes(np.shape(a), np.shape(b)))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def _normalize(v):
    """Unit vectors ``(n, 3)``; zero vectors stay zero."""
    n = _norm(v)
    with quiet("divide"):
        inv = np.where(n > 0, 1.0 / n, 0.0)
    return v * inv[:, None]


def _angle_between(a, b):
    """Angle between unit vectors ``(n, 3)``, accurate near 0 and pi (pbrt's AngleBetween)."""
    # The half-chord to b (near 0) or to -b (near pi) keeps arcsin well conditioned.
    far = _dot(a, b) < 0
    chord = _norm(np.where(far[:, None], a + b, b - a))
    half = 2.0 * np.arcsin(np.clip(0.5 * chord, 0.0, 1.0))
    return np.where(far, np.pi - half, half)


def _gram_schmidt(v, w):
    """Unit component of ``v`` orthogonal to unit ``w``."""
    return _normalize(v - _dot(v, w)[:, None] * w)


def spherical_triangle_solid_angle(a, b, c, p):
    """Solid angle that triangles ``(a, b, c)`` subtend at points ``p`` (Van Oosterom and
    Strackee 1983), in steradians.

    Parameters
    ----------
    a, b, c : (n, 3) float
        Triangle vertices.
    p : (n, 3) float
        Viewpoints.

    Returns
    -------
    (n,) float64
        In [0, 2 pi]; zero for degenerate triangles or a viewpoint in the triangle's plane.
    """
    ra, rb, rc = (np.asarray(v, np.float64) - p for v in (a, b, c))
    la, lb, lc = (_norm(v) for v in (ra, rb, rc))
    triple = np.abs(_dot(ra, _cross(rb, rc)))
    # A triple product within rounding of zero is a flat (degenerate or edge-on) triangle.
    triple = np.where(triple <= 16 * np.finfo(np.float64).eps * la * lb * lc, 0.0, triple)
    denom = la * lb * lc + _dot(ra, rb) * lc + _dot(ra, rc) * lb + _dot(rb, rc) * la
    omega = 2.0 * np.arctan2(triple, denom)
    return np.where(np.isfinite(omega), np.maximum(omega, 0.0), 0.0)


def _spherical_triangle(a, b, c, p):
    """Unit vertex directions, corner angles and area of the spherical triangles."""
    wa, wb, wc = (_normalize(np.asarray(v, np.float64) - p) for v in (a, b, c))
    n_ab = _normalize(_cross(wa, wb))
    n_bc = _normalize(_cross(wb, wc))
    n_ca = _normalize(_cross(wc, wa))
    alpha = _angle_between(n_ab, -n_ca)
    beta = _angle_between(n_bc, -n_ab)
    gamma = _angle_between(n_ca, -n_bc)
    return wa, wb, wc, n_ab, alpha, beta, gamma


def sample_spherical_triangle(u, a, b, c, p):
    """Directions uniform over the solid angle of triangles, as seen from ``p`` (Arvo 1995).

    Arvo's two steps. First, ``u[:, 0]`` fixes the area ``u0 * A`` of a sub-triangle
    ``(a, b, c')`` with ``c'`` on the arc from ``a`` to ``c``: it shares the corner angle
    ``alpha`` at ``a`` and the side ``a b`` (length ``ab``), so its area ``E`` and the length
    ``x`` of its side ``a c'`` are tied by the spherical-excess identity
    ``tan(E / 2) = tan(x / 2) tan(ab / 2) sin(alpha) / (1 + tan(x / 2) tan(ab / 2) cos(alpha))``,
    which solved for ``x`` gives ``tan(x / 2) = sin(E / 2) / (tan(ab / 2) sin(alpha - E / 2))``.
    Second, ``u[:, 1]`` picks the direction on the arc from ``b`` to ``c'`` whose cosine to ``b``
    is uniform between 1 and ``cos(b, c')``: the area swept from ``b`` grows linearly in it.

    Parameters
    ----------
    u : (n, 2) float
    a, b, c : (n, 3) float
        Triangle vertices (either winding; the triangle may face either way).
    p : (n, 3) float
        Viewpoints, not in the triangle's plane.

    Returns
    -------
    (n, 3) float64
        Unit directions from ``p``; their density is :func:`spherical_triangle_pdf`.
    """
    u = np.asarray(u, np.float64)
    wa, wb, wc, n_ab, alpha, beta, gamma = _spherical_triangle(a, b, c, p)
    half_area = 0.5 * u[:, 0] * np.maximum(alpha + beta + gamma - np.pi, 0.0)
    # tan(ab / 2) = sin(ab) / (1 + cos(ab)); multiplying it out keeps atan2 finite for long sides.
    cos_ab = _dot(wa, wb)
    sin_ab = _norm(_cross(wa, wb))
    half_x = np.arctan2(np.sin(half_area) * (1.0 + cos_ab), sin_ab * np.sin(alpha - half_area))
    # c' may not pass c (rounding near u0 = 1).
    x = np.minimum(2.0 * half_x, _angle_between(wa, wc))
    cp = np.cos(x)[:, None] * wa + np.sin(x)[:, None] * _gram_schmidt(wc, wa)
    # Uniform in 1 - cos(b, w) over [0, 1 - cos(b, c')].
    cos_t = 1.0 - u[:, 1] * (1.0 - _dot(cp, wb))
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    w = cos_t[:, None] * wb + sin_t[:, None] * _gram_schmidt(cp, wb)
    return _normalize(w)


def spherical_triangle_pdf(a, b, c, p):
    """Solid-angle density of :func:`sample_spherical_triangle`: 1 / solid angle, ``(n,)``.

    Zero where the triangle subtends no solid angle (degenerate, or ``p`` in its plane).
    """
    omega = spherical_triangle_solid_angle(a, b, c, p)
    with quiet("divide"):
        return np.where(omega > 0, 1.0 / np.where(omega > 0, omega, 1.0), 0.0)


def invert_spherical_triangle_sample(w, a, b, c, p):
    """Inverse of :func:`sample_spherical_triangle`: directions ``w (n, 3)`` -> ``u (n, 2)``."""
    w = _normalize(np.asarray(w, np.float64))
    wa, wb, wc, n_ab, alpha, beta, gamma = _spherical_triangle(a, b, c, p)
    area = alpha + beta + gamma - np.pi
    # c' is where the great circle through b and w meets the arc from a to c.
    cp = _normalize(_cross(_cross(wb, w), _cross(wc, wa)))
    cp = np.where((_dot(cp, wa + wc) < 0)[:, None], -cp, cp)
    # u0 is the area of the sub-triangle (a, b, c') over the whole: both by the stable
    # Van Oosterom-Strackee formula, which stays accurate for slivers (c' near a).
    sub = _unit_triangle_area(wa, wb, cp)
    whole = _unit_triangle_area(wa, wb, wc)
    with quiet("invalid", "divide"):
        u0 = sub / whole
        u1 = (1.0 - _dot(w, wb)) / (1.0 - _dot(cp, wb))
    u = np.stack([np.nan_to_num(u0), np.nan_to_num(u1)], axis=-1)
    return np.clip(u, 0.0, 1.0)


def _unit_triangle_area(wa, wb, wc):
    """Area of spherical triangles with unit vertex vectors (Van Oosterom and Strackee)."""
    triple = np.abs(_dot(wa, _cross(wb, wc)))
    return 2.0 * np.arctan2(triple, 1.0 + _dot(wa, wb) + _dot(wb, wc) + _dot(wc, wa))


def _rectangle_frame(s, ex, ey, p):
    """Ureña et al.'s local frame: the rectangle at z0 < 0, spanning [x0, x1] x [y0, y1]."""
    s, ex, ey = (np.asarray(v, np.float64) for v in (s, ex, ey))
    exl = _norm(ex)
    eyl = _norm(ey)
    fx = _normalize(ex)
    fy = _normalize(ey)
    fz = _cross(fx, fy)
    d = s - p
    z0 = _dot(d, fz)
    # Flip z so that the rectangle lies below the viewpoint: z0 < 0.
    flip = z0 > 0
    fz = np.where(flip[:, None], -fz, fz)
    z0 = np.where(flip, -z0, z0)
    x0, y0 = _dot(d, fx), _dot(d, fy)
    return fx, fy, fz, x0, y0, z0, x0 + exl, y0 + eyl


def _rectangle_angles(x0, y0, z0, x1, y1):
    """Edge-plane normals' z and the corner angles of the spherical rectangle, and its area."""
    v00 = np.stack([x0, y0, z0], -1)
    v01 = np.stack([x0, y1, z0], -1)
    v10 = np.stack([x1, y0, z0], -1)
    v11 = np.stack([x1, y1, z0], -1)
    n0 = _normalize(_cross(v00, v10))
    n1 = _normalize(_cross(v10, v11))
    n2 = _normalize(_cross(v11, v01))
    n3 = _normalize(_cross(v01, v00))
    g0 = _angle_between(-n0, n1)
    g1 = _angle_between(-n1, n2)
    g2 = _angle_between(-n2, n3)
    g3 = _angle_between(-n3, n0)
    area = g0 + g1 + g2 + g3 - 2.0 * np.pi
    return n0[:, 2], n2[:, 2], g0, g1, g2, g3, np.maximum(area, 0.0)


def spherical_rectangle_solid_angle(s, ex, ey, p):
    """Solid angle that rectangles subtend at ``p``, in steradians.

    Parameters
    ----------
    s : (n, 3) float
        A corner.
    ex, ey : (n, 3) float
        The two edges from it; they must be orthogonal.
    p : (n, 3) float
        Viewpoints.

    Returns
    -------
    (n,) float64
        In [0, 2 pi]: the spherical rectangle's area (the sum of its corner angles minus 2 pi),
        computed as the two triangles' Van Oosterom-Strackee solid angles, which is cheaper.
    """
    s, ex, ey = (np.asarray(v, np.float64) for v in (s, ex, ey))
    far = s + ex + ey
    return (spherical_triangle_solid_angle(s, s + ex, far, p)
            + spherical_triangle_solid_angle(s, far, s + ey, p))


def sample_spherical_rectangle(u, s, ex, ey, p):
    """Points on rectangles whose directions from ``p`` are uniform over the solid angle.

    Ureña, Fajardo and King 2013, "An area-preserving parametrization for spherical
    rectangles": ``u[:, 0]`` picks the x coordinate by the area to its left, ``u[:, 1]`` the y
    coordinate along that column by the cosine-like parameter ``h``.

    Parameters
    ----------
    u : (n, 2) float
    s, ex, ey : (n, 3) float
        Corner and orthogonal edges of each rectangle.
    p : (n, 3) float
        Viewpoints, not in the rectangle's plane.

    Returns
    -------
    (n, 3) float64
        Points on the rectangles; the directions ``normalize(q - p)`` have density
        :func:`spherical_rectangle_pdf`.
    """
    u = np.asarray(u, np.float64)
    p = np.asarray(p, np.float64)
    fx, fy, fz, x0, y0, z0, x1, y1 = _rectangle_frame(s, ex, ey, p)
    b0, b1, g0, g1, g2, g3, area = _rectangle_angles(x0, y0, z0, x1, y1)
    # The x coordinate: the sub-rectangle left of it has area u0 * area.
    au = u[:, 0] * (g0 + g1 - 2.0 * np.pi) + (u[:, 0] - 1.0) * (g2 + g3)
    with quiet("invalid", "divide"):
        fu = (np.cos(au) * b0 - b1) / np.sin(au)
        cu = np.copysign(1.0, fu) / np.sqrt(fu * fu + b0 * b0)
        cu = np.clip(np.nan_to_num(cu), -_ONE_MINUS, _ONE_MINUS)
        xu = -(cu * z0) / np.sqrt(np.maximum(0.0, 1.0 - cu * cu))
    xu = np.clip(np.nan_to_num(xu), x0, x1)
    # The y coordinate: h (the sine of the elevation along the column) is uniform.
    dd = np.sqrt(xu * xu + z0 * z0)
    h0 = y0 / np.sqrt(dd * dd + y0 * y0)
    h1 = y1 / np.sqrt(dd * dd + y1 * y1)
    hv = h0 + u[:, 1] * (h1 - h0)
    hv2 = hv * hv
    with quiet("invalid", "divide"):
        yv = np.where(hv2 < 1.0 - 1e-12, hv * dd / np.sqrt(np.maximum(1.0 - hv2, 1e-300)), y1)
    yv = np.clip(np.nan_to_num(yv), y0, y1)
    return p + xu[:, None] * fx + yv[:, None] * fy + z0[:, None] * fz


def spherical_rectangle_pdf(s, ex, ey, p):
    """Solid-angle density of :func:`sample_spherical_rectangle`: 1 / solid angle, ``(n,)``."""
    omega = spherical_rectangle_solid_angle(s, ex, ey, p)
    with quiet("divide"):
        return np.where(omega > 0, 1.0 / np.where(omega > 0, omega, 1.0), 0.0)


def invert_spherical_rectangle_sample(q, s, ex, ey, p):
    """Inverse of :func:`sample_spherical_rectangle`: points ``q (n, 3)`` -> ``u (n, 2)``.

    ``q`` may also be any point along the ray from ``p`` through the rectangle.
    """
    p = np.asarray(p, np.float64)
    fx, fy, fz, x0, y0, z0, x1, y1 = _rectangle_frame(s, ex, ey, p)
    b0, b1, g0, g1, g2, g3, area = _rectangle_angles(x0, y0, z0, x1, y1)
    v = np.asarray(q, np.float64) - p
    # Project along the ray onto the rectangle's plane z = z0.
    with quiet("invalid", "divide"):
        scale = z0 / _dot(v, fz)
    xu = np.clip(_dot(v, fx) * scale, x0, x1)
    yv = np.clip(_dot(v, fy) * scale, y0, y1)
    # u0: invert cu = xu / sqrt(xu^2 + z0^2) -> fu -> the sub-rectangle's angle sum au.
    with quiet("invalid", "divide"):
        cu = xu / np.sqrt(xu * xu + z0 * z0)
        fu = np.copysign(np.sqrt(np.maximum(0.0, 1.0 / (cu * cu) - b0 * b0)), cu)
        # Solve b0 cos(au) - fu sin(au) = b1, i.e. R cos(au + phi) = b1: two roots per turn;
        # the one inside the range that u0 in [0, 1] sweeps is the answer.
        r = np.sqrt(b0 * b0 + fu * fu)
        phi = np.arctan2(fu, b0)
        half = np.arccos(np.clip(b1 / r, -1.0, 1.0))
    lo, hi = -(g2 + g3), g0 + g1 - 2.0 * np.pi
    mid = 0.5 * (lo + hi)
    roots = np.stack([-phi + half, -phi - half], axis=-1)
    # Bring each root to the turn nearest the range, then keep the nearer one.
    roots = roots - 2.0 * np.pi * np.round((roots - mid[:, None]) / (2.0 * np.pi))
    miss = np.maximum(lo[:, None] - roots, 0.0) + np.maximum(roots - hi[:, None], 0.0)
    au = np.take_along_axis(roots, np.argmin(miss, axis=1)[:, None], axis=1)[:, 0]
    with quiet("invalid", "divide"):
        u0 = (au + g2 + g3) / area
    # u1: h of the column is uniform between h0 and h1.
    dd = np.sqrt(xu * xu + z0 * z0)
    h0 = y0 / np.sqrt(dd * dd + y0 * y0)
    h1 = y1 / np.sqrt(dd * dd + y1 * y1)
    hv = yv / np.sqrt(dd * dd + yv * yv)
    with quiet("invalid", "divide"):
        u1 = (hv - h0) / (h1 - h0)
    u = np.stack([np.nan_to_num(u0), np.nan_to_num(u1)], axis=-1)
    return np.clip(u, 0.0, 1.0)
