"""The hard-scenes benchmark (``python -m sampling_lab bench-scenes``) runs end to end.

A smoke run: one tiny scene, our path tracer and Cycles for half a second each. It checks that
the CSV, the markdown table and the figure are written with finite figures; it says nothing
about speed (``docs/CONVENTIONS.md``, "Tests": speed is never asserted).
"""

import csv
import math

import pytest

from sampling_lab.tools import hard_scenes


def test_bench_scenes_writes_finite_figures_for_path_and_cycles_inside_its_output_folder(
        tmp_path):
    out = tmp_path / "out"
    status = hard_scenes.run(scenes=["mirror_ball"], integrators=["path"], seconds=0.5,
                             size=(16, 16), reference_spp=16, reference_seconds=2.0,
                             output=str(out), repeats=1)
    assert status == 0
    assert [p.name for p in tmp_path.iterdir()] == ["out"]

    with open(out / "hard_scenes.csv") as f:
        rows = list(csv.DictReader(f))
    assert sorted(r["renderer"] for r in rows) == ["Cycles", "path"]
    for r in rows:
        for key in ("spp", "time_s", "samples_per_s", "relmse_vs_ref", "relmse_vs_cycles_ref",
                    "mean_over_ref"):
            assert math.isfinite(float(r[key])), (r["renderer"], key, r[key])
        assert float(r["spp"]) >= 1

    text = (out / "HARD_SCENES.md").read_text()
    assert "| mirror_ball | path |" in text and "| mirror_ball | Cycles |" in text
    assert "load average" in text
    assert (out / "images" / "hard_scenes.png").is_file()
    assert (out / "hard_scenes_summary.csv").is_file()


def test_bench_scenes_repeats_every_equal_time_render_with_seeds_no_reference_uses(tmp_path):
    """``repeats=2``: two rows per renderer in the CSV, each with its own seed outside the
    references' seeds; the report's line for each renderer is the mean of its two renders'
    errors at the budget, with their spread and each render's figure, and the ratio to Cycles is
    the ratio of the means."""
    out = tmp_path / "out"
    status = hard_scenes.run(scenes=["mirror_ball"], integrators=["path"], seconds=0.4,
                             size=(12, 12), reference_spp=8, reference_seconds=1.0,
                             output=str(out), repeats=2, seed=3)
    assert status == 0
    with open(out / "hard_scenes.csv") as f:
        rows = list(csv.DictReader(f))
    by = {}
    for r in rows:
        by.setdefault(r["renderer"], []).append(r)
    reference_seeds = {3 + 1 + i for i in range(hard_scenes.CHUNKS)}
    assert sorted(by) == ["Cycles", "path"]
    for renderer, group in by.items():
        seeds = [int(r["seed"]) for r in group]
        assert [int(r["repeat"]) for r in group] == [0, 1] and len(set(seeds)) == 2, group
        assert not set(seeds) & reference_seeds, seeds
        for r in group:
            assert math.isfinite(float(r["relmse_at_budget"])), r

    text = (out / "HARD_SCENES.md").read_text()
    means = {}
    for renderer, group in by.items():
        each = [float(r["relmse_at_budget"]) for r in group]
        means[renderer] = sum(each) / 2
        line = next(x for x in text.splitlines() if x.startswith(f"| mirror_ball | {renderer} |"))
        cells = [c.strip() for c in line.split("|")[1:-1]]
        assert cells[2] == "2"
        assert float(cells[8].split()[0].strip("*")) == pytest.approx(means[renderer], rel=0.01)
        assert cells[9] == f"{min(each):.2e}–{max(each):.2e}"
        assert [float(x) for x in cells[10].split()] == pytest.approx(each, rel=0.01)
    ratio = next(x for x in text.splitlines() if x.startswith("- mirror_ball (means of 2"))
    assert f"`path` {means['path'] / means['Cycles']:.3g} ×" in ratio


def test_bench_scenes_rejects_unknown_scenes_and_integrators(tmp_path):
    assert hard_scenes.run(scenes=["no_such_scene"], output=str(tmp_path), report=False) == 2
    assert hard_scenes.run(scenes=["mirror_ball"], integrators=["no_such_integrator"],
                           output=str(tmp_path), report=False) == 2
    assert hard_scenes.run(scenes=["mirror_ball"], repeats=0, output=str(tmp_path),
                           report=False) == 2


def test_bench_gap_writes_one_finite_row_per_configuration(tmp_path):
    """``bench-gap`` smoke run: every configuration of ours and of Cycles gets a row with a
    finite error and ratio, Cycles' default a ratio of exactly one."""
    from sampling_lab.tools import gap

    rows = gap.run(scenes=["cornell"], size=(8, 8), spp=2, seeds=2, reference_spp=8,
                   output=str(tmp_path / "gap"), progress=lambda *_: None)
    assert [(r["renderer"], r["config"]) for r in rows] == (
        [("ours", c) for c in gap.OURS] + [("Cycles", c) for c in gap.CYCLES])
    for r in rows:
        assert math.isfinite(r["relmse"]) and math.isfinite(r["vs_cycles"]), r
    assert next(r["vs_cycles"] for r in rows if r["config"] == "default") == 1.0
    assert (tmp_path / "gap" / "gap.csv").is_file()
    assert "## cornell" in (tmp_path / "gap" / gap.REPORT).read_text()


def test_bench_export_exports_every_triangle_of_the_grid():
    from sampling_lab.tools import export_speed

    out = export_speed.run(triangles=2000, repeats=2, progress=lambda *_: None)
    assert 1800 <= out["triangles"] <= 2200  # run() checks the export has exactly as many
    assert out["best_s"] > 0 and out["best_mtri_per_s"] > 0
