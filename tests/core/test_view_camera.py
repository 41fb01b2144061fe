"""The viewport's camera: Blender's view and window matrices, camera view, reduced films.

References are written in their own terms: the window matrix is OpenGL's ``glFrustum`` /
``glOrtho`` of a view plane (Blender's ``perspective_m4`` / ``orthographic_m4``), and a ray
through region pixel ``(px, py)`` must project back to the normalised device coordinates
``(2 px / width - 1, 2 py / height - 1)``, from depth -1 at its origin (the near clipping plane)
to +1 at its end (the far one). Camera view follows ``BKE_camera_params_from_view3d``: the zoom
factor ``f = (sqrt(2) + zoom / 50)^2 / 4`` shrinks the camera frame to ``f`` times the region
(same shape as the render) and the offset ``(dx, dy)`` moves it by ``-2 f (dx, dy)`` region
sizes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sampling_lab.core.camera import generate_rays
from sampling_lab.core.scene import Camera
from sampling_lab.core.view_camera import (camera_frame, camera_from_matrices,
                                           camera_view_camera, film_camera, zoom_factor)
from tests.helpers import random_rigid

FIT_ZOOM = 50.0 * (2.0 - math.sqrt(2.0))  # zoom factor 1: the frame fills the region


def rigid(seed):
    return random_rigid(seed, spread=4.0)


def frustum(l, r, b, t, n, f):
    """glFrustum: the plane (l, r, b, t) at distance n, far plane at f."""
    return np.array([[2 * n / (r - l), 0, (r + l) / (r - l), 0],
                     [0, 2 * n / (t - b), (t + b) / (t - b), 0],
                     [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)],
                     [0, 0, -1, 0]])


def ortho(l, r, b, t, n, f):
    """glOrtho."""
    return np.array([[2 / (r - l), 0, 0, -(r + l) / (r - l)],
                     [0, 2 / (t - b), 0, -(t + b) / (t - b)],
                     [0, 0, -2 / (f - n), -(f + n) / (f - n)],
                     [0, 0, 0, 1]])


def ndc(proj, view, p):
    h = np.einsum("ij,nj->ni", proj @ view, np.c_[p, np.ones(len(p))])
    return h[:, :3] / h[:, 3:]


def film_points(width, height, n=64, seed=1):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, 1, (n, 2)) * [width, height]


def render_camera(kind="PERSP", fit="AUTO", shift=(0.0, 0.0), size=(64, 36), seed=3):
    return Camera(to_world=rigid(seed), width=size[0], height=size[1], type=kind, lens=42.0,
                  sensor_width=36.0, sensor_height=24.0, sensor_fit=fit, shift_x=shift[0],
                  shift_y=shift[1], clip_start=0.2, clip_end=80.0, ortho_scale=5.0)


def assert_same_rays(cam_a, xy_a, cam_b, xy_b):
    oa, da, ta = generate_rays(cam_a, xy_a)
    ob, db, tb = generate_rays(cam_b, xy_b)
    np.testing.assert_allclose(da, db, atol=1e-12)
    np.testing.assert_allclose(oa, ob, atol=1e-10)
    np.testing.assert_allclose(ta, tb, rtol=1e-12)


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
@pytest.mark.parametrize("plane", [(-0.6, 0.6, -0.35, 0.35), (-0.2, 0.9, -0.7, 0.1)])
def test_rays_project_back_to_their_pixels(kind, plane):
    width, height = 50, 31
    if kind == "PERSP":
        near, far = 0.05, 300.0
        proj = frustum(plane[0] * near, plane[1] * near, plane[2] * near, plane[3] * near,
                       near, far)
    else:
        # Blender's orthographic viewport: clip_start = -clip_end / 2.
        near, far = -150.0, 150.0
        proj = ortho(*(3 * np.asarray(plane)), near, far)
    view = np.linalg.inv(rigid(7))
    cam = camera_from_matrices(view, proj, width, height)
    assert cam.type == kind
    xy = film_points(width, height)
    origins, directions, tmax = generate_rays(cam, xy)
    expected = 2.0 * xy / [width, height] - 1.0
    for t, depth in ((0.0, -1.0), (0.5, None), (1.0, 1.0)):
        p = ndc(proj, view, origins + directions * (t * tmax)[:, None])
        np.testing.assert_allclose(p[:, :2], expected, atol=1e-9)
        if depth is not None:
            np.testing.assert_allclose(p[:, 2], depth, atol=1e-9)


def test_zoom_factor_matches_blender():
    assert zoom_factor(0.0) == pytest.approx(0.5)
    assert zoom_factor(FIT_ZOOM) == pytest.approx(1.0)
    assert zoom_factor(-30.0) == pytest.approx((math.sqrt(2) - 0.6) ** 2 / 4)


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
@pytest.mark.parametrize("fit,size", [("AUTO", (64, 36)), ("AUTO", (30, 48)),
                                      ("HORIZONTAL", (30, 48)), ("VERTICAL", (64, 36))])
def test_camera_view_filling_the_region_is_the_render_camera(kind, fit, size):
    cam = render_camera(kind, fit, shift=(0.1, -0.2), size=size)
    view = camera_view_camera(cam, size[0], size[1], FIT_ZOOM, (0.0, 0.0))
    xy = film_points(*size)
    assert_same_rays(view, xy, cam, xy)


@pytest.mark.parametrize("zoom", [0.0, 20.0, -10.0])
@pytest.mark.parametrize("offset", [(0.0, 0.0), (0.1, -0.05)])
@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_camera_view_frame_holds_the_render_image(zoom, offset, kind):
    # A region twice the render size, as Blender's camera view draws it.
    cam = render_camera(kind, "AUTO", shift=(-0.15, 0.05), size=(64, 36))
    width, height = 128, 72
    fac = zoom_factor(zoom)
    frame = camera_frame(cam, width, height, zoom, offset)
    expected = (width * (0.5 - 2 * fac * offset[0] - fac / 2),
                width * (0.5 - 2 * fac * offset[0] + fac / 2),
                height * (0.5 - 2 * fac * offset[1] - fac / 2),
                height * (0.5 - 2 * fac * offset[1] + fac / 2))
    np.testing.assert_allclose(frame, expected, atol=1e-9)
    view = camera_view_camera(cam, width, height, zoom, offset)
    xy = film_points(64, 36)
    region_xy = np.c_[frame[0] + xy[:, 0] / 64 * (frame[1] - frame[0]),
                      frame[2] + xy[:, 1] / 36 * (frame[3] - frame[2])]
    assert_same_rays(view, region_xy, cam, xy)


def test_camera_view_of_another_shape_keeps_the_render_rays_inside_the_frame():
    # A portrait region looking through a landscape camera: Blender fits the sensor to the
    # region (AUTO -> vertical: the frame's height is the zoom factor times the region's, its
    # width may pass the region's sides) and draws the frame where the render's plane lies.
    cam = render_camera("PERSP", "AUTO", shift=(0.2, 0.1), size=(64, 36))
    width, height = 90, 160
    frame = camera_frame(cam, width, height, 5.0, (0.03, 0.02))
    assert frame[3] - frame[2] == pytest.approx(zoom_factor(5.0) * height * 36 / 64 * 1)
    # The frame keeps the render's shape.
    assert (frame[1] - frame[0]) / (frame[3] - frame[2]) == pytest.approx(64 / 36)
    view = camera_view_camera(cam, width, height, 5.0, (0.03, 0.02))
    xy = film_points(64, 36)
    region_xy = np.c_[frame[0] + xy[:, 0] / 64 * (frame[1] - frame[0]),
                      frame[2] + xy[:, 1] / 36 * (frame[3] - frame[2])]
    assert_same_rays(view, region_xy, cam, xy)


@pytest.mark.parametrize("divisor", [1, 2, 3, 8])
@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_film_camera_pixel_covers_its_region_pixels(divisor, kind):
    cam = camera_view_camera(render_camera(kind), 101, 57, 7.0, (0.02, 0.0))
    film = film_camera(cam, divisor)
    assert (film.width, film.height) == (-(-101 // divisor), -(-57 // divisor))
    xy = film_points(film.width, film.height)
    assert_same_rays(film, xy, cam, xy * divisor)


@pytest.mark.parametrize("kind,clip", [("PERSP", (0.5, 20.0)), ("ORTHO", (-7.0, 9.0))])
def test_given_clipping_distances_replace_the_matrix_ones(kind, clip):
    plane = (-0.6, 0.6, -0.35, 0.35)
    proj = (frustum(*(0.1 * np.asarray(plane)), 0.1, 100.0) if kind == "PERSP"
            else ortho(*plane, -50.0, 50.0))
    to_world = rigid(5)
    cam = camera_from_matrices(np.linalg.inv(to_world), proj, 40, 24, clip=clip)
    origins, directions, tmax = generate_rays(cam, film_points(40, 24))
    forward = -to_world[:3, 2]
    # Depth along the view axis, from the eye (Blender clips planes perpendicular to it).
    depth = lambda p: (p - to_world[:3, 3]) @ forward  # noqa: E731
    np.testing.assert_allclose(depth(origins), clip[0], atol=1e-9)
    np.testing.assert_allclose(depth(origins + directions * tmax[:, None]), clip[1], atol=1e-9)


@pytest.mark.parametrize("proj,size", [(np.zeros((4, 4)), (40, 30)),
                                       (frustum(-0.1, 0.1, -0.1, 0.1, 0.1, 10.0), (0, 30))])
def test_degenerate_views_raise_instead_of_making_nan_rays(proj, size):
    with pytest.raises(ValueError):
        camera_from_matrices(np.eye(4), proj, *size)
