"""The Direct Light Points setting in real Blender: a row of the Light Sampling panel, active
for Bidirectional alone (the only integrator whose render it changes,
``core.applied_settings.used_settings``), whatever the MIS setting, read into the core's
settings."""

import importlib

import pytest

from panels import drawn_rows
from scenes import ADDON_MODULE


@pytest.mark.parametrize("mis", ['POWER', 'BSDF'])
@pytest.mark.parametrize("integrator", ['PATH', 'LIGHT', 'BDPT', 'SPPM', 'MLT', 'RADIOSITY'])
def test_light_points_row_is_active_exactly_where_the_render_uses_it(empty_scene, addon,
                                                                     integrator, mis):
    core_render = importlib.import_module(f"{addon.__name__}.core.render")
    empty_scene.sampling_lab.integrator = integrator
    empty_scene.sampling_lab.mis_heuristic = mis
    active = drawn_rows("SAMPLINGLAB_RENDER_PT_light_sampling", empty_scene)
    used = core_render.used_settings(core_render.RenderSettings(
        integrator=integrator.lower(), mis_heuristic=mis.lower()))
    assert active["light_points"] == (used["light_points"] != "n/a")
    assert active["light_points"] == (integrator == 'BDPT')


def test_light_points_are_read_into_the_render_settings(empty_scene, addon):
    engine = importlib.import_module(f"{ADDON_MODULE}.addon.engine")
    props = empty_scene.sampling_lab
    assert props.light_points == 'LIGHT_PATH'
    props.integrator, props.light_points = 'BDPT', 'FRESH'
    assert engine.render_settings(props).light_points == "fresh"
