"""BDPT's Connection Roulette (:mod:`core.integrators.connection_roulette`): Russian roulette
of connections before their shadow rays, an unbiased option.

Properties: the survivors, divided by their survival probability, keep every connection's
expected value (a roulette that forgot the division, or divided by the wrong probability,
fails); the decisions' numbers are uniform and reproducible; a BDPT render with the roulette
agrees with one without it (independent replicates) while tracing fewer rays; the stats say
what was used, and the option applies to BDPT alone.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core.integrators.connection_roulette import (ConnectionRoulette, survival,
                                                               uniforms)
from sampling_lab.core.render import render
from sampling_lab.core.scenes import cornell_box
from tests.helpers import (assert_mean_within_ci, assert_replicates_agree, ks_uniform_test,
                           plain_settings)


def test_survival_is_one_above_the_threshold_and_proportional_below():
    c = np.array([0.1, 0.5, 1.0, 2.0, 6.4])  # mean 2.0
    np.testing.assert_allclose(survival(c, 0.5), [0.1, 0.5, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(survival(c, 2.0), [0.025, 0.125, 0.25, 0.5, 1.0])


def test_uniforms_are_uniform_and_reproducible():
    pixel = np.repeat(np.arange(500), 40)
    sample = np.tile(np.arange(40), 500)
    key = 3 * 1024 + (np.arange(pixel.size) % 5)
    u = uniforms(7, pixel, sample, key)
    ks_uniform_test(u, what="roulette numbers")
    assert np.array_equal(u, uniforms(7, pixel, sample, key))
    assert not np.array_equal(u, uniforms(8, pixel, sample, key))  # the seed changes them


def test_survivors_divided_by_their_probability_keep_every_expected_value():
    """20,000 independent roulettes (seeds) of 40 connections with contributions from 1e-3
    to 3 times the mean; the mean of each connection's thinned value must be its value.
    Smallest error detected: a connection with survival probability q has per-draw standard
    deviation v sqrt(1/q - 1), so a relative error of about 4.3 sqrt((1/q - 1) / 20,000):
    9 % at q = 0.1 (the bias of the missing division is 1 - q, 90 %)."""
    rng = np.random.default_rng(3)
    m = 40
    value = rng.uniform(0.1, 1.0, (m, 3)) * np.geomspace(1e-3, 3.0, m)[:, None]
    cand = np.arange(m)
    rows = np.arange(m)
    keys = np.full(m, 2 * 1024 + 2)
    draws = 20_000
    out = np.zeros((draws, m, 3))
    for i in range(draws):
        roulette = ConnectionRoulette(0.8, seed=i, pixel=np.arange(m), sample_index=np.zeros(m))
        v = value.copy()
        kept = roulette.thin(v, cand, rows, keys)
        out[i, kept] = v[kept]
    q = survival(value.max(axis=1), 0.8)
    assert 0.0 < q.min() < 0.01 and (q == 1.0).any()  # from almost never to always kept
    assert_mean_within_ci(out, value, what="thinned connection values")


@pytest.fixture(scope="module")
def box():
    return cornell_box(16, 16, "mesh")


def _replicates(scene, runs, **kw):
    imgs, rays = [], []
    for i in range(runs):
        res = render(scene, plain_settings(integrator="bdpt", spp=16, seed=11 + 1000 * i,
                                           max_bounces=3, **kw))
        img = res.film.mean()
        assert np.isfinite(img).all() and (img >= 0).all()
        imgs.append(img)
        rays.append(res.stats["rays"])
    return np.stack(imgs), np.mean(rays), res


def test_bdpt_with_connection_roulette_agrees_with_bdpt_without_and_traces_fewer_rays(box):
    """A strong roulette (factor 2: most connections below the threshold) against none, 24
    independent renders of 16 samples per pixel each, block by block (`assert_replicates_agree`; it must be able to
    see 2 % of the image mean and 15 % of a block). A roulette that forgot to divide the
    survivors by their probability darkens the connections' share by about a third here and
    fails."""
    off, rays_off, res_off = _replicates(box, 24)
    on, rays_on, res_on = _replicates(box, 24, connection_roulette=2.0)
    found = assert_replicates_agree(on, off, detect=(0.02, 0.15),
                                    what="BDPT with vs without connection roulette")
    print(f"roulette / none: image mean ratio {np.round(found.ratio, 4)}, rays "
          f"{rays_on / rays_off:.3f}")
    assert rays_on < 0.9 * rays_off
    assert res_on.stats["connection_roulette"] == 2.0
    assert res_off.stats["connection_roulette"] == 0.0


def test_connection_roulette_changes_bdpt_renders_and_no_other_integrator(box):
    def image(integrator, factor):
        return render(box, plain_settings(integrator=integrator, spp=2, seed=4, max_bounces=3,
                                          connection_roulette=factor)).film.mean()

    assert not np.array_equal(image("bdpt", 0.5), image("bdpt", 0.0))
    for integrator in ("path", "light"):
        assert np.array_equal(image(integrator, 0.5), image(integrator, 0.0))
        res = render(box, plain_settings(integrator=integrator, spp=1, connection_roulette=0.5))
        assert res.stats["connection_roulette"] == "n/a"


def test_negative_or_nan_connection_roulette_is_refused_with_its_name(box):
    from sampling_lab.core.render import check_settings

    for bad in (-0.1, float("nan"), 11.0):
        with pytest.raises(ValueError, match="connection_roulette"):
            check_settings(box, plain_settings(integrator="bdpt", connection_roulette=bad))
