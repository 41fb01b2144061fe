"""Photon stages (core/photons): kd-tree queries equal brute force (also far from the origin),
kernels integrate to one, photon tracing carries the emitted power and roulette by albedo keeps
it unbiased, and the memory cap stops a render with a clear message."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from sampling_lab.core import render, scenes
from sampling_lab.core.integrators.base import Counters
from sampling_lab.core.photons.grid import PointGrid
from sampling_lab.core.photons.kernels import KERNELS, kernel_weight
from sampling_lab.core.photons.lookup import PhotonTree
from sampling_lab.core.photons.tracing import check_memory, spans, trace_photons
from sampling_lab.core.prepare import prepare
from sampling_lab.core.sampling.samplers import make_sampler
from tests.helpers import assert_mean_within_ci


def _brute_pairs(points, photons, radii):
    d = np.linalg.norm(points[:, None, :] - photons[None, :, :], axis=2)
    i, j = np.nonzero(d < radii[:, None])
    return set(zip(i.tolist(), j.tolist()))


@pytest.mark.parametrize("offset", [0.0, 1e4])
def test_pairs_within_are_exactly_the_brute_force_neighbours(offset):
    rng = np.random.default_rng(3)
    photons = rng.random((2000, 3)) + offset
    points = rng.random((300, 3)) + offset
    radii = rng.uniform(0.01, 0.15, 300)
    tree = PhotonTree(photons)
    i, j, dist = tree.pairs_within(points, radii)
    # Brute force on the positions the tree stores (float32 offsets from its origin).
    stored = tree.local.astype(np.float64)
    expected = _brute_pairs(points - tree.origin, stored, radii)
    assert set(zip(i.tolist(), j.tolist())) == expected and len(expected) > 1000
    assert np.allclose(dist, np.linalg.norm(points[i] - tree.origin - stored[j], axis=1))


def test_neighbours_far_from_the_origin_equal_those_near_it():
    """Stability: the same configuration 1e4 units away finds the same neighbours (float32
    offsets from a local origin keep the precision; raw float32 coordinates would not: their
    spacing there is 1e-3, a tenth of the smallest radius)."""
    rng = np.random.default_rng(4)
    photons, points = rng.random((3000, 3)), rng.random((200, 3))
    radii = rng.uniform(0.01, 0.1, 200)
    near = PhotonTree(photons, origin=np.zeros(3)).pairs_within(points, radii)
    shift = np.array([1e4, -1e4, 1e4])
    far = PhotonTree(photons + shift, origin=shift).pairs_within(points + shift, radii)
    assert set(zip(*near[:2])) == set(zip(*far[:2]))
    order_near, order_far = np.lexsort(near[:2]), np.lexsort(far[:2])
    assert np.allclose(near[2][order_near], far[2][order_far], atol=1e-7)


def test_grid_finds_exactly_the_kd_trees_pairs():
    """pbrt-v4's grid (the benchmark's alternative lookup) against the kd-tree, on points and
    photons on the faces of a cube with varied radii: the same pairs, so timing them compares
    like with like."""
    rng = np.random.default_rng(6)

    def on_faces(n):
        p = rng.uniform(-1, 1, (n, 3))
        axis = rng.integers(0, 3, n)
        p[np.arange(n), axis] = np.sign(p[np.arange(n), axis])
        return p

    photons, points = on_faces(5000), on_faces(2000)
    radii = rng.uniform(0.02, 0.1, 2000)
    tree = PhotonTree(photons, origin=np.zeros(3))
    i, j, _ = tree.pairs_within(points, radii)
    gi, gj, _ = PointGrid(points, radii).pairs_within(tree.local.astype(np.float64))
    assert set(zip(i.tolist(), j.tolist())) == set(zip(gi.tolist(), gj.tolist()))
    assert i.size > 1000


def test_nearest_are_the_brute_force_k_nearest():
    rng = np.random.default_rng(5)
    photons, points = rng.random((1500, 3)), rng.random((100, 3))
    dist, idx = PhotonTree(photons, origin=np.zeros(3)).nearest(points, 12)
    d = np.linalg.norm(points[:, None] - photons.astype(np.float32)[None].astype(np.float64),
                       axis=2)
    order = np.argsort(d, axis=1)[:, :12]
    assert (np.sort(idx, axis=1) == np.sort(order, axis=1)).all()
    assert np.allclose(dist, np.take_along_axis(d, order, axis=1), atol=1e-6)


@pytest.mark.parametrize("kind", KERNELS)
def test_kernel_integrates_to_one_over_the_unit_disk(kind):
    total, err = quad(lambda t: kernel_weight(kind, np.array([t]))[0] * 2 * np.pi * t, 0, 1)
    assert abs(total - 1.0) < 1e-9 and err < 1e-9
    assert kernel_weight(kind, np.array([1.0, 1.5])).tolist() == [0.0, 0.0]


def test_unknown_kernel_is_refused_by_name():
    with pytest.raises(ValueError, match="unknown kernel 'gauss'"):
        kernel_weight("gauss", np.zeros(1))


def test_photons_carry_the_light_power_and_roulette_by_albedo_keeps_each_bounce_unbiased():
    """A 100 W point light inside a closed diffuse sphere of albedo 0.5: every photon first hits
    the sphere with power 100 W exactly; the power arriving at the k-th hit, per emitted photon,
    has mean 100 * 0.5^(k - 1) (checked by a confidence interval: roulette by albedo keeps
    survivors' power and kills the rest, a wrong survival probability biases this)."""
    prep = prepare(scenes.point_in_sphere(power=100.0, albedo=0.5, subdivisions=3))
    n = 40000
    stream = make_sampler("independent", seed=2).stream(np.arange(n), np.zeros(n, np.int64))
    photons = trace_photons(prep, stream, 4, Counters())
    first = photons.take(photons.hit == 1)
    assert len(first) == n and np.allclose(first.power, 100.0, rtol=1e-5)
    assert photons.p.dtype == np.float32 and not photons.caustic.any()
    for hit in (2, 3):
        got = photons.take(photons.hit == hit)
        per_photon = np.zeros(n)
        per_photon[:len(got)] = got.power[:, 0]
        assert_mean_within_ci(per_photon, 100.0 * 0.5 ** (hit - 1), p_false=1e-5,
                              comparisons=2, what=f"power at hit {hit}")


def test_photons_stored_from_the_second_hit_are_the_same_paths_less_their_first_hits():
    """SPPM stores photons from the second hit on (``min_hit=2``): the same paths as a full
    trace of the same streams, without the hits straight from the light."""
    prep = prepare(scenes.cornell_sphere(8, 8, ball="glass", light="point"))
    sampler = make_sampler("sobol", seed=4, width=8)

    def trace(min_hit):
        stream = sampler.stream(np.arange(3000), np.full(3000, 2, np.int64))
        return trace_photons(prep, stream, 4, Counters(), min_hit)

    every, later = trace(1), trace(2)
    expected = every.take(every.hit >= 2)
    assert len(later) == len(expected) > 0 and (later.hit >= 2).all()
    for name in ("p", "wi", "power", "hit", "caustic"):
        assert np.array_equal(getattr(later, name), getattr(expected, name)), name


@pytest.mark.parametrize("n, parts", [(0, 2), (1, 2), (5, 2), (25_000, 2), (100_000, 2),
                                      (100_000, 8), (7, 16)])
def test_spans_cover_the_range_once_in_order_with_one_span_per_thread_at_least(n, parts):
    cut = spans(n, parts, most=32768)
    flat = np.concatenate([np.arange(a, b) for a, b in cut]) if cut else np.zeros(0)
    assert np.array_equal(flat, np.arange(n))
    assert all(0 < b - a <= 32768 for a, b in cut)
    assert len(cut) >= min(n, parts)


def test_photon_memory_cap_stops_a_render_with_a_message():
    with pytest.raises(ValueError, match="lower Photons or Max Bounces, or raise Photon Memory"):
        check_memory(10_000_000, 8, 1024.0)
    settings = render.RenderSettings(integrator="sppm", photons=50_000_000, spp=1)
    with pytest.raises(ValueError, match="more than the Photon Memory cap of 1,024 MB"):
        render.render(scenes.cornell_box(8, 8), settings)


def test_photon_integrators_without_scipy_stop_with_a_message_naming_it(monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "scipy" else real(name, *a))
    for integrator in ("sppm", "photon"):
        with pytest.raises(ValueError, match="need the Python module scipy"):
            render.render(scenes.cornell_box(4, 4), render.RenderSettings(integrator=integrator,
                                                                          spp=1))


def test_bench_scores_apart_the_pixels_seen_through_a_mirror_or_glass():
    """bench-photons scores the pixels seen directly apart (and checks its references per
    group: BDPT alone lacks the light seen through specular surfaces): the floor view of the mirror scene sees no mirror, the
    mirror view sees the floor through it, and the glass ball of point_mirror_glass hides a
    patch of floor that is seen through it."""
    from sampling_lab.tools.photons import SCENES, direct_pixels

    masks = {name: direct_pixels(scenes.BUILTIN[name](16, 16), SCENES[name], samples=4)
             for name in ("point_mirror", "point_mirror_seen", "point_mirror_glass")}
    assert masks["point_mirror"].all()
    assert 0.2 < masks["point_mirror_seen"].mean() < 0.8
    assert 0.5 < masks["point_mirror_glass"].mean() < 1.0
