"""Camera rays reproduce Blender's projection: sensor fit, lens, shift, pixel aspect, clipping.

The reference is Blender's view plane (``BKE_camera_params_compute_viewplane``), written here in
its own terms rather than ``core.camera``'s: with ``ycor = aspect_y / aspect_x`` and the fitted
dimension ``viewfac`` (``width`` for a horizontal fit, ``ycor * height`` for a vertical one;
AUTO fits the larger of ``width * aspect_x`` and ``height * aspect_y``, ties horizontal, and
always uses the sensor *width*), a raster position ``(px, py)`` (pixels from the bottom-left
corner) maps to the view plane at unit distance as

    x = (px - width / 2 + shift_x * viewfac) * s
    y = (ycor * (py - height / 2) + shift_y * viewfac) * s

with ``s = sensor / lens / viewfac`` (perspective; ``ortho_scale / viewfac`` orthographic):
the fitted dimension spans ``sensor / lens`` at unit distance and the shift is in units of it.
A world point projects with the pinhole formula ``(X / -Z, Y / -Z)`` in camera space.
Comparisons are to float64 rounding.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from sampling_lab.core.camera import generate_rays, project, view_extent
from sampling_lab.core.scene import Camera
from tests.helpers import random_rigid

RESOLUTIONS = {"landscape": (64, 36), "portrait": (30, 48), "square": (40, 40)}
FITS = ("AUTO", "HORIZONTAL", "VERTICAL")
SHIFTS = ((0.0, 0.0), (0.15, -0.3))
ASPECTS = ((1.0, 1.0), (2.0, 1.0), (1.0, 1.6))


def camera_matrix(seed=0, scale=(1.0, 1.0, 1.0)):
    """A rotated, translated camera object matrix (optionally with object scale)."""
    return random_rigid(seed, scale=scale, spread=5.0)


def make_camera(res="landscape", fit="AUTO", shift=(0.0, 0.0), aspect=(1.0, 1.0),
                kind="PERSP", **kw):
    w, h = RESOLUTIONS[res]
    return Camera(to_world=kw.pop("to_world", camera_matrix()), width=w, height=h, type=kind,
                  lens=kw.pop("lens", 35.0), sensor_width=36.0, sensor_height=24.0,
                  sensor_fit=fit, shift_x=shift[0], shift_y=shift[1], clip_start=0.1,
                  clip_end=100.0, ortho_scale=kw.pop("ortho_scale", 7.0),
                  pixel_aspect_x=aspect[0], pixel_aspect_y=aspect[1], **kw)


def blender_view_plane(cam):
    """(scale s, viewfac, ycor) of Blender's view plane at unit distance (see module doc)."""
    ycor = cam.pixel_aspect_y / cam.pixel_aspect_x
    fit = cam.sensor_fit
    if fit == "AUTO":
        horizontal = cam.pixel_aspect_x * cam.width >= cam.pixel_aspect_y * cam.height
        sensor = cam.sensor_width
    else:
        horizontal = fit == "HORIZONTAL"
        sensor = cam.sensor_width if horizontal else cam.sensor_height
    viewfac = cam.width if horizontal else ycor * cam.height
    span = cam.ortho_scale if cam.type == "ORTHO" else sensor / cam.lens
    return span / viewfac, viewfac, ycor


def raster_to_plane(cam, pxy):
    s, viewfac, ycor = blender_view_plane(cam)
    x = (pxy[:, 0] - cam.width / 2 + cam.shift_x * viewfac) * s
    y = (ycor * (pxy[:, 1] - cam.height / 2) + cam.shift_y * viewfac) * s
    return x, y


def plane_to_raster(cam, x, y):
    s, viewfac, ycor = blender_view_plane(cam)
    px = x / s + cam.width / 2 - cam.shift_x * viewfac
    py = (y / s - cam.shift_y * viewfac) / ycor + cam.height / 2
    return np.stack([px, py], axis=-1)


def camera_frame(cam):
    """Unscaled rotation (columns x, y, z of the camera) and position."""
    m = np.asarray(cam.to_world, np.float64)
    rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
    return rot, m[:3, 3]


def distance_to_rays(points, origins, directions):
    d = points - origins
    along = np.einsum("ij,ij->i", d, directions)
    return np.linalg.norm(d - along[:, None] * directions, axis=1), along


def random_points_in_view(cam, n=64, seed=0):
    """World points in front of the camera, inside the frame, and their raster positions."""
    rng = np.random.default_rng(seed)
    pxy = rng.random((n, 2)) * [cam.width, cam.height]
    x, y = raster_to_plane(cam, pxy)
    depth = rng.uniform(1.0, 50.0, n)
    rot, pos = camera_frame(cam)
    if cam.type == "ORTHO":
        local = np.stack([x, y, -depth], axis=-1)
    else:
        local = np.stack([x * depth, y * depth, -depth], axis=-1)
    return pos + local @ rot.T, pxy


