"""Light Paths as Cycles: bounce limits per kind and transparent shadows, in real Blender.

- Our bounce-limit properties have Cycles' names and defaults (read from ``scene.cycles`` of a
  new scene), and the Light Paths panel greys out the per-kind limits exactly where
  ``core.applied_settings.used_settings`` says the integrator does not read them.
- Cycles agreement (unbiased Cycles, several seeds; image mean per channel and every 8 x 8
  block mean within confidence intervals, as ``test_cycles_mixtures.py``) on the Cornell box
  with a Principled plane of Alpha 0.5 hanging under the lamp, so that shadow rays toward the
  lamp cross it: with its blocks and every limit at 8 (transparent shadows), and with a glass
  ball and low limits of every kind set alike in both engines (each of them changes this
  image: measured on Cycles, total 6 and diffuse 1 take 26 %, transparent 1 takes 8 %).
"""

import bpy
import pytest

import scenes as S
from panels import drawn_rows

RESOLUTION = (32, 32)
OUR_SPP = 1024
CYCLES_SPP = 256
CYCLES_RUNS = 4
LIMITS = ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
          "transparent_max_bounces")


def test_bounce_limits_have_cycles_names_and_defaults(empty_scene):
    fresh = bpy.data.scenes.new("Defaults")
    try:
        for name in LIMITS:
            assert getattr(fresh.sampling_lab, name) == getattr(fresh.cycles, name), name
    finally:
        bpy.data.scenes.remove(fresh)


@pytest.mark.parametrize("integrator", ['PATH', 'LIGHT', 'BDPT', 'PHOTON', 'RADIOSITY'])
def test_per_kind_rows_are_active_exactly_where_the_render_uses_them(empty_scene, addon,
                                                                      integrator):
    from importlib import import_module
    core_render = import_module(f"{addon.__name__}.core.render")
    empty_scene.sampling_lab.integrator = integrator
    active = drawn_rows("SAMPLINGLAB_RENDER_PT_light_paths", empty_scene)
    used = core_render.used_settings(core_render.RenderSettings(integrator=integrator.lower()))
    for row in LIMITS[1:]:
        assert active[row] == (used[row] != "n/a"), row
    assert active["max_bounces"] == (integrator != 'RADIOSITY')


