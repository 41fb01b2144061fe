"""BSDFs never produce NaN or Inf: a sweep over hard directions and parameters.

Every kind is evaluated, its pdf taken and sampled on every combination of: directions at the
pole, at grazing angles (|cos| = 1e-7, 1e-12), exactly in the tangent plane, below the
surface, antiparallel pairs (zero-length half vectors), mirror pairs, refraction pairs of an
index-matched interface; roughness 0, just below and above the smooth threshold, 0.5 and 1; IOR
1 (index-matched), within 1e-4 of 1, 1.001, 1.1, 1.5, 2.5 and extreme; random numbers 0 and
1 - 2^-53. NumPy floating-point errors (division by zero, invalid operations, overflow) raise
instead of warning, so a NaN masked away by ``np.where`` also fails.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from sampling_lab.core.materials import bsdf as B
from sampling_lab.core.materials import microfacet as mf

ROUGHNESS = [0.0, 1e-3, float(np.sqrt(mf.ALPHA_SMOOTH)) * 0.999,
             float(np.sqrt(mf.ALPHA_SMOOTH)) * 1.001, 0.05, 0.5, 1.0]
IOR = [1.0, 1.0 + 5e-5, 1.0 - 5e-5, 1.001, 1.1, 1.5, 2.5, 1e-3, 50.0]
ONE_MINUS = 1.0 - 2.0**-53


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _hard_directions():
    zs = [1.0, 0.7, 0.2, 1e-3, 1e-7, 1e-12, 0.0, -0.0, -1e-12, -1e-7, -0.3, -1.0]
    out = []
    for z in zs:
        s = np.sqrt(max(0.0, 1.0 - z * z))
        for phi in (0.0, 2.0, np.pi):
            out.append([s * np.cos(phi), s * np.sin(phi), z])
    return _unit(np.array(out))


def _pairs():
    """(wo, wi) pairs: all combinations of the hard directions, plus mirror, antiparallel and
    refraction-like pairs."""
    d = _hard_directions()
    wo, wi = (np.array(v) for v in zip(*itertools.product(d, d)))
    extra_wo = np.concatenate([d, d, d])
    extra_wi = np.concatenate([d * [-1, -1, 1], -d, d * [1, 1, -1]])
    rng = np.random.default_rng(0)
    r = _unit(rng.normal(size=(2000, 3)))
    r2 = _unit(rng.normal(size=(2000, 3)))
    return (np.concatenate([wo, extra_wo, r]), np.concatenate([wi, extra_wi, r2]))


def _check(name, *arrays):
    for a in arrays:
        assert np.all(np.isfinite(a)), f"{name}: non-finite output"


@pytest.mark.parametrize("kind", B.KINDS, ids=[B.KIND_NAMES[k] for k in B.KINDS])
def test_bsdf_outputs_are_finite_and_non_negative_on_hard_inputs(kind):
    wo, wi = _pairs()
    k = len(wo)
    combos = list(itertools.product(ROUGHNESS, IOR))
    rng = np.random.default_rng(kind)
    with np.errstate(divide="raise", invalid="raise", over="raise"):
        for roughness, ior in combos:
            params = B.make_params(kind, rng.random((k, 3)), roughness, ior,
                                   specular_ior_level=rng.random(k), tint=rng.random((k, 3)),
                                   k=k)
            name = f"{B.KIND_NAMES[kind]} r={roughness} ior={ior}"
            pdf = B.pdf_bsdf(params, wo, wi)
            _check(name, pdf)
            assert np.all(pdf >= 0), name
            for mode in B.TRANSPORT_MODES:
                f = B.eval_bsdf(params, wo, wi, mode)
                _check(name, f)
                assert np.all(f >= 0), name
                for u_val in (0.0, 0.5, ONE_MINUS, None):
                    if u_val is None:
                        u_lobe, u = rng.random(k), rng.random((k, 2))
                    else:
                        u_lobe, u = np.full(k, u_val), np.full((k, 2), u_val)
                    s = B.sample_bsdf(params, wo, u_lobe, u, mode)
                    _check(name, s.wi, s.weight, s.pdf)
                    assert np.all(s.weight >= 0) and np.all(s.pdf >= 0), name
                    # A sample is either a unit direction with a positive pdf, or nothing.
                    length = np.linalg.norm(s.wi, axis=1)
                    ok = s.pdf > 0
                    np.testing.assert_allclose(length[ok], 1.0, atol=1e-9, err_msg=name)
                    assert np.all(length[~ok] == 0) and np.all(s.weight[~ok] == 0), name


def test_mixed_batches_are_finite_through_the_dispatcher():
    wo, wi = _pairs()
    k = len(wo)
    rng = np.random.default_rng(1)
    with np.errstate(divide="raise", invalid="raise", over="raise"):
        params = B.make_params(rng.integers(0, 4, k), rng.random((k, 3)),
                               rng.choice(ROUGHNESS, k), rng.choice(IOR, k),
                               specular_ior_level=rng.random(k), tint=rng.random((k, 3)))
        for mode in B.TRANSPORT_MODES:
            f = B.eval_bsdf(params, wo, wi, mode)
            s = B.sample_bsdf(params, wo, rng.random(k), rng.random((k, 2)), mode)
            _check("mixed", f, s.wi, s.weight, s.pdf, B.pdf_bsdf(params, wo, wi))
            assert np.all(f >= 0) and np.all(s.weight >= 0)


def test_out_of_range_parameters_are_clamped_not_propagated():
    k = 6
    wo = np.tile(_unit([0.3, 0.1, 0.8]), (k, 1))
    with np.errstate(divide="raise", invalid="raise", over="raise"):
        for kind in B.KINDS:
            params = B.make_params(kind, np.array([[-1, 2, np.inf]] * k),
                                   np.array([-1.0, 2.0, np.nan, 0.3, 0.3, 0.3]),
                                   np.array([0.0, -2.0, np.nan, np.inf, 1e9, 1.5]), k=k)
            s = B.sample_bsdf(params, wo, np.full(k, 0.3), np.full((k, 2), 0.6))
            _check(B.KIND_NAMES[kind], s.wi, s.weight, s.pdf, params.color, params.alpha,
                   params.eta)
            assert np.all(s.weight >= 0) and np.all(params.color <= 1)
