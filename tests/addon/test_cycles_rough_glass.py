"""Rough glass at roughness 0.2, 0.6 and 1.0 against Cycles, and Cycles against itself.

Cycles' rough glass is two functions: its sampler (``bsdf_microfacet_sample``) produces only
refraction pairs whose microfacet faces both directions, while its evaluation
(``bsdf_microfacet_eval``, used by light sampling) also admits pairs whose microfacet faces
away from one of them. So light that reaches a rough glass surface by light sampling is
weighted by a larger function than light found by BSDF sampling, and a Cycles image of rough
glass depends on which strategy found its light. Here the same scene is rendered by Cycles
twice, everything equal but the light sampling: once as Blender sets it up (world and mesh
lamp light-sampled), once with both found by BSDF sampling only (World > Settings > Sampling
Method None, the lamp material's Emission Sampling None). At roughness 1 the light-sampled
sphere is 7-9 % brighter (measured), at 0.2 the two agree: Cycles' light-sampled image is not
the integral of one BSDF. ``test_cycles_light_sampled_rough_glass_is_brighter_than_bsdf_sampled``
documents that and fails if a Blender update makes the two agree.

Our glass is one function (evaluation, sampling and pdf agree, ``tests/core/``), so our image
is the same whichever strategy finds the light; it is compared with Cycles' self-consistent
image, the one whose light arrives through its own sampler. Three glass spheres of Blender's
default distribution (Multiscatter GGX) on a grey floor, under a uniform world and a 1.5 m
square emitting quad above (a mesh lamp: an area lamp cannot be left to BSDF sampling in
Cycles). Method as in ``test_cycles_multiscatter.py``.
"""

import bpy
import numpy as np
import pytest

import scenes as S
from test_cycles_multiscatter import (RESOLUTION, _glass, assert_spheres_agree,
                                      sphere_masks)
from tests.helpers import assert_estimates_agree, z_for_false_failure

ROUGHNESS = (0.2, 0.6, 1.0)
OUR_SPP = 1024
# Light-sampled, BSDF-sampled (the noisier, compared block by block with ours).
CYCLES_SPP = {True: 256, False: 1024}
CYCLES_RUNS = {True: 4, False: 6}
BOUNCES = 8
# Smallest errors the comparison with Cycles detects with 99 % power, measured: 1.0 % in the
# image mean, 5.5 % in the worst 8 x 8 block (the floor lit through BSDF sampling alone is
# noisy in Cycles' image); the checker fails the test if they grow past these.
DETECT_STATED = (0.02, 0.06)
LAMP_RADIANCE = 40.0 / (np.pi * 1.5**2)  # the 40 W, 1.5 m area lamp of the multiscatter test


def glass_spheres_under_a_mesh_lamp(scene):
    """Floor, world and camera of ``three_metal_spheres``; glass spheres of ``ROUGHNESS``;
    a downward 1.5 m square quad of radiance ``LAMP_RADIANCE`` at z = 2.5."""
    grey = S.diffuse_material("Floor", (0.3, 0.3, 0.3))
    S.add_quad(scene, "Floor", [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], grey)
    nodes = []
    for i, (x, roughness) in enumerate(zip((-0.65, 0.0, 0.65), ROUGHNESS)):
        mat, node = _glass(f"Metal{i}", roughness)
        nodes.append(node)
        S.add_uv_sphere(scene, f"Sphere{i}", (x, 0.0, 0.3), 0.3, mat)
    h = 0.75
    S.add_quad(scene, "Lamp", [(-h, -h, 2.5), (h, -h, 2.5), (h, h, 2.5), (-h, h, 2.5)],
               S.emission_material("Lamp", (1.0, 1.0, 1.0), LAMP_RADIANCE))
    S.set_world(scene, (0.8, 0.9, 1.0), 1.0)
    S.add_camera(scene, (0.0, -3.2, 1.2), (np.radians(74.3), 0.0, 0.0))
    S.set_resolution(scene, *RESOLUTION)
    return nodes


def set_cycles_light_sampling(scene, on):
    """Light-sample the world and the lamp (Blender's defaults) or leave both to BSDF
    sampling alone (Cycles then adds their light only where a sampled direction hits them)."""
    scene.world.cycles.sampling_method = 'AUTOMATIC' if on else 'NONE'
    bpy.data.materials["Lamp"].cycles.emission_sampling = 'AUTO' if on else 'NONE'


def render_cycles(scene, folder, light_sampling, seed):
    """``(runs, h, w, 3)``: Cycles' Combined of each run (seeds ``seed + run``)."""
    set_cycles_light_sampling(scene, light_sampling)
    runs = []
    for run in range(CYCLES_RUNS[light_sampling]):
        S.set_cycles_unbiased(scene, samples=CYCLES_SPP[light_sampling], seed=seed + run,
                              max_bounces=BOUNCES)
        path = folder / f"cycles_{int(light_sampling)}_{run}.exr"
        runs.append(S.render_to_exr(scene, path)["Combined"][..., :3])
    return np.stack(runs)


