"""The tools' subcommands of the command line: benchmarks and the sampler lab.

Each command writes into ``out/<command>/`` or its ``--output`` folder and nowhere else; with
``--update-docs`` it also copies its report and the figures ``docs/`` shows into the repository's
``docs/`` (:mod:`.outputs`). ``cli.build_parser`` adds these parsers beside ``render``; each sets
``run``, the function that carries the command out and returns its exit code.
"""

from __future__ import annotations

import os

from ..cli import _option_type, _positive_float, _positive_int, _resolution
from ..core import scenes as builtin_scenes
from ..core.integrators import INTEGRATORS
from ..core.options import OPTIONS
from .outputs import add_output_arguments


def _bench(args):
    from .cornell import run

    return run(resolution=args.resolution, seconds=args.seconds,
               reference_spp=args.reference_spp, cycles=not args.no_cycles, output=args.output,
               workers=args.workers)


def _workers(parser):
    """``--workers``: where our renders' work units run (the registry's option)."""
    parser.add_argument("--workers", type=_option_type(OPTIONS["workers"]),
                        default=OPTIONS["workers"].default, metavar="KIND",
                        help=f"where our renders' work units run: one of "
                             f"{OPTIONS['workers'].allowed()}")


def _bench_strategies(args):
    from .strategies import run

    if args.update_docs and args.quick:
        raise ValueError("--update-docs needs the full run docs/ shows, not --quick")
    return run(quick=args.quick, resolution=args.resolution, seconds=args.seconds,
               output=args.output, update_docs=args.update_docs)


def _bench_scenes(args):
    from .hard_scenes import run

    command = "python -m sampling_lab " + " ".join(args.argv)
    return run(scenes=args.scenes, integrators=args.integrators, seconds=args.seconds,
               size=args.size, reference_spp=args.reference_spp, cycles=not args.no_cycles,
               output=args.output, update_docs=args.update_docs,
               reference_seconds=args.reference_seconds, sampler=args.sampler, seed=args.seed,
               command=command, workers=args.workers, repeats=args.repeats)


def _bdpt_views(args):
    from .bdpt_views import DOCS_FOLDER, run
    from .outputs import publish

    path, means = run(scene=args.scene, size=args.size, spp=args.spp,
                      max_length=args.max_length,
                      output=os.path.join(args.output, DOCS_FOLDER))
    for name, mean in means.items():
        print(f"{name:32s} image mean {mean:.5g}")
    print(path)
    if args.update_docs:
        publish(args.output, [f"{DOCS_FOLDER}/{os.path.basename(path)}"])
    return 0


def _bdpt_error(args):
    from .bdpt_error import run

    bench = args.scene is None
    run(scene=args.bench_scene if bench else args.scene, bench=bench, size=args.size, spp=args.spp, renders=args.renders,
        max_length=args.max_length, max_bounces=args.max_bounces, sampler=args.sampler,
        seed=args.seed, top=args.top, output=args.output)
    return 0


def _add_bdpt_error(sub, **kw):
    from .hard_scenes import SCENES

    p = _add(sub, "bdpt-error", "where BDPT's error lies: each strategy's share of the image's "
             "variance (relMSE-weighted) over independent renders, the per-render error "
             "distribution and the worst pixel (figures; docs/BENCHMARKS.md quotes a run)",
             _bdpt_error, **kw)
    which = p.add_mutually_exclusive_group()
    which.add_argument("--bench-scene", default="mirror_ball", choices=list(SCENES),
                       help="a bench-scenes scene, built in bpy (default: %(default)s)")
    which.add_argument("--scene", default=None, choices=sorted(builtin_scenes.BUILTIN),
                       help="instead, a built-in scene (no bpy; default: the bench-scene)")
    _size(p, (96, 96))
    p.add_argument("--spp", type=_positive_int, default=16, help="samples per pixel per render")
    p.add_argument("--renders", type=_positive_int, default=32,
                   help="independent renders (at least 2)")
    p.add_argument("--max-length", type=_positive_int, default=8,
                   help="longest path with strategy views, in segments (at most 8; "
                        "max bounces + 2 covers every path)")
    p.add_argument("--max-bounces", type=int, default=8, help="bounce limit of every kind")
    p.add_argument("--sampler", type=_option_type(OPTIONS["sampler"]),
                   default=OPTIONS["sampler"].default, metavar="NAME",
                   help=f"one of {OPTIONS['sampler'].allowed()}")
    p.add_argument("--seed", type=int, default=1000, help="seed of the first render")
    p.add_argument("--top", type=_positive_int, default=12, help="strategies listed")
    add_output_arguments(p, "bdpt-error")


