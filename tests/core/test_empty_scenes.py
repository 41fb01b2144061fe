"""Scenes that leave the image empty render without error and say why: one without any light
(no lamps, no emission, a black world) and one without geometry, for every integrator."""

import dataclasses

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.integrators import INTEGRATORS
from sampling_lab.core.render import render
from sampling_lab.core.scene import Lights
from tests.helpers import plain_settings

NO_LIGHT = "the scene emits no light"
NO_GEOMETRY = "the scene has no geometry"


def _dark():
    s = scenes.cornell_box(8, 6, "point")
    return dataclasses.replace(s, lights=Lights.empty(), world_color=np.zeros(3, np.float32))


def _empty():
    s = scenes.cornell_box(8, 6, "point")
    return dataclasses.replace(s, vertices=np.zeros((0, 3), np.float32),
                               triangles=np.zeros((0, 3), np.int32),
                               material=np.zeros(0, np.int32), visibility=np.zeros(0, np.int32))


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_a_scene_without_light_renders_black_and_says_so(integrator):
    result = render(_dark(), plain_settings(integrator=integrator, spp=2, photons=1000))
    assert any(m.startswith(NO_LIGHT) for m in result.messages), result.messages
    assert not any(m.startswith(NO_GEOMETRY) for m in result.messages)
    rgb = result.combined()[..., :3]
    assert np.isfinite(rgb).all() and rgb.max() == 0.0


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_a_scene_without_geometry_renders_and_says_so(integrator):
    result = render(_empty(), plain_settings(integrator=integrator, spp=2, photons=1000))
    assert any(m.startswith(NO_GEOMETRY) for m in result.messages), result.messages
    assert not any(m.startswith(NO_LIGHT) for m in result.messages)
    assert np.isfinite(result.combined()).all()
