"""Camera rays exactly as Blender and Cycles frame them (sensor fit, lens, shift, clipping)."""

from __future__ import annotations

import numpy as np

from .scene import Camera
from .quiet import quiet


def view_extent(cam: Camera):
    """Half extents and shift of the view plane at unit distance (perspective) or in units.

    Returns
    -------
    half_x, half_y, shift_x, shift_y : float
        For a perspective camera, in tangent units at distance 1; for an orthographic camera,
        in Blender units.
    """
    x_ratio = cam.width * cam.pixel_aspect_x
    y_ratio = cam.height * cam.pixel_aspect_y
    if cam.sensor_fit == "AUTO":
        horizontal, sensor = x_ratio > y_ratio, cam.sensor_width
    elif cam.sensor_fit == "HORIZONTAL":
        horizontal, sensor = True, cam.sensor_width
    else:
        horizontal, sensor = False, cam.sensor_height
    span = cam.ortho_scale if cam.type == "ORTHO" else sensor / cam.lens
    if horizontal:
        half_x, half_y = 0.5 * span, 0.5 * span * y_ratio / x_ratio
    else:
        half_x, half_y = 0.5 * span * x_ratio / y_ratio, 0.5 * span
    return half_x, half_y, cam.shift_x * span, cam.shift_y * span


def generate_rays(cam: Camera, film_xy):
    """Rays through continuous film positions.

    Parameters
    ----------
    cam : Camera
    film_xy : (n, 2) float64
        Positions in pixels, x from the left and y from the bottom edge of the image.

    Returns
    -------
    origins : (n, 3) float64
        Already moved to the near clipping plane.
    directions : (n, 3) float64
        Unit vectors.
    tmax : (n,) float64
        Distance from the origin to the far clipping plane.
    """
    half_x, half_y, sx, sy = view_extent(cam)
    px = (film_xy[:, 0] / cam.width - 0.5) * 2.0 * half_x + sx
    py = (film_xy[:, 1] / cam.height - 0.5) * 2.0 * half_y + sy
    m = np.asarray(cam.to_world, np.float64)
    rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0, keepdims=True)
    pos = m[:3, 3]
    n = film_xy.shape[0]
    if cam.type == "ORTHO":
        local_o = np.stack([px, py, np.zeros(n)], axis=-1)
        origins = pos + np.einsum("ij,kj->ik", local_o, rot)
        d = np.broadcast_to(-rot[:, 2], (n, 3)).copy()
        origins = origins + d * cam.clip_start
        tmax = np.full(n, cam.clip_end - cam.clip_start)
        return origins, d, tmax
    # The camera-space direction (px, py, -1), normalised and rotated one world axis at a
    # time: no (n, 3) x (3, 3) product, which would wake multi-threaded BLAS (its spinning
    # threads steal the core the second render thread needs) or go through einsum's slower
    # general loop.
    length = px * px
    length += py * py
    length += 1.0
    np.sqrt(length, out=length)
    ux, uy = px / length, py / length
    uz = -1.0 / length
    # Clipping planes are perpendicular to the view axis, as in Cycles.
    t_near = cam.clip_start * length
    d, origins = np.empty((n, 3)), np.empty((n, 3))
    for k in range(3):
        column = d[:, k]
        np.multiply(ux, rot[k, 0], out=column)
        column += uy * rot[k, 1]
        column += uz * rot[k, 2]
        np.multiply(column, t_near, out=origins[:, k])
        origins[:, k] += pos[k]
    tmax = (cam.clip_end - cam.clip_start) * length
    return origins, d, tmax


def film_plane_area(cam: Camera):
    """Area of the whole film on the plane at unit distance (perspective), tangent units^2."""
    half_x, half_y, _, _ = view_extent(cam)
    return 4.0 * half_x * half_y


def camera_position(cam: Camera):
    """The pinhole's world position ``(3,)`` float64."""
    return np.asarray(cam.to_world, np.float64)[:3, 3].copy()


