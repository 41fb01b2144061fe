"""Sampling Lab agrees with Cycles (unbiased settings) on Lambertian scenes, in the same session.

Both engines render the scene with ``bpy.ops.render.render`` to multilayer EXR files, read back
from disk. Cycles renders several times with different seeds so that its noise can be estimated;
Sampling Lab reports its own variance pass. The checks (``tests.helpers.assert_images_agree``):
image mean per channel within 0.5 % (plus its confidence interval), and every 8 x 8 block mean
within the confidence interval of the difference. Each test states the smallest errors it
detects with 99 % power (the checker asserts them); the slow tier (``-m slow``) renders
``FULL_SCALE`` times the samples and detects 2 % image-mean and 5 % block errors.
"""

import pytest

import scenes as S
from tests.helpers import DETECT, power_tiers

RESOLUTION = (64, 64)
OUR_SPP = 256
CYCLES_SPP = 16
CYCLES_RUNS = 16
BOUNCES = 8

SCENES = {
    "cornell_mesh_light": lambda sc: S.cornell_box(sc, "mesh", RESOLUTION),
    "cornell_point_light": lambda sc: S.cornell_box(sc, "point", RESOLUTION),
    "cornell_area_light": lambda sc: S.cornell_box(sc, "area", RESOLUTION),
    "plane_under_sun": lambda sc: S.plane_under_sun(sc, RESOLUTION),
}


# (image mean, worst 8x8 block) detected with 99 % power at the default size. Measured:
# mesh light 3.4 % / 29 %, point light 2.4 % / 36 %, area light 1.6 % / 18 %, sun 0.9 % / 4.1 %.
STATED = {"cornell_mesh_light": (0.04, 0.33), "cornell_point_light": (0.03, 0.42),
          "cornell_area_light": (0.02, 0.2), "plane_under_sun": DETECT}
# Sample-count factor of the slow tier: (stated block error / 5 %)^2, rounded up.
FULL_SCALE = {"cornell_mesh_light": 36, "cornell_point_light": 56, "cornell_area_light": 16,
              "plane_under_sun": 1}


@pytest.mark.parametrize("tier", power_tiers())
@pytest.mark.parametrize("name", list(SCENES))
def test_render_agrees_with_cycles(empty_scene, tmp_path, name, tier):
    scene = empty_scene
    SCENES[name](scene)

    scale = FULL_SCALE[name] if tier.full else 1
    our_spp = OUR_SPP * scale
    ours, cycles = S.render_ours_and_cycles(scene, tmp_path, our_spp, CYCLES_SPP * scale,
                                            CYCLES_RUNS, BOUNCES, our_seed=7, cycles_seed=101)
    assert set(ours) >= {"Combined", "Variance", "Sample Count"}
    S.assert_ours_agree_with_cycles(ours, cycles, name, spp=our_spp,
                                    detect=DETECT if tier.full else STATED[name])
