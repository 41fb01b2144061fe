"""Accel.intersect and Accel.occluded return exactly what Embree answers for the rays rounded to
float32 (the wrapper only converts): prim, t, u, v of each closest hit, misses as -1 / inf,
visibility-class scenes mapped back to the scene's triangle rows, and inf or scalar ray lengths."""

import numpy as np

from sampling_lab.core import scenes
from sampling_lab.core.accel import Accel, ray_lengths
from sampling_lab.core.scene import VIS_ALL, VIS_CAMERA


def _rays(scene, n=500, seed=3):
    rng = np.random.default_rng(seed)
    lo, hi = scene.vertices.min(0), scene.vertices.max(0)
    o = lo + (hi - lo) * (0.05 + 0.9 * rng.random((n, 3)))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    return o, d, rng.random(n) * 2.0


def _reference(accel, o, d, tmax, mask):
    """Closest hits straight from embreex, in the scene's triangle rows."""
    scene, rows, _ = accel._scene_for(mask)
    dists = np.minimum(tmax, 3e38).astype(np.float32)
    out = scene.run(o.astype(np.float32), d.astype(np.float32), dists=dists, output=1)
    prim = out["primID"]
    hit = prim >= 0
    if rows is not None:
        prim = np.where(hit, rows[np.maximum(prim, 0)], -1)
    return prim, np.where(hit, out["tfar"].astype(np.float64), np.inf), out["u"], out["v"], hit


def _check_same_hits(accel, o, d, tmax, mask):
    h = accel.intersect(o, d, tmax, mask=mask)
    prim, t, u, v, hit = _reference(accel, o, d, tmax, mask)
    assert h.prim.dtype == np.int32 and h.t.dtype == h.u.dtype == h.v.dtype == np.float64
    np.testing.assert_array_equal(h.prim, prim)
    np.testing.assert_array_equal(h.t, t)
    np.testing.assert_array_equal(h.u[hit], u[hit])
    np.testing.assert_array_equal(h.v[hit], v[hit])
    return h


def test_intersect_returns_embree_hits_exactly():
    scene = scenes.cornell_box(16, 16, light="mesh")
    accel = Accel(scene.vertices, scene.triangles, scene.visibility)
    o, d, tmax = _rays(scene)
    h = _check_same_hits(accel, o, d, tmax, VIS_ALL)
    assert 0 < h.hit.sum() < len(o)  # both hits and misses were compared
    h = _check_same_hits(accel, o, d, np.full(len(o), np.inf), VIS_ALL)
    assert h.hit.mean() > 0.5  # unbounded rays inside the box (open at the front) mostly hit


def test_intersect_maps_visibility_scene_rows_back():
    scene = scenes.cornell_box(16, 16, light="mesh")
    vis = np.full(len(scene.triangles), VIS_ALL, np.int32)
    vis[::3] &= ~VIS_CAMERA
    accel = Accel(scene.vertices, scene.triangles, vis)
    o, d, _ = _rays(scene)
    h = _check_same_hits(accel, o, d, np.full(len(o), np.inf), VIS_CAMERA)
    assert h.hit.any() and not np.any(h.prim[h.hit] % 3 == 0)


def test_occluded_matches_embree_and_takes_scalar_lengths():
    scene = scenes.cornell_box(16, 16, light="mesh")
    accel = Accel(scene.vertices, scene.triangles, scene.visibility)
    o, d, tmax = _rays(scene)
    scene_all, _, _ = accel._scene_for(VIS_ALL)
    raw = scene_all.run(o.astype(np.float32), d.astype(np.float32),
                        dists=tmax.astype(np.float32), query="OCCLUDED") != -1
    blocked = accel.occluded(o, d, tmax)
    np.testing.assert_array_equal(blocked, raw)
    assert 0 < blocked.sum() < len(o)
    np.testing.assert_array_equal(accel.occluded(o, d, 0.5),
                                  accel.occluded(o, d, np.full(len(o), 0.5)))


def test_ray_lengths_cap_inf_like_float64_then_float32():
    t = np.array([0.0, 1.5, 1e-30, 1e300, np.inf, 2.0 ** -130])
    got = ray_lengths(t, len(t))
    assert got.dtype == np.float32 and np.all(np.isfinite(got))
    np.testing.assert_array_equal(got, np.minimum(t, 3e38).astype(np.float32))
