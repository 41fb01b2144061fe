"""The world's environment map: Cycles' equirectangular mapping, importance sampling, MIS.

Checks: the mapping's orientation and inverse; the sampling density integrates to one over the
sphere and matches a histogram of the sampled directions (chi-square); the density MIS reads
from ``world_radiance`` is the one ``sample`` drew from; NEE irradiance under a map of constant
rows equals its closed form; a white diffuse sphere under a uniform map renders as under the
same constant world (a furnace); BSDF-only, light-only and MIS renders agree under a map with a
tiny bright sun; and no NaN at the poles.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core import lights as L
from sampling_lab.core import scenes
from sampling_lab.core.prepare import prepare
from sampling_lab.core.render import render
from sampling_lab.core.scene import Camera, Lights, Materials, Scene
from tests.helpers import (
    assert_estimates_agree,
    assert_mean_within_ci,
    chi_square_directions,
    integrate_solid_angle,
    plain_settings,
)

METHODS = ("cdf", "alias")


def gradient_map(h=16, w=32, sun=True):
    """A sky brighter toward +Y and the zenith, a dark ground, and optionally one bright pixel."""
    v = (np.arange(h) + 0.5) / h
    u = (np.arange(w) + 0.5) / w
    sky = 0.2 + 2.0 * v[:, None] ** 2 + 0.5 * np.sin(2 * np.pi * u)[None, :] ** 2
    m = np.stack([sky, 0.8 * sky, 0.5 * sky], axis=-1)
    if sun:
        m[int(0.7 * h), int(0.3 * w)] = (400.0, 380.0, 300.0)
    return m.astype(np.float32)


def world_scene(world_map=None, world_color=(0.0, 0.0, 0.0), geometry=None, albedo=1.0,
                camera=None):
    """Only a world (and optionally a diffuse mesh ``geometry = (v, f)``)."""
    v, f = geometry if geometry is not None else (np.zeros((0, 3)), np.zeros((0, 3), np.int32))
    mats = Materials.from_lists(["Diffuse"], [(albedo,) * 3], [(0.0, 0.0, 0.0)])
    cam = camera or Camera(scenes.look_at((0, -4, 0), (0, 0, 0)), 16, 16, lens=35.0)
    return Scene(v, f, np.zeros(len(f), np.int32), mats, Lights.empty(), cam,
                 world_color=world_color, world_map=world_map)


def world_sampler(world_map, method="cdf"):
    lights = prepare(world_scene(world_map), distribution=method).lights
    assert lights.has_world and lights.world_dist is not None
    return lights


def test_equirect_mapping_follows_cycles_orientation():
    # Cycles: u = 0.5 faces +X, 0.25 faces +Y, 0.75 faces -Y, 0 faces -X; v = 1 is the zenith.
    d = np.array([[1, 0, 0], [0, 1, 0], [0, -1, 0], [-1, 1e-12, 0], [0, 0, 1], [0, 0, -1],
                  [1, 0, 1]], np.float64)
    uv = L.equirect_uv(d)
    np.testing.assert_allclose(uv[:, 0][:4], [0.5, 0.25, 0.75, 0.0], atol=1e-9)
    np.testing.assert_allclose(uv[:, 1], [0.5, 0.5, 0.5, 0.5, 1.0, 0.0, 0.75], atol=1e-12)
    rng = np.random.default_rng(0)
    uv = rng.random((1000, 2))
    d, sin_t = L.equirect_direction(uv)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(sin_t, np.hypot(d[:, 0], d[:, 1]), atol=1e-12)
    np.testing.assert_allclose(L.equirect_uv(d), uv, atol=1e-9)


def test_environment_lookup_is_bilinear_between_pixel_centres_and_wraps():
    m = np.zeros((4, 8, 3), np.float32)
    m[2, 3] = 1.0
    centre = np.array([[3.5 / 8, 2.5 / 4]])
    np.testing.assert_allclose(L.environment_lookup(m, centre), [[1, 1, 1]])
    half = np.array([[4.0 / 8, 2.5 / 4], [3.5 / 8, 3.0 / 4]])
    np.testing.assert_allclose(L.environment_lookup(m, half), 0.5)
    # Repeat on u: the left edge blends the first and last columns.
    m2 = np.zeros((4, 8, 3), np.float32)
    m2[1, 7] = 2.0
    np.testing.assert_allclose(L.environment_lookup(m2, np.array([[0.0, 1.5 / 4]])), 1.0)


@pytest.mark.parametrize("method", METHODS)
def test_environment_pdf_integrates_to_one_over_the_sphere(method):
    lights = world_sampler(gradient_map(), method)
    assert lights.select_prob[lights.world_index] == pytest.approx(1.0)
    total = integrate_solid_angle(lights.world_pdf, res=(1024, 1024))
    assert total == pytest.approx(1.0, abs=5e-3)


@pytest.mark.parametrize("method", METHODS)
def test_environment_directions_match_environment_pdf(method):
    lights = world_sampler(gradient_map(sun=False), method)
    # The solid-angle density has an integrable 1 / sin(theta) peak at the poles: a fine
    # quadrature (and its residual error in the mass check) in the (cos theta, phi) cells.
    chi_square_directions(lambda u: lights._sample_world_map(u)[0], lights.world_pdf,
                          n=200_000, res=(16, 32), subdiv=64, seed=3, mass_tol=3e-3,
                          what=f"environment ({method})")


def test_environment_chi_square_rejects_a_wrong_density():
    """The checker sees the map's shape: claiming the uniform density must fail."""
    lights = world_sampler(gradient_map(sun=False))
    with pytest.raises(AssertionError, match="chi-square"):
        chi_square_directions(lambda u: lights._sample_world_map(u)[0],
                              lambda w: np.full(w.shape[0], 1 / (4 * np.pi)), n=200_000,
                              res=(16, 32), seed=3, what="uniform claim")