@pytest.fixture(scope="module")
def glass_renders(addon, tmp_path_factory):
    """The scene rendered by Cycles with and without light sampling, and by us (path
    tracing, light sampling on: our default)."""
    folder = tmp_path_factory.mktemp("rough_glass")
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    nodes = glass_spheres_under_a_mesh_lamp(scene)
    assert {node.distribution for node in nodes} == {'MULTI_GGX'}
    light = render_cycles(scene, folder, True, seed=511)
    bsdf = render_cycles(scene, folder, False, seed=611)
    S.set_sampling_lab(scene, samples=OUR_SPP, seed=7, max_bounces=BOUNCES)
    ours = S.render_to_exr(scene, folder / "ours.exr")
    # The camera's matrix is evaluated by the renders: the masks come after them.
    return {"light": light, "bsdf": bsdf, "ours": ours, "masks": sphere_masks(scene)}


def sphere_means(runs, masks):
    """Each sphere's mean colour over the runs and its standard error: two ``(3, 3)``.

    The error is pooled over the sphere's pixels (each pixel's variance over the runs, summed:
    pixels are independent), so it rests on hundreds of degrees of freedom, not on the few
    runs' spread of the sphere mean, and a normal interval applies."""
    mean = runs.mean(axis=0)
    var = runs.var(axis=0, ddof=1) / runs.shape[0]  # (h, w, 3): of each pixel's mean
    means = np.stack([mean[mask].mean(axis=0) for mask in masks])
    errors = np.stack([np.sqrt(var[mask].sum(axis=0)) / mask.sum() for mask in masks])
    return means, errors


def test_cycles_light_sampled_rough_glass_is_brighter_than_bsdf_sampled(glass_renders):
    """Cycles disagrees with itself at roughness 1 and agrees at 0.2.

    Each sphere's mean from ``CYCLES_RUNS`` runs of each (``sphere_means``). Measured light /
    BSDF sampled (per channel): 1.001-1.0015 at roughness 0.2, 1.018-1.023 at 0.6, 1.072-1.086
    at 1.0, standard errors 0.1-0.4 %. At roughness 0.2 the two must agree within 1 % plus
    the interval (z = 4.3, six comparisons: a 2 % difference is caught with 99 % power); at
    roughness 1 the light-sampled sphere must be more than 4 % brighter beyond it.
    """
    light, se_light = sphere_means(glass_renders["light"], glass_renders["masks"])
    bsdf, se_bsdf = sphere_means(glass_renders["bsdf"], glass_renders["masks"])
    for r, ratio, se in zip(ROUGHNESS, light / bsdf, np.hypot(se_light, se_bsdf) / bsdf):
        print(f"Cycles light / BSDF sampled, roughness {r}: {ratio} (standard error {se})")
    assert_estimates_agree(light[0], se_light[0], bsdf[0], se_bsdf[0], comparisons=6,
                           atol=0.01 * bsdf[0],
                           what="Cycles' glass of roughness 0.2, light vs BSDF sampled")
    z = z_for_false_failure(1e-4, comparisons=6)
    excess = light[2] - 1.04 * bsdf[2]
    assert (excess > z * np.hypot(se_light[2], 1.04 * se_bsdf[2])).all(), (
        f"Cycles' light-sampled rough glass (roughness 1) is no longer 4 % brighter than its "
        f"BSDF-sampled one: ratio {light[2] / bsdf[2]} (a Blender fix? then compare ours with "
        f"the light-sampled image too)")


def test_rough_glass_agrees_with_cycles_sampled_glass(glass_renders):
    """Ours against Cycles' self-consistent (BSDF-sampled) image: the image mean per channel
    within 0.5 % plus its interval and every 8 x 8 block within its interval
    (``assert_ours_agree_with_cycles``, ``DETECT_STATED``), and each sphere within 1 % plus its
    interval (``assert_spheres_agree``).

    Measured ours / Cycles: image mean 1.0013 / 1.0056 / 1.0025 (R, G, B); spheres 0.998 at
    roughness 0.2, 1.009 / 1.018 / 1.012 at 0.6, 1.005 / 1.017 / 1.009 at 1.0 (standard errors
    0.3-0.8 %: the 1-2 % excess at 0.6 and 1.0 is within the allowance and not explained, see
    docs/USER_GUIDE.md). Against Cycles' light-sampled image our roughness-1 sphere is 0.92-0.93
    and fails the sphere check."""
    ours, bsdf = glass_renders["ours"], glass_renders["bsdf"]
    S.assert_ours_agree_with_cycles(ours, bsdf, "rough glass vs BSDF-sampled Cycles",
                                    detect=DETECT_STATED, spp=OUR_SPP)
    assert_spheres_agree(ours, bsdf, glass_renders["masks"], "glass", ROUGHNESS)
