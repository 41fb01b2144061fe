"""Command line: ``python -m sampling_lab render|samplers|bench|... ``.

``render SCENE -o OUT.exr`` renders a built-in scene (no Blender needed) or a ``.blend`` file (with
the ``bpy`` module, like ``blender -b file.blend -f N``: the file's camera, resolution, frame and
Sampling Lab settings unless overridden) and writes a multilayer EXR (Combined, Variance, Sample
Count, and with ``--strategy-views`` BDPT's per-strategy layers) atomically. A progress bar goes
to stderr; ``--json`` prints one JSON line of figures to stdout. Its option flags, their help,
defaults and checks are made from :data:`core.options.OPTIONS`, the registry the add-on's
properties and the core's validation read too.

The other commands are the tools of ``tools/`` (benchmarks and the sampler lab): each writes
into ``out/<command>/`` or its ``--output`` folder, and into the repository's ``docs/`` only
with ``--update-docs``.

Usage errors, unknown names and unreadable files exit with code 2 and a one-line message.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import tempfile

from .core import scenes as builtin_scenes
from .core.applied_settings import unused_options
from .core.errors import RenderRefused
from .core.options import OPTIONS
from .core.render import RenderSettings, render

PROG = "sampling_lab"
DESCRIPTION = ("Sampling Lab: render scenes with Monte Carlo estimators and samplers, and "
               "measure them (Blender is needed only to read a .blend file)")


class UsageError(Exception):
    """A mistake in the command line or its inputs: exit code 2, one line."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(message)


class _Help(argparse.HelpFormatter):
    """Appends ``(default: ...)`` to every option whose help does not say its default."""

    def _get_help_string(self, action):
        text = action.help or ""
        if ("%(default)" in text or "default:" in text or not action.option_strings
                or action.default in (None, argparse.SUPPRESS)):
            return text
        return text + (" (default: off)" if action.default is False
                       else " (default: %(default)s)")


def _joined_resolution(argv):
    """``--resolution -5x10`` as ``--resolution=-5x10``: argparse would take ``-5x10`` for an
    option and say the value is missing instead of saying what is wrong with it."""
    out = []
    for arg in argv:
        if out and out[-1] == "--resolution" and arg[:1] == "-" and arg[1:2].isdigit():
            out[-1] = f"--resolution={arg}"
        else:
            out.append(arg)
    return out


def _resolution(text):
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"resolution must look like 640x480, not {text!r}")
    if w < 1 or h < 1:
        raise argparse.ArgumentTypeError(f"resolution must be at least 1x1, not {text!r}")
    return w, h


def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, not {text!r}")
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


def _option_type(option):
    """argparse ``type`` of a registry option: its own parse and check, its own message."""
    def parse(text):
        try:
            return option.parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(f"{exc}{option.why_not(text)}") from None

    parse.__name__ = option.name
    return parse


# The halting options exclude each other; every other registry option is a flag of its own.
HALTING = ("spp", "time_limit")


def _option_help(option):
    what = (f"one of {option.allowed()}" if option.choices
            else "" if option.kind is bool else f"in {option.allowed()}")
    default = option.default
    if option.kind is bool:
        default = "on" if default else "off"
    return (f"{option.description}{'; ' + what if what else ''} (default: {default}; a .blend "
            f"file: its own setting)").replace("%", "%%")


def add_option(parser, option, **kw):
    """The flag of registry ``option``: default None, so a .blend file's setting stays unless
    the flag is given."""
    if option.kind is bool:
        action = argparse.BooleanOptionalAction if option.default else "store_true"
        return parser.add_argument(option.flag_name, action=action, default=None,
                                   help=_option_help(option), **kw)
    metavar = option.name.split("_")[-1].upper() if not option.choices else "NAME"
    return parser.add_argument(option.flag_name, type=_option_type(option), default=None,
                               metavar=metavar, help=_option_help(option), **kw)