def project(cam: Camera, p, margin=0.0, window=None):
    """Where points ``p (n, 3)`` land on the film of a perspective camera (inverse of
    :func:`generate_rays`).

    ``margin`` (pixels) widens the film on every side: with a pixel filter wider than a pixel,
    camera rays of edge pixels leave through film positions up to half the filter's width
    outside the image, and light paths arriving there must still reach those pixels.
    ``window = (x0, y0, x1, y1)`` (frame pixels, a render region) narrows the film to that
    window before the margin widens it; None is the whole frame.

    Returns
    -------
    film_xy : (n, 2) float64
        Film position in frame pixels (x from the left, y from the bottom); may lie outside.
    visible : (n,) bool
        In front of the camera, between the clipping planes and inside the film's extent (the
        window's, widened by ``margin``).
    cos_theta : (n,) float64
        Cosine between the view axis and the direction to the point.
    dist : (n,) float64
        Distance from the pinhole.
    """
    if cam.type != "PERSP":
        raise ValueError("only perspective cameras can be reached from light paths")
    half_x, half_y, sx, sy = view_extent(cam)
    m = np.asarray(cam.to_world, np.float64)
    rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0, keepdims=True)
    # Camera space one contiguous axis at a time, with the sums einsum forms:
    # ``einsum("ij,jk->ik", p - pos, rot)`` adds the products in order j = 0, 1, 2, and
    # ``einsum("ij,ij->i", local, local)`` as ``(x x + z z) + y y``
    # (tests/core/test_camera.py: the same values to the bit). 1.33 -> 0.82 ms on 39 k points
    # (the bench box's light vertices per BDPT unit), no (n, 3) tables and no strided reads.
    rel = [p[:, j] - m[j, 3] for j in range(3)]
    # depth = -z formed with the negated axis: the same values (negation is exact and
    # rounding symmetric), one pass fewer.
    lx, ly, depth = (_row_dot(rel, r) for r in (rot[:, 0], rot[:, 1], -rot[:, 2]))
    dist = lx * lx
    dist += depth * depth
    dist += ly * ly
    np.sqrt(dist, out=dist)
    with quiet("divide", "invalid"):
        tx = lx / depth
        ty = ly / depth
        cos_theta = depth / dist
    # Straight into the columns of one (n, 2) table (no stack copy).
    film_xy = np.empty((p.shape[0], 2))
    fx, fy = film_xy[:, 0], film_xy[:, 1]
    # Without a lens shift, t - 0.0 is t (to the bit, -0.0 and NaN included): not formed.
    np.multiply((tx - sx if sx else tx) / (2.0 * half_x) + 0.5, cam.width, out=fx)
    np.multiply((ty - sy if sy else ty) / (2.0 * half_y) + 0.5, cam.height, out=fy)
    x0, y0, x1, y1 = window if window is not None else (0, 0, cam.width, cam.height)
    # The bounds hold for finite coordinates only (NaN and +-Inf fail one of each axis'
    # two comparisons), so no isfinite test is needed for ``visible``; depth > 0 follows
    # from depth >= clip_start where that is positive.
    visible = (depth >= cam.clip_start) & (depth <= cam.clip_end)
    if not cam.clip_start > 0:
        visible &= depth > 0
    visible &= (fx >= x0 - margin) & (fx < x1 + margin) & (fy >= y0 - margin) & (fy < y1 + margin)
    if not visible.all():  # the positions of hidden points may be NaN or Inf
        np.copyto(film_xy, -1.0, where=~np.isfinite(film_xy))
        cos_theta[~visible] = 0.0
    return film_xy, visible, cos_theta, dist


def _row_dot(columns, r):
    """``columns[0] * r[0] + columns[1] * r[1] + columns[2] * r[2]`` ``(n,)``, added left to
    right, for three ``(n,)`` columns and a ``(3,)`` vector."""
    out = columns[0] * r[0]
    out += columns[1] * r[1]
    out += columns[2] * r[2]
    return out


def importance(cam: Camera, cos_theta):
    """Importance ``W_e`` per pixel of a pinhole toward a direction at ``cos_theta (n,)`` from
    the view axis, before the pixel filter: ``1 / (A_pixel cos^3 theta)``, with ``A_pixel`` a
    pixel's area on the plane at unit distance. A light-path vertex at distance ``r`` seen
    through it adds ``beta f |cos| W_e / r^2`` times the filter's weight to a pixel (see
    :meth:`core.film.Film.splat`); camera samples of the same pixel estimate the same integral.

    The density of camera rays in that direction, one per light path, is
    ``1 / (A_film cos^3 theta)`` (:func:`camera_pdf`).
    """
    a_pixel = film_plane_area(cam) / (cam.width * cam.height)
    c = np.asarray(cos_theta, np.float64)
    front = c > 0
    with quiet("divide"):
        if front.all():  # points in view (the splats'): no selection, the same values
            return 1.0 / (a_pixel * c**3)
        return np.where(front, 1.0 / (a_pixel * c**3), 0.0)


def camera_pdf(cam: Camera, cos_theta, pixels=None):
    """Solid-angle density ``(n,)`` of a camera ray in a direction at ``cos_theta`` from the
    view axis (uniform over the film): ``1 / (A_film cos^3 theta)``; zero behind the camera.

    ``pixels`` is the number of pixels the camera rays are drawn over when that is not the
    whole frame (a render region): the film area is then that many pixels' area.
    """
    c = np.asarray(cos_theta, np.float64)
    area = film_plane_area(cam)
    if pixels is not None:
        area *= pixels / (cam.width * cam.height)
    front = c > 0
    with quiet("divide"):
        if front.all():  # directions in view (the splats'): no selection, the same values
            return 1.0 / (area * c**3)
        return np.where(front, 1.0 / (area * c**3), 0.0)
