"""Sampling Lab agrees with Cycles on mirrors, glass and glossy surfaces (the BSDF families).

Same method as ``test_cycles_agreement.py``: Cycles under unbiased settings (equal bounce limits
for every ray type, caustics on, no glossy blur) renders several seeds, Sampling Lab reports its
own variance pass, and ``tests.helpers.assert_images_agree`` compares the image mean per channel
and every 8 x 8 block mean. Glossy nodes use single-scattering GGX (``distribution = 'GGX'``),
which is what the core conductor models; spheres are flat-shaded UV spheres. Camera and lights
are outside the glass, where Cycles (no 1 / eta^2 radiance scaling) and our radiance-mode
dielectric agree.
"""

import numpy as np
import pytest

import scenes as S
from tests.helpers import DETECT, assert_images_agree

RESOLUTION = (48, 48)
OUR_SPP = 1024
CYCLES_SPP = 256
CYCLES_RUNS = 4
BOUNCES = 8

SCENES = {
    "mirror_ball": lambda sc: S.cornell_sphere(
        sc, S.glossy_material("Mirror", (0.9, 0.9, 0.9), 0.0), RESOLUTION),
    "glass_sphere": lambda sc: S.cornell_sphere(
        sc, S.glass_material("Glass", (1.0, 1.0, 1.0), 1.5, 0.0), RESOLUTION, light_size=0.5),
    "glossy_plates": lambda sc: S.glossy_plates(sc, RESOLUTION),
}


# Smallest errors each comparison detects with 99 % power, (image mean, worst 8x8 block),
# measured at these sample counts; the checker fails the test if its images fall below them.
# Measured: mirror ball 4.5 % / 130 %, glass sphere 4.4 % / 90 % (their few caustic and
# highlight blocks), glossy plates 1.1 % / 4.2 %.
STATED = {"mirror_ball": (0.05, 1.5), "glass_sphere": (0.05, 1.0), "glossy_plates": DETECT}


@pytest.mark.parametrize("name", list(SCENES))
def test_bsdf_families_agree_with_cycles(empty_scene, export, tmp_path, name):
    scene = empty_scene
    SCENES[name](scene)

    ours, cycles = S.render_ours_and_cycles(scene, tmp_path, OUR_SPP, CYCLES_SPP, CYCLES_RUNS,
                                            BOUNCES, our_seed=7, cycles_seed=101)
    assert scene.cycles.caustics_reflective and scene.cycles.caustics_refractive
    assert scene.cycles.blur_glossy == 0.0
    assert (ours["Sample Count"] == OUR_SPP).all()
    for img in list(ours.values()) + list(cycles):
        assert np.isfinite(img).all()
    # The nodes were exported as the core's BSDF kinds, with nothing approximated or ignored.
    import bpy
    from sampling_lab.core.scene import MAT_CONDUCTOR, MAT_DIELECTRIC

    expected = {"mirror_ball": {"Mirror": MAT_CONDUCTOR}, "glass_sphere": {"Glass": MAT_DIELECTRIC},
                "glossy_plates": dict.fromkeys(["Glossy0", "Glossy1", "Glossy2"], MAT_CONDUCTOR)}
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get())
    assert not exported.messages, exported.messages
    names = exported.materials.names
    assert {m: int(exported.materials.kind[names.index(m)]) for m in expected[name]} == (
        expected[name])

    found = assert_images_agree(ours["Combined"][..., :3], ours["Variance"], cycles,
                                detect=STATED[name], what=name)
    print(f"{name}: image mean ours / Cycles {found.ratio}")
