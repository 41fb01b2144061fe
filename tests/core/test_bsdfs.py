"""BSDFs: samples follow their pdfs, pdfs integrate to the sampled mass, weights are eval / pdf,
energy is conserved or lost as documented, reciprocity holds, dielectrics obey Fresnel and Snell.

Method. Directions are histogrammed on the lobe grids of :mod:`tests.sphere_chi2`: theta bands
free of the pdf's discontinuities, each warped toward the pdf's largest value wherever it lies
on the sphere, with expected counts from an adaptive Gauss-Legendre cubature of the pdf under
error control. Every case is viewed from its own azimuth off the plane x-z (``Case.phi``), so the
lobes do not sit where a grid built for the plane of incidence would be dense.

Tolerances. Chi-square tests use :data:`tests.sphere_chi2.ALPHA` each (Bonferroni over the
suite: a correct implementation fails any of them with probability < 1 % for a fresh seed).
They test the *shape* of the non-delta samples (cell masses normalised by their sum); the mass
itself is tested separately against the fraction of non-delta samples, with a binomial
confidence interval (p_false = 1e-4) plus the cubature's own error estimate. Means use
Student-t intervals from ``tests.helpers`` (p_false = 1e-4).
"""
from __future__ import annotations

import math
import zlib
from typing import NamedTuple

import numpy as np
import pytest

from sampling_lab.core.materials import bsdf as B
from sampling_lab.core.materials import conductor, dielectric, layered, mirror
from sampling_lab.core.materials import microfacet as mf
from sampling_lab.core.materials.frame import refract, shading_frame, to_local
from sampling_lab.core.materials.fresnel import (
    adjust_ior_for_specular_level,
    f0_from_ior,
    fresnel_dielectric,
    fresnel_schlick,
)
from sampling_lab.core.materials.lambert import eval_lambert, pdf_lambert
from sampling_lab.core.scene import MAT_DIFFUSE, Materials
from tests.helpers import assert_mean_within_ci, z_for_false_failure
from tests.sphere_chi2 import (  # noqa: F401  (re-exported to the other BSDF test modules)
    HALF_PI,
    N_CHI,
    chi_square_bsdf,
    integrate_sphere,
    lobe_grids,
)

P_FALSE = 1e-4


# --------------------------------------------------------------------------------------------
# Cases
# --------------------------------------------------------------------------------------------


class Case(NamedTuple):
    kind: int
    roughness: float = 0.5
    ior: float = 1.5
    z: float = 0.8           # wo.z: negative is below the surface (inside a dielectric)
    color: float = 1.0
    mode: str = B.RADIANCE
    phi: float = 0.0         # azimuth of wo

    @property
    def id(self):
        name = B.KIND_NAMES[self.kind]
        view = f"z{self.z}" + (f"-phi{self.phi}" if self.phi else "")
        if self.kind == B.KIND_DIFFUSE:
            return f"{name}-{view}"
        if self.kind in (B.KIND_CONDUCTOR, B.KIND_CONDUCTOR_MS):
            return f"{name}-r{self.roughness}-{view}"
        return f"{name}-r{self.roughness}-ior{self.ior}-{view}"

    @property
    def eta(self):
        """Index of the interface whose refraction cone splits the sphere (dielectrics only)."""
        return self.ior if self.kind in (B.KIND_DIELECTRIC, B.KIND_DIELECTRIC_MS) else None

    def wo(self, k=1):
        return np.tile(_wo(self.z, self.phi), (k, 1))

    def params(self, k):
        return B.make_params(self.kind, self.color, self.roughness, self.ior, k=k)

    def sample(self, u_lobe, u):
        return B.sample_bsdf(self.params(len(u_lobe)), self.wo(len(u_lobe)), u_lobe, u,
                             self.mode)

    def pdf(self, w):
        return B.pdf_bsdf(self.params(len(w)), self.wo(len(w)), w)

    def eval(self, w):
        return B.eval_bsdf(self.params(len(w)), self.wo(len(w)), w, self.mode)


def _wo(z, phi=0.0):
    s = math.sqrt(max(0.0, 1.0 - z * z))
    return np.array([s * math.cos(phi), s * math.sin(phi), z])


def _off_plane(cases):
    """The cases, each seen from its own azimuth off the plane x-z (the BSDFs are isotropic, so
    this moves the lobes, not the values: it tests that the checker finds lobes anywhere)."""
    azimuths = (0.4, 1.9, 3.6, 5.2, 2.7)
    return [c._replace(phi=azimuths[i % len(azimuths)]) for i, c in enumerate(cases)]


CHI_CASES = _off_plane(
    [Case(B.KIND_DIFFUSE, z=z) for z in (0.8, 0.05, -0.6)]
    + [Case(B.KIND_CONDUCTOR, r, z=z) for r in (0.05, 0.2, 0.5, 1.0) for z in (0.8, 0.05, -0.6)]
    + [Case(B.KIND_DIELECTRIC, r, ior, z) for r in (0.05, 0.2, 0.5, 1.0)
       for ior in (1.1, 1.5, 2.5) for z in (0.8, 0.05, -0.6, -0.05)]
    + [Case(B.KIND_LAYERED, r, ior, z) for r in (0.0, 0.05, 0.2, 0.5, 1.0) for ior in (1.5, 2.5)
       for z in (0.8, 0.05)]
    # Multiscatter GGX: the conductor and the dielectric's reflection and transmission.
    + [Case(B.KIND_CONDUCTOR_MS, r, z=z) for r in (0.05, 0.6, 1.0) for z in (0.8, 0.05)]
    + [Case(B.KIND_DIELECTRIC_MS, r, ior, z) for r in (0.05, 0.6, 1.0) for ior in (1.1, 1.5)
       for z in (0.8, -0.6, -0.05)]
) + [Case(B.KIND_CONDUCTOR, 0.05, z=0.8), Case(B.KIND_DIELECTRIC, 0.05, 1.5, 0.8)]