def _add_render_parser(sub):
    r = sub.add_parser("render", help="render a built-in scene or a .blend file to an EXR file",
                       description="Render a built-in scene or a .blend file to a multilayer "
                                   "EXR file", formatter_class=_Help)
    r.add_argument("scene", help=f".blend path or built-in scene: "
                                 f"{', '.join(builtin_scenes.BUILTIN)}")
    r.add_argument("-o", "--output", required=True, metavar="OUT.exr", help="output .exr path")
    halt = r.add_mutually_exclusive_group()
    for name, option in OPTIONS.items():
        add_option(halt if name in HALTING else r, option)
    r.add_argument("--resolution", type=_resolution, default=None, metavar="WxH",
                   help="image size (default: 256x256; a .blend file: its own)")
    r.add_argument("--frame", type=int, default=None,
                   help="frame of a .blend to render (default: its current frame)")
    r.add_argument("--png", action="store_true", help="also write an sRGB PNG preview beside OUT")
    r.add_argument("--json", action="store_true", help="print one JSON line of figures")
    r.add_argument("--quiet", action="store_true", help="no progress bar")


def build_parser():
    """The whole command line: ``render`` and, in a source checkout, the tools' commands
    (:mod:`.tools.commands`)."""
    parser = _Parser(prog=PROG, description=DESCRIPTION, formatter_class=_Help)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser,
                                metavar="COMMAND")
    _add_render_parser(sub)
    try:
        from .tools import commands
    except ImportError:
        # An installed extension archive has no tools/: `render` still works.
        return parser
    commands.add_parsers(sub, formatter_class=_Help)
    return parser


class ProgressBar:
    """A one-line progress bar on stderr (redrawn in place on a terminal, every 10 % otherwise)."""

    def __init__(self, stream=None, quiet=False):
        # sys.stderr when the bar is made, not when this module was imported (a test's
        # captured stream, closed since, would be kept otherwise).
        self.stream = sys.stderr if stream is None else stream
        self.quiet = quiet
        self.tty = self.stream.isatty()
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


def _is_blend(name):
    """Whether the scene argument names a file (else a built-in scene)."""
    return name.lower().endswith(".blend") or os.path.sep in name


def load_scene(args):
    """Scene and the settings it carries, from a built-in name or a .blend file."""
    # The registry's default workers (processes), not the core's (threads: see RenderSettings).
    settings = RenderSettings(workers=OPTIONS["workers"].default)
    name = args.scene
    if _is_blend(name):
        if not os.path.isfile(name) or not os.access(name, os.R_OK):
            raise UsageError(f"cannot read scene file {name!r}")
        from .addon.blendfile import is_blend_file, load_blend

        if not is_blend_file(name):
            raise UsageError(f"{name!r} is not a .blend file")
        try:
            scene, file_settings = load_blend(os.path.abspath(name), frame=args.frame,
                                              resolution=args.resolution)
        except (RuntimeError, ValueError) as exc:
            raise UsageError(f"cannot render {name!r}: {str(exc).strip().splitlines()[-1]}")
        settings = file_settings
    else:
        if os.path.splitext(name)[1]:
            raise UsageError(f"{name!r} is not a scene: give a .blend file or one of the "
                             f"built-in scenes {', '.join(builtin_scenes.BUILTIN)}")
        if name not in builtin_scenes.BUILTIN:
            raise UsageError(f"unknown scene {name!r}; built-in scenes: "
                             f"{', '.join(builtin_scenes.BUILTIN)} (or give a .blend path)")
        w, h = args.resolution or (256, 256)
        scene = builtin_scenes.BUILTIN[name](w, h)
    return scene, settings


def _dest(option):
    return option.flag_name[2:].replace("-", "_")


def apply_flags(settings, args):
    """Set every registry option given on the command line; returns their names."""
    given = [name for name, o in OPTIONS.items() if getattr(args, _dest(o), None) is not None]
    for name in given:
        setattr(settings, name, getattr(args, _dest(OPTIONS[name])))
    # --spp and --time exclude each other: the one given halts the render alone.
    if "time_limit" in given:
        settings.spp = 0
    elif "spp" in given:
        settings.time_limit = 0.0
    return given


