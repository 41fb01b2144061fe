"""The Principled BSDF's layers: the coat over every base kind (core/materials/coat.py) --
sampling follows the pdf, weights are eval / pdf, the layering is Cycles', white furnaces, the
adjoint -- and the specular layer's Specular Tint (core/materials/layered.py)."""

from __future__ import annotations

import math
import zlib

import numpy as np
import pytest

from sampling_lab.core.materials import bsdf as B
from sampling_lab.core.materials.coat import coat_attenuation
from sampling_lab.core.materials.fresnel import fresnel_dielectric
from sampling_lab.core.scene import Materials
from tests.core.test_bsdfs import P_FALSE, _wo, chi_square_bsdf, integrate_sphere, lobe_grids
from tests.helpers import assert_mean_within_ci, z_for_false_failure

N = 100_000
# (base kind, base roughness, base colour) under a coat of weight 0.8, tint (0.9, 0.6, 0.4).
BASES = {
    "diffuse": (B.KIND_DIFFUSE, 0.5, 0.7),
    "layered": (B.KIND_LAYERED, 0.4, 0.5),
    "metal": (B.KIND_CONDUCTOR, 0.3, 0.9),
    "mirror": (B.KIND_CONDUCTOR, 0.0, 0.9),
    "glass": (B.KIND_DIELECTRIC, 0.5, 1.0),
    "metal_ms": (B.KIND_CONDUCTOR_MS, 0.6, 0.9),
}
TINT = (0.9, 0.6, 0.4)


def coated(base, k, coat_roughness=0.2, coat_weight=0.8, coat_ior=1.6, tint=TINT):
    kind, roughness, color = BASES[base]
    return B.make_params(kind, color, roughness, 1.5, k=k, coat_weight=coat_weight,
                         coat_roughness=coat_roughness, coat_ior=coat_ior, coat_tint=tint)


# Every base under a rough and a smooth coat (a smooth coat over a mirror has no non-delta
# samples), a grazing view, and glass seen from inside.
CASES = ([(b, r, 0.8) for b in BASES for r in (0.0, 0.2) if (b, r) != ("mirror", 0.0)]
         + [("diffuse", 0.2, 0.1), ("metal", 0.0, 0.1), ("glass", 0.2, -0.6),
            ("glass", 0.0, -0.6)])
MASS_CASES = [("diffuse", 0.2, 0.8), ("metal", 0.0, 0.8), ("mirror", 0.2, 0.8),
              ("layered", 0.2, 0.8), ("glass", 0.2, -0.6)]


@pytest.mark.parametrize("base,coat_roughness,z", CASES)
def test_coated_samples_follow_their_pdf(base, coat_roughness, z):
    wo = _wo(z)
    eta = 1.5 if BASES[base][0] == B.KIND_DIELECTRIC else None

    def sample(u_lobe, u):
        k = len(u_lobe)
        s = B.sample_bsdf(coated(base, k, coat_roughness), np.tile(wo, (k, 1)), u_lobe, u)
        return s.wi, s.pdf, s.delta

    def pdf(w):
        return B.pdf_bsdf(coated(base, len(w), coat_roughness), np.tile(wo, (len(w), 1)), w)

    chi_square_bsdf(sample, pdf, z, eta, seed=zlib.crc32(f"{base}{coat_roughness}{z}".encode()),
                    what=f"coat {coat_roughness} over {base}")


@pytest.mark.parametrize("base,coat_roughness,z", MASS_CASES)
def test_coated_pdf_integrates_to_the_probability_of_a_non_delta_sample(base, coat_roughness,
                                                                         z):
    wo = _wo(z)
    eta = 1.5 if BASES[base][0] == B.KIND_DIELECTRIC else None
    rng = np.random.default_rng(3)
    s = B.sample_bsdf(coated(base, N, coat_roughness), np.tile(wo, (N, 1)), rng.random(N),
                      rng.random((N, 2)))
    frac = float(np.mean((s.pdf > 0) & ~s.delta))

    def pdf(w):
        return B.pdf_bsdf(coated(base, len(w), coat_roughness), np.tile(wo, (len(w), 1)), w)

    total, quad_err = integrate_sphere(pdf, lobe_grids(pdf, z, eta))
    se = math.sqrt(max(frac * (1 - frac), 1.0 / N) / N)
    assert abs(total - frac) <= z_for_false_failure(P_FALSE) * se + quad_err + 1e-6


