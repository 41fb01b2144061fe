"""Film > Transparent for Metropolis light transport and radiosity: the alpha from their own
camera rays (core/integrators/camera_alpha.py for MLT), the world seen directly left out of the
colour, the world still lighting the scene."""

import dataclasses

import numpy as np
import pytest

from sampling_lab.core.render import render
from tests.core.test_film_transparent import _floor_under_sky
from tests.helpers import assert_images_agree, plain_settings

FULL_SHEET = ([1, 1], [1, 0])  # a Transparent BSDF of colour (0.6, 0.4, 0.2)
HALF_SHEET = ([1, 2], [0.5, 0.5])  # half that, half black diffuse


def _render(transparent, integrator, spp=8, seed=3, sheet=None, **kw):
    return render(_floor_under_sky(transparent, sheet=sheet),
                  plain_settings(spp=spp, max_bounces=2, seed=seed, integrator=integrator, **kw))


@pytest.mark.parametrize("integrator", ["mlt", "radiosity"])
def test_alpha_is_the_path_tracers_and_the_film_is_not_reported_opaque(integrator):
    # Same sampler and seed: the camera samples are the path tracer's (dimensions 0-1), so the
    # alpha is the path tracer's bit for bit: a wrong escape in any one sample of 8 in any
    # pixel (an alpha error of 1/8) is detected. Before, the film stayed alpha 1: this fails.
    path = _render(True, "path").combined()
    res = _render(True, integrator)
    rgba = res.combined()
    assert not [m for m in res.messages if "Film > Transparent" in m], res.messages
    np.testing.assert_array_equal(rgba[..., 3], path[..., 3])
    floor, sky = rgba[..., 3] == 1.0, rgba[..., 3] == 0.0
    assert floor.sum() > 50 and sky.sum() > 100
    # The world still lights the floor (radiance 1 from above, albedo 0.5).
    assert rgba[floor, :3].min() > 0.0


def test_radiosity_opaque_minus_transparent_is_the_world_seen():
    # Radiosity's camera samples and solve are the same on both films: the two images differ
    # by exactly the world (radiance 1) times the escaped share 1 - alpha (float32 rounding):
    # the world left in, or any light of the floor lost with it, shows in a pixel.
    clear = _render(True, "radiosity").combined()
    opaque = _render(False, "radiosity").combined()
    world_seen = np.broadcast_to(1.0 - clear[..., 3:], clear[..., :3].shape)
    np.testing.assert_allclose(opaque[..., :3] - clear[..., :3], world_seen, atol=1e-6)
    assert (opaque[..., 3] == 1.0).all()


def _far_from(mask, reach=2):
    """Pixels more than ``reach`` pixels (Chebyshev) from any pixel of ``mask (h, w)``."""
    near = np.zeros_like(mask)
    h, w = mask.shape
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            near[max(dy, 0):h + min(dy, 0), max(dx, 0):w + min(dx, 0)] |= \
                mask[max(-dy, 0):h + min(-dy, 0), max(-dx, 0):w + min(-dx, 0)]
    return ~near


def test_mlt_leaves_the_world_seen_out_of_its_chains():
    # Max Bounces 2 under a white world: on the transparent film the only light is the floor's.
    # The chains' target leaves the world seen by camera rays out, so sky pixels beyond the
    # pixel filter's reach of the floor get no splat at all (exactly black); with the world
    # in the target they would be about 1, as on the opaque film (there a chain's histogram:
    # its mean over those pixels within 10 % of 1, a loose bound on a correct estimate whose
    # b alone has a relative standard error of about 1 %).
    clear = _render(True, "mlt").combined()
    opaque = _render(False, "mlt").combined()
    far = _far_from(clear[..., 3] > 0.0)
    assert far.sum() > 100
    assert clear[far, :3].max() == 0.0
    assert abs(opaque[far, :3].mean() - 1.0) < 0.1