def _bench_caustic(args):
    from .caustic import run

    run(size=args.size, seconds=args.seconds, reference_seconds=args.reference_seconds,
        output=args.output, update_docs=args.update_docs)
    return 0


def _bench_photons(args):
    from .photons import run, sweep, variants

    if args.variants:
        variants(scenes=args.scenes, size=args.size, seconds=args.seconds,
                 reference_seconds=args.reference_seconds, output=args.output)
        return 0
    if args.sweep:
        sweep(scenes=args.scenes, size=args.size, seconds=args.seconds,
              reference_seconds=args.reference_seconds, output=args.output)
        return 0
    run(scenes=args.scenes, size=args.size, seconds=args.seconds,
        reference_seconds=args.reference_seconds, photons=args.photons,
        cycles=not args.no_cycles, output=args.output, update_docs=args.update_docs)
    return 0


def _add_bench_photons(sub, **kw):
    from .photons import SCENES

    p = _add(sub, "bench-photons", "equal-time error of SPPM, photon mapping, path, BDPT and "
             "Cycles on point-light mirror and glass caustics, with M photons/s and photon "
             "memory (PHOTONS_BENCH.md)", _bench_photons, **kw)
    p.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES),
                   metavar="SCENE", help=f"from: {', '.join(SCENES)} (default: all)")
    _size(p, (64, 64))
    p.add_argument("--seconds", type=_positive_float, default=8.0,
                   help="equal wall-clock budget of every render")
    p.add_argument("--reference-seconds", type=_positive_float, default=120.0,
                   help="time of the BDPT references of point_glass and point_mirror_glass")
    p.add_argument("--photons", type=_positive_int, default=None,
                   help="photons per SPPM pass and in photon mapping's maps (default: the "
                        "render default, Photons)")
    p.add_argument("--no-cycles", action="store_true", help="skip the Cycles renders")
    p.add_argument("--variants", action="store_true",
                   help="instead: SPPM with and without the surface test, with footprint "
                        "radii and with 25k photons per pass, between two BDPT renders "
                        "(photons_variants.csv)")
    p.add_argument("--sweep", action="store_true",
                   help="instead: SPPM's photons per pass, initial radius and alpha against "
                        "BDPT at equal time (photons_sweep.csv), what its defaults rest on")
    add_output_arguments(p, "bench-photons", "PHOTONS_BENCH.md")


def _bench_mlt(args):
    from .mlt import run

    run(size=args.size, seconds=args.seconds, seeds=args.seeds,
        reference_seconds=args.reference_seconds, output=args.output)
    return 0


def _bench_lights(args):
    from .light_tree import run

    run(size=args.size, seconds=args.seconds, reference_seconds=args.reference_seconds,
        output=args.output)
    return 0


def _bench_gap(args):
    from .gap import run

    run(scenes=args.scenes, size=args.size, spp=args.spp, seeds=args.seeds,
        reference_spp=args.reference_spp, output=args.output)
    return 0


def _bench_export(args):
    from .export_speed import run

    run(triangles=args.triangles, repeats=args.repeats)
    return 0


def _bench_materials(args):
    from .materials_speed import run

    run(rows=args.rows, repeats=args.repeats)
    return 0


def _bench_radiosity(args):
    from .radiosity import SIZES, run

    sizes = ({k: (1.5,) for k in SIZES} if args.quick
             else {k: v[:args.levels] for k, v in SIZES.items()})
    run(size=args.size, seconds=args.seconds, reference_seconds=args.reference_seconds,
        cycles=not (args.no_cycles or args.quick), sizes=sizes, output=args.output,
        figure=not args.quick)
    return 0


def _bench_limits(args):
    from .limits import run

    from .limits import BVH_SIZES

    bvh_sizes = args.bvh_sizes or (BVH_SIZES if args.bvh or args.bvh_only else ())
    run(integrators=() if args.bvh_only else args.integrators, repeats=args.repeats,
        cancel_size=args.cancel_size, rss_size=args.rss_size, cli=not args.no_cli,
        rss=not args.no_rss, output=args.output, bvh_sizes=bvh_sizes)
    return 0


