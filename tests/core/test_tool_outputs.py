"""The tools write where the user says: every documented command writes only inside its
``--output`` folder (default ``out/<command>``), and rewrites the repository's tracked ``docs/``
only with ``--update-docs``. (``bench-scenes`` needs Blender: ``tests/addon/test_bench_hard_scenes.py``.)

Tiny sizes and budgets: these runs check where files go, not the figures.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from sampling_lab import cli
from sampling_lab.tools import outputs

DOCS = Path(__file__).resolve().parents[2] / "docs"
# The docs/ files some tool could write (reports and figures); hand-written pages are not watched.
WATCHED = ("SAMPLERS.md", "STRATEGIES.md", "HARD_SCENES.md", "CAUSTIC.md", "PHOTONS_BENCH.md",
           "samplers", "images")

COMMANDS = {
    "samplers": ["--quick", "--n", "8", "--sampler", "independent"],
    "bench": ["--no-cycles", "--resolution", "8x8", "--seconds", "0.2", "--reference-spp", "4"],
    "bench-caustic": ["--size", "8x8", "--seconds", "0.1", "--reference-seconds", "0.3"],
    "bdpt-views": ["--size", "8x8", "--spp", "1", "--max-length", "2"],
    "bench-strategies": ["--quick", "--resolution", "4x4"],
    "bench-photons": ["--size", "8x8", "--seconds", "0.1", "--reference-seconds", "0.3",
                      "--photons", "1000", "--no-cycles"],
}


def _snapshot(root):
    """Every watched file under ``root`` with its size and modification time."""
    out = {}
    for name in WATCHED:
        path = root / name
        files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
        for f in files:
            st = f.stat()
            out[str(f.relative_to(root))] = (st.st_size, st.st_mtime_ns)
    return out


def _files(folder):
    return sorted(str(p.relative_to(folder)) for p in Path(folder).rglob("*") if p.is_file())


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Each command run once into its own folder of an otherwise empty working directory."""
    work = tmp_path_factory.mktemp("tool_outputs")
    before = _snapshot(DOCS)
    cwd = os.getcwd()
    os.chdir(work)
    try:
        codes = {name: cli.main([name, *argv, "--output", str(work / "given" / name)])
                 for name, argv in COMMANDS.items()}
    finally:
        os.chdir(cwd)
    return work, codes, before


@pytest.mark.parametrize("command", list(COMMANDS))
def test_each_tool_writes_only_inside_its_output_folder(runs, command):
    work, codes, _ = runs
    assert codes[command] == 0, command
    assert sorted(os.listdir(work)) == ["given"]
    assert _files(work / "given" / command), command


def test_no_tool_touches_docs_without_update_docs(runs):
    _, _, before = runs
    assert _snapshot(DOCS) == before


def test_the_reports_are_laid_out_as_in_docs(runs):
    work, _, _ = runs
    given = work / "given"
    assert {"SAMPLERS.md", "samplers/summary.csv", "samplers/points.png"} <= set(
        _files(given / "samplers"))
    assert "CAUSTIC.md" in _files(given / "bench-caustic")
    assert "images/bdpt_views_glass_caustic.png" in _files(given / "bdpt-views")
    assert {"STRATEGIES.md", "images/strategies_cornell_mesh.png"} <= set(
        _files(given / "bench-strategies"))
    assert "](images/strategies_cornell_mesh.png)" in (
        given / "bench-strategies" / "STRATEGIES.md").read_text()


def test_the_default_output_folder_is_out_slash_the_command(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli.main(["bench-caustic", *COMMANDS["bench-caustic"]]) == 0
    assert _files(tmp_path) == ["out/bench-caustic/CAUSTIC.md"]


def test_update_docs_copies_the_report_and_its_figures_into_docs(tmp_path, monkeypatch):
    docs = tmp_path / "docs"
    monkeypatch.setattr(outputs, "DOCS", docs)
    for command in ("bench-caustic", "bdpt-views"):
        assert cli.main([command, *COMMANDS[command], "--output", str(tmp_path / command),
                         "--update-docs"]) == 0
    assert _files(docs) == ["CAUSTIC.md", "images/bdpt_views_glass_caustic.png"]
    assert (docs / "CAUSTIC.md").read_bytes() == (
        tmp_path / "bench-caustic" / "CAUSTIC.md").read_bytes()


@pytest.mark.parametrize("command", ["samplers", "bench-strategies"])
def test_update_docs_refuses_a_quick_run(command, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(outputs, "DOCS", tmp_path / "docs")
    assert cli.main([command, "--quick", "--output", str(tmp_path / "out"),
                     "--update-docs"]) == 2
    assert "--update-docs" in capsys.readouterr().err
    assert not (tmp_path / "docs").exists() and not (tmp_path / "out").exists()