@pytest.mark.parametrize("method", METHODS)
def test_world_radiance_pdf_equals_the_sampling_pdf(method):
    lights = world_sampler(gradient_map(), method)
    rng = np.random.default_rng(5)
    n = 50_000
    p = np.zeros((n, 3))
    wi, dist, le, pdf, delta, _ = lights.sample(p, rng.random(n), rng.random((n, 2)))
    le_ray, pdf_ray = lights.world_radiance(wi)
    assert np.all(np.isinf(dist)) and not delta.any()
    assert np.all(pdf > 0) and np.all(np.isfinite(pdf))
    # Directions on a cell edge may round into the neighbouring cell; nothing else may differ.
    same = np.isclose(pdf_ray, pdf, rtol=1e-6)
    assert same.mean() > 0.999
    np.testing.assert_allclose(le_ray, le, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("method", METHODS)
def test_nee_irradiance_under_constant_rows_matches_closed_form(method):
    """Sky of radiance ``L_top`` above the horizon, dark ground: E = pi L_top on an upward
    surface, up to the bilinear blend across the horizon and the zenith row (both computed
    here from the rows independently of the renderer)."""
    h, w, l_top = 64, 16, 2.0
    rows = np.where(np.arange(h) >= h // 2, l_top, 0.0)
    m = np.repeat(rows[:, None, None], w, axis=1).repeat(3, axis=2).astype(np.float32)
    # Radiance profile in v: linear between row centres, wrapping past both poles.
    centres = (np.arange(-1, h + 1) + 0.5) / h
    values = np.concatenate([[rows[-1]], rows, [rows[0]]])
    v = 0.5 + (np.arange(400_000) + 0.5) / 800_000
    profile = np.interp(v, centres, values)
    theta = np.pi * (1 - v)
    expected = 2 * np.pi * np.sum(profile * np.cos(theta) * np.sin(theta)) * np.pi * (0.5 / v.size)
    assert expected == pytest.approx(np.pi * l_top, rel=0.03)

    lights = world_sampler(m, method)
    rng = np.random.default_rng(11)
    n = 400_000
    wi, _, le, pdf, _, _ = lights.sample(np.zeros((n, 3)), rng.random(n), rng.random((n, 2)))
    est = np.where(pdf > 0, le[:, 0] * np.maximum(wi[:, 2], 0.0) / np.where(pdf > 0, pdf, 1.0),
                   0.0)
    assert np.all(np.isfinite(est))
    assert_mean_within_ci(est.reshape(400, -1).mean(axis=1), expected, what="irradiance")


@pytest.mark.parametrize("use_map", [False, True], ids=["constant", "uniform_map"])
def test_white_sphere_under_uniform_world_is_a_furnace(use_map):
    c = (0.7, 0.5, 0.3)
    world_map = np.broadcast_to(np.asarray(c, np.float32), (8, 16, 3)) if use_map else None
    scene = world_scene(world_map=world_map, world_color=c, geometry=scenes.icosphere(2))
    res = render(scene, plain_settings(spp=16, max_bounces=4, seed=2))
    img = res.combined()[..., :3].reshape(-1, 3).astype(np.float64)
    assert np.all(np.isfinite(img))
    # A convex white object under a uniform sky reflects exactly the sky: every pixel is c.
    assert_mean_within_ci(img, np.asarray(c), rtol=1e-5, what="furnace")


def _plane_and_sphere(world_map, spp, mis, seed):
    v_s, f_s = scenes.icosphere(2, radius=0.5)
    v_s = v_s + (0.0, 0.0, 0.5)
    v_p = np.array([[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]], np.float64)
    f_p = np.array([[0, 1, 2], [0, 2, 3]]) + len(v_s)
    geometry = (np.concatenate([v_s, v_p]), np.concatenate([f_s, f_p]))
    cam = Camera(scenes.look_at((0, -4, 2.0), (0, 0, 0.4)), 16, 16, lens=35.0)
    scene = world_scene(world_map=world_map, geometry=geometry, albedo=0.6, camera=cam)
    return render(scene, plain_settings(spp=spp, max_bounces=3, seed=seed, mis_heuristic=mis,
                                        use_russian_roulette=False))


def test_bsdf_light_and_mis_agree_under_a_map_with_a_tiny_bright_sun():
    """Light-only sampling is right only if the samples follow the pdf it divides by; BSDF-only
    is right whatever the map's sampling; MIS needs both pdfs to agree. All three must match."""
    m = gradient_map(h=32, w=64)

    def image_mean(mis, seed):
        res = _plane_and_sphere(m, 64, mis, seed)
        img = res.combined()[..., :3].astype(np.float64)
        var = res.variance().astype(np.float64)
        assert np.all(np.isfinite(img)) and np.all(np.isfinite(var))
        n = img.shape[0] * img.shape[1]
        # Pixel estimates are independent: the image mean's variance is their sum / n^2.
        return img.mean(axis=(0, 1)), np.sqrt(var.sum(axis=(0, 1))) / n

    ref = image_mean("power", 4)
    for mis, seed in (("light", 5), ("bsdf", 6)):
        assert_estimates_agree(*ref, *image_mean(mis, seed), what=f"image mean power vs {mis}")


def test_no_nan_at_the_poles_or_for_a_single_bright_pixel():
    h, w = 16, 32
    m = np.zeros((h, w, 3), np.float32)
    m[h - 1, 5] = 1e4      # at the zenith row
    m[0, 17] = 1e3         # at the nadir row
    m[9, 20] = 5e4         # a tiny bright sun
    lights = world_sampler(m)
    poles = np.array([[0, 0, 1.0], [0, 0, -1.0], [1e-300, 0, 1.0]])
    le, pdf = lights.world_radiance(poles)
    assert np.all(np.isfinite(le)) and np.all(np.isfinite(pdf))
    # Extreme random numbers reach the poles' rows and the map's seams.
    u = np.array([[0.0, 0.0], [0.0, 1 - 2**-53], [1 - 2**-53, 1 - 2**-53], [0.5, 0.0]])
    wi, le, pdf = lights._sample_world_map(u)
    assert np.all(np.isfinite(wi)) and np.all(np.isfinite(le)) and np.all(np.isfinite(pdf))
    res = _plane_and_sphere(m, 8, "power", seed=1)
    assert np.all(np.isfinite(res.combined()))
    assert np.all(np.isfinite(res.variance()))


def test_black_map_is_no_emitter():
    lights = prepare(world_scene(np.zeros((4, 8, 3), np.float32), world_color=(1, 1, 1))).lights
    assert not lights.has_world and lights.world_index == -1 and lights.n_emitters == 0