@pytest.mark.parametrize("mode", [B.RADIANCE, B.IMPORTANCE])
def test_coated_sample_weight_equals_eval_over_pdf(mode):
    rng = np.random.default_rng(11)
    k = 60_000
    kind = rng.choice(B.KINDS, k)
    params = B.make_params(kind, rng.random((k, 3)), rng.uniform(0, 1, k),
                           rng.uniform(1.0, 2.5, k), tint=rng.random((k, 3)),
                           coat_weight=rng.uniform(-0.2, 1.0, k),
                           coat_roughness=rng.choice([0.0, 0.05, 0.5, 1.0], k),
                           coat_ior=rng.uniform(1.0, 2.5, k), coat_tint=rng.random((k, 3)))
    assert 0.6 < np.mean(params.coat_weight > 0) < 0.9
    wo = rng.normal(size=(k, 3))
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    s = B.sample_bsdf(params, wo, rng.random(k), rng.random((k, 2)), mode)
    assert np.all(np.isfinite(s.weight)) and np.all(s.weight >= 0)
    live = (s.pdf > 0) & ~s.delta
    assert live.mean() > 0.5 and (s.delta & (params.coat_weight > 0)).any()
    p = params.take(live)
    f = B.eval_bsdf(p, wo[live], s.wi[live], mode)
    pdf = B.pdf_bsdf(p, wo[live], s.wi[live])
    np.testing.assert_allclose(pdf, s.pdf[live], rtol=1e-7)
    np.testing.assert_allclose(s.weight[live], f / pdf[:, None], rtol=1e-7, atol=1e-12)
    assert np.all(s.weight[s.pdf == 0] == 0) and np.all(s.wi[s.pdf == 0] == 0)
    # Sampled coat reflections say so: a reflection, glossy or singular.
    assert np.all(s.lobe[s.pdf > 0] != 0)


def test_coat_of_weight_zero_is_the_base_exactly():
    rng = np.random.default_rng(2)
    k = 5000
    kind = rng.choice(B.KINDS, k)
    args = (kind, rng.random((k, 3)), rng.uniform(0, 1, k), rng.uniform(1.0, 2.5, k))
    plain = B.make_params(*args)
    zero = B.make_params(*args, coat_weight=0.0, coat_tint=0.2)
    assert not zero.has_coat
    some = B.make_params(*args, coat_weight=np.where(np.arange(k) < 10, 0.5, 0.0))
    wo, wi = rng.normal(size=(k, 3)), rng.normal(size=(k, 3))
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    u_lobe, u = rng.random(k), rng.random((k, 2))
    rest = np.arange(k) >= 10
    np.testing.assert_array_equal(B.eval_bsdf(some, wo, wi)[rest],
                                  B.eval_bsdf(plain, wo, wi)[rest])
    np.testing.assert_array_equal(B.pdf_bsdf(some, wo, wi)[rest], B.pdf_bsdf(plain, wo, wi)[rest])
    a, b = B.sample_bsdf(some, wo, u_lobe, u), B.sample_bsdf(plain, wo, u_lobe, u)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x[rest], y[rest])


def test_coat_attenuation_is_cycles_layering_and_tint():
    smooth = np.full(1, 1e-8)  # a smooth coat: its albedo is the Fresnel term
    # Weight 1, IOR 1.5, tint 0.5 at normal incidence: (1 - F0) * 0.5, F0 = 0.04.
    a = coat_attenuation(np.ones(1), np.full(1, 1.5), np.full((1, 3), 0.5), np.ones(1), smooth)
    np.testing.assert_allclose(a, 0.96 * 0.5, rtol=1e-12)
    # At 60 degrees the path through the coat is 1 / cos_t long; weight 0.5 fades both.
    mu, eta, w = 0.5, 1.5, 0.5
    cos_t = math.sqrt(1 - (1 - mu * mu) / eta**2)
    f = fresnel_dielectric(np.array([mu]), np.array([eta]))[0]
    expect = (1 - w * f) * (1 - w + w * 0.25 ** (1 / cos_t))
    a = coat_attenuation(np.full(1, w), np.full(1, eta), np.full((1, 3), 0.25), np.full(1, mu),
                         smooth)
    np.testing.assert_allclose(a, expect, rtol=1e-12)


