"""Metropolis light transport (``core/integrators/mlt.py``) on the built-in Cornell box: its
image agrees with the path tracer's over independent seeds, a seed gives the same image
whatever the thread count, every option of its own changes the render, the stats report b and
its standard error, and the settings it uses are the path tracer's plus its own.

No NaN/Inf on the hard cases: ``tests/core/test_hard_cases.py`` renders every case with every
registered integrator, MLT included; cancel: ``tests/core/test_cancel.py``; the integrator
contract: ``tests/core/test_integrator_contract.py``.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from sampling_lab import cli
from sampling_lab.core import scenes
from sampling_lab.core.applied_settings import unused_options, used_settings
from sampling_lab.core.render import render
from tests.helpers import assert_replicates_agree, plain_settings

# The lower three quarters of a 32 x 32 Cornell box: the area light, seen directly, is left
# out of the window (its huge luminance would make b, which scales the whole image, the
# dominant error; see docs/INTEGRATORS.md).
REGION = (0, 0, 32, 24)
REPLICATES = 20


@functools.lru_cache(maxsize=1)
def _scene():
    return scenes.cornell_box(32, 32, "area")


def _settings(integrator, seed=0, **kw):
    base = dict(integrator=integrator, spp=16, seed=seed, threads=2, max_bounces=4,
                region=REGION, mlt_bootstrap=16384)
    return plain_settings(**{**base, **kw})


def _replicates(integrator):
    out, prepared = [], None
    for seed in range(REPLICATES):
        result = render(_scene(), _settings(integrator, seed), prepared=prepared)
        assert result.error is None, result.error
        prepared = result.prepared
        out.append(result.combined()[..., :3].astype(np.float64))
    return np.array(out)


def test_mlt_image_agrees_with_the_path_tracer_over_seeds():
    """20 MLT renders (16 mutations per pixel, b from 16,384 bootstrap paths) against 20 path
    tracer renders (16 spp), different seeds: the image mean and every 8 x 8 block mean per
    channel agree within Welch t intervals (Bonferroni over 39 means, p_false 1e-4). The seeds
    make the renders independent, so the spread of their block means is an honest variance
    although MLT's pixels are correlated within a render. Measured: it detects a 3.7 %
    image-mean error (mostly b's 1 % error per render) and a 31 % 8 x 8 block error with 99 %
    power (16 renders a side detected 4.0 % with pbrt's roulette, 4.5 % with the square-root
    rule: too close to the 4.5 % asked); the same images scaled by 1.05 (b off by 5 %) fail
    it."""
    mlt, path = _replicates("mlt"), _replicates("path")
    assert mlt.max() > 0 and np.isfinite(mlt).all()
    assert_replicates_agree(mlt, path, detect=(0.045, 0.5), what="mlt vs path")
    with pytest.raises(AssertionError):
        assert_replicates_agree(mlt * 1.05, path, detect=None, what="mlt x 1.05")


def test_same_seed_gives_the_same_image_whatever_the_threads():
    one = render(_scene(), _settings("mlt", spp=4, threads=1))
    two = render(_scene(), _settings("mlt", spp=4, threads=2))
    assert np.array_equal(one.combined(), two.combined())
    assert one.stats["spp"] == 4


def test_each_metropolis_option_changes_the_render():
    """Large-step probability, bootstrap paths and chains per batch each change the image (the
    add-on shows them active for MLT only)."""
    base = render(_scene(), _settings("mlt", spp=2, mlt_chains=256)).combined()
    for change in (dict(mlt_large_step=0.9), dict(mlt_bootstrap=8192), dict(mlt_chains=128)):
        image = render(_scene(), _settings("mlt", spp=2, **{"mlt_chains": 256, **change}))
        assert not np.array_equal(image.combined(), base), change


def test_stats_report_b_its_standard_error_and_the_mutations():
    result = render(_scene(), _settings("mlt", spp=3))
    stats = result.stats
    pixels = 32 * 24
    assert stats["spp"] == 3 and stats["mlt_mutations"] == 3 * pixels
    assert stats["samples"] == 3 * pixels
    assert stats["mlt_b"] > 0 and 0 < stats["mlt_b_se"] < stats["mlt_b"]
    assert stats["mlt_b_rel_se"] == pytest.approx(stats["mlt_b_se"] / stats["mlt_b"])
    assert stats["mlt_bootstrap_paths"] == 16384 and stats["mlt_chains"] == pixels
    assert 0 < stats["mlt_acceptance"] < 1
    assert stats["mlt_large_step"] == 0.3 and "consistent" in stats["estimator_bias"]
    # Correlated pixels: the Variance pass is zero, not estimated (up to the film's rounding).
    assert result.variance().max() <= 1e-9 * result.combined()[..., :3].max() ** 2


def test_used_settings_are_the_path_tracers_plus_the_metropolis_options():
    mlt = used_settings(plain_settings(integrator="mlt", diffuse_bounces=2))
    path = used_settings(plain_settings(integrator="path", diffuse_bounces=2))
    assert mlt["diffuse_bounces"] == 2 and mlt["mis_heuristic"] == path["mis_heuristic"]
    assert mlt["light_sampling"] == path["light_sampling"]
    assert (mlt["mlt_large_step"], mlt["mlt_bootstrap"]) == (0.3, 100000)
    for other in ("path", "bdpt", "sppm", "radiosity"):
        used = used_settings(plain_settings(integrator=other))
        assert {used[name] for name in ("mlt_large_step", "mlt_bootstrap",
                                        "mlt_chains")} == {"n/a"}, other
    assert "mlt_chains" in unused_options(plain_settings(integrator="path"))
    assert "mlt_chains" not in unused_options(plain_settings(integrator="mlt"))


def test_command_line_renders_with_metropolis(tmp_path, capsys):
    out = tmp_path / "mlt.exr"
    code = cli.main(["render", "cornell", "-o", str(out), "--integrator", "mlt", "--spp", "2",
                     "--resolution", "16x12", "--mlt-large-step", "0.5", "--mlt-bootstrap",
                     "2000", "--mlt-chains", "64", "--quiet"])
    assert code == 0 and out.exists()
    assert cli.main(["render", "cornell", "-o", str(out), "--integrator", "mlt",
                     "--mlt-large-step", "1.5", "--quiet"]) == 2
    assert "mlt_large_step" in capsys.readouterr().err


def test_chain_count_gives_each_chain_about_512_mutations_of_the_budget():
    """Enough chains for each to run ``TARGET_STEPS`` mutations, within [256, mlt_chains] per
    batch of four, never more than pixels (the gap-room benchmark: many short chains leave
    blotches)."""
    from sampling_lab.core.integrators.mlt import MLT
    from sampling_lab.core.prepare import prepare

    prep = prepare(_scene())

    def count(pixels, **kw):
        return MLT(prep, plain_settings(integrator="mlt", **kw)).chain_count(pixels)

    assert count(1920 * 1080, spp=16) == 4 * 8192  # 33 M mutations: capped by mlt_chains
    assert count(1920 * 1080, spp=16, mlt_chains=20000) == 4 * 16200
    assert count(160 * 120, spp=32) == 4 * 300  # 614,400 mutations / 2,048
    assert count(160 * 120, spp=0, time_limit=10.0) == 4 * 600  # 64 per pixel planned
    assert count(32 * 24, spp=16) == 32 * 24  # at least 256 per batch, at most one per pixel
