"""Materials that mix several BSDFs: one component chosen per path vertex.

Checks: :meth:`PreparedScene.choose_material` picks each component as often as its weight
(chi-square), by CDF inversion and by alias table as the ``distribution`` setting says, and
never a zero-weight one, the remapped lobe number is uniform again for every
component (Kolmogorov-Smirnov), single rows pass their number through unchanged; renders of
mixtures equal the weighted sums of their components in closed form (a plane under a uniform
sky, a furnace), and next-event estimation agrees with BSDF sampling on a mixed material.
"""

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.prepare import prepare
from sampling_lab.core.render import render
from sampling_lab.core.scene import (MAT_CONDUCTOR, MAT_DIELECTRIC, MAT_DIFFUSE, MAT_LAYERED,
                                     Camera, Lights, Materials, Scene)
from tests.helpers import (assert_mean_within_ci, assert_two_images_agree, chi_square_test,
                           ks_uniform_test, plain_settings)

WEIGHTS = np.array([0.2, 0.5, 0.3])


def _mixed_table(weights=WEIGHTS, pad=1):
    """Row 0: mixture of rows 1-3 (diffuse, white mirror, transparent pass-through) with
    ``weights``, padded with ``pad`` zero-weight columns; row 4: a plain diffuse row."""
    mix_rows = np.arange(5)[:, None].repeat(3 + pad, axis=1)
    mix_weights = np.zeros((5, 3 + pad))
    mix_weights[:, 0] = 1.0
    mix_rows[0, :3] = [1, 2, 3]
    mix_weights[0] = 0.0
    mix_weights[0, :3] = weights
    return Materials.from_lists(
        ["Mix", "Diffuse", "Mirror", "Clear", "Plain"],
        [(0.5,) * 3, (0.5,) * 3, (1.0,) * 3, (1.0,) * 3, (0.3,) * 3], np.zeros((5, 3)),
        kinds=[MAT_DIFFUSE, MAT_DIFFUSE, MAT_CONDUCTOR, MAT_DIELECTRIC, MAT_DIFFUSE],
        roughness=[0.5, 0.5, 0.0, 0.0, 0.5], ior=[1.5, 1.5, 1.5, 1.0, 1.5],
        mix_rows=mix_rows, mix_weights=mix_weights)


