"""Hard cases through Blender's data API, where the exporter meets them first: a mesh with NaN
and infinite vertex coordinates and an area light of zero size render finite images, and the
render says which triangles it left out (the core cases: ``tests/core/test_hard_cases.py``)."""

import bpy
import numpy as np
import pytest

import scenes


@pytest.mark.parametrize("integrator", ["path", "light", "bdpt"])
def test_nonfinite_vertices_and_a_zero_size_light_from_blender(empty_scene, export, integrator):
    from sampling_lab.core.render import render
    from tests.helpers import plain_settings

    scenes.cornell_box_point_light(empty_scene, resolution=(8, 8))
    nan, inf = float("nan"), float("inf")
    scenes.add_mesh(empty_scene, "Broken", [(nan, 0, 0), (0.5, 0, 0), (0, 0.5, 1), (inf, 0, 1)],
                    [(0, 1, 2), (1, 2, 3)])
    lamp = bpy.data.lights.new("Zero", 'AREA')
    lamp.size = 0.0
    lamp.energy = 100.0
    empty_scene.collection.objects.link(bpy.data.objects.new("Zero", lamp))
    scene = export.export_scene(bpy.context.evaluated_depsgraph_get())
    result = render(scene, plain_settings(integrator=integrator, spp=4))
    assert any("2 triangle(s) with NaN or infinite vertex coordinates were left out" in m
               for m in result.messages), result.messages
    assert np.isfinite(result.combined()).all()
    assert result.combined()[..., :3].max() > 0
