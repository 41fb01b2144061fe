"""Rough metals, a plastic and glass left at Blender's default distribution, Multiscatter GGX,
agree with Cycles.

Three flat-shaded spheres of roughness 0.2, 0.6 and 1.0 on a grey floor under a uniform world
and an area light, made of a Glossy BSDF (Blender's default grey), of a Principled BSDF with
Metallic 1 and a copper colour, of a dark Principled plastic (the compensated specular
layer) or of a pale green Glass BSDF, with the node's distribution left as Blender creates it
(``'MULTI_GGX'``, asserted). Method as in ``test_cycles_materials.py``: Cycles under unbiased
settings renders several seeds, Sampling Lab reports its own variance pass, and
``tests.helpers.assert_images_agree`` compares the image mean per channel (0.5 % plus its
interval) and every 8 x 8 block mean (intervals); each sphere's mean is compared too.
"""

import bpy
import numpy as np
import pytest

import scenes as S
from tests.helpers import DETECT, assert_estimates_agree

RESOLUTION = (64, 32)
OUR_SPP = 1024
CYCLES_SPP = 256
CYCLES_RUNS = 4
BOUNCES = 8
ROUGHNESS = (0.2, 0.6, 1.0)

# Smallest errors each comparison detects with 99 % power (image mean, worst 8 x 8 block),
# measured at these sample counts: glossy 1.0 % / 4.5 %, principled 1.1 % / 4.1 %; the checker
# fails the test if its images fall below the default 2 % / 5 %. Without the compensation the
# glossy image mean is 7.8 % below Cycles' and the test fails. The dark plastic's blocks are
# noisier (0.84 % / 5.5 % measured), so its block error is stated at 6 %; rendered with the
# specular layer single-scattering, three of its blocks fall outside their intervals.
STATED = {"glossy": DETECT, "principled": DETECT, "plastic": (DETECT[0], 0.06),
          "glass": DETECT}


def _glossy(name, roughness):
    mat = S.shader_material(name, "ShaderNodeBsdfGlossy", color=(0.8, 0.8, 0.8))
    node = mat.node_tree.nodes["Glossy BSDF"]
    node.inputs["Roughness"].default_value = roughness
    return mat, node


def _principled(name, roughness):
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    node.inputs["Base Color"].default_value = (0.95, 0.64, 0.54, 1.0)
    node.inputs["Metallic"].default_value = 1.0
    node.inputs["Roughness"].default_value = roughness
    return mat, node


def _plastic(name, roughness):
    """A dark Principled plastic (Specular IOR Level 1, F0 = 0.08): the specular layer's
    compensation shows above a base that adds little."""
    mat, node = _principled(name, roughness)
    node.inputs["Base Color"].default_value = (0.1, 0.05, 0.02, 1.0)
    node.inputs["Metallic"].default_value = 0.0
    node.inputs["Specular IOR Level"].default_value = 1.0
    return mat, node


def _glass(name, roughness):
    """A Glass BSDF of a pale green (the colour is Cycles' multiple-scattering Fresnel
    average) as Blender creates it."""
    mat = S.shader_material(name, "ShaderNodeBsdfGlass", color=(0.8, 1.0, 0.9))
    node = mat.node_tree.nodes["Glass BSDF"]
    node.inputs["Roughness"].default_value = roughness
    return mat, node


MATERIALS = {"glossy": _glossy, "principled": _principled, "plastic": _plastic,
             "glass": _glass}
# Glass at roughness 1 is left out here: under an area lamp (light-sampled in Cycles) our
# glass sphere is 7-9 % darker than Cycles', because Cycles' evaluation, which its light
# sampling uses, is larger than what its sampler produces. test_cycles_rough_glass.py shows
# that Cycles disagrees with itself there and compares ours with its BSDF-sampled image at
# roughness 0.2, 0.6 and 1.0.
SPHERE_ROUGHNESS = {"glass": (0.2, 0.4, 0.6)}
# Kind of the exported rows: conductor, layered (the specular layer over the base), dielectric.
KINDS = {"glossy": 1, "principled": 1, "plastic": 3, "glass": 2}