# The mass test on a representative subset (each case integrates the pdf twice).
MASS_CASES = (
    [c for c in CHI_CASES if c.kind in (B.KIND_DIFFUSE, B.KIND_CONDUCTOR)]
    + [c for c in CHI_CASES if c.kind == B.KIND_DIELECTRIC and c.roughness in (0.2, 1.0)
       and c.ior in (1.1, 2.5) and c.z != -0.05]
    + [c for c in CHI_CASES if c.kind == B.KIND_LAYERED and c.roughness in (0.0, 0.5)
       and c.ior == 1.5]
    + [c for c in CHI_CASES if c.kind in (B.KIND_CONDUCTOR_MS, B.KIND_DIELECTRIC_MS)
       and c.roughness == 0.6 and c.ior == 1.5]
)


# --------------------------------------------------------------------------------------------
# Samples follow the pdf; the pdf integrates to the non-delta sample mass
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", CHI_CASES, ids=[c.id for c in CHI_CASES])
def test_bsdf_samples_follow_their_pdf(case):
    def sample(u_lobe, u):
        s = case.sample(u_lobe, u)
        return s.wi, s.pdf, s.delta

    chi_square_bsdf(sample, case.pdf, case.z, case.eta, seed=zlib.crc32(case.id.encode()),
                    what=case.id)


def test_bsdf_chi_square_rejects_a_mismatched_pdf():
    # GGX at roughness 0.2 against the pdf of roughness 0.22: the checker must object.
    true, wrong = Case(B.KIND_CONDUCTOR, 0.2, z=0.8), Case(B.KIND_CONDUCTOR, 0.22, z=0.8)

    def sample(u_lobe, u):
        s = true.sample(u_lobe, u)
        return s.wi, s.pdf, s.delta

    with pytest.raises(AssertionError, match="chi-square"):
        chi_square_bsdf(sample, wrong.pdf, 0.8)
    # Refraction at IOR 1.5 against the pdf of IOR 1.45.
    true, wrong = Case(B.KIND_DIELECTRIC, 0.5, 1.5, 0.8), Case(B.KIND_DIELECTRIC, 0.5, 1.45, 0.8)

    def sample_glass(u_lobe, u):
        s = true.sample(u_lobe, u)
        return s.wi, s.pdf, s.delta

    with pytest.raises(AssertionError, match="chi-square"):
        chi_square_bsdf(sample_glass, wrong.pdf, 0.8, 1.5)


@pytest.mark.parametrize("case", MASS_CASES, ids=[c.id for c in MASS_CASES])
def test_pdf_integrates_to_the_probability_of_a_non_delta_sample(case):
    n = N_CHI
    rng = np.random.default_rng(7)
    s = case.sample(rng.random(n), rng.random((n, 2)))
    frac = float(np.mean((s.pdf > 0) & ~s.delta))
    total, quad_err = integrate_sphere(case.pdf, lobe_grids(case.pdf, case.z, case.eta))
    # Binomial interval; at frac = 1 the count is exact, the quadrature error remains.
    se = math.sqrt(max(frac * (1 - frac), 1.0 / n) / n)
    tol = z_for_false_failure(P_FALSE) * se + quad_err + 1e-6
    assert abs(total - frac) <= tol, (case.id, total, frac, tol)
    assert total <= 1.0 + quad_err + 1e-6


def test_lambert_pdf_integrates_to_one():
    case = Case(B.KIND_DIFFUSE, z=0.3)
    total, err = integrate_sphere(case.pdf, lobe_grids(case.pdf, 0.3))
    assert total == pytest.approx(1.0, abs=err + 1e-6)


# --------------------------------------------------------------------------------------------
# GGX
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("alpha", [0.01, 0.2, 1.0])
def test_ggx_ndf_projected_area_is_one(alpha):
    # int D(m) cos(theta_m) dm = 1 (the microsurface projects onto the macro surface).
    fn = lambda m: mf.ggx_d(m[:, 2], np.full(len(m), alpha)) * np.maximum(m[:, 2], 0)  # noqa
    total, err = integrate_sphere(fn, lobe_grids(fn, 1.0))
    assert total == pytest.approx(1.0, abs=err + 1e-6)


@pytest.mark.parametrize("alpha,z", [(0.04, 0.9), (0.25, 0.05), (1.0, 0.5), (0.25, -0.7)])
def test_ggx_visible_normal_pdf_integrates_to_one(alpha, z):
    wo = _wo(z)
    fn = lambda m: mf.ggx_visible_pdf(np.tile(wo, (len(m), 1)), m, np.full(len(m), alpha))  # noqa
    total, err = integrate_sphere(fn, lobe_grids(fn, 1.0))
    assert total == pytest.approx(1.0, abs=err + 1e-6)


