"""BDPT's connection stage (:func:`core.integrators.connections.connect_all`) adds its pieces
strategy by strategy without joining and sorting them, and gives what a join, a stable sort
by strategy and one sum per strategy give, to the last bit.

Restructuring only: every comparison here is exact (``assert_array_equal``). Adding the
strategies in another order changes the last bits of some sums (found: swapping the order of
``t`` and ``s`` in the runs' sort fails the image test), and a dropped, doubled or misplaced
run changes them by a whole contribution.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.film import PixelFilter
from sampling_lab.core.integrators import connections
from sampling_lab.core.integrators.base import Counters
from sampling_lab.core.integrators.bdpt import BDPT, _fresh_points
from sampling_lab.core.integrators.lambert_vertices import gatherer
from sampling_lab.core.integrators.mis_densities import Near, connection_weight
from sampling_lab.core.integrators.mis_sums import RunningSums, summable
from sampling_lab.core.lights.emission import EmitterPoints
from sampling_lab.core.prepare import prepare
from sampling_lab.core.sampling.samplers import make_sampler
from tests.helpers import plain_settings


def _joined(t, s, rows):
    m = len(rows)
    cols = [np.asarray(s), np.asarray(t), np.asarray(rows), np.ones((m, 3))]
    return connections._Joined(*cols, *[np.ones(m)] * 5, np.zeros(m, bool))


def test_strategy_runs_cover_every_connection_once_in_strategy_order():
    rng = np.random.default_rng(3)
    parts = []
    for _ in range(6):  # pieces in strategy order, as the joins make them
        t = np.sort(rng.integers(2, 6, 40))
        s = np.where(rng.random(40) < 0.3, 1, rng.integers(2, 5, 40))
        key = np.lexsort((s, t))
        parts.append(_joined(t[key], s[key], rng.integers(0, 1000, 40)))
    runs = connections._strategy_runs(parts)
    assert [(t, s) for s, t, _, _ in runs] == sorted((t, s) for s, t, _, _ in runs)
    seen = [np.zeros(p.row.size, int) for p in parts]
    for s, t, i, e in runs:
        assert (parts[i].s[e] == s).all() and (parts[i].t[e] == t).all()
        seen[i][e] += 1
    assert all((c == 1).all() for c in seen)


def _connections_of_a_batch(scene, piece, **settings):
    """``(ctx, L, C, fresh, (image, strategy layers) before, tally after)`` of BDPT's
    connection stage on one
    batch (the first 256 pixels, one sample each), with pieces of ``piece`` connections."""
    seen = []

    class Probe(BDPT):
        def connect(self, ctx, stream, C, L, out):
            fresh = _fresh_points(ctx, stream, C)
            before = out.image.copy(), {k: v.copy() for k, v in out.camera_layers.items()}
            connections.connect_all(ctx, L, C, fresh, out)
            seen.append((ctx, L, C, fresh, before, out))

    options = plain_settings(integrator="bdpt", spp=1, max_bounces=5, **settings)
    integ = Probe(prepare(scene), options)
    sampler = make_sampler("independent", seed=5, spp=1, width=scene.camera.width)
    old, connections.PIECE = connections.PIECE, piece
    try:
        integ.render_samples(sampler.stream(np.arange(256), np.zeros(256, np.int64)),
                             PixelFilter(options.filter_type, options.filter_width), Counters())
    finally:
        connections.PIECE = old
    return seen[-1]


def _sorted_sums(ctx, L, C, fresh, before):
    """The image and strategy layers, from those ``before`` the stage, as one join, a stable
    sort by ``(t, s)`` and one sum per strategy make them (the stage's former form)."""
    image, layers = before[0].copy(), {k: v.copy() for k, v in before[1].items()}
    gather = gatherer(ctx, L, C)
    parts = [*connections._connect_emitters(ctx, L, C, fresh, gather),
             *connections._connect_vertices(ctx, L, C, gather)]
    j = connections._Joined(*(np.concatenate(c) for c in zip(*parts)))
    order = np.argsort(j.t * 1000 + j.s, kind="stable")
    j = connections._Joined(*(c[order] for c in j))
    sums = RunningSums(ctx.mis, L, C, ctx.light_points.delta_light) if summable(ctx.mis) else None
    for s, t in sorted({(int(s), int(t)) for s, t in zip(j.s, j.t)}, key=lambda st: st[::-1]):
        e = np.nonzero((j.s == s) & (j.t == t))[0]
        near = Near(*(c[e] for c in j[4:]))
        weight = (sums.weights(L, C, j.s[e], j.t[e], j.row[e], near) if sums is not None
                  else connection_weight(ctx.mis, L, C, s, t, j.row[e], near))
        image[j.row[e]] += j.value[e] * weight[:, None]
        if s + t - 1 <= ctx.view_length:
            for name, v in ((f"Strategy s{s} t{t}", j.value[e]),
                            (f"Strategy s{s} t{t} weighted", j.value[e] * weight[:, None])):
                layers.setdefault(name, np.zeros_like(image))[j.row[e]] += v
    return image, layers


@pytest.mark.parametrize("mis, views", [("power", False), ("balance", True), ("maximum", True)])
def test_connection_sums_equal_one_sorted_sum_per_strategy_bit_for_bit(mis, views):
    scene = scenes.cornell_box(16, 16, "mesh")
    # Pieces of 97 connections: runs of one strategy span pieces.
    ctx, L, C, fresh, before, out = _connections_of_a_batch(
        scene, 97, mis_heuristic=mis, strategy_views=views, strategy_max_length=4)
    image, layers = _sorted_sums(ctx, L, C, fresh, before)
    assert np.count_nonzero(image != before[0]) > 100  # connections were added
    np.testing.assert_array_equal(out.image, image)
    assert sorted(out.camera_layers) == sorted(layers)
    for name, v in layers.items():
        np.testing.assert_array_equal(out.camera_layers[name], v)


def test_emitter_directions_without_infinite_emitters_equal_the_general_form_bit_for_bit():
    rng = np.random.default_rng(11)
    m = 3000
    normal = rng.normal(size=(m, 3))
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    p = rng.normal(size=(m, 3)) * np.exp(rng.uniform(-8, 8, (m, 1)))
    z = p + rng.normal(size=(m, 3)) * np.exp(rng.uniform(-12, 4, (m, 1)))
    z[:5] = p[:5]  # a zero distance
    infinite = np.zeros(m, bool)
    infinite[-1] = True  # one infinite point sends the whole batch through the general form
    w_inf = np.zeros((m, 3))
    w_inf[-1] = (0.0, 0.0, -1.0)
    pts = EmitterPoints(np.zeros(m, np.int64), p, normal, w_inf, np.ones(m), np.zeros(m, bool),
                        infinite)
    general = connections._toward_emitters(pts, z)
    finite = connections._toward_emitters(EmitterPoints(*(a[:-1] for a in pts)), z[:-1])
    for a, b in zip(finite, general):
        np.testing.assert_array_equal(a, b[:-1])
    assert general[1][-1] == np.inf and general[3][-1] == 1.0 and not general[2][-1].any()
