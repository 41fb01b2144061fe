"""The path tracer against closed forms, its determinism, and its numerical hard cases."""

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.render import render
from sampling_lab.core.scene import Lights, Materials, Scene
from sampling_lab.core import lights as L
from tests.helpers import assert_mean_within_ci, plain_settings


def pixel_means(result):
    """Each pixel's mean is an independent estimate of the same value in these scenes."""
    return result.combined()[..., 0].ravel().astype(np.float64)


@pytest.mark.parametrize("rho,bounces", [(0.5, 8), (0.8, 3)])
def test_furnace_converges_to_emission_over_one_minus_albedo(rho, bounces):
    scene = scenes.furnace(emission=1.0, albedo=rho, width=32, height=32)
    res = render(scene, plain_settings(spp=64, max_bounces=bounces, seed=7))
    # Paths of up to bounces + 1 scattering vertices: a truncated geometric series.
    expected = (1 - rho ** (bounces + 2)) / (1 - rho)
    assert_mean_within_ci(pixel_means(res), expected)


def test_furnace_without_roulette_agrees_with_roulette():
    scene = scenes.furnace(emission=1.0, albedo=0.7, width=32, height=32)
    res = render(scene, plain_settings(spp=32, max_bounces=6, use_russian_roulette=False))
    assert_mean_within_ci(pixel_means(res), (1 - 0.7**8) / 0.3)


def test_point_light_in_sphere_matches_radiosity_solution():
    rho, power, bounces = 0.5, 100.0, 6
    scene = scenes.point_in_sphere(power=power, albedo=rho, width=32, height=32)
    res = render(scene, plain_settings(spp=64, max_bounces=bounces, seed=3))
    # Uniform radiosity of a sphere: L = rho I / (pi R^2) * sum_k rho^k. The icosphere's facets
    # lie between its inradius and radius 1, which brackets the closed form.
    tri = scene.vertices.astype(np.float64)[scene.triangles]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    r_min = float(np.abs(np.einsum("ij,ij->i", normal, tri[:, 0])).min())
    series = (1 - rho ** (bounces + 1)) / (1 - rho)
    intensity = power / (4 * np.pi)
    hi = rho * intensity / (np.pi * r_min**2) * series
    lo = rho * intensity / np.pi * series
    x = pixel_means(res)
    assert_mean_within_ci(x, 0.5 * (hi + lo), atol=0.5 * (hi - lo))


def test_same_seed_gives_bit_identical_images_for_any_thread_count():
    scene = scenes.cornell_box(24, 20)
    a = render(scene, plain_settings(spp=6, seed=5, threads=1)).combined()
    b = render(scene, plain_settings(spp=6, seed=5, threads=2)).combined()
    c = render(scene, plain_settings(spp=6, seed=6, threads=2)).combined()
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_sample_count_and_variance_passes_are_consistent():
    res = render(scenes.cornell_box(16, 16), plain_settings(spp=5))
    assert (res.sample_count() == 5).all()
    var = res.variance()
    assert var.shape == (16, 16, 3) and np.isfinite(var).all() and (var >= 0).all()
    assert var.max() > 0


def test_cancel_keeps_the_samples_already_taken():
    units = []  # cancel once two work units have reported

    res = render(scenes.cornell_box(64, 64), plain_settings(spp=1000),
                 progress=lambda fraction, text: units.append(fraction),
                 cancel=lambda: len(units) >= 2)
    assert res.cancelled
    counts = res.sample_count()
    assert counts.max() > 0 and counts.max() < 1000
    img = res.combined()
    assert np.isfinite(img).all() and img[..., :3].max() > 0


class _FakeClock:
    """Stands in for the ``time`` module of ``core.render``: its clock moves only when the test
    moves it, so the time limit runs out at a chosen point whatever the machine's speed."""

    def __init__(self):
        self.now = 0.0

    def perf_counter(self):
        return self.now


@pytest.mark.parametrize("spp", [0, 1 << 20])
def test_time_limit_halts_the_render(monkeypatch, spp):
    """With no sample count (0) or one far beyond reach, the render stops once the time limit
    has passed, keeping the samples taken, and is not reported as cancelled."""
    from sampling_lab.core import passes as passes_module

    clock = _FakeClock()
    monkeypatch.setattr(passes_module, "time", clock)
    limit, units_before_limit, backstop = 10.0, 3, 50
    progress_calls, cancel_polls = [], []

    def progress(fraction, text):
        progress_calls.append(fraction)
        if len(progress_calls) == units_before_limit:
            clock.now = limit  # the limit runs out after the third work unit

    def cancel():
        # Only stops a render whose time limit is broken, which then fails as cancelled.
        cancel_polls.append(1)
        return len(cancel_polls) > backstop

    res = render(scenes.cornell_box(16, 16), plain_settings(spp=spp, time_limit=limit),
                 progress=progress, cancel=cancel)
    assert not res.cancelled, "the time limit did not stop the render"
    counts = res.sample_count()
    assert counts.min() > 0
    # It stops at the first check after the limit: at most one more work unit reports.
    assert units_before_limit <= len(progress_calls) <= units_before_limit + 1
    if spp:  # a sample count far beyond reach was not reached
        assert counts.max() < spp and res.stats["spp"] < spp
    # The stats time is the (fake) clock's: the render ended after the limit.
    assert res.stats["time_s"] >= limit
    assert np.isfinite(res.combined()).all()