def _add_bench_limits(sub, **kw):
    p = _add(sub, "bench-limits", "cancel latency (core hook and Ctrl-C on the command line) "
             "and peak RSS at 1920x1080 of every integrator (a table; docs/LIMITS.md quotes a "
             "run)", _bench_limits, **kw)
    p.add_argument("--integrators", nargs="+", default=list(INTEGRATORS),
                   choices=list(INTEGRATORS), metavar="NAME",
                   help=f"from: {', '.join(INTEGRATORS)} (default: all)")
    p.add_argument("--repeats", type=_positive_int, default=5,
                   help="cancels per integrator (half as many on the command line)")
    _size(p, (640, 360), "--cancel-size", "image size of the cancelled renders")
    _size(p, (1920, 1080), "--rss-size", "image size of the peak-memory renders")
    p.add_argument("--no-cli", action="store_true", help="skip the command-line cancels")
    p.add_argument("--no-rss", action="store_true", help="skip the peak-memory renders")
    p.add_argument("--bvh", action="store_true",
                   help="also cancel Embree's BVH build of 1, 3 and 10 M triangles")
    p.add_argument("--bvh-sizes", type=_positive_int, nargs="+", metavar="TRIANGLES",
                   help="triangle counts of the BVH build measurements (implies --bvh; "
                        "default: none, or 1, 3 and 10 M with --bvh)")
    p.add_argument("--bvh-only", action="store_true",
                   help="only the BVH build measurements (no integrator)")
    add_output_arguments(p, "bench-limits")


def _bench_soak(args):
    from .soak import run

    run(minutes=args.minutes, size=args.size, spp=args.spp, output=args.output,
        new_file=args.new_file)
    return 0


def _add_bench_soak(sub, **kw):
    p = _add(sub, "bench-soak", "repeated renders of several scenes and integrators in one "
             "Blender session: RSS and time per render over time (a table and a CSV; "
             "docs/LIMITS.md quotes a run)", _bench_soak, **kw)
    p.add_argument("--minutes", type=_positive_float, default=30.0,
                   help="how long to keep rendering (whole rounds)")
    _size(p, (96, 72))
    p.add_argument("--spp", type=_positive_int, default=8, help="samples per pixel")
    p.add_argument("--new-file", action="store_true",
                   help="build every job in a new file (read_homefile) instead of emptying the "
                        "scene: adds Blender's own few kB per file read and rendered")
    add_output_arguments(p, "bench-soak")


def _samplers(args):
    from .sampler_lab import main

    return main(args)


def _size(parser, default, flag="--size", text=None):
    """The image size flag: ``WxH``."""
    text = text or f"image size (default: {default[0]}x{default[1]})"
    parser.add_argument(flag, type=_resolution, default=default, metavar="WxH", help=text)


def _fuzz(args):
    from .fuzz import run

    return run(count=args.count, seed=args.seed, timeout=args.timeout, batch=args.batch,
               memory_gb=args.memory_gb, output=args.output, update_docs=args.update_docs,
               command="python -m sampling_lab " + " ".join(args.argv))


def _add_fuzz(sub, **kw):
    f = _add(sub, "fuzz", "randomly broken scenes and command lines: each must render or be "
             "refused in one line, never a traceback, crash, hang or NaN (FUZZ.md)", _fuzz, **kw)
    f.add_argument("--count", type=_positive_int, default=500, help="cases to make and run")
    f.add_argument("--seed", type=_positive_int, default=0, help="seed of the cases")
    f.add_argument("--timeout", type=_positive_float, default=60.0,
                   help="seconds after which a case counts as a hang")
    f.add_argument("--batch", type=_positive_int, default=25,
                   help="cases per child process (a crash or hang costs only its child)")
    f.add_argument("--memory-gb", type=_positive_float, default=8.0,
                   help="address-space cap of each child, so a runaway allocation fails there")
    add_output_arguments(f, "fuzz", "FUZZ.md")


def _add(sub, name, summary, run, **kw):
    p = sub.add_parser(name, help=summary, description=summary[0].upper() + summary[1:], **kw)
    p.set_defaults(run=run)
    return p


