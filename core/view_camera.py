"""The 3D viewport's camera as a :class:`core.scene.Camera`.

A viewport shows one of three views (``RegionView3D.view_perspective``):

- ``'PERSP'`` and ``'ORTHO'``, free views: Blender's view matrix (world to view) and window
  matrix (an OpenGL projection of the view plane between the clipping distances) say exactly what
  the region shows; :func:`camera_from_matrices` inverts them.
- ``'CAMERA'``, looking through the scene camera: Blender widens the camera's view plane to the
  whole region by the viewport's zoom and offset (``BKE_camera_params_from_view3d`` followed by
  ``BKE_camera_params_compute_viewplane``), so the camera frame drawn in the region holds exactly
  the final render's image. :func:`camera_view_camera` does the same starting from the camera
  the exporter built for final renders, so inside the frame both render the same rays.

A view plane is ``(left, right, bottom, top)``: at unit distance in front of the eye for a
perspective view (tangents), in Blender units for an orthographic one. Any plane is expressed as
a core camera with a horizontal sensor fit, the plane's width as its span, the lens shift as the
plane's centre and the pixel aspect ratio as the ratio of its sides, so core's ray generation
(:func:`core.camera.generate_rays`) needs no second code path.

Nothing here imports ``bpy``: matrices arrive as ``(4, 4)`` arrays (a ``mathutils.Matrix``
converts with ``np.array(m)``).
"""

from __future__ import annotations

import math

import numpy as np

from .camera import view_extent
from .scene import Camera

# Any sensor width would do: the view plane's width fixes lens / sensor_width.
_SENSOR_WIDTH = 36.0


def zoom_factor(camera_zoom):
    """Blender's camera-view zoom factor for ``RegionView3D.view_camera_zoom``.

    ``BKE_screen_view3d_zoom_to_fac``: ``(sqrt(2) + zoom / 50)^2 / 4``; 0.5 at zoom 0 (the camera
    frame spans half of the region's fitted dimension), 1 at ``50 (2 - sqrt(2))`` (the frame
    fills it).
    """
    return (math.sqrt(2.0) + float(camera_zoom) / 50.0) ** 2 / 4.0


def camera_plane(cam: Camera):
    """``(left, right, bottom, top)`` view plane of ``cam`` (:func:`core.camera.view_extent`)."""
    half_x, half_y, sx, sy = view_extent(cam)
    return (sx - half_x, sx + half_x, sy - half_y, sy + half_y)


def camera_from_plane(to_world, kind, plane, clip_start, clip_end, width, height):
    """A core camera whose film of ``width x height`` pixels spans ``plane``.

    Parameters
    ----------
    to_world : (4, 4) float64
        View to world (rotation columns are normalised here).
    kind : str
        ``'PERSP'`` or ``'ORTHO'``.
    plane : (4,) float
        ``(left, right, bottom, top)``, at unit distance (perspective) or in units (orthographic).
    clip_start, clip_end : float
        Clipping distances along the view axis (``clip_start`` may be negative for
        orthographic views: Blender's orthographic viewport sees behind its view point).
    width, height : int
        Film size in pixels.

    Returns
    -------
    Camera
    """
    left, right, bottom, top = (float(v) for v in plane)
    span = right - left
    if not (all(map(math.isfinite, (left, right, bottom, top))) and span > 0 and top > bottom
            and width > 0 and height > 0):
        raise ValueError(f"degenerate view plane {plane!r} or film {width} x {height}")
    m = np.array(to_world, np.float64)
    norms = np.linalg.norm(m[:3, :3], axis=0)
    m[:3, :3] /= np.where(norms > 0, norms, 1.0)
    return Camera(
        to_world=m, width=int(width), height=int(height), type=kind,
        lens=_SENSOR_WIDTH / span if kind == "PERSP" else 50.0,
        sensor_width=_SENSOR_WIDTH, sensor_height=_SENSOR_WIDTH, sensor_fit="HORIZONTAL",
        shift_x=0.5 * (left + right) / span, shift_y=0.5 * (bottom + top) / span,
        clip_start=float(clip_start), clip_end=float(clip_end),
        ortho_scale=span if kind == "ORTHO" else 6.0,
        # The pixel aspect carries the plane's height: view_extent gives half_y =
        # half_x * (height * aspect_y) / (width * aspect_x).
        pixel_aspect_x=1.0, pixel_aspect_y=(top - bottom) / span * width / height,
    )


