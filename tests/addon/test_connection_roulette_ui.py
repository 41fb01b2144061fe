"""The Connection Roulette setting in real Blender: a row of the Light Paths panel, active for
Bidirectional alone (the only integrator whose render it changes,
``core.applied_settings.used_settings``), read into the core's settings."""

import importlib

import pytest

from panels import drawn_rows
from scenes import ADDON_MODULE


@pytest.mark.parametrize("integrator", ['PATH', 'LIGHT', 'BDPT', 'PHOTON', 'MLT'])
def test_connection_roulette_row_is_active_exactly_where_the_render_uses_it(empty_scene, addon,
                                                                             integrator):
    core_render = importlib.import_module(f"{addon.__name__}.core.render")
    empty_scene.sampling_lab.integrator = integrator
    active = drawn_rows("SAMPLINGLAB_RENDER_PT_light_paths", empty_scene)
    used = core_render.used_settings(core_render.RenderSettings(integrator=integrator.lower()))
    assert active["connection_roulette"] == (used["connection_roulette"] != "n/a")
    assert active["connection_roulette"] == (integrator == 'BDPT')


def test_connection_roulette_is_read_into_the_render_settings(empty_scene, addon):
    engine = importlib.import_module(f"{ADDON_MODULE}.addon.engine")
    props = empty_scene.sampling_lab
    assert props.connection_roulette == 0.0
    props.integrator, props.connection_roulette = 'BDPT', 0.3
    assert engine.render_settings(props).connection_roulette == pytest.approx(0.3)
