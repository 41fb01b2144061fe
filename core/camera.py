"""Camera rays exactly as Blender and Cycles frame them (sensor fit, lens, shift, clipping)."""

from __future__ import annotations

import numpy as np

from .scene import Camera


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
    local_d = np.stack([px, py, -np.ones(n)], axis=-1)
    # einsum, not `@`: a (n, 3) x (3, 3) product would wake multi-threaded BLAS, whose spinning
    # threads steal the core the second render thread needs.
    length = np.sqrt(np.einsum("ij,ij->i", local_d, local_d))
    d = np.einsum("ij,kj->ik", local_d / length[:, None], rot)
    # Clipping planes are perpendicular to the view axis, as in Cycles.
    t_near = cam.clip_start * length
    origins = pos + d * t_near[:, None]
    tmax = (cam.clip_end - cam.clip_start) * length
    return origins, d, tmax
