"""Would Russian roulette of BDPT's connections pay? A prototype measured against no roulette
(a measurement, not a feature: the renderer has no such option).

Before its shadow ray, connection ``i`` with unweighted contribution ``c_i`` (the largest
channel of its value) survives with probability ``q_i = min(1, c_i / (theta * mean c))`` (the
mean over the candidates of its piece) and is divided by ``q_i`` if it does: unbiased, since
the decision's random number is independent of the values. Fewer shadow rays, more variance.
For each ``theta`` (and none), units of the scene are rendered in turn (alternated rounds, one
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


def _roulette(conn, state):
    """``conn._unblocked`` with the roulette of ``state["theta"]`` (None: the original)."""
    original, common = conn._unblocked, conn

    def unblocked(ctx, C, at_z, z, z_ng, w, dist, y_normal, value, ok, budget, ends=None):
        theta = state["theta"]
        if theta is not None:
            c = common.max_component(value)
            ok = ok & (c > 0) & common.finite_rows(value)
            cand = np.nonzero(ok)[0]
            if cand.size:
                q = np.minimum(1.0, c[cand] / (theta * c[cand].mean()))
                live = state["rng"].random(cand.size) < q
                state["candidates"] += cand.size
                state["survivors"] += int(live.sum())
                ok[cand[~live]] = False
                value[cand[live]] /= q[live][:, None]
        return original(ctx, C, at_z, z, z_ng, w, dist, y_normal, value, ok, budget, ends)

    return unblocked


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
    from sampling_lab.core.integrators import base, connections
    from sampling_lab.core.sampling.samplers import make_sampler

    keep_freed_batches()
    state = {"theta": None, "rng": np.random.default_rng(1), "candidates": 0, "survivors": 0}
    connections._unblocked = _roulette(connections, state)
    scene = _scene("sampling_lab", args)
    settings = render.RenderSettings(integrator="bdpt", spp=4, threads=1, seed=0,
                                     sampler="independent", light_selection="power",
                                     **uniform_bounces(render.RenderSettings, 8))
    integ = integrators.integrator_class("bdpt")(prepare.prepare(scene, "power"), settings)
    sampler = make_sampler("independent", seed=0, spp=4, width=args.size)
    pixel_filter = film.PixelFilter(settings.filter_type, settings.filter_width)
    n, pixels_n = integ.unit_paths, args.size * args.size
    thetas = [None] + [float(t) for t in args.thetas.split(",")]
    sums = {t: [np.zeros(pixels_n), np.zeros(pixels_n), np.zeros(pixels_n), 0.0, 0]
            for t in thetas}
    print(f"load average at start: {os.getloadavg()}")
    for r in range(args.rounds):
        for theta in thetas:
            state["theta"] = theta
            for u in range(args.units):
                unit = r * args.units + u
                pixels = (np.arange(n) + unit * n) % pixels_n
                stream = sampler.stream(pixels, np.full(n, unit * n // pixels_n))
                t0 = time.thread_time()
                out = integ.render_samples(stream, pixel_filter, base.Counters())
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
              f"CPU x {us / ref[1]:.4f}, efficiency gain {ref[0] * ref[1] / (var * us):.4f}")
    print(f"survivors: {state['survivors'] / max(state['candidates'], 1):.3f} of the "
          f"connections that had a contribution (all thetas together)")


if __name__ == "__main__":
    main()