@pytest.mark.parametrize("alpha,z", [(0.04, 0.9), (0.25, 0.05), (1.0, 0.5), (0.25, -0.7)])
def test_ggx_visible_normals_follow_their_pdf(alpha, z):
    wo = _wo(z)

    def sample(u_lobe, u):
        m = mf.sample_ggx_visible(np.tile(wo, (len(u), 1)), np.full(len(u), alpha), u)
        return m, np.ones(len(u)), np.zeros(len(u), bool)

    fn = lambda m: mf.ggx_visible_pdf(np.tile(wo, (len(m), 1)), m, np.full(len(m), alpha))  # noqa
    chi_square_bsdf(sample, fn, 1.0, seed=11, what=f"vndf alpha={alpha} z={z}")


def test_ggx_masking_is_height_correlated_smith():
    rng = np.random.default_rng(3)
    k = 10_000
    co, ci = rng.uniform(-1, 1, k), rng.uniform(-1, 1, k)
    alpha = rng.uniform(mf.ALPHA_MIN, 1, k)
    lo, li = mf.ggx_lambda(co, alpha), mf.ggx_lambda(ci, alpha)
    g2 = mf.ggx_g2(co, ci, alpha)
    np.testing.assert_allclose(g2, 1.0 / (1.0 + lo + li), rtol=1e-10)
    np.testing.assert_allclose(mf.ggx_g1(co, alpha), 1.0 / (1.0 + lo), rtol=1e-10)
    # Height correlation: never less than the separable product.
    assert np.all(g2 >= mf.ggx_g1(co, alpha) * mf.ggx_g1(ci, alpha) - 1e-12)
    np.testing.assert_allclose(mf.ggx_g2_over_g1(co, ci, alpha), g2 / mf.ggx_g1(co, alpha),
                               rtol=1e-10)
    np.testing.assert_allclose(mf.ggx_visibility(co, ci, alpha), g2 / (4 * np.abs(co * ci)),
                               rtol=1e-10)


def test_alpha_is_roughness_squared_and_smooth_below_the_cycles_threshold():
    r = np.array([0.0, 0.01, 0.0177, 0.0178, 0.2, 1.0, 1.5])
    alpha = mf.alpha_from_roughness(r)
    np.testing.assert_allclose(alpha, np.maximum(np.clip(r, 0, 1) ** 2, mf.ALPHA_MIN))
    # Cycles: alpha_x * alpha_y <= 1e-7 is singular.
    assert mf.is_smooth(alpha).tolist() == [True, True, True, False, False, False, False]


# --------------------------------------------------------------------------------------------
# Weights
# --------------------------------------------------------------------------------------------