def test_scene_without_camera_is_a_clear_error():
    scene = scenes.cornell_box(8, 8)
    scene.camera = None
    with pytest.raises(ValueError, match="no camera"):
        render(scene, plain_settings(spp=1))


def _finite_nonneg(res):
    for img in (res.combined(), res.variance(), res.sample_count()):
        assert np.isfinite(img).all()
    assert res.combined()[..., :3].min() >= 0


@pytest.mark.parametrize("scale,offset", [(1e-3, 0.0), (1.0, 0.0), (1e3, 0.0), (1.0, 1e4),
                                          (1e3, 1e4), (1e-3, 1.0)])
def test_no_self_intersection_at_any_scale_or_distance_from_origin(scale, offset):
    """A furnace scaled and moved far away must still give Le / (1 - rho) (no acne)."""
    scene = scenes.furnace(emission=1.0, albedo=0.5, width=16, height=16)
    scene.vertices = (scene.vertices.astype(np.float64) * scale + offset).astype(np.float32)
    scene.camera.to_world = scene.camera.to_world.copy()
    scene.camera.to_world[:3, 3] = offset
    scene.camera.clip_start = 1e-3 * scale
    scene.camera.clip_end = 100 * scale
    res = render(scene, plain_settings(spp=32, max_bounces=4))
    _finite_nonneg(res)
    assert_mean_within_ci(pixel_means(res), (1 - 0.5**6) / 0.5)


def test_degenerate_triangles_and_tiny_bright_sun_leave_no_nan():
    scene = scenes.cornell_box(16, 16)
    v = scene.vertices
    n = v.shape[0]
    # Zero-area triangles: a repeated vertex and three collinear points.
    extra_v = np.array([[0, 0, 1], [0, 0, 1], [0.5, 0, 1], [1e-3, 0, 1]], np.float32)
    scene.vertices = np.concatenate([v, extra_v])
    scene.triangles = np.concatenate([scene.triangles, [[n, n + 1, n + 2], [n, n + 2, n + 3]]])
    scene.material = np.concatenate([scene.material, [0, 3]]).astype(np.int32)
    scene.visibility = np.concatenate([scene.visibility, [31, 31]]).astype(np.int32)
    scene.lights = Lights.concat([L.sun_light((0.1, 0.2, -1), (1, 1, 1), 1e6, 1e-5),
                                  L.point_light((0, 0, 1), (1, 1, 1), 1e3)])
    _finite_nonneg(render(scene, plain_settings(spp=4)))


def test_point_light_on_a_surface_and_grazing_camera_leave_no_nan():
    scene = scenes.cornell_box(16, 16, light="point")
    scene.lights = L.point_light((0.0, 0.0, 0.0), (1, 1, 1), 100.0)  # exactly on the floor
    scene.camera.to_world = scenes.look_at((0, -0.999, 1e-4), (0, 1, 1e-4))
    _finite_nonneg(render(scene, plain_settings(spp=4)))


def test_scene_with_no_geometry_and_no_lights_renders_black():
    scene = scenes.cornell_box(8, 8)
    empty = Scene(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), Materials.from_lists(
        [], np.zeros((0, 3)), np.zeros((0, 3))), Lights.empty(), scene.camera)
    res = render(empty, plain_settings(spp=2))
    assert (res.combined()[..., :3] == 0).all()


def test_finite_rows_flags_rows_with_any_nan_or_inf():
    """``finite_rows`` (the path tracer's test for a usable throughput or estimate) agrees with
    ``np.isfinite(v).all(axis=1)`` on rows with NaN or infinity in any channel."""
    from sampling_lab.core.integrators.common import finite_rows

    rng = np.random.default_rng(2)
    v = rng.normal(size=(600, 3))
    rows = rng.choice(600, 60, replace=False)
    v[rows, rng.integers(0, 3, 60)] = rng.choice([np.nan, np.inf, -np.inf], 60)
    np.testing.assert_array_equal(finite_rows(v), np.isfinite(v).all(axis=1))
    assert (~finite_rows(v)).sum() == 60
