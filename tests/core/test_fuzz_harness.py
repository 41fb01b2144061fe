"""The fuzz harness (``tools/fuzz.py``) counts what it must count as failures: a traceback, a hang
and a crash of a real child process, and a NaN or a many-line refusal in a record; cases after a
crash or a hang still run. (The fixed-seed run over broken scenes is
``tests/addon/test_fuzz.py``: its child needs Blender.)"""

from __future__ import annotations

from sampling_lab.tools.fuzz import FAILURES, classify, run_cases
from sampling_lab.tools.fuzz_cases import ROUTES, make_cases

REFUSED = {"route": "cli", "code": 2, "exr": "none",
           "text": "note: a note\nsampling_lab: error: unknown scene 'x'\n"}


def test_classifier_counts_a_clean_refusal_and_a_finite_render_as_successes():
    assert classify(REFUSED) == "refused"
    assert classify({"route": "cli", "code": 0, "exr": "finite", "text": ""}) == "rendered"
    assert classify({"route": "blender", "code": 2, "exr": "none", "text": "",
                     "message": "Error: Sampling Lab: the scene has no camera"}) == "refused"


def test_classifier_counts_tracebacks_nans_and_unclear_endings_as_failures():
    bad = {
        "traceback": dict(REFUSED, text="Traceback (most recent call last):\n  File ...\n"
                                        "sampling_lab: error: boom\n"),
        "nan": {"route": "cli", "code": 0, "exr": "nonfinite", "text": ""},
        "two error lines": dict(REFUSED, text="sampling_lab: error: a\nsampling_lab: error: b\n"),
        "leaked output": dict(REFUSED, text='Read blend: "x.blend"\nsampling_lab: error: a\n'),
        "exit code 1": {"route": "cli", "code": 1, "exr": "finite", "text": ""},
        "catch-all report": {"route": "blender", "code": 2, "exr": "none", "text": "",
                             "message": "Error: Sampling Lab: render failed: KeyError: 'x'"},
        "success without image": {"route": "blender", "code": 0, "exr": "none", "text": ""},
    }
    outcomes = {name: classify(record) for name, record in bad.items()}
    assert outcomes["traceback"] == "traceback" and outcomes["nan"] == "nan"
    assert all(o in FAILURES for o in outcomes.values()), outcomes


def test_a_real_hang_crash_and_traceback_are_counted_and_later_cases_still_run():
    cli = make_cases(3, seed=5)[2]  # route 'cli' (routes take turns)
    assert cli["route"] == "cli"
    cases = [{"id": 0, "route": "selftest", "fail": "hang"},
             {"id": 1, "route": "selftest", "fail": "crash"},
             {"id": 2, "route": "selftest", "fail": "traceback"},
             dict(cli, id=3)]
    results = run_cases(cases, timeout=4.0, batch=4, memory_gb=0, log=lambda *_: None)
    assert [results[i]["outcome"] for i in range(3)] == ["hang", "crash", "traceback"]
    assert results[3]["outcome"] in ("rendered", "refused"), results[3]


def test_cases_are_a_function_of_count_and_seed_and_cover_every_route():
    assert make_cases(30, seed=3) == make_cases(30, seed=3)
    assert make_cases(30, seed=3) != make_cases(30, seed=4)
    assert {c["route"] for c in make_cases(3, seed=0)} == set(ROUTES)