def _random_directions(rng, k, lower=True):
    w = rng.normal(size=(k, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    if not lower:
        w[:, 2] = np.abs(w[:, 2])
    return w


def _random_params(rng, kind, k):
    return B.make_params(kind, rng.random((k, 3)), rng.uniform(0, 1, k), rng.uniform(1.0, 2.5, k),
                         specular_ior_level=rng.random(k), tint=rng.random((k, 3)))


@pytest.mark.parametrize("mode", [B.RADIANCE, B.IMPORTANCE])
@pytest.mark.parametrize("kind", B.KINDS, ids=[B.KIND_NAMES[k] for k in B.KINDS])
def test_sample_weight_equals_eval_over_pdf(kind, mode):
    rng = np.random.default_rng(kind)
    k = 50_000
    params = _random_params(rng, kind, k)
    wo = _random_directions(rng, k)
    s = B.sample_bsdf(params, wo, rng.random(k), rng.random((k, 2)), mode)
    live = (s.pdf > 0) & ~s.delta
    assert live.mean() > 0.5
    p = params.take(live)
    f = B.eval_bsdf(p, wo[live], s.wi[live], mode)
    pdf = B.pdf_bsdf(p, wo[live], s.wi[live])
    np.testing.assert_allclose(pdf, s.pdf[live], rtol=1e-7)
    np.testing.assert_allclose(s.weight[live], f / pdf[:, None], rtol=1e-7, atol=1e-12)
    # Delta samples are not in eval / pdf, and failed samples carry nothing.
    assert np.all(s.weight[s.pdf == 0] == 0) and np.all(s.wi[s.pdf == 0] == 0)


# --------------------------------------------------------------------------------------------
# Energy (white furnace)
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("z", [1.0, 0.3, 0.01, -0.5])
def test_white_lambert_reflects_all_energy(z):
    rng = np.random.default_rng(1)
    k = 10_000
    s = B.sample_bsdf(B.make_params(B.KIND_DIFFUSE, 1.0, k=k), np.tile(_wo(z), (k, 1)),
                      rng.random(k), rng.random((k, 2)))
    np.testing.assert_array_equal(s.weight, 1.0)
    assert np.all(s.wi[:, 2] * np.sign(z) >= 0)


@pytest.mark.parametrize("z", [1.0, 0.3, 1e-7, -0.5])
def test_perfect_mirror_reflects_all_energy_about_the_normal(z):
    k = 100
    wo = np.tile(_wo(z, 0.7), (k, 1))
    s = B.sample_bsdf(B.make_params(B.KIND_CONDUCTOR, 1.0, roughness=0.0, k=k), wo,
                      np.random.default_rng(0).random(k), np.random.default_rng(1).random((k, 2)))
    assert np.all(s.delta) and np.all(s.pdf == 1.0)
    np.testing.assert_array_equal(s.weight, 1.0)
    np.testing.assert_allclose(s.wi, wo * [-1, -1, 1], atol=1e-15)
    assert np.all(B.eval_bsdf(B.make_params(B.KIND_CONDUCTOR, 1.0, 0.0, k=k), wo, s.wi) == 0)


def test_mirror_reflects_schlick_fresnel_of_its_f0():
    f0 = np.array([[0.9, 0.6, 0.2]] * 4)
    wo = np.array([_wo(z) for z in (1.0, 0.5, 0.1, -0.3)])
    wi, weight, pdf, delta = mirror.sample_mirror(f0, wo)
    np.testing.assert_allclose(weight, fresnel_schlick(f0, wo[:, 2]), rtol=1e-15)
    c = 1 - np.abs(wo[:, 2])
    np.testing.assert_allclose(weight, f0 + (1 - f0) * (c**5)[:, None], rtol=1e-12)


@pytest.mark.parametrize("ior", [1.1, 1.5, 2.5])
@pytest.mark.parametrize("z", [1.0, 0.5, 0.05, -0.3, -0.9])
def test_smooth_dielectric_splits_energy_by_fresnel(ior, z):
    k = 40_000
    rng = np.random.default_rng(2)
    wo = np.tile(_wo(z), (k, 1))
    params = B.make_params(B.KIND_DIELECTRIC, 1.0, 0.0, ior, k=k)
    u_lobe, u = rng.random(k), rng.random((k, 2))
    imp = B.sample_bsdf(params, wo, u_lobe, u, B.IMPORTANCE)
    rad = B.sample_bsdf(params, wo, u_lobe, u, B.RADIANCE)
    f = fresnel_dielectric(np.array([z]), np.array([ior]))[0]
    reflected = imp.wi[:, 2] * z > 0
    assert np.all(imp.delta) and np.all(imp.pdf > 0)
    # Importance mode: every sample carries weight one (R + T = 1) ...
    np.testing.assert_allclose(imp.weight, 1.0, rtol=1e-15)
    np.testing.assert_allclose(imp.pdf, np.where(reflected, f, 1 - f), rtol=1e-12)
    assert_mean_within_ci(reflected.astype(float), f, P_FALSE, what="reflected fraction")
    # ... radiance mode scales refraction by (n_wo / n_wi)^2.
    etap = ior if z > 0 else 1 / ior
    np.testing.assert_allclose(rad.weight[:, 0], np.where(reflected, 1.0, 1 / etap**2),
                               rtol=1e-12)
    np.testing.assert_array_equal(rad.wi, imp.wi)


@pytest.mark.parametrize("ior", [1.1, 1.5, 2.5])
def test_smooth_dielectric_reflects_fresnel_f0_at_normal_incidence(ior):
    f0 = ((ior - 1) / (ior + 1)) ** 2
    assert fresnel_dielectric(np.array([1.0]), np.array([ior]))[0] == pytest.approx(f0, rel=1e-12)
    assert fresnel_dielectric(np.array([-1.0]), np.array([ior]))[0] == pytest.approx(f0, rel=1e-12)
    assert f0_from_ior(ior) == pytest.approx(f0, rel=1e-15)


@pytest.mark.parametrize("ior", [1.1, 1.5, 2.5])
def test_total_internal_reflection_beyond_the_critical_angle(ior):
    critical = math.asin(1 / ior)
    k = 1000
    rng = np.random.default_rng(4)
    for theta, tir in [(critical + 1e-6, True), (critical + 0.2, True), (critical - 1e-3, False)]:
        if theta >= HALF_PI:
            continue
        wo = np.tile([math.sin(theta), 0.0, -math.cos(theta)], (k, 1))  # inside
        f = fresnel_dielectric(wo[:1, 2], np.array([ior]))[0]
        assert (f == 1.0) == tir
        s = B.sample_bsdf(B.make_params(B.KIND_DIELECTRIC, 1.0, 0.0, ior, k=k), wo,
                          rng.random(k), rng.random((k, 2)))
        if tir:
            assert np.all(s.wi[:, 2] < 0) and np.all(s.pdf == 1.0)
            np.testing.assert_array_equal(s.weight, 1.0)
            _, ok, _ = refract(wo[:1], np.array([[0, 0, 1.0]]), np.array([ior]))
            assert not ok[0]
        else:
            assert np.any(s.wi[:, 2] > 0)


@pytest.mark.parametrize("roughness", [0.0, 0.3, 1.0])
@pytest.mark.parametrize("z", [1.0, 0.3, 1e-7, -0.6])
def test_index_matched_dielectric_transmits_straight_through(roughness, z):
    k = 200
    wo = np.tile(_wo(z, 1.1), (k, 1))
    rng = np.random.default_rng(5)
    params = B.make_params(B.KIND_DIELECTRIC, 1.0, roughness, 1.0, k=k)
    assert np.all(B.is_delta_only(params))
    for mode in B.TRANSPORT_MODES:
        s = B.sample_bsdf(params, wo, rng.random(k), rng.random((k, 2)), mode)
        assert np.all(s.delta) and np.all(s.pdf == 1.0)
        np.testing.assert_array_equal(s.wi, -wo)
        np.testing.assert_array_equal(s.weight, 1.0)
    assert np.all(B.eval_bsdf(params, wo, -wo) == 0) and np.all(B.pdf_bsdf(params, wo, -wo) == 0)


class EnergyCase(NamedTuple):
    kind: int
    roughness: float
    ior: float
    z: float


ENERGY_CASES = (
    [EnergyCase(B.KIND_CONDUCTOR, r, 1.5, z) for r in (0.2, 0.5, 1.0) for z in (1.0, 0.5, 0.05)]
    + [EnergyCase(B.KIND_DIELECTRIC, r, ior, z) for r in (0.2, 1.0) for ior in (1.1, 2.5)
       for z in (0.9, 0.1, -0.5)]
)


@pytest.mark.parametrize("case", ENERGY_CASES,
                         ids=[f"{B.KIND_NAMES[c.kind]}-r{c.roughness}-ior{c.ior}-z{c.z}"
                              for c in ENERGY_CASES])
def test_rough_albedo_matches_the_integral_of_eval_and_is_at_most_one(case):
    # White F0 / tints, importance mode: the albedo is what single scattering keeps.
    c = Case(case.kind, case.roughness, case.ior, case.z, mode=B.IMPORTANCE)
    n = 100_000
    rng = np.random.default_rng(6)
    w = c.sample(rng.random(n), rng.random((n, 2))).weight[:, 0]
    fn = lambda wi: c.eval(wi)[:, 0]  # noqa: E731
    integral, quad_err = integrate_sphere(fn, lobe_grids(fn, c.z, c.eta))
    mean, se = assert_mean_within_ci(w, integral, P_FALSE, atol=quad_err,
                                     what=f"albedo {case}")
    q = z_for_false_failure(P_FALSE)
    assert mean - q * se <= 1.0 and integral <= 1.0 + quad_err
    if case.kind == B.KIND_CONDUCTOR and case.roughness == 0.2 and case.z >= 0.5:
        # At alpha = 0.04 single scattering loses almost nothing.
        assert integral > 0.9


@pytest.mark.parametrize("roughness", [0.6, 1.0])
@pytest.mark.parametrize("z", [0.9, 0.2, -0.9, -0.2])
def test_multiscatter_glass_flux_albedo_is_true_over_tabulated_albedo(roughness, z):
    # Radiance mode divides the single-scattering lobe by the tabulated albedo of wo's side, so
    # reflection plus transmission in flux terms (the refracted samples' 1 / etap^2 undone) is
    # E(mu_o) / E_table(mu_o): one up to the table's interpolation, and exactly that ratio. A
    # factor read from the other side's table would miss it by 14-85 % (measured). The
    # quadrature of E errs by < 1e-3 (tests/core/test_rough_glass.py).
    from sampling_lab.core.materials.glass_albedo import albedo_lookup, glass_albedo
    ior, n = 1.45, 200_000
    rng = np.random.default_rng(23)
    s = Case(B.KIND_DIELECTRIC_MS, roughness, ior, z, phi=1.1).sample(rng.random(n),
                                                                       rng.random((n, 2)))
    side = ior if z > 0 else 1.0 / ior
    flux = s.weight[:, 0] * np.where(s.wi[:, 2] * z < 0, side**2, 1.0)
    args = np.array([abs(z)]), np.array([roughness**2]), np.array([side])
    e_true, e_table = glass_albedo(*args, n=256)[0], albedo_lookup(*args)[0]
    assert_mean_within_ci(flux, e_true / e_table, P_FALSE, atol=1e-3 / e_table,
                          what=f"multiscatter glass flux albedo r{roughness} z{z}")


@pytest.mark.parametrize("roughness", [0.0, 0.2, 1.0])
@pytest.mark.parametrize("ior", [1.05, 1.5, 2.5])
@pytest.mark.parametrize("z", [1.0, 0.2])
def test_layered_with_white_base_conserves_energy_to_the_table_accuracy(roughness, ior, z):
    # Radiance albedo = E(mu_o) + (1 - E_table(mu_o)): exactly one where the table is exact.
    n = 100_000
    rng = np.random.default_rng(8)
    case = Case(B.KIND_LAYERED, roughness, ior, z)
    w = case.sample(rng.random(n), rng.random((n, 2))).weight
    alpha = mf.alpha_from_roughness(np.array([roughness]))
    eta = np.array([ior])
    e_true = (fresnel_dielectric(np.array([z]), eta)[0] if mf.is_smooth(alpha)[0]
              else layered.coat_albedo(np.array([z]), alpha, eta, n=96)[0])
    e_table = layered.coat_albedo_lookup(np.array([z]), alpha, eta)[0]
    assert abs(e_table - e_true) <= 2e-3
    assert_mean_within_ci(w, 1.0 + e_true - e_table, P_FALSE, atol=2e-4, what="layered albedo")


@pytest.mark.parametrize("z", [0.9, 0.3])
def test_layered_black_base_reflects_the_coat_albedo(z):
    n = 100_000
    rng = np.random.default_rng(9)
    params = B.make_params(B.KIND_LAYERED, 0.0, 0.4, 1.5, k=n)
    s = B.sample_bsdf(params, np.tile(_wo(z), (n, 1)), rng.random(n), rng.random((n, 2)))
    e_true = layered.coat_albedo(np.array([z]), np.array([0.16]), np.array([1.5]), n=96)[0]
    assert_mean_within_ci(s.weight[:, 1], e_true, P_FALSE, atol=2e-4, what="coat albedo")


def test_layered_albedo_is_at_most_one_for_coloured_inputs():
    n = 100_000
    rng = np.random.default_rng(10)
    for _ in range(4):
        color, tint = rng.random(3), rng.random(3)
        params = B.make_params(B.KIND_LAYERED, color, rng.random(), rng.uniform(1, 3), tint=tint,
                               k=n)
        wo = np.tile(_wo(rng.uniform(0.2, 1)), (n, 1))
        s = B.sample_bsdf(params, wo, rng.random(n), rng.random((n, 2)))
        mean = s.weight.mean(axis=0)
        se = s.weight.std(axis=0, ddof=1) / math.sqrt(n)
        assert np.all(mean - z_for_false_failure(P_FALSE, 12) * se <= 1.0 + 2e-3)


def test_coat_albedo_table_matches_its_quadrature():
    table = layered.albedo_table()
    rng = np.random.default_rng(12)
    mu_n, alpha_n, eta_n = layered._table_nodes()
    # Stored nodes are the quadrature, rounded to 16 bits.
    for _ in range(8):
        i, j, m = rng.integers(1, 32, 3)
        value = layered.coat_albedo(mu_n[i:i + 1], alpha_n[j:j + 1], eta_n[m:m + 1])[0]
        assert table[i, j, m] == pytest.approx(value, abs=0.6 / 65535)
    # Trilinear interpolation: the accuracy the layered model's docstring promises.
    k = 400
    mu = rng.uniform(0.0, 1.0, k)
    alpha = rng.uniform(mf.ALPHA_SMOOTH, 1.0, k) ** 2
    eta = rng.uniform(1.0, 3.0, k)
    err = np.abs(layered.coat_albedo_lookup(mu, alpha, eta) - layered.coat_albedo(mu, alpha, eta))
    assert err[mu >= 0.2].max() <= 2e-3
    assert err.max() <= 1.1e-2


# --------------------------------------------------------------------------------------------
# Reciprocity
# --------------------------------------------------------------------------------------------


def _f(params, wo, wi, mode=B.RADIANCE):
    """The BSDF value itself, f = eval / |cos theta_i|."""
    return B.eval_bsdf(params, wo, wi, mode) / np.abs(wi[:, 2])[:, None]


@pytest.mark.parametrize("kind", [B.KIND_DIFFUSE, B.KIND_CONDUCTOR, B.KIND_DIELECTRIC],
                         ids=["diffuse", "conductor", "dielectric"])
def test_reflection_is_reciprocal(kind):
    rng = np.random.default_rng(13)
    k = 20_000
    params = _random_params(rng, kind, k)
    wo = _random_directions(rng, k)
    wi = _random_directions(rng, k)
    wi[:, 2] = np.abs(wi[:, 2]) * np.sign(wo[:, 2])  # same side: reflection
    a, b = _f(params, wo, wi), _f(params, wi, wo)
    assert np.count_nonzero(a[:, 0]) > k // 2
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-300)


def test_refraction_obeys_generalized_reciprocity():
    # Radiance mode: f(wo, wi) / n(wo)^2 == f(wi, wo) / n(wi)^2 (Veach 1997, eq. 5.14).
    rng = np.random.default_rng(14)
    k = 20_000
    params = _random_params(rng, B.KIND_DIELECTRIC, k)
    wo = _random_directions(rng, k)
    wi = _random_directions(rng, k)
    wi[:, 2] = -np.abs(wi[:, 2]) * np.sign(wo[:, 2])  # opposite side: refraction
    n_of = lambda w: np.where(w[:, 2] > 0, 1.0, params.eta)[:, None]  # noqa: E731
    a = _f(params, wo, wi) / n_of(wo) ** 2
    b = _f(params, wi, wo) / n_of(wi) ** 2
    assert np.count_nonzero(a[:, 0]) > k // 10
    # 1 - F near grazing microfacets and the Jacobian's (wi.m + wo.m / etap)^2 cancel digits.
    np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-300)


