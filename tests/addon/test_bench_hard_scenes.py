"""The hard-scenes benchmark (``python -m sampling_lab bench-scenes``) runs end to end.

A smoke run: one tiny scene, our path tracer and Cycles for half a second each. It checks that
the CSV, the markdown table and the figure are written with finite figures; it says nothing
about speed (``docs/CONVENTIONS.md``, "Tests": speed is never asserted).
"""

import csv
import math

from sampling_lab.tools import hard_scenes


def test_bench_scenes_writes_finite_figures_for_path_and_cycles_inside_its_output_folder(
        tmp_path):
    out = tmp_path / "out"
    status = hard_scenes.run(scenes=["mirror_ball"], integrators=["path"], seconds=0.5,
                             size=(16, 16), reference_spp=16, reference_seconds=2.0,
                             output=str(out))
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


def test_bench_scenes_rejects_unknown_scenes_and_integrators(tmp_path):
    assert hard_scenes.run(scenes=["no_such_scene"], output=str(tmp_path), report=False) == 2
    assert hard_scenes.run(scenes=["mirror_ball"], integrators=["no_such_integrator"],
                           output=str(tmp_path), report=False) == 2


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
