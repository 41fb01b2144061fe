"""MIS weights: every heuristic partitions unity, handles impossible strategies, never NaNs.

``w(a, b) + w(b, a) == 1`` is what keeps a two-strategy MIS estimator unbiased (Veach 1997,
eq. 9.3), so it is checked to rounding over pdf pairs spanning 600 orders of magnitude, and the
closed forms (Veach sec. 9.2.2-9.2.3) are checked at moderate pdfs.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core.sampling.mis import HEURISTICS, MIS, mis_weight
from tests.helpers import plain_settings

EPS = np.finfo(np.float64).eps

# Every heuristic of mis.py, with several parameters where it has one.
VARIANTS = ([("balance", {})]
            + [("power", {"beta": b}) for b in (0.5, 1.0, 2.0, 3.0, 8.0)]
            + [("maximum", {})]
            + [("cutoff", {"alpha": a}) for a in (0.0, 0.05, 0.1, 0.5, 1.0)]
            + [("none", {})])
IDS = [f"{h}-{'-'.join(f'{k}{v:g}' for k, v in kw.items())}".rstrip("-") for h, kw in VARIANTS]


def test_every_heuristic_is_covered():
    assert {h for h, _ in VARIANTS} == set(HEURISTICS)


def pdf_pairs(seed=0, n=20_000):
    """Positive pdf pairs: log-uniform over [1e-300, 1e300], plus exact ties and extremes."""
    rng = np.random.default_rng(seed)
    a = 10.0 ** rng.uniform(-300, 300, n)
    b = 10.0 ** rng.uniform(-300, 300, n)
    # Ratios near one (where heuristics switch), equal pdfs, and the extreme corners.
    near = 10.0 ** rng.uniform(-5, 5, 2000)
    c = near * (1 + rng.uniform(-1e-3, 1e-3, 2000))
    ext = np.array([1e-300, 1e300, 1e-300, 1e300, 5e-324, 1.0, 5e-324, 1e300, 1.0])
    ext_b = np.array([1e300, 1e-300, 1e-300, 1e300, 1.0, 5e-324, 5e-324, 1.0, 1.0])
    return np.concatenate([a, near, near, ext]), np.concatenate([b, c, near, ext_b])


@pytest.mark.parametrize("heuristic, kw", VARIANTS, ids=IDS)
def test_weights_of_the_two_strategies_sum_to_one(heuristic, kw):
    a, b = pdf_pairs()
    wa = mis_weight(a, b, heuristic, **kw)
    wb = mis_weight(b, a, heuristic, **kw)
    assert np.all(np.isfinite(wa)) and np.all(np.isfinite(wb))
    assert np.all((wa >= 0) & (wa <= 1))
    np.testing.assert_allclose(wa + wb, 1.0, rtol=0, atol=4 * EPS)


@pytest.mark.parametrize("heuristic, kw", VARIANTS, ids=IDS)
def test_batches_where_both_strategies_can_make_every_sample_get_the_general_weights(heuristic, kw):
    # Such a batch takes a shortcut; one impossible sample sends the same rows through the
    # general case. Smallest error detected: any difference in any bit.
    a, b = pdf_pairs(seed=3)
    fast = mis_weight(a, b, heuristic, **kw)
    general = mis_weight(np.append(a, 0.0), np.append(b, 1.0), heuristic, **kw)
    np.testing.assert_array_equal(fast, general[:-1])


@pytest.mark.parametrize("heuristic, kw", VARIANTS, ids=IDS)
def test_weight_is_one_where_the_other_pdf_is_zero_and_zero_where_its_own_is(heuristic, kw):
    p = np.array([5e-324, 1e-300, 1e-5, 1.0, 3.7, 1e300, np.finfo(np.float64).max])
    zero = np.zeros_like(p)
    np.testing.assert_array_equal(mis_weight(p, zero, heuristic, **kw), 1.0)
    np.testing.assert_array_equal(mis_weight(zero, p, heuristic, **kw), 0.0)
    # Neither strategy can make the sample: it never happens, but must not poison the film.
    w00 = mis_weight(np.zeros(1), np.zeros(1), heuristic, **kw)
    assert np.all(np.isfinite(w00)) and np.all((w00 >= 0) & (w00 <= 1))


@pytest.mark.parametrize("heuristic, kw", VARIANTS, ids=IDS)
def test_weights_depend_only_on_the_pdf_ratio(heuristic, kw):
    # Changing the measure (both pdfs times a constant) must not change the weights.
    rng = np.random.default_rng(1)
    a = 10.0 ** rng.uniform(-100, 100, 5000)
    b = a * 10.0 ** rng.uniform(-3, 3, 5000)
    w = mis_weight(a, b, heuristic, **kw)
    for scale in (1e-150, 1e-7, 3.0, 1e150):
        np.testing.assert_allclose(mis_weight(a * scale, b * scale, heuristic, **kw), w,
                                   rtol=16 * EPS, atol=4 * EPS)


def test_closed_forms_at_moderate_pdfs():
    rng = np.random.default_rng(2)
    a = rng.uniform(0.01, 10.0, 10_000)
    b = rng.uniform(0.01, 10.0, 10_000)
    np.testing.assert_allclose(mis_weight(a, b, "balance"), a / (a + b), rtol=1e-14)
    for beta in (0.5, 1.0, 2.0, 3.0):
        np.testing.assert_allclose(mis_weight(a, b, "power", beta=beta),
                                   a**beta / (a**beta + b**beta), rtol=1e-13)
    np.testing.assert_array_equal(mis_weight(a, b, "maximum"), (a > b).astype(float))
    np.testing.assert_array_equal(mis_weight(np.array([2.0]), np.array([2.0]), "maximum"), 0.5)
    for alpha in (0.05, 0.5):
        # Veach's cutoff: strategies below alpha * max get zero, the rest share by balance.
        m = np.maximum(a, b)
        expected = np.where(a < alpha * m, 0.0, np.where(b < alpha * m, 1.0, a / (a + b)))
        np.testing.assert_allclose(mis_weight(a, b, "cutoff", alpha=alpha), expected,
                                   rtol=1e-14)


def test_power_heuristic_with_beta_two_is_the_default():
    a, b = pdf_pairs(seed=3, n=1000)
    np.testing.assert_array_equal(mis_weight(a, b), mis_weight(a, b, "power", beta=2.0))


DBL_MAX = float(np.finfo(np.float64).max)
NEAR_LIMIT = [pytest.param(h, kw, big, id=f"{i}-{big:g}")
              for (h, kw), i in zip(VARIANTS, IDS) for big in (1e300, 1e307, DBL_MAX)]


@pytest.mark.parametrize("heuristic, kw, big", NEAR_LIMIT)
def test_weights_sum_to_one_for_pdfs_near_the_float_limit(heuristic, kw, big):
    """Delta-like lobes give huge pdfs: a weight must not vanish because a + b overflows."""
    a = np.array([big, big, big * 0.75, big])
    b = np.array([big, big * 0.5, big, 1.0])
    wa = mis_weight(a, b, heuristic, **kw)
    wb = mis_weight(b, a, heuristic, **kw)
    np.testing.assert_allclose(wa + wb, 1.0, rtol=0, atol=4 * EPS)


def test_unknown_heuristic_is_rejected():
    with pytest.raises(ValueError, match="heuristic"):
        mis_weight(np.ones(1), np.ones(1), "nearest")


# ------------------------------------------------------------------ the MIS value object
def _mis(heuristic, kw):
    return MIS(heuristic, kw.get("beta", 2.0), kw.get("alpha", 0.1))


@pytest.mark.parametrize("heuristic, kw", VARIANTS, ids=IDS)
def test_two_strategy_weights_are_the_stack_weights_with_k_two(heuristic, kw):
    """The path tracer's pair is the k = 2 case of the one weight over a stack of densities."""
    a, b = pdf_pairs(seed=5, n=5000)
    # Densities whose powers (beta <= 8) stay finite without the pair's rescaling.
    keep = (a > 1e-30) & (b > 1e-30) & (a < 1e30) & (b < 1e30)
    a, b = a[keep], b[keep]
    mis = _mis(heuristic, kw)
    stack = np.stack([a, b])
    np.testing.assert_allclose(mis.pair_weight(a, b), mis.weight(stack, 0), rtol=1e-12, atol=0)
    np.testing.assert_allclose(mis.pair_weight(b, a), mis.weight(stack, 1), rtol=1e-12, atol=0)


