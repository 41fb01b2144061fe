"""Smooth shading: interpolated corner normals, and the geometric-side rule against light leaks."""

import types

import numpy as np
import pytest

from sampling_lab.core import lights as L
from sampling_lab.core import scenes
from sampling_lab.core.integrators.common import shading_normals
from sampling_lab.core.render import render
from sampling_lab.core.scene import (MAT_CONDUCTOR, MAT_DIELECTRIC, MAT_DIFFUSE, MAT_LAYERED,
                                     Camera, Lights, Materials, Scene)
from tests.helpers import assert_mean_within_ci, plain_settings


def pixel_means(result):
    """Each pixel's mean is an independent estimate of the same value in these scenes."""
    return result.combined()[..., 0].ravel().astype(np.float64)


def smooth_normals(vertices, triangles):
    """Corner normals of a sphere centred at the origin: the unit vertex positions."""
    v = vertices.astype(np.float64)
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    return n[triangles]


def test_shading_normal_interpolation_is_exact_at_vertices():
    rng = np.random.default_rng(1)
    t = 50
    ng = np.tile([0.0, 0.0, 1.0], (t, 1))
    corner = rng.normal(size=(t, 3, 3)) * 0.4 + [0.0, 0.0, 1.0]
    scene = Scene(np.zeros((3 * t, 3)), np.arange(3 * t).reshape(t, 3), np.zeros(t),
                  Materials.from_lists(["M"], [(0.5,) * 3], [(0,) * 3]), Lights.empty(), None,
                  corner_normals=corner)
    prep = types.SimpleNamespace(scene=scene)
    unit = corner / np.linalg.norm(corner, axis=2, keepdims=True)
    prim = np.arange(t)
    for k, (u, v) in enumerate([(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)]):
        # Viewed along each corner normal so that the wo-side fallback never applies.
        wo = unit[:, k]
        n = shading_normals(prep, prim, np.full(t, u), np.full(t, v), ng, wo)
        np.testing.assert_allclose(n, unit[:, k], atol=1e-6)
    # Between the corners: unit length, the normalised barycentric blend.
    u, v = rng.uniform(0, 0.5, t), rng.uniform(0, 0.5, t)
    blend = (1 - u - v)[:, None] * unit[:, 0] + u[:, None] * unit[:, 1] + v[:, None] * unit[:, 2]
    blend /= np.linalg.norm(blend, axis=1, keepdims=True)
    n = shading_normals(prep, prim, u, v, ng, blend)
    np.testing.assert_allclose(n, blend, atol=1e-6)
    # Flat meshes are the geometric normal itself.
    flat = types.SimpleNamespace(scene=types.SimpleNamespace(corner_normals=None))
    assert shading_normals(flat, prim, u, v, ng, blend) is ng


@pytest.mark.parametrize("kind", [MAT_DIFFUSE, MAT_CONDUCTOR, MAT_DIELECTRIC, MAT_LAYERED])
def test_smooth_sphere_under_lights_leaves_no_nan(kind):
    box = scenes.cornell_box(24, 24, "area")
    sv, sf = scenes.icosphere(2, 0.4)
    smooth = smooth_normals(sv, sf)
    sv = sv + [0.0, 0.0, 0.6]
    n0 = box.vertices.shape[0]
    m = len(box.materials.kind)
    kinds = np.concatenate([box.materials.kind, [kind]])
    mats = Materials.from_lists(
        box.materials.names + ["Sphere"],
        np.concatenate([box.materials.base_color, [[0.8, 0.7, 0.6]]]),
        np.concatenate([box.materials.emission, [[0, 0, 0]]]), kinds=kinds,
        roughness=np.concatenate([box.materials.roughness, [0.3]]),
        ior=np.concatenate([box.materials.ior, [1.5]]))
    tris = np.concatenate([box.triangles, sf + n0])
    corner = np.concatenate([box.vertices.astype(np.float64)[box.triangles] * 0, smooth])
    # Flat box faces: their corner normals are their geometric normals.
    tri = box.vertices.astype(np.float64)[box.triangles]
    flat = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    corner[:len(box.triangles)] = flat[:, None, :]
    scene = Scene(np.concatenate([box.vertices, sv]), tris,
                  np.concatenate([box.material, np.full(len(sf), m)]), mats,
                  Lights.concat([box.lights, L.point_light((0.3, -0.5, 0.6), (1, 1, 1), 50.0)]),
                  box.camera, corner_normals=corner)
    res = render(scene, plain_settings(spp=8, max_bounces=6, seed=2))
    img = res.combined()
    assert np.isfinite(img).all() and (img >= 0).all()
    assert img.mean() > 0


