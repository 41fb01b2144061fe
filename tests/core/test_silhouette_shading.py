"""Cycles' shading-normal rules near the silhouettes of smooth faces (docs/SHADING_NORMALS.md):
the layered BSDF's base normal (the diffuse base around its own normal while the specular lobe
is bent), the rows seen from below their shading normal (core/materials/lower_view.py), which
materials bend their glossy normal, and the path tracer keeping a normal the view falls below.
"""

import dataclasses

import numpy as np
import pytest

from sampling_lab.core.integrators.common import bends_normals, shading_normals
from sampling_lab.core.materials import bsdf as B
from sampling_lab.core.materials import bump_correction, layered
from sampling_lab.core.materials.coat import coat_attenuation
from sampling_lab.core.materials.lower_view import lower_view_params, view_below
from tests.helpers import (chi_square_2d, directions_from_z_phi, integrate_solid_angle,
                           z_phi_from_directions)

N_CHI = 100_000


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


WO = _unit([0.6, 0.2, 0.35])
TILTED = _unit([-0.5, 0.1, 0.8])  # the base's own normal, tilted away from the view


def base_params(k, roughness, normal=TILTED, kind=B.KIND_LAYERED):
    p = B.make_params(kind, (0.7, 0.5, 0.3), roughness, 1.5, k=k)
    return dataclasses.replace(p, base_normal=np.tile(normal, (k, 1)))


@pytest.mark.parametrize("kind,roughness", [(B.KIND_LAYERED, 0.0), (B.KIND_LAYERED, 0.3),
                                            (B.KIND_LAYERED_MS, 0.7)])
def test_layered_base_normal_samples_match_its_pdf(roughness, kind):
    """The non-delta samples of a layered row with a tilted base normal follow ``pdf_bsdf``
    (chi-square over the sphere), and the pdf's mass is the share of such samples."""
    rng = np.random.default_rng(3)
    smp = B.sample_bsdf(base_params(N_CHI, roughness, kind=kind), np.tile(WO, (N_CHI, 1)),
                        rng.random(N_CHI), rng.random((N_CHI, 2)))
    kept = (smp.pdf > 0) & ~smp.delta

    def pdf(w):
        return B.pdf_bsdf(base_params(len(w), roughness, kind=kind), np.tile(WO, (len(w), 1)),
                          w)

    mass = integrate_solid_angle(pdf, res=(512, 512))
    # Binomial share of kept samples: 4 standard errors plus the quadrature's error.
    assert abs(mass - kept.mean()) < 4 * np.sqrt(0.25 / N_CHI) + 2e-3
    chi_square_2d(z_phi_from_directions(smp.wi[kept]),
                  lambda zp: pdf(directions_from_z_phi(zp)) / mass,
                  ((-1.0, 1.0), (0.0, 2 * np.pi)), res=(16, 32), mass_tol=2e-3,
                  what=f"base normal r={roughness}")


@pytest.mark.parametrize("roughness", [0.0, 0.3])
def test_layered_base_normal_weights_are_eval_over_pdf(roughness):
    k = 2000
    rng = np.random.default_rng(5)
    p = base_params(k, roughness)
    wo = np.tile(WO, (k, 1))
    smp = B.sample_bsdf(p, wo, rng.random(k), rng.random((k, 2)))
    rows = (smp.pdf > 0) & ~smp.delta
    f = B.eval_bsdf(p.take(rows), wo[rows], smp.wi[rows])
    np.testing.assert_allclose(smp.weight[rows], f / smp.pdf[rows][:, None], rtol=1e-9)


