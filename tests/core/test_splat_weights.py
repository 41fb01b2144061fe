"""BDPT's ``t = 1`` MIS weights of every light-vertex depth in one pass
(:func:`core.integrators.mis_densities.splat_weights`) against the depth-by-depth reference
(:func:`~core.integrators.mis_densities.splat_weight`).

Property: for the balance, power (beta 2, 3.5, 0.5) and 'none' heuristics the two give the
same weights to the last bit (compared as bytes), for strategies ``s = 2 .. 8`` of random
subpaths: densities over 24 decades with zeros, delta vertices (including the splat's own
and its neighbour), delta lights, and light vertices after an infinite emitter (``d_prev``
inf). Smallest error detected: one weight differing in its last bit (a term added in another
order, a missing or extra strategy).
"""

from types import SimpleNamespace

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.integrators.lambert_vertices import LambertVertices
from sampling_lab.core.integrators.mis_densities import splat_weight, splat_weights
from sampling_lab.core.sampling.mis import MIS

SUMMED = [MIS("balance"), MIS("power", 2.0), MIS("power", 3.5), MIS("power", 0.5),
          MIS("none")]


def _density(rng, shape):
    p = np.exp(rng.uniform(-28, 28, shape))
    return np.where(rng.random(shape) < 0.05, 0.0, p)


def _case(rng, mis, depth=8, n=300):
    """Random stored light subpaths, splats of strategies 2 .. depth (sorted) and a ctx."""
    delta = rng.random((depth, n)) < 0.25
    delta[0] = False
    d_prev = rng.uniform(0.1, 5.0, (depth, n))
    d_prev[1, rng.random(n) < 0.2] = np.inf
    L = SimpleNamespace(valid=np.ones((depth, n), bool), pdf_fwd=_density(rng, (depth, n)),
                        pdf_rev=_density(rng, (depth, n)), delta=delta,
                        cos_prev=rng.uniform(-1, 1, (depth, n)), d_prev=d_prev)
    s = np.concatenate([np.full(rng.integers(1, 60), k) for k in range(2, depth + 1)])
    rows = np.concatenate([np.sort(rng.choice(n, (s == k).sum(), replace=False))
                           for k in range(2, depth + 1)])
    m = s.size
    unit = lambda v: v / np.linalg.norm(v, axis=1, keepdims=True)  # noqa: E731
    yv = LambertVertices(None, None, rng.uniform(-1, 1, m), unit(rng.normal(size=(m, 3))))
    ctx = SimpleNamespace(cam=scenes.cornell_box(32, 32).camera, film_pixels=None, mis=mis,
                          light_points=SimpleNamespace(delta_light=rng.random(n) < 0.3))
    args = (rows, yv, unit(rng.normal(size=(m, 3))), rng.uniform(-1, 1, m),
            rng.uniform(0.2, 6.0, m), rng.uniform(0.05, 1.0, m))
    return ctx, L, s, args


@pytest.mark.parametrize("mis", SUMMED, ids=lambda m: f"{m.setting} {m.beta}")
def test_one_pass_splat_weights_equal_the_depth_by_depth_weights_bit_for_bit(mis):
    rng = np.random.default_rng(5)
    ctx, L, s, (rows, yv, w, w_y, dist, cos_theta) = _case(rng, mis)
    got = splat_weights(ctx, L, s, rows, yv, w, w_y, dist, cos_theta)
    assert np.isfinite(got).all() and (got >= 0).all() and (got <= 1).all()
    for k in range(2, 9):
        e = np.flatnonzero(s == k)
        ref = splat_weight(ctx, L, k, rows[e], yv.for_densities(e), w[e], w_y[e], dist[e],
                           cos_theta[e])
        assert got[e].tobytes() == ref.tobytes(), k
    assert ((got > 0) & (got < 1)).mean() > 0.5  # most splats share with other strategies
