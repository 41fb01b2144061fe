"""The Principled BSDF's Coat, Specular IOR Level, Specular Tint and Emission agree with Cycles.

The scene of ``test_cycles_multiscatter.py`` (three flat-shaded spheres on a grey floor under a
pale blue world and an area light) with three coated Principled BSDFs (distribution GGX, so
that only the coat is under test):

- a red plastic (roughness 0.5) under a full, smooth coat (weight 1, Blender's roughness 0.03,
  IOR 1.5): the sharp reflection of the lamp and the world over a darkened base;
- a copper metal (roughness 0.4) under a rough tinted coat (weight 0.7, roughness 0.2, IOR 1.5,
  tint (0.8, 0.6, 0.4));
- a blue plastic with Specular IOR Level 0 (a diffuse base) under a half coat (weight 0.5,
  roughness 0.5, IOR 1.8, tint (0.6, 0.8, 1.0)).

A second scene has a plastic of Specular IOR Level 1, one of Specular Tint (1, 0.4, 0.1) (Cycles'
generalized Schlick Fresnel) and an emitter of Emission Color (1, 0.5, 0.2) x Strength 1.5.

Method as the other agreement tests: image mean per channel within 0.5 % plus its interval and
every 8 x 8 block mean within intervals (``tests.helpers.assert_images_agree``), and each
sphere's mean within 1 % plus the interval.
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

# (base colour, metallic, roughness, specular IOR level, coat weight, roughness, IOR, tint)
COATED = (
    ((0.6, 0.08, 0.05), 0.0, 0.5, 0.5, 1.0, 0.03, 1.5, (1.0, 1.0, 1.0)),
    ((0.95, 0.64, 0.54), 1.0, 0.4, 0.5, 0.7, 0.2, 1.5, (0.8, 0.6, 0.4)),
    ((0.1, 0.3, 0.7), 0.0, 0.5, 0.0, 0.5, 0.5, 1.8, (0.6, 0.8, 1.0)),
)
NAMES = ("plastic under a smooth coat", "metal under a rough tinted coat",
         "diffuse under a half coat")


# Specular IOR Level, Specular Tint and Emission: (base colour, roughness, inputs).
SPECULAR = (
    ((0.2, 0.2, 0.2), 0.3, {"Specular IOR Level": 1.0}),
    ((0.1, 0.1, 0.3), 0.2, {"Specular Tint": (1.0, 0.4, 0.1, 1.0)}),
    ((0.5, 0.5, 0.5), 0.5, {"Emission Color": (1.0, 0.5, 0.2, 1.0), "Emission Strength": 1.5}),
)
SPECULAR_NAMES = ("specular IOR level 1", "specular tint", "emission colour x strength")


def _principled(name, inputs):
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    node.distribution = 'GGX'
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    return mat, node


def _coated(name, _roughness):
    color, metallic, roughness, level, weight, coat_roughness, ior, tint = COATED[int(name[-1])]
    return _principled(name, {"Base Color": (*color, 1.0), "Metallic": metallic,
                              "Roughness": roughness, "Specular IOR Level": level,
                              "Coat Weight": weight, "Coat Roughness": coat_roughness,
                              "Coat IOR": ior, "Coat Tint": (*tint, 1.0)})


def _specular(name, _roughness):
    color, roughness, inputs = SPECULAR[int(name[-1])]
    return _principled(name, {"Base Color": (*color, 1.0), "Roughness": roughness, **inputs})


def assert_spheres_agree(scene, ours, cycles, names):
    """Each sphere's mean within 1 % of Cycles' plus the interval of the difference (Cycles'
    standard error taken no smaller than ours, as in ``test_cycles_multiscatter.py``)."""
    assert_regions_agree(ours, cycles, sphere_masks(scene), names)


def test_principled_coat_agrees_with_cycles(empty_scene, export, tmp_path):
    scene = empty_scene
    three_metal_spheres(scene, _coated)
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get())
    assert not exported.messages, exported.messages
    m = exported.materials
    rows = [m.names.index(f"Metal{i}") for i in range(3)]
    np.testing.assert_allclose(m.coat_weight[rows], [c[4] for c in COATED], rtol=1e-6)

    ours, cycles = S.render_ours_and_cycles(scene, tmp_path, OUR_SPP, CYCLES_SPP, CYCLES_RUNS,
                                            BOUNCES, our_seed=7, cycles_seed=401)
    S.assert_ours_agree_with_cycles(ours, cycles, "coat", detect=DETECT, spp=OUR_SPP)
    assert_spheres_agree(scene, ours, cycles, NAMES)


def test_principled_specular_level_tint_and_emission_agree_with_cycles(empty_scene, export,
                                                                       tmp_path):
    scene = empty_scene
    three_metal_spheres(scene, _specular)
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get())
    assert not exported.messages, exported.messages
    ours, cycles = S.render_ours_and_cycles(scene, tmp_path, OUR_SPP, CYCLES_SPP, CYCLES_RUNS,
                                            BOUNCES, our_seed=9, cycles_seed=501)
    S.assert_ours_agree_with_cycles(ours, cycles, "specular", detect=DETECT, spp=OUR_SPP)
    assert_spheres_agree(scene, ours, cycles, SPECULAR_NAMES)