def test_layered_base_is_a_lambert_lobe_around_its_normal():
    """With a black-Fresnel layer (IOR 1) the row is the base alone: albedo max(n_d . wi, 0)
    / pi, whatever the view; the base normal +Z gives back the plain layered row."""
    wi = np.array([_unit([-0.7, 0.1, 0.2]), _unit([0.5, 0.0, 0.4]), _unit([-0.2, 0.3, -0.1])])
    k = len(wi)
    p = dataclasses.replace(B.make_params(B.KIND_LAYERED, (0.7, 0.5, 0.3), 0.3, 1.0, k=k),
                            base_normal=np.tile(TILTED, (k, 1)))
    f = B.eval_bsdf(p, np.tile(WO, (k, 1)), wi)
    cos = np.maximum(wi @ TILTED, 0.0)
    np.testing.assert_allclose(f, np.outer(cos / np.pi, [0.7, 0.5, 0.3]), atol=1e-12)
    plain = B.make_params(B.KIND_LAYERED, (0.7, 0.5, 0.3), 0.3, 1.5, k=k)
    up = dataclasses.replace(plain, base_normal=np.tile([0.0, 0.0, 1.0], (k, 1)))
    np.testing.assert_allclose(B.eval_bsdf(up, np.tile(WO, (k, 1)), wi),
                               B.eval_bsdf(plain, np.tile(WO, (k, 1)), wi), atol=1e-12)


def test_rows_seen_from_below_shade_as_cycles_closures():
    """Diffuse keeps its albedo, a layered row keeps its base times 1 - max E_t(0) (its
    specular lobe gives nothing), conductors and dielectrics give nothing; rows above are
    untouched; the view is mirrored through the tangent plane."""
    kinds = [B.KIND_DIFFUSE, B.KIND_LAYERED, B.KIND_CONDUCTOR, B.KIND_DIELECTRIC,
             B.KIND_LAYERED]
    p = B.make_params(np.array(kinds), (0.7, 0.5, 0.3), 0.4, 1.5)
    wo = np.tile(_unit([0.8, 0.0, -0.1]), (5, 1))
    below = np.array([True, True, True, True, False])
    q, wo2 = lower_view_params(p, wo, below)
    grazing = layered.specular_albedo(np.zeros(1), p.alpha[1:2], p.eta[1:2], p.tint[1:2])
    scale = 1.0 - grazing.max()
    assert 0.0 < scale < 1.0
    np.testing.assert_allclose(q.color[:4], [p.color[0], p.color[1] * scale, 0 * p.color[2],
                                             0 * p.color[3]], atol=1e-12)
    assert (q.kind[:4] == B.KIND_DIFFUSE).all() and q.kind[4] == B.KIND_LAYERED
    np.testing.assert_array_equal(q.color[4], p.color[4])
    np.testing.assert_allclose(wo2[:, 2], [-wo[0, 2]] * 4 + [wo[0, 2]])
    wi = np.tile(_unit([-0.3, 0.2, 0.9]), (5, 1))
    f = B.eval_bsdf(q, wo2, wi)
    np.testing.assert_allclose(f[0], p.color[0] * wi[0, 2] / np.pi, rtol=1e-12)


def test_coated_rows_seen_from_below_keep_only_the_coats_attenuation():
    """Cycles' coat is a microfacet closure: from below its normal its lobe gives nothing,
    and it still dims the layers below by its albedo estimate and tint at |cos|. A coated
    metal there is black (it reflected the coat's lobe before this rule); a coated layered
    row is its Lambert base times 1 - max E_t(0) times the coat's attenuation; a row above
    keeps its coat."""
    kinds = np.array([B.KIND_CONDUCTOR, B.KIND_LAYERED, B.KIND_LAYERED])
    p = B.make_params(kinds, (0.7, 0.5, 0.3), 0.4, 1.5, coat_weight=0.8,
                      coat_roughness=0.2, coat_ior=1.6, coat_tint=(0.9, 0.6, 0.5))
    wo = np.tile(_unit([0.8, 0.0, -0.1]), (3, 1))
    below = np.array([True, True, False])
    q, wo2 = lower_view_params(p, wo, below)
    wi = np.tile(_unit([-0.3, 0.2, 0.9]), (3, 1))
    f = B.eval_bsdf(q, wo2, wi)
    np.testing.assert_array_equal(f[0], 0.0)
    assert (B.eval_bsdf(p.take([0]), wo2[:1], wo2[:1] * [-1, -1, 1]) > 0).all()  # the lobe
    mu = wo[1, 2]  # the real view, below the coat's normal: its albedo read at grazing
    coat = coat_attenuation(p.coat_weight[1:2], p.coat_eta[1:2], p.coat_tint[1:2],
                            np.array([mu]), p.coat_alpha[1:2])[0]
    grazing = layered.specular_albedo(np.zeros(1), p.alpha[1:2], p.eta[1:2], p.tint[1:2])
    np.testing.assert_allclose(f[1], p.color[1] * (1 - grazing.max()) * coat * wi[1, 2]
                               / np.pi, rtol=1e-12)
    assert q.coat_weight.tolist() == [0.0, 0.0, p.coat_weight[2]]
    np.testing.assert_array_equal(q.color[2], p.color[2])


