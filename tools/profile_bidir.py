"""Stage profile of light tracing and BDPT on the bench Cornell box (a measurement, not a test).

Wraps the stages of the bidirectional integrators (:mod:`core.integrators.bidir` and the
modules it calls) with exclusive timers, as :mod:`tools.profile_path` does for the path tracer
(a stage's time excludes the stages it calls), renders the 36-triangle Cornell box of
``python -m sampling_lab bench`` at a fixed sample count, and prints each stage's share of the
summed worker-thread time. Before that it prints camera samples/s of the path tracer, light
tracing and BDPT, untimed, in one run (their ratios are the issue's targets), best of
``--repeats`` interleaved renders each, so that a load spike hits all three alike.

Run it from a checkout's parent so that ``sampling_lab`` resolves to the tree to measure::

    PYTHONPATH=/path/to/parent python tools/profile_bidir.py --threads 2 --spp 4

It imports the package by its absolute name, so the same file profiles an older worktree when
``PYTHONPATH`` names that one; stages that a tree lacks are skipped.

``--units N`` measures the work itself instead: the integrator's ``render_samples`` called
directly on this thread, ``N`` work units of ``--unit-paths`` paths (by default the
integrator's own unit size, as in a render; independent sampler,
power light selection), CPU microseconds per sample (best of ``--repeats``), without the
render loop, its threads or the film. With ``--cprofile K`` it then prints the ``K``
functions of most own time in a ``cProfile`` of those units on a thread-CPU clock (other
processes' load does not count; a profiler of the render would see only the render loop's
thread)::

    PYTHONPATH=/path/to/parent python tools/profile_bidir.py --units 4 --repeats 6

``--scene NAME`` profiles a ``bench-scenes`` scene (``tools.hard_scenes.SCENES``, built in
``bpy`` and exported as the add-on does) instead of the bench's box, e.g. ``--scene
mirror_ball --width 96 --height 96``. The stage profile prints each stage's share and its
CPU microseconds per camera sample.
"""

from __future__ import annotations

import argparse
import importlib
import os
import time

# From the script's own folder (tools/), whichever tree PYTHONPATH puts first.
from stage_timer import TOTALS as _TOTALS, patch as _patch, timed as _timed
from stage_timer import uniform_bounces as _bounces

