"""BDPT's Direct Light Points option (``light_points``): strategy ``s = 1`` joins each camera
vertex either to the point its sample's light path starts from (``'light_path'``, Veach's
formulation, the default) or to a fresh point sampled for that vertex (``'fresh'``, pbrt's).

Properties: both give the same image (independent replicates agree, and a light-path point
whose density is misstated by a factor of two fails the same check); the light-path form draws
no light samples of its own (only the light paths' choices); the option changes BDPT's render
and no other integrator's, and the stats say what was used.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core.integrators import bdpt as bdpt_module
from sampling_lab.core.lights.emission import EmitterPoints
from sampling_lab.core.render import check_settings, render
from sampling_lab.core.scenes import cornell_box
from tests.helpers import assert_replicates_agree, plain_settings


@pytest.fixture(scope="module")
def box():
    return cornell_box(16, 16, "mesh")


def _replicates(scene, runs, points):
    imgs = []
    for i in range(runs):
        res = render(scene, plain_settings(integrator="bdpt", spp=16, seed=31 + 1000 * i,
                                           max_bounces=3, light_points=points))
        img = res.film.mean()
        assert np.isfinite(img).all() and (img >= 0).all()
        imgs.append(img)
    return np.stack(imgs), res


def test_light_path_points_and_fresh_points_give_the_same_image(box):
    """24 independent renders of 16 samples per pixel each way, block by block
    (`assert_replicates_agree`, sized to see 2 % of the image mean and 15 % of an 8 x 8
    block with 99 % power; it sees 1.2 % and 4.4 % here)."""
    path_points, res = _replicates(box, 24, "light_path")
    fresh, res_fresh = _replicates(box, 24, "fresh")
    found = assert_replicates_agree(path_points, fresh, detect=(0.02, 0.15),
                                    what="BDPT light-path points vs fresh points")
    print(f"light-path / fresh points: image mean ratio {np.round(found.ratio, 4)}")
    assert res.stats["light_points"] == "light_path"
    assert res_fresh.stats["light_points"] == "fresh"


def test_a_misstated_light_path_point_density_fails_the_agreement_check(box, monkeypatch):
    """The check above is not blind to the option's own mistakes: light-path points whose
    density reads twice what it is halve the ``s = 1`` strategy's contributions and shift
    every MIS weight, which darkens the directly lit box by far more than the check sees."""
    points = bdpt_module._light_path_points

    def misstated(ctx, C):
        fresh = points(ctx, C)
        pts = fresh.points
        return fresh._replace(points=EmitterPoints(*pts[:4], pts[4] * 2.0, *pts[5:]))

    fresh, _ = _replicates(box, 24, "fresh")
    monkeypatch.setattr(bdpt_module, "_light_path_points", misstated)
    wrong, _ = _replicates(box, 24, "light_path")
    with pytest.raises(AssertionError, match="block means differ"):
        assert_replicates_agree(wrong, fresh, detect=(0.02, 0.15),
                                what="BDPT with misstated light-path point densities")


def test_light_path_points_draw_no_light_samples_of_their_own(box):
    """Fresh points choose a light for every connectible camera vertex; light-path points only
    for the light paths (one choice of a light and one of its triangle per sample)."""
    counts = {}
    for points in ("light_path", "fresh"):
        settings = plain_settings(integrator="bdpt", spp=1, seed=2, max_bounces=3,
                                  light_points=points, light_selection="power")
        res = render(box, settings)
        counts[points] = res.stats["distribution_samples"]
    samples = 16 * 16
    assert counts["light_path"] == 2 * samples
    assert counts["fresh"] > 2 * counts["light_path"]


def test_light_points_change_bdpt_renders_and_no_other_integrator(box):
    def image(integrator, points):
        return render(box, plain_settings(integrator=integrator, spp=2, seed=4, max_bounces=3,
                                          light_points=points)).film.mean()

    assert not np.array_equal(image("bdpt", "light_path"), image("bdpt", "fresh"))
    for integrator in ("path", "light"):
        assert np.array_equal(image(integrator, "light_path"), image(integrator, "fresh"))
        res = render(box, plain_settings(integrator=integrator, spp=1, light_points="fresh"))
        assert res.stats["light_points"] == "n/a"


def test_an_unknown_light_points_value_is_refused_with_its_name(box):
    with pytest.raises(ValueError, match="light_points"):
        check_settings(box, plain_settings(integrator="bdpt", light_points="nearest"))


def test_light_path_points_are_the_light_subpaths_first_vertices():
    """Each connectible camera vertex gets its own sample's light point, row for row."""
    rng = np.random.default_rng(5)
    n, depth = 6, 4
    pts = EmitterPoints(np.array([0, 1, -1, 0, 1, 0]), rng.random((n, 3)), rng.random((n, 3)),
                        np.zeros((n, 3)), rng.random(n) + 0.5, np.zeros(n, bool),
                        np.zeros(n, bool))

    class Ctx:
        light_points = pts

    class Camera:
        valid = np.zeros((depth, n), bool)
        connectible = np.ones((depth, n), bool)

    Camera.valid[0] = True
    Camera.valid[1, [0, 2, 3]] = True
    Camera.valid[2, [3, 4]] = True
    fresh = bdpt_module._light_path_points(Ctx(), Camera())
    # Depth-major order; row 2's light path found no emitter (index -1): no join.
    np.testing.assert_array_equal(fresh.row, [0, 3, 3, 4])
    np.testing.assert_array_equal(fresh.zj, [1, 1, 2, 2])
    for got, table in zip(fresh.points, pts):
        np.testing.assert_array_equal(got, table[fresh.row])