def _plane(mats, material_rows=(0, 4), world=(1.0, 1.0, 1.0), n=16):
    """Two unit squares side by side at z = 0 (materials ``material_rows``), seen from above
    by an orthographic camera, under a uniform world."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                  [1, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0]], np.float64)
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]], np.int32)
    material = np.repeat(np.asarray(material_rows, np.int32), 2)
    cam = Camera(scenes.look_at((0.5, 0.5, 1.0), (0.5, 0.5, 0.0), up=(0, 1, 0)), n, n,
                 type="ORTHO", ortho_scale=1.0)
    return Scene(v, f, material, mats, Lights.empty(), cam, world_color=world)


@pytest.mark.parametrize("method", ["cdf", "alias"])
def test_mixture_choice_frequencies_match_weights(method):
    prep = prepare(_plane(_mixed_table()), distribution=method)
    n = 200_000
    u = np.random.default_rng(1).random(n)
    rows, _ = prep.choose_material(np.zeros(n, np.int64), u)
    assert set(np.unique(rows)) <= {1, 2, 3}
    chi_square_test(rows - 1, WEIGHTS, what="mixture components")


@pytest.mark.parametrize("method", ["cdf", "alias"])
def test_remapped_lobe_number_is_uniform_for_every_component(method):
    prep = prepare(_plane(_mixed_table()), distribution=method)
    n = 100_000
    u = np.random.default_rng(2).random(n)
    rows, remapped = prep.choose_material(np.zeros(n, np.int64), u)
    assert remapped.min() >= 0.0 and remapped.max() < 1.0
    for row in (1, 2, 3):
        ks_uniform_test(remapped[rows == row], what=f"remapped u of component {row}")


@pytest.mark.parametrize("method", ["cdf", "alias"])
def test_single_rows_keep_their_lobe_number_and_their_own_bsdf(method):
    prep = prepare(_plane(_mixed_table()), distribution=method)
    u = np.random.default_rng(3).random(1000)
    prim = np.full(u.size, 2, np.int64)  # a triangle of the plain row
    rows, remapped = prep.choose_material(prim, u)
    assert (rows == 4).all()
    np.testing.assert_array_equal(remapped, u)
    params, delta_only, remapped = prep.choose_bsdf(prim, u)
    np.testing.assert_allclose(params.color, 0.3)
    assert not delta_only.any()


def test_zero_weight_components_are_never_chosen_even_at_cdf_edges():
    prep = prepare(_plane(_mixed_table(weights=[0.5, 0.0, 0.5], pad=2)))
    u = np.array([0.0, np.nextafter(0.5, 0.0), 0.5, np.nextafter(1.0, 0.0)])
    rows, remapped = prep.choose_material(np.zeros(u.size, np.int64), u)
    np.testing.assert_array_equal(rows, [1, 1, 3, 3])
    assert remapped[2] == 0.0 and remapped[1] < 1.0 and remapped[3] < 1.0
    params, delta_only, _ = prep.choose_bsdf(np.zeros(u.size, np.int64), u)
    np.testing.assert_array_equal(delta_only, [False, False, True, True])


def test_alias_table_never_chooses_zero_weight_components_or_padding():
    prep = prepare(_plane(_mixed_table(weights=[0.5, 0.0, 0.5], pad=2)), distribution="alias")
    # Every column edge of the 5-column table and the numbers next to them.
    edges = np.arange(6) / 5.0
    u = np.clip(np.concatenate([edges, np.nextafter(edges, 0.0), np.nextafter(edges, 1.0),
                                np.linspace(0.0, 1.0, 10_001)]), 0.0, np.nextafter(1.0, 0.0))
    rows, remapped = prep.choose_material(np.zeros(u.size, np.int64), u)
    assert set(np.unique(rows)) == {1, 3}
    assert remapped.min() >= 0.0 and remapped.max() < 1.0


def test_distribution_setting_decides_how_a_number_picks_a_component():
    # CDF inversion keeps the order of the numbers (monotone in u); the alias table does not.
    # Both pick components with the same frequencies (the test above), so only this shows
    # that the setting reaches the mixture choice.
    u = np.linspace(0.0, 0.999, 1000)
    picks = {m: prepare(_plane(_mixed_table()), distribution=m).choose_material(
        np.zeros(u.size, np.int64), u)[0] for m in ("cdf", "alias")}
    assert np.all(np.diff(picks["cdf"]) >= 0)
    assert np.any(picks["alias"] != picks["cdf"])


def test_lambert_fast_path_only_without_mixtures():
    assert not prepare(_plane(_mixed_table())).lambert_only
    assert prepare(_plane(_mixed_table(), material_rows=(4, 1))).lambert_only


def test_mixture_plane_under_uniform_sky_is_the_weighted_sum_of_its_components():
    # Under a uniform sky of radiance L (nothing else in the scene) a two-sided diffuse plane
    # of albedo rho reflects rho L, a white mirror L and a pass-through shows the sky: L.
    world = np.array([0.8, 1.0, 1.2])
    scene = _plane(_mixed_table(), world=world, n=24)
    res = render(scene, plain_settings(spp=64, max_bounces=2, seed=5))
    img = res.combined()[..., :3].astype(np.float64).reshape(-1, 3)
    assert np.isfinite(img).all()
    expected = (WEIGHTS[0] * 0.5 + WEIGHTS[1] + WEIGHTS[2]) * world
    assert_mean_within_ci(img, expected, what="mixture plane")


@pytest.mark.parametrize("bounces", [6])
def test_mixture_furnace_has_the_mean_albedo_of_its_components(bounces):
    # Inside a closed emitting sphere (Le = 1) each vertex chooses a component independently,
    # so the expected throughput after k bounces is a^k with a the weighted mean albedo.
    base = scenes.furnace(emission=1.0, albedo=0.5, width=24, height=24)
    mix = np.array([0.6, 0.4])
    mats = Materials.from_lists(
        ["Furnace", "Diffuse", "Mirror"], [(0.5,) * 3, (0.5,) * 3, (1.0,) * 3],
        [(1.0,) * 3, (0.0,) * 3, (0.0,) * 3], kinds=[MAT_DIFFUSE, MAT_DIFFUSE, MAT_CONDUCTOR],
        roughness=[0.5, 0.5, 0.0],
        mix_rows=[[1, 2], [1, 1], [2, 2]], mix_weights=[mix, [1, 0], [1, 0]])
    scene = Scene(base.vertices, base.triangles, base.material, mats, base.lights,
                  base.camera)
    res = render(scene, plain_settings(spp=64, max_bounces=bounces, seed=9))
    img = res.combined()[..., 0].ravel().astype(np.float64)
    a = mix[0] * 0.5 + mix[1] * 1.0
    assert_mean_within_ci(img, (1 - a ** (bounces + 2)) / (1 - a), what="mixture furnace")


def test_nee_and_bsdf_sampling_agree_on_a_mixed_material():
    # NEE evaluates the component chosen for the vertex; light-only and BSDF-only estimates
    # agree with the MIS one only if both strategies use the same choice.
    base = scenes.cornell_box(16, 16, light="area")
    m = base.materials
    k = len(m.names)
    names = list(m.names) + ["Mix", "Rough metal", "Coat", "Glass"]
    colors = np.concatenate([m.base_color, [(0.5,) * 3, (0.9, 0.7, 0.5), (0.2, 0.4, 0.6),
                                            (1.0,) * 3]])
    kinds = list(m.kind) + [MAT_DIFFUSE, MAT_CONDUCTOR, MAT_LAYERED, MAT_DIELECTRIC]
    mix_rows = np.arange(k + 4)[:, None].repeat(3, axis=1)
    mix_weights = np.zeros((k + 4, 3))
    mix_weights[:, 0] = 1.0
    mix_rows[k] = [k + 1, k + 2, k + 3]
    mix_weights[k] = [0.4, 0.4, 0.2]
    mats = Materials.from_lists(names, colors, np.concatenate([m.emission, np.zeros((4, 3))]),
                                kinds=kinds, roughness=list(m.roughness) + [0.5, 0.4, 0.3, 0.0],
                                mix_rows=mix_rows, mix_weights=mix_weights)
    material = base.material.copy()
    material[10:34] = k  # both blocks
    scene = Scene(base.vertices, base.triangles, material, mats, base.lights, base.camera)
    ref = render(scene, plain_settings(spp=128, max_bounces=3, seed=1))
    for heuristic in ("bsdf", "light"):
        other = render(scene, plain_settings(spp=128, max_bounces=3, seed=2,
                                             mis_heuristic=heuristic))
        assert_two_images_agree(ref.combined()[..., :3], ref.variance()[..., :3],
                                other.combined()[..., :3], other.variance()[..., :3],
                                detect=(0.43, 1.05),  # measured 33-37 % / 45-90 %
                                what=f"mixture power vs {heuristic}")


@pytest.mark.parametrize("visible_camera", [False, True])
def test_lamp_seen_through_a_transparent_plane_keeps_its_camera_visibility(visible_camera):
    # Cycles' transparent bounces keep the ray a camera ray: a lamp hidden from the camera
    # stays hidden behind an Alpha 0 / Transparent surface, and a visible one shows fully.
    from sampling_lab.core.lights import area_light

    mats = _mixed_table(weights=[0.0, 0.0, 1.0])
    to_world = np.eye(4)
    to_world[:3, 3] = (0.5, 0.5, -1.0)
    to_world[:3, :3] = np.diag([1.0, -1.0, -1.0])  # local -Z (the emitting side) toward +z
    lamp = area_light(to_world, 'SQUARE', 4.0, 4.0, (1.0, 1.0, 1.0), 100.0,
                      visible_camera=visible_camera)
    scene = _plane(mats)
    scene = Scene(scene.vertices, scene.triangles, scene.material, mats, lamp, scene.camera)
    res = render(scene, plain_settings(spp=4, max_bounces=2, seed=3))
    img = res.combined()[..., :3]
    assert np.isfinite(img).all()
    if visible_camera:
        radiance = lamp.radiance[0]
        np.testing.assert_allclose(img[4:-4, 4:-4].reshape(-1, 3), radiance[None].repeat(
            img[4:-4, 4:-4].reshape(-1, 3).shape[0], 0), rtol=1e-5)
    else:
        assert img.max() == 0.0
