"""Persistent Data: a prepared scene (BVH, light tables) reused by the next render of the same
scene; only the camera may differ (Blender keeps it between the frames of an animation)."""

import numpy as np
import pytest

from sampling_lab.core.render import preparation_key, render
from sampling_lab.core.scenes import cornell_box, look_at
from tests.helpers import plain_settings


@pytest.mark.parametrize("integrator", ["path", "bdpt"])
def test_reused_preparation_renders_the_same_image(integrator):
    """Persistent Data: a scene prepared for one camera renders another camera's view exactly
    as a fresh preparation does, and a changed scene has another key."""
    first = cornell_box(16, 16, "area")
    moved = cornell_box(16, 16, "area")
    moved.camera.to_world = look_at((0.3, -3.5, 1.2), (0.0, 0.0, 1.0))
    settings = plain_settings(integrator=integrator, spp=2, seed=4)
    assert preparation_key(first, settings) == preparation_key(moved, settings)
    earlier = render(first, settings)
    reused = render(moved, settings, prepared=earlier.prepared)
    fresh = render(moved, settings)
    assert reused.stats["prepared_reused"] and not fresh.stats["prepared_reused"]
    np.testing.assert_array_equal(reused.combined(), fresh.combined())
    assert not np.array_equal(reused.combined(), earlier.combined())

    changed = cornell_box(16, 16, "area")
    changed.vertices = changed.vertices.copy()
    changed.vertices[0, 2] += 0.01
    assert preparation_key(changed, settings) != preparation_key(first, settings)
    assert (preparation_key(first, plain_settings(light_selection="uniform"))
            != preparation_key(first, settings))
