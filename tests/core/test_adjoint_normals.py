"""Light paths read the shading normal as the camera side chooses it: by the direction toward
the camera (:mod:`sampling_lab.core.integrators.adjoint_normals`)."""

import numpy as np
import pytest

from sampling_lab.core import lights as L
from sampling_lab.core.integrators.adjoint_normals import VertexNormals, mixture_share
from sampling_lab.core.integrators.common import geometric_side_valid, view_fallback
from sampling_lab.core.materials.bsdf import (KIND_CONDUCTOR, KIND_DIELECTRIC, KIND_DIFFUSE,
                                              KIND_LAYERED, RADIANCE, eval_bsdf, make_params,
                                              pdf_bsdf)
from sampling_lab.core.materials.frame import shading_frame, to_local
from sampling_lab.core.render import render
from sampling_lab.core.scene import Camera, Materials, Scene
from tests.core.test_normal_maps import with_normal_map
from tests.helpers import assert_replicates_agree, plain_settings

ALBEDO, IRRADIANCE, TILT = 0.8, 3.0, 60.0


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def tilted_plane(toward_sun):
    """A diffuse plane z = 0 whose normal map tilts 60 degrees toward +X, under a sun, seen
    from 1 m above by a wide lens (half-angle 61 degrees): the pixels right of x = cot 60 see
    the plane from below its mapped normal."""
    # Just wider than the view (x, y in [-1.8, 1.8]): the sun's light paths start over it.
    v = np.array([(-2.5, -2.5, 0), (2.5, -2.5, 0), (2.5, 2.5, 0), (-2.5, 2.5, 0)], np.float32)
    mats = Materials.from_lists(["White"], [(ALBEDO,) * 3], [(0, 0, 0)],
                                bump_correction=[False])
    to_world = np.eye(4)
    to_world[2, 3] = 1.0
    w = unit(np.asarray(toward_sun, np.float64))
    scene = Scene(v, [(0, 1, 2), (0, 2, 3)], [0, 0], mats,
                  L.sun_light(-w, (1, 1, 1), IRRADIANCE), Camera(to_world, 16, 16, lens=10.0))
    t = np.radians(TILT)
    color = tuple(0.5 * (np.array([np.sin(t), 0.0, np.cos(t)]) + 1.0))
    return with_normal_map(scene, [0], color), w


@pytest.mark.parametrize("toward_sun", [(1.0, 0.0, 1.0), (-1.0, 0.0, 1.0)],
                         ids=["sun above the mapped normal", "sun below the mapped normal"])
def test_light_tracing_shades_a_tilted_map_as_the_camera_side_does(toward_sun):
    """One bounce of a sun on the plane. The path tracer's image is exact here (a delta sun:
    every sample is rho E |l . N| / pi with N the mapped normal where the view sees the plane
    above it and ng elsewhere); light tracing must agree with it. Choosing the normal by the
    sun's direction made the right-hand columns black (sun above the mapped normal: 0 where
    the closed form is 0.71 rho E / pi) or lit the left ones (sun below it: 0.74 where it is
    0), so that check failed by more than 70 % per block."""
    scene, w = tilted_plane(toward_sun)
    exact = render(scene, plain_settings(spp=4, max_bounces=0, seed=1)).film.mean()
    t = np.radians(TILT)
    n = np.array([np.sin(t), 0.0, np.cos(t)])
    scale = ALBEDO * IRRADIANCE / np.pi
    # The closed form on columns away from the switch (x = cot 60 lies in column 10).
    np.testing.assert_allclose(exact[:, :6, 0], scale * max(w @ n, 0.0), rtol=1e-4)
    np.testing.assert_allclose(exact[:, 12:, 0], scale * w[2], rtol=1e-4)
    imgs = np.stack([render(scene, plain_settings(integrator="light", spp=64, max_bounces=0,
                                                  seed=11 + 1000 * i)).film.mean()
                     for i in range(16)])
    # Detects 9 % image-mean and 14 % 8x8-block errors with 99 % power (the checker asserts
    # it; the exact reference has no variance, the blocks all of light tracing's).
    # Columns where the pixel filter stays on one side of the switch; the black ones must
    # stay black, the others agree.
    sides = np.zeros(exact.shape[:2], bool)
    sides[:, :6] = sides[:, 12:] = True
    black = sides & (exact.sum(-1) == 0)
    assert not np.any(imgs[:, black] > 0)
    assert_replicates_agree(imgs, np.stack([exact, exact]), mask=sides & ~black,
                            detect=(0.09, 0.14), what="light tracing vs the exact plane")


def random_dirs(rng, k, z_min=-1.0):
    d = unit(rng.normal(size=(k, 3)))
    d[:, 2] = np.maximum(d[:, 2], z_min)
    return unit(d)


