"""Sheen agrees with Cycles: the Principled BSDF's Sheen Weight, Roughness and Tint, and the
Sheen BSDF node (Cycles' microfiber sheen, :mod:`core.materials.sheen`).

The scene of ``test_cycles_multiscatter.py`` (three flat-shaded spheres on a grey floor under a
pale blue world and an area light), the spheres made of

- a dark blue Principled plastic under a white sheen of weight 1 and roughness 0.3;
- a dark red Principled plastic under a tinted sheen (weight 0.8, tint (1, 0.7, 0.4)) of
  roughness 0.8;
- a Sheen BSDF node (colour (0.9, 0.8, 0.7), roughness 0.5) alone.

The bases are dark so that the sheen, brightest toward the silhouettes, carries much of each
sphere's light; the Principled distribution is GGX, as in ``test_cycles_principled.py``. Method as the other agreement tests: image mean per channel within 0.5 % plus
its interval and every 8 x 8 block mean within intervals (``tests.helpers.
assert_images_agree``), and each sphere's mean within 1 % plus the interval of the difference
(``assert_regions_agree``).

Smallest errors detected (99 % power, at these sample counts): image mean 0.87 %, worst
8 x 8 block 5.6 % (asserted at 2 % / 6 % by the checker, the dark spheres making noisy blocks);
each sphere's interval is 4.4 standard errors of 0.4 % to 0.55 % (with the 1 %), so a 3.5 %
error in one sphere fails. Measured (ours / Cycles, on a loaded machine): image mean 1.0001;
spheres 1.005-1.006, 0.994-0.995 and 1.002-1.003 (per channel). With the Principled sheen
ignored (as before; measured with the Multiscatter distribution) the image mean is 2.6 % to
5.4 % below Cycles' per channel and the first sphere 2.5 % to 6 %: the test fails.
"""

import bpy
import numpy as np

import scenes as S
from test_cycles_multiscatter import assert_regions_agree, sphere_masks, three_metal_spheres
from tests.helpers import DETECT

OUR_SPP = 1024
CYCLES_SPP = 256
CYCLES_RUNS = 4
BOUNCES = 8
# Smallest errors detected with 99 % power (image mean, worst 8 x 8 block), asserted by the
# checker: the dark spheres make noisy blocks, so the block error is stated at 6 %.
STATED = (DETECT[0], 0.06)

# (base colour, roughness, sheen weight, sheen roughness, sheen tint)
PRINCIPLED = (
    ((0.02, 0.03, 0.1), 0.5, 1.0, 0.3, (1.0, 1.0, 1.0)),
    ((0.15, 0.02, 0.02), 0.4, 0.8, 0.8, (1.0, 0.7, 0.4)),
)
SHEEN_NODE = ((0.9, 0.8, 0.7), 0.5)
NAMES = ("white sheen of roughness 0.3", "tinted sheen of roughness 0.8", "Sheen BSDF node")


def _sheen_material(name, _roughness):
    i = int(name[-1])
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    principled = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    if i < len(PRINCIPLED):
        # GGX, as test_cycles_principled.py: only the sheen is under test (and it renders
        # faster than the Multiscatter specular layer).
        principled.distribution = 'GGX'
        color, roughness, weight, sheen_roughness, tint = PRINCIPLED[i]
        for key, value in {"Base Color": (*color, 1.0), "Roughness": roughness,
                           "Sheen Weight": weight, "Sheen Roughness": sheen_roughness,
                           "Sheen Tint": (*tint, 1.0)}.items():
            principled.inputs[key].default_value = value
        return mat, principled
    output = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    tree.nodes.remove(principled)
    node = tree.nodes.new("ShaderNodeBsdfSheen")
    color, roughness = SHEEN_NODE
    node.inputs["Color"].default_value = (*color, 1.0)
    node.inputs["Roughness"].default_value = roughness
    tree.links.new(node.outputs[0], output.inputs["Surface"])
    return mat, node


def test_sheen_agrees_with_cycles(empty_scene, export, tmp_path):
    scene = empty_scene
    three_metal_spheres(scene, _sheen_material)
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get())
    assert not exported.messages, exported.messages
    m = exported.materials
    rows = [m.names.index(f"Metal{i}") for i in range(3)]
    np.testing.assert_allclose(m.sheen_weight[rows], [1.0, 0.8, 1.0], rtol=1e-6)
    np.testing.assert_allclose(m.sheen_roughness[rows], [0.3, 0.8, 0.5], rtol=1e-6)

    ours, cycles = S.render_ours_and_cycles(scene, tmp_path, OUR_SPP, CYCLES_SPP, CYCLES_RUNS,
                                            BOUNCES, our_seed=11, cycles_seed=601)
    S.assert_ours_agree_with_cycles(ours, cycles, "sheen", detect=STATED, spp=OUR_SPP)
    assert_regions_agree(ours, cycles, sphere_masks(scene), NAMES)
