"""CPU time per camera sample of two trees in ONE process, alternated unit by unit (a
measurement, not a test).

On a loaded machine two trees timed in turn, process after process, see different loads;
here the base tree is imported a second time under another package name
(``sampling_lab_base``: the package uses relative imports, so any name works) and each round
times one work unit of each tree in turn, on the same thread, so that a load spike hits both
alike. For each measure it prints the minimum and the median over the rounds of thread CPU
microseconds per camera sample, and head / base.

Units here run on the main thread, whose glibc arena page-faults the memory of large batch
arrays in again batch after batch (0.2-0.3 faults per camera sample on the bench box) where a
render's worker threads hardly do; ``--keep-freed`` (:mod:`core.allocator`, both trees) takes
that cost out of both figures.

Measures (``--measures``): ``bdpt_walks`` (BDPT's camera and light subpath walks alone, as
:mod:`tools.profile_walks`), ``bdpt``, ``light`` and ``path`` (the integrator's
``render_samples`` of one work unit; BDPT two units per round). Independent sampler (or
``--sampler``), power light selection, 8 bounces, each integrator's own unit size. The head
is the tree that ``sampling_lab`` resolves to::

    PYTHONPATH=/path/to/parent python tools/ab_units.py --base /tmp/base/sampling_lab \\
        --rounds 5 --scene bench
    ... --scene mirror_ball --size 96      # a bench-scenes scene (needs bpy)
    ... --scene rough_mirror --size 96     # the Cornell box around a rough (0.3) ball:
                                           # rough_mirror, rough_glass, rough_coat,
                                           # rough_mirror_smooth (smooth shading)
"""

from __future__ import annotations

import argparse
import importlib
import os
import statistics
import sys
import tempfile
import time

import numpy as np

from stage_timer import uniform_bounces as _bounces

BASE = "sampling_lab_base"
HEAD = "sampling_lab"



def tree_order(round_):
    """The two trees in the order round ``round_`` times them: each goes first in every other
    round (the second finds warm caches: it read about 2.5 % cheaper on identical trees,
    docs/BENCHMARKS.md, eighth round)."""
    return (BASE, HEAD) if round_ % 2 == 0 else (HEAD, BASE)


def print_ratio(name, b, h, digits=3):
    """One line: minimum and median of the base's and head's microseconds per camera sample
    ``b``, ``h`` (lists over rounds), and head / base."""
    mb, mh = statistics.median(b), statistics.median(h)
    print(f"{name:>10}: base min {min(b):.{digits}f} median {mb:.{digits}f} | head min "
          f"{min(h):.{digits}f} median {mh:.{digits}f} us per camera sample | head / base: "
          f"min {min(h) / min(b):.3f}, median {mh / mb:.3f}")

def _import_base(path):
    """Make the base tree's package importable as :data:`BASE` (a symbolic link)."""
    folder = tempfile.mkdtemp(prefix="ab_units_")
    os.symlink(os.path.abspath(path), os.path.join(folder, BASE))
    sys.path.insert(0, folder)


def keep_freed_both():
    """:func:`core.allocator.keep_freed_batches` in the head AND the base (call it after
    :func:`_import_base`): glibc's setting is per process, but each tree reads its own
    module's flag (``keeps_freed()``, e.g. the connections' piece size): tuning the head's
    alone ran the base's connections in small pieces, a head / base of about 0.94 for two
    identical trees. A base without the module is left alone. Returns the head's text."""
    texts = {}
    for pkg in (HEAD, BASE):
        try:
            allocator = importlib.import_module(f"{pkg}.core.allocator")
        except ImportError:  # a base from before core.allocator
            continue
        texts[pkg] = allocator.keep_freed_batches()
    return texts[HEAD]