def _flag_text(name, value):
    option = OPTIONS[name]
    if option.kind is bool:
        return option.flag_name if value else f"--no-{option.flag_name[2:]}"
    return f"{option.flag_name} {value}"


def _notes(settings, given):
    """Tell the user once about each flag the render ignores (:func:`core.applied_settings.unused_options`)
    or replaces with another value."""
    unused = unused_options(settings)
    for name in given:
        if name not in unused:
            continue
        flag = _flag_text(name, getattr(settings, name))
        if name == "strategy_views":
            print(f"note: the {settings.integrator} integrator writes no strategy views "
                  f"(only bdpt does)", file=sys.stderr)
        elif unused[name] == "n/a":
            print(f"note: {flag} does not apply to {settings.integrator}"
                  f"{_because(name, settings)}; it is ignored", file=sys.stderr)
        else:
            print(f"note: {flag} does not apply to {settings.integrator}"
                  f"{_because(name, settings)}: it uses {unused[name]}", file=sys.stderr)


def _because(name, settings):
    """The other setting that makes option ``name`` not apply, as a clause (or '')."""
    if name in ("mis_beta", "mis_alpha", "light_selection", "light_sampling") and \
            settings.integrator in ("path", "bdpt"):
        return f" with --mis {settings.mis_heuristic}"
    if name in ("photon_k", "photon_radius") and settings.integrator == "photon":
        return f" with --photon-lookup {settings.photon_lookup}"
    if name == "radiosity_adaptive" and settings.integrator == "radiosity":
        return f" with --radiosity-solver {settings.radiosity_solver}"
    if name in ("light_selection", "light_sampling") and settings.integrator == "radiosity":
        return f" with --radiosity-display {settings.radiosity_display}"
    if name in ("rr_min_bounces", "rr_survival") and not settings.use_russian_roulette:
        return " with --no-russian-roulette"
    if name == "strategy_max_length" and settings.integrator == "bdpt":
        return " without --strategy-views"
    return ""


