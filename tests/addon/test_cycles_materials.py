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
from tests.helpers import assert_images_agree

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


@pytest.mark.parametrize("name", list(SCENES))
def test_bsdf_families_agree_with_cycles(empty_scene, tmp_path, name):
    scene = empty_scene
    SCENES[name](scene)

    cycles = []
    for run in range(CYCLES_RUNS):
        S.set_cycles_unbiased(scene, samples=CYCLES_SPP, seed=101 + run, max_bounces=BOUNCES)
        assert scene.cycles.caustics_reflective and scene.cycles.caustics_refractive
        assert scene.cycles.blur_glossy == 0.0
        cycles.append(S.render_to_exr(scene, tmp_path / f"cycles_{run}.exr")["Combined"][..., :3])

    S.set_sampling_lab(scene, samples=OUR_SPP, seed=7, max_bounces=BOUNCES)
    ours = S.render_to_exr(scene, tmp_path / "ours.exr")
    assert (ours["Sample Count"] == OUR_SPP).all()
    for img in list(ours.values()) + cycles:
        assert np.isfinite(img).all()
    assert scene.sampling_lab  # the engine ran on this scene, materials exported as the core kinds

    a, b = assert_images_agree(ours["Combined"][..., :3], ours["Variance"], np.stack(cycles),
                               what=name)
    print(f"{name}: image mean ours {a} cycles {b} ratio {a / b}")
