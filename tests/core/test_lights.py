"""Lights: Cycles' units, unbiased next-event estimation, and MIS pdfs that agree.

Each NEE test estimates the irradiance at a point, E = integral of L cos over the hemisphere, from
light samples (Li cos / pdf) and compares it with the closed form; a wrong pdf, unit or selection
probability moves the mean. Tolerances are confidence intervals of the estimate.
"""

import numpy as np
import pytest

from sampling_lab.core import lights as L
from sampling_lab.core.prepare import prepare
from sampling_lab.core.scene import Lights, Materials, Scene
from sampling_lab.core.scenes import look_at
from sampling_lab.core.scene import Camera
from tests.helpers import assert_mean_within_ci

N = 200_000


def make_scene(lights=None, tris=None, emission=(0, 0, 0), world=(0, 0, 0)):
    if tris is None:
        v = np.zeros((0, 3))
        f = np.zeros((0, 3), np.int32)
    else:
        v, f = tris
    cam = Camera(look_at((0, -5, 0), (0, 0, 0)), 8, 8)
    mats = Materials.from_lists(["M"], [(0.5, 0.5, 0.5)], [emission])
    return Scene(v, f, np.zeros(len(f), np.int32), mats, lights or Lights.empty(), cam,
                 world_color=world)


def nee_irradiance(scene, p, n, seed=1):
    rng = np.random.default_rng(seed)
    prep = prepare(scene)
    pts = np.broadcast_to(p - prep.shift, (N, 3)).astype(np.float64)
    wi, dist, li, pdf, delta, _ = prep.lights.sample(pts, rng.random(N), rng.random((N, 2)))
    cos = np.maximum(wi @ np.asarray(n, np.float64), 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(pdf[:, None] > 0, li * (cos / pdf)[:, None], 0.0)
    assert np.isfinite(x).all()
    return x[:, 0], prep, (wi, dist, pdf)


def polygon_irradiance(p, n, verts, radiance):
    """Lambert's closed form for a uniformly emitting polygon entirely above the horizon."""
    v = np.asarray(verts, np.float64) - p
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    total = 0.0
    for i in range(len(v)):
        a, b = v[i], v[(i + 1) % len(v)]
        c = np.cross(a, b)
        total += np.arccos(np.clip(a @ b, -1, 1)) * (c @ n) / np.linalg.norm(c)
    return radiance * abs(total) / 2


def test_point_light_intensity_is_power_over_four_pi():
    row = L.point_light((0, 0, 0), (1, 0.5, 0.25), 100.0)
    np.testing.assert_allclose(row.radiance[0], np.array([1, 0.5, 0.25]) * 100 / (4 * np.pi))


def test_sphere_light_radiance_is_power_over_four_pi_squared_r_squared():
    row = L.point_light((0, 0, 0), (1, 1, 1), 100.0, radius=0.5)
    np.testing.assert_allclose(row.radiance[0], 100 / (4 * np.pi**2 * 0.25))


def test_area_light_radiance_is_power_over_pi_area():
    m = np.diag([2.0, 1.0, 1.0, 1.0])  # object scale stretches x
    rect = L.area_light(m, "RECTANGLE", 1.0, 0.5, (1, 1, 1), 10.0)
    np.testing.assert_allclose(rect.radiance[0], 10 / (np.pi * 2.0 * 0.5))
    disk = L.area_light(np.eye(4), "DISK", 2.0, 0.0, (1, 1, 1), 10.0)
    np.testing.assert_allclose(disk.radiance[0], 10 / (np.pi * np.pi))
    np.testing.assert_allclose(disk.direction[0], (0, 0, -1))


def test_sun_with_angle_has_disk_radiance_giving_its_irradiance():
    a = np.radians(10)
    row = L.sun_light((0, 0, -1), (1, 1, 1), 3.0, a)
    np.testing.assert_allclose(row.radiance[0] * np.pi * np.sin(a / 2) ** 2, 3.0)


P = np.array([0.1, -0.2, 0.0])
NRM = np.array([0.0, 0.0, 1.0])


def test_point_light_nee_matches_inverse_square_law():
    lights = L.point_light((0.5, 0.3, 2.0), (1, 1, 1), 100.0)
    x, *_ = nee_irradiance(make_scene(lights), P, NRM)
    d = np.array([0.5, 0.3, 2.0]) - P
    expected = 100 / (4 * np.pi) * (d[2] / np.linalg.norm(d)) / (d @ d)
    np.testing.assert_allclose(x.mean(), expected, rtol=1e-12)


def test_spot_light_nee_applies_cycles_smoothstep_falloff():
    pos = np.array([0.0, 0.0, 2.0])
    spot_dir = np.array([-np.sin(0.42), 0.0, -np.cos(0.42)])
    lights = L.point_light(pos, (1, 1, 1), 100.0, spot_direction=spot_dir,
                           spot_size=np.radians(60), spot_blend=0.5)
    x, *_ = nee_irradiance(make_scene(lights), P, NRM)
    d = pos - P
    w_out = -d / np.linalg.norm(d)
    cos_half = np.cos(np.radians(30))
    t = np.clip((w_out @ spot_dir - cos_half) / ((1 - cos_half) * 0.5), 0, 1)
    att = t * t * (3 - 2 * t)
    expected = att * 100 / (4 * np.pi) * (d[2] / np.linalg.norm(d)) / (d @ d)
    assert 0 < att < 1
    np.testing.assert_allclose(x.mean(), expected, rtol=1e-12)


def test_soft_falloff_point_light_matches_a_lambertian_disk_facing_the_receiver():
    """Blender's Soft Falloff: on the axis, E = S / (4 pi (d^2 + r^2)) (a disk of radiance L)."""
    r, h = 0.4, 1.2
    lights = L.point_light(P + (0, 0, h), (1, 1, 1), 100.0, radius=r, soft_falloff=True)
    x, *_ = nee_irradiance(make_scene(lights), P, NRM)
    assert_mean_within_ci(x, 100.0 / (4 * np.pi * (h * h + r * r)))


def test_point_inside_a_sphere_light_sees_its_radiance_all_around():
    """Inside the sphere every direction meets its inner wall: E = pi L on a surface."""
    lights = L.point_light(P + (0.1, 0.0, 0.2), (1, 1, 1), 100.0, radius=0.5)
    x, *_ = nee_irradiance(make_scene(lights), P, NRM)
    assert_mean_within_ci(x, np.pi * lights.radiance[0, 0])


def test_sphere_light_nee_is_unbiased():
    c, r = np.array([0.3, 0.2, 1.5]), 0.4
    lights = L.point_light(c, (1, 1, 1), 100.0, radius=r)
    x, *_ = nee_irradiance(make_scene(lights), P, NRM)
    d = c - P
    dist = np.linalg.norm(d)
    radiance = 100 / (4 * np.pi**2 * r * r)
    # A uniform sphere acts as a point of intensity L pi r^2 for irradiance (fully above horizon).
    expected = radiance * np.pi * (r / dist) ** 2 * (d[2] / dist)
    assert_mean_within_ci(x, expected)


@pytest.mark.parametrize("shape", ["RECTANGLE", "ELLIPSE"])
def test_area_light_nee_matches_closed_form(shape):
    m = look_at((0.2, 0.1, 1.2), (0.0, 0.3, 3.0))  # faces away from P: emits toward -Z = away
    m = look_at((0.2, 0.1, 1.2), (0.0, 0.1, -3.0))  # local -Z toward the floor
    lights = L.area_light(m, shape, 0.8, 0.5, (1, 1, 1), 30.0)
    x, *_ = nee_irradiance(make_scene(lights), P, NRM)
    radiance = lights.radiance[0, 0]
    if shape == "RECTANGLE":
        c, ax, ay = lights.position[0], lights.axis_x[0] / 2, lights.axis_y[0] / 2
        verts = [c - ax - ay, c + ax - ay, c + ax + ay, c - ax + ay]
    else:
        phi = np.linspace(0, 2 * np.pi, 4001)[:-1]
        c = lights.position[0]
        verts = [c + np.cos(t) * lights.axis_x[0] / 2 + np.sin(t) * lights.axis_y[0] / 2
                 for t in phi]
    expected = polygon_irradiance(P, NRM, verts, radiance)
    # The 4000-gon underestimates the ellipse's solid angle by < 1e-6 relative.
    assert_mean_within_ci(x, expected, atol=1e-6 * expected)


def test_area_light_emits_from_one_side_only():
    m = look_at((0, 0, 1.5), (0, 0, 3.0), up=(0, 1, 0))  # local -Z points up, away from P
    lights = L.area_light(m, "SQUARE", 1.0, 1.0, (1, 1, 1), 30.0)
    x, *_ = nee_irradiance(make_scene(lights), P, NRM)
    assert x.max() == 0.0


def test_emissive_triangle_nee_matches_closed_form_from_both_faces():
    tri = np.array([[-0.5, -0.4, 1.0], [0.7, -0.2, 1.3], [0.1, 0.6, 0.9]])
    for faces in ([[0, 1, 2]], [[0, 2, 1]]):
        scene = make_scene(tris=(tri, np.array(faces, np.int32)), emission=(2.0, 2.0, 2.0))
        x, *_ = nee_irradiance(scene, P, NRM)
        assert_mean_within_ci(x, polygon_irradiance(P, NRM, tri, 2.0))


def test_world_nee_gives_pi_times_radiance():
    x, *_ = nee_irradiance(make_scene(world=(0.7, 0.7, 0.7)), P, NRM)
    assert_mean_within_ci(x, np.pi * 0.7)


def test_sun_nee_gives_its_strength_times_cosine():
    sun_dir = np.array([0.3, 0.0, -1.0]) / np.linalg.norm([0.3, 0.0, -1.0])
    for angle in (0.0, np.radians(20)):
        x, *_ = nee_irradiance(make_scene(L.sun_light(sun_dir, (1, 1, 1), 4.0, angle)), P, NRM)
        assert_mean_within_ci(x, 4.0 * -sun_dir[2], atol=1e-12)


def test_light_selection_is_proportional_to_power_and_unbiased():
    rows = [L.point_light((0, 0, 2), (1, 1, 1), 100.0),
            L.point_light((1, 0, 2), (1, 1, 1), 300.0, radius=0.2)]
    x, prep, _ = nee_irradiance(make_scene(Lights.concat(rows)), P, NRM)
    np.testing.assert_allclose(prep.lights.select_prob, [0.25, 0.75])
    d1 = np.array([0, 0, 2]) - P
    e1 = 100 / (4 * np.pi) * d1[2] / np.linalg.norm(d1) ** 3
    d2 = np.array([1, 0, 2]) - P
    e2 = 300 / (4 * np.pi**2 * 0.04) * np.pi * 0.04 / (d2 @ d2) * d2[2] / np.linalg.norm(d2)
    assert_mean_within_ci(x, e1 + e2)


@pytest.mark.parametrize("which", ["sphere", "inside_sphere", "soft_point", "rect", "disk", "sun"])
def test_nee_pdf_equals_pdf_of_the_same_direction_found_by_a_ray(which):
    """MIS needs both strategies to agree on the light's density of every direction."""
    if which == "sphere":
        lights = L.point_light((0.3, 0.2, 1.5), (1, 1, 1), 10.0, radius=0.4)
    elif which == "inside_sphere":
        lights = L.point_light(P + (0.1, 0.0, 0.2), (1, 1, 1), 10.0, radius=0.5)
    elif which == "soft_point":
        lights = L.point_light((0.3, 0.2, 1.5), (1, 1, 1), 10.0, radius=0.4, soft_falloff=True)
    elif which == "sun":
        lights = L.sun_light((0.2, 0.1, -1.0), (1, 1, 1), 3.0, np.radians(15))
    else:
        m = look_at((0.2, 0.1, 1.2), (0.0, 0.1, -3.0))
        lights = L.area_light(m, "RECTANGLE" if which == "rect" else "DISK", 0.8, 0.5,
                              (1, 1, 1), 30.0)
    scene = make_scene(Lights.concat([lights, L.point_light((5, 5, 5), (1, 1, 1), 10.0)]))
    prep = prepare(scene)
    rng = np.random.default_rng(3)
    n = 2000
    p = np.broadcast_to(P, (n, 3)).astype(np.float64)
    wi, dist, li, pdf, delta, _ = prep.lights.sample(p, rng.random(n), rng.random((n, 2)))
    keep = (~delta) & (pdf > 0)
    assert keep.sum() > n // 4
    found = np.zeros(n)
    for rows, le, pdf_hit in prep.lights.hit_shapes(p[keep], wi[keep], np.full(keep.sum(), np.inf),
                                                    camera=False):
        found[np.nonzero(keep)[0][rows]] = pdf_hit
    np.testing.assert_allclose(found[keep], pdf[keep], rtol=1e-6)


def test_triangle_pdf_equals_nee_pdf():
    tri = np.array([[-0.5, -0.4, 1.0], [0.7, -0.2, 1.3], [0.1, 0.6, 0.9]])
    scene = make_scene(tris=(tri, np.array([[0, 1, 2]], np.int32)), emission=(2.0, 2.0, 2.0))
    prep = prepare(scene)
    rng = np.random.default_rng(4)
    n = 1000
    p = np.broadcast_to(P - prep.shift, (n, 3)).astype(np.float64)
    wi, dist, li, pdf, delta, _ = prep.lights.sample(p, rng.random(n), rng.random((n, 2)))
    hits = prep.accel.intersect(p, wi)
    assert (hits.prim == 0).all()
    np.testing.assert_allclose(hits.t, dist, rtol=1e-4)
    cos = np.einsum("ij,ij->i", wi, prep.tri_normal[hits.prim])
    np.testing.assert_allclose(prep.lights.triangle_pdf(hits.prim, p, hits.t, cos), pdf, rtol=1e-3)
