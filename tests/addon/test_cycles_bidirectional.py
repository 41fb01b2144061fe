"""Light tracing and BDPT agree with Cycles (unbiased settings) on the diffuse Cornell box.

Cycles and Sampling Lab render in the same session, read back from the EXR files Blender
writes. Light-path splats make neighbouring pixels of our images correlated, so both sides are
rendered several times with different seeds and compared block by block with replicate
confidence intervals (:func:`tests.helpers.assert_replicates_agree`).
"""

import numpy as np
import pytest

import scenes as S
from tests.helpers import assert_replicates_agree

RESOLUTION = (32, 32)
RUNS = 4
CYCLES_SPP = 64
OUR_SPP = {"LIGHT": 64, "BDPT": 16}
BOUNCES = 4


@pytest.mark.parametrize("light", ["area", "point"])
def test_light_tracing_and_bdpt_agree_with_cycles_on_the_cornell_box(empty_scene, tmp_path,
                                                                      light):
    scene = empty_scene
    S.cornell_box(scene, light, RESOLUTION)
    cycles = []
    for run in range(RUNS):
        S.set_cycles_unbiased(scene, samples=CYCLES_SPP, seed=101 + run, max_bounces=BOUNCES)
        cycles.append(S.render_to_exr(scene, tmp_path / f"cycles_{run}.exr")["Combined"][..., :3])
    cycles = np.stack(cycles)
    for integrator, spp in OUR_SPP.items():
        ours = []
        for run in range(RUNS):
            S.set_sampling_lab(scene, samples=spp, seed=7 + run, max_bounces=BOUNCES)
            scene.sampling_lab.integrator = integrator
            img = S.render_to_exr(scene, tmp_path / f"{integrator}_{run}.exr")["Combined"]
            assert np.isfinite(img).all() and (img >= 0).all()
            ours.append(img[..., :3])
        ratio = assert_replicates_agree(np.stack(ours), cycles,
                                        what=f"{integrator} vs Cycles, Cornell {light}")
        print(f"{integrator} / Cycles, Cornell {light} light: image mean {np.round(ratio, 4)}")
