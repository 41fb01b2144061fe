"""Error per sample against Cycles, factor by factor: where Cycles' fewer samples come from.

``python -m sampling_lab bench-gap`` calls :func:`run`. For every scene of
:data:`.hard_scenes.SCENES` (built in ``bpy`` and exported as ``bench-scenes`` does), in one
process:

1. *Reference*: Cycles at ``reference_spp`` with two seeds, averaged. Two independent renders
   of equal sample count differ by twice the variance of each, so the average's own error,
   in relMSE units, is a quarter of the relMSE between them (its *noise*); it is subtracted
   from every error below.
2. *Our path tracer* renders ``spp`` samples per pixel in each configuration of :data:`OURS`:
   the baseline (independent sampler, area sampling of area lights, power light selection)
   and the baseline with one factor changed to what Cycles does, then our defaults, then all
   of Cycles' choices together.
3. *Cycles* renders the same ``spp`` in each configuration of :data:`CYCLES`: its defaults as
   ``bench-scenes`` sets them (tabulated Sobol, light tree) and with one factor changed.
4. *Errors*: every configuration renders ``seeds`` times with different seeds; its relMSE
   (``core.metrics.rel_mse``) against the reference, minus the reference's noise, is averaged
   over the seeds, with the standard error of that mean.

At equal sample count the ratio of two errors is the ratio of their *error per sample*,
independent of speed and of the machine's load; ``bench-scenes`` measures the speed. A ratio
below 1 means fewer samples for the same error. CPU seconds of each render (both threads,
``time.process_time``) are recorded for context. Output: ``gap.csv`` and ``GAP_BENCH.md`` in
``output`` (default ``out/bench-gap``); ``docs/GAP.md`` quotes a run by hand. Figures, never
asserted.
"""

from __future__ import annotations

import math
import os
import time

import numpy as np

from ..core.metrics import rel_mse
from ..core.options import DEFAULTS
from ..core.render import RenderSettings, render
from .common import EPS, loadavg, machine_summary, stage, write_csv
from .cycles_runner import CyclesRunner
from .hard_scenes import SCENES, build_scene
from ..core.integrators.bounces import uniform_limits

REPORT = "GAP_BENCH.md"
# Our baseline, spelled out so that the table keeps its meaning when the defaults change.
BASELINE = dict(sampler="independent", light_sampling="area", light_selection="power",
                use_russian_roulette=True)
# Our configurations: name -> changes to BASELINE (each a factor in which Cycles differs).
OURS = {
    "baseline": {},
    "sampler=sobol": dict(sampler="sobol"),
    "light_sampling=solid_angle": dict(light_sampling="solid_angle"),
    "light_selection=tree": dict(light_selection="tree"),
    "russian_roulette=off": dict(use_russian_roulette=False),
    "defaults": {k: DEFAULTS[k] for k in ("sampler", "light_sampling", "light_selection")},
    "sobol+solid_angle+tree": dict(sampler="sobol", light_sampling="solid_angle",
                                   light_selection="tree"),
}
# Cycles' configurations: name -> scene.cycles attributes changed from bench-scenes' set-up.
CYCLES = {
    "default": {},
    "pattern=blue_noise": dict(sampling_pattern="BLUE_NOISE"),
    "light_tree=off": dict(use_light_tree=False),
}
CYCLES_DEFAULTS = dict(sampling_pattern="TABULATED_SOBOL", use_light_tree=True)


def run(scenes=tuple(SCENES), size=(96, 96), spp=64, seeds=4, reference_spp=4096,
        threads=2, max_bounces=8, output="out/bench-gap", progress=print):
    """Measure, print and write ``output/gap.csv`` and ``output/GAP_BENCH.md``.

    Parameters
    ----------
    scenes : sequence of str
        Keys of :data:`.hard_scenes.SCENES`.
    size : (int, int)
    spp : int
        Samples per pixel of every compared render.
    seeds : int
        Renders per configuration (seeds 1 .. seeds; the references use 1001 and 1002).
    reference_spp : int
        Samples per pixel of each of the two Cycles references.
    threads, max_bounces : int
    output : str or None

    Returns
    -------
    list of dict
        One row per scene and configuration.
    """
    summary = machine_summary()
    t0 = time.perf_counter()
    rows = []
    for name in scenes:
        rows += _scene_rows(name, size, spp, seeds, reference_spp, threads, max_bounces,
                            progress)
    summary.update(load_end=loadavg(), bench_seconds=time.perf_counter() - t0)
    if output:
        os.makedirs(output, exist_ok=True)
        write_csv(os.path.join(output, "gap.csv"), rows)
        with open(os.path.join(output, REPORT), "w") as f:
            f.write(report(rows, summary, size, spp, seeds, reference_spp))
        progress(f"wrote {output}/gap.csv and {output}/{REPORT}")
    return rows


