"""Stage profile of BDPT's two subpath walks beside the path tracer (a measurement, not a test).

Calls BDPT's camera and light subpath stages (``bidir._camera_subpath``,
``bidir._light_subpath``) directly on this thread, work unit by work unit (BDPT's own unit
size; independent sampler unless ``--sampler`` says otherwise, power light selection, 8
bounces), with exclusive thread-CPU timers
(:mod:`stage_timer`) around the stages of :func:`core.integrators.subpaths.walk`, and prints
thread CPU nanoseconds per camera sample per stage, best of ``--repeats`` (the run with the
smallest total; the stages are that run's). The path tracer's ``render_samples`` is timed the
same way, whole, on the same pixels (its samples of 8 bounces do the work of a camera walk plus
next-event estimation). No connections, MIS or film: only what the walks cost.

Run it from a checkout's parent so that ``sampling_lab`` resolves to the tree to measure; to
compare two trees, alternate them (``--repeats 1`` several times each)::

    PYTHONPATH=/path/to/parent python tools/profile_walks.py --units 2 --repeats 3
    PYTHONPATH=/path/to/parent python tools/profile_walks.py --scene mirror_ball \
        --width 96 --height 96

Stages a tree lacks are skipped, so the same file profiles an older tree.
"""

from __future__ import annotations

import argparse
import importlib
import os
import time

# From the script's own folder (tools/), whichever tree PYTHONPATH puts first.
from stage_timer import TOTALS as _TOTALS, patch as _patch
from stage_timer import uniform_bounces as _bounces

# (module under sampling_lab.core.integrators, attribute path, row name).
STAGES = [
    ("bidir", "_camera_subpath", "camera setup (rays, pdfs)"),
    ("bidir", "_light_subpath", "light setup (emitter points, directions)"),
    ("bidir", "_Context.subpath", "reset or allocate the vertex tables"),
    ("subpaths", "walk", "walk bookkeeping (the rest)"),
    ("bidir", "walk", "walk bookkeeping (the rest)"),
    ("subpaths", "intersect_by_class", "intersect (Embree closest hit)"),
    ("subpaths", "surface_hits", "surface interaction"),
    ("subpaths", "surface_interaction", "surface interaction"),
    ("subpaths", "prep.choose_bsdf", "choose BSDF (material tables)"),
    ("subpaths", "shading_tangents", "shading frame"),
    ("subpaths", "shading_frame", "shading frame"),
    ("subpaths", "to_local", "shading frame"),
    ("subpaths", "with_bump_normals", "shading frame"),
    ("subpaths", "with_coat_normals", "shading frame"),
    ("subpaths", "_scatter", "BSDF sampling (+ reverse pdf)"),
    ("subpaths", "_store_vertex", "store vertices"),
    ("subpaths", "_walk_store", "store vertices"),
    ("subpaths", "russian_roulette", "Russian roulette"),
    ("subpaths", "next_1d_if", "sample stream (draws, compaction)"),
    ("camera_hits", "camera_emission", "s = 0: emitters the camera walk finds"),
]
STREAM = [("sampling.stream", "SampleStream." + a, "sample stream (draws, compaction)")
          for a in ("next_1d", "next_2d", "skip_to", "compact")]
ACCEL = [("accel", "Accel.offset_origin", "next rays (offset origins)")]
CHOOSE = [("prepare", "PreparedScene.choose_bsdf", "choose BSDF (material tables)"),
          ("lights.emission", "Emission.sample_points", "emitter points and directions (y_0)"),
          ("lights.emission", "Emission.sample_directions",
           "emitter points and directions (y_0)")]


def install_timers():
    """Wrap every stage this tree has (module-level names in the module that calls them)."""
    core = "sampling_lab.core."
    rows = [("integrators." + m, a, n) for m, a, n in STAGES if not a.startswith("prep.")]
    for module, attr, name in rows + STREAM + ACCEL + CHOOSE:
        owner = importlib.import_module(core + module)
        *path, last = attr.split(".")
        for part in path:
            owner = getattr(owner, part, None)
        if owner is None or not hasattr(owner, last):
            continue
        if last == "camera_emission":
            _wrap_handler(owner, name)
            continue
        _patch(owner, last, name)


