"""BDPT's connection weights by running sums (:mod:`core.integrators.mis_sums`) against the
per-strategy reference (:func:`core.integrators.mis_densities.connection_weight`).

Property: for the balance, power and 'none' heuristics the two give the same weight, to
rounding (relative 1e-9), for every strategy ``s >= 1, t >= 2`` of subpaths up to the depth
limit, on random densities (over 12 decades, with zeros), random delta vertices on both
subpaths (including the vertices next to the connection), delta lights and a fresh emitter
point (``s = 1``); and on the real subpaths of BDPT renders with mirrors, glass, point and
sphere lights, and paths cut by the bounce limit. Smallest error detected: a weight off by a
relative 1e-9 in one connection (a missing or extra strategy changes weights by far more).
"""

from types import SimpleNamespace

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.integrators import connections, mis_sums
from sampling_lab.core.integrators.mis_densities import Near, connection_weight
from sampling_lab.core.render import render
from sampling_lab.core.sampling.mis import MIS
from tests.helpers import plain_settings

SUMMED = [MIS("balance"), MIS("power", 2.0), MIS("power", 3.5), MIS("power", 0.5),
          MIS("none")]
RTOL = 1e-9


def _random_subpath(rng, depth, n, first_vertex_delta=False):
    """Stored densities and delta flags as a walk leaves them (vertex 0 never delta)."""
    def density():
        p = np.exp(rng.uniform(-14, 14, (depth, n)))
        return np.where(rng.random((depth, n)) < 0.05, 0.0, p)

    delta = rng.random((depth, n)) < 0.25
    delta[0] = first_vertex_delta
    return SimpleNamespace(valid=np.ones((depth, n), bool), pdf_fwd=density(),
                           pdf_rev=density(), delta=delta)


def _random_near(rng, m):
    cols = [np.where(rng.random(m) < 0.05, 0.0, np.exp(rng.uniform(-14, 14, m)))
            for _ in range(5)]
    return Near(*cols, rng.random(m) < 0.3)


@pytest.mark.parametrize("mis", SUMMED, ids=lambda m: f"{m.setting} {m.beta}")
def test_running_sum_weights_equal_the_per_strategy_weights_on_random_paths(mis):
    rng = np.random.default_rng(11)
    depth, n = 7, 400
    L, C = _random_subpath(rng, depth, n), _random_subpath(rng, depth, n)
    delta_light = rng.random(n) < 0.3
    sums = mis_sums.RunningSums(mis, L, C, delta_light)
    s_all, t_all, rows, refs, nears = [], [], [], [], []
    for s in range(1, depth + 1):
        for t in range(2, depth + 1):
            row = rng.choice(n, 150, replace=False)
            near = _random_near(rng, row.size)
            if s >= 2:  # as the connections pass them: stored endpoint, the lights' flag
                near = near._replace(light_0=L.pdf_fwd[0, row], delta_light=delta_light[row])
            refs.append(connection_weight(mis, L, C, s, t, row, near))
            s_all.append(np.full(row.size, s))
            t_all.append(np.full(row.size, t))
            rows.append(row)
            nears.append(near)
    # Every strategy in one call, shuffled: the weights may not depend on their order.
    order = rng.permutation(sum(r.size for r in rows))
    near = Near(*(np.concatenate(c)[order] for c in zip(*nears)))
    got = sums.weights(L, C, np.concatenate(s_all)[order], np.concatenate(t_all)[order],
                       np.concatenate(rows)[order], near)
    want = np.concatenate(refs)[order]
    np.testing.assert_allclose(got, want, rtol=RTOL, atol=1e-300)
    assert want.min() < 0.2 and want.max() > 0.9 and np.unique(want).size > 5


def test_heuristics_without_running_sums_are_named():
    assert [mis_sums.summable(MIS(h)) for h in ("balance", "power", "none", "maximum",
                                                "cutoff")] == [True] * 3 + [False] * 2


def _compare_on_render(monkeypatch, scene, mis, **kw):
    """Render BDPT with ``mis`` while every batch's connection weights are also computed by
    the reference; returns the number of connections compared."""
    seen = []
    weights = mis_sums.RunningSums.weights

    def both(self, L, C, s, t, row, near):
        got = weights(self, L, C, s, t, row, near)
        for st in {(int(a), int(b)) for a, b in zip(s, t)}:
            e = np.nonzero((s == st[0]) & (t == st[1]))[0]
            want = connection_weight(self.mis, L, C, *st, row[e], Near(*(c[e] for c in near)))
            np.testing.assert_allclose(got[e], want, rtol=RTOL, atol=1e-300,
                                       err_msg=f"strategy {st}")
        seen.append(s.size)
        return got

    monkeypatch.setattr(mis_sums.RunningSums, "weights", both)
    render(scene, plain_settings(integrator="bdpt", spp=2, seed=5, threads=1,
                                 mis_heuristic=mis.setting, mis_beta=mis.beta, **kw))
    return sum(seen)


@pytest.mark.parametrize("ball, light", [("mirror", "point"), ("glass", "sphere")])
@pytest.mark.parametrize("mis", [MIS("power", 2.0), MIS("balance"), MIS("none")],
                         ids=lambda m: m.setting)
def test_running_sum_weights_equal_the_per_strategy_weights_on_rendered_paths(
        monkeypatch, ball, light, mis):
    scene = scenes.cornell_sphere(12, 12, ball=ball, light=light)
    assert _compare_on_render(monkeypatch, scene, mis, max_bounces=4) > 1000


def test_connect_all_uses_the_running_sums_only_for_summed_heuristics(monkeypatch):
    calls = []
    monkeypatch.setattr(connections, "connection_weight",
                        lambda *a, **k: calls.append(1) or connection_weight(*a, **k))
    scene = scenes.cornell_box(8, 8, "area")
    for h, used in (("power", False), ("maximum", True)):
        calls.clear()
        render(scene, plain_settings(integrator="bdpt", spp=1, seed=1, threads=1,
                                     max_bounces=3, mis_heuristic=h))
        assert bool(calls) == used, h
