"""The light tree (``light_selection='tree'``): its pmf, its sampling, and its images.

- the pmf over all emitters sums to one for any receiving point and normal, also behind
  one-sided lamps, and is positive for every emitter that can light the point;
- ``choose`` returns exactly ``pmf(index, p, n)`` and its frequencies match the pmf
  (chi-square), while a pmf off by a factor, or one that leaves out the normal, fails;
- path tracing with the tree gives the same image as with power selection (within confidence
  intervals), and on the many-lights scene a lower relative variance at equal spp.
"""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from sampling_lab.core import lights as L
from sampling_lab.core import scenes
from sampling_lab.core.lights.selection import TreeSelection
from sampling_lab.core.lights.tree import LightTree, lamp_bounds
from sampling_lab.core.prepare import prepare
from sampling_lab.core.render import render, used_settings
from sampling_lab.core.scene import Lights
from tests.helpers import (assert_two_images_agree, chi_square_test, plain_settings,
                           z_for_false_failure)


def _mixed_scene():
    """Many-lights quads plus every finite lamp kind (one-sided area lamps facing down and up,
    a sphere, a delta point, a delta spot), a sun and a constant world."""
    scene = scenes.many_lights(8, 8, n=64)
    down, up = np.eye(4), np.diag([1.0, -1.0, -1.0, 1.0])
    down[:3, 3] = (0.3, 0.2, 1.8)
    up[:3, 3] = (-0.4, 0.1, 0.2)
    scene.lights = Lights.concat([
        L.area_light(down, "SQUARE", 0.3, 0.3, (1, 1, 1), 20.0),
        L.area_light(up, "DISK", 0.2, 0.2, (1, 1, 1), 5.0),
        L.point_light((0.5, -0.5, 1.0), (1, 1, 1), 10.0, radius=0.05),
        L.point_light((-0.5, 0.5, 1.5), (1, 0.5, 0.2), 8.0),
        L.point_light((0.0, 0.0, 1.9), (1, 1, 1), 30.0, spot_direction=(0, 0, -1),
                      spot_size=np.radians(60)),
        L.sun_light((0.2, 0.1, -1.0), (1, 1, 1), 2.0),
    ])
    scene.world_color = np.array([0.05, 0.05, 0.08])
    return scene


@pytest.fixture(scope="module")
def mixed():
    """The mixed scene's light sampler (in the prepared, recentred frame)."""
    return prepare(_mixed_scene(), light_selection="tree").lights


def _points(rng, m):
    """Receiving points in and around the recentred room (some behind the lamps) and unit
    normals."""
    p = rng.uniform(-1.3, 1.3, (m, 3))
    n = rng.normal(size=(m, 3))
    return p, n / np.linalg.norm(n, axis=1, keepdims=True)


def _pmf_table(ls, p, n):
    """``(m, emitters)`` pmf of every emitter from every point."""
    e = ls.n_emitters
    idx = np.tile(np.arange(e), p.shape[0])
    nn = None if n is None else np.repeat(n, e, axis=0)
    return ls.selector.pmf(idx, np.repeat(p, e, axis=0), nn).reshape(p.shape[0], e)


