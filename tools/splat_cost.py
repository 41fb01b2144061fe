"""CPU time of the light-vertex splats' own steps in two trees, in ONE process, alternated (a
measurement, not a test).

Beside :mod:`tools.ab_units` (whose ``light`` and ``bdpt`` measures time ``render_samples``,
the ``t = 1`` bookkeeping included), this times what a unit does with its splats afterwards
on the worker (``Film.unit_splats``, or ``Film.splat_taps`` then ``Film.compact_splat_taps``
in older trees: the filter taps and their per-pixel sums) and the camera projection of the
light vertices (``camera.project``).
Both trees get the same inputs: the splats of one light-tracing unit of the head tree, and
points standing in for its light vertices, on the camera ray through each splat's film
position at a random distance of 1 to 5 units (the distance changes no step's work). Thread CPU microseconds per camera sample (one
light path is one camera sample), minimum and median over the rounds, and head / base::

    PYTHONPATH=/path/to/parent:<head>/tools python tools/splat_cost.py \\
        --base /tmp/base/sampling_lab --rounds 15 --keep-freed [--scene mirror_ball --size 96]
"""

from __future__ import annotations

import argparse
import importlib
import os
import time

import numpy as np

from ab_units import BASE, HEAD, _import_base, _scene, print_ratio, tree_order


def _splats(scene, size):
    """The splats ``(film_xy (k, 2), value (k, 3))`` of one light-tracing unit of the head tree,
    points ``(k, 3)`` that project onto them (see the module docstring), and the unit's paths."""
    from sampling_lab.core.camera import generate_rays
    from sampling_lab.core.film import PixelFilter
    from sampling_lab.core.integrators import integrator_class
    from sampling_lab.core.integrators.base import Counters
    from sampling_lab.core.prepare import prepare
    from sampling_lab.core.render import RenderSettings
    from sampling_lab.core.sampling.samplers import make_sampler

    settings = RenderSettings(integrator="light", spp=4, threads=1, seed=0,
                              sampler="independent", light_selection="power")
    integ = integrator_class("light")(prepare(scene, "power"), settings)
    n = integ.unit_paths
    stream = make_sampler("independent", seed=0, spp=4, width=size).stream(
        np.arange(n) % (size * size), np.zeros(n, np.int64))
    out = integ.render_samples(stream, PixelFilter(settings.filter_type, settings.filter_width),
                               Counters())
    xy, value = np.asarray(out.splats.xy), np.asarray(out.splats.value)
    origin, direction, _ = generate_rays(scene.camera, xy)
    depth = np.random.default_rng(0).uniform(1.0, 5.0, len(xy))
    return xy, value, origin + direction * depth[:, None], n


def _steps(pkg, scene, xy, value, points):
    """``{name: run()}`` of the steps measured in package ``pkg``."""
    film_mod = importlib.import_module(f"{pkg}.core.film")
    camera = importlib.import_module(f"{pkg}.core.camera")
    cam = scene.camera
    film = film_mod.Film(cam.width, cam.height)
    pixel_filter = film_mod.PixelFilter()
    if hasattr(film, "unit_splats"):
        taps = lambda: film.unit_splats(xy, value, pixel_filter)  # noqa: E731
    else:  # trees before the thirteenth round
        taps = lambda: film.compact_splat_taps(*film.splat_taps(xy, value, pixel_filter))  # noqa: E731
    return {"taps": taps,
            "project": lambda: camera.project(cam, points, 1.5)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", required=True, help="the base tree's package folder")
    parser.add_argument("--scene", default="bench")
    parser.add_argument("--size", type=int, default=256, help="square image side")
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--keep-freed", action="store_true",
                        help="glibc keeps freed batch memory (core.allocator), as in workers")
    args = parser.parse_args(argv)
    if args.keep_freed:
        from sampling_lab.core.allocator import keep_freed_batches

        print(f"allocator: {keep_freed_batches()}")
    _import_base(args.base)
    scene = _scene(HEAD, args)
    xy, value, points, n = _splats(scene, args.size)
    print(f"{len(xy)} splats of {n} light paths")
    steps = {pkg: _steps(pkg, scene, xy, value, points) for pkg in (BASE, HEAD)}
    for pkg in steps:
        for run in steps[pkg].values():
            run()  # warm-up
    print(f"load average at start: {os.getloadavg()}")
    times = {(pkg, name): [] for pkg in steps for name in steps[pkg]}
    for round_ in range(args.rounds):
        for name in steps[HEAD]:
            for pkg in tree_order(round_):
                t0 = time.thread_time()
                steps[pkg][name]()
                times[pkg, name].append(1e6 * (time.thread_time() - t0) / n)
    for name in steps[HEAD]:
        print_ratio(name, times[BASE, name], times[HEAD, name], digits=4)
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