@pytest.mark.parametrize("heuristic, kw", VARIANTS, ids=IDS)
@pytest.mark.parametrize("k", [1, 2, 3, 5, 9])
def test_weights_of_a_stack_of_strategies_sum_to_one(heuristic, kw, k):
    """Where no density is a delta (infinite), the weights of the strategies that can make a
    sample (positive density) sum to one; a strategy that cannot (zero density) gets zero."""
    rng = np.random.default_rng(k)
    m = 4000
    densities = np.exp(rng.normal(0, 3, (k, m)))
    densities[rng.random((k, m)) < 0.2] = 0.0
    densities[0] = np.where(densities.max(axis=0) > 0, densities[0], 1.0)  # one can, at least
    possible = densities > 0
    mis = _mis(heuristic, kw)
    weights = np.stack([mis.weight(densities, s, possible) for s in range(k)])
    assert np.isfinite(weights).all() and (weights >= 0).all()
    np.testing.assert_allclose(weights.sum(axis=0), 1.0, rtol=1e-12)
    np.testing.assert_array_equal(weights[~possible], 0.0)


def test_mis_is_built_once_from_the_settings_and_rejects_unknown_settings():
    mis = MIS.from_settings(plain_settings(mis_heuristic="cutoff", mis_beta=3.0, mis_alpha=0.25))
    assert (mis.setting, mis.beta, mis.alpha) == ("cutoff", 3.0, 0.25)
    assert mis.samples_lights and not MIS("bsdf").samples_lights
    with pytest.raises(ValueError, match="heuristic"):
        MIS("nearest")
    # The single strategies weigh a pair, not a stack.
    with pytest.raises(ValueError, match="single strategy"):
        MIS("light").weight(np.ones((2, 1)), 0)
