"""Photon mapping in real Blender: the Photon Mapping panel greys out every row the chosen
integrator does not read (as ``core.applied_settings.used_settings`` reports), and an SPPM render shows
its image pass by pass and writes a finite EXR."""

import bpy
import numpy as np
import pytest

import scenes
from panels import drawn_rows

ROWS = ("photons", "photon_memory", "sppm_alpha", "photon_lookup", "photon_k", "photon_radius",
        "photon_kernel", "gather_rays", "sppm_radius", "use_photon_surface_test",
        "use_sppm_coverage")
# Property name -> option name where they differ.
OPTION = {"use_photon_surface_test": "photon_surface_test", "use_sppm_coverage": "sppm_coverage"}


@pytest.mark.parametrize("integrator, lookup, radius", [
    ('PATH', 'KNN', 0.0), ('BDPT', 'KNN', 0.0), ('SPPM', 'KNN', 0.0), ('SPPM', 'KNN', 0.1),
    ('PHOTON', 'KNN', 0.0), ('PHOTON', 'RADIUS', 0.0)])
def test_photon_rows_are_active_exactly_where_the_render_uses_them(empty_scene, addon,
                                                                    integrator, lookup, radius):
    from importlib import import_module
    core_render = import_module(f"{addon.__name__}.core.render")
    props = empty_scene.sampling_lab
    props.integrator, props.photon_lookup, props.photon_radius = integrator, lookup, radius
    active = drawn_rows("SAMPLINGLAB_RENDER_PT_photons", empty_scene)
    assert set(active) == set(ROWS)
    settings = core_render.RenderSettings(integrator=integrator.lower(),
                                          photon_lookup=lookup.lower(), photon_radius=radius)
    used = core_render.used_settings(settings)
    for row in ROWS:
        assert active[row] == (used[OPTION.get(row, row)] != "n/a"), row
    light = drawn_rows("SAMPLINGLAB_RENDER_PT_light_sampling", empty_scene)
    assert light["mis_heuristic"] == (used["mis_heuristic"] != "n/a")
    # The Transparent limit: photons and camera paths pass transparent surfaces up to it.
    paths = drawn_rows("SAMPLINGLAB_RENDER_PT_light_paths", empty_scene)
    assert paths["transparent_max_bounces"] == (used["transparent_max_bounces"] != "n/a")


def test_sppm_render_shows_every_pass_and_writes_a_finite_image(empty_scene, tmp_path,
                                                                pass_counts):
    scenes.cornell_box_point_light(empty_scene, resolution=(16, 16))
    scenes.set_sampling_lab(empty_scene, samples=4, max_bounces=3)
    empty_scene.sampling_lab.integrator = 'SPPM'
    empty_scene.sampling_lab.photons = 5000
    passes = scenes.render_to_exr(empty_scene, tmp_path / "sppm.exr")
    assert pass_counts[:4] == [1.0, 2.0, 3.0, 4.0]
    combined = passes["Combined"] if "Combined" in passes else passes["Image"]
    assert np.isfinite(combined).all() and combined[..., :3].max() > 0