CASES = list(itertools.product(RESOLUTIONS, FITS, SHIFTS, ASPECTS))


def _id(case):
    res, fit, shift, aspect = case
    return f"{res}-{fit}-shift{shift[0]:g},{shift[1]:g}-aspect{aspect[0]:g}x{aspect[1]:g}"


# --------------------------------------------------------------------------------------------
# Perspective projection
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", CASES, ids=[_id(c) for c in CASES])
def test_perspective_ray_through_projected_point_passes_through_it(case):
    res, fit, shift, aspect = case
    cam = make_camera(res, fit, shift, aspect)
    rot, pos = camera_frame(cam)
    rng = np.random.default_rng(1)
    # Points anywhere in front of the camera (not only in frame); project with the pinhole
    # formula and Blender's view plane, then the ray through that film position must hit them.
    local = rng.normal(size=(200, 3)) * [4, 4, 1]
    local[:, 2] = -np.abs(local[:, 2]) - 0.5
    points = pos + local @ rot.T
    pxy = plane_to_raster(cam, local[:, 0] / -local[:, 2], local[:, 1] / -local[:, 2])
    o, d, tmax = generate_rays(cam, pxy)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-14)
    miss, along = distance_to_rays(points, o, d)
    assert np.all(along > 0), "the point lies behind the ray"
    assert miss.max() < 1e-12 * np.linalg.norm(local, axis=1).max()


@pytest.mark.parametrize("scale, shift", [((1.0, 1.0, 1.0), (0.15, -0.3)),
                                          ((0.5, 2.0, 1.5), (0.0, 0.0))])
def test_project_axis_by_axis_equals_einsum_form_to_the_bit(scale, shift):
    # core.camera.project forms camera space one axis at a time: the same values as the
    # einsum form it replaced (products added in order, |local|^2 as (x x + z z) + y y),
    # for points in front of, beside and behind the camera.
    cam = make_camera("landscape", "AUTO", shift, to_world=camera_matrix(3, scale))
    points = np.random.default_rng(2).normal(size=(5000, 3)) * 6.0
    film_xy, visible, cos_theta, dist = project(cam, points, 1.5)
    m = np.asarray(cam.to_world, np.float64)
    rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0, keepdims=True)
    local = np.einsum("ij,jk->ik", points - m[:3, 3], rot)
    depth = -local[:, 2]
    ref_dist = np.sqrt(np.einsum("ij,ij->i", local, local))
    half_x, half_y, sx, sy = view_extent(cam)
    with np.errstate(divide="ignore", invalid="ignore"):
        fx = ((local[:, 0] / depth - sx) / (2.0 * half_x) + 0.5) * cam.width
        fy = ((local[:, 1] / depth - sy) / (2.0 * half_y) + 0.5) * cam.height
    ref_visible = ((depth > 0) & (depth >= cam.clip_start) & (depth <= cam.clip_end)
                   & (fx >= -1.5) & (fx < cam.width + 1.5) & (fy >= -1.5)
                   & (fy < cam.height + 1.5))
    assert np.array_equal(visible, ref_visible)
    assert 0 < visible.sum() < visible.size
    assert np.array_equal(dist, ref_dist)
    assert np.array_equal(cos_theta[visible], (depth / ref_dist)[visible])
    assert np.array_equal(film_xy[visible], np.stack([fx, fy], axis=1)[visible])


def test_fitted_dimension_spans_sensor_over_lens_landscape():
    # 36 mm sensor, 50 mm lens, horizontal fit: the frame's half width is tan = 0.36.
    cam = make_camera("landscape", "HORIZONTAL", lens=50.0, to_world=np.eye(4))
    w, h = cam.width, cam.height
    o, d, _ = generate_rays(cam, np.array([[w, h / 2], [0, h / 2], [w / 2, h], [w / 2, 0]]))
    tan = d[:, :2] / -d[:, 2:3]
    np.testing.assert_allclose(tan[0], [0.36, 0.0], atol=1e-15)
    np.testing.assert_allclose(tan[1], [-0.36, 0.0], atol=1e-15)
    np.testing.assert_allclose(tan[2], [0.0, 0.36 * h / w], atol=1e-15)
    np.testing.assert_allclose(tan[3], [0.0, -0.36 * h / w], atol=1e-15)  # film y=0: bottom


