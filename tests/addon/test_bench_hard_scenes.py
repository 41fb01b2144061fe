"""The hard-scenes benchmark (``python -m sampling_lab bench-scenes``) runs end to end.

A smoke run: one tiny scene, our path tracer and Cycles for half a second each. It checks that
the CSV, the markdown table and the figure are written with finite figures; it says nothing
about speed (``docs/CONVENTIONS.md``, "Tests": speed is never asserted).
"""

import csv
import math

from sampling_lab.tools import hard_scenes


def test_bench_scenes_writes_finite_figures_for_path_and_cycles(tmp_path):
    docs = tmp_path / "HARD_SCENES.md"
    status = hard_scenes.run(scenes=["mirror_ball"], integrators=["path"], seconds=0.5,
                             size=(16, 16), reference_spp=16, reference_seconds=2.0,
                             output=str(tmp_path), docs=str(docs))
    assert status == 0

    with open(tmp_path / "hard_scenes.csv") as f:
        rows = list(csv.DictReader(f))
    assert sorted(r["renderer"] for r in rows) == ["Cycles", "path"]
    for r in rows:
        for key in ("spp", "time_s", "samples_per_s", "relmse_vs_ref", "relmse_vs_cycles_ref",
                    "mean_over_ref"):
            assert math.isfinite(float(r[key])), (r["renderer"], key, r[key])
        assert float(r["spp"]) >= 1

    text = docs.read_text()
    assert "| mirror_ball | path |" in text and "| mirror_ball | Cycles |" in text
    assert "load average" in text
    assert (tmp_path / "images" / "hard_scenes.png").is_file()
    assert (tmp_path / "hard_scenes_summary.csv").is_file()


def test_bench_scenes_rejects_unknown_scenes_and_integrators(tmp_path):
    assert hard_scenes.run(scenes=["no_such_scene"], output=str(tmp_path), docs=None) == 2
    assert hard_scenes.run(scenes=["mirror_ball"], integrators=["no_such_integrator"],
                           output=str(tmp_path), docs=None) == 2