INTERSECT = "subpaths: intersect (Embree closest hit)"
SHADOW = "shadow rays (offsets + Embree occluded)"
BSDF_EVAL = "connections: BSDF eval + pdf (gathered vertices)"
MIS = "MIS densities + weights"
# (module under sampling_lab.core, attribute path, row name): the rows of the profile table.
STAGES = [
    ("passes", "Passes.run_unit", "other (render_samples bookkeeping, render loop)"),
    ("integrators.bidir", "_camera_subpath", "subpaths: camera setup (rays, pdfs)"),
    ("integrators.bidir", "_light_subpath", "subpaths: light setup (emitter points, directions)"),
    ("integrators.subpaths", "walk", "subpaths: walk bookkeeping"),
    ("accel", "Accel.intersect", INTERSECT),
    ("integrators.subpaths", "intersect_by_class", INTERSECT),
    ("integrators.subpaths", "surface_hits", "subpaths: surface interaction"),
    ("integrators.subpaths", "surface_interaction", "subpaths: surface interaction"),
    ("integrators.subpaths", "shading_frame", "subpaths: surface interaction"),
    ("prepare", "PreparedScene.choose_bsdf", "subpaths: choose BSDF (material tables)"),
    ("integrators.subpaths", "sample_bsdf", "subpaths: BSDF sampling"),
    ("integrators.subpaths", "pdf_bsdf", "subpaths: BSDF sampling"),
    ("integrators.adjoint_normals", "VertexNormals.sample_importance", "subpaths: BSDF sampling"),
    ("integrators.subpaths", "_store_vertex", "subpaths: store vertices"),
    ("integrators.subpaths", "Subpath.empty", "subpaths: store vertices"),
    ("integrators.subpaths", "Subpath.reset", "subpaths: store vertices"),
    ("integrators.subpaths", "russian_roulette", "subpaths: walk bookkeeping"),
    ("accel", "Accel.offset_origin", "subpaths: walk bookkeeping"),
    ("integrators.subpaths", "Gathered.__init__", "connections: gather vertices"),
    ("integrators.subpaths", "Gathered.at", "connections: gather vertices"),
    ("integrators.subpaths", "Gathered.take", "connections: gather vertices"),
    ("integrators.subpaths", "Gathered.for_densities", "connections: gather vertices"),
    ("integrators.lambert_vertices", "LambertVertices.at", "connections: gather vertices"),
    ("integrators.lambert_vertices", "LambertVertices.for_densities",
     "connections: gather vertices"),
    ("integrators.lambert_vertices", "LambertVertices.f", BSDF_EVAL),
    ("integrators.lambert_vertices", "LambertVertices.pdf_toward", BSDF_EVAL),
    ("integrators.lambert_vertices", "LambertVertices.pdf_back", BSDF_EVAL),
    ("integrators.subpaths", "Gathered.f", BSDF_EVAL),
    ("integrators.subpaths", "Gathered.pdf_toward", BSDF_EVAL),
    ("integrators.subpaths", "Gathered.pdf_back", BSDF_EVAL),
    ("integrators.subpaths", "Gathered.values", BSDF_EVAL),
    ("integrators.lambert_vertices", "LambertVertices.values", BSDF_EVAL),
    ("integrators.camera_hits", "camera_emission", "s = 0: camera hits (emitters found)"),
    ("integrators.connections", "connect", "s >= 1, t >= 2: connect bookkeeping"),
    ("integrators.connections", "connect_all", "s >= 1, t >= 2: connect bookkeeping"),
    ("integrators.connections", "_join_vertices", "s >= 1, t >= 2: connect bookkeeping"),
    ("integrators.connections", "_join_emitters", "s >= 1, t >= 2: connect bookkeeping"),
    ("integrators.bdpt", "_fresh_points", "emitter sampling (points, s = 1 and y_0)"),
    ("integrators.connections", "connect_camera", "t = 1: light tracing splats (bookkeeping)"),
    ("integrators.connections", "connect_cameras", "t = 1: light tracing splats (bookkeeping)"),
    ("integrators.connections", "splat_vertices", "t = 1: light tracing splats (bookkeeping)"),
    ("integrators.connections", "project", "t = 1: light tracing splats (bookkeeping)"),
    ("integrators.connections", "connect_emitter_to_camera",
     "s = 1, t = 1: emitter seen by the pinhole"),
    ("accel", "Accel.shadow_rays", SHADOW),
    ("accel", "Accel.occluded", SHADOW),
    ("lights.emission", "Emission.sample_points", "emitter sampling (points, s = 1 and y_0)"),
    ("lights.emission", "Emission.radiance", "emitter radiance / pdfs"),
    ("lights.emission", "Emission.pdf_origin", "emitter radiance / pdfs"),
    ("lights.emission", "Emission.pdf_direction", "emitter radiance / pdfs"),
    ("integrators.mis_densities", "camera_hit_weight", MIS),
    ("integrators.mis_densities", "connection_weight", MIS),
    ("integrators.mis_densities", "splat_weight", MIS),
    ("integrators.mis_densities", "direct_weight", MIS),
    ("integrators.mis_densities", "strategy_weight", MIS),
    ("integrators.mis_sums", "RunningSums.__init__", MIS),
    ("integrators.mis_sums", "RunningSums.weights", MIS),
    ("integrators.strategy_views", "Tally.add", "tally (image sums, splat lists, output)"),
    ("integrators.strategy_views", "Tally.splat", "tally (image sums, splat lists, output)"),
    ("integrators.strategy_views", "Tally.output", "tally (image sums, splat lists, output)"),
    ("sampling.stream", "SampleStream.next_1d", "sample stream (draws, compaction)"),
    ("sampling.stream", "SampleStream.next_2d", "sample stream (draws, compaction)"),
    ("sampling.stream", "SampleStream.skip_to", "sample stream (draws, compaction)"),
    ("sampling.stream", "SampleStream.compact", "sample stream (draws, compaction)"),
    ("render", "_Passes.accumulate", "film accumulation + splats"),
    ("film", "Film.splat", "film accumulation + splats"),
    ("film", "Film.add_splat_taps", "film accumulation + splats"),
    ("film", "Film.splat_taps", "film splat taps (worker thread since issue 12)"),
    ("film", "tap_sums", "film splat taps (worker thread since issue 12)"),
    ("film", "Film.add_splat_sums", "film accumulation + splats"),
    ("film", "Film.add_samples", "film accumulation + splats"),
]


