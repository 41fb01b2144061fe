"""The sampler figures committed in ``docs/`` are what ``python -m sampling_lab samplers`` computes.

``docs/samplers/summary.csv``, ``docs/samplers/checkerboard.csv`` and the table in
``docs/SAMPLERS.md`` are written by :func:`tools.sampler_lab.run` with its full settings and seed
0. Every figure in them except the ``seconds`` column is a deterministic function of the code:
the samplers are deterministic in (pixel, sample index, dimension, seed) and the blue-noise
tables depend only on (kind, N, set seed, generator version). So a fresh run must reproduce them.

The fresh run uses an empty table cache: the blue-noise rows once went stale because they were
measured on point sets and masks cached by an earlier generator, and a run that reads the
machine's cache would repeat that mistake instead of catching it.

Tolerances
    Numbers are compared with ``rtol = 1e-7``: the CSV files keep 9 significant digits (a
    rounding of at most 5e-9 relative), and float64 sums, the periodogram's complex products and
    the slope fit may differ between NumPy and BLAS builds by about 1e-13 relative. A changed
    point set moves these figures by 1e-4 relative or more (the stale blue-noise rows were off
    by 10 to 20 %). ``atol = 1e-12`` only matters for the low-frequency power's standard error
    of the blue-noise samplers, which is rounding noise (about 1e-17: every pixel shows the
    same set, shifted). The markdown table prints 2 to 4 digits and must match exactly.
"""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path

import numpy as np
import pytest

from sampling_lab.core.sampling.samplers import available, bluenoise
from sampling_lab.tools import sampler_lab

DOCS = Path(__file__).resolve().parents[2] / "docs"
RTOL = 1e-7
ATOL = 1e-12
TIMING_COLUMNS = {"seconds"}


def read_rows(path):
    """The rows of a lab CSV file as dicts of strings."""
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    """A fresh full run of the lab (no plots) into a temporary folder, with an empty table cache."""
    out = tmp_path_factory.mktemp("sampler_docs")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("SAMPLING_LAB_CACHE", str(out / "cache"))
        # The PNGs are not figures; drawing them would only cost time.
        mp.setattr(sampler_lab, "_pyplot", lambda: None)
        bluenoise.clear_memo()
        try:
            res = sampler_lab.run(output=str(out / "samplers"), markdown=str(out / "SAMPLERS.md"),
                                  seed=0, log=lambda message: None)
        finally:
            bluenoise.clear_memo()
    assert not res["failures"], res["failures"]
    return out


def assert_rows_match(committed, computed, key_columns, what):
    """Committed and computed CSV rows agree on every non-timing column (see the tolerances)."""
    assert [tuple(r[k] for k in key_columns) for r in committed] == \
        [tuple(r[k] for k in key_columns) for r in computed], f"{what}: rows differ"
    for old, new in zip(committed, computed):
        assert old.keys() == new.keys(), f"{what}: columns differ"
        for col in old:
            if col in TIMING_COLUMNS or col in key_columns:
                continue
            a, b = float(old[col]), float(new[col])
            assert math.isclose(a, b, rel_tol=RTOL, abs_tol=ATOL), (
                f"{what}, {tuple(old[k] for k in key_columns)}, {col}: committed {old[col]}, "
                f"fresh run {new[col]}")


def test_summary_csv_matches_a_fresh_run(fresh):
    committed = read_rows(DOCS / "samplers" / "summary.csv")
    assert [r["sampler"] for r in committed] == available()
    assert_rows_match(committed, read_rows(fresh / "samplers" / "summary.csv"),
                      ("sampler", "n"), "summary.csv")


def test_checkerboard_csv_matches_a_fresh_run(fresh):
    assert_rows_match(read_rows(DOCS / "samplers" / "checkerboard.csv"),
                      read_rows(fresh / "samplers" / "checkerboard.csv"),
                      ("sampler", "n", "pixels"), "checkerboard.csv")


def test_samplers_md_matches_a_fresh_run(fresh):
    committed = (DOCS / "SAMPLERS.md").read_text().splitlines()
    computed = (fresh / "SAMPLERS.md").read_text().splitlines()
    assert committed == computed


def test_samplers_md_shows_the_committed_summary():
    """The table's star discrepancies are summary.csv's, rounded (the files were written together)."""
    summary = {r["sampler"]: r for r in read_rows(DOCS / "samplers" / "summary.csv")}
    rows = [line for line in (DOCS / "SAMPLERS.md").read_text().splitlines()
            if line.startswith("| ") and "(`" in line]
    assert len(rows) == len(summary)
    for line in rows:
        name = line.split("(`", 1)[1].split("`)", 1)[0]
        cells = [c.strip() for c in line.strip("|").split("|")]
        r = summary[name]
        assert cells[1] == (f"{float(r['star_discrepancy']):.4f} "
                            f"(mean {float(r['star_discrepancy_mean']):.4f})"), name
        assert cells[2] == (f"{float(r['checkerboard_slope']):.2f} ± "
                            f"{float(r['checkerboard_slope_se']):.2f}"), name
        assert cells[4] == (f"{float(r['low_frequency_power']):.3f} ± "
                            f"{float(r['low_frequency_power_se']):.3f}"), name


def test_the_fresh_run_generates_its_own_blue_noise_tables(fresh):
    """The fixture's tables went to its own cache folder, so the comparison measured the code."""
    files = os.listdir(fresh / "cache" / "bluenoise")
    assert any(f.startswith("poisson_disk_n256_") for f in files)
    assert np.all([f.endswith(".npz") for f in files])
