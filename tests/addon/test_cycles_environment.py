"""An environment-lit scene agrees with Cycles, and the exporter reads Environment Textures.

The world is an Environment Texture (a small float image, ``tools/bpy_scenes.sky_pixels``: a
colour gradient along both image axes and a bright spot) into a Background node. A diffuse
plane and a flat-shaded UV sphere are lit by it, and the camera sees the sky directly, so that
the equirectangular lookup (orientation, row order, bilinear interpolation) is compared pixel
by pixel as well as the importance-sampled lighting. The comparison is the one of
``test_cycles_agreement.py``: image mean per channel within 1 % (plus its confidence interval),
every 8 x 8 block within the confidence interval of the difference.
"""

import bpy
import numpy as np
import pytest

import scenes as S

RESOLUTION = (64, 64)
OUR_SPP = 256
CYCLES_SPP = 64
CYCLES_RUNS = 4
BOUNCES = 8
MAP_W, MAP_H = S.SKY_W, S.SKY_H
sky_pixels = S.sky_pixels


def environment_scene(scene, strength=1.5):
    """The shared environment scene (``tools/bpy_scenes.py``) at this module's resolution."""
    return S.environment_scene(scene, RESOLUTION, strength)


def test_environment_texture_exports_pixels_times_strength(empty_scene, export):
    _, env, _ = environment_scene(empty_scene, strength=1.5)
    s = export.export_scene(bpy.context.evaluated_depsgraph_get())
    assert s.world_map is not None and s.world_map.shape == (MAP_H, MAP_W, 3)
    np.testing.assert_allclose(s.world_map, 1.5 * sky_pixels(), rtol=1e-6)
    np.testing.assert_allclose(s.world_color, 0.0)
    assert not [m for m in s.messages if "World" in m]


@pytest.mark.parametrize("case", ["vector_linked", "mirror_ball", "sky_texture", "no_image"])
def test_unsupported_world_textures_fall_back_to_the_background_colour(empty_scene, export,
                                                                      case):
    world, env, bg = environment_scene(empty_scene, strength=2.0)
    bg.inputs["Color"].default_value = (0.1, 0.2, 0.3, 1.0)
    tree = world.node_tree
    if case == "vector_linked":
        mapping = tree.nodes.new("ShaderNodeMapping")
        tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    elif case == "mirror_ball":
        env.projection = 'MIRROR_BALL'
    elif case == "sky_texture":
        sky = tree.nodes.new("ShaderNodeTexSky")
        tree.links.new(sky.outputs["Color"], bg.inputs["Color"])
    else:
        env.image = None
    s = export.export_scene(bpy.context.evaluated_depsgraph_get())
    assert s.world_map is None
    np.testing.assert_allclose(s.world_color, [0.2, 0.4, 0.6], rtol=1e-6)
    world_messages = [m for m in s.messages if m.startswith("World")]
    assert len(world_messages) == 1, s.messages


def test_diffuse_objects_under_an_environment_map_agree_with_cycles(empty_scene, tmp_path):
    scene = empty_scene
    world, _, _ = environment_scene(scene)
    # Cycles importance-samples the world at the image's own resolution (unbiased either way).
    world.cycles.sampling_method = 'AUTOMATIC'

    ours, cycles = S.render_ours_and_cycles(scene, tmp_path, OUR_SPP, CYCLES_SPP, CYCLES_RUNS,
                                            BOUNCES, our_seed=9, cycles_seed=201)
    # Detects 0.7 % image-mean and 4.4 % block errors with 99 % power (the default target).
    S.assert_ours_agree_with_cycles(ours, cycles, "environment map")
