"""Command line: ``python -m sampling_lab render|bench ...``.

``render SCENE -o OUT.exr`` renders a built-in scene (no Blender needed) or a ``.blend`` file (with
the ``bpy`` module, like ``blender -b file.blend -f N``: the file's camera, resolution and frame
unless overridden) and writes a multilayer EXR (Combined, Variance, Sample Count, and with
``--strategy-views`` BDPT's per-strategy layers) atomically.
A progress bar goes to stderr; ``--json`` prints one JSON line of figures to stdout.

Usage errors, unknown names and unreadable files exit with code 2 and a one-line message.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys

from ..core import scenes as builtin_scenes
from ..core.integrators import INTEGRATORS
from ..core.render import RenderSettings, render, used_settings
from ..core.lights import LIGHT_SAMPLINGS, LIGHT_SELECTIONS
from ..core.sampling.distributions import DISTRIBUTION_METHODS
from ..core.sampling.mis import MIS_SETTINGS
from ..core.sampling.samplers import available as available_samplers


class UsageError(Exception):
    """A mistake in the command line or its inputs: exit code 2, one line."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(message)


def _resolution(text):
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"resolution must look like 640x480, not {text!r}")
    if w < 1 or h < 1:
        raise argparse.ArgumentTypeError("resolution must be at least 1x1")
    return w, h


def _positive_int(text):
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, not {text}")
    return value