@pytest.mark.parametrize("mu", [0.9, 0.3, 0.05, -0.2])
def test_rough_coat_attenuates_by_its_albedo_at_the_clamped_cosine(mu):
    """Cycles 5.0 attenuates the layers below a coat by ``1 - w E``, ``E`` the rough coat's
    directional albedo with the exact Fresnel (its GGX table read at the view's cosine clamped
    to [0, 1]; a view below the coat's normal reads the grazing row), the tint by the path
    length at ``|mu|``. Checked against the albedo's quadrature (independent of our table,
    within the table's interpolation error, 2e-3 here). The smooth Fresnel used before is
    0.23 above ``E`` at ``mu = 0.05`` and 0.39 at ``mu <= 0`` (roughness 0.2): far outside."""
    from sampling_lab.core.materials.layered import coat_albedo

    w, eta, alpha = 0.8, 1.5, 0.2**2
    tint = np.array([[0.9, 0.6, 0.4]])
    e = coat_albedo(np.array([max(mu, 0.0)]), np.array([alpha]), np.array([eta]))[0]
    cos_t = math.sqrt(1 - (1 - mu * mu) / eta**2)
    expect = (1 - w * e) * (1 - w + w * tint[0] ** (1 / cos_t))
    a = coat_attenuation(np.full(1, w), np.full(1, eta), tint, np.full(1, mu), np.full(1, alpha))
    np.testing.assert_allclose(a[0], expect, atol=2e-3)


@pytest.mark.parametrize("z", [0.9, 0.4, 0.05])
def test_smooth_coat_over_white_lambert_conserves_energy(z):
    # Albedo F(mu) + (1 - F(mu)) * 1 = 1: the sample weights average to one.
    rng = np.random.default_rng(int(z * 100))
    p = B.make_params(B.KIND_DIFFUSE, 1.0, k=N, coat_weight=1.0, coat_roughness=0.0,
                      coat_ior=1.5)
    s = B.sample_bsdf(p, np.tile(_wo(z), (N, 1)), rng.random(N), rng.random((N, 2)))
    assert s.delta.any() and (~s.delta).any()
    assert_mean_within_ci(s.weight, np.ones(3), p_false=P_FALSE)


@pytest.mark.parametrize("z", [0.9, 0.3])
def test_rough_coat_reflects_its_weight_times_its_albedo_over_a_black_base(z):
    # Directional albedo = w E_coat(mu) (quadrature of eval), E from the coat's own table.
    from sampling_lab.core.materials.layered import coat_albedo
    wo = _wo(z)
    p = B.make_params(B.KIND_DIFFUSE, 0.0, k=1, coat_weight=0.7, coat_roughness=0.4,
                      coat_ior=1.5)

    def f(w):
        return B.eval_bsdf(p.take(np.zeros(len(w), int)), np.tile(wo, (len(w), 1)), w)[:, 0]

    total, err = integrate_sphere(f, lobe_grids(f, z))
    expect = 0.7 * coat_albedo(np.array([z]), np.array([0.16]), np.array([1.5]))[0]
    assert abs(total - expect) <= err + 1e-3, (total, expect)


def test_coat_is_not_reciprocal_and_importance_mode_is_its_adjoint():
    rng = np.random.default_rng(5)
    k = 20_000
    p = B.make_params(B.KIND_DIFFUSE, rng.random((k, 3)), k=k, coat_weight=rng.random(k),
                      coat_roughness=0.3, coat_tint=rng.random((k, 3)))
    wo = _wo(0.9) * np.ones((k, 1))
    wi = rng.normal(size=(k, 3))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wi[:, 2] = np.abs(wi[:, 2])

    def f(a, b, mode):
        return B.eval_bsdf(p, a, b, mode) / np.abs(b[:, 2])[:, None]

    np.testing.assert_allclose(f(wo, wi, B.IMPORTANCE), f(wi, wo, B.RADIANCE), rtol=1e-9)
    assert not np.allclose(f(wo, wi, B.RADIANCE), f(wi, wo, B.RADIANCE), rtol=1e-3)


