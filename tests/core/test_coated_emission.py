"""Emission under a Principled Coat: attenuated as the layers below the coat, seen directly,
found by BSDF-sampled rays and sampled by next-event estimation alike."""

import numpy as np
import pytest

from sampling_lab.core.materials.coat import DEFAULT_COAT_ROUGHNESS, coat_attenuation
from sampling_lab.core.materials.microfacet import alpha_from_roughness
from sampling_lab.core.render import render
from sampling_lab.core.scene import MAT_LAYERED, Camera, Lights, Materials, Scene
from tests.helpers import assert_mean_within_ci, plain_settings

COAT = dict(coat_weight=[0.0, 0.9], coat_ior=[1.5, 1.8], coat_tint=[(1, 1, 1), (0.4, 0.7, 1.0)])
EMISSION = np.array([2.0, 3.0, 4.0])


def coated_lamp_scene(coat=True):
    """A white floor (row 0) and a coated emissive quad (row 1) at z = 1 facing down, tilted
    about y; a camera 3 m above the floor looking down."""
    floor = [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)]
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    lamp = [(x * c, y, 1.0 + x * s) for x, y in ((-0.5, -0.5), (-0.5, 0.5), (0.5, 0.5),
                                                   (0.5, -0.5))]
    mats = Materials.from_lists(["Floor", "Lamp"], [(0.8, 0.8, 0.8), (0.5, 0.5, 0.5)],
                                [(0, 0, 0), EMISSION], kinds=[0, MAT_LAYERED],
                                **(COAT if coat else {}))
    to_world = np.eye(4)
    to_world[2, 3] = 3.0
    cam = Camera(to_world, 16, 16, type="PERSP", lens=30.0)
    return Scene(floor + lamp, [(0, 1, 2), (0, 2, 3), (4, 5, 6), (4, 6, 7)], [0, 0, 1, 1],
                 mats, Lights.empty(), cam)


def test_lamp_seen_from_below_is_attenuated_by_the_coat():
    scene = coated_lamp_scene()
    # Looking up at the lamp from the floor: a camera at z = 0.5 looking up (+Z).
    to_world = np.diag([1.0, -1.0, -1.0, 1.0])
    to_world[:3, 3] = [0.0, 0.0, 0.5]
    scene.camera = Camera(to_world, 8, 8, type="ORTHO", ortho_scale=0.4)
    img = render(scene, plain_settings(spp=2, max_bounces=0, seed=1)).combined()[..., :3]
    mu = np.cos(np.radians(30))
    expect = EMISSION * coat_attenuation(np.array([0.9]), np.array([1.8]),
                                         np.array([[0.4, 0.7, 1.0]]), np.array([mu]),
                                         alpha_from_roughness(DEFAULT_COAT_ROUGHNESS))[0]
    # Seen directly every sample is exact: the coat's attenuation at the view angle.
    np.testing.assert_allclose(img.reshape(-1, 3), np.tile(expect, (64, 1)), rtol=1e-5)
    assert expect[0] < 0.5 * EMISSION[0]  # the coat matters in this test


@pytest.mark.parametrize("integrator,mis", [("path", "light"), ("path", "bsdf"),
                                            ("light", "power")])
def test_every_strategy_sees_the_same_coated_lamp(integrator, mis):
    """The floor lit by the lamp through next-event estimation alone, through BSDF-sampled
    hits alone and by light tracing (emission sampled from the lamp): all unbiased, so per-pixel differences have mean zero (z-test at 1e-4 over
    256 pixels). Without the coat the floor is about 2.5 times brighter in red (measured, and
    checked below), so a coat missing from one path would be far outside."""
    reference = render(coated_lamp_scene(), plain_settings(spp=256, max_bounces=1, seed=2,
                                                           mis_heuristic="power"))
    other = render(coated_lamp_scene(), plain_settings(spp=256, max_bounces=1, seed=3,
                                                       mis_heuristic=mis, integrator=integrator))
    d = (other.combined()[..., :3] - reference.combined()[..., :3]).reshape(-1, 3)
    assert_mean_within_ci(d, 0.0, what=f"{mis} minus power")
    bare = render(coated_lamp_scene(coat=False), plain_settings(spp=64, max_bounces=1, seed=4))
    assert (bare.combined()[..., 0].mean() > 2.0 * reference.combined()[..., 0].mean())