def test_smooth_furnace_is_bounded_by_the_flat_solution():
    """Closed furnace, smooth normals: Le <= L <= Le / (1 - rho), and close to the upper bound.

    With shading normals, cosine sampling around ns sends the fraction (1 - cos a) / 2 of the
    lobe below the geometric surface (a = angle between ns and ng); the geometric-side rule
    drops those directions, so each bounce keeps the albedo times a factor s in
    [(1 + cos a_max) / 2, 1]. Hence Le / (1 - rho s_min) <= L <= Le / (1 - rho) (the smooth
    furnace is not exactly the flat one: shading normals are not energy conserving).
    """
    rho, bounces = 0.5, 8
    scene = scenes.furnace(emission=1.0, albedo=rho, subdivisions=2, width=32, height=32)
    scene.corner_normals = smooth_normals(scene.vertices, scene.triangles)
    scene.__post_init__()
    tri = scene.vertices.astype(np.float64)[scene.triangles]
    ng = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    ng /= np.linalg.norm(ng, axis=1, keepdims=True)
    cos_min = np.einsum("tj,tkj->tk", ng, scene.corner_normals.astype(np.float64)).min()
    s_min = (1 + cos_min) / 2
    res = render(scene, plain_settings(spp=64, max_bounces=bounces, seed=7,
                                       use_russian_roulette=False))
    x = pixel_means(res)
    n = bounces + 2
    hi = (1 - rho ** n) / (1 - rho)
    lo = (1 - (rho * s_min) ** n) / (1 - rho * s_min)
    assert hi - lo < 0.05 * hi  # the bound is informative (a nearly-flat tessellation)
    assert_mean_within_ci(x, 0.5 * (hi + lo), atol=0.5 * (hi - lo))


def test_smooth_furnace_with_face_normals_as_corner_normals_is_exact():
    rho, bounces = 0.5, 6
    scene = scenes.furnace(emission=1.0, albedo=rho, subdivisions=2, width=32, height=32)
    tri = scene.vertices.astype(np.float64)[scene.triangles]
    ng = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    scene.corner_normals = np.repeat(ng[:, None, :], 3, axis=1)
    scene.__post_init__()
    res = render(scene, plain_settings(spp=32, max_bounces=bounces, seed=3))
    assert_mean_within_ci(pixel_means(res), (1 - rho ** (bounces + 2)) / (1 - rho))


def _tilted_plane(kind, light_z, tilt_deg=70.0):
    """A 2 x 2 plane at z = 0 (geometric normal +Z), corner normals tilted by ``tilt_deg`` in
    alternating directions, a point light at height ``light_z``, a camera above looking down."""
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    a = np.radians(tilt_deg)
    dirs = np.array([[np.sin(a), 0, np.cos(a)], [-np.sin(a), 0, np.cos(a)],
                     [0, np.sin(a), np.cos(a)], [0, -np.sin(a), np.cos(a)]])
    corner = dirs[f]
    mats = Materials.from_lists(["Plane"], [(0.8, 0.8, 0.8)], [(0, 0, 0)], kinds=[kind],
                                roughness=[0.3], ior=[1.5])
    lights = L.point_light((0.2, 0.1, light_z), (1, 1, 1), 100.0)
    cam = Camera(to_world=scenes.look_at((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0)), width=16,
                 height=16, lens=50.0, sensor_width=36.0, clip_start=0.01, clip_end=100.0)
    return Scene(v, f, np.zeros(2, np.int32), mats, lights, cam, corner_normals=corner)


@pytest.mark.parametrize("kind", [MAT_DIFFUSE, MAT_CONDUCTOR, MAT_LAYERED])
def test_perturbed_shading_normals_do_not_leak_light_through_a_plane(kind):
    below = render(_tilted_plane(kind, -0.5), plain_settings(spp=16, max_bounces=4, seed=1))
    img = below.combined()[..., :3]
    assert np.isfinite(img).all()
    assert img.max() == 0.0
    above = render(_tilted_plane(kind, 0.5), plain_settings(spp=16, max_bounces=4, seed=1))
    assert above.combined()[..., :3].mean() > 0