def test_rough_coat_makes_a_smooth_base_shadeable():
    mirror = B.make_params(B.KIND_CONDUCTOR, 0.9, 0.0, k=3, coat_weight=[0.0, 0.5, 0.5],
                           coat_roughness=[0.2, 0.2, 0.0])
    assert B.is_delta_only(mirror).tolist() == [True, False, True]


def test_material_table_coat_columns_reach_the_bsdf():
    mats = Materials.from_lists(["a", "b"], [(0.5,) * 3] * 2, [(0,) * 3] * 2, kinds=[3, 1],
                                coat_weight=[0.0, 0.6], coat_roughness=[0.1, 0.5],
                                coat_ior=[1.3, 1.7], coat_tint=[(1, 1, 1), (0.2, 0.3, 0.4)])
    p = B.BSDFParams.from_materials(mats, np.array([1, 0, 1]))
    np.testing.assert_allclose(p.coat_weight, [0.6, 0.0, 0.6], rtol=1e-6)
    np.testing.assert_allclose(p.coat_alpha, [0.25, 0.01, 0.25], rtol=1e-6)
    np.testing.assert_allclose(p.coat_eta, [1.7, 1.3, 1.7], rtol=1e-6)
    np.testing.assert_allclose(p.coat_tint[0], [0.2, 0.3, 0.4], rtol=1e-6)
    plain = Materials.from_lists(["a"], [(0.5,) * 3], [(0,) * 3], kinds=[3])
    assert not B.BSDFParams.from_materials(plain, np.array([0])).has_coat


# --------------------------------------------------------------------------------------------
# The Principled specular layer's Specular Tint (core/materials/layered.py)
# --------------------------------------------------------------------------------------------


def test_specular_tint_is_cycles_generalized_schlick():
    from sampling_lab.core.materials.layered import tinted_fresnel
    eta = np.full(3, 1.5)
    mu = np.array([1.0, 0.5, 0.0])
    f = fresnel_dielectric(mu, eta)
    tint = np.tile([1.0, 0.4, 0.1], (3, 1))
    ft = tinted_fresnel(f, eta, tint)
    np.testing.assert_allclose(ft[0], 0.04 * tint[0], rtol=1e-12)   # normal incidence: tint F0
    np.testing.assert_allclose(ft[2], 1.0, rtol=1e-12)               # grazing: white
    s = (f[1] - 0.04) / 0.96
    np.testing.assert_allclose(ft[1], 0.04 * tint[1] + (1 - 0.04 * tint[1]) * s, rtol=1e-12)
    np.testing.assert_allclose(tinted_fresnel(f, eta, np.ones((3, 3))), f[:, None] * np.ones(3),
                               rtol=1e-12)


@pytest.mark.parametrize("roughness,z", [(0.6, 0.3), (0.0, 0.5)])
def test_tinted_specular_albedo_matches_the_integral_of_its_lobe(roughness, z):
    # A black base leaves the specular lobe alone: its directional albedo per channel is
    # specular_albedo, to the tables' accuracy (2e-3) plus the quadrature's own error.
    from sampling_lab.core.materials.layered import specular_albedo
    tint = (1.0, 0.4, 0.1)
    wo = _wo(z)
    p = B.make_params(B.KIND_LAYERED, 0.0, roughness, 1.5, tint=tint, k=1)
    expect = specular_albedo(np.array([z]), p.alpha, p.eta, p.tint[:1])[0]
    if roughness == 0.0:
        rng = np.random.default_rng(1)
        s = B.sample_bsdf(p.take(np.zeros(N, int)), np.tile(wo, (N, 1)), rng.random(N),
                          rng.random((N, 2)))
        np.testing.assert_allclose(s.weight.mean(axis=0), expect, rtol=1e-9)
        return
    for c in range(3):
        def f(w, c=c):
            return B.eval_bsdf(p.take(np.zeros(len(w), int)), np.tile(wo, (len(w), 1)),
                               w)[:, c]

        total, err = integrate_sphere(f, lobe_grids(f, z))
        assert abs(total - expect[c]) <= err + 2e-3, (c, total, expect[c])


# --------------------------------------------------------------------------------------------
# Multiscatter GGX on the Principled specular layer (KIND_LAYERED_MS)
# --------------------------------------------------------------------------------------------


