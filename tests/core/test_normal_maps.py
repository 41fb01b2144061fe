"""Normal Map node (tangent space): the decoding of Cycles, a flat map that changes nothing, and
the cosine law on a plane whose normal the map tilts."""

import dataclasses

import numpy as np
import pytest

from sampling_lab.core import lights as L
from sampling_lab.core import scenes
from sampling_lab.core.normal_maps import tangent_space_normals
from sampling_lab.core.render import render
from sampling_lab.core.scene import Camera, Materials, Scene
from tests.helpers import plain_settings

FLAT = (0.5, 0.5, 1.0)


def constant_map(color, size=4):
    return np.tile(np.asarray(color, np.float32), (size, size, 1))


def with_normal_map(scene, rows, color, sign=1.0, strength=1.0):
    """``scene`` with a constant normal map on material ``rows``, tangent +X on every corner."""
    t = scene.n_triangles
    tangents = np.zeros((t, 3, 4), np.float32)
    tangents[..., 0] = 1.0
    tangents[..., 3] = sign
    column = np.full(len(scene.materials.kind), -1, np.int32)
    column[rows] = len(scene.textures)
    materials = dataclasses.replace(scene.materials, normal_texture=column,
                                    normal_strength=np.full(len(column), strength, np.float32))
    return dataclasses.replace(
        scene, materials=materials, textures=list(scene.textures) + [constant_map(color)],
        corner_uvs=np.zeros((t, 3, 2), np.float32) if scene.corner_uvs is None
        else scene.corner_uvs,
        texture_interpolation=None, texture_extension=None, corner_tangents=tangents)


def test_tangent_space_decoding_follows_tangent_bitangent_and_normal():
    t = np.array([[2.0, 0.0, 0.0]] * 3)  # not normalised: Cycles keeps the length
    n = np.array([[0.0, 0.0, 1.0]] * 3)
    color = np.array([[1.0, 0.5, 0.5], [0.5, 1.0, 0.5], [0.5, 1.0, 0.5]])
    sign = np.array([1.0, 1.0, -1.0])
    got = tangent_space_normals(color, t, sign, n)
    np.testing.assert_allclose(got, [[1, 0, 0], [0, 1, 0], [0, -1, 0]], atol=1e-12)
    # Blender 4.0+ applies Strength to the decoded colour (m_x, m_y scaled by k, m_z moved
    # toward 1 by clamp(k, 0, 1)): 0 keeps n, 1 the map, 0.5 of a 90-degree tilt (1, 0, 0)
    # gives (0.5, 0, 0.5) -> 45 degrees, and 2 gives (2, 0, 0) -> +X.
    t1 = np.tile([1.0, 0.0, 0.0], (4, 1))
    n1 = np.tile([0.0, 0.0, 1.0], (4, 1))
    tilt = np.tile([1.0, 0.5, 0.5], (4, 1))  # m = (1, 0, 0)
    out = tangent_space_normals(tilt, t1, np.ones(4), n1, np.array([0.0, 1.0, 0.5, 2.0]))
    h = 0.5 ** 0.5
    np.testing.assert_allclose(out, [[0, 0, 1], [1, 0, 0], [h, 0, h], [1, 0, 0]], atol=1e-12)
    # Where the frame is not orthonormal the rule is not the old linear blend of world
    # normals (normalize(n + k (N - n)), Blender 3.x): a tangent of length 2 and k = 0.5.
    t2 = np.tile([2.0, 0.0, 0.0], (1, 1))
    got = tangent_space_normals(np.array([[1.0, 0.5, 0.5]]), t2, np.ones(1), n1[:1],
                                np.array([0.5]))
    np.testing.assert_allclose(got, [[2 / 5 ** 0.5, 0, 1 / 5 ** 0.5]], atol=1e-12)


def test_flat_normal_map_leaves_the_image_unchanged():
    box = scenes.cornell_box(16, 16, "area")
    settings = plain_settings(spp=4, max_bounces=3, seed=5)
    plain = render(box, settings).combined()
    mapped = render(with_normal_map(box, np.arange(len(box.materials.kind)), FLAT),
                    settings).combined()
    # A texel-exact (0.5, 0.5, 1) decodes to the normal itself: the same paths, bit for bit
    # up to the rounding of the normalisation.
    np.testing.assert_allclose(mapped, plain, rtol=1e-5, atol=1e-6)


def sun_plane(normal_color, sign=1.0, strength=1.0):
    """A white diffuse plane z = 0 under a 3 W/m^2 sun toward (+X, +2Y), seen from above."""
    v = np.array([(-9, -9, 0), (9, -9, 0), (9, 9, 0), (-9, 9, 0)], np.float32)
    mats = Materials.from_lists(["White"], [(0.8, 0.8, 0.8)], [(0, 0, 0)])
    to_world = np.eye(4)
    to_world[2, 3] = 1.0
    cam = Camera(to_world, 8, 8, type="ORTHO", ortho_scale=1.0)
    toward_sun = np.array([0.3, 0.6, 0.6]) / 0.9
    scene = Scene(v, [(0, 1, 2), (0, 2, 3)], [0, 0], mats,
                  L.sun_light(-toward_sun, (1, 1, 1), 3.0), cam)
    if normal_color is not None:
        scene = with_normal_map(scene, [0], normal_color, sign, strength)
    return scene, toward_sun


