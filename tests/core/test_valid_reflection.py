"""Shading normals bent for valid reflections (Cycles' ensure_valid_specular_reflection):
the bent normal's mirror reflection rises just above the geometry, the bend is the smallest in
the plane of the two normals, and a smooth low-poly mirror ball loses no reflection to the
geometric-side rule (it lost some before: black rims)."""

import numpy as np

from sampling_lab.core import scenes
from sampling_lab.core.camera import generate_rays
from sampling_lab.core.integrators.common import (geometric_side_valid, surface_interaction,
                                                  valid_reflection_normals)
from sampling_lab.core.prepare import prepare


def _unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _reflect(wo, n):
    return 2.0 * np.einsum("ij,ij->i", wo, n)[:, None] * n - wo


def _random_configurations(k=20000, seed=3):
    """Geometric normals, viewer directions above them and shading normals tilted up to 60
    degrees toward the viewer's side (many of whose reflections dip below the surface)."""
    rng = np.random.default_rng(seed)
    ng = _unit(rng.normal(size=(k, 3)))
    wo = _unit(rng.normal(size=(k, 3)))
    wo *= np.where(np.einsum("ij,ij->i", wo, ng) < 0, -1.0, 1.0)[:, None]
    tilt = _unit(rng.normal(size=(k, 3)))
    ns = _unit(ng + rng.uniform(0, 1.7, (k, 1)) * tilt)
    ns *= np.where(np.einsum("ij,ij->i", ns, ng) < 0, -1.0, 1.0)[:, None]
    keep = np.einsum("ij,ij->i", ns, wo) > 0  # as Interaction.ns guarantees
    return ng[keep], wo[keep], ns[keep]


def test_bent_normals_reflect_just_above_the_surface_and_keep_valid_ones():
    ng, wo, ns = _random_configurations()
    out = valid_reflection_normals(ng, wo, ns)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-12)
    t = np.minimum(0.9 * np.einsum("ij,ij->i", wo, ng), 0.01)
    height = np.einsum("ij,ij->i", _reflect(wo, ns), ng)
    valid = height >= t
    assert 0.05 < (~valid).mean() < 0.95  # both cases are exercised
    np.testing.assert_array_equal(out[valid], ns[valid])
    bent = ~valid
    # The bent reflection rises exactly t above the geometry ...
    np.testing.assert_allclose(np.einsum("ij,ij->i", _reflect(wo[bent], out[bent]), ng[bent]),
                               t[bent], atol=1e-9)
    # ... and the bent normal lies in the plane of ns and ng, on the viewer's side.
    plane = np.einsum("ij,ij->i", out[bent], np.cross(ns[bent], ng[bent]))
    np.testing.assert_allclose(plane, 0.0, atol=1e-9)
    assert (np.einsum("ij,ij->i", out[bent], ng[bent]) > 0).all()


def test_bend_is_the_smaller_of_the_two_solutions():
    ng, wo, ns = _random_configurations(seed=5)
    out = valid_reflection_normals(ng, wo, ns)
    bent = np.nonzero(np.any(out != ns, axis=1))[0]
    # The other normal with the same reflection height: the half vector of wo and the other
    # in-plane reflection (tangent component of the reflection mirrored).
    g, w, n, o = ng[bent], wo[bent], ns[bent], out[bent]
    x = _unit(n - np.einsum("ij,ij->i", n, g)[:, None] * g)
    r = _reflect(w, o)
    other_r = r - 2.0 * np.einsum("ij,ij->i", r, x)[:, None] * x
    other = _unit(other_r + w)
    cos_out = np.einsum("ij,ij->i", o, n)
    cos_other = np.einsum("ij,ij->i", other, n)
    assert (cos_out >= cos_other - 1e-12).all()


def test_smooth_low_poly_mirror_ball_keeps_every_camera_reflection():
    # An icosahedron-based ball (subdivision 1) with the sphere's normals: its shading normals
    # differ from the facets by up to ~20 degrees. Camera rays that hit it must reflect to the
    # geometric outside with the bent normals; with the interpolated ones, some do not.
    scene = scenes.cornell_sphere(96, 96, ball="mirror", light="area", subdivisions=1,
                                  smooth=True)
    prep = prepare(scene)
    xy = np.stack(np.meshgrid(np.arange(96) + 0.5, np.arange(96) + 0.5), -1).reshape(-1, 2)
    o, d, tmax = generate_rays(prep.scene.camera, xy)
    hits = prep.accel.intersect(o, d, tmax)
    ball = np.nonzero(hits.hit & (prep.tri_material[np.maximum(hits.prim, 0)] == 3))[0]
    si = surface_interaction(prep, hits, d, ball)
    before = geometric_side_valid(si.ng, si.wo, _reflect(si.wo, si.ns), False)
    after = geometric_side_valid(si.ng, si.wo,
                                 _reflect(si.wo, valid_reflection_normals(si.ng, si.wo, si.ns)),
                                 False)
    assert ball.size > 500
    assert (~before).sum() > 10, "the scene no longer has invalid reflections to fix"
    assert after.all()