def test_multiscatter_specular_layer_keeps_the_specular_ior_level():
    ms = B.make_params(B.KIND_LAYERED_MS, 0.5, 0.5, 1.5, specular_ior_level=1.0, k=1)
    ss = B.make_params(B.KIND_LAYERED, 0.5, 0.5, 1.5, specular_ior_level=1.0, k=1)
    np.testing.assert_allclose(ms.eta, ss.eta, rtol=1e-12)
    assert ms.eta[0] > 1.7


@pytest.mark.parametrize("roughness,z", [(0.3, 0.8), (1.0, 0.2)])
def test_multiscatter_specular_layer_samples_follow_their_pdf(roughness, z):
    wo = _wo(z)

    def params(k):
        return B.make_params(B.KIND_LAYERED_MS, (0.3, 0.2, 0.1), roughness, 1.5,
                             tint=(1.0, 0.5, 0.3), k=k)

    def sample(u_lobe, u):
        s = B.sample_bsdf(params(len(u_lobe)), np.tile(wo, (len(u_lobe), 1)), u_lobe, u)
        return s.wi, s.pdf, s.delta

    def pdf(w):
        return B.pdf_bsdf(params(len(w)), np.tile(wo, (len(w), 1)), w)

    chi_square_bsdf(sample, pdf, z, seed=17, what=f"layered_ms r{roughness} z{z}")


@pytest.mark.parametrize("z", [0.9, 0.3])
def test_multiscatter_specular_layer_recovers_the_lost_energy(z):
    # Black base: the compensated lobe reflects E(mu) (1 + F_ms (1 - E1) / E1) -- the quadrature
    # of eval matches specular_albedo(multiscatter=True) and exceeds the single-scattering one
    # by the factor; a white layer over a white base reflects everything.
    from sampling_lab.core.materials.layered import multiscatter_factor, specular_albedo
    wo = _wo(z)
    p = B.make_params(B.KIND_LAYERED_MS, 0.0, 1.0, 2.5, k=1)
    expect = specular_albedo(np.array([z]), p.alpha, p.eta, p.tint, multiscatter=True)[0, 0]

    def f(w):
        return B.eval_bsdf(p.take(np.zeros(len(w), int)), np.tile(wo, (len(w), 1)), w)[:, 0]

    total, err = integrate_sphere(f, lobe_grids(f, z))
    assert abs(total - expect) <= err + 3e-3, (total, expect)
    single = specular_albedo(np.array([z]), p.alpha, p.eta, p.tint)[0, 0]
    factor = multiscatter_factor(np.array([z]), p.alpha, p.eta, p.tint)[0, 0]
    assert factor > 1.05 and abs(expect - single * factor) < 1e-12
    white = B.make_params(B.KIND_LAYERED_MS, 1.0, 1.0, 2.5, k=N)
    rng = np.random.default_rng(4)
    s = B.sample_bsdf(white, np.tile(wo, (N, 1)), rng.random(N), rng.random((N, 2)))
    assert_mean_within_ci(s.weight, np.ones(3), p_false=P_FALSE)


# --------------------------------------------------------------------------------------------
# Multiscatter GGX on rough glass (KIND_DIELECTRIC_MS, core/materials/glass_albedo.py)
# --------------------------------------------------------------------------------------------


def test_glass_albedo_table_matches_its_quadrature_between_nodes():
    from sampling_lab.core.materials.glass_albedo import albedo_lookup, glass_albedo
    rng = np.random.default_rng(8)
    k = 40
    mu, rough = rng.uniform(0.05, 1.0, k), rng.uniform(0.1, 1.0, k)
    eta = np.where(rng.random(k) < 0.5, rng.uniform(1.1, 2.5, k), 1.0 / rng.uniform(1.1, 2.5, k))
    exact = glass_albedo(mu, rough**2, eta)
    err = np.abs(albedo_lookup(mu, rough**2, eta) - exact)
    # Trilinear interpolation on 16^3 nodes: measured worst 1.2e-2, mean 2e-3.
    assert err.max() < 0.02 and err.mean() < 5e-3, (err.max(), err.mean())


@pytest.mark.parametrize("roughness,z,eta", [(1.0, 0.9, 1.5), (0.5, 0.3, 1.5),
                                             (1.0, 0.8, 1 / 1.5)])