@pytest.mark.parametrize("color,sign,strength,normal", [
    # +X in tangent space tilts toward the sun, -X away, +Y (bitangent n x T = +Y) sideways;
    # a negative sign flips the bitangent; Strength 0.5 blends with the plane's normal.
    ((0.75, 0.5, 1.0), 1.0, 1.0, (0.5, 0.0, 1.0)),
    ((0.25, 0.5, 1.0), 1.0, 1.0, (-0.5, 0.0, 1.0)),
    ((0.5, 0.85, 1.0), 1.0, 1.0, (0.0, 0.7, 1.0)),
    ((0.5, 0.85, 1.0), -1.0, 1.0, (0.0, -0.7, 1.0)),
    ((1.0, 0.5, 0.5), 1.0, 0.5, (0.5 ** 0.5, 0.0, 0.5 ** 0.5)),
])
def test_tilted_normal_follows_the_cosine_law(color, sign, strength, normal):
    scene, toward_sun = sun_plane(color, sign, strength)
    img = render(scene, plain_settings(spp=4, max_bounces=1, seed=3)).combined()[..., :3]
    n = np.asarray(normal) / np.linalg.norm(normal)
    # A delta sun on a Lambertian plane under a black sky: every sample gives exactly
    # rho E cos / pi, so the image is that constant (any error in the frame shows at once).
    expect = 0.8 * 3.0 * max(n @ toward_sun, 0.0) / np.pi
    np.testing.assert_allclose(img, expect, rtol=1e-4)
    flat, _ = sun_plane(None)
    untilted = render(flat, plain_settings(spp=4, max_bounces=1, seed=3)).combined()[..., :3]
    assert abs(untilted.mean() - expect) > 0.05 * expect  # the map changed the picture


def test_normal_maps_without_tangents_keep_the_normal():
    scene, toward_sun = sun_plane((0.75, 0.5, 1.0))
    np.testing.assert_allclose(scene.corner_normals[..., 2], 1.0)  # filled for flat faces
    bare = dataclasses.replace(scene, corner_tangents=None)
    assert bare.corner_tangents.shape == (2, 3, 4) and not bare.corner_tangents.any()
    img = render(bare, plain_settings(spp=2, max_bounces=1, seed=3)).combined()[..., :3]
    np.testing.assert_allclose(img, 0.8 * 3.0 * toward_sun[2] / np.pi, rtol=1e-4)


def ramp_height(slope, size=8):
    """A grey image whose bilinear lookup is ``slope * u`` between the outer texel centres."""
    h = slope * (np.arange(size) + 0.5) / size
    return np.repeat(np.tile(h[None, :, None], (size, 1, 1)), 3, axis=2).astype(np.float32)


def bumped_sun_plane(height, distance=1.0, strength=1.0):
    """:func:`sun_plane` (u = (x + 9) / 18) with a Bump node of ``height`` (Extend)."""
    scene, toward_sun = sun_plane(None)
    uv = (scene.vertices[scene.triangles][..., :2] + 9.0) / 18.0
    materials = dataclasses.replace(scene.materials, bump_texture=[0], bump_distance=[distance],
                                    bump_strength=[strength])
    scene = dataclasses.replace(scene, materials=materials, textures=[height], corner_uvs=uv,
                                texture_interpolation=None, texture_extension=["EXTEND"])
    return scene, toward_sun


@pytest.mark.parametrize("distance,strength,normal", [
    # h = 7.2 u with u = (x + 9) / 18: dh/dx = 0.4, N = normalize(n - d grad h) (Invert: d < 0).
    (1.0, 1.0, (-0.4, 0.0, 1.0)),
    (-1.0, 1.0, (0.4, 0.0, 1.0)),
    (2.5, 1.0, (-1.0, 0.0, 1.0)),
    (2.5, 0.5, (-0.5 ** 0.5 / 2, 0.0, 0.5 + 0.5 ** 0.5 / 2)),
])
def test_bumped_plane_follows_the_cosine_law(distance, strength, normal):
    scene, toward_sun = bumped_sun_plane(ramp_height(7.2), distance, strength)
    img = render(scene, plain_settings(spp=4, max_bounces=1, seed=3)).combined()[..., :3]
    n = np.asarray(normal) / np.linalg.norm(normal)
    # The delta sun makes the image exact (see test_tilted_normal_follows_the_cosine_law).
    np.testing.assert_allclose(img, 0.8 * 3.0 * (n @ toward_sun) / np.pi, rtol=1e-4)


def test_constant_height_leaves_the_normal():
    scene, toward_sun = bumped_sun_plane(np.full((4, 4, 3), 0.7, np.float32), 3.0)
    img = render(scene, plain_settings(spp=2, max_bounces=1, seed=3)).combined()[..., :3]
    np.testing.assert_allclose(img, 0.8 * 3.0 * toward_sun[2] / np.pi, rtol=1e-5)