def test_tree_pmf_sums_to_one(mixed):
    rng = np.random.default_rng(3)
    p, n = _points(rng, 200)
    for normals in (n, None):
        table = _pmf_table(mixed, p, normals)
        assert np.all(table >= 0) and np.all(np.isfinite(table))
        np.testing.assert_allclose(table.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    # Some points lie behind a one-sided area lamp (rows 0 and 1), whose pmf is then zero.
    assert (table[:, :2] == 0).any()


def test_tree_pmf_positive_where_light_arrives(mixed):
    """An emitter that can light the point (in front of a one-sided lamp, inside a spot's cone,
    any two-sided triangle or omnidirectional lamp) is never given probability zero."""
    rng = np.random.default_rng(4)
    prep_lights = mixed.lights
    p, n = _points(rng, 300)
    table = _pmf_table(mixed, p, n)
    to_p = p[:, None, :] - prep_lights.position[None, :2]
    front = np.einsum("mkj,kj->mk", to_p, prep_lights.direction[:2]) > 1e-9
    assert np.all(table[:, :2][front] > 0)
    assert np.all(table[:, 2:4] > 0)                       # sphere and delta point
    spot_dir = prep_lights.direction[4]
    to_p = p - prep_lights.position[4]
    in_cone = to_p @ spot_dir > np.cos(np.radians(30)) * np.linalg.norm(to_p, axis=1)
    assert np.all(table[in_cone, 4] > 0)
    assert np.all(table[:, 5:] > 0)                        # sun, triangles, world


def test_tree_choose_returns_exact_pmf(mixed):
    rng = np.random.default_rng(5)
    p, n = _points(rng, 4000)
    index, pmf = mixed.selector.choose(rng.random(4000), None, p, n)
    np.testing.assert_array_equal(pmf, mixed.selector.pmf(index, p, n))
    assert np.all(pmf > 0)


@pytest.mark.parametrize("point", [0, 1, 2])
def test_tree_frequencies_match_pmf(mixed, point):
    """Chi-square of 200k choices from one (p, n) against the pmf; a pmf with one child of
    the root scaled by 1.1 (renormalised) and the pmf without the normal term must fail at the
    same sample count."""
    rng = np.random.default_rng(10 + point)
    p, n = _points(rng, 3)
    p, n = p[point:point + 1], n[point:point + 1]
    k = 200_000
    pk, nk = np.repeat(p, k, axis=0), np.repeat(n, k, axis=0)
    index, _ = mixed.selector.choose(rng.random(k), None, pk, nk)
    pmf = _pmf_table(mixed, p, n)[0]
    chi_square_test(index, pmf, what="light tree choices")

    tree = mixed.selector.tree
    left = np.zeros(mixed.n_emitters, bool)
    left[tree.leaf_rows[tree.path_left[:, 0] & (tree.path_node[:, 0] == 0)]] = True
    scaled = np.where(left, 1.1 * pmf, pmf)
    with pytest.raises(AssertionError):
        chi_square_test(index, scaled / scaled.sum(), what="scaled pmf")
    no_normal = _pmf_table(mixed, p, None)[0]
    with pytest.raises(AssertionError):
        chi_square_test(index, no_normal, what="pmf without the normal")


def test_tree_power_fallback_where_both_children_are_dark():
    """Two one-sided lamps facing away from a point: the importance of both is zero, the pmf
    falls back to their power and still sums to one."""
    lights = Lights.concat([L.area_light(np.diag([1.0, 1, 1, 1]), "SQUARE", 0.1, 0.1,
                                         (1, 1, 1), w) for w in (10.0, 30.0)])
    lights.position[1] = (1.0, 0, 0)
    bounds = lamp_bounds(lights, np.arange(2), np.array([10.0, 30.0]))
    tree = LightTree(bounds)
    above = np.array([[0.5, 0.0, 1.0]])                   # lamps emit toward -Z
    imp = tree.importance(np.array([1, 2]), LightTree._components(np.repeat(above, 2, axis=0)))
    assert np.all(imp == 0)
    np.testing.assert_allclose(tree.pmf(np.arange(2), np.repeat(above, 2, axis=0)),
                               [0.25, 0.75])
    below = np.array([[0.5, 0.0, -1.0]])
    assert tree.pmf(np.arange(2), np.repeat(below, 2, axis=0)).sum() == pytest.approx(1.0)


def test_tree_importance_prefers_near_and_facing_lights():
    lights = Lights.concat([L.point_light((x, 0, 0), (1, 1, 1), 10.0) for x in (0.0, 4.0)])
    tree = LightTree(lamp_bounds(lights, np.arange(2), np.array([10.0, 10.0])))
    p = np.array([[0.5, 0.0, 0.0]] * 2)
    pm = tree.pmf(np.arange(2), p)
    np.testing.assert_allclose(pm, np.array([1 / 0.25, 1 / 12.25]) / (1 / 0.25 + 1 / 12.25))
    # Equal lights at equal distance: the one in the receiver's tangent plane cannot light it.
    lights = Lights.concat([L.point_light(q, (1, 1, 1), 10.0) for q in ((0, 0, 1), (1, 0, 0))])
    tree = LightTree(lamp_bounds(lights, np.arange(2), np.array([10.0, 10.0])))
    p, n = np.zeros((2, 3)), np.array([[0.0, 0.0, 1.0]] * 2)
    np.testing.assert_allclose(tree.pmf(np.arange(2), p), [0.5, 0.5])
    np.testing.assert_allclose(tree.pmf(np.arange(2), p, n), [1.0, 0.0], atol=1e-15)


def test_used_settings_report_power_for_light_paths():
    for integrator, expected in (("path", "tree"), ("light", "power"), ("bdpt", "power")):
        used = used_settings(plain_settings(integrator=integrator, light_selection="tree"))
        assert used["light_selection"] == expected


# ---------------------------------------------------------------------------------------------
# Images

SPP = 2048


@pytest.fixture(scope="module")
def many_renders():
    scene = scenes.many_lights(24, 24)
    out = {}
    for sel, seed in (("power", 1), ("tree", 2)):
        res = render(scene, plain_settings(spp=SPP, seed=seed, max_bounces=3,
                                           light_selection=sel))
        out[sel] = res.combined()[..., :3].astype(np.float64), res.variance().astype(np.float64)
    return out


def test_tree_image_agrees_with_power(many_renders):
    """Tree and power selection render the same image of the many-lights scene: image means
    and 8 x 8 block means within their confidence intervals (p_false 1e-4). Detects a 2 %
    error of the image mean and a 6 % error of a block with 99 % probability."""
    (ma, va), (mb, vb) = many_renders["tree"], many_renders["power"]
    assert_two_images_agree(ma, va, mb, vb, detect=(0.02, 0.06), what="tree vs power")


def test_tree_image_check_rejects_a_wrong_image(many_renders):
    (ma, va), (mb, vb) = many_renders["tree"], many_renders["power"]
    with pytest.raises(AssertionError):
        assert_two_images_agree(1.06 * ma, va, mb, vb, detect=(0.02, 0.06))


def test_tree_image_check_rejects_mis_with_the_wrong_pmf(many_renders, monkeypatch):
    """The same check catches a tree render whose MIS reads power selection's table for the
    emitters BSDF rays find instead of the tree's pmf (measured +17 % on the image mean)."""
    from sampling_lab.core.lights.sampler import LightSampler

    def table_pmf(self, index, p, n=None):
        return np.where(index >= 0, self.select_prob[np.maximum(index, 0)], 0.0)

    monkeypatch.setattr(LightSampler, "nee_pmf", table_pmf)
    res = render(scenes.many_lights(24, 24), plain_settings(spp=SPP, seed=2, max_bounces=3,
                                                            light_selection="tree"))
    mb, vb = many_renders["power"]
    with pytest.raises(AssertionError):
        assert_two_images_agree(res.combined()[..., :3], res.variance(), mb, vb,
                                detect=(0.02, 0.06))


def test_tree_lowers_relative_variance_on_many_lights(many_renders):
    """At equal spp, the tree's summed relative variance (pixel variance over the squared mean
    of both images) is at most 0.8 of power selection's. The bound is tested against the
    ratio's own sampling error (delta method over the pixels, z for p_false 1e-4), so a tree
    no better than power fails; measured 0.51 +- 0.01 (seeds 1 and 2)."""
    (ma, va), (mb, vb) = many_renders["tree"], many_renders["power"]
    mean = 0.5 * (ma + mb).sum(axis=-1)
    keep = mean > 0.05 * mean.mean()
    rel_t = (va.sum(axis=-1) / mean**2)[keep]
    rel_p = (vb.sum(axis=-1) / mean**2)[keep]
    ratio = rel_t.sum() / rel_p.sum()
    # Sampling error of the ratio of two sums over the same pixels (delta method).
    resid = rel_t - ratio * rel_p
    se = np.sqrt(resid.size * resid.var(ddof=1)) / rel_p.sum()
    z = z_for_false_failure(1e-4)
    print(f"tree / power relative variance {ratio:.3f} +- {se:.3f}")
    assert ratio + z * se < 0.8, f"tree / power relative variance {ratio:.3f} +- {se:.3f}"


@pytest.mark.parametrize("integrator", ["light", "bdpt"])
def test_light_paths_choose_by_power_under_tree(integrator):
    """Light tracing and BDPT start paths without a receiving point: with ``tree`` they render
    exactly the power-selection image (as ``used_settings`` reports)."""
    scene = scenes.many_lights(8, 8, n=32)
    images = [render(scene, plain_settings(integrator=integrator, spp=2, seed=4, max_bounces=2,
                                           light_selection=sel)).combined()
              for sel in ("power", "tree")]
    np.testing.assert_array_equal(images[0], images[1])


@pytest.mark.parametrize("lights", ["none", "world", "one_point", "sun_and_world", "one_quad"])
def test_tree_renders_scenes_with_few_lights(lights):
    """No emitter, only infinite ones, a one-leaf tree or a quad's two triangles: finite
    images, and the same image as power selection where the choice cannot differ (no emitter,
    one, or two that the tree cannot tell apart: it is power selection there)."""
    scene = scenes.cornell_box(8, 8, light="mesh" if lights == "one_quad" else "point")
    if lights != "one_point" and lights != "one_quad":
        scene.lights = Lights.empty()
    if lights == "sun_and_world":
        scene.lights = L.sun_light((0.2, 0.1, -1.0), (1, 1, 1), 2.0)
    if lights in ("world", "sun_and_world"):
        scene.world_color = np.array([0.2, 0.2, 0.3])
    images = [render(scene, plain_settings(spp=4, seed=3, max_bounces=2, light_selection=sel))
              .combined() for sel in ("power", "tree")]
    assert np.isfinite(images[1]).all() and images[1][..., :3].min() >= 0
    if lights in ("none", "one_point", "world", "one_quad"):
        np.testing.assert_array_equal(images[0], images[1])
    np.testing.assert_allclose(images[1][..., :3].mean(), images[0][..., :3].mean(), rtol=0.5)


@pytest.mark.parametrize("selection, normals", [("tree", True), ("power", False)])
def test_path_tracer_gives_the_tree_its_shading_normals_in_nee_and_mis(selection, normals,
                                                                       monkeypatch):
    # Next-event estimation and the MIS weights of emitters that BSDF rays find must hand the
    # selection the same normals (measured: tree / power relative variance 0.51 without them,
    # 0.48 with them); the table selections get none.
    from sampling_lab.core.lights.sampler import LightSampler

    seen = {"sample": set(), "hit_shapes": set(), "triangle_pdf": set()}
    for name, key in (("sample", "n"), ("hit_shapes", "n"), ("triangle_pdf", "n_prev")):
        original = getattr(LightSampler, name)

        def spy(self, *args, _original=original, _name=name, _key=key, **kw):
            bound = inspect.signature(_original).bind(self, *args, **kw)
            seen[_name].add(bound.arguments.get(_key) is not None)
            return _original(self, *args, **kw)

        monkeypatch.setattr(LightSampler, name, spy)
    render(scenes.many_lights(8, 8), plain_settings(spp=2, seed=1, max_bounces=3,
                                                    light_selection=selection))
    assert seen["sample"] == {normals}
    # Camera rays have no origin vertex; every later bounce has one.
    assert normals in seen["hit_shapes"] and normals in seen["triangle_pdf"]


@pytest.fixture(scope="module")
def triangles_only():
    """A tree of two-sided emissive triangles alone (no sun, no world): every NEE row
    descends the tree, and the tree has no orientation cones (``omni``)."""
    return prepare(scenes.many_lights(8, 8, n=64), light_selection="tree").lights


def test_tree_only_batches_choose_with_the_exact_pmf(triangles_only):
    """The whole-batch path of ``TreeSelection.choose`` (no sun or world rows to set aside)
    returns the probability ``pmf`` gives, bit for bit."""
    assert triangles_only.selector.tree.omni
    rng = np.random.default_rng(15)
    p, n = _points(rng, 3000)
    for normals in (n, None):
        index, pmf = triangles_only.selector.choose(rng.random(3000), None, p, normals)
        np.testing.assert_array_equal(pmf, triangles_only.selector.pmf(index, p, normals))
        assert np.all(pmf > 0)


@pytest.mark.parametrize("which", ["mixed", "triangles_only"])
def test_tree_root_level_broadcast_equals_the_per_point_gather(which, request):
    """At the root every point asks about the same node: the broadcast fields give the same
    probabilities, to the bit, as gathering them per point."""
    tree = request.getfixturevalue(which).selector.tree
    rng = np.random.default_rng(16)
    p, n = _points(rng, 2000)
    pc, nc = tree._components(p), tree._components(n)
    for normals in (nc, None):
        np.testing.assert_array_equal(tree._p_left(0, pc, normals),
                                      tree._p_left(np.zeros(2000, np.int64), pc, normals))


def test_alike_bounds_are_those_of_one_box_and_cone():
    """``EmitterBounds.alike``: a quad's two triangles (one box, two-sided) are alike; lamps
    in two places, or one-sided lamps in one box facing two ways, are not."""
    quad = prepare(scenes.cornell_box(8, 8, light="mesh"), light_selection="tree")
    tris = quad.lights.triangles
    from sampling_lab.core.lights.tree import triangle_bounds

    assert triangle_bounds(tris, 0, tris.emit_power).alike()
    two_quads = prepare(scenes.many_lights(8, 8, n=2), light_selection="tree").lights
    assert two_quads.selector.steers
    down, up = np.eye(4), np.diag([1.0, -1.0, -1.0, 1.0])
    facing = Lights.concat([L.area_light(m, "SQUARE", 0.3, 0.3, (1, 1, 1), 20.0)
                            for m in (down, up)])
    bounds = lamp_bounds(facing, np.arange(2), np.ones(2))
    assert np.array_equal(bounds.lo, bounds.lo[[1, 0]]) and not bounds.alike()


def test_a_tree_that_steers_nothing_is_power_selection():
    """The bench's box (one emissive quad) under ``tree``: the tree's own pmf is power
    selection's from every point and normal (to float32 rounding), so the sampler uses power
    selection itself (no normals needed), says so, and renders the power image bit for bit."""
    scene = scenes.cornell_box(8, 8, light="mesh")
    lights = prepare(scene, light_selection="tree").lights
    assert lights.selector is lights.path_selector and not lights.selector.point_dependent
    assert any("Light Tree" in note and "by power" in note for note in lights.notes)
    tree_sel = TreeSelection(lights._power(scene), scene.lights, np.zeros(0, bool),
                             lights.triangles, lights.has_world, "cdf")
    assert not tree_sel.steers
    rng = np.random.default_rng(17)
    p, n = _points(rng, 500)
    idx = np.repeat(len(scene.lights) + np.arange(2), 250)  # the two triangles' rows
    np.testing.assert_allclose(tree_sel.pmf(idx, p, n), lights.selector.pmf(idx), rtol=1e-6)
    result = render(scene, plain_settings(spp=2, seed=5, light_selection="tree"))
    assert any("Light Tree" in m for m in result.messages)
    power = render(scene, plain_settings(spp=2, seed=5, light_selection="power"))
    np.testing.assert_array_equal(result.combined(), power.combined())
