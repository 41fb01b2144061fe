"""A fixed-seed subset of the fuzz harness (``python -m sampling_lab fuzz``): broken scenes built
with the data API and rendered inside Blender or saved and rendered by the command line, and
broken command lines, each in one child process with a time limit. Every case must render or
be refused in one line: a traceback, crash, hang, NaN or unclear ending fails the test. (That
the harness counts those as failures is ``tests/core/test_fuzz_harness.py``.)"""

from __future__ import annotations

from collections import Counter

from sampling_lab.tools.fuzz import FAILURES, run_cases
from sampling_lab.tools.fuzz_cases import ROUTES, make_cases

COUNT, SEED = 45, 16


def test_fixed_seed_fuzz_cases_render_or_are_refused_in_one_line():
    cases = make_cases(COUNT, SEED)
    results = run_cases(cases, timeout=120.0, batch=COUNT, log=lambda *_: None)
    failed = {c["id"]: (c, results[c["id"]]) for c in cases
              if results[c["id"]]["outcome"] in FAILURES}
    assert not failed, "\n".join(f"{c}\n  -> {r}" for c, r in failed.values())
    # The subset exercises every route and both good endings (else it would check little).
    assert {c["route"] for c in cases} == set(ROUTES)
    outcomes = Counter(r["outcome"] for r in results.values())
    assert outcomes["rendered"] > 0 and outcomes["refused"] > 0, outcomes