@pytest.mark.parametrize("kind", [B.KIND_DIELECTRIC, B.KIND_LAYERED, B.KIND_CONDUCTOR_MS],
                         ids=["dielectric", "layered", "conductor_ms"])
def test_importance_mode_is_the_adjoint_of_radiance_mode(kind):
    rng = np.random.default_rng(15)
    k = 20_000
    params = _random_params(rng, kind, k)
    wo = _random_directions(rng, k)
    wi = _random_directions(rng, k)
    a = _f(params, wo, wi, B.IMPORTANCE)
    b = _f(params, wi, wo, B.RADIANCE)
    assert np.count_nonzero(a[:, 0]) > k // 10
    # The two sides build the half vector from different sums: rounding, not 1e-9.
    np.testing.assert_allclose(a, b, rtol=1e-7, atol=1e-300)
    if kind in (B.KIND_LAYERED, B.KIND_CONDUCTOR_MS):
        # The albedo-scaled base and the multiscatter factor are not reciprocal by themselves:
        # the modes must differ somewhere.
        assert not np.allclose(_f(params, wo, wi, B.RADIANCE), a)


@pytest.mark.parametrize("kind", B.KINDS, ids=[B.KIND_NAMES[k] for k in B.KINDS])
def test_bsdf_is_invariant_under_rotation_about_the_normal(kind):
    rng = np.random.default_rng(16)
    k = 5000
    params = _random_params(rng, kind, k)
    wo = _random_directions(rng, k)
    wi = _random_directions(rng, k)
    phi = rng.uniform(0, 2 * np.pi, k)
    c, s = np.cos(phi), np.sin(phi)

    def rot(w):
        return np.stack([c * w[:, 0] - s * w[:, 1], s * w[:, 0] + c * w[:, 1], w[:, 2]], -1)

    for mode in B.TRANSPORT_MODES:
        np.testing.assert_allclose(B.eval_bsdf(params, rot(wo), rot(wi), mode),
                                   B.eval_bsdf(params, wo, wi, mode), rtol=1e-8, atol=1e-300)
    np.testing.assert_allclose(B.pdf_bsdf(params, rot(wo), rot(wi)), B.pdf_bsdf(params, wo, wi),
                               rtol=1e-8, atol=1e-300)