def add_parsers(sub, **kw):
    """Add every tool's subcommand to ``sub`` (argparse subparsers); ``kw`` to each parser."""
    from .sampler_lab import add_arguments as samplers_arguments

    samplers_arguments(_add(sub, "samplers", "sampler lab: points, spectra, star discrepancy "
                            "and checkerboard variance of every sampler (CSV, PNG, markdown)",
                            _samplers, **kw))
    _add_fuzz(sub, **kw)
    b = _add(sub, "bench", "speed against error of embreex, our path tracer and Cycles on the "
             "Cornell box (figures, not tests)", _bench, **kw)
    _size(b, (256, 256), "--resolution")
    b.add_argument("--seconds", type=_positive_float, default=10.0,
                   help="equal-time budget per renderer")
    b.add_argument("--reference-spp", type=_positive_int, default=1024,
                   help="samples per pixel of the references (capped by time)")
    b.add_argument("--no-cycles", action="store_true", help="skip the Cycles comparison")
    _workers(b)
    add_output_arguments(b, "bench")
    s = _add(sub, "bench-strategies", "equal-time error of every sampler and MIS setting on "
             "the Cornell box (STRATEGIES.md)", _bench_strategies, **kw)
    s.add_argument("--quick", action="store_true", help="tiny smoke run (seconds, not minutes)")
    _size(s, None, "--resolution", text="image size (default: 128x128; 32x32 with --quick)")
    s.add_argument("--seconds", type=_positive_float, default=None,
                   help="equal-time budget in CPU seconds (default: the baseline's time at its "
                        "largest sample count)")
    add_output_arguments(s, "bench-strategies", "STRATEGIES.md and its figures")
    _add_bench_scenes(sub, **kw)
    _add_bench_photons(sub, **kw)
    v = _add(sub, "bdpt-views", "BDPT's per-strategy images in one figure, by path length "
             "(images/bdpt_views_<scene>.png)", _bdpt_views, **kw)
    v.add_argument("--scene", default="glass_caustic", choices=sorted(builtin_scenes.BUILTIN),
                   help="built-in scene")
    _size(v, (96, 96))
    v.add_argument("--spp", type=_positive_int, default=32, help="samples per pixel")
    v.add_argument("--max-length", type=_positive_int, default=4,
                   help="longest path shown, in segments")
    add_output_arguments(v, "bdpt-views", "the figure (images/bdpt_views_<scene>.png)")
    _add_bdpt_error(sub, **kw)
    c = _add(sub, "bench-caustic", "equal-time error of path, light and BDPT on the "
             "small-light glass caustic (CAUSTIC.md)", _bench_caustic, **kw)
    _size(c, (64, 64))
    c.add_argument("--seconds", type=_positive_float, default=8.0,
                   help="equal wall-clock budget of every render")
    c.add_argument("--reference-seconds", type=_positive_float, default=120.0,
                   help="time of the BDPT reference render")
    add_output_arguments(c, "bench-caustic", "CAUSTIC.md")
    g = _add(sub, "bench-lights", "equal-time error of power, uniform and light-tree "
             "selection on the many-lights scene (a table; docs/LIGHT_TREE.md quotes a run)",
             _bench_lights, **kw)
    _size(g, (64, 64))
    g.add_argument("--seconds", type=_positive_float, default=10.0,
                   help="equal wall-clock budget of every render")
    g.add_argument("--reference-seconds", type=_positive_float, default=60.0,
                   help="time of the light-tree reference render")
    add_output_arguments(g, "bench-lights")
    t = _add(sub, "bench-mlt", "equal-time error of Metropolis light transport and path "
             "tracing on two rooms joined by a narrow slit (a table; docs/INTEGRATORS.md "
             "quotes a run)", _bench_mlt, **kw)
    _size(t, (160, 120))
    t.add_argument("--seconds", type=_positive_float, default=15.0,
                   help="equal wall-clock budget of every render (MLT's bootstrap included)")
    t.add_argument("--seeds", type=_positive_int, default=3, help="renders per integrator")
    t.add_argument("--reference-seconds", type=_positive_float, default=240.0,
                   help="time of the path-traced reference (two halves of different seeds)")
    add_output_arguments(t, "bench-mlt")
    _add_bench_gap(sub, **kw)
    _add_bench_limits(sub, **kw)
    _add_bench_soak(sub, **kw)
    e = _add(sub, "bench-export", "triangles per second of the exporter on a large grid mesh "
             "(figures; docs/BENCHMARKS.md quotes a run)", _bench_export, **kw)
    e.add_argument("--triangles", type=_positive_int, default=1_000_000,
                   help="about this many triangles")
    e.add_argument("--repeats", type=_positive_int, default=5, help="exports timed")
    m = _add(sub, "bench-materials", "rows per second of BSDF sample + eval + pdf for every "
             "material model (coat, Multiscatter GGX, ...), side by side (figures, not tests)",
             _bench_materials, **kw)
    m.add_argument("--rows", type=_positive_int, default=100_000, help="rows per round")
    m.add_argument("--repeats", type=_positive_int, default=5, help="rounds (best is kept)")
    r = _add(sub, "bench-radiosity", "radiosity: solve time and peak memory against patch "
             "count for every solver, and equal-time error against path tracing and Cycles "
             "(a table; docs/RADIOSITY.md quotes a run)", _bench_radiosity, **kw)
    _size(r, (64, 64))
    r.add_argument("--seconds", type=_positive_float, default=10.0,
                   help="equal wall-clock budget of every render (radiosity's includes its "
                        "solve)")
    r.add_argument("--reference-seconds", type=_positive_float, default=120.0,
                   help="time of the path-traced reference render")
    r.add_argument("--levels", type=_positive_int, default=4,
                   help="patch sizes per solver, coarsest first (hierarchical: 4 reaches "
                        "about 106k patches)")
    r.add_argument("--no-cycles", action="store_true", help="skip the Cycles comparison")
    r.add_argument("--quick", action="store_true",
                   help="tiny smoke run: one coarse mesh per solver, no Cycles")
    add_output_arguments(r, "bench-radiosity")


