"""``bdpt-error`` (``tools/bdpt_error.py``): the split of BDPT's error by strategy and by render.

On synthetic views the shares are checked against their known values; on a tiny rendered scene
the covariance shares must add up to the whole error when the views cover every path (the
weighted views add up to the image) and leave a remainder when they do not. Figures only: no
speed is asserted.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab import cli
from sampling_lab.tools import bdpt_error


def _synthetic(n, rng, sigma=(3.0, 1.0), mean=10.0, shape=(2, 3)):
    """Two independent strategies of known standard deviations around ``mean / 2`` each."""
    views = {(1, 2): mean / 2 + sigma[0] * rng.standard_normal((n, *shape, 3)),
             (2, 1): mean / 2 + sigma[1] * rng.standard_normal((n, *shape, 3))}
    return views[(1, 2)] + views[(2, 1)], views


def test_shares_of_independent_strategies_are_their_variances_over_the_total():
    n = 20000
    images, views = _synthetic(n, np.random.default_rng(5))
    out = bdpt_error.shares(images, views)
    got = {(s, t): (var, cov) for s, t, var, cov in out["strategies"]}
    # Each share is a ratio of variance estimates over n * 6 values: relative standard error
    # about sqrt(2 / (n * 6)) = 0.4 %, so 2 % absolute (5 sigma) detects an error of 2 % of
    # the total, e.g. a share taken against the wrong denominator or a missing n - 1.
    assert got[(1, 2)][0] == pytest.approx(0.9, abs=0.02)
    assert got[(2, 1)][0] == pytest.approx(0.1, abs=0.02)
    assert got[(1, 2)][1] == pytest.approx(0.9, abs=0.02)
    assert out["covered"] == pytest.approx(1.0, abs=1e-9)  # an identity: views add up
    # total: mean of w * (9 + 1) with w = 1 / (10^2 + EPS); 2 % detects the same slips.
    assert out["total"] == pytest.approx(10.0 / (100.0 + bdpt_error.EPS), rel=0.02)
    assert np.mean(out["per_render"]) == pytest.approx(out["total"], rel=1e-9)


def test_the_worst_render_pixel_and_strategy_are_found():
    rng = np.random.default_rng(6)
    images, views = _synthetic(64, rng, sigma=(0.1, 0.1))
    views[(2, 1)][17, 1, 2] += 40.0  # a rare large sample of one strategy in one render
    images[17, 1, 2] += 40.0
    out = bdpt_error.shares(images, views)
    assert out["worst"] == 17 and out["worst_pixel"] == (1, 2)
    assert out["worst_pixel_share"] > 0.99
    s, t, share = out["worst_pixel_strategies"][0]
    assert (s, t) == (2, 1) and share > 0.99


def test_covariance_shares_add_up_to_the_error_only_when_the_views_cover_every_path():
    """Rendered: views up to max bounces + 2 segments cover every path of the Cornell box, and
    their covariance shares sum to one (to rounding); views of one and two segments leave out
    the indirect light, whose share shows as the remainder."""
    kw = dict(scene="cornell", bench=False, size=(8, 8), spp=2, renders=4, max_bounces=2,
              threads=1, progress=None)
    full = bdpt_error.run(max_length=4, **kw)
    assert full["covered"] == pytest.approx(1.0, abs=1e-6)
    assert sum(r[2] for r in full["worst_pixel_strategies"]) == pytest.approx(1.0, abs=1e-6)
    assert all(r[2] >= 0 for r in full["strategies"]) and full["total"] > 0
    short = bdpt_error.run(max_length=2, **kw)
    assert short["total"] == pytest.approx(full["total"], rel=1e-9)  # same seeds, same image
    assert short["covered"] < 0.9


def test_command_writes_its_table_inside_its_output_folder(tmp_path, capsys):
    out = tmp_path / "given"
    code = cli.main(["bdpt-error", "--scene", "cornell", "--size", "6x6", "--spp", "1",
                     "--renders", "3", "--max-length", "3", "--max-bounces", "1",
                     "--output", str(out)])
    assert code == 0
    assert [p.name for p in out.iterdir()] == ["bdpt_error_cornell.csv"]
    rows = (out / "bdpt_error_cornell.csv").read_text().splitlines()
    assert rows[0].startswith("kind,s,t,variance_share,covariance_share")
    assert sum(r.startswith("render,") for r in rows) == 3
    assert "worst render" in capsys.readouterr().out