def test_mlt_alpha_behind_transparent_sheets_is_its_expectation_in_every_pixel():
    # MLT's alpha takes each pass through a transparent surface in expectation: behind the
    # full sheet every pixel is 1 - 0.4 and behind the half sheet 1 - 0.5 x 0.4 = 0.8,
    # exactly (to float rounding) where the path tracer's is a mean of sampled passes; an
    # error of 1e-6 in any pixel is detected (the path tracer's own check is a CI).
    full = _render(True, "mlt", spp=2, sheet=FULL_SHEET).combined()
    np.testing.assert_allclose(full[..., 3][[0, -1]].ravel(), 0.6, rtol=1e-6)
    half = _render(True, "mlt", spp=2, sheet=HALF_SHEET).combined()
    np.testing.assert_allclose(half[..., 3][[0, -1]].ravel(), 0.8, rtol=1e-6)


def test_mlt_transparent_limit_zero_still_passes_one_sheet_as_the_path_tracer():
    # Cycles' rule (core/integrators/bounces.py): a camera ray passes max(T, 1) surfaces, so
    # the sky behind one sheet shows through it at Transparent 0 too, in both estimators.
    kw = dict(spp=2, sheet=FULL_SHEET, transparent_max_bounces=0)
    path = _render(True, "path", **kw).combined()
    mlt = _render(True, "mlt", **kw).combined()
    np.testing.assert_allclose(mlt[..., 3][[0, -1]], path[..., 3][[0, -1]], rtol=1e-6)
    np.testing.assert_allclose(mlt[..., 3][[0, -1]].ravel(), 0.6, rtol=1e-6)


def test_radiosity_stops_camera_rays_at_a_transparent_sheet_and_says_so():
    # Radiosity renders every surface diffuse (reported): its camera rays stop at the sheet,
    # so the alpha behind it is 1 where the path tracer's is 0.6 (a documented limitation).
    res = _render(True, "radiosity", spp=2, sheet=FULL_SHEET)
    assert (res.combined()[..., 3] == 1.0).all()
    assert any("treated as diffuse" in m for m in res.messages), res.messages


def test_mlt_colour_on_a_transparent_film_agrees_with_path_tracing():
    # Sixteen seeds of 128 mutations per pixel against the path tracer's 512 spp, image and
    # 8 x 8 block means within confidence intervals (seeds are independent; pixels within one
    # render are not, so only the replicates give MLT's variance). The floor is lit by the
    # world alone. A world left in the chains would add about 1 to each of the 428 sky pixels
    # of 576: the image mean several times over. Detects (measured, 99 % power) a 1.9 %
    # image-mean and a 33 % block error (the blocks straddle the floor's edge).
    path = _render(True, "path", spp=512, seed=1)
    reps = np.array([_render(True, "mlt", spp=128, seed=10 + s).film.mean()
                     for s in range(16)])
    assert_images_agree(path.film.mean(), path.film.variance(), reps, block=8,
                        detect=(0.02, 0.40), what="mlt vs path, transparent film")


def _two_sheets():
    """The floor under the sky behind two full Transparent sheets (z = 1 and z = 1.5)."""
    scene = _floor_under_sky(True, sheet=FULL_SHEET)
    v = np.asarray(scene.vertices)
    second = v[-4:] + np.array([0, 0, 0.5], np.float32)
    return dataclasses.replace(
        scene, vertices=np.concatenate([v, second]),
        triangles=np.concatenate([scene.triangles, scene.triangles[-2:] + 4]),
        material=np.concatenate([scene.material, scene.material[-2:]]))


@pytest.mark.parametrize("limit,expected", [(1, 1.0), (2, 1.0 - (0.36 + 0.16 + 0.04) / 3)])
def test_transparent_limit_changes_mlts_alpha_as_the_path_tracers(limit, expected):
    # The Transparent limit is used by MLT (used_settings: the path tracer's): behind two
    # sheets a camera ray reaches the sky only if it may pass two surfaces, then with
    # transparency mean((0.6, 0.4, 0.2)^2) = 0.187; with a limit of one it stops at the second
    # sheet (alpha 1). Both estimators pass every sheet with its colour (no choice), so the
    # path tracer's alpha is exact too; an alpha error of 1e-6 is detected.
    scene = _two_sheets()
    kw = dict(spp=2, max_bounces=2, transparent_max_bounces=limit)
    mlt = render(scene, plain_settings(integrator="mlt", **kw)).combined()[..., 3]
    path = render(scene, plain_settings(**kw)).combined()[..., 3]
    np.testing.assert_allclose(mlt[[0, -1]].ravel(), expected, rtol=1e-6)
    np.testing.assert_allclose(path[[0, -1]].ravel(), expected, rtol=1e-6)
