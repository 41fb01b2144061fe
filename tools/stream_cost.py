"""Cost of the sample stream per drawn dimension (a measurement, not a test).

Times ``stream.sample(d, 1)`` and ``stream.sample(d, 2)`` of the Sobol and the independent
sampler on one unit of ``--paths`` paths (thread CPU time, the minimum over ``--repeats``
draws, in nanoseconds per path and dimension); for Sobol, one path-tracer bounce's five
slots drawn call by call and with ``next_slots`` at several path counts, and the stages of
one 2-D draw of the base tree's form (slot key, the three sub-keys, the index shuffle, the
two coordinates' scrambles, bit reversal, conversion to doubles). With ``--base`` the base
tree's streams are timed in the same process, one right after the other (as
:mod:`tools.ab_units`), so a load spike hits both alike. Memory is kept as in a render
(``core.allocator.keep_freed_batches``)::

    PYTHONPATH=/path/to/parent python tools/stream_cost.py --base /tmp/base/sampling_lab
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import time

import numpy as np

from ab_units import BASE, HEAD, _import_base


def _min_time(fn, repeats):
    """Minimum thread CPU seconds of ``fn()`` over ``repeats`` calls (after one warm-up)."""
    fn()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t0)
    return best


def _streams(pkg, n):
    samplers = importlib.import_module(f"{pkg}.core.sampling.samplers")
    pixel, index = np.arange(n) % 9216, np.arange(n) // 9216
    return {name: samplers.make_sampler(name, seed=0, spp=16, width=96).stream(pixel, index)
            for name in ("sobol", "independent")}


def _bounce(stream):
    """The path tracer's draws of one bounce, call by call."""
    stream.skip_to(9)
    stream.next_1d(), stream.next_2d(), stream.next_1d(), stream.next_2d(), stream.next_1d()


def _stages(pkg, stream, repeats):
    """Nanoseconds per path of each stage of one 2-D Sobol draw, in the base tree's form."""
    ld = importlib.import_module(f"{pkg}.core.sampling.lowdiscrepancy")
    n, rev = len(stream), stream._reversed_index
    key = ld.slot_keys(stream._key, 7)
    k = [ld.sub_key(key, s) for s in range(3)]
    lk = ld.laine_karras_permutation(rev, k[0])
    two = np.stack([lk, lk])
    stages = {
        "slot key (1 hash)": lambda: ld.slot_keys(stream._key, 7),
        "sub-keys (3 hashes)": lambda: [ld.sub_key(key, s) for s in range(3)],
        "LK permutation x3": lambda: [ld.laine_karras_permutation(rev, s) for s in k],
        "Sobol dimension 1": lambda: ld.sobol_reversed(1, lk),
        "bit reversal (1 + 2 rows)": lambda: (ld.reverse_bits(lk), ld.reverse_bits(two)),
        "to doubles (2 rows)": lambda: ld.unit_from_u32(two.T),
    }
    return {name: 1e9 * _min_time(fn, repeats) / n for name, fn in stages.items()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", help="the base tree's package folder (optional)")
    parser.add_argument("--paths", type=int, default=65536)
    parser.add_argument("--repeats", type=int, default=30)
    args = parser.parse_args(argv)
    importlib.import_module(f"{HEAD}.core.allocator").keep_freed_batches()  # as a render does
    pkgs = [HEAD]
    if args.base:
        _import_base(args.base)
        pkgs = [BASE, HEAD]
    print(f"load average at start: {os.getloadavg()}; {args.paths} paths per draw")
    streams = {pkg: _streams(pkg, args.paths) for pkg in pkgs}
    for name in ("sobol", "independent"):
        for count in (1, 2):
            cells = []
            for pkg in pkgs:
                s = streams[pkg][name]
                t = _min_time(lambda: s.sample(7, count), args.repeats)
                cells.append(f"{pkg}: {1e9 * t / (args.paths * count):6.2f}")
            print(f"{name:>11} {count}-D: ns per path and dimension | " + " | ".join(cells))
    print("one path-tracer bounce (slots 1, 2, 1, 2, 1), ns per path:")
    for n in (4096, 16384, 65536):
        cells = []
        for pkg in pkgs:
            s = _streams(pkg, n)["sobol"]
            t = _min_time(lambda: _bounce(s), args.repeats)
            cells.append(f"{pkg}: calls {1e9 * t / n:6.2f}")
            if hasattr(s, "next_slots"):
                t = _min_time(lambda: s.next_slots((1, 2, 1, 2, 1)), args.repeats)
                cells[-1] += f", next_slots {1e9 * t / n:6.2f}"
        print(f"  {n:>6} paths: " + " | ".join(cells))
    print("Sobol 2-D draw by stage (base form), ns per path:")
    stages = {pkg: _stages(pkg, streams[pkg]["sobol"], args.repeats) for pkg in pkgs}
    for stage in stages[pkgs[0]]:
        print(f"  {stage:>26}: " + " | ".join(f"{p}: {stages[p][stage]:6.2f}" for p in pkgs))
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    sys.exit(main())
