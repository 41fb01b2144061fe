"""The radiosity integrator in the render loop (core/integrators/radiosity.py): the furnace seen
through each display, what the options change, what the stats and messages say, the patches
pass, and cancel."""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.render import render, used_settings
from tests.helpers import assert_mean_within_ci, plain_settings

FAST = dict(integrator="radiosity", radiosity_patch_size=1.0, radiosity_samples=4, spp=2)


def _render(scene, **kw):
    return render(scene, plain_settings(**{**FAST, **kw}))


@pytest.mark.parametrize("display", ["gouraud", "flat"])
def test_furnace_pixels_are_emission_over_one_minus_albedo(display):
    # Closed sphere, Le = 1, albedo 0.5: every pixel sees Le / (1 - rho) = 2. The solution's
    # own error (form-factor row sums, tested elsewhere) is far below the 1 % checked here.
    result = _render(scenes.furnace(subdivisions=1, width=8, height=8), radiosity_display=display,
                     radiosity_samples=16)
    image = result.combined()[..., :3]
    assert np.abs(image - 2.0).max() < 0.02


def test_final_gather_of_the_furnace_is_unbiased_for_the_solution():
    # One gather bounce: Le + rho Le (next-event estimation) + rho R / pi (the gather ray) = 2
    # on average; pixels are independent estimates, so their spread gives the interval.
    result = _render(scenes.furnace(subdivisions=1, width=16, height=16),
                     radiosity_display="final_gather",
                     radiosity_samples=16, spp=4)
    pixels = result.combined()[..., 0].reshape(-1)
    assert_mean_within_ci(pixels, 2.0, what="final-gather pixel")
    # Power: an error of 2 % in the mean would show.
    assert 4.5 * pixels.std(ddof=1) / np.sqrt(pixels.size) < 0.04


def test_the_options_change_the_render():
    scene = scenes.cornell_box(16, 16, "area")
    base = _render(scene)
    finer = _render(scene, radiosity_patch_size=0.5)
    flat = _render(scene, radiosity_display="flat")
    gather = _render(scene, radiosity_display="final_gather")
    images = [r.combined() for r in (base, finer, flat, gather)]
    for a in range(4):
        for b in range(a):
            assert not np.allclose(images[a], images[b])
    assert finer.stats["radiosity_patch_count"] > base.stats["radiosity_patch_count"]
    progressive = _render(scene, radiosity_solver="progressive")
    assert progressive.stats["radiosity_solver"] == "progressive"
    for r in (base, finer, flat, gather, progressive):
        image = r.combined()
        assert np.isfinite(image).all() and (image >= 0).all()


def test_stats_and_messages_say_what_was_used_and_that_it_is_biased():
    result = _render(scenes.cornell_sphere(8, 8, "glass", "area", subdivisions=1))
    stats = result.stats
    assert stats["radiosity_solver"] == "gauss_seidel" and stats["radiosity_patch_count"] > 0
    assert stats["mis_heuristic"] == "n/a" and stats["light_selection"] == "n/a"
    assert "biased" in stats["radiosity_bias"]
    texts = " | ".join(result.messages)
    assert "biased and not consistent unless the mesh refines" in texts
    assert sum("treated as diffuse" in m for m in result.messages) == 1
    assert "Ball" in texts and "White" not in texts.split("treated")[0]


def test_radiosity_settings_do_not_apply_to_other_integrators():
    used = used_settings(plain_settings(integrator="path"))
    assert used["radiosity_solver"] == "n/a" and used["radiosity_patch_size"] == "n/a"
    used = used_settings(plain_settings(integrator="radiosity",
                                        radiosity_display="final_gather"))
    assert used["radiosity_display"] == "final_gather" and used["mis_heuristic"] == "n/a"
    assert used["light_selection"] == "power"


def test_the_patches_pass_is_written_only_when_asked_for():
    scene = scenes.cornell_box(8, 8, "area")
    assert _render(scene).layers() == {}
    layers = _render(scene, radiosity_patches=True).layers()
    patches = layers["Radiosity Patches"]
    assert patches.shape == (8, 8, 3) and np.isfinite(patches).all()
    assert len(np.unique(patches.reshape(-1, 3), axis=0)) > 4  # many patches in view


def test_a_cancelled_radiosity_render_stops_in_the_solve():
    calls = []
    result = render(scenes.cornell_box(8, 8, "area"),
                    plain_settings(**{**FAST, "radiosity_patch_size": 0.25}),
                    progress=lambda f, t: calls.append(t), cancel=lambda: len(calls) >= 2)
    assert result.cancelled
    assert result.stats["spp"] == 0
    assert any(t.startswith("Radiosity") for t in calls)


def test_a_bad_patch_size_is_a_clear_error():
    with pytest.raises(ValueError, match="radiosity_patch_size"):
        _render(scenes.cornell_box(8, 8, "area"), radiosity_patch_size=0.0)


def test_a_reused_prepared_scene_reuses_the_solution_for_a_new_camera():
    scene = scenes.cornell_box(8, 8, "area")
    first = _render(scene)
    calls = []
    again = render(scene, plain_settings(**FAST), prepared=first.prepared,
                   progress=lambda f, t: calls.append(t))
    assert not any(t.startswith("Radiosity") for t in calls)
    assert np.array_equal(again.combined(), first.combined())
    other = render(scene, plain_settings(**{**FAST, "radiosity_patch_size": 0.7}),
                   prepared=first.prepared)
    assert other.stats["radiosity_patch_count"] != first.stats["radiosity_patch_count"]


def test_the_benchmark_runs_and_writes_only_its_report(tmp_path):
    from sampling_lab import cli

    out = tmp_path / "bench"
    code = cli.main(["bench-radiosity", "--quick", "--size", "4x4", "--seconds", "0.3",
                     "--reference-seconds", "0.3", "--output", str(out)])
    assert code == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "RADIOSITY_BENCH.md", "radiosity_equal_time.csv", "radiosity_scaling.csv"]
    text = (out / "RADIOSITY_BENCH.md").read_text()
    assert "radiosity, gouraud" in text and "path tracing" in text


@pytest.mark.parametrize("lamp", ["sun", "world"])
def test_an_open_plane_under_the_sun_or_the_sky_is_exact(lamp):
    # Nothing occludes the plane, so every patch's irradiance is exact: the sun's S cos, or
    # pi L from a constant sky (cosine-sampled directions that all escape).
    from sampling_lab.core import lights as L
    from sampling_lab.core.scene import Lights, Materials, Scene

    mats = Materials.from_lists(["W"], [(0.5,) * 3], [(0, 0, 0)])
    v = np.array([[-10, -10, 0], [10, -10, 0], [10, 10, 0], [-10, 10, 0]], float)
    d = np.array((0.3, 0.2, -1.0))
    lights = L.sun_light(d, (1, 1, 1), 3.0) if lamp == "sun" else Lights.empty()
    world = (0, 0, 0) if lamp == "sun" else (0.2, 0.2, 0.2)
    camera = scenes.Camera(scenes.look_at((0, 0, 3), (0, 0, 0), up=(0, 1, 0)), 8, 8)
    scene = Scene(v, [[0, 1, 2], [0, 2, 3]], np.zeros(2), mats, lights, camera,
                  world_color=world)
    expected = 0.5 * 3.0 / np.linalg.norm(d) / np.pi if lamp == "sun" else 0.5 * 0.2
    image = _render(scene, radiosity_patch_size=5.0).combined()[..., :3]
    assert np.allclose(image, expected, rtol=1e-5)
