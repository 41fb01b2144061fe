"""Anisotropic GGX conductors and specular layers (core/materials/anisotropic.py): the
isotropic limit is the existing GGX, sampling follows the pdf, the pdf integrates to the
valid-sample mass, weights are eval / pdf, single scattering is reciprocal, the rotation turns
the lobe, Cycles' roughness mappings, and the tangent frame (core/materials/frame.py)."""

from __future__ import annotations

import math
import zlib

import numpy as np
import pytest

from sampling_lab.core.materials import anisotropic as A
from sampling_lab.core.materials import bsdf as B
from sampling_lab.core.materials import conductor, layered
from sampling_lab.core.materials import microfacet as mf
from sampling_lab.core.materials.frame import shading_frame
from sampling_lab.core.scene import Materials
from tests.core.test_bsdfs import P_FALSE, _wo, chi_square_bsdf, integrate_sphere, lobe_grids
from tests.helpers import integrate_solid_angle, z_for_false_failure

N = 100_000
F0 = (0.95, 0.64, 0.54)


def _unit(rng, k, upper=False):
    w = rng.normal(size=(k, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    if upper:
        w[:, 2] = np.abs(w[:, 2])
    return w


def metal(k, roughness=0.5, scale=2.0, rotation=0.0, kind=B.KIND_CONDUCTOR):
    return B.make_params(kind, F0, roughness, k=k, aniso_scale=scale, aniso_rotation=rotation)


def test_isotropic_limit_is_the_existing_ggx():
    rng = np.random.default_rng(1)
    k = 20_000
    alpha = rng.uniform(mf.ALPHA_MIN, 1.0, k)
    m = _unit(rng, k, upper=True)
    np.testing.assert_allclose(A.ggx_d_aniso(m, alpha, alpha), mf.ggx_d(m[:, 2], alpha),
                               rtol=1e-12)
    wo, wi = _unit(rng, k), _unit(rng, k)
    f0 = rng.random((k, 3))
    for ms in (False, True):
        np.testing.assert_allclose(
            A.eval_conductor_aniso(f0, alpha, alpha, wo, wi, ms),
            conductor.eval_conductor(f0, alpha, wo, wi, multiscatter=ms), rtol=1e-12,
            atol=1e-300)
    np.testing.assert_allclose(A.pdf_conductor_aniso(alpha, alpha, wo, wi),
                               conductor.pdf_conductor(alpha, wo, wi), rtol=1e-12, atol=1e-300)
    # Samples: the same directions; near a sharp lobe's peak D is written two ways whose
    # rounding differs by up to ~1e-9 relative (1 + (a^2 - 1) c^2 against a sum of squares).
    u = rng.random((k, 2))
    for x, y in zip(A.sample_conductor_aniso(f0, alpha, alpha, wo, u),
                    conductor.sample_conductor(f0, alpha, wo, u)):
        np.testing.assert_allclose(x, y, rtol=1e-8, atol=1e-14)
    # A scale of one (any rotation) adds no columns: the very same code path.
    assert not metal(4, scale=1.0, rotation=1.0).has("aniso")
    # The specular layer with alpha_y = alpha is the isotropic layer.
    albedo, eta, tint = rng.random((k, 3)), rng.uniform(1.0, 2.5, k), rng.random((k, 3))
    for ms in (False, True):
        np.testing.assert_allclose(
            layered.eval_layered(albedo, alpha, eta, tint, wo, wi, multiscatter=ms,
                                 alpha_y=alpha),
            layered.eval_layered(albedo, alpha, eta, tint, wo, wi, multiscatter=ms),
            rtol=1e-12, atol=1e-300)
        np.testing.assert_allclose(
            layered.pdf_layered(albedo, alpha, eta, tint, wo, wi, ms, alpha_y=alpha),
            layered.pdf_layered(albedo, alpha, eta, tint, wo, wi, ms), rtol=1e-12,
            atol=1e-300)


def test_anisotropic_ndf_is_normalised():
    # int D(m) cos_m dm = 1, midpoint rule on 2048 x 512 cells (error below 1e-4 here).
    for ax, ay in ((0.2, 0.6), (0.5, 0.1), (1.0, 0.3)):
        def density(m):
            return A.ggx_d_aniso(m, np.full(len(m), ax), np.full(len(m), ay)) * m[:, 2]
        total = integrate_solid_angle(density, (0.0, 1.0), (2048, 512))
        assert abs(total - 1.0) < 2e-3, (ax, ay, total)


# (roughness, scale, rotation in radians, cos theta_o, kind)
CASES = [(0.5, 2.0, 0.0, 0.8, 1), (0.4, 0.3, 0.7, 0.5, 1), (0.7, 3.0, 2.0, 0.2, 4),
         (0.3, 1.9, -0.4, -0.6, 1), (1.0, 1.5, 0.3, 0.9, 4), (0.4, 2.5, 0.5, 0.7, 3),
         (0.6, 0.4, 1.0, 0.3, 5)]


@pytest.mark.parametrize("roughness,scale,rotation,z,kind", CASES)
def test_anisotropic_samples_follow_their_pdf(roughness, scale, rotation, z, kind):
    wo = _wo(z, phi=0.4)

    def sample(u_lobe, u):
        k = len(u_lobe)
        s = B.sample_bsdf(metal(k, roughness, scale, rotation, kind), np.tile(wo, (k, 1)),
                          u_lobe, u)
        return s.wi, s.pdf, s.delta

    def pdf(w):
        return B.pdf_bsdf(metal(len(w), roughness, scale, rotation, kind),
                          np.tile(wo, (len(w), 1)), w)

    chi_square_bsdf(sample, pdf, z, seed=zlib.crc32(f"{roughness}{scale}{z}".encode()),
                    what=f"anisotropic {roughness} x{scale} rot {rotation}")


@pytest.mark.parametrize("roughness,scale,rotation,z,kind", CASES[:3])
def test_anisotropic_pdf_integrates_to_the_probability_of_a_valid_sample(roughness, scale,
                                                                         rotation, z, kind):
    wo = _wo(z, phi=0.4)
    rng = np.random.default_rng(3)
    s = B.sample_bsdf(metal(N, roughness, scale, rotation, kind), np.tile(wo, (N, 1)),
                      rng.random(N), rng.random((N, 2)))
    frac = float(np.mean(s.pdf > 0))

    def pdf(w):
        return B.pdf_bsdf(metal(len(w), roughness, scale, rotation, kind),
                          np.tile(wo, (len(w), 1)), w)

    total, quad_err = integrate_sphere(pdf, lobe_grids(pdf, z))
    se = math.sqrt(max(frac * (1 - frac), 1.0 / N) / N)
    assert abs(total - frac) <= z_for_false_failure(P_FALSE) * se + quad_err + 1e-3


@pytest.mark.parametrize("mode", [B.RADIANCE, B.IMPORTANCE])
def test_anisotropic_sample_weight_equals_eval_over_pdf(mode):
    rng = np.random.default_rng(11)
    k = 40_000
    kind = rng.choice([B.KIND_CONDUCTOR, B.KIND_CONDUCTOR_MS, B.KIND_LAYERED, B.KIND_LAYERED_MS,
                       B.KIND_DIFFUSE], k)
    p = B.make_params(kind, rng.random((k, 3)), rng.uniform(0, 1, k), k=k,
                      aniso_scale=rng.choice([1.0, 0.2, 3.0, 10.0], k),
                      aniso_rotation=rng.uniform(-7, 7, k))
    wo = _unit(rng, k)
    s = B.sample_bsdf(p, wo, rng.random(k), rng.random((k, 2)), mode)
    assert np.all(np.isfinite(s.weight)) and np.all(s.weight >= 0)
    live = (s.pdf > 0) & ~s.delta
    assert live.mean() > 0.5 and A.aniso_rows(p.take(live)).size > 0.3 * k
    q = p.take(live)
    f = B.eval_bsdf(q, wo[live], s.wi[live], mode)
    pdf = B.pdf_bsdf(q, wo[live], s.wi[live])
    np.testing.assert_allclose(pdf, s.pdf[live], rtol=1e-7)
    np.testing.assert_allclose(s.weight[live], f / pdf[:, None], rtol=1e-7, atol=1e-12)
    assert np.all(s.weight[s.pdf == 0] == 0) and np.all(s.wi[s.pdf == 0] == 0)


def test_single_scattering_anisotropic_lobe_is_reciprocal_and_multiscatter_uses_the_mean():
    rng = np.random.default_rng(5)
    k = 20_000
    p = metal(k, rng.uniform(0.05, 1.0, k), rng.choice([0.3, 2.5], k), rng.uniform(0, 6, k))
    wo, wi = _unit(rng, k, upper=True), _unit(rng, k, upper=True)

    def f(a, b, params=p):
        return B.eval_bsdf(params, a, b) / np.abs(b[:, 2])[:, None]

    np.testing.assert_allclose(f(wo, wi), f(wi, wo), rtol=1e-9, atol=1e-300)
    # Multiscatter: Cycles' compensation at the geometric mean sqrt(ax ay), a factor of wo.
    ms = metal(k, p.alpha ** 0.5, p.aniso_scale, p.aniso_rotation, B.KIND_CONDUCTOR_MS)
    ax, ay = A.alphas(p.alpha, p.aniso_scale)
    factor = conductor.multiscatter_factor(p.color, np.sqrt(ax * ay), wo, wi)
    np.testing.assert_allclose(B.eval_bsdf(ms, wo, wi), B.eval_bsdf(p, wo, wi) * factor,
                               rtol=1e-9, atol=1e-300)


def test_rotation_turns_the_lobe_about_the_normal():
    rng = np.random.default_rng(6)
    k = 5000
    wo, wi = _unit(rng, k, upper=True), _unit(rng, k, upper=True)
    theta = 0.9

    def turn(w, a):
        c, s = math.cos(a), math.sin(a)
        return np.stack([c * w[:, 0] - s * w[:, 1], s * w[:, 0] + c * w[:, 1], w[:, 2]], 1)

    base = B.eval_bsdf(metal(k, 0.5, 2.5), wo, wi)
    turned = B.eval_bsdf(metal(k, 0.5, 2.5, theta), turn(wo, theta), turn(wi, theta))
    np.testing.assert_allclose(turned, base, rtol=1e-9, atol=1e-300)
    # A quarter turn swaps the axes (scale k <-> 1 / k); half a turn changes nothing.
    np.testing.assert_allclose(B.eval_bsdf(metal(k, 0.5, 2.5, np.pi / 2), wo, wi),
                               B.eval_bsdf(metal(k, 0.5, 1 / 2.5), wo, wi), rtol=1e-9,
                               atol=1e-300)
    np.testing.assert_allclose(B.eval_bsdf(metal(k, 0.5, 2.5, np.pi), wo, wi), base, rtol=1e-9,
                               atol=1e-300)
    assert not np.allclose(B.eval_bsdf(metal(k, 0.5, 2.5, 0.5), wo, wi), base, rtol=1e-3)


def test_roughness_mappings_are_cycles():
    # Principled: ax = alpha / sqrt(1 - 0.9 a), ay = alpha sqrt(1 - 0.9 a).
    np.testing.assert_allclose(A.principled_scale([0.0, 0.5, 1.0, 2.0]),
                               [1.0, 1 / math.sqrt(0.55), 1 / math.sqrt(0.1),
                                1 / math.sqrt(0.1)])
    # Glossy: ax = alpha (1 - a), ay = alpha / (1 - a); negative a the other way round.
    np.testing.assert_allclose(A.glossy_scale([0.0, 0.5, -0.5, 1.0]), [1.0, 0.5, 2.0, 0.01])
    ax, ay = A.alphas(np.array([0.25, 0.81]), np.array([2.0, 2.0]))
    np.testing.assert_allclose(ax, [0.5, 1.0])    # clamped to 1, as Cycles' setup
    np.testing.assert_allclose(ay, [0.125, 0.405])


def test_material_table_anisotropy_reaches_conductor_and_specular_layer_rows_only():
    mats = Materials.from_lists(["a", "b", "c", "d"], [(0.5,) * 3] * 4, [(0,) * 3] * 4,
                                kinds=[1, 3, 1, 2], aniso_scale=[2.0, 2.0, 1.0, 2.0],
                                aniso_rotation=[0.25, 0.25, 0.25, 0.25])
    p = B.BSDFParams.from_materials(mats, np.array([0, 1, 2, 3]))
    np.testing.assert_allclose(p.aniso_scale, [2.0, 2.0, 1.0, 1.0])
    np.testing.assert_allclose(p.aniso_rotation, [np.pi / 2, np.pi / 2, 0.0, 0.0])


def test_tangent_frame_follows_the_projected_tangent():
    rng = np.random.default_rng(7)
    k = 1000
    n = _unit(rng, k)
    tangent = rng.normal(size=(k, 3))
    tangent[:3] = n[:3] * 2.0        # parallel to the normal: the default frame instead
    tangent[3] = 0.0
    s, t, nn = shading_frame(n, tangent)
    for a, b in ((s, t), (t, nn), (s, nn)):
        np.testing.assert_allclose(np.einsum("ij,ij->i", a, b), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.cross(s, t), nn, atol=1e-12)
    proj = (tangent - np.einsum("ij,ij->i", tangent, n)[:, None] * n)[4:]
    proj /= np.linalg.norm(proj, axis=1, keepdims=True)
    np.testing.assert_allclose(s[4:], proj, atol=1e-12)
    s0, t0, _ = shading_frame(n[:4])
    np.testing.assert_allclose(s[:4], s0, atol=1e-12)


def test_hit_tangents_interpolate_the_corner_tangents_at_the_hit_point():
    # shading_tangents recovers the hit's barycentrics from its position (after the prepared
    # scene's recentring) and interpolates the scene's corner tangents with them.
    import dataclasses
    from types import SimpleNamespace

    from sampling_lab.core import scenes
    from sampling_lab.core.integrators.common import shading_tangents
    from sampling_lab.core.prepare import prepare

    scene = scenes.cornell_sphere(8, 8, "mirror", "area", light_radius=0.15, roughness=0.5)
    rng = np.random.default_rng(9)
    corners = rng.normal(size=(scene.triangles.shape[0], 3, 3)).astype(np.float32)
    prep = prepare(dataclasses.replace(scene, aniso_tangents=corners))
    k = 2000
    prim = rng.integers(0, scene.triangles.shape[0], k)
    u = rng.random(k)
    v = rng.random(k) * (1.0 - u)
    p = (prep.tri_v0[prim] + u[:, None] * prep.tri_e1[prim]
         + v[:, None] * prep.tri_e2[prim]).astype(np.float64)
    t = shading_tangents(prep, SimpleNamespace(p=p, prim=prim))
    c = corners[prim].astype(np.float64)
    expect = (1 - u - v)[:, None] * c[:, 0] + u[:, None] * c[:, 1] + v[:, None] * c[:, 2]
    # Float32 vertices: the recovered barycentrics are exact to about 1e-6.
    np.testing.assert_allclose(t, expect, atol=2e-5)
    assert shading_tangents(prepare(scene), SimpleNamespace(p=p, prim=prim)) is None