def three_metal_spheres(scene, make, roughnesses=ROUGHNESS):
    """Three flat-shaded spheres of ``roughnesses`` on a grey floor, under a pale blue uniform
    world and a 1.5 m square area light above: the spheres mostly reflect the world, where
    the lost single-scattering energy shows most and the noise is low."""
    grey = S.diffuse_material("Floor", (0.3, 0.3, 0.3))
    S.add_quad(scene, "Floor", [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], grey)
    nodes = []
    for i, (x, roughness) in enumerate(zip((-0.65, 0.0, 0.65), roughnesses)):
        mat, node = make(f"Metal{i}", roughness)
        nodes.append(node)
        S.add_uv_sphere(scene, f"Sphere{i}", (x, 0.0, 0.3), 0.3, mat)
    S.add_light(scene, 'AREA', "Lamp", (0.0, 0.0, 2.5), energy=40.0, shape='SQUARE', size=1.5)
    S.set_world(scene, (0.8, 0.9, 1.0), 1.0)
    S.add_camera(scene, (0.0, -3.2, 1.2), (np.radians(74.3), 0.0, 0.0))
    S.set_resolution(scene, *RESOLUTION)
    return nodes


def sphere_masks(scene):
    """``(3, h, w)`` bool: the pixels inside each sphere's silhouette, shrunk by one pixel."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    w, h = RESOLUTION
    cam = scene.camera
    x, y = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    masks = []
    for i in range(3):
        centre = bpy.data.objects[f"Sphere{i}"].location
        c = world_to_camera_view(scene, cam, centre)
        edge = world_to_camera_view(scene, cam, centre + Vector((0.3, 0.0, 0.0)))
        radius = (edge.x - c.x) * w * 0.95 - 1.0
        masks.append((x - c.x * w) ** 2 + (y - c.y * h) ** 2 < radius**2)
    return np.stack(masks)


def assert_spheres_agree(ours, cycles, masks, what, roughnesses=ROUGHNESS):
    """Each sphere's mean colour: within 1 % of Cycles' plus the interval of the difference
    (4.4 standard errors of 0.35 % to 0.6 %): errors of 3.4 % (roughness 0.2) to 5 %
    (roughness 1) in one sphere are detected with 99 % power. Cycles' standard error comes from
    its few runs; it is taken no smaller than ours (the same number of samples of a path
    tracer), which only widens the interval.

    Measured (ours / Cycles): Principled 0.998 / 1.002 / 0.999 at
    roughness 0.2 / 0.6 / 1.0; Glossy 1.000 / 1.005 / 1.011. The Glossy excess is the known
    difference of its Fresnel: Cycles' Glossy BSDF is a constant tint, ours Schlick with F0 =
    the colour, whose hemispherical average is ``0.8 + 0.2 / 21``, 1.2 % above 0.8.
    """
    assert_regions_agree(ours, cycles, masks,
                         [f"{what} sphere of roughness {r}" for r in roughnesses])


def assert_regions_agree(ours, cycles, masks, labels):
    """Each region ``masks[i]``'s mean colour within 1 % of Cycles' plus the interval of the
    difference (of 9 comparisons), Cycles' standard error from its runs and taken no smaller
    than ours; prints each ratio under ``labels[i]``."""
    mean_a, var_a = ours["Combined"][..., :3], ours["Variance"][..., :3]
    for label, mask in zip(labels, masks):
        n = mask.sum()
        a = mean_a[mask].mean(axis=0)
        se_a = np.sqrt(var_a[mask].sum(axis=0)) / n
        reps = cycles[:, mask].mean(axis=1)
        b, se_b = reps.mean(axis=0), reps.std(axis=0, ddof=1) / np.sqrt(len(reps))
        se_b = np.maximum(se_b, se_a)
        print(f"{label}: {n} pixels, ours / Cycles {a / b}, "
              f"standard error {np.hypot(se_a, se_b) / b}")
        assert_estimates_agree(a, se_a, b, se_b, comparisons=9, atol=0.01 * b, what=label)


@pytest.mark.parametrize("name", list(MATERIALS))
def test_default_multiscatter_metals_agree_with_cycles(empty_scene, export, tmp_path, name):
    scene = empty_scene
    roughnesses = SPHERE_ROUGHNESS.get(name, ROUGHNESS)
    nodes = three_metal_spheres(scene, MATERIALS[name], roughnesses)
    # Left at the default: Multiscatter GGX.
    assert {node.distribution for node in nodes} == {'MULTI_GGX'}
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get())
    assert not exported.messages, exported.messages
    m = exported.materials
    metals = [m.names.index(f"Metal{i}") for i in range(3)]
    assert m.kind[metals].tolist() == [KINDS[name]] * 3 and m.multiscatter[metals].all()

    ours, cycles = S.render_ours_and_cycles(scene, tmp_path, OUR_SPP, CYCLES_SPP, CYCLES_RUNS,
                                            BOUNCES, our_seed=5, cycles_seed=301)
    S.assert_ours_agree_with_cycles(ours, cycles, name, detect=STATED[name],
                                    spp=OUR_SPP)
    assert_spheres_agree(ours, cycles, sphere_masks(scene), name, roughnesses)