# --------------------------------------------------------------------------------------------
# Frames, Snell and Fresnel
# --------------------------------------------------------------------------------------------


def test_refraction_obeys_snells_law_and_reverses():
    rng = np.random.default_rng(17)
    k = 10_000
    w = _random_directions(rng, k)
    m = _random_directions(rng, k, lower=False)
    eta = rng.uniform(0.4, 2.5, k)
    wt, ok, etap = refract(w, m, eta)
    cos_i = np.abs(np.sum(w * m, axis=1))
    cos_t = np.abs(np.sum(wt * m, axis=1))
    sin_i, sin_t = np.sqrt(1 - cos_i**2), np.sqrt(np.maximum(0, 1 - cos_t**2))
    np.testing.assert_allclose(sin_i[ok], (etap * sin_t)[ok], atol=1e-9)
    # The refracted direction lies on the other side, in the plane of incidence.
    side = np.sum(w * m, axis=1) * np.sum(wt * m, axis=1)
    assert np.all(side[ok] < 0)
    np.testing.assert_allclose(np.einsum("ij,ij->i", np.cross(w, m), wt)[ok], 0, atol=1e-9)
    back, ok2, _ = refract(wt[ok], m[ok], eta[ok])
    assert np.all(ok2)
    np.testing.assert_allclose(back, w[ok], atol=1e-9)
    # Where refraction fails, Fresnel reflects everything.
    f = fresnel_dielectric(np.sum(w * m, axis=1), eta)
    assert np.all(f[~ok] == 1.0)


