"""The sampler lab's measures, and what they show about every sampler.

The lecture's claims, checked with confidence intervals: stratified and low-discrepancy samplers
have lower variance than independent sampling on the checkerboard at equal n and converge faster
(log-log slope steeper than -1, independent ~ -1); blue-noise sets have less low-frequency power
than white noise.
"""

import itertools

import numpy as np
import pytest

from sampling_lab.core.sampling import lab
from sampling_lab.core.sampling.samplers import available
from tests.helpers import z_for_false_failure

NS = (4, 16, 64, 256)
PIXELS = 1024
SAMPLERS = [s for s in available() if s != "independent"]
BLUE_NOISE = [s for s in ("poisson_disk", "lloyd", "cvt") if s in available()]


def brute_star_discrepancy(p):
    """max over boxes [0,a)x[0,b) and [0,a]x[0,b] with corners on the points' coordinates."""
    xs = np.concatenate([p[:, 0], [1.0]])
    ys = np.concatenate([p[:, 1], [1.0]])
    n = len(p)
    worst = 0.0
    for a, b in itertools.product(xs, ys):
        open_count = np.count_nonzero((p[:, 0] < a) & (p[:, 1] < b))
        closed_count = np.count_nonzero((p[:, 0] <= a) & (p[:, 1] <= b))
        worst = max(worst, a * b - open_count / n, closed_count / n - a * b)
    return worst


def test_star_discrepancy_of_one_centred_point_is_three_quarters():
    assert lab.star_discrepancy(np.array([[0.5, 0.5]])) == pytest.approx(0.75)


def test_star_discrepancy_of_the_centred_2x2_grid():
    grid = np.array([[0.25, 0.25], [0.75, 0.25], [0.25, 0.75], [0.75, 0.75]])
    assert lab.star_discrepancy(grid) == pytest.approx(brute_star_discrepancy(grid))
    assert lab.star_discrepancy(grid) == pytest.approx(7 / 16)


@pytest.mark.parametrize("seed", range(5))
def test_star_discrepancy_matches_brute_force_on_random_sets(seed):
    p = np.random.default_rng(seed).random((23, 2))
    assert lab.star_discrepancy(p) == pytest.approx(brute_star_discrepancy(p), abs=1e-12)


def test_periodogram_of_white_noise_averages_one():
    rng = np.random.default_rng(1)
    power = lab.periodogram(rng.random((64, 128, 2)), 8)
    values = power[:, np.arange(17) != 8][:, :, np.arange(17) != 8].reshape(64, -1).mean(axis=1)
    z = z_for_false_failure(1e-4)
    assert abs(values.mean() - 1.0) < z * values.std(ddof=1) / np.sqrt(values.size)


def test_periodogram_of_a_regular_grid_peaks_at_its_frequency():
    g = (np.stack(np.meshgrid(np.arange(8), np.arange(8)), -1).reshape(-1, 2) + 0.5) / 8
    power = lab.periodogram(g, 10)
    assert power[10, 10 + 8] == pytest.approx(64.0)      # k = (8, 0): every point in phase
    assert power[10, 10 + 3] == pytest.approx(0.0, abs=1e-9)


@pytest.fixture(scope="module")
def independent_study():
    return lab.checkerboard_study("independent", NS, PIXELS, seed=11)


def test_independent_checkerboard_variance_falls_as_one_over_n(independent_study):
    rows, (slope, se_fit, se_sampling) = independent_study
    for r in rows:
        z = z_for_false_failure(1e-4, comparisons=len(rows))
        assert abs(r["variance"] - r["independent_variance"]) < z * r["variance_se"]
    assert abs(slope + 1.0) < z_for_false_failure(1e-4) * se_sampling


@pytest.mark.parametrize("name", SAMPLERS)
def test_sampler_beats_independent_on_the_checkerboard_and_converges_faster(name,
                                                                            independent_study):
    rows, (slope, se_fit, se_sampling) = lab.checkerboard_study(name, NS, PIXELS, seed=23)
    ind_rows, _ = independent_study
    z = z_for_false_failure(1e-4, comparisons=len(NS) + 1)
    for r, ri in zip(rows, ind_rows):
        if r["n"] < 64:
            # The checkerboard has 3 x 3 tilted periods: with 16 points or fewer a stratum spans
            # several cells, and stratification promises little (measured: Hammersley's 16-point
            # net is no better than random there). The claim is about the convergence regime.
            continue
        gap = ri["variance"] - r["variance"]
        assert gap > z * np.hypot(r["variance_se"], ri["variance_se"]), (name, r["n"], r, ri)
    assert slope + z * se_sampling < -1.0, (name, slope, se_sampling)


@pytest.mark.parametrize("name", BLUE_NOISE)
def test_blue_noise_sets_have_less_low_frequency_power_than_white_noise(name):
    n, realizations = 256, 24
    k_max = int(np.ceil(lab.LOW_BAND * np.sqrt(n))) + 1
    pts = lab.sample_points(name, n, np.arange(realizations))
    white = lab.sample_points("independent", n, np.arange(realizations))
    blue_low = lab.low_frequency_power(lab.periodogram(pts, k_max), n)
    white_low = lab.low_frequency_power(lab.periodogram(white, k_max), n)
    z = z_for_false_failure(1e-4)
    se = np.hypot(blue_low.std(ddof=1), white_low.std(ddof=1)) / np.sqrt(realizations)
    assert white_low.mean() - blue_low.mean() > z * se
    assert blue_low.mean() < 0.5


def test_lab_run_writes_csv_png_and_markdown(tmp_path):
    out = tmp_path / "lab"
    md = tmp_path / "SAMPLERS.md"
    assert lab.main(["--quick", "--output", str(out), "--markdown", str(md),
                     "--sampler", "independent", "--sampler", "sobol"]) in (0, None)
    assert (out / "checkerboard.csv").is_file() and (out / "checkerboard.png").is_file()
    assert (out / "points_sobol.csv").is_file() and (out / "points.png").is_file()
    text = md.read_text()
    assert "sobol" in text.lower() and "|" in text
