"""What padding the subpath tables to 4 columns would save or cost, primitive by primitive
(a measurement, not a test).

The connections gather ``(k, 3)`` rows of ``(n, 3)`` float64 tables at random. A padded
``(n, 4)`` table gathers faster (NumPy copies 32-byte items with a fixed-size move, 24-byte
ones with ``memmove``), but what the gather gives is ``(k, 4)``: its ``[:, :3]`` view has a
row stride of 32 bytes, and NumPy's element-wise operations on such a view run a 3-element
inner loop per row, several times slower than over a contiguous ``(k, 3)`` array; copying
it to a contiguous one costs the same. This prints best-of-``--repeats`` microseconds per
call of each primitive for ``--rows`` random rows of a ``--table``-row table, one thread::

    python tools/pad_gathers.py --rows 90000 --table 131072
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from numpy.lib.stride_tricks import as_strided


def best_us(f, repeats):
    """Best of ``repeats`` calls of ``f()``, in microseconds of thread CPU."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.thread_time()
        f()
        best = min(best, time.thread_time() - t0)
    return 1e6 * best


def primitives(n, k, seed=1):
    """``{name: f}``: the gathers and the operations after them that padding changes."""
    rng = np.random.default_rng(seed)
    t3 = rng.random((n, 3))
    t4 = np.zeros((n, 4))
    t4[:, :3] = t3
    view = t4[:, :3]
    rows = rng.integers(0, n, k)
    g3, g4 = np.take(t3, rows, axis=0), np.take(t4, rows, axis=0)
    out = np.empty((k, 3))
    return {
        "gather (n, 3) table": lambda: np.take(t3, rows, axis=0),
        "gather (n, 4) table": lambda: np.take(t4, rows, axis=0),
        "gather the [:, :3] view of an (n, 4) table": lambda: np.take(view, rows, axis=0),
        "gather (n, 4) through the view (as_strided), keep [:, :3]":
            lambda: np.take(as_strided(view, (n, 4), (32, 8)), rows, axis=0)[:, :3],
        "copy a gathered (k, 4)[:, :3] to contiguous (k, 3)": lambda: np.copyto(out, g4[:, :3]),
        "a - b of contiguous (k, 3)": lambda: g3 - g3,
        "a - b of (k, 4)[:, :3] views": lambda: g4[:, :3] - g4[:, :3],
        "a - b of whole (k, 4) blocks": lambda: g4 - g4,
        "row dot (einsum) of contiguous (k, 3)": lambda: np.einsum("ij,ij->i", g3, g3),
        "row dot (einsum) of (k, 4)[:, :3] views":
            lambda: np.einsum("ij,ij->i", g4[:, :3], g4[:, :3]),
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=90000, help="rows gathered (k)")
    parser.add_argument("--table", type=int, default=131072, help="rows of the table (n)")
    parser.add_argument("--repeats", type=int, default=50)
    args = parser.parse_args(argv)
    print(f"NumPy {np.__version__}; load average {os.getloadavg()}; k = {args.rows}, "
          f"n = {args.table}; best of {args.repeats}, thread CPU us per call")
    for name, f in primitives(args.table, args.rows).items():
        print(f"{best_us(f, args.repeats):9.1f}  {name}")


if __name__ == "__main__":
    main()
