"""Sampling Lab agrees with Cycles (unbiased settings) on Lambertian scenes, in the same session.

Both engines render the scene with ``bpy.ops.render.render`` to multilayer EXR files, read back
from disk. Cycles renders several times with different seeds so that its noise can be estimated;
Sampling Lab reports its own variance pass. The checks (``tests.helpers.assert_images_agree``):
image mean per channel within 1 % (plus its confidence interval), and every 8 x 8 block mean
within the confidence interval of the difference.
"""

import numpy as np
import pytest

import scenes as S
from tests.helpers import assert_images_agree

RESOLUTION = (64, 64)
OUR_SPP = 256
CYCLES_SPP = 64
CYCLES_RUNS = 4
BOUNCES = 8

SCENES = {
    "cornell_mesh_light": lambda sc: S.cornell_box(sc, "mesh", RESOLUTION),
    "cornell_point_light": lambda sc: S.cornell_box(sc, "point", RESOLUTION),
    "cornell_area_light": lambda sc: S.cornell_box(sc, "area", RESOLUTION),
    "plane_under_sun": lambda sc: S.plane_under_sun(sc, RESOLUTION),
}


@pytest.mark.parametrize("name", list(SCENES))
def test_render_agrees_with_cycles(empty_scene, tmp_path, name):
    scene = empty_scene
    SCENES[name](scene)

    ours, cycles = S.render_ours_and_cycles(scene, tmp_path, OUR_SPP, CYCLES_SPP, CYCLES_RUNS,
                                            BOUNCES, our_seed=7, cycles_seed=101)
    assert set(ours) >= {"Combined", "Variance", "Sample Count"}
    assert (ours["Sample Count"] == OUR_SPP).all()
    for img in list(ours.values()) + list(cycles):
        assert np.isfinite(img).all()

    a, b = assert_images_agree(ours["Combined"][..., :3], ours["Variance"], cycles,
                               what=name)
    print(f"{name}: image mean ours {a} cycles {b} ratio {a / b}")