def _add_bench_gap(sub, **kw):
    from .hard_scenes import SCENES

    p = _add(sub, "bench-gap", "error per sample of our path tracer and Cycles on the hard "
             "scenes, one sampling factor changed at a time (a table; docs/GAP.md quotes a run)",
             _bench_gap, **kw)
    p.add_argument("--scenes", nargs="+", default=list(SCENES), metavar="SCENE",
                   help=f"from: {', '.join(SCENES)} (default: all)")
    _size(p, (96, 96))
    p.add_argument("--spp", type=_positive_int, default=64,
                   help="samples per pixel of every compared render")
    p.add_argument("--seeds", type=_positive_int, default=4,
                   help="renders (seeds) per configuration")
    p.add_argument("--reference-spp", type=_positive_int, default=4096,
                   help="samples per pixel of each of the two Cycles references")
    add_output_arguments(p, "bench-gap")


def _add_bench_scenes(sub, **kw):
    from .hard_scenes import INTEGRATOR_SCENES, MATERIAL_SCENES, SCENE_REPEATS, SCENES

    h = _add(sub, "bench-scenes", "equal-time error of our integrators and Cycles on hard "
             "scenes (HARD_SCENES.md)", _bench_scenes, **kw)
    h.add_argument("--scenes", nargs="+", default=list(SCENES), metavar="SCENE",
                   help=f"from: {', '.join(SCENES)} (default: all; materials: "
                        f"{' '.join(MATERIAL_SCENES)}; integrators: {' '.join(INTEGRATOR_SCENES)})")
    h.add_argument("--integrators", nargs="+", default=None, metavar="NAME",
                   help=f"from: {', '.join(INTEGRATORS)} (default: all of them)")
    h.add_argument("--seconds", type=_positive_float, default=4.0,
                   help="equal wall-clock budget of every render")
    _size(h, (64, 64))
    h.add_argument("--reference-spp", type=_positive_int, default=1 << 16,
                   help="samples per pixel of each reference (capped by time, which usually "
                        "decides)")
    h.add_argument("--reference-seconds", type=float, default=None,
                   help="time cap of each of the two references, ours and Cycles' (default: "
                        "max(30, 6 x --seconds); 0: none)")
    h.add_argument("--sampler", type=_option_type(OPTIONS["sampler"]),
                   default=OPTIONS["sampler"].default,
                   metavar="NAME", help=f"sampler of our equal-time renders and reference: one of "
                                        f"{OPTIONS['sampler'].allowed()}")
    h.add_argument("--seed", type=_positive_int, default=0,
                   help="seed of the first equal-time render of each renderer (the references "
                        "take the next four, further repeats the seeds after them)")
    h.add_argument("--repeats", type=_positive_int, default=None, metavar="K",
                   help="equal-time renders per renderer and scene, ours and Cycles' alike, "
                        "with seeds no reference uses; the report gives their mean, spread and "
                        "each (default: " + ", ".join(f"{k} on {s}" for s, k in
                                                      SCENE_REPEATS.items()) + ", 1 elsewhere)")
    h.add_argument("--no-cycles", action="store_true", help="skip the Cycles renders")
    _workers(h)
    add_output_arguments(h, "bench-scenes", "HARD_SCENES.md and its figure")