def _positive_float(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, not {text!r}")
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive number, not {text}")
    return value


def _unit_float(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number in [0, 1], not {text!r}")
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a number in [0, 1], not {text}")
    return value


# Longest path with strategy views (the add-on's Max Path Length allows the same).
MAX_STRATEGY_LENGTH = 8


def _path_length(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a path length in segments, not {text!r}")
    if not 1 <= value <= MAX_STRATEGY_LENGTH:
        raise argparse.ArgumentTypeError(
            f"expected a path length from 1 to {MAX_STRATEGY_LENGTH} segments, not {text}")
    return value


def build_parser():
    parser = _Parser(prog="python -m sampling_lab", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    r = sub.add_parser("render", help="render a built-in scene or a .blend file to EXR")
    r.add_argument("scene", help=f".blend path or built-in scene: {', '.join(builtin_scenes.BUILTIN)}")
    r.add_argument("-o", "--output", required=True, help="output .exr path")
    r.add_argument("--integrator", default="path", help=f"one of: {', '.join(INTEGRATORS)}")
    r.add_argument("--sampler", default="independent", help=f"one of: {', '.join(available_samplers())}")
    halt = r.add_mutually_exclusive_group()
    halt.add_argument("--spp", type=_positive_int, help="samples per pixel (default 16)")
    halt.add_argument("--time", type=float, help="time limit in seconds")
    r.add_argument("--max-depth", type=_positive_int, default=None,
                   help="maximum bounces (Cycles' max bounces; default 8)")
    r.add_argument("--mis", choices=MIS_SETTINGS, default=None,
                   help="how light and BSDF samples are combined (default power)")
    r.add_argument("--mis-beta", type=_positive_float, default=None,
                   help="power heuristic exponent (default 2)")
    r.add_argument("--mis-alpha", type=_unit_float, default=None,
                   help="cutoff heuristic fraction in [0, 1] (default 0.1)")
    r.add_argument("--light-selection", choices=LIGHT_SELECTIONS, default=None,
                   help="choose lights by power or uniformly (default power)")
    r.add_argument("--light-sampling", choices=LIGHT_SAMPLINGS, default=None,
                   help="path tracing: sample area emitters by area or solid angle (default "
                        "area); light tracing and bdpt always sample them by area")
    r.add_argument("--distribution", choices=DISTRIBUTION_METHODS, default=None,
                   help="discrete sampling by CDF inversion or alias table (default cdf)")
    r.add_argument("--strategy-views", action="store_true", default=None,
                   help="bdpt: also write two EXR layers per strategy (s, t), its own estimate "
                        "and its MIS-weighted share")
    r.add_argument("--strategy-max-length", type=_path_length, default=None, metavar="K",
                   help=f"longest path (segments) with strategy views, 1..{MAX_STRATEGY_LENGTH} "
                        f"(default 3)")
    r.add_argument("--seed", type=int, default=None)
    r.add_argument("--resolution", type=_resolution, default=None, help="WxH")
    r.add_argument("--threads", type=_positive_int, default=None,
                   help="worker threads (default: a .blend file's Render > Performance > "
                        "Threads, else one per CPU core)")
    r.add_argument("--frame", type=int, default=None, help="frame of a .blend to render")
    r.add_argument("--png", action="store_true", help="also write an sRGB PNG preview beside OUT")
    r.add_argument("--json", action="store_true", help="print one JSON line of figures")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    b = sub.add_parser("bench", help="speed against error on the Cornell box (figures, not tests)")
    b.add_argument("--resolution", type=_resolution, default=(256, 256))
    b.add_argument("--seconds", type=float, default=10.0, help="equal-time budget per renderer")
    b.add_argument("--reference-spp", type=_positive_int, default=1024)
    b.add_argument("--no-cycles", action="store_true", help="skip the Cycles comparison")
    b.add_argument("--output", default="bench/results", help="folder for CSV and images")
    from ..core.sampling.lab import build_parser as lab_parser

    lab_parser(sub.add_parser("samplers", help="sampler lab: points, spectra, star discrepancy "
                              "and checkerboard variance of every sampler (CSV, PNG, markdown)"))
    bs = sub.add_parser("bench-strategies",
                        help="equal-time error of every sampler and MIS setting (figures)")
    bs.add_argument("--quick", action="store_true", help="tiny smoke run (seconds, not minutes)")
    bs.add_argument("--resolution", type=_resolution, default=None, help="WxH (default 128x128)")
    bs.add_argument("--seconds", type=float, default=None,
                    help="equal-time budget in CPU seconds (default: the baseline's 64-spp time)")
    bs.add_argument("--output", default="bench/results", help="folder for CSV, cache and plots")
    bs.add_argument("--docs", default=None,
                    help="markdown report to write (default docs/STRATEGIES.md unless --quick)")
    _add_bench_scenes_parser(sub)
    v = sub.add_parser("bdpt-views", help="BDPT's per-strategy images in one figure, by path "
                       "length (docs/images/bdpt_views_<scene>.png)")
    v.add_argument("--scene", default="glass_caustic", choices=sorted(builtin_scenes.BUILTIN))
    v.add_argument("--size", type=_resolution, default=(96, 96), help="WxH (default 96x96)")
    v.add_argument("--spp", type=_positive_int, default=32)
    v.add_argument("--max-length", type=_positive_int, default=4,
                   help="longest path shown, in segments (default 4)")
    v.add_argument("--output", default="docs/images", help="folder of the PNG")
    c = sub.add_parser("bench-caustic", help="equal-time error of path, light and BDPT on the "
                       "small-light glass caustic (docs/CAUSTIC.md)")
    c.add_argument("--size", type=_resolution, default=(64, 64), help="WxH (default 64x64)")
    c.add_argument("--seconds", type=_positive_float, default=8.0)
    c.add_argument("--reference-seconds", type=_positive_float, default=120.0)
    c.add_argument("--docs", default="docs/CAUSTIC.md", help="markdown report ('' for none)")
    return parser


def _add_bench_scenes_parser(sub):
    from ..bench.hard_scenes import INTEGRATOR_SCENES, MATERIAL_SCENES, SCENES

    h = sub.add_parser("bench-scenes", help="equal-time error of our integrators and Cycles on "
                       "hard scenes (figures, docs/HARD_SCENES.md)")
    h.add_argument("--scenes", nargs="+", default=list(SCENES),
                   help=f"from: {', '.join(SCENES)} (default: all; materials: "
                   f"{' '.join(MATERIAL_SCENES)}; integrators: {' '.join(INTEGRATOR_SCENES)})")
    h.add_argument("--integrators", nargs="+", default=None,
                   help=f"from: {', '.join(INTEGRATORS)} (default: all of them)")
    h.add_argument("--seconds", type=_positive_float, default=4.0,
                   help="equal wall-clock budget of every render")
    h.add_argument("--size", type=_resolution, default=(64, 64), help="WxH (default 64x64)")
    h.add_argument("--reference-spp", type=_positive_int, default=1024)
    h.add_argument("--reference-seconds", type=float, default=None,
                   help="time cap of each reference (default max(30, 8 x --seconds); 0: none)")
    h.add_argument("--sampler", default="independent",
                   help="sampler of our equal-time renders (default independent)")
    h.add_argument("--no-cycles", action="store_true", help="skip the Cycles renders")
    h.add_argument("--output", default="bench/results", help="folder for CSV and images")
    h.add_argument("--docs", default="docs/HARD_SCENES.md",
                   help="markdown report to write ('' for none)")


class ProgressBar:
    """A one-line progress bar on stderr (redrawn in place on a terminal, every 10 % otherwise)."""

    def __init__(self, stream=sys.stderr, quiet=False):
        self.stream = stream
        self.quiet = quiet
        self.tty = stream.isatty()
        self.last_decile = -1

    def __call__(self, fraction, text):
        if self.quiet:
            return
        fraction = min(max(fraction, 0.0), 1.0)
        bar = "#" * int(30 * fraction) + "-" * (30 - int(30 * fraction))
        line = f"[{bar}] {100 * fraction:5.1f}% {text}"
        if self.tty:
            self.stream.write("\r" + line)
        elif int(10 * fraction) > self.last_decile:
            self.last_decile = int(10 * fraction)
            self.stream.write(line + "\n")
        self.stream.flush()

    def close(self):
        if self.tty and not self.quiet:
            self.stream.write("\n")


def load_scene(args):
    """Scene and the settings it carries, from a built-in name or a .blend file."""
    settings = RenderSettings()
    name = args.scene
    if name.lower().endswith(".blend") or os.path.sep in name:
        if not os.path.isfile(name) or not os.access(name, os.R_OK):
            raise UsageError(f"cannot read scene file {name!r}")
        from .blendfile import is_blend_file, load_blend

        if not is_blend_file(name):
            raise UsageError(f"{name!r} is not a .blend file")
        try:
            scene, file_settings = load_blend(os.path.abspath(name), frame=args.frame,
                                              resolution=args.resolution)
        except (RuntimeError, ValueError) as exc:
            raise UsageError(f"cannot render {name!r}: {str(exc).strip().splitlines()[-1]}")
        settings = file_settings
    else:
        if name not in builtin_scenes.BUILTIN:
            raise UsageError(f"unknown scene {name!r}; built-in scenes: "
                             f"{', '.join(builtin_scenes.BUILTIN)} (or give a .blend path)")
        w, h = args.resolution or (256, 256)
        scene = builtin_scenes.BUILTIN[name](w, h)
    return scene, settings


def cmd_render(args):
    if args.integrator not in INTEGRATORS:
        raise UsageError(f"unknown integrator {args.integrator!r}; choose from "
                         f"{', '.join(INTEGRATORS)}")
    if args.sampler.lower() not in available_samplers():
        raise UsageError(f"unknown sampler {args.sampler!r}; choose from {', '.join(available_samplers())}")
    if not args.output.lower().endswith(".exr"):
        raise UsageError(f"output must be an .exr file, not {args.output!r}")
    scene, settings = load_scene(args)
    settings.integrator = args.integrator
    settings.sampler = args.sampler.lower()
    if args.threads is not None:
        settings.threads = args.threads
    if args.time is not None:
        settings.spp, settings.time_limit = 0, args.time
    elif args.spp is not None:
        settings.spp, settings.time_limit = args.spp, 0.0
    if args.max_depth is not None:
        settings.max_bounces = args.max_depth
    if args.seed is not None:
        settings.seed = args.seed
    for flag, field in (("mis", "mis_heuristic"), ("mis_beta", "mis_beta"),
                        ("mis_alpha", "mis_alpha"), ("light_selection", "light_selection"),
                        ("light_sampling", "light_sampling"), ("distribution", "distribution"),
                        ("strategy_views", "strategy_views"),
                        ("strategy_max_length", "strategy_max_length")):
        if getattr(args, flag) is not None:
            setattr(settings, field, getattr(args, flag))
    used = used_settings(settings)
    for flag, field in (("mis", "mis_heuristic"), ("mis_beta", "mis_beta"),
                        ("mis_alpha", "mis_alpha"), ("light_selection", "light_selection"),
                        ("light_sampling", "light_sampling"), ("distribution", "distribution")):
        if getattr(args, flag) is not None and used[field] != getattr(settings, field):
            print(f"note: --{flag.replace('_', '-')} {getattr(args, flag)} does not apply to "
                  f"{settings.integrator} with --mis {settings.mis_heuristic}: it uses "
                  f"{used[field]}", file=sys.stderr)
    if settings.strategy_views and not getattr(INTEGRATORS[settings.integrator],
                                               "HAS_STRATEGY_VIEWS", False):
        print(f"note: the {settings.integrator} integrator writes no strategy views "
              f"(only bdpt does)", file=sys.stderr)
    for message in scene.messages:
        print(f"note: {message}", file=sys.stderr)

    from ..core.exr import write_multilayer, write_png_preview

    bar = ProgressBar(quiet=args.quiet)
    interrupted = []
    # Ctrl-C cancels like Esc in Blender: the samples taken so far are still written.
    previous = signal.signal(signal.SIGINT, lambda *_: interrupted.append(True))
    try:
        result = render(scene, settings, progress=bar, cancel=lambda: bool(interrupted))
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    finally:
        signal.signal(signal.SIGINT, previous)
        bar.close()
    if result.cancelled:
        print("sampling_lab: cancelled; writing the samples taken", file=sys.stderr)
    # BDPT's strategy views (empty unless asked for) go into the same file as extra layers.
    layers = result.layers()
    write_multilayer(args.output, {
        "Combined": result.combined(),
        "Variance": result.variance(),
        "Sample Count": result.sample_count()[..., None],
        **layers,
    })
    if args.png:
        write_png_preview(os.path.splitext(args.output)[0] + ".png", result.combined()[..., :3])
    stats = dict(result.stats)
    stats.update(output=os.path.abspath(args.output), integrator=settings.integrator,
                 sampler=settings.sampler, width=scene.camera.width, height=scene.camera.height,
                 strategy_views=settings.strategy_views,
                 strategy_max_length=settings.strategy_max_length,
                 layers=list(layers))
    if args.json:
        print(json.dumps(stats))
    elif not args.quiet:
        png = f" and {os.path.splitext(args.output)[0]}.png" if args.png else ""
        print(f"wrote {args.output}{png}: {stats['spp']} spp in {stats['time_s']:.2f} s, "
              f"{stats['samples_per_s'] / 1e6:.3f} M samples/s, "
              f"{stats['rays_per_s'] / 1e6:.2f} M rays/s", file=sys.stderr)
    return 0


def cmd_bench(args):
    from ..bench.cornell import run

    return run(resolution=args.resolution, seconds=args.seconds,
               reference_spp=args.reference_spp, cycles=not args.no_cycles, output=args.output)


def cmd_bench_strategies(args):
    from ..bench.strategies import run

    return run(quick=args.quick, resolution=args.resolution, seconds=args.seconds,
               output=args.output, docs=args.docs)


def cmd_bench_scenes(args, argv):
    from ..bench.hard_scenes import run

    command = "python -m sampling_lab " + " ".join(argv if argv is not None else sys.argv[1:])
    return run(scenes=args.scenes, integrators=args.integrators, seconds=args.seconds,
               size=args.size, reference_spp=args.reference_spp, cycles=not args.no_cycles,
               output=args.output, docs=args.docs or None,
               reference_seconds=args.reference_seconds, sampler=args.sampler.lower(),
               command=command)


def cmd_bdpt_views(args):
    from ..bench.bdpt_views import run

    path, means = run(scene=args.scene, size=args.size, spp=args.spp,
                      max_length=args.max_length, output=args.output)
    for name, mean in means.items():
        print(f"{name:32s} image mean {mean:.5g}")
    print(path)
    return 0


def main(argv=None):
    try:
        args = build_parser().parse_args(argv)
        if args.command == "render":
            return cmd_render(args)
        if args.command == "bench-strategies":
            return cmd_bench_strategies(args)
        if args.command == "bench-scenes":
            return cmd_bench_scenes(args, argv)
        if args.command == "bdpt-views":
            return cmd_bdpt_views(args)
        if args.command == "bench-caustic":
            from ..bench.caustic import run as caustic_run

            caustic_run(size=args.size, seconds=args.seconds,
                        reference_seconds=args.reference_seconds, output=args.docs or None)
            return 0
        if args.command == "samplers":
            from ..core.sampling.lab import main as lab_main

            try:
                return lab_main(args=args)
            except ValueError as exc:
                raise UsageError(str(exc)) from None
        return cmd_bench(args)
    except UsageError as exc:
        print(f"sampling_lab: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("sampling_lab: interrupted", file=sys.stderr)
        return 130