def test_a_transparent_bsdf_seen_from_below_still_passes_light_straight_through():
    p = B.make_params(B.KIND_DIELECTRIC, 1.0, 0.0, 1.0, k=1)
    wo = np.array([_unit([0.8, 0.0, -0.1])])
    q, wo2 = lower_view_params(p, wo, np.array([True]))
    assert q.kind[0] == B.KIND_DIELECTRIC and (wo2 == wo).all()
    smp = B.sample_bsdf(q, wo2, np.array([0.5]), np.array([[0.5, 0.5]]))
    np.testing.assert_allclose(smp.wi, -wo, atol=1e-12)
    np.testing.assert_allclose(smp.weight, 1.0, atol=1e-12)


def test_view_below_is_relative_to_the_viewers_geometric_side():
    ng = np.tile([0.0, 0.0, 1.0], (4, 1))
    n = np.tile(_unit([0.6, 0.0, 0.8]), (4, 1))
    wo = np.array([_unit([-0.9, 0.0, 0.2]), _unit([0.2, 0.0, 0.9]),
                   _unit([0.9, 0.0, -0.2]), _unit([1.0, 0.0, 0.0])])
    cos_g, cos_s = np.einsum("ij,ij->i", wo, ng), np.einsum("ij,ij->i", wo, n)
    # front, below n | front, above | back side, above n's plane from below | grazing
    np.testing.assert_array_equal(view_below(cos_g, cos_s), [True, False, True, False])


def test_bump_correction_reads_the_deviation_from_the_closure_normal():
    """cos_d is Ns . N of the diffuse closure: with a base normal, that normal, not +Z."""
    ns = np.array([_unit([0.3, 0.0, 0.95])])
    w = np.array([_unit([0.9, 0.0, 0.1])])
    frame = bump_correction.shadowing(ns, w)
    own = bump_correction.shadowing(ns, w, np.array([_unit([-0.4, 0.0, 0.9])]))
    same = bump_correction.shadowing(ns, w, np.zeros((1, 3)))
    assert own[0] < frame[0] < 1.0 and same[0] == frame[0]


class _Materials:
    def __init__(self, normal_texture, bump_texture, bump_correction):
        self.normal_texture = np.array(normal_texture)
        self.bump_texture = np.array(bump_texture)
        self.bump_correction = np.array(bump_correction)


def test_only_mapped_materials_without_correction_keep_their_glossy_normal():
    class Scene:
        materials = _Materials([-1, 0, 0, -1], [-1, -1, -1, 2], [False, False, True, False])
        material = np.array([0, 1, 2, 3])
    np.testing.assert_array_equal(bends_normals(Scene, np.array([0, 1, 2, 3])),
                                  [True, False, True, False])


def test_path_tracer_keeps_a_normal_the_view_falls_below():
    class Prep:
        class scene:
            corner_normals = np.array([[[0.6, 0.0, 0.8]] * 3], np.float32)
            corner_tangents = None
            materials = dataclasses.make_dataclass("M", [("bump_texture", object)])(
                np.array([-1]))
            material = np.array([0])
    ng = np.array([[0.0, 0.0, 1.0]])
    wo = np.array([_unit([-0.9, 0.0, 0.2])])
    args = (Prep, np.array([0]), np.array([0.2]), np.array([0.3]), ng, wo)
    np.testing.assert_allclose(shading_normals(*args), ng)
    np.testing.assert_allclose(shading_normals(*args, keep_below=True), [[0.6, 0.0, 0.8]],
                               atol=1e-6)