def install_timers():
    """Wrap every stage of :data:`STAGES` that this tree has.

    A function imported by name into other integrator modules is wrapped there too (the
    caller looks it up in its own module)."""
    integrators = [importlib.import_module(f"sampling_lab.core.integrators.{m}")
                   for m in ("bidir", "bdpt", "light", "connections", "camera_hits",
                             "mis_densities", "subpaths")]
    for module, attr, name in STAGES:
        try:
            owner = importlib.import_module(f"sampling_lab.core.{module}")
        except ImportError:
            continue
        *path, last = attr.split(".")
        for part in path:
            owner = getattr(owner, part, None)
        if owner is None or not hasattr(owner, last):
            continue
        if last == "camera_emission":
            _patch_handler(owner, name)
            continue
        original = getattr(owner, last)
        _patch(owner, last, name)
        if not path:
            for mod in integrators:
                if mod is not owner and getattr(mod, last, None) is original:
                    _patch(mod, last, name)


def _patch_handler(module, name):
    """``camera_emission`` returns the ``on_segment`` closure: time the closure."""
    from sampling_lab.core.integrators import bidir

    make = module.camera_emission

    def timed_make(*args, **kwargs):
        return _timed(name, make(*args, **kwargs))

    bidir.camera_emission = timed_make


def _scene(args):
    """The bench's Cornell box (``--scene bench``) or a ``bench-scenes`` scene (needs
    ``bpy``), as :func:`tools.profile_path.load_scene` loads them."""
    from profile_path import load_scene

    return load_scene(args.scene, args.width, args.height)


def speeds(scene, args, integrators=("path", "light", "bdpt")):
    """Per integrator, best of ``args.repeats`` interleaved renders: wall-clock camera
    samples/s at ``args.threads`` threads, and CPU microseconds per camera sample of a
    1-thread render (all of the process's threads: the render loop's film work included).
    The CPU figure hardly moves with other processes' load; the wall figure does."""
    from sampling_lab.core.render import RenderSettings, render

    best, cpu = {}, {}
    for _ in range(args.repeats):
        for name in integrators:
            spp = args.path_spp if name == "path" else args.spp
            settings = RenderSettings(integrator=name, spp=spp, threads=args.threads,
                                      **_bounces(RenderSettings, 8), seed=0)
            stats = render(scene, settings).stats
            if stats["samples_per_s"] > best.get(name, {}).get("samples_per_s", 0.0):
                best[name] = stats
            t0 = time.process_time()
            stats = render(scene, RenderSettings(integrator=name, spp=spp, threads=1,
                                                 **_bounces(RenderSettings, 8), seed=0)).stats
            cpu[name] = min(cpu.get(name, float("inf")),
                            1e6 * (time.process_time() - t0) / stats["samples"])
    return best, cpu


