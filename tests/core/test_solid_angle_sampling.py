"""Solid-angle sampling of emissive triangles and rectangular area lights.

The warps (spherical triangles, Arvo 1995; spherical rectangles, Ureña et al. 2013) must give
directions uniform over the emitter's solid angle (chi-square against 1 / solid angle, binned
around the emitter as in ``test_light_sampling.py``), invert exactly, and report the solid angle
that a numerical integral gives. Through ``LightSampler`` with ``light_sampling='solid_angle'``,
next-event estimation must still give the closed-form irradiance, its pdf must equal the pdf
that MIS assigns to the same direction found by a ray (including the fallback to area sampling
for tiny or degenerate solid angles), and for a large light close to the receiver its variance
must be lower than area sampling's, by a margin outside the two variances' confidence intervals.

Tolerances: chi-square at alpha = 1e-3; means within Student-t intervals at p_false = 1e-4
(tests/helpers.py); round trips at 1e-6 (float64 warps, worst cases near the edges).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sampling_lab.core import lights as L
from sampling_lab.core.metrics import normal_quantile
from sampling_lab.core.prepare import prepare
from sampling_lab.core.sampling import warps
from sampling_lab.core.scene import Lights
from sampling_lab.core.scenes import look_at
from tests.core.test_light_sampling import (
    P_WORLD,
    _area_case,
    chi_square_light,
    frame_around,
    make_scene,
    nee_directions,
    polygon_zone,
    shape_pdf,
    triangle_hit_pdf,
)
from tests.core.test_lights import polygon_irradiance
from tests.helpers import assert_mean_within_ci

N = 200_000
NRM = np.array([0.0, 0.0, 1.0])
P0 = np.array([0.1, -0.2, 0.0])

TRIANGLES = {
    # name: (vertices, viewpoint)
    "tilted": (np.array([[-0.5, -0.4, 1.0], [0.7, -0.2, 1.3], [0.1, 0.6, 0.9]]), P0),
    "large_close": (np.array([[-2.0, -2.0, 0.3], [2.5, -1.5, 0.4], [0.0, 2.5, 0.2]]), P0),
    "thin": (np.array([[-1.0, 0.0, 1.0], [1.0, 0.2, 1.0], [0.8, -0.1, 1.2]]), P0),
    "grazing": (np.array([[-1.0, 1.0, 0.05], [1.0, 1.0, 0.05], [0.0, 3.0, 0.6]]), P0),
}
RECTANGLES = {
    # name: (corner, edge x, edge y, viewpoint)
    "facing": ((-0.4, -0.3, 1.0), (0.8, 0.0, 0.0), (0.0, 0.6, 0.0), P0),
    "large_close": ((-2.0, -1.5, 0.25), (4.0, 0.0, 0.0), (0.0, 3.0, 0.0), P0),
    "tilted_offside": ((0.4, -0.5, 0.5), (0.8, 0.0, 0.5), (0.0, 1.0, 0.0), P0),
    "seen_from_behind": ((-0.4, -0.3, -1.0), (0.8, 0.0, 0.0), (0.0, 0.6, 0.0), P0),
}


def _b(x, n):
    return np.broadcast_to(np.asarray(x, np.float64), (n, 3))


def triangle_hit(o, d, a, b, c):
    """Whether rays ``(o, d)`` hit triangle ``(a, b, c)`` (Möller-Trumbore, both faces)."""
    e1, e2 = b - a, c - a
    pv = np.cross(d, e2)
    det = pv @ e1
    tv = o - a
    qv = np.cross(tv, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        u = (pv @ tv) * inv
        v = (d @ qv) * inv
        t = (e2 @ qv) * inv
    return (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)


def rectangle_hit(o, d, s, ex, ey):
    n = np.cross(ex, ey)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((s - o) @ n) / (d @ n)
        q = o + d * t[:, None] - s
    x, y = q @ ex / (ex @ ex), q @ ey / (ey @ ey)
    return (t > 0) & (x >= 0) & (x <= 1) & (y >= 0) & (y <= 1)


def uniform_pdf(hit_fn, p, frame, omega):
    """The claimed density: 1 / solid angle on the emitter, zero elsewhere (light frame)."""
    def pdf(w_local):
        d = w_local @ frame
        return hit_fn(p, d) / omega
    return pdf


def _triangle_case(name):
    tri, p = TRIANGLES[name]
    n = 1
    omega = float(warps.spherical_triangle_solid_angle(*(_b(v, n) for v in tri), _b(p, n))[0])
    axis = tri.mean(axis=0) - p
    zone, res = polygon_zone(p, axis, tri)
    return tri, p, omega, axis, zone, res


def _rect_case(name):
    s, ex, ey, p = (np.asarray(v, np.float64) for v in RECTANGLES[name])
    omega = float(warps.spherical_rectangle_solid_angle(_b(s, 1), _b(ex, 1), _b(ey, 1),
                                                        _b(p, 1))[0])
    corners = np.array([s, s + ex, s + ey, s + ex + ey])
    axis = s + 0.5 * (ex + ey) - p
    zone, res = polygon_zone(p, axis, corners)
    return s, ex, ey, p, omega, axis, zone, res


# --------------------------------------------------------------------------------------------
# The warps
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(TRIANGLES))
def test_spherical_triangle_directions_are_uniform_over_its_solid_angle(name):
    tri, p, omega, axis, zone, res = _triangle_case(name)
    frame = frame_around(axis)
    u = np.random.default_rng(1).random((N, 2))
    w = warps.sample_spherical_triangle(u, *(_b(v, N) for v in tri), _b(p, N))
    np.testing.assert_allclose(np.linalg.norm(w, axis=1), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(warps.spherical_triangle_pdf(*(_b(v, 3) for v in tri), _b(p, 3)),
                               1.0 / omega, rtol=1e-12)
    pdf = uniform_pdf(lambda o, d: triangle_hit(o, d, *tri), p, frame, omega)
    chi_square_light(w @ frame.T, pdf, zone, res, what=f"spherical triangle {name}")


@pytest.mark.parametrize("name", [k for k in RECTANGLES])
def test_spherical_rectangle_directions_are_uniform_over_its_solid_angle(name):
    s, ex, ey, p, omega, axis, zone, res = _rect_case(name)
    frame = frame_around(axis)
    u = np.random.default_rng(2).random((N, 2))
    q = warps.sample_spherical_rectangle(u, _b(s, N), _b(ex, N), _b(ey, N), _b(p, N))
    # Points lie on the rectangle.
    local = np.linalg.lstsq(np.stack([ex, ey], 1), (q - s).T, rcond=None)[0].T
    assert local.min() >= -1e-9 and local.max() <= 1 + 1e-9
    np.testing.assert_allclose((q - s) @ np.cross(ex, ey), 0.0, atol=1e-12)
    w = (q - p) / np.linalg.norm(q - p, axis=1, keepdims=True)
    pdf = uniform_pdf(lambda o, d: rectangle_hit(o, d, s, ex, ey), p, frame, omega)
    chi_square_light(w @ frame.T, pdf, zone, res, what=f"spherical rectangle {name}")


def test_uniform_solid_angle_check_rejects_area_sampling():
    """The chi-square has the power to tell solid-angle from area sampling of a large light."""
    s, ex, ey, p, omega, axis, zone, res = _rect_case("large_close")
    frame = frame_around(axis)
    u = np.random.default_rng(3).random((N, 2))
    q = s + u[:, :1] * ex + u[:, 1:] * ey
    w = (q - p) / np.linalg.norm(q - p, axis=1, keepdims=True)
    pdf = uniform_pdf(lambda o, d: rectangle_hit(o, d, s, ex, ey), p, frame, omega)
    with pytest.raises(AssertionError, match="chi-square"):
        chi_square_light(w @ frame.T, pdf, zone, res, what="area samples claimed uniform")


@pytest.mark.parametrize("name", list(TRIANGLES))
def test_spherical_triangle_sample_then_invert_returns_u(name):
    tri, p = TRIANGLES[name]
    n = 50_000
    u = np.random.default_rng(4).random((n, 2))
    args = [_b(v, n) for v in tri] + [_b(p, n)]
    w = warps.sample_spherical_triangle(u, *args)
    np.testing.assert_allclose(warps.invert_spherical_triangle_sample(w, *args), u, rtol=0,
                               atol=1e-6)


@pytest.mark.parametrize("name", list(RECTANGLES))
def test_spherical_rectangle_sample_then_invert_returns_u(name):
    s, ex, ey, p = RECTANGLES[name]
    n = 50_000
    u = np.random.default_rng(5).random((n, 2))
    args = [_b(s, n), _b(ex, n), _b(ey, n), _b(p, n)]
    q = warps.sample_spherical_rectangle(u, *args)
    np.testing.assert_allclose(warps.invert_spherical_rectangle_sample(q, *args), u, rtol=0,
                               atol=1e-6)


def _surface_integral(points, weights, normal, p):
    """Midpoint rule for the solid angle: sum of |cos| / d^2 dA over surface points."""
    d = points - p
    r2 = np.einsum("ij,ij->i", d, d)
    return float(np.sum(weights * np.abs(d @ normal) / r2 ** 1.5))


@pytest.mark.parametrize("name", list(TRIANGLES))
def test_spherical_triangle_solid_angle_matches_a_numerical_integral(name):
    tri, p = TRIANGLES[name]
    # Midpoints of a k x k subdivision of the triangle into congruent sub-triangles (area
    # weights equal): the rule converges as 1/k^2, so two levels bound its error.
    def integral(k):
        i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
        up = i + j < k
        ii, jj = i[up], j[up]
        cent_up = np.stack([ii + 1 / 3, jj + 1 / 3], -1) / k
        dn = i + j < k - 1
        cent_dn = np.stack([i[dn] + 2 / 3, j[dn] + 2 / 3], -1) / k
        bc = np.concatenate([cent_up, cent_dn])
        pts = tri[0] + bc[:, :1] * (tri[1] - tri[0]) + bc[:, 1:] * (tri[2] - tri[0])
        n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        area = 0.5 * np.linalg.norm(n)
        return _surface_integral(pts, area / k**2, n / np.linalg.norm(n), p)
    coarse, fine = integral(400), integral(800)
    omega = warps.spherical_triangle_solid_angle(*(_b(v, 1) for v in tri), _b(p, 1))[0]
    # Richardson: the fine rule's error is about (fine - coarse) / 3.
    assert abs(omega - fine) <= 2 * abs(fine - coarse) / 3 + 1e-12 * fine, (omega, coarse, fine)


@pytest.mark.parametrize("name", list(RECTANGLES))
def test_spherical_rectangle_solid_angle_matches_a_numerical_integral(name):
    s, ex, ey, p = (np.asarray(v, np.float64) for v in RECTANGLES[name])

    def integral(k):
        t = (np.arange(k) + 0.5) / k
        a, b = np.meshgrid(t, t, indexing="ij")
        pts = s + a.reshape(-1, 1) * ex + b.reshape(-1, 1) * ey
        n = np.cross(ex, ey)
        return _surface_integral(pts, np.linalg.norm(n) / k**2, n / np.linalg.norm(n), p)
    coarse, fine = integral(500), integral(1000)
    omega = warps.spherical_rectangle_solid_angle(_b(s, 1), _b(ex, 1), _b(ey, 1), _b(p, 1))[0]
    assert abs(omega - fine) <= 2 * abs(fine - coarse) / 3 + 1e-12 * fine, (omega, coarse, fine)
    # The corner-angle sum that the warp maps u0 with is the same solid angle (to rounding).
    fx, fy, fz, x0, y0, z0, x1, y1 = warps._rectangle_frame(_b(s, 1), _b(ex, 1), _b(ey, 1),
                                                            _b(p, 1))
    np.testing.assert_allclose(warps._rectangle_angles(x0, y0, z0, x1, y1)[-1], omega,
                               rtol=1e-10)


def test_degenerate_triangles_and_viewpoints_in_the_plane_give_zero_pdf_and_no_nan():
    tri = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [2.0, 0.0, 1.0]])  # collinear
    p = np.array([[0.3, 0.2, 0.0], [0.5, 0.5, 1.0], [3.0, 3.0, 1.0]])
    args = [_b(v, 3) for v in tri]
    assert np.all(warps.spherical_triangle_pdf(*args, p) == 0.0)
    flat = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    in_plane = np.array([[3.0, 3.0, 1.0]])
    assert warps.spherical_triangle_solid_angle(*(_b(v, 1) for v in flat), in_plane)[0] == 0.0
    w = warps.sample_spherical_triangle(np.full((3, 2), 0.5), *args, p)
    assert np.all(np.isfinite(w))


# --------------------------------------------------------------------------------------------
# Through the light sampler
# --------------------------------------------------------------------------------------------


def nee_irradiance(scene, p, n=NRM, sampling="solid_angle", seed=1, count=N):
    """Per-sample irradiance estimates ``Li cos / pdf`` of NEE at ``p`` with normal ``n``."""
    rng = np.random.default_rng(seed)
    prep = prepare(scene, light_sampling=sampling)
    pts = np.broadcast_to(p - prep.shift, (count, 3)).astype(np.float64)
    wi, dist, li, pdf, delta, _ = prep.lights.sample(pts, rng.random(count), rng.random((count, 2)))
    cos = np.maximum(wi @ np.asarray(n, np.float64), 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(pdf[:, None] > 0, li * (cos / pdf)[:, None], 0.0)
    assert np.isfinite(x).all()
    return x[:, 0], prep, (pts, wi, dist, pdf)


def _rect_light(kind="RECTANGLE", center=(0.2, 0.1, 1.2), size=(0.8, 0.5)):
    m = look_at(center, (center[0] - 0.2, center[1], -3.0))
    return L.area_light(m, kind, size[0], size[1], (1, 1, 1), 30.0)


def _rect_corners(lights):
    c, ax, ay = lights.position[0], lights.axis_x[0] / 2, lights.axis_y[0] / 2
    return [c - ax - ay, c + ax - ay, c + ax + ay, c - ax + ay]


@pytest.mark.parametrize("case", ["small", "large_close", "square"])
def test_solid_angle_nee_of_a_rectangle_light_matches_closed_form_irradiance(case):
    if case == "small":
        lights = _rect_light()
    elif case == "large_close":
        lights = _rect_light(center=(0.3, 0.1, 0.35), size=(3.0, 2.0))
    else:
        lights = _rect_light("SQUARE", center=(-0.4, 0.2, 0.8), size=(1.0, 1.0))
    x, *_ = nee_irradiance(make_scene(lights), P0)
    expected = polygon_irradiance(P0, NRM, _rect_corners(lights), lights.radiance[0, 0])
    assert_mean_within_ci(x, expected)


@pytest.mark.parametrize("faces", [[0, 1, 2], [0, 2, 1]], ids=["front", "back"])
@pytest.mark.parametrize("name", ["tilted", "large_close"])
def test_solid_angle_nee_of_an_emissive_triangle_matches_closed_form_from_both_faces(name, faces):
    tri, p = TRIANGLES[name]
    scene = make_scene(tris=(tri, [faces]), emissions=[(2.0, 2.0, 2.0)])
    x, *_ = nee_irradiance(scene, p)
    assert_mean_within_ci(x, polygon_irradiance(p, NRM, tri, 2.0))


def test_disk_lights_stay_area_sampled_and_unbiased_with_solid_angle_sampling():
    lights = _rect_light("DISK", size=(0.8, 0.8))
    x_sa, prep, (pts, wi, dist, pdf) = nee_irradiance(make_scene(lights), P0)
    x_area, *_ = nee_irradiance(make_scene(lights), P0, sampling="area")
    np.testing.assert_array_equal(x_sa, x_area)  # same numbers: the disk is area-sampled


def test_tiny_emitters_fall_back_to_area_sampling_in_nee_and_mis_alike():
    """Below the solid-angle threshold the pdf is the area pdf on both sides of MIS."""
    tri = TRIANGLES["tilted"][0] * 0.01 + np.array([0.0, 0.0, 3.0])
    scene = make_scene(tris=(tri, [[0, 1, 2]]), emissions=[(2.0, 2.0, 2.0)])
    n = 1000
    _, prep_sa, (pts, wi, dist, pdf_sa) = nee_irradiance(scene, P0, count=n)
    _, prep_a, (_, _, _, pdf_a) = nee_irradiance(scene, P0, sampling="area", count=n)
    omega = warps.spherical_triangle_solid_angle(*(_b(v - prep_sa.shift, 1) for v in tri),
                                                 pts[:1])[0]
    assert omega < warps.MIN_SPHERICAL_SOLID_ANGLE, "test setup: the triangle must be tiny"
    np.testing.assert_array_equal(pdf_sa, pdf_a)
    cos = np.einsum("ij,ij->i", wi, prep_sa.tri_normal[np.zeros(n, np.int64)])
    np.testing.assert_allclose(prep_sa.lights.triangle_pdf(np.zeros(n, np.int64), pts, dist, cos),
                               pdf_sa, rtol=1e-9)


@pytest.mark.parametrize("case", ["rect", "large_close", "sheared"])
def test_rect_nee_pdf_equals_the_mis_pdf_of_the_same_direction(case):
    if case == "rect":
        lights = _rect_light()
    elif case == "large_close":
        lights = _rect_light(center=(0.3, 0.1, 0.35), size=(3.0, 2.0))
    else:
        m = look_at((0.2, 0.1, 1.2), (0.0, 0.1, -3.0))
        m[:3, 0] += 0.4 * m[:3, 1]  # shear: a parallelogram, sampled by area
        lights = L.area_light(m, "RECTANGLE", 0.8, 0.5, (1, 1, 1), 30.0)
    scene = make_scene(Lights.concat([lights, L.point_light((5, 5, 5), (1, 1, 1), 10.0)]))
    prep = prepare(scene, light_sampling="solid_angle")
    assert prep.lights.rect_spherical[0] == (case != "sheared")
    rng = np.random.default_rng(6)
    n = 4000
    p = np.broadcast_to(P0 - prep.shift, (n, 3)).astype(np.float64)
    wi, dist, li, pdf, delta, _ = prep.lights.sample(p, rng.random(n), rng.random((n, 2)))
    keep = (~delta) & (pdf > 0)
    assert keep.sum() > n // 4
    found = np.zeros(n)
    for rows, _, pdf_hit in prep.lights.hit_shapes(p[keep], wi[keep], np.full(keep.sum(), np.inf),
                                                   camera=False):
        found[np.nonzero(keep)[0][rows]] = pdf_hit
    np.testing.assert_allclose(found[keep], pdf[keep], rtol=1e-6)
    if case != "sheared":
        corner = _b(lights.position[0] - 0.5 * (lights.axis_x[0] + lights.axis_y[0])
                    - prep.shift, 1)
        omega = warps.spherical_rectangle_solid_angle(corner, _b(lights.axis_x[0], 1),
                                                      _b(lights.axis_y[0], 1), p[:1])[0]
        np.testing.assert_allclose(pdf[keep], prep.lights.select_prob[0] / omega, rtol=1e-12)


@pytest.mark.parametrize("name", ["tilted", "large_close"])
def test_triangle_nee_pdf_equals_the_mis_pdf_of_the_same_hit(name):
    tri, p = TRIANGLES[name]
    scene = make_scene(tris=(tri, [[0, 1, 2]]), emissions=[(2.0, 2.0, 2.0)])
    n = 2000
    _, prep, (pts, wi, dist, pdf) = nee_irradiance(scene, p, count=n)
    hits = prep.accel.intersect(pts, wi)
    assert (hits.prim == 0).all()
    np.testing.assert_allclose(hits.t, dist, rtol=1e-4)
    cos = np.einsum("ij,ij->i", wi, prep.tri_normal[hits.prim])
    np.testing.assert_allclose(prep.lights.triangle_pdf(hits.prim, pts, hits.t, cos), pdf,
                               rtol=1e-9)


@pytest.mark.parametrize("case", ["rect", "rect_grazing"])
def test_solid_angle_nee_directions_match_the_hit_pdf(case):
    lights, boundary = _area_case(case)
    prep = prepare(make_scene(lights), light_sampling="solid_angle")
    axis = lights.position[0] - P_WORLD
    zone, res = polygon_zone(P_WORLD, axis, boundary)
    frame = frame_around(axis)
    samples = nee_directions(prep, P_WORLD, frame)(np.random.default_rng(7).random((N, 2)))
    chi_square_light(samples, shape_pdf(prep, P_WORLD, frame), zone, res,
                     what=f"solid-angle NEE {case}")


def test_solid_angle_nee_directions_of_a_triangle_match_triangle_pdf():
    tri, p = TRIANGLES["large_close"]
    prep = prepare(make_scene(tris=(tri, [[0, 1, 2]]), emissions=[(2.0, 2.0, 2.0)]),
                   light_sampling="solid_angle")
    p = p - prep.shift
    verts = prep.tri_v0[0] + np.stack([np.zeros(3), prep.tri_e1[0], prep.tri_e2[0]])
    axis = verts.mean(axis=0) - p
    zone, res = polygon_zone(p, axis, verts)
    frame = frame_around(axis)
    samples = nee_directions(prep, p, frame)(np.random.default_rng(8).random((N, 2)))
    chi_square_light(samples, triangle_hit_pdf(prep, p, frame), zone, res,
                     what="solid-angle NEE triangle")


def _log_variance_and_se(x):
    """log of the sample variance and its standard error (delta method, any distribution)."""
    x = np.asarray(x, np.float64)
    d = x - x.mean()
    m2 = np.mean(d * d)
    m4 = np.mean(d**4)
    return math.log(m2), math.sqrt(max(m4 / (m2 * m2) - 1.0, 0.0) / x.size)


@pytest.mark.parametrize("emitter", ["rectangle", "triangle"])
def test_solid_angle_sampling_has_lower_variance_near_a_large_light(emitter):
    """An F-test-like bound: var(area) / var(solid angle) > 1 beyond both variances' CIs.

    Up close to a big light, area sampling puts most samples on its far parts (small solid
    angle, low pdf ratio) and rarely on the near part (which dominates the integral), so its
    estimates vary wildly; uniform directions leave only the cosine at the receiver to vary.
    """
    if emitter == "rectangle":
        scene = make_scene(_rect_light(center=(0.3, 0.1, 0.35), size=(3.0, 2.0)))
    else:
        tri, _ = TRIANGLES["large_close"]
        scene = make_scene(tris=(tri, [[0, 1, 2]]), emissions=[(2.0, 2.0, 2.0)])
    x_sa, *_ = nee_irradiance(scene, P0, seed=9)
    x_area, *_ = nee_irradiance(scene, P0, sampling="area", seed=10)
    lv_sa, se_sa = _log_variance_and_se(x_sa)
    lv_area, se_area = _log_variance_and_se(x_area)
    z = -normal_quantile(1e-4)  # one-sided, p_false = 1e-4
    ratio = math.exp(lv_area - lv_sa)
    assert lv_area - lv_sa > z * math.hypot(se_sa, se_area), (
        f"variance ratio area / solid angle = {ratio:.3g}, not significantly above 1")
    assert ratio > 2.0, f"variance ratio only {ratio:.3g}"
