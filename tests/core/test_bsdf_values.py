"""``eval_with_pdfs`` (one dispatch for a connection end's ``f`` and both densities) equals the
separate ``eval_bsdf`` / ``pdf_bsdf`` calls bit for bit, on random rows of every family, mixed
batches, coated and sheened rows, and rows with a bump normal."""

import dataclasses

import numpy as np
import pytest

from sampling_lab.core.materials import bsdf as B
from sampling_lab.core.materials.bsdf_values import eval_with_pdfs


def _directions(rng, k):
    w = rng.normal(size=(k, 3))
    return w / np.linalg.norm(w, axis=1, keepdims=True)


def _params(rng, kinds, k, **layers):
    return B.make_params(kinds, rng.random((k, 3)), rng.uniform(0, 1, k), rng.uniform(1.0, 2.5, k),
                         specular_ior_level=rng.random(k), tint=rng.random((k, 3)), **layers)


def _assert_same_as_separate_calls(params, wo, wi):
    for mode in B.TRANSPORT_MODES:
        f, pdf_wi, pdf_wo = eval_with_pdfs(params, wo, wi, mode)
        np.testing.assert_array_equal(f, B.eval_bsdf(params, wo, wi, mode))
        np.testing.assert_array_equal(pdf_wi, B.pdf_bsdf(params, wo, wi))
        np.testing.assert_array_equal(pdf_wo, B.pdf_bsdf(params, wi, wo))
        assert np.any(pdf_wi != pdf_wo)  # the two directions are told apart


@pytest.mark.parametrize("kind", B.KINDS, ids=[B.KIND_NAMES[k] for k in B.KINDS])
def test_one_call_equals_eval_and_both_pdfs_on_every_family(kind):
    rng = np.random.default_rng(100 + kind)
    k = 2000
    _assert_same_as_separate_calls(_params(rng, kind, k), _directions(rng, k),
                                   _directions(rng, k))


def test_one_call_equals_the_separate_calls_on_mixed_coated_and_sheened_rows():
    rng = np.random.default_rng(7)
    k = 6000
    kinds = rng.integers(min(B.KINDS), max(B.KINDS) + 1, k)
    coat = np.where(rng.random(k) < 0.4, rng.random(k), 0.0)
    sheen = np.where(rng.random(k) < 0.4, rng.random(k), 0.0)
    params = _params(rng, kinds, k, coat_weight=coat, coat_roughness=rng.random(k),
                     sheen_weight=sheen)
    assert params.coat_weight is not None and params.sheen_color is not None
    _assert_same_as_separate_calls(params, _directions(rng, k), _directions(rng, k))


def test_one_call_equals_the_separate_calls_with_a_bump_normal():
    rng = np.random.default_rng(8)
    k = 2000
    params = _params(rng, rng.integers(0, 4, k), k)
    bump = np.array([0.3, -0.2, 1.0]) + 0.2 * rng.normal(size=(k, 3))
    params = dataclasses.replace(params, bump_normal=bump / np.linalg.norm(bump, axis=1)[:, None])
    _assert_same_as_separate_calls(params, _directions(rng, k), _directions(rng, k))


def test_one_call_on_no_rows_gives_empty_values():
    p = B.make_params(B.KIND_DIFFUSE, 0.5, k=0)
    f, pdf_wi, pdf_wo = eval_with_pdfs(p, np.zeros((0, 3)), np.zeros((0, 3)))
    assert f.shape == (0, 3) and pdf_wi.shape == (0,) and pdf_wo.shape == (0,)


def test_plain_diffuse_sample_and_pdf_equal_the_general_ones_bit_for_bit():
    """``sample_plain_diffuse`` / ``pdf_plain_diffuse`` (the walks' form for scenes of plain
    diffuse materials) give ``sample_bsdf`` / ``pdf_bsdf``'s values, both sides of the surface,
    directions in the tangent plane and degenerate numbers included."""
    rng = np.random.default_rng(11)
    k = 5000
    params = _params(rng, B.KIND_DIFFUSE, k)
    wo = _directions(rng, k)
    wo[:40, 2] = 0.0  # in the tangent plane
    wo[40:80, 2] = -0.0
    u = rng.random((k, 2))
    u[80:120] = 0.5  # the concentric map's centre: z = 1, or the disk's rim
    u[120:160, 0] = 0.0
    for mode in B.TRANSPORT_MODES:
        lean = B.sample_plain_diffuse(params, wo, u, mode)
        general = B.sample_bsdf(params, wo, rng.random(k), u, mode)
        for a, b in zip(lean, general):
            assert a.dtype == b.dtype
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(B.pdf_plain_diffuse(params, lean.wi, wo),
                                      B.pdf_bsdf(params, lean.wi, wo))
    # Rows below the surface, and rim samples of density zero (lobe 0), occur.
    assert (wo[:, 2] < 0).any() and (lean.pdf == 0).any() and (lean.lobe == 0).any()