def camera_from_matrices(view_matrix, window_matrix, width, height, clip=None):
    """The camera of a free viewport (``'PERSP'`` or ``'ORTHO'``) from Blender's matrices.

    Parameters
    ----------
    view_matrix : (4, 4) float
        World to view (``RegionView3D.view_matrix``).
    window_matrix : (4, 4) float
        Projection (``RegionView3D.window_matrix``): Blender's ``perspective_m4`` or
        ``orthographic_m4`` of the view plane between the clipping distances.
    width, height : int
        Region size in pixels.
    clip : (float, float) or None
        Clipping distances to use instead of the matrix's: the far distance read back from a
        float32 projection keeps only about three digits.

    Returns
    -------
    Camera
        Perspective when the projection divides by depth (``w = -z``), orthographic otherwise.
    """
    p = np.asarray(window_matrix, np.float64)
    if p[0, 0] == 0 or p[1, 1] == 0:
        raise ValueError("the window matrix projects nothing (not drawn yet?)")
    to_world = np.linalg.inv(np.asarray(view_matrix, np.float64))
    if abs(p[3, 3]) > 0.5:
        # orthographic_m4: x_ndc = (2 x - (r + l)) / (r - l), z_ndc = (-2 z - (f + n)) / (f - n)
        plane = ((-1.0 - p[0, 3]) / p[0, 0], (1.0 - p[0, 3]) / p[0, 0],
                 (-1.0 - p[1, 3]) / p[1, 1], (1.0 - p[1, 3]) / p[1, 1])
        near, far = clip or ((p[2, 3] + 1.0) / p[2, 2], (p[2, 3] - 1.0) / p[2, 2])
        return camera_from_plane(to_world, "ORTHO", plane, near, far, width, height)
    # perspective_m4 of the plane (l, r, b, t) at the near distance n: x_ndc w = (2 n x + (r +
    # l) z') / (r - l) with w = -z; at unit distance the plane is (l / n, r / n, ...).
    plane = ((p[0, 2] - 1.0) / p[0, 0], (p[0, 2] + 1.0) / p[0, 0],
             (p[1, 2] - 1.0) / p[1, 1], (p[1, 2] + 1.0) / p[1, 1])
    near, far = clip or (p[2, 3] / (p[2, 2] - 1.0), p[2, 3] / (p[2, 2] + 1.0))
    return camera_from_plane(to_world, "PERSP", plane, near, far, width, height)


def camera_view_plane(cam: Camera, width, height, camera_zoom=0.0, camera_offset=(0.0, 0.0)):
    """View plane of a region of ``width x height`` pixels looking through camera ``cam``.

    Blender's camera view: the camera's lens, sensor and shift with the zoom factor ``f`` of
    :func:`zoom_factor` and the offset ``(dx, dy)`` (``RegionView3D.view_camera_offset``). The
    sensor fit is decided on the region's shape (square pixels); with ``viewfac`` the fitted
    side in pixels and ``span`` the fitted sensor over the lens (or the orthographic scale),
    the plane is centred on ``shift * span + 2 (dx, dy) (width, height) span / viewfac`` with
    half extents ``(width, height) span / (2 f viewfac)``.

    Parameters
    ----------
    cam : Camera
        The final render's camera (:func:`addon.export.export_camera`).
    width, height : int
        Region size in pixels.
    camera_zoom : float
        ``RegionView3D.view_camera_zoom``.
    camera_offset : (2,) float
        ``RegionView3D.view_camera_offset``.

    Returns
    -------
    (4,) tuple of float
        ``(left, right, bottom, top)``.
    """
    fac = zoom_factor(camera_zoom)
    if cam.type == "ORTHO":
        span = cam.ortho_scale
    else:
        span = (cam.sensor_height if cam.sensor_fit == "VERTICAL" else cam.sensor_width) / cam.lens
    fit = cam.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if width >= height else "VERTICAL"
    viewfac = float(width if fit == "HORIZONTAL" else height)
    half_x = 0.5 * width * span / (fac * viewfac)
    half_y = 0.5 * height * span / (fac * viewfac)
    cx = cam.shift_x * span + 2.0 * camera_offset[0] * width * span / viewfac
    cy = cam.shift_y * span + 2.0 * camera_offset[1] * height * span / viewfac
    return (cx - half_x, cx + half_x, cy - half_y, cy + half_y)


def camera_view_camera(cam: Camera, width, height, camera_zoom=0.0, camera_offset=(0.0, 0.0)):
    """The camera of a region of ``width x height`` pixels in camera view through ``cam``.

    Same position, orientation, projection and clipping as ``cam``; the view plane of
    :func:`camera_view_plane`. Inside the camera frame it generates ``cam``'s rays.
    """
    plane = camera_view_plane(cam, width, height, camera_zoom, camera_offset)
    return camera_from_plane(cam.to_world, cam.type, plane, cam.clip_start, cam.clip_end,
                             width, height)


def camera_frame(cam: Camera, width, height, camera_zoom=0.0, camera_offset=(0.0, 0.0)):
    """Where the final render's image lies in a region in camera view, in region pixels.

    Returns
    -------
    (4,) tuple of float
        ``(x_min, x_max, y_min, y_max)`` from the region's bottom-left corner (Blender's camera
        border, ``ED_view3d_calc_camera_border``).
    """
    left, right, bottom, top = camera_view_plane(cam, width, height, camera_zoom, camera_offset)
    c_left, c_right, c_bottom, c_top = camera_plane(cam)
    sx, sy = width / (right - left), height / (top - bottom)
    return ((c_left - left) * sx, (c_right - left) * sx, (c_bottom - bottom) * sy,
            (c_top - bottom) * sy)


def film_camera(cam: Camera, pixel_size):
    """``cam`` rendered with ``pixel_size x pixel_size`` region pixels per film pixel.

    The film has ``ceil(width / pixel_size) x ceil(height / pixel_size)`` pixels and keeps the
    region's bottom-left corner and pixel grid: where the last film column or row reaches past
    the region, the view plane grows by the same fraction to the right or the top, so drawn at
    ``pixel_size`` times its size from the region's corner the film lines up with the view.

    Returns
    -------
    Camera
    """
    pixel_size = max(1, int(pixel_size))
    if pixel_size == 1:
        return cam
    width = -(-cam.width // pixel_size)
    height = -(-cam.height // pixel_size)
    left, right, bottom, top = camera_plane(cam)
    right = left + (right - left) * width * pixel_size / cam.width
    top = bottom + (top - bottom) * height * pixel_size / cam.height
    return camera_from_plane(cam.to_world, cam.type, (left, right, bottom, top), cam.clip_start,
                             cam.clip_end, width, height)
