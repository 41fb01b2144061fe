"""Film > Transparent (path tracing): camera rays that escape give alpha 0, the world still
lights the scene, transparent surfaces in front of the background give partial alpha, and the
EXR keeps the alpha channel."""

import numpy as np
import pytest

from sampling_lab.core import exr, scenes
from sampling_lab.core.materials.bsdf import KIND_DIELECTRIC
from sampling_lab.core.render import render
from sampling_lab.core.scene import Camera, Lights, Materials, Scene
from tests.helpers import assert_images_agree, assert_mean_within_ci, plain_settings


def _floor_under_sky(transparent, sheet=None, size=24):
    """A grey floor of half-size 0.5 seen from above with a wide lens (the sky around it), a
    white world of radiance 1; ``sheet``: (material rows, weights) of a large sheet over the
    whole view at z = 1."""
    v = np.array([[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, 0.5, 0], [-0.5, 0.5, 0]], np.float32)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    mats = [0, 0]
    table = dict(kinds=[0, KIND_DIELECTRIC, 0], roughness=[0.5, 0.0, 0.5], ior=[1.5, 1.0, 1.5])
    colors = [(0.5,) * 3, (0.6, 0.4, 0.2), (0,) * 3]
    if sheet is not None:
        v = np.concatenate([v, 4 * v + np.array([0, 0, 1], np.float32)])
        f = np.concatenate([f, f + 4])
        mats += [3, 3]
        rows, weights = sheet
        table["kinds"] = table["kinds"] + [0]
        table["roughness"] = table["roughness"] + [0.5]
        table["ior"] = table["ior"] + [1.5]
        colors.append((1,) * 3)
        table["mix_rows"] = [[0, 0], [1, 1], [2, 2], rows]
        table["mix_weights"] = [[1, 0], [1, 0], [1, 0], weights]
    materials = Materials.from_lists([f"m{i}" for i in range(len(colors))], colors,
                                     np.zeros((len(colors), 3)), **table)
    camera = Camera(to_world=scenes.look_at((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0)), width=size,
                    height=size, lens=50.0, sensor_width=36.0, clip_start=0.1, clip_end=100.0)
    return Scene(v, f, np.array(mats, np.int32), materials, Lights.empty(), camera,
                 world_color=np.ones(3), film_transparent=transparent)


def test_background_is_transparent_and_the_world_still_lights_the_floor():
    settings = plain_settings(spp=8, max_bounces=2, seed=3)
    opaque = render(_floor_under_sky(False), settings).combined()
    clear = render(_floor_under_sky(True), settings).combined()
    floor = clear[..., 3] == 1.0
    sky = clear[..., 3] == 0.0
    assert floor.sum() > 50 and sky.sum() > 100
    # Pixels whose every sample saw the floor: the same samples, the same light (bit for bit).
    np.testing.assert_array_equal(clear[floor, :3], opaque[floor, :3])
    assert clear[floor, :3].min() > 0.0
    # The world is not drawn: sky pixels are black with alpha 0 (opaque: the world, alpha 1).
    assert clear[sky, :3].max() == 0.0
    np.testing.assert_allclose(opaque[sky], 1.0, rtol=1e-6)
    assert (opaque[..., 3] == 1.0).all()


def test_alpha_behind_a_transparent_sheet_is_one_minus_its_mean_colour():
    # A Transparent BSDF of colour (0.6, 0.4, 0.2) over everything: alpha 1 - 0.4 over the sky.
    clear = render(_floor_under_sky(True, sheet=([1, 1], [1, 0])),
                   plain_settings(spp=4, max_bounces=2)).combined()
    sky = clear[[0, -1], :, 3].ravel()
    np.testing.assert_allclose(sky, 1.0 - 0.4, rtol=1e-6)


def test_alpha_behind_a_half_transparent_sheet_is_one_minus_half_its_colour():
    # Half black diffuse, half the Transparent BSDF of mean colour 0.4: each sample passes with
    # probability 1/2 and then counts 0.4 transparent: alpha 1 - 0.5 x 0.4 on average.
    res = render(_floor_under_sky(True, sheet=([1, 2], [0.5, 0.5])),
                 plain_settings(spp=16, max_bounces=2, seed=5))
    corner = res.combined()[:4, :4, 3].ravel().astype(np.float64)
    # Per-pixel alpha is a mean of 16 independent samples: a CI over the 16 corner pixels.
    assert_mean_within_ci(corner, 0.8)


def test_exr_keeps_the_alpha_channel(tmp_path):
    res = render(_floor_under_sky(True), plain_settings(spp=2, max_bounces=1))
    path = tmp_path / "alpha.exr"
    exr.write_multilayer(str(path), {"Combined": res.combined()})
    back = exr.read_multilayer(str(path))["Combined"]
    assert back.shape[-1] == 4
    np.testing.assert_array_equal(back[..., 3], res.combined()[..., 3])
    assert back[..., 3].min() == 0.0 and back[..., 3].max() == 1.0


