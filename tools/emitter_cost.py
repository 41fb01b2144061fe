"""Light endpoints' cost of two trees in ONE process: BDPT's emitter points and directions per
draw, base and head alternated (a measurement, not a test).

As :mod:`tools.ab_units`, the base tree is imported a second time as ``sampling_lab_base``.
Each round times, in both trees on the same numbers, ``Emission.sample_points`` (the ``y_0``
and ``s = 1`` points), ``Emission.sample_directions`` (the ``y_0`` directions) and the light
paths' emitter choice (``LightSampler.choose``), ``--rows`` draws per call, and prints thread
CPU nanoseconds per draw (min and median over ``--rounds``) and head / base. ``--keep-freed``
(:mod:`core.allocator`, both trees) keeps freed batch memory as a render's threads and worker
processes do (otherwise the large fresh arrays are page-faulted in again on every call)::

    PYTHONPATH=/path/to/parent:/path/to/parent/sampling_lab/tools \\
        python tools/emitter_cost.py --base /tmp/base/sampling_lab --keep-freed
    ... --light area --rows 40000
"""

from __future__ import annotations

import argparse
import importlib
import os
import statistics
import time

import numpy as np

from ab_units import BASE, HEAD, _import_base, keep_freed_both

STEPS = ("choose", "sample_points", "sample_directions")


def _calls(pkg, light, rows):
    """``{step: call}`` of package ``pkg`` on the Cornell box with ``light`` (power
    selection: what light paths choose with whatever the render's setting)."""
    core = lambda name: importlib.import_module(f"{pkg}.core.{name}")  # noqa: E731
    em = core("prepare").prepare(core("scenes").cornell_box(64, 64, light=light), "power").emission
    rng = np.random.default_rng(0)
    u_sel, u_pos, u_dir = rng.random(rows), rng.random((rows, 2)), rng.random((rows, 2))
    pts = em.sample_points(u_sel, u_pos)
    return {"choose": lambda: em.ls.choose(u_sel),
            "sample_points": lambda: em.sample_points(u_sel, u_pos),
            "sample_directions": lambda: em.sample_directions(pts, u_dir)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", required=True, help="the base tree's package folder")
    parser.add_argument("--light", default="mesh", help="Cornell box light: mesh, area, point")
    parser.add_argument("--rows", type=int, default=16384, help="draws per call")
    parser.add_argument("--rounds", type=int, default=30)
    parser.add_argument("--keep-freed", action="store_true")
    args = parser.parse_args(argv)
    _import_base(args.base)
    if args.keep_freed:
        print(f"allocator: {keep_freed_both()}")
    calls = {pkg: _calls(pkg, args.light, args.rows) for pkg in (BASE, HEAD)}
    print(f"load average at start: {os.getloadavg()}")
    times = {(pkg, step): [] for pkg in calls for step in STEPS}
    for r in range(args.rounds):
        for step in STEPS:
            # Each tree first in every other round: the second call of a step finds its
            # inputs in cache (identical trees read choose 0.76-0.80 x with the base always first).
            for pkg in (BASE, HEAD) if r % 2 == 0 else (HEAD, BASE):
                t0 = time.thread_time()
                calls[pkg][step]()
                times[pkg, step].append(1e9 * (time.thread_time() - t0) / args.rows)
    for step in STEPS:
        b, h = times[BASE, step], times[HEAD, step]
        print(f"{step:>17}: base min {min(b):.1f} median {statistics.median(b):.1f} | head min "
              f"{min(h):.1f} median {statistics.median(h):.1f} ns per draw | head / base: min "
              f"{min(h) / min(b):.3f}, median {statistics.median(h) / statistics.median(b):.3f}")
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
