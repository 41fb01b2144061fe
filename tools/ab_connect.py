"""BDPT's connection stage of two trees in ONE process: the same outputs bit for bit, and the
stage's thread CPU per camera sample alternated (a measurement, not a test).

Like :mod:`tools.ab_units`, the base tree is imported a second time as ``sampling_lab_base``.
``--check`` renders one BDPT work unit (8,192 paths or the integrator's unit if smaller;
4 samples per pixel, independent sampler, power selection, 8 bounces) of each case with both
trees and compares every array of the two outputs (image, splats, strategy layers) with
``np.array_equal``. ``--time`` runs one work unit per tree (the integrator's own unit size),
keeps what each tree's own :func:`~core.integrators.connections.connect_all` was given (the
same subpaths: same seed, same walks), and then times that call alone, base and head in turn
for ``--rounds`` rounds (each with its own tree's tally, accel and gathers): the minimum and
the median of thread CPU microseconds per camera sample, and head / base::

    PYTHONPATH=/path/to/parent:/path/to/parent/sampling_lab/tools \\
        python tools/ab_connect.py --base /tmp/base/sampling_lab --check --time
    ... --scene mirror_ball --size 96 --time   # a bench-scenes scene (needs bpy)
    ... --time --stage cameras                 # connect_cameras (the t = 1 splats) instead
    ... --time --keep-freed                    # malloc as a render sets it (core.allocator)
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import os
import statistics
import time

import numpy as np

from ab_units import BASE, HEAD, _import_base, _scene, keep_freed_both
from stage_timer import uniform_bounces as _bounces

# (scene, image side, settings): --check's cases; "+world" / "+sun" add an infinite emitter.
CASES = [("bench", 64, {}), ("bench", 64, {"mis_heuristic": "balance"}),
         ("bench", 64, {"mis_heuristic": "maximum"}),
         ("bench", 48, {"strategy_views": True, "strategy_max_length": 4}),
         ("bench+world", 48, {}), ("bench+sun", 48, {}), ("rough_mirror", 48, {}),
         ("rough_glass", 48, {})]
BPY_CASES = [("mirror_ball", 48, {}), ("glossy_plates", 48, {}), ("glass_sphere", 48, {})]


class _Args:
    def __init__(self, scene, size):
        self.scene, self.size = scene, size


def _integrator(pkg, name, size, extra, cap=8192):
    """``(integrator, stream, pixel filter, Counters)`` of a one-unit BDPT run in ``pkg``
    (at most ``cap`` paths; None: the integrator's own unit)."""
    core = lambda m: importlib.import_module(f"{pkg}.core.{m}")  # noqa: E731
    base_name, _, emitter = name.partition("+")
    own = base_name == "bench" or base_name.startswith("rough_")
    scene = _scene(pkg if own else HEAD, _Args(base_name, size))
    if emitter == "world":
        scene = dataclasses.replace(scene, world_color=(0.4, 0.5, 0.6))
    elif emitter == "sun":
        sun = core("lights").sun_light((0.3, 0.5, -1.0), (1, 1, 1), 3.0, angle=0.3)
        scene = dataclasses.replace(scene, lights=sun)
    settings_class = core("render").RenderSettings
    settings = settings_class(**{"integrator": "bdpt", "spp": 4, "threads": 1, "seed": 0,
                                 "sampler": "independent", "light_selection": "power",
                                 **_bounces(settings_class, 8), **extra})
    integ = core("integrators").integrator_class("bdpt")(core("prepare").prepare(scene, "power"),
                                                         settings)
    n = integ.unit_paths if cap is None else min(integ.unit_paths, cap)
    sampler = core("sampling.samplers").make_sampler("independent", seed=0, spp=4, width=size)
    stream = sampler.stream(np.arange(n) % (size * size), np.zeros(n, np.int64))
    return (integ, stream, core("film").PixelFilter(settings.filter_type, settings.filter_width),
            core("integrators.base").Counters)


def _arrays(out):
    arrays = {"image": out.radiance, "splat xy": out.splats.xy, "splats": out.splats.value}
    arrays.update({f"layer {k}": v for k, v in out.camera_layers.items()})
    arrays.update({f"splat layer {k}": v.value for k, v in out.splat_layers.items()})
    return arrays


def check(cases):
    """Print, per case, whether base and head give the same arrays bit for bit."""
    differ = 0
    for name, size, extra in cases:
        outs = []
        for pkg in (BASE, HEAD):
            integ, stream, pixel_filter, counters = _integrator(pkg, name, size, extra)
            outs.append(_arrays(integ.render_samples(stream, pixel_filter, counters())))
        bad = [k for k in outs[0]
               if k not in outs[1] or not np.array_equal(outs[0][k], outs[1][k])]
        differ += len(bad) + len(set(outs[1]) - set(outs[0]))
        print(f"{name} {size} px {extra}: {len(outs[0])} arrays, "
              f"{'identical' if not bad else 'DIFFER: ' + ', '.join(bad)}")
    print("every array identical" if differ == 0 else f"{differ} arrays differ")


# --stage: the module that calls the stage and the stage's name there.
STAGES = {"all": ("bdpt", "connect_all"), "cameras": ("bidir", "connect_cameras")}


def _captured(pkg, name, size, stage="all"):
    """``(run(), camera samples)``: ``run`` times ``pkg``'s ``connect_all`` (``stage``
    "cameras": ``connect_cameras``, the ``t = 1`` splats) in thread CPU seconds, on the
    inputs it had in one work unit of ``name``."""
    integ, stream, pixel_filter, counters = _integrator(pkg, name, size, {}, cap=None)
    module, attr = STAGES[stage]
    caller = importlib.import_module(f"{pkg}.core.integrators.{module}")
    tally = importlib.import_module(f"{pkg}.core.integrators.strategy_views").Tally
    call, seen = getattr(caller, attr), []

    def record(*args):
        out = args[-1]
        seen.append((args[:-1], out.image.shape[0], out.view_length))
        return call(*args)

    setattr(caller, attr, record)
    try:
        integ.render_samples(stream, pixel_filter, counters())
    finally:
        setattr(caller, attr, call)
    args, n, views = seen[0]

    def run():
        out = tally(n, views)
        t0 = time.thread_time()
        call(*args, out)
        return time.thread_time() - t0

    run()  # warm-up
    return run, n


def time_connect(name, size, rounds, stage="all"):
    runs = {pkg: _captured(pkg, name, size, stage) for pkg in (BASE, HEAD)}
    print(f"load average at start: {os.getloadavg()}")
    times = {pkg: [] for pkg in runs}
    for _ in range(rounds):
        for pkg, (run, n) in runs.items():
            times[pkg].append(1e6 * run() / n)
    b, h = times[BASE], times[HEAD]
    mb, mh = statistics.median(b), statistics.median(h)
    print(f"{STAGES[stage][1]} ({name}, {runs[HEAD][1]} paths): base min {min(b):.3f} "
          f"median {mb:.3f} | head min {min(h):.3f} median {mh:.3f} us per camera sample | head / base: min "
          f"{min(h) / min(b):.3f}, median {mh / mb:.3f}")
    print(f"load average at end: {os.getloadavg()}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", required=True, help="the base tree's package folder")
    parser.add_argument("--check", action="store_true", help="outputs bit for bit (see doc)")
    parser.add_argument("--bpy", action="store_true",
                        help="--check also on bench-scenes scenes (needs bpy)")
    parser.add_argument("--time", action="store_true", help="connect_all's CPU, alternated")
    parser.add_argument("--scene", default="bench")
    parser.add_argument("--size", type=int, default=256, help="square image side (--time)")
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--stage", choices=sorted(STAGES), default="all",
                        help="--time: connect_all or connect_cameras (t = 1)")
    parser.add_argument("--keep-freed", action="store_true",
                        help="glibc keeps freed batch memory (core.allocator), as a render "
                             "does (both trees: each then joins connections in its large pieces)")
    args = parser.parse_args(argv)
    _import_base(args.base)
    if args.keep_freed:
        print(f"allocator: {keep_freed_both()}")
    if args.check:
        check(CASES + (BPY_CASES if args.bpy else []))
    if args.time:
        time_connect(args.scene, args.size, args.rounds, args.stage)


if __name__ == "__main__":
    main()
