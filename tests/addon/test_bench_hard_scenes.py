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
