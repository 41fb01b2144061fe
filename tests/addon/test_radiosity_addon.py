"""Radiosity inside real Blender: its panel (greyed out unless it applies), the options that do
not apply to it greyed out, and a render with the Radiosity Patches pass."""

import bpy
import numpy as np
import pytest

import scenes as S
from panels import drawn_rows

RADIOSITY_PROPS = ("radiosity_solver", "radiosity_patch_size", "radiosity_samples",
                   "radiosity_adaptive", "radiosity_display", "use_radiosity_patches")


@pytest.mark.parametrize("integrator", ['PATH', 'RADIOSITY'])
def test_radiosity_panel_is_active_only_for_radiosity(empty_scene, integrator):
    empty_scene.sampling_lab.integrator = integrator
    drawn = drawn_rows("SAMPLINGLAB_RENDER_PT_radiosity", empty_scene)
    assert set(drawn) == set(RADIOSITY_PROPS)
    assert all(active == (integrator == 'RADIOSITY') for active in drawn.values())
    empty_scene.sampling_lab.radiosity_solver = 'HIERARCHICAL'
    assert drawn_rows("SAMPLINGLAB_RENDER_PT_radiosity", empty_scene)["radiosity_adaptive"] is False
    # Bounces and roulette do nothing for radiosity.
    paths = drawn_rows("SAMPLINGLAB_RENDER_PT_light_paths", empty_scene)
    assert paths["max_bounces"] == (integrator != 'RADIOSITY')


@pytest.mark.parametrize("display, samples_lights", [('GOURAUD', False), ('FINAL_GATHER', True)])
def test_light_sampling_applies_to_radiosity_only_in_its_final_gather(empty_scene, display,
                                                                       samples_lights):
    s = empty_scene.sampling_lab
    s.integrator, s.radiosity_display = 'RADIOSITY', display
    drawn = drawn_rows("SAMPLINGLAB_RENDER_PT_light_sampling", empty_scene)
    assert drawn["mis_heuristic"] is False
    assert drawn["light_selection"] == samples_lights
    assert drawn["light_sampling"] == samples_lights


def test_radiosity_render_writes_combined_and_the_patches_pass(empty_scene, tmp_path, capfd):
    S.cornell_box_mesh_light(empty_scene, resolution=(24, 24))
    S.set_sampling_lab(empty_scene, samples=4)
    s = empty_scene.sampling_lab
    s.integrator, s.radiosity_patch_size, s.radiosity_samples = 'RADIOSITY', 1.0, 4
    s.use_radiosity_patches = True
    passes = S.render_to_exr(empty_scene, tmp_path / "radiosity.exr")
    assert {"Combined", "Radiosity Patches"} <= set(passes)
    combined, patches = passes["Combined"], passes["Radiosity Patches"]
    assert np.isfinite(combined).all() and combined[..., :3].mean() > 0.01
    assert patches.shape == (24, 24, 3) and len(np.unique(patches.reshape(-1, 3), axis=0)) > 4
    out = capfd.readouterr().out
    assert out.count("not consistent unless the mesh refines") == 1, out