def add_leaf(scene):
    """A Principled plane of Alpha 0.5 (green, rough) hanging under the Cornell box's lamp."""
    leaf = S.shader_material("Leaf", "ShaderNodeBsdfPrincipled")
    node = next(n for n in leaf.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    node.inputs["Base Color"].default_value = (0.2, 0.6, 0.1, 1.0)
    node.inputs["Roughness"].default_value = 1.0
    node.inputs["Alpha"].default_value = 0.5
    return S.add_quad(scene, "Leaf", [(-0.6, -0.6, 1.5), (0.6, -0.6, 1.5), (0.6, 0.6, 1.5),
                                      (-0.6, 0.6, 1.5)], leaf)


def leaf_box(scene):
    """The Cornell box with its blocks and a 0.5 m area lamp, and the leaf under the lamp."""
    objects = S.cornell_box(scene, "area", RESOLUTION, light_size=0.5)
    objects["leaf"] = add_leaf(scene)
    return objects


def leaf_glass_box(scene):
    """The Cornell box with a glass ball instead of the blocks, and the leaf."""
    objects = S.cornell_sphere(scene, S.glass_material("Glass", ior=1.45), RESOLUTION,
                               light_size=0.5)
    objects["leaf"] = add_leaf(scene)
    return objects


def render_both(scene, folder, limits):
    """Cycles runs and our render with the bounce limits ``limits`` (name -> value) in both."""
    cycles = []
    for run in range(CYCLES_RUNS):
        S.set_cycles_unbiased(scene, samples=CYCLES_SPP, seed=101 + run)
        for name, value in limits.items():
            setattr(scene.cycles, name, value)
        cycles.append(S.render_to_exr(scene, folder / f"cycles_{run}.exr")["Combined"][..., :3])
    S.set_sampling_lab(scene, samples=OUR_SPP, seed=7)
    for name, value in limits.items():
        setattr(scene.sampling_lab, name, value)
    return S.render_to_exr(scene, folder / "ours.exr"), S.np.stack(cycles)


CASES = {
    "transparent_shadows": (leaf_box, {name: 8 for name in LIMITS}),
    "low_limits": (leaf_glass_box, dict(max_bounces=6, diffuse_bounces=1, glossy_bounces=1,
                                        transmission_bounces=2, transparent_max_bounces=1)),
}
# Smallest errors each comparison detects with 99 % power (image mean, worst 8x8 block),
# measured at these sample counts (2.1 % / 16 % and 4.6 % / 36 %): the glass ball's caustics
# make the second one noisy.
STATED = {"transparent_shadows": (0.025, 0.2), "low_limits": (0.05, 0.4)}


@pytest.mark.parametrize("case", list(CASES))
def test_light_paths_agree_with_cycles(empty_scene, tmp_path, case):
    build, limits = CASES[case]
    build(empty_scene)
    ours, cycles = render_both(empty_scene, tmp_path, limits)
    S.assert_ours_agree_with_cycles(ours, cycles, case, detect=STATED[case], spp=OUR_SPP)


def test_transparent_film_agrees_with_cycles_alpha(empty_scene, tmp_path):
    """Film > Transparent on a plane under a sun and a dim world, with the alpha leaf in front
    of part of the sky: our Combined RGB agrees with Cycles' (the world lights the plane but is
    not drawn), and our alpha with Cycles' alpha: the image mean within 0.5 % and every 8 x 8
    block mean within 0.02 (alpha is a mean of per-sample transparencies in [0, 1])."""
    scene = empty_scene
    S.plane_under_sun(scene, RESOLUTION)
    leaf = add_leaf(scene)
    leaf.location = (0.0, -1.0, 0.4)
    scene.render.film_transparent = True
    cycles = []
    for run in range(CYCLES_RUNS):
        S.set_cycles_unbiased(scene, samples=CYCLES_SPP, seed=201 + run)
        scene.render.film_transparent = True
        cycles.append(S.render_to_exr(scene, tmp_path / f"cycles_{run}.exr")["Combined"])
    cycles = S.np.stack(cycles)
    S.set_sampling_lab(scene, samples=OUR_SPP, seed=9)
    ours = S.render_to_exr(scene, tmp_path / "ours.exr")
    assert ours["Combined"].shape[-1] == 4
    S.assert_ours_agree_with_cycles({**ours}, cycles[..., :3], "transparent film",
                                    detect=(0.02, 0.2), spp=OUR_SPP)
    ours_alpha, cycles_alpha = ours["Combined"][..., 3], cycles[..., 3].mean(axis=0)
    leaf = int(((cycles_alpha > 0.2) & (cycles_alpha < 0.8)).sum())
    print(f"alpha mean ours {ours_alpha.mean():.4f}, Cycles {cycles_alpha.mean():.4f}; pixels "
          f"with 0.2 < alpha < 0.8 (the leaf): {leaf}")
    assert 0.1 < cycles_alpha.mean() < 0.9  # sky, plane and leaf all in view
    assert abs(ours_alpha.mean() - cycles_alpha.mean()) < 0.005 * cycles_alpha.mean()
    blocks = lambda a: a.reshape(4, 8, 4, 8).mean(axis=(1, 3))  # noqa: E731
    assert S.np.abs(blocks(ours_alpha) - blocks(cycles_alpha)).max() < 0.02


@pytest.mark.parametrize("integrator", ['PATH', 'LIGHT', 'BDPT', 'PHOTON', 'SPPM', 'MLT',
                                        'RADIOSITY'])
def test_film_panel_shows_transparent_active_where_it_is_rendered(empty_scene, integrator):
    empty_scene.sampling_lab.integrator = integrator
    active = drawn_rows("SAMPLINGLAB_RENDER_PT_film", empty_scene)
    assert active["film_transparent"]  # every estimator renders the alpha