def vertex(kind, k, tilt_deg=40.0, **kw):
    """``k`` hits of a BSDF ``kind`` on a plane (ng = +Z) whose shading normal tilts toward +X,
    stored in the frame of the mapped normal."""
    t = np.radians(tilt_deg)
    ng = np.tile([0.0, 0.0, 1.0], (k, 1))
    nm = np.tile([np.sin(t), 0.0, np.cos(t)], (k, 1))
    params = make_params(np.full(k, kind), (0.7, 0.5, 0.3), roughness=0.5, k=k, **kw)
    return VertexNormals(params, shading_frame(nm), ng, nm), params


@pytest.mark.parametrize("kind", [KIND_DIFFUSE, KIND_CONDUCTOR, KIND_LAYERED, KIND_DIELECTRIC])
def test_light_side_bsdf_is_the_adjoint_of_the_camera_side(kind):
    """``f_light(wl -> wc) |wl . ng| / |wc . ng| == f_camera(wc -> wl)`` for every pair of
    directions, the camera side shading with ``N(wc)`` (its view fallback) and the
    geometric-side rule: the two sides see one BSDF. With the normal chosen by ``wl`` the
    two differ on the pairs where ``wl`` and ``wc`` pick different normals (a third here)."""
    rng = np.random.default_rng(3)
    k = 4000
    normals, params = vertex(kind, k)
    wl, wc = random_dirs(rng, k), random_dirs(rng, k)
    light = normals.f_importance(wl, wc) * (np.abs(wl[:, 2]) / np.abs(wc[:, 2]))[:, None]
    n = view_fallback(normals.nm, normals.ng, wc)
    frame = shading_frame(n)
    wc_l, wl_l = to_local(wc, *frame), to_local(wl, *frame)
    camera = eval_bsdf(params, wc_l, wl_l, RADIANCE)
    camera *= geometric_side_valid(normals.ng, wc, wl, wc_l[:, 2] * wl_l[:, 2] < 0)[:, None]
    np.testing.assert_allclose(light, camera, rtol=1e-9, atol=1e-12)
    # The camera side's density, as BDPT's MIS reads it at a light vertex, is the one the
    # camera walk samples with (its frame is N(wc)).
    np.testing.assert_allclose(normals.pdf_camera(wc, wl), pdf_bsdf(params, wc_l, wl_l),
                               rtol=1e-12)
    assert np.count_nonzero(camera.sum(1)) > k // 10
    picks_differ = view_fallback(normals.nm, normals.ng, wl)[:, 0] != n[:, 0]
    assert picks_differ.mean() > 0.2


@pytest.mark.parametrize("kind", [KIND_DIFFUSE, KIND_LAYERED, KIND_DIELECTRIC])
@pytest.mark.parametrize("wl", [(0.5, 0.0, 0.866), (-0.9, 0.0, 0.436)],
                         ids=["light above nm", "light below nm"])
def test_light_side_sampling_weights_integrate_the_light_side_bsdf(kind, wl):
    """The mean sampled weight equals the integral of ``f_light(wl -> .)`` over the sphere
    (uniform directions), and the sampled pdf is the mixture :meth:`pdf_light`: the mixture
    covers the wedge between the two normals, where the frame of ``nm`` alone samples
    nothing (measured: sampling in ``nm``'s frame only reads 0.702 for the diffuse row with
    the light above nm, where the integral is 0.787: the wedge holds 10 % of it; the
    interval, 5 standard errors of the difference, is 2.2 % of it there)."""
    rng = np.random.default_rng(8)
    k = 100_000
    normals, _ = vertex(kind, k)
    wl = np.tile(unit(np.array(wl)), (k, 1))
    wc, weight, pdf, delta, _ = normals.sample_importance(wl, rng.random(k), rng.random((k, 2)))
    ok = ~delta & (pdf > 0)
    np.testing.assert_allclose(pdf[ok], normals.take(np.nonzero(ok)[0]).pdf_light(
        wl[ok], wc[ok]), rtol=1e-9)
    sampled = np.where(ok[:, None], weight, 0.0)
    u = random_dirs(rng, k)
    uniform = normals.f_importance(wl, u) * 4.0 * np.pi
    for a, b in ((sampled, uniform),):
        diff = a.mean(0) - b.mean(0)
        se = np.sqrt(a.var(0) / k + b.var(0) / k)
        assert np.all(np.abs(diff) < 5.0 * se + 1e-12), (a.mean(0), b.mean(0), se)
    assert uniform.mean(0)[0] > 0.05


def test_mixture_share_is_zero_where_the_normals_agree():
    ng = np.tile([0.0, 0.0, 1.0], (3, 1))
    nm = unit(np.array([[0.0, 0.0, 1.0], [0.1, 0.0, 1.0], [1.0, 0.0, 0.2]]))
    q = mixture_share(nm, ng)
    assert q[0] == 0.0 and 0.0 < q[1] < 0.5 and q[2] == 0.5