def test_fresnel_is_the_same_from_both_sides_of_a_refraction():
    rng = np.random.default_rng(18)
    k = 10_000
    cos_i = rng.uniform(0, 1, k)
    eta = rng.uniform(1.01, 3, k)
    sin_t = np.sqrt(1 - cos_i**2) / eta
    cos_t = np.sqrt(1 - sin_t**2)
    np.testing.assert_allclose(fresnel_dielectric(cos_i, eta), fresnel_dielectric(-cos_t, eta),
                               rtol=1e-9, atol=1e-15)


def test_shading_frame_round_trips_world_directions():
    rng = np.random.default_rng(19)
    k = 1000
    n = _random_directions(rng, k)
    v = _random_directions(rng, k)
    s, t, nn = shading_frame(n)
    local = to_local(v, s, t, nn)
    np.testing.assert_allclose(local[:, 2], np.sum(v * n, axis=1), atol=1e-12)
    from sampling_lab.core.materials.frame import to_world
    np.testing.assert_allclose(to_world(local, s, t, nn), v, atol=1e-12)


@pytest.mark.parametrize("ior", [1.05, 1.5, 2.5])
def test_specular_ior_level_scales_f0(ior):
    assert adjust_ior_for_specular_level(ior, 0.5) == pytest.approx(ior, rel=1e-12)
    assert adjust_ior_for_specular_level(ior, 0.0) == pytest.approx(1.0, abs=1e-12)
    assert f0_from_ior(adjust_ior_for_specular_level(ior, 1.0)) == pytest.approx(
        2 * f0_from_ior(ior), rel=1e-9)


# --------------------------------------------------------------------------------------------
# The dispatcher
# --------------------------------------------------------------------------------------------


def test_dispatcher_matches_the_family_functions_on_mixed_batches():
    rng = np.random.default_rng(20)
    k = 4000
    kinds = rng.integers(0, 4, k)
    params = B.make_params(kinds, rng.random((k, 3)), rng.uniform(0, 1, k),
                           rng.uniform(1, 2.5, k), specular_ior_level=rng.random(k),
                           tint=rng.random((k, 3)))
    wo, wi = _random_directions(rng, k), _random_directions(rng, k)
    u_lobe, u = rng.random(k), rng.random((k, 2))
    for mode in B.TRANSPORT_MODES:
        f = B.eval_bsdf(params, wo, wi, mode)
        pdf = B.pdf_bsdf(params, wo, wi)
        s = B.sample_bsdf(params, wo, u_lobe, u, mode)
        for kind in B.KINDS:
            rows = np.nonzero(kinds == kind)[0]
            p = params.take(rows)
            # Kind by kind, as a batch of one kind: the same numbers, row for row.
            np.testing.assert_array_equal(f[rows], B.eval_bsdf(p, wo[rows], wi[rows], mode))
            np.testing.assert_array_equal(pdf[rows], B.pdf_bsdf(p, wo[rows], wi[rows]))
            alone = B.sample_bsdf(p, wo[rows], u_lobe[rows], u[rows], mode)
            for got, want in zip(s, alone):
                np.testing.assert_array_equal(got[rows], want)
    # And the family modules directly.
    rows = np.nonzero(kinds == B.KIND_CONDUCTOR)[0]
    p = params.take(rows)
    np.testing.assert_array_equal(f[rows], conductor.eval_conductor(p.color, p.alpha, wo[rows],
                                                                    wi[rows]))
    rows = np.nonzero(kinds == B.KIND_DIELECTRIC)[0]
    p = params.take(rows)
    np.testing.assert_array_equal(pdf[rows], dielectric.pdf_dielectric(p.eta, p.alpha, wo[rows],
                                                                       wi[rows]))


def test_dispatcher_rejects_unknown_kinds_and_modes():
    params = B.make_params(np.array([0, 7]), 0.5, k=2)
    w = np.tile([0.0, 0.0, 1.0], (2, 1))
    with pytest.raises(ValueError, match="unknown BSDF kind"):
        B.eval_bsdf(params, w, w)
    with pytest.raises(ValueError, match="transport mode"):
        B.eval_bsdf(B.make_params(0, k=2), w, w, mode="photons")