def unit_costs(scene, args):
    """Per integrator of ``args.integrators``: CPU microseconds per sample of ``args.units``
    work units called directly (best of ``args.repeats``), and the ``cProfile`` statistics
    of one more such run when ``args.cprofile`` asks for them."""
    import cProfile

    import numpy as np
    from sampling_lab.core.film import PixelFilter
    from sampling_lab.core.integrators import integrator_class
    from sampling_lab.core.integrators.base import Counters
    from sampling_lab.core.prepare import prepare
    from sampling_lab.core.render import RenderSettings
    from sampling_lab.core.sampling.samplers import make_sampler

    w, h = args.width, args.height
    out = {}
    for name in args.integrators.split(","):
        settings = RenderSettings(integrator=name, spp=4, threads=1, seed=0,
                                  sampler="independent", light_selection="power",
                                  **_bounces(RenderSettings, 8))
        integ = integrator_class(name)(prepare(scene, "power"), settings)
        n = args.unit_paths or integ.unit_paths  # a render's own unit size by default
        sampler = make_sampler("independent", seed=0, spp=4, width=w)
        pixel_filter = PixelFilter(settings.filter_type, settings.filter_width)

        def run(units):
            for u in range(units):
                pixels = (np.arange(n) + u * n) % (w * h)
                integ.render_samples(sampler.stream(pixels, np.full(n, u * n // (w * h))),
                                     pixel_filter, Counters())

        run(1)  # warm-up: per-thread buffers, first-call costs
        best = float("inf")
        for _ in range(args.repeats):
            t0 = time.thread_time()
            run(args.units)
            best = min(best, 1e6 * (time.thread_time() - t0) / (args.units * n))
        out[name] = best
        print(f"{name:>5}: {best:.3f} CPU us per sample ({args.units} units of {n} paths, "
              f"best of {args.repeats})")
        if args.cprofile:
            import pstats
            profile = cProfile.Profile(time.thread_time)
            profile.runcall(run, args.units)
            pstats.Stats(profile).sort_stats(args.cprofile_sort).print_stats(args.cprofile)
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--spp", type=int, default=4, help="light tracing and BDPT")
    parser.add_argument("--path-spp", type=int, default=16)
    parser.add_argument("--width", type=int, default=256)
    parser.add_argument("--height", type=int, default=256)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--scene", default="bench",
                        help="bench (the bench's mesh-light box) or a bench-scenes scene "
                             "(tools.hard_scenes.SCENES, e.g. mirror_ball; needs bpy)")
    parser.add_argument("--integrators", default="light,bdpt",
                        help="measured and profiled beside the path tracer, comma-separated")
    parser.add_argument("--no-profile", action="store_true", help="speed figures only")
    parser.add_argument("--units", type=int, default=0,
                        help="CPU time per sample of this many work units called directly")
    parser.add_argument("--unit-paths", type=int, default=0,
                        help="paths per unit (default: the integrator's own, as a render's)")
    parser.add_argument("--cprofile", type=int, default=0,
                        help="with --units: print this many functions of a cProfile")
    parser.add_argument("--cprofile-sort", default="tottime",
                        help="order of the cProfile's functions (pstats key: tottime, "
                             "cumulative, ...)")
    args = parser.parse_args(argv)
    if args.units:
        print(f"load average at start: {os.getloadavg()}")
        unit_costs(_scene(args), args)
        print(f"load average at end: {os.getloadavg()}")
        return

    from sampling_lab.core.render import RenderSettings, render

    scene = _scene(args)
    print(f"load average at start: {os.getloadavg()}")
    best, cpu = speeds(scene, args, ("path", *args.integrators.split(",")))
    path_sps = best["path"]["samples_per_s"]
    print(f"camera samples/s at {args.threads} threads (wall clock, best of {args.repeats}) | "
          f"CPU us per sample at 1 thread (min of {args.repeats})")
    for name, stats in best.items():
        print(f"{name:>5}: {stats['samples_per_s'] / 1e6:.4f} M samples/s "
              f"({stats['samples_per_s'] / path_sps:.3f} x path), "
              f"{stats['rays_per_s'] / 1e6:.3f} M rays/s, {stats['time_s']:.2f} s | "
              f"{cpu[name]:.2f} us ({cpu['path'] / cpu[name]:.3f} x path)")
    if args.no_profile:
        return
    install_timers()
    for name in args.integrators.split(","):
        _TOTALS.clear()
        render(scene, RenderSettings(integrator=name, spp=args.spp, threads=args.threads,
                                     **_bounces(RenderSettings, 8), seed=0))
        total = sum(_TOTALS.values())
        per = 1e6 / (args.width * args.height * args.spp)  # us per camera sample
        print(f"\n{name}: stage profile (exclusive thread CPU seconds, total {total:.2f} s, "
              f"{total * per:.2f} us per sample):")
        for stage, sec in sorted(_TOTALS.items(), key=lambda kv: -kv[1]):
            print(f"  {100 * sec / total:5.1f} %  {sec * per:6.3f} us  {stage}")
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