def _scene(pkg, args):
    scenes = importlib.import_module(f"{pkg}.core.scenes")
    if args.scene == "bench":
        return scenes.cornell_box(args.size, args.size, light="mesh")
    if args.scene.startswith("rough_"):  # rough_mirror, rough_glass_smooth, ...
        ball, _, smooth = args.scene[len("rough_"):].partition("_")
        return scenes.cornell_sphere(args.size, args.size, ball=ball, light="area",
                                     roughness=0.3, smooth=smooth == "smooth")
    from profile_path import load_scene  # built by the head's exporter, read by both trees

    return load_scene(args.scene, args.size, args.size)


def _runner(pkg, measure, scene, size, sampler_name="independent"):
    """``(run(units), paths per unit)`` of ``measure`` in package ``pkg``."""
    core = lambda name: importlib.import_module(f"{pkg}.core.{name}")  # noqa: E731
    name = "bdpt" if measure == "bdpt_walks" else measure
    settings_class = core("render").RenderSettings
    settings = settings_class(integrator=name, spp=4, threads=1, seed=0, sampler=sampler_name,
                              light_selection="power", **_bounces(settings_class, 8))
    integ = core("integrators").integrator_class(name)(core("prepare").prepare(scene, "power"),
                                                       settings)
    sampler = core("sampling.samplers").make_sampler(sampler_name, seed=0, spp=4, width=size)
    pixel_filter = core("film").PixelFilter(settings.filter_type, settings.filter_width)
    counters = core("integrators.base").Counters
    n = integ.unit_paths

    def streams(units):
        for u in range(units):
            pixels = (np.arange(n) + u * n) % (size * size)
            yield sampler.stream(pixels, np.full(n, u * n // (size * size)))

    if measure != "bdpt_walks":
        def run(units):
            for stream in streams(units):
                integ.render_samples(stream, pixel_filter, counters())
        return run, n
    bidir, tally = core("integrators.bidir"), core("integrators.strategy_views").Tally
    depth = settings.max_bounces + 2
    base = bidir.DIMS_CAMERA + (depth + 1) * bidir.DIMS_PER_CAMERA_VERTEX

    def walks(units):
        for stream in streams(units):
            ctx = bidir._Context(integ, counters(), pixel_filter)
            bidir._camera_subpath(ctx, pixel_filter, stream, n, depth, tally(n, 0))
            bidir._light_subpath(ctx, stream, n, base, depth)
    return walks, n


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", required=True, help="the base tree's package folder")
    parser.add_argument("--scene", default="bench")
    parser.add_argument("--size", type=int, default=256, help="square image side")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--measures", default="bdpt_walks,bdpt,light,path")
    parser.add_argument("--sampler", default="independent",
                        help="sampler of both trees (sobol: the default of a render)")
    parser.add_argument("--keep-freed", action="store_true",
                        help="glibc keeps freed batch memory (core.allocator, both trees): "
                             "units on this main thread then page-fault no more than a "
                             "render's worker threads")
    args = parser.parse_args(argv)
    _import_base(args.base)
    if args.keep_freed:
        print(f"allocator: {keep_freed_both()}")
    measures = args.measures.split(",")
    runs = {}
    for pkg in (BASE, HEAD):
        scene = _scene(pkg if args.scene == "bench" or args.scene.startswith("rough_")
                       else HEAD, args)
        for measure in measures:
            runs[pkg, measure] = _runner(pkg, measure, scene, args.size, args.sampler)
            runs[pkg, measure][0](1)  # warm-up: buffers, first-call costs
    print(f"load average at start: {os.getloadavg()}")
    times = {key: [] for key in runs}
    for round_ in range(args.rounds):
        for measure in measures:
            units = 2 if measure.startswith("bdpt") else 1
            for pkg in tree_order(round_):
                run, n = runs[pkg, measure]
                t0 = time.thread_time()
                run(units)
                times[pkg, measure].append(1e6 * (time.thread_time() - t0) / (units * n))
    for measure in measures:
        print_ratio(measure, times[BASE, measure], times[HEAD, measure])
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