# Light tracing, BDPT, photon mapping and SPPM make the alpha from their camera rays as the path
# tracer does (core/integrators/camera_hits.py, core/photons/visible.py).
ESTIMATORS = {
    "light": dict(integrator="light"),
    "bdpt": dict(integrator="bdpt"),
    "photon": dict(integrator="photon", photons=20_000, photon_lookup="radius",
                   photon_radius=0.03, gather_rays=1),
    "sppm": dict(integrator="sppm", photons=1000, photon_radius=0.02),
}


@pytest.mark.parametrize("integrator", sorted(ESTIMATORS))
def test_other_estimators_hide_the_background_and_make_the_path_tracers_alpha(integrator):
    # Same sampler and seed: the camera rays are the path tracer's (the pixel filter's numbers
    # are the same dimensions), so the alpha is the path tracer's bit for bit (an error in any
    # pixel is detected). The same render on an opaque film differs by exactly the world seen
    # by the camera rays (radiance 1 times the escaped share 1 - alpha, to float32 rounding):
    # the world still lights the floor (next-event estimation, light paths, photons), only what
    # the camera rays see of it goes. Before, the film stayed opaque: this fails.
    kw = ESTIMATORS[integrator]
    path = render(_floor_under_sky(True), plain_settings(spp=8, max_bounces=2, seed=3))
    clear = render(_floor_under_sky(True), plain_settings(spp=8, max_bounces=2, seed=3, **kw))
    opaque = render(_floor_under_sky(False), plain_settings(spp=8, max_bounces=2, seed=3, **kw))
    assert not [m for m in clear.messages if "Film > Transparent" in m], clear.messages
    rgba, opaque = clear.combined(), opaque.combined()
    np.testing.assert_array_equal(rgba[..., 3], path.combined()[..., 3])
    floor, sky = rgba[..., 3] == 1.0, rgba[..., 3] == 0.0
    assert floor.sum() > 50 and sky.sum() > 100
    world_seen = np.broadcast_to(1.0 - rgba[..., 3:], rgba[..., :3].shape)
    np.testing.assert_allclose(opaque[..., :3] - rgba[..., :3], world_seen, atol=1e-6)
    assert rgba[floor, :3].min() > 0.0
    assert (opaque[..., 3] == 1.0).all()


@pytest.mark.parametrize("integrator", sorted(ESTIMATORS))
def test_other_estimators_alpha_behind_transparent_sheets(integrator):
    # A Transparent BSDF of colour (0.6, 0.4, 0.2) over everything: alpha 1 - 0.4 over the sky
    # (every sample, exactly). Half black diffuse, half that Transparent BSDF: alpha 1 - 0.5 x
    # 0.4 on average, a mean of 16 independent samples per pixel: a confidence interval over
    # the 16 corner pixels (half-width measured 0.063 at p = 1e-4, standard error 0.0125: an
    # alpha error of 0.1, 12 %, is detected with 99 % power).
    kw = ESTIMATORS[integrator]
    full = render(_floor_under_sky(True, sheet=([1, 1], [1, 0])),
                  plain_settings(spp=4, max_bounces=2, **kw)).combined()
    np.testing.assert_allclose(full[[0, -1], :, 3].ravel(), 1.0 - 0.4, rtol=1e-6)
    half = render(_floor_under_sky(True, sheet=([1, 2], [0.5, 0.5])),
                  plain_settings(spp=16, max_bounces=2, seed=5, **kw)).combined()
    assert_mean_within_ci(half[:4, :4, 3].ravel().astype(np.float64), 0.8)


@pytest.fixture(scope="module")
def path_on_transparent_film():
    """The path tracer's image of the floor under the sky on a transparent film (512 spp)."""
    return render(_floor_under_sky(True), plain_settings(spp=512, max_bounces=2, seed=1))


@pytest.mark.parametrize("integrator", sorted(ESTIMATORS))
def test_other_estimators_colour_on_a_transparent_film_agrees_with_path_tracing(
        integrator, path_on_transparent_film):
    # Eight seeds of 64 spp against the path tracer's 512 spp, image and 8 x 8 block means
    # within confidence intervals. The floor is lit by the world alone and its light escapes
    # (Max Bounces 2): the photon estimators read no photon here, so no bias allowance.
    # Detects (measured, 99 % power) 3.6 % (light), 2.0 % (BDPT), 3.2 % (photon, SPPM)
    # image-mean errors; the blocks straddle the floor's edge and detect 18-39 % only. A world
    # left in the picture would add 1 to each of the 428 sky pixels of 576: the image mean
    # several times over.
    path = path_on_transparent_film
    reps = np.array([render(_floor_under_sky(True), plain_settings(
        spp=64, max_bounces=2, seed=10 + s, **ESTIMATORS[integrator])).film.mean()
        for s in range(8)])
    assert_images_agree(path.film.mean(), path.film.variance(), reps, block=8,
                        detect=(0.04, 0.40), what=f"{integrator} vs path, transparent film")
