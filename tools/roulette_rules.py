"""Russian roulette's survival rule and start at equal time: error per sample and time per
sample of each (a measurement, not a test).

Renders a scene with each ``survival:min_bounces`` variant (``rr_survival`` and
``rr_min_bounces``; ``off``: no roulette) ``--seeds`` times at ``--spp`` on one thread, and
prints the mean relMSE against our own reference (two renders of ``--ref-spp`` with other
seeds, averaged; its noise, a quarter of their relMSE, is subtracted), the median wall time and
their product, the error at equal time (lower is better; compare within one run)::

    PYTHONPATH=/path/to/parent:/path/to/parent/sampling_lab/tools \\
        python tools/roulette_rules.py --scene cornell --size 96 --spp 256 \\
        --variants throughput:3,square_root:2,square_root:3,off
    ... --scene bench --size 128 --spp 64 --ref-spp 2048 --integrator bdpt
    ... --cycles 0,3,8     # also Cycles (one thread) with each Min Light Bounces

Cycles' roulette is the square-root rule from the first bounce; ``min_light_bounces`` delays
it (``--cycles``, a ``bench-scenes`` scene only).
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time

import numpy as np

from profile_path import load_scene


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="cornell")
    parser.add_argument("--size", type=int, default=96, help="square image side")
    parser.add_argument("--spp", type=int, default=256)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--ref-spp", type=int, default=4096)
    parser.add_argument("--integrator", default="path")
    parser.add_argument("--variants", default="throughput:3,square_root:3,off")
    parser.add_argument("--cycles", default="",
                        help="comma-separated Min Light Bounces to render Cycles with")
    args = parser.parse_args(argv)
    from sampling_lab.core.integrators.bounces import uniform_limits
    from sampling_lab.core.metrics import rel_mse
    from sampling_lab.core.render import RenderSettings, render
    from sampling_lab.tools.common import EPS

    scene = load_scene(args.scene, args.size, args.size)
    cycles = _cycles(args) if args.cycles else None

    def image(spp, seed, threads=1, **kw):
        start = time.perf_counter()
        result = render(scene, RenderSettings(spp=spp, seed=seed, threads=threads,
                                              **uniform_limits(8), **kw))
        return result.combined()[..., :3].astype(np.float64), time.perf_counter() - start

    ref_a = image(args.ref_spp, 9001, threads=2)[0]
    ref_b = image(args.ref_spp, 9002, threads=2)[0]
    ref, noise = 0.5 * (ref_a + ref_b), rel_mse(ref_a, ref_b, EPS) / 4
    print(f"{args.scene} {args.size}^2, {args.integrator}, {args.spp} spp x {args.seeds} seeds; "
          f"reference noise {noise:.2e}")
    def report(variant, runs):
        errors = np.array([rel_mse(img, ref, EPS) - noise for img, _ in runs])
        seconds = float(np.median([t for _, t in runs]))
        se = errors.std(ddof=1) / math.sqrt(len(errors)) if len(errors) > 1 else math.nan
        print(f"{variant:15s} relMSE {errors.mean():.3e} +- {se:.1e}  {seconds:.2f} s  "
              f"error x time {errors.mean() * seconds:.3e}", flush=True)

    for variant in args.variants.split(","):
        if variant == "off":
            kw = dict(use_russian_roulette=False)
        else:
            survival, min_bounces = variant.split(":")
            kw = dict(rr_survival=survival, rr_min_bounces=int(min_bounces))
        report(variant, [image(args.spp, 100 + s, integrator=args.integrator, **kw)
                         for s in range(args.seeds)])
    for min_bounces in args.cycles.split(",") if cycles else ():
        report(f"Cycles mlb={min_bounces}",
               [cycles(args.spp, 100 + s, int(min_bounces)) for s in range(args.seeds)])


def _cycles(args):
    """``render(spp, seed, min_light_bounces) -> (image, seconds)`` of Cycles on one thread."""
    from sampling_lab.tools import blender_scene as bs
    from sampling_lab.tools.hard_scenes import build_scene

    bl_scene = build_scene(args.scene, (args.size, args.size))[0]
    bl_scene.render.engine = "CYCLES"
    path = os.path.join(tempfile.mkdtemp(prefix="roulette_rules_"), "cycles.exr")

    def render(spp, seed, min_light_bounces):
        bs.configure_cycles(bl_scene, spp, seed=seed, threads=1, max_bounces=8)
        bl_scene.cycles.min_light_bounces = min_light_bounces
        start = time.perf_counter()
        passes = bs.render_cycles(bl_scene, path)[1]
        return passes["Combined"][..., :3].astype(np.float64), time.perf_counter() - start
    return render


if __name__ == "__main__":
    main()
