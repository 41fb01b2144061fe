"""Does the Connection Roulette pay? BDPT with each of several factors against none, at equal
work (a measurement, not a test).

The setting (:mod:`core.integrators.connection_roulette`): before its shadow ray, a
connection with unweighted contribution ``c`` survives with probability
``q = min(1, c / (theta * mean c))`` and is divided by ``q`` if it does (unbiased; fewer
shadow rays, more variance). For each ``theta`` (and 0, off), units of the scene are rendered
in turn (alternated rounds, one
thread, independent sampler, power selection, 8 bounces, malloc as a render sets it), and the
tool prints thread CPU per camera sample, the mean over pixels of the per-pixel variance of the
camera samples' values (the part of the image the connections add to; the splats are not in
it) and the efficiency gain ``(var_0 * cpu_0) / (var * cpu)`` (above 1: roulette wins at equal
time)::

    PYTHONPATH=/path/to/parent:/path/to/parent/sampling_lab/tools \\
        python tools/roulette_probe.py --scene bench --size 64 --units 2 --rounds 6
    ... --scene mirror_ball --size 64        # a bench-scenes scene (needs bpy)
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from ab_units import _scene
from stage_timer import uniform_bounces


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="bench")
    parser.add_argument("--size", type=int, default=64, help="square image side")
    parser.add_argument("--units", type=int, default=2, help="units per setting and round")
    parser.add_argument("--rounds", type=int, default=6)
    parser.add_argument("--thetas", default="0.1,0.2,0.3,0.5")
    args = parser.parse_args(argv)
    from sampling_lab.core import film, integrators, prepare, render
    from sampling_lab.core.allocator import keep_freed_batches
    from sampling_lab.core.integrators import base
    from sampling_lab.core.sampling.samplers import make_sampler

    keep_freed_batches()
    scene = _scene("sampling_lab", args)
    prep = prepare.prepare(scene, "power")
    thetas = [0.0] + [float(t) for t in args.thetas.split(",")]
    integ = {}
    for theta in thetas:
        settings = render.RenderSettings(integrator="bdpt", spp=4, threads=1, seed=0,
                                         sampler="independent", light_selection="power",
                                         connection_roulette=theta,
                                         **uniform_bounces(render.RenderSettings, 8))
        integ[theta] = integrators.integrator_class("bdpt")(prep, settings)
    sampler = make_sampler("independent", seed=0, spp=4, width=args.size)
    pixel_filter = film.PixelFilter(settings.filter_type, settings.filter_width)
    n, pixels_n = integ[0.0].unit_paths, args.size * args.size
    rays = {t: 0 for t in thetas}
    sums = {t: [np.zeros(pixels_n), np.zeros(pixels_n), np.zeros(pixels_n), 0.0, 0]
            for t in thetas}
    print(f"load average at start: {os.getloadavg()}")
    for r in range(args.rounds):
        for theta in thetas:
            for u in range(args.units):
                unit = r * args.units + u
                pixels = (np.arange(n) + unit * n) % pixels_n
                stream = sampler.stream(pixels, np.full(n, unit * n // pixels_n))
                t0 = time.thread_time()
                counters = base.Counters()
                out = integ[theta].render_samples(stream, pixel_filter, counters)
                rays[theta] += counters.rays
                acc = sums[theta]
                acc[3] += time.thread_time() - t0
                acc[4] += n
                y = out.radiance.mean(axis=1)
                for k, v in enumerate((y, y * y, np.ones(n))):
                    np.add.at(acc[k], pixels, v)
    print(f"load average at end: {os.getloadavg()}")
    ref = None
    for theta in thetas:
        s, s2, count, cpu, paths = sums[theta]
        mean = s / count
        var = float(((s2 - count * mean ** 2) / (count - 1)).mean())
        us = 1e6 * cpu / paths
        ref = ref or (var, us)
        print(f"theta {theta}: {us:.3f} us CPU per camera sample, mean pixel variance "
              f"{var:.4e}, image mean {mean.mean():.5f} | variance x {var / ref[0]:.4f}, "
              f"CPU x {us / ref[1]:.4f}, rays x {rays[theta] / rays[0.0]:.4f}, "
              f"efficiency gain {ref[0] * ref[1] / (var * us):.4f}")


if __name__ == "__main__":
    main()
