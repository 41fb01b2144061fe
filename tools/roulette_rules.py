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
"""

from __future__ import annotations

import argparse
import math
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
    parser.add_argument("--variants", default="throughput:3,square_root:2,off")
    args = parser.parse_args(argv)
    from sampling_lab.core.integrators.bounces import uniform_limits
    from sampling_lab.core.metrics import rel_mse
    from sampling_lab.core.render import RenderSettings, render
    from sampling_lab.tools.common import EPS

    scene = load_scene(args.scene, args.size, args.size)

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
    for variant in args.variants.split(","):
        if variant == "off":
            kw = dict(use_russian_roulette=False)
        else:
            survival, min_bounces = variant.split(":")
            kw = dict(rr_survival=survival, rr_min_bounces=int(min_bounces))
        runs = [image(args.spp, 100 + s, integrator=args.integrator, **kw)
                for s in range(args.seeds)]
        errors = np.array([rel_mse(img, ref, EPS) - noise for img, _ in runs])
        seconds = float(np.median([t for _, t in runs]))
        se = errors.std(ddof=1) / math.sqrt(len(errors)) if len(errors) > 1 else math.nan
        print(f"{variant:15s} relMSE {errors.mean():.3e} +- {se:.1e}  {seconds:.2f} s  "
              f"error x time {errors.mean() * seconds:.3e}", flush=True)


if __name__ == "__main__":
    main()