def _scene_rows(name, size, spp, seeds, reference_spp, threads, max_bounces, progress):
    bl_scene, core_scene = build_scene(name, size)
    cy = CyclesRunner(core_scene, threads, max_bounces, blender_scene=bl_scene)
    stage(f"{name}: Cycles references, 2 x {reference_spp} spp")
    ref_a = _cycles_image(cy, {}, reference_spp, 1001)[0]
    ref_b = _cycles_image(cy, {}, reference_spp, 1002)[0]
    ref = 0.5 * (ref_a + ref_b)
    noise = rel_mse(ref_a, ref_b, EPS) / 4.0
    pixels = size[0] * size[1]
    rows = []
    for label, changes in OURS.items():
        stage(f"{name}: ours {label}, {seeds} x {spp} spp")
        settings = {**BASELINE, **changes}
        runs = [_ours_image(core_scene, settings, spp, seed, threads, max_bounces)
                for seed in range(1, seeds + 1)]
        rows.append(_row(name, "ours", label, runs, ref, noise, spp, pixels))
    for label, changes in CYCLES.items():
        stage(f"{name}: Cycles {label}, {seeds} x {spp} spp")
        runs = [_cycles_image(cy, changes, spp, seed) for seed in range(1, seeds + 1)]
        rows.append(_row(name, "Cycles", label, runs, ref, noise, spp, pixels))
    base = next(r["relmse"] for r in rows if r["renderer"] == "Cycles" and r["config"] == "default")
    for r in rows:
        r["vs_cycles"] = r["relmse"] / base if base > 0 else math.nan
        r["reference_noise"] = noise
        progress(f"{name:14s} {r['renderer']:6s} {r['config']:28s} relMSE {r['relmse']:.3e} "
                 f"+- {r['relmse_se']:.1e}  vs Cycles {r['vs_cycles']:.2f}x")
    return rows


def _ours_image(scene, settings, spp, seed, threads, max_bounces):
    c0 = time.process_time()
    res = render(scene, RenderSettings(spp=spp, seed=seed, threads=threads,
                                       **uniform_limits(max_bounces), **settings))
    return res.combined()[..., :3].astype(np.float64), time.process_time() - c0


def _cycles_image(cy, changes, spp, seed):
    for key, value in {**CYCLES_DEFAULTS, **changes}.items():
        setattr(cy.scene.cycles, key, value)
    c0 = time.process_time()
    _, img = cy.render(spp, seed)
    return img[..., :3].astype(np.float64), time.process_time() - c0


def _row(scene, renderer, config, runs, ref, noise, spp, pixels):
    errors = np.array([rel_mse(img, ref, EPS) - noise for img, _ in runs])
    cpu = float(np.mean([c for _, c in runs]))
    se = float(errors.std(ddof=1) / math.sqrt(len(errors))) if len(errors) > 1 else math.nan
    return {"scene": scene, "renderer": renderer, "config": config, "spp": spp,
            "relmse": float(errors.mean()), "relmse_se": se, "cpu_s": cpu,
            "cpu_us_per_sample": 1e6 * cpu / (spp * pixels)}


def report(rows, summary, size, spp, seeds, reference_spp):
    """The markdown table of a run: one section per scene."""
    lines = [
        "# Error per sample against Cycles, factor by factor",
        "",
        f"`python -m sampling_lab bench-gap` ({summary['date']}, {summary['bench_seconds']:.0f} "
        f"s; {summary['cpu']}, {summary['cpus']} CPUs, load {summary['load_start']} at start, "
        f"{summary['load_end']} at end). {size[0]}x{size[1]}, {spp} spp, {seeds} seeds per "
        f"configuration; reference: two Cycles renders of {reference_spp} spp, averaged.",
        "",
        "relMSE: mean over seeds of `rel_mse(x, ref)` minus the reference's noise, ± its "
        "standard error. *vs Cycles*: over Cycles' default at the same spp (above 1: we need "
        "more samples). CPU µs per sample: both threads, the whole render call.",
    ]
    for scene in dict.fromkeys(r["scene"] for r in rows):
        lines += ["", f"## {scene}", "",
                  "| renderer | configuration | relMSE | ± | vs Cycles | CPU µs / sample |",
                  "|---|---|---:|---:|---:|---:|"]
        lines += [f"| {r['renderer']} | {r['config']} | {r['relmse']:.3e} | {r['relmse_se']:.1e} "
                  f"| {r['vs_cycles']:.2f} | {r['cpu_us_per_sample']:.2f} |"
                  for r in rows if r["scene"] == scene]
    return "\n".join(lines) + "\n"