def _wrap_handler(module, name):
    """``camera_emission`` returns the ``on_segment`` closure: time the closure."""
    from sampling_lab.core.integrators import bidir
    from stage_timer import timed

    make = module.camera_emission
    bidir.camera_emission = lambda *a, **k: timed(name, make(*a, **k))


def _setup(args, name):
    import numpy as np
    from profile_path import load_scene
    from sampling_lab.core.film import PixelFilter
    from sampling_lab.core.integrators import integrator_class
    from sampling_lab.core.prepare import prepare
    from sampling_lab.core.render import RenderSettings
    from sampling_lab.core.sampling.samplers import make_sampler

    scene = load_scene(args.scene, args.width, args.height)
    settings = RenderSettings(integrator=name, spp=4, threads=1, seed=0,
                              sampler=args.sampler, light_selection="power",
                              **_bounces(RenderSettings, 8))
    integ = integrator_class(name)(prepare(scene, "power"), settings)
    sampler = make_sampler(args.sampler, seed=0, spp=4, width=args.width)
    pixel_filter = PixelFilter(settings.filter_type, settings.filter_width)
    w, h = args.width, args.height

    def streams(n):
        for u in range(args.units):
            pixels = (np.arange(n) + u * n) % (w * h)
            yield sampler.stream(pixels, np.full(n, u * n // (w * h)))

    return integ, pixel_filter, streams


def walk_costs(args):
    """Thread CPU ns per camera sample of BDPT's two walks, by stage (best total of
    ``args.repeats``)."""
    from sampling_lab.core.integrators import bidir
    from sampling_lab.core.integrators.base import Counters
    from sampling_lab.core.integrators.strategy_views import Tally

    integ, pixel_filter, streams = _setup(args, "bdpt")
    n = integ.unit_paths
    depth = integ.settings.max_bounces + 2
    base = bidir.DIMS_CAMERA + (depth + 1) * bidir.DIMS_PER_CAMERA_VERTEX

    def run():
        for stream in streams(n):
            ctx = bidir._Context(integ, Counters(), pixel_filter)
            bidir._camera_subpath(ctx, pixel_filter, stream, n, depth, Tally(n, 0))
            bidir._light_subpath(ctx, stream, n, base, depth)

    run()  # warm-up: per-thread buffers, first-call costs
    install_timers()
    best = None
    for _ in range(args.repeats):
        _TOTALS.clear()
        run()
        total = sum(_TOTALS.values())
        if best is None or total < best[0]:
            best = (total, dict(_TOTALS))
    return best, args.units * n


def path_cost(args):
    """Thread CPU ns per camera sample of the path tracer's ``render_samples`` (best of
    ``args.repeats``), untimed inside."""
    from sampling_lab.core.integrators.base import Counters

    integ, pixel_filter, streams = _setup(args, "path")
    n = integ.unit_paths

    def run():
        for stream in streams(n):
            integ.render_samples(stream, pixel_filter, Counters())

    run()
    best = float("inf")
    for _ in range(args.repeats):
        t0 = time.thread_time()
        run()
        best = min(best, time.thread_time() - t0)
    return best * 1e9 / (args.units * n)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="bench",
                        help="bench (the bench's mesh-light box) or a bench-scenes scene "
                             "(e.g. mirror_ball; needs bpy)")
    parser.add_argument("--width", type=int, default=256)
    parser.add_argument("--height", type=int, default=256)
    parser.add_argument("--units", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-path", action="store_true", help="the walks only")
    parser.add_argument("--sampler", default="independent",
                        help="independent (default) or a render's sobol")
    args = parser.parse_args(argv)
    print(f"load average at start: {os.getloadavg()}")
    if not args.no_path:
        print(f"path tracer, whole sample: {path_cost(args):.0f} ns per camera sample")
    (total, stages), samples = walk_costs(args)
    per = 1e9 / samples
    print(f"BDPT walks (camera + light), {samples} camera samples: {total * per:.0f} ns per "
          f"camera sample (best of {args.repeats})")
    for stage, sec in sorted(stages.items(), key=lambda kv: -kv[1]):
        print(f"  {sec * per:7.0f} ns  {stage}")
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