def test_white_rough_glass_loses_no_energy_with_multiscatter(roughness, z, eta):
    # Seen from the camera (radiance mode, the factor at wo), reflection plus transmission in
    # flux terms (the transmitted samples' 1 / etap^2 undone) sums to one up to the table's
    # interpolation error (2e-2 at worst); single scattering loses 5-50 %.
    from sampling_lab.core.materials.glass_albedo import glass_albedo
    rng = np.random.default_rng(9)
    wo = np.tile(_wo(z), (N, 1))
    ms = B.make_params(B.KIND_DIELECTRIC_MS, 1.0, roughness, eta, k=N)
    s = B.sample_bsdf(ms, wo, rng.random(N), rng.random((N, 2)))
    etap = np.where(s.wi[:, 2] < 0, eta, 1.0)
    assert_mean_within_ci(s.weight * (etap**2)[:, None], np.ones(3), p_false=P_FALSE, atol=0.02)
    assert glass_albedo(np.array([z]), np.array([roughness**2]), np.array([eta]))[0] < 0.96


def test_multiscatter_glass_in_importance_mode_is_the_adjoint():
    rng = np.random.default_rng(12)
    k = 20_000
    p = B.make_params(B.KIND_DIELECTRIC_MS, rng.random((k, 3)), rng.uniform(0.1, 1.0, k),
                      rng.uniform(1.1, 2.5, k))
    wo, wi = rng.normal(size=(k, 3)), rng.normal(size=(k, 3))
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)

    def f(a, b, mode):
        return B.eval_bsdf(p, a, b, mode) / np.abs(b[:, 2])[:, None]

    a, b = f(wo, wi, B.IMPORTANCE), f(wi, wo, B.RADIANCE)
    assert np.count_nonzero(a[:, 0]) > k // 4
    np.testing.assert_allclose(a, b, rtol=1e-7, atol=1e-300)


def test_coloured_glass_darkens_like_cycles_with_its_colour_as_fresnel_average():
    from sampling_lab.core.materials.glass_albedo import compensation
    mu, alpha, eta = np.full(2, 0.7), np.full(2, 0.5), np.full(2, 1.5)
    f = compensation(mu, alpha, eta, np.array([[1.0, 1.0, 1.0], [1.0, 0.5, 0.2]]))
    from sampling_lab.core.materials.glass_albedo import albedo_lookup
    np.testing.assert_allclose(f[0], 1.0 / albedo_lookup(mu[:1], alpha[:1], eta[:1])[0],
                               rtol=1e-12)
    assert f[1, 0] == f[0, 0] and 1.0 < f[1, 2] < f[1, 1] < f[1, 0]


def test_coated_outputs_are_finite_and_non_negative_on_hard_inputs():
    # The hard direction pairs of test_bsdf_stability (grazing, tangent, mirrored,
    # antiparallel) under coats over every kind, with floating-point errors raised.
    from tests.core.test_bsdf_stability import ONE_MINUS, _pairs
    wo, wi = _pairs()
    k = len(wo)
    rng = np.random.default_rng(21)
    with np.errstate(divide="raise", invalid="raise", over="raise"):
        for coat_roughness in (0.0, 0.3, 1.0):
            params = B.make_params(rng.choice(B.KINDS, k), rng.random((k, 3)),
                                   rng.choice([0.0, 0.5, 1.0], k), rng.choice([1.0, 1.5], k),
                                   coat_weight=rng.random(k), coat_roughness=coat_roughness,
                                   coat_ior=rng.choice([1.0, 1.5, 3.0], k),
                                   coat_tint=rng.random((k, 3)))
            assert np.all(B.pdf_bsdf(params, wo, wi) >= 0)
            for mode in B.TRANSPORT_MODES:
                assert np.all(B.eval_bsdf(params, wo, wi, mode) >= 0)
                for u_val in (0.0, 0.5, ONE_MINUS):
                    s = B.sample_bsdf(params, wo, np.full(k, u_val), np.full((k, 2), u_val),
                                      mode)
                    assert np.all(np.isfinite(s.weight)) and np.all(s.weight >= 0)
                    assert np.all(np.isfinite(s.pdf)) and np.all(s.pdf >= 0)