def test_params_from_the_material_table_use_blender_defaults():
    mats = Materials.from_lists(["a", "b"], [(0.2, 0.4, 0.6), (1.0, 1.0, 1.0)],
                                [(0, 0, 0), (0, 0, 0)])
    params = B.BSDFParams.from_materials(mats, np.array([1, 0, 0]))
    assert MAT_DIFFUSE == B.KIND_DIFFUSE
    np.testing.assert_array_equal(params.kind, [0, 0, 0])
    np.testing.assert_allclose(params.color[1], [0.2, 0.4, 0.6], rtol=1e-6)
    np.testing.assert_allclose(params.alpha, 0.25)
    np.testing.assert_allclose(params.eta, 1.5)
    np.testing.assert_allclose(params.tint, 1.0)
    # Layered rows fold the Specular IOR Level into the coat index.
    mats.kind = np.array([B.KIND_LAYERED, B.KIND_DIELECTRIC], np.int32)
    mats.ior = np.array([1.5, 1.5])
    mats.specular_ior_level = np.array([1.0, 1.0])
    params = B.BSDFParams.from_materials(mats, np.array([0, 1]))
    assert f0_from_ior(params.eta[0]) == pytest.approx(2 * f0_from_ior(1.5))
    assert params.eta[1] == 1.5


def test_diffuse_kind_matches_the_lambert_module_in_world_space():
    rng = np.random.default_rng(21)
    k = 5000
    n = _random_directions(rng, k)
    wo_w, wi_w = _random_directions(rng, k), _random_directions(rng, k)
    albedo = rng.random((k, 3))
    s, t, nn = shading_frame(n)
    params = B.make_params(B.KIND_DIFFUSE, albedo)
    f = B.eval_bsdf(params, to_local(wo_w, s, t, nn), to_local(wi_w, s, t, nn))
    n_flipped = n * np.where(np.sum(n * wo_w, axis=1) >= 0, 1.0, -1.0)[:, None]
    np.testing.assert_allclose(f, eval_lambert(albedo, n_flipped, wi_w), rtol=1e-10, atol=1e-15)
    np.testing.assert_allclose(B.pdf_bsdf(params, to_local(wo_w, s, t, nn),
                                          to_local(wi_w, s, t, nn)),
                               pdf_lambert(n_flipped, wi_w), rtol=1e-10, atol=1e-15)


def test_is_delta_only_marks_smooth_mirrors_and_glass():
    kinds = [B.KIND_CONDUCTOR, B.KIND_CONDUCTOR, B.KIND_DIELECTRIC, B.KIND_DIELECTRIC,
             B.KIND_DIELECTRIC, B.KIND_LAYERED, B.KIND_DIFFUSE]
    rough = [0.0, 0.3, 0.01, 0.3, 0.3, 0.0, 0.0]
    ior = [1.5, 1.5, 1.5, 1.5, 1.00005, 1.5, 1.5]
    params = B.make_params(np.array(kinds), 1.0, np.array(rough), np.array(ior))
    assert B.is_delta_only(params).tolist() == [True, False, True, False, True, False, False]


def test_sampled_lobes_are_labelled_like_cycles_closures():
    rng = np.random.default_rng(22)
    k = 20_000
    kinds = rng.integers(0, 4, k)
    params = B.make_params(kinds, rng.random((k, 3)), rng.choice([0.0, 0.3], k),
                           rng.uniform(1, 2.5, k), tint=rng.random((k, 3)))
    wo = _random_directions(rng, k)
    s = B.sample_bsdf(params, wo, rng.random(k), rng.random((k, 2)))
    ok = s.pdf > 0
    assert np.all(s.lobe[~ok] == 0)
    lobe = s.lobe[ok]
    transmit = (s.wi[:, 2] * wo[:, 2] < 0)[ok]
    assert np.all(((lobe & B.LOBE_TRANSMIT) > 0) == transmit)
    assert np.all(((lobe & B.LOBE_REFLECT) > 0) == ~transmit)
    assert np.all(((lobe & B.LOBE_SINGULAR) > 0) == s.delta[ok])
    kk = kinds[ok]
    assert np.all(lobe[kk == B.KIND_DIFFUSE] == B.LOBE_DIFFUSE | B.LOBE_REFLECT)
    assert np.all((lobe[kk == B.KIND_CONDUCTOR] & B.LOBE_DIFFUSE) == 0)
    assert np.all((lobe[kk != B.KIND_DIELECTRIC] & B.LOBE_TRANSMIT) == 0)
    # The layered base is diffuse, its coat glossy (or singular when smooth).
    n = 2000
    wo = np.tile(_wo(0.6), (n, 1))
    u_lobe, u = rng.random(n), rng.random((n, 2))
    coat_only = B.sample_bsdf(B.make_params(B.KIND_LAYERED, 0.0, 0.3, 1.5, k=n), wo, u_lobe, u)
    # (Specular IOR Level 0 removes the specular lobe; a black tint would not: its
    # generalized Schlick Fresnel still turns white at grazing angles.)
    base_only = B.sample_bsdf(B.make_params(B.KIND_LAYERED, 1.0, 0.3, 1.5,
                                            specular_ior_level=0.0, k=n), wo, u_lobe, u)
    live = coat_only.pdf > 0
    assert np.all(coat_only.lobe[live] == B.LOBE_GLOSSY | B.LOBE_REFLECT)
    assert np.all(base_only.lobe == B.LOBE_DIFFUSE | B.LOBE_REFLECT)