def check_output(path):
    """Refuse, before any rendering, an output path the EXR could not be written to: not an
    ``.exr`` name, an existing folder, a folder part that is a file, or a folder that exists
    but cannot be written (``UsageError`` naming the cause)."""
    if not path.lower().endswith(".exr"):
        raise UsageError(f"output must be an .exr file, not {path!r}")
    if os.path.isdir(path):
        raise UsageError(f"cannot write {path!r}: it is a folder")
    folder = os.path.dirname(os.path.abspath(path))
    while not os.path.exists(folder):
        folder = os.path.dirname(folder)
    if not os.path.isdir(folder):
        raise UsageError(f"cannot write {path!r}: {folder!r} is a file, not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UsageError(f"cannot write {path!r}: the folder {folder!r} is not writable")


def check_halt(settings):
    """A render must stop by itself: refuse ``--spp 0`` without a time limit, naming both."""
    if settings.spp == 0 and settings.time_limit == float("inf"):
        raise UsageError("--time inf never stops: give a finite time limit in seconds, or a "
                         "sample count with --spp N")
    if settings.spp == 0 and not settings.time_limit > 0:
        raise UsageError("--spp 0 renders no samples: give --spp N with N >= 1, or a time "
                         "limit with --time SECONDS")


def write_output(path, layers, metadata=None):
    """Write the EXR (with ``metadata`` in its header); if that fails after all (disk full,
    folder removed meanwhile), write it to the temporary folder instead so that the render is
    not lost. Returns the path written."""
    from .core.exr import write_multilayer

    try:
        write_multilayer(path, layers, metadata=metadata)
        return path
    except OSError as exc:
        fallback = os.path.join(tempfile.gettempdir(), f"sampling_lab-{os.path.basename(path)}")
        write_multilayer(fallback, layers, metadata=metadata)
        print(f"{PROG}: could not write {path!r} ({exc.strerror or exc}); the image is in "
              f"{fallback!r}", file=sys.stderr)
        return fallback


def cmd_render(args):
    check_output(args.output)
    scene, settings = load_scene(args)
    given = apply_flags(settings, args)
    check_halt(settings)
    _notes(settings, given)
    if args.frame is not None and not _is_blend(args.scene):
        print(f"note: --frame {args.frame} does not apply to the built-in scene "
              f"{args.scene!r} (it has no animation); it applies to .blend files", file=sys.stderr)
    for message in scene.messages:
        print(f"note: {message}", file=sys.stderr)

    from .core.exr import render_metadata, write_png_preview

    bar = ProgressBar(quiet=args.quiet)
    interrupted = []
    # Ctrl-C cancels like Esc in Blender: the samples taken so far are still written.
    previous = signal.signal(signal.SIGINT, lambda *_: interrupted.append(True))
    try:
        result = render(scene, settings, progress=bar, cancel=lambda: bool(interrupted))
    except RenderRefused as exc:
        raise UsageError(str(exc)) from None
    finally:
        signal.signal(signal.SIGINT, previous)
        bar.close()
    for message in result.messages:
        if message not in scene.messages:  # those were printed before rendering
            print(f"note: {message}", file=sys.stderr)
    if interrupted and not result.error and not result.sample_count().any():
        # Ctrl-C before the first sample (while preparing the scene): nothing to keep, and an
        # existing file at the output path is left alone.
        print(f"{PROG}: cancelled before any sample was taken; nothing written",
              file=sys.stderr)
        if args.json:
            print(json.dumps({**result.stats, "output": None, "layers": [],
                              "cancelled": True}))
        return 130
    if result.error:
        print(f"{PROG}: error: the render failed ({result.error}); writing the samples taken",
              file=sys.stderr)
    elif result.cancelled:
        print(f"{PROG}: cancelled; writing the samples taken", file=sys.stderr)
    # BDPT's strategy views (empty unless asked for) go into the same file as extra layers.
    layers = {
        "Combined": result.combined(),
        "Variance": result.variance(),
        "Sample Count": result.sample_count()[..., None],
        **result.layers(),
    }
    output = write_output(args.output, layers, render_metadata(result))
    if args.png:
        write_png_preview(os.path.splitext(output)[0] + ".png", result.combined()[..., :3])
    stats = dict(result.stats)
    stats.update(output=os.path.abspath(output), integrator=settings.integrator,
                 sampler=settings.sampler, width=scene.camera.width, height=scene.camera.height,
                 strategy_views=settings.strategy_views,
                 strategy_max_length=settings.strategy_max_length,
                 layers=list(layers), cancelled=result.cancelled)
    if args.json:
        print(json.dumps(stats))
    elif not args.quiet:
        png = f" and {os.path.splitext(output)[0]}.png" if args.png else ""
        print(f"wrote {output}{png}: {stats['spp']} spp in {stats['time_s']:.2f} s, "
              f"{stats['samples_per_s'] / 1e6:.3f} M samples/s, "
              f"{stats['rays_per_s'] / 1e6:.2f} M rays/s", file=sys.stderr)
    # Ctrl-C: the samples are written, and the exit code says the render was interrupted.
    # A failed render's samples are written too, and the exit code says it failed.
    if interrupted:
        return 130
    return 0 if output == args.output and not result.error else 1


def main(argv=None):
    """Run the command line ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = build_parser().parse_args(_joined_resolution(argv))
        args.argv = argv
        if args.command == "render":
            return cmd_render(args)
        try:
            return args.run(args)
        except ValueError as exc:
            raise UsageError(str(exc)) from None
    except UsageError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    except MemoryError:
        print(f"{PROG}: error: out of memory: lower the resolution or the photon count",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
