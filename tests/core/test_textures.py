"""Image textures into the base colour: Cycles' lookups, and renders with them.

Checks: the lookup returns the texel at texel centres, blends linearly between them and wraps
(Repeat); Closest returns the texel containing the point, Extend clamps to the edge texels,
Clip is black outside the image (and blends with black across its border), Mirror reflects
at the edges, all against hand-picked texels; a closed sphere whose texture is a constant albedo is the untextured furnace; a
checker-textured plane under a uniform world renders each cell as albedo x L (a diffuse plane
under a uniform sky of radiance L reflects rho L), with the image's orientation (row 0 at v = 0)
checked by an asymmetric pattern of cells.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.render import render
from sampling_lab.core.scene import Camera, Lights, Materials, Scene
from sampling_lab.core.textures import texture_lookup
from tests.helpers import assert_mean_within_ci, plain_settings


def _image(h=3, w=4, seed=1):
    return np.random.default_rng(seed).random((h, w, 3)).astype(np.float32)


def test_texture_lookup_is_the_texel_at_texel_centres():
    img = _image()
    h, w = img.shape[:2]
    j, i = np.meshgrid(np.arange(w), np.arange(h))
    uv = np.stack([(j.ravel() + 0.5) / w, (i.ravel() + 0.5) / h], axis=-1)
    np.testing.assert_allclose(texture_lookup(img, uv), img.reshape(-1, 3), rtol=1e-6)


def test_texture_lookup_blends_linearly_between_texel_centres():
    img = _image()
    h, w = img.shape[:2]
    t = np.linspace(0.0, 1.0, 7)
    # Along u between texels (1, 1) and (1, 2), along v between (0, 2) and (1, 2).
    uv_u = np.stack([(1.5 + t) / w, np.full_like(t, 1.5 / h)], axis=-1)
    expected_u = (1 - t)[:, None] * img[1, 1] + t[:, None] * img[1, 2]
    np.testing.assert_allclose(texture_lookup(img, uv_u), expected_u, rtol=1e-6)
    uv_v = np.stack([np.full_like(t, 2.5 / w), (0.5 + t) / h], axis=-1)
    expected_v = (1 - t)[:, None] * img[0, 2] + t[:, None] * img[1, 2]
    np.testing.assert_allclose(texture_lookup(img, uv_v), expected_v, rtol=1e-6)


def test_texture_lookup_repeats():
    img = _image()
    rng = np.random.default_rng(3)
    uv = rng.random((100, 2))
    base = texture_lookup(img, uv)
    for shift in ((1, 0), (0, -1), (3, 2), (-2, 5)):
        np.testing.assert_allclose(texture_lookup(img, uv + shift), base, rtol=1e-5, atol=1e-6)
    # Between the last and first texel centres the lookup blends across the edge.
    h, w = img.shape[:2]
    np.testing.assert_allclose(texture_lookup(img, [[1.0, 0.5 / h]]),
                               0.5 * (img[0, 0] + img[0, w - 1])[None], rtol=1e-6)


def test_closest_lookup_is_the_texel_containing_the_point():
    img = _image()
    h, w = img.shape[:2]
    j, i = np.meshgrid(np.arange(w), np.arange(h))
    for fu, fv in ((0.01, 0.99), (0.5, 0.5), (0.99, 0.01)):
        uv = np.stack([(j.ravel() + fu) / w, (i.ravel() + fv) / h], axis=-1)
        np.testing.assert_array_equal(texture_lookup(img, uv, "Closest"), img.reshape(-1, 3))
    # Repeat by default; Extend clamps to the edge texels.
    np.testing.assert_array_equal(texture_lookup(img, [[-0.1 / w, 0.5 / h]], "Closest"),
                                  img[None, 0, w - 1])
    np.testing.assert_array_equal(
        texture_lookup(img, [[-0.1 / w, 0.5 / h], [3.0, -2.0]], "Closest", "EXTEND"),
        np.stack([img[0, 0], img[0, w - 1]]))


def test_extend_lookup_clamps_to_the_edge_texels():
    img = _image()
    h, w = img.shape[:2]
    uv = [[-5.0, 0.5 / h], [0.25 / w, 1.0 / h], [1.7, 10.0], [(w - 0.5) / w, 0.25 / h]]
    expected = [img[0, 0], 0.5 * (img[0, 0] + img[1, 0]), img[h - 1, w - 1], img[0, w - 1]]
    np.testing.assert_allclose(texture_lookup(img, uv, "Linear", "EXTEND"), expected, rtol=1e-6)


def test_clip_lookup_is_black_outside_and_blends_with_black_across_the_border():
    img = _image()
    h, w = img.shape[:2]
    outside = [[-0.3, 0.5], [0.5, 1.4], [1.0 + 0.6 / w, 0.5 / h]]
    for interpolation in ("Linear", "Closest"):
        np.testing.assert_array_equal(texture_lookup(img, outside, interpolation, "CLIP"), 0.0)
    # On the left edge, at a texel centre's height: half the edge texel, half black.
    np.testing.assert_allclose(texture_lookup(img, [[0.0, 1.5 / h]], "Linear", "CLIP"),
                               0.5 * img[None, 1, 0], rtol=1e-6)
    np.testing.assert_array_equal(texture_lookup(img, [[0.1 / w, 1.5 / h]], "Closest", "CLIP"),
                                  img[None, 1, 0])


def test_mirror_lookup_reflects_at_the_edges():
    img = _image()
    h, w = img.shape[:2]
    uv = np.random.default_rng(4).random((200, 2))
    base = texture_lookup(img, uv, "Linear", "MIRROR")
    for mirrored in (np.stack([-uv[:, 0], uv[:, 1]], -1), np.stack([uv[:, 0], 2 - uv[:, 1]], -1),
                     uv + 2):
        np.testing.assert_allclose(texture_lookup(img, mirrored, "Linear", "MIRROR"), base,
                                   rtol=1e-6, atol=1e-7)
    np.testing.assert_array_equal(
        texture_lookup(img, [[-0.5 / w, 0.5 / h], [1 + 1.5 / w, 0.5 / h]], "Closest", "MIRROR"),
        np.stack([img[0, 0], img[0, w - 2]]))


def _textured(scene, image, uvs):
    mats = scene.materials
    textured = Materials.from_lists(mats.names, mats.base_color, mats.emission, kinds=mats.kind,
                                    texture=[0])
    return Scene(scene.vertices, scene.triangles, scene.material, textured, scene.lights,
                 scene.camera, textures=[image], corner_uvs=uvs)


@pytest.mark.parametrize("rho,bounces", [(0.6, 6)])
def test_constant_texture_furnace_equals_untextured(rho, bounces):
    # The material's own colour (0.1) must be replaced by the texture's albedo.
    plain = scenes.furnace(emission=1.0, albedo=0.1, width=32, height=32)
    uvs = np.random.default_rng(5).uniform(-2, 3, (plain.n_triangles, 3, 2))
    scene = _textured(plain, np.full((4, 5, 3), rho, np.float32), uvs)
    res = render(scene, plain_settings(spp=64, max_bounces=bounces, seed=7))
    img = res.combined()[..., 0].ravel().astype(np.float64)
    assert_mean_within_ci(img, (1 - rho ** (bounces + 2)) / (1 - rho), what="textured furnace")


# Cells of a 2 x 2 checker (row 0 at v = 0); three colours, so any flip of u or v shows.
CELLS = np.array([[(0.9, 0.5, 0.2), (0.1, 0.3, 0.6)],
                  [(0.4, 0.8, 0.1), (0.9, 0.5, 0.2)]], np.float32)


def test_checker_plane_under_uniform_world_is_albedo_times_radiance():
    block, n = 4, 32  # texels per cell, pixels across the plane
    image = np.repeat(np.repeat(CELLS, block, axis=0), block, axis=1)  # (8, 8, 3)
    world = np.array([0.8, 1.0, 1.2])
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float64)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    uvs = v[f][..., :2]
    mats = Materials.from_lists(["Checker"], [(0.5, 0.5, 0.5)], [(0, 0, 0)], texture=[0])
    cam = Camera(scenes.look_at((0.5, 0.5, 1.0), (0.5, 0.5, 0.0), up=(0, 1, 0)), n, n,
                 type="ORTHO", ortho_scale=1.0)
    scene = Scene(v, f, np.zeros(2, np.int32), mats, Lights.empty(), cam, world_color=world,
                  textures=[image], corner_uvs=uvs)
    res = render(scene, plain_settings(spp=16, max_bounces=2, seed=4))
    img = res.combined()[..., :3].astype(np.float64)  # row 0 at the bottom (v = 0)
    assert np.all(np.isfinite(img))
    # Pixels whose filter support (3 px) stays where the bilinear lookup is one cell's colour.
    cell_px = n // 2
    inner = np.arange(cell_px)
    inner = inner[(inner >= 4) & (inner <= cell_px - 5)]
    for cy in range(2):
        for cx in range(2):
            rows, cols = np.meshgrid(cy * cell_px + inner, cx * cell_px + inner, indexing="ij")
            samples = img[rows.ravel(), cols.ravel()]
            assert_mean_within_ci(samples, CELLS[cy, cx] * world, comparisons=12,
                                  what=f"cell ({cy}, {cx})")


def test_roughness_texture_replaces_the_roughness_and_the_delta_flag():
    # A white conductor plane seen straight down under a uniform world: the left half's
    # texel says roughness 0 (a mirror: it reflects the world, 1 x L), the right half's 1 (single
    # scattering GGX reflects E(1, alpha = 1) x L). The material's own roughness, 0, would
    # make both halves mirrors and its delta flag would skip light sampling on the rough half.
    from sampling_lab.core.materials.multiscatter import ggx_albedo
    from sampling_lab.core.scene import MAT_CONDUCTOR
    n = 32
    image = np.array([[(0.0, 0.0, 0.0), (1.0, 1.0, 1.0)]], np.float32)  # (1, 2, 3)
    world = np.array([0.8, 1.0, 1.2])
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float64)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    mats = Materials.from_lists(["Rough"], [(1.0, 1.0, 1.0)], [(0, 0, 0)], kinds=[MAT_CONDUCTOR],
                                roughness=[0.0], roughness_texture=[0])
    cam = Camera(scenes.look_at((0.5, 0.5, 1.0), (0.5, 0.5, 0.0), up=(0, 1, 0)), n, n,
                 type="ORTHO", ortho_scale=1.0)
    scene = Scene(v, f, np.zeros(2, np.int32), mats, Lights.empty(), cam, world_color=world,
                  textures=[image], corner_uvs=v[f][..., :2], texture_interpolation=["Closest"])
    res = render(scene, plain_settings(spp=16, max_bounces=1, seed=3))
    img = res.combined()[..., :3].astype(np.float64)
    assert np.all(np.isfinite(img))
    rough = ggx_albedo(np.array([1.0]), np.array([1.0]))[0]
    assert rough < 0.9
    # Columns whose 3-pixel filter support stays on one half.
    for cols, albedo in ((np.arange(2, n // 2 - 2), 1.0), (np.arange(n // 2 + 2, n - 2), rough)):
        samples = img[2:n - 2][:, cols].reshape(-1, 3)
        assert_mean_within_ci(samples, albedo * world, comparisons=6, rtol=1e-6,
                              what=f"albedo {albedo}")