def test_auto_fit_of_portrait_fits_the_height_to_the_sensor_width():
    cam = make_camera("portrait", "AUTO", lens=50.0, to_world=np.eye(4))
    w, h = cam.width, cam.height
    _, d, _ = generate_rays(cam, np.array([[w / 2, h], [w, h / 2]]))
    tan = d[:, :2] / -d[:, 2:3]
    np.testing.assert_allclose(tan[0], [0.0, 0.36], atol=1e-15)
    np.testing.assert_allclose(tan[1], [0.36 * w / h, 0.0], atol=1e-15)


@pytest.mark.parametrize("res", ["landscape", "portrait"])
def test_shift_is_in_units_of_the_fitted_dimension(res):
    # AUTO fits the larger dimension (36 mm / 50 mm = 0.72 wide at unit distance) in both
    # orientations, so a shift of 0.25 moves the image centre by 0.18 either way.
    cam = make_camera(res, "AUTO", (0.25, -0.5), lens=50.0, to_world=np.eye(4))
    _, d, _ = generate_rays(cam, np.array([[cam.width / 2, cam.height / 2]]))
    np.testing.assert_allclose(d[0, :2] / -d[0, 2], [0.18, -0.36], atol=1e-15)


def test_pixel_aspect_stretches_pixels_not_the_fitted_span():
    # Pixels twice as wide: 64 x 36 pixels of aspect 2:1 are 128 x 36 wide; the width still
    # spans the sensor, and the height spans 36 / 128 of it.
    cam = make_camera("landscape", "AUTO", aspect=(2.0, 1.0), lens=50.0, to_world=np.eye(4))
    _, d, _ = generate_rays(cam, np.array([[cam.width, cam.height / 2], [cam.width / 2, 0]]))
    tan = d[:, :2] / -d[:, 2:3]
    np.testing.assert_allclose(tan[0], [0.36, 0.0], atol=1e-15)
    np.testing.assert_allclose(tan[1], [0.0, -0.36 * 36 / 128], atol=1e-15)


def test_camera_object_scale_does_not_change_rays():
    """Cycles clears the camera object's scale (transform_clear_scale)."""
    pxy = np.random.default_rng(2).random((50, 2)) * [64, 36]
    plain = generate_rays(make_camera(to_world=camera_matrix(3)), pxy)
    scaled = generate_rays(make_camera(to_world=camera_matrix(3, scale=(2.0, 0.5, 3.0))), pxy)
    for a, b in zip(plain, scaled):
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13)


# --------------------------------------------------------------------------------------------
# Clipping planes
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_clipping_distances_are_planes_perpendicular_to_the_view_axis(kind):
    cam = make_camera("landscape", "AUTO", (0.2, 0.1), kind=kind, lens=18.0)
    rot, pos = camera_frame(cam)
    forward = -rot[:, 2]
    # Corners and edges of a wide frame: the distance along each ray differs, the depth not.
    pxy = np.array([[0, 0], [64, 36], [0, 36], [64, 0], [32, 18], [5.5, 30.25]], np.float64)
    o, d, tmax = generate_rays(cam, pxy)
    np.testing.assert_allclose((o - pos) @ forward, cam.clip_start, rtol=1e-12)
    far = o + d * tmax[:, None]
    np.testing.assert_allclose((far - pos) @ forward, cam.clip_end, rtol=1e-12)
    assert np.all(tmax > 0)


# --------------------------------------------------------------------------------------------
# Orthographic
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", CASES, ids=[_id(c) for c in CASES])
def test_orthographic_ray_through_projected_point_passes_through_it(case):
    res, fit, shift, aspect = case
    cam = make_camera(res, fit, shift, aspect, kind="ORTHO")
    points, pxy = random_points_in_view(cam, seed=4)
    o, d, _ = generate_rays(cam, pxy)
    miss, along = distance_to_rays(points, o, d)
    assert np.all(along > 0)
    assert miss.max() < 1e-12 * 100


def test_orthographic_scale_spans_the_fitted_dimension_and_directions_are_equal():
    for res, fitted_axis, other in (("landscape", 0, 1), ("portrait", 1, 0)):
        cam = make_camera(res, "AUTO", kind="ORTHO", ortho_scale=7.0)
        rot, _ = camera_frame(cam)
        w, h = cam.width, cam.height
        pxy = np.array([[0, h / 2], [w, h / 2], [w / 2, 0], [w / 2, h]], np.float64)
        o, d, _ = generate_rays(cam, pxy)
        np.testing.assert_allclose(d, np.broadcast_to(-rot[:, 2], d.shape), atol=1e-15)
        width_span = np.linalg.norm(o[1] - o[0])
        height_span = np.linalg.norm(o[3] - o[2])
        spans = (width_span, height_span)
        assert spans[fitted_axis] == pytest.approx(7.0, rel=1e-13)
        ratio = (h / w) if fitted_axis == 0 else (w / h)
        assert spans[other] == pytest.approx(7.0 * ratio, rel=1e-13)
