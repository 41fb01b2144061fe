"""The photon lookups' surface-compatibility test (core/photons/compatible.py): it keeps every
photon of the looked-up surface (flat or gently curved) and drops only those of other
surfaces, on synthetic configurations and on photons traced in the Cornell box."""

from __future__ import annotations

import numpy as np

from sampling_lab.core import scenes
from sampling_lab.core.integrators.base import Counters
from sampling_lab.core.film import PixelFilter
from sampling_lab.core.photons.compatible import MAX_ANGLE, compatible
from sampling_lab.core.photons.lookup import PhotonTree
from sampling_lab.core.photons.tracing import trace_photons
from sampling_lab.core.photons.visible import trace_visible_points
from sampling_lab.core.prepare import prepare
from sampling_lab.core.render import render
from sampling_lab.core.sampling.samplers import make_sampler
from tests.helpers import plain_settings


def _pairs_in_ball(points, photons, r):
    """Every (point, photon) pair closer than ``r``, by brute force."""
    d = np.linalg.norm(points[:, None, :] - photons[None, :, :], axis=-1)
    return np.nonzero(d < r)


def test_on_a_flat_floor_the_surface_test_keeps_every_photon_in_the_disk():
    rng = np.random.default_rng(1)
    pts = np.c_[rng.uniform(-1, 1, (200, 2)), np.zeros(200)]
    phs = np.c_[rng.uniform(-1, 1, (4000, 2)), np.zeros(4000)]
    up = np.array([0.0, 0.0, 1.0])
    i, j = _pairs_in_ball(pts, phs, 0.1)
    # Either side of the normal: a photon may land on the floor from below (thin surfaces).
    sign = rng.choice([-1.0, 1.0], j.size)[:, None]
    keep = compatible(pts[i], np.broadcast_to(up, (i.size, 3)), phs[j], sign * up,
                      np.full(i.size, 0.1))
    assert i.size > 1000 and keep.all()


def test_at_a_corner_the_surface_test_drops_exactly_the_other_wall():
    """Floor z = 0 and wall x = 0 meet at a corner; floor points within ``r`` of it find
    photons on both. The test keeps every floor photon and no wall photon (a wall photon's
    plane offset, its height, is up to ``r``; its normal is 90 degrees off)."""
    rng = np.random.default_rng(2)
    r = 0.1
    pts = np.c_[rng.uniform(0, r, 300), rng.uniform(-1, 1, 300), np.zeros(300)]
    floor = np.c_[rng.uniform(0, 1, 3000), rng.uniform(-1, 1, 3000), np.zeros(3000)]
    wall = np.c_[np.zeros(3000), rng.uniform(-1, 1, 3000), rng.uniform(0, 1, 3000)]
    phs = np.r_[floor, wall]
    normals = np.r_[np.tile([0.0, 0.0, 1.0], (3000, 1)), np.tile([1.0, 0.0, 0.0], (3000, 1))]
    i, j = _pairs_in_ball(pts, phs, r)
    keep = compatible(pts[i], np.tile([0.0, 0.0, 1.0], (i.size, 1)), phs[j], normals[j],
                      np.full(i.size, r))
    on_floor = j < 3000
    assert on_floor.sum() > 1000 and (~on_floor).sum() > 1000
    np.testing.assert_array_equal(keep, on_floor)


def test_on_a_sphere_the_surface_test_keeps_every_photon_while_the_radius_is_small():
    """On a sphere of radius R every photon within r <= R sin(MAX_ANGLE) of a point passes
    (normal within MAX_ANGLE, offset within r tan(MAX_ANGLE / 2)): the test removes nothing
    from a smooth surface once the radius is small, so SPPM stays consistent; beyond that
    radius it starts dropping the far ones."""
    rng = np.random.default_rng(3)
    on_sphere = rng.normal(size=(20000, 3))
    on_sphere /= np.linalg.norm(on_sphere, axis=1, keepdims=True)
    pts, phs = on_sphere[:200], on_sphere[200:]
    for r, all_kept in ((0.999 * np.sin(MAX_ANGLE), True), (1.0, False)):
        i, j = _pairs_in_ball(pts, phs, r)
        keep = compatible(pts[i], pts[i], phs[j], phs[j], np.full(i.size, r))
        assert keep.all() == all_kept, r


def test_on_traced_cornell_photons_the_surface_test_keeps_the_same_planes_pairs():
    """Real photons and visible points in the Cornell box (axis-aligned walls, rotated
    blocks): within SPPM's lookup radius, the kept pairs are exactly those whose photon lies
    on the visible point's own plane (same normal up to sign, offset below 2 mm: the ceiling
    lamp's quad hangs 1 mm below the ceiling and counts as the ceiling's surface)."""
    scene = scenes.cornell_box(32, 32)
    prep = prepare(scene)
    n = 32 * 32
    sampler = make_sampler("independent", seed=5)
    points = trace_visible_points(prep, sampler.stream(np.arange(n), np.zeros(n, np.int64)),
                                  PixelFilter("box", 1.0), 4, Counters(), np.zeros((n, 3)))
    photons = trace_photons(prep, sampler.stream(np.arange(50_000), np.ones(50_000, np.int64)),
                            4, Counters())
    r = 0.08
    i, j, _ = PhotonTree(photons.p, origin=np.zeros(3)).pairs_within(points.p,
                                                                     np.full(points.rows.size, r))
    keep = compatible(points.p[i], points.ng[i], photons.p[j], photons.n[j], np.full(i.size, r))
    n_p, n_x = photons.n[j].astype(np.float64), points.ng[i]
    offset = np.einsum("ij,ij->i", n_x, photons.p[j] - points.p[i])
    same_plane = (np.abs(np.einsum("ij,ij->i", n_p, n_x)) > 1 - 1e-5) & (np.abs(offset) < 2e-3)
    assert same_plane.sum() > 10_000 and (~same_plane).sum() > 100
    np.testing.assert_array_equal(keep, same_plane)


def test_sppm_image_on_a_floor_alone_is_the_same_with_and_without_the_surface_test():
    """The mirror scene's photons land on one flat floor: the surface test must change
    nothing (bit for bit), so it drops no photon of the looked-up surface."""
    scene = scenes.mirror_point_light(24, 24)
    images = [render(scene, plain_settings(integrator="sppm", spp=3, photons=20_000,
                                           max_bounces=1, seed=4, threads=1,
                                           photon_surface_test=flag)).film.mean()
              for flag in (False, True)]
    assert images[0].sum() > 0
    np.testing.assert_array_equal(images[0], images[1])
