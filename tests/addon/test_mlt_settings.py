"""Metropolis light transport in real Blender: the Metropolis panel's rows, and the path
tracer's rows that MLT reads (per-kind bounces, area-light sampling), are active exactly where
the render uses them (``core.applied_settings.used_settings``), and an MLT render shows its image pass by
pass and writes a finite EXR."""

import numpy as np
import pytest

import scenes
from panels import drawn_rows

ROWS = ("mlt_large_step", "mlt_bootstrap", "mlt_chains")
PATH_ROWS = {"SAMPLINGLAB_RENDER_PT_light_paths": ("diffuse_bounces", "glossy_bounces",
                                                   "transmission_bounces",
                                                   "transparent_max_bounces"),
             "SAMPLINGLAB_RENDER_PT_light_sampling": ("mis_heuristic", "light_sampling")}


@pytest.mark.parametrize("integrator", ['MLT', 'PATH', 'BDPT', 'SPPM', 'RADIOSITY'])
def test_metropolis_rows_are_active_exactly_where_the_render_uses_them(empty_scene, addon,
                                                                        integrator):
    from importlib import import_module
    core_render = import_module(f"{addon.__name__}.core.render")
    empty_scene.sampling_lab.integrator = integrator
    used = core_render.used_settings(core_render.RenderSettings(integrator=integrator.lower()))
    active = drawn_rows("SAMPLINGLAB_RENDER_PT_mlt", empty_scene)
    assert set(active) == set(ROWS)
    for row in ROWS:
        assert active[row] == (used[row] != "n/a") == (integrator == 'MLT'), row
    if integrator not in ('MLT', 'PATH'):
        return
    # MLT runs the path tracer: its rows are active as they are for path tracing.
    for panel, rows in PATH_ROWS.items():
        active = drawn_rows(panel, empty_scene)
        for row in rows:
            assert active[row] == (used[row] != "n/a"), (panel, row)


def test_mlt_render_shows_every_pass_and_writes_a_finite_image(empty_scene, tmp_path,
                                                               pass_counts):
    scenes.cornell_box_point_light(empty_scene, resolution=(16, 16))
    scenes.set_sampling_lab(empty_scene, samples=3, max_bounces=3)
    empty_scene.sampling_lab.integrator = 'MLT'
    empty_scene.sampling_lab.mlt_bootstrap = 4000
    passes = scenes.render_to_exr(empty_scene, tmp_path / "mlt.exr")
    assert pass_counts[:3] == [1.0, 2.0, 3.0]
    combined = passes["Combined"] if "Combined" in passes else passes["Image"]
    assert np.isfinite(combined).all() and combined[..., :3].max() > 0


def test_stats_line_gives_b_its_error_and_the_acceptance(addon):
    from importlib import import_module
    engine = import_module(f"{addon.__name__}.addon.engine")
    text = engine.estimator_text({"estimator_bias": "consistent, b estimated", "mlt_b": 0.7143,
                                  "mlt_b_rel_se": 0.0123, "mlt_acceptance": 0.4})
    assert text == ", consistent, b estimated: b 0.7143 +- 1.2%, acceptance 40%"
    dark = engine.estimator_text({"estimator_bias": "consistent, b estimated", "mlt_b": 0.0,
                                  "mlt_b_rel_se": None, "mlt_acceptance": 0.0})
    assert dark == ", consistent, b estimated: b 0, acceptance 0%"
