"""Sampling Lab agrees with Cycles on smooth-shaded meshes (interpolated corner normals).

Same method as ``test_cycles_materials.py``: Cycles under unbiased settings renders several
seeds, Sampling Lab reports its own variance pass, and ``tests.helpers.assert_images_agree``
compares the image mean per channel and every 8 x 8 block mean. The sphere is a coarse
(16 x 8) UV sphere with Shade Smooth, so shading and geometric normals differ by up to ~11
degrees and a flat-shaded export would visibly disagree.
"""

import numpy as np
import pytest

import scenes as S

RESOLUTION = (32, 32)
OUR_SPP = 512
CYCLES_SPP = 128
CYCLES_RUNS = 4
BOUNCES = 6

SCENES = {
    "smooth_diffuse_sphere": lambda sc: S.cornell_smooth_sphere(
        sc, S.diffuse_material("Smooth", (0.8, 0.8, 0.8)), RESOLUTION),
    "smooth_glossy_sphere": lambda sc: S.cornell_smooth_sphere(
        sc, S.glossy_material("SmoothGlossy", (0.9, 0.9, 0.9), 0.3), RESOLUTION),
}


# Smallest errors each comparison detects with 99 % power, (image mean, worst 8x8 block),
# measured at these sample counts; the checker fails the test if its images fall below them.
# Measured: diffuse sphere 1.7 % / 16 %, glossy sphere 6.8 % / 48 % (its highlight).
STATED = {"smooth_diffuse_sphere": (0.02, 0.18), "smooth_glossy_sphere": (0.075, 0.55)}


@pytest.mark.parametrize("name", list(SCENES))
def test_smooth_shading_agrees_with_cycles(empty_scene, tmp_path, name):
    scene = empty_scene
    objects = SCENES[name](scene)
    assert all(p.use_smooth for p in objects["sphere"].data.polygons)

    ours, cycles = S.render_ours_and_cycles(scene, tmp_path, OUR_SPP, CYCLES_SPP, CYCLES_RUNS,
                                            BOUNCES, our_seed=7, cycles_seed=101)
    S.assert_ours_agree_with_cycles(ours, cycles, name, detect=STATED[name],
                                    spp=OUR_SPP)


SKY = (0.8, 0.6, 0.4)


def mirror_ball_in_sky(scene):
    """A coarse (8 x 4) smooth-shaded white mirror ball filling most of the view, in a world of
    constant colour :data:`SKY`: every reflection that is kept sees the world (or the ball, then
    the world), every dropped one is black."""
    import math

    mirror = S.glossy_material("Mirror", (1.0, 1.0, 1.0), 0.0)
    ob = S.add_uv_sphere(scene, "Ball", (0.0, 0.0, 0.0), 1.0, mirror, 8, 4)
    ob.data.polygons.foreach_set("use_smooth", [True] * len(ob.data.polygons))
    ob.data.update()
    S.set_world(scene, SKY, 1.0)
    S.add_camera(scene, (0.0, -4.0, 0.0), (math.radians(90), 0.0, 0.0), lens=60.0)
    S.set_resolution(scene, *RESOLUTION)
    return {"sphere": ob}


def test_smooth_mirror_ball_has_no_black_rims_and_agrees_with_cycles(empty_scene, tmp_path):
    """Cycles bends the ball's shading normals so that reflections stay above the facets; so
    do we. The image is then the world's colour everywhere, in both engines (a white mirror
    reflects it unchanged, up to 0.1 %); dropping the reflections that dip below the facets,
    as we did before, darkened the ball's rims (10 % of the pixels, by up to 69 %)."""
    mirror_ball_in_sky(empty_scene)
    ours, cycles = S.render_ours_and_cycles(empty_scene, tmp_path, 16, 16, 2, 2, our_seed=7,
                                            cycles_seed=101)
    sky = np.array(SKY, np.float32)
    np.testing.assert_allclose(cycles, np.broadcast_to(sky, cycles.shape), rtol=1e-3)
    np.testing.assert_allclose(ours["Combined"][..., :3],
                               np.broadcast_to(sky, ours["Combined"][..., :3].shape), rtol=1e-3)


def test_smooth_sphere_exports_world_corner_normals(empty_scene):
    """Shade Smooth exports unit corner normals, ~ (p - centre) / r on a UV sphere, transformed
    by the inverse transpose of a non-uniform scale; flat-shaded scenes export None."""
    import bpy
    from sampling_lab.addon import export

    scene = empty_scene
    objects = S.cornell_smooth_sphere(scene, S.diffuse_material("Smooth", (0.8, 0.8, 0.8)))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    s = export.export_scene(depsgraph)
    assert s.corner_normals is not None and s.corner_normals.shape == (s.n_triangles, 3, 3)
    centre = np.array(objects["sphere"].location)
    p = s.vertices[s.triangles].astype(np.float64)
    on_sphere = np.abs(np.linalg.norm(p - centre, axis=2) - 0.45).max(axis=1) < 1e-4
    expected = (p - centre) / 0.45
    # UV-sphere vertex normals are the face-angle-weighted mean of the adjacent facets: within
    # a few degrees of the radial direction.
    cos = np.einsum("tkj,tkj->tk", s.corner_normals[on_sphere], expected[on_sphere])
    assert cos.min() > np.cos(np.radians(5.0))
    np.testing.assert_allclose(np.linalg.norm(s.corner_normals, axis=2), 1.0, atol=1e-5)
    # Flat walls keep their face normals at every corner.
    tri = p[~on_sphere]
    face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    face /= np.linalg.norm(face, axis=1, keepdims=True)
    np.testing.assert_allclose(s.corner_normals[~on_sphere], np.repeat(face[:, None], 3, 1),
                               atol=1e-5)

    # A non-uniform scale: normals follow the inverse transpose (an ellipsoid's gradient).
    sphere = objects["sphere"]
    sphere.scale = (2.0, 1.0, 0.5)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    depsgraph.update()
    s = export.export_scene(depsgraph)
    p = s.vertices[s.triangles].astype(np.float64)
    q = (p - centre) / np.array([2.0, 1.0, 0.5])
    ell = np.abs(np.linalg.norm(q, axis=2) - 0.45).max(axis=1) < 1e-4
    grad = (p - centre) / np.array([4.0, 1.0, 0.25])
    grad /= np.linalg.norm(grad, axis=2, keepdims=True)
    cos = np.einsum("tkj,tkj->tk", s.corner_normals[ell], grad[ell])
    assert ell.sum() > 100 and cos.min() > np.cos(np.radians(8.0))

    for ob in list(scene.objects):
        if ob.type == 'MESH':
            ob.data.polygons.foreach_set("use_smooth", [False] * len(ob.data.polygons))
            ob.data.update()
    assert export.export_scene(bpy.context.evaluated_depsgraph_get()).corner_normals is None
