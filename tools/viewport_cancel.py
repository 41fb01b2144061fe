"""Cancel latency of the rendered viewport: how long stopping its worker thread takes.

``python -m sampling_lab.tools.viewport_cancel [--size 960x540] [--repeats 12] [--bounces 8]
[--integrator path]``

The viewport (``addon/viewport.py``) renders on a worker thread; a restart or the end of
rendered shading sets the cancel flag, which ``core.render`` polls between work units, and the
thread ends after the units in flight. On the Cornell box at a viewport-like size, unlimited
samples, this starts a render, lets it run a random time, and measures:

- *stop*: wall time of ``ProgressiveRender.stop()`` (set the flag, join the thread), the latency
  the issue bounds at 0.2 s;
- *unit*: time between two polls of the flag (one work unit per thread);
- *first frame*: from ``start()`` to the first published preview (what a view change shows).

Figures are printed (median, 90th percentile, maximum), never asserted: they depend on the
machine and its load. Needs ``bpy`` (the viewport module imports it).
"""

from __future__ import annotations

import argparse
import os
import random
import statistics
import threading
import time

from ..addon import viewport
from ..core import scenes
from ..core.render import RenderSettings


class _TimedPolls(viewport.ProgressiveRender):
    """Records when the worker polls the cancel flag."""

    def __init__(self, notify=None):
        super().__init__(notify)
        self.polls = []

    def _poll(self, job):
        self.polls.append(time.perf_counter())
        return super()._poll(job)


def _figures(values):
    values = sorted(values)
    p90 = values[min(len(values) - 1, int(round(0.9 * (len(values) - 1))))]
    return f"median {1e3 * statistics.median(values):7.1f} ms  p90 {1e3 * p90:7.1f} ms  " \
           f"max {1e3 * values[-1]:7.1f} ms"


def run(width=960, height=540, repeats=12, bounces=8, threads=2, seed=1, integrator="path"):
    """Measure and print the figures; returns them as lists of seconds by name."""
    scene = scenes.cornell_box(width=width, height=height)
    settings = RenderSettings(integrator=integrator, spp=0, time_limit=float("inf"),
                              max_bounces=bounces, threads=threads)
    stages = viewport.progressive_stages(width, height, 1, 0)
    rng = random.Random(seed)
    stops, units, firsts = [], [], []
    for _ in range(repeats):
        first = threading.Event()
        renderer = _TimedPolls(notify=first.set)
        t0 = time.perf_counter()
        renderer.start(scene, settings, stages)
        first.wait(60.0)
        firsts.append(time.perf_counter() - t0)
        # Stop at a random point: inside a preview, between units, inside the full film.
        time.sleep(rng.uniform(0.0, 1.0))
        t0 = time.perf_counter()
        stopped = renderer.stop(timeout=30.0)
        stops.append(time.perf_counter() - t0)
        if not stopped:
            raise RuntimeError("the viewport worker did not stop within 30 s")
        units.extend(b - a for a, b in zip(renderer.polls, renderer.polls[1:]))
    print(f"viewport cancel latency: Cornell box {width}x{height}, {integrator}, {bounces} "
          f"bounces, {threads} threads, {repeats} stops, load {os.getloadavg()[0]:.2f}")
    print(f"  stop        {_figures(stops)}")
    print(f"  unit        {_figures(units)}")
    print(f"  first frame {_figures(firsts)}")
    return {"stop": stops, "unit": units, "first_frame": firsts}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", default="960x540")
    parser.add_argument("--repeats", type=int, default=12)
    parser.add_argument("--bounces", type=int, default=8)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--integrator", default="path")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    run(width, height, args.repeats, args.bounces, args.threads, integrator=args.integrator)


if __name__ == "__main__":
    main()
