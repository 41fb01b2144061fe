"""Radiosity benchmark: solve cost against patch count, and equal-time error against Monte Carlo.

``python -m sampling_lab bench-radiosity`` calls :func:`run`:

1. **Scaling.** The diffuse Cornell box (area lamp) meshed at several patch sizes; for each
   solver the whole solve (meshing, lamp shooting, form factors, iterations) is timed and its
   peak memory taken by ``tracemalloc`` (NumPy's arrays; Embree's BVH is not counted, it does
   not change with the patch count). A least-squares line through log(time) and
   log(patches) gives each solver's fitted exponent. Jacobi and Gauss-Seidel store the dense
   matrix, progressive refinement computes a column per shot, hierarchical radiosity links
   elements of a quadtree.
2. **Equal time.** The same room (lamp hidden from the camera), the same wall-clock budget for
   radiosity (hierarchical solve included, Gouraud and final-gather display), our path tracer
   and Cycles, in one run; relMSE = mean of (x - ref)^2 / (ref^2 + 0.01) against a long path
   trace (another seed; its own noise is in every figure alike). Radiosity's error is mostly
   bias: it does not shrink with time.

Figures only, never asserted; the markdown report ``RADIOSITY_BENCH.md``, two CSVs and
``images/radiosity_displays.png`` (the displays side by side, which ``docs/RADIOSITY.md``
shows) go into ``output``. The machine's load is part of every figure: run it on a quiet machine to compare.
"""

from __future__ import annotations

import os
import time
import tracemalloc

import numpy as np

from ..core.metrics import rel_mse
from ..core.prepare import prepare
from ..core.radiosity.system import RadiosityParams, solve_scene
from ..core.render import RenderSettings, render
from ..core.scenes import cornell_box
from .common import loadavg, machine_summary, stage, write_csv
from ..core.integrators.bounces import uniform_limits

REPORT = "RADIOSITY_BENCH.md"
# Patch sizes per solver (Blender units on the 2 m Cornell box): about 0.5k-2k patches for the
# matrix-free progressive solver, 1k-4k for the dense ones, 1.7k-106k for the hierarchical one.
SIZES = {
    "jacobi": (0.5, 0.35, 0.25),
    "gauss_seidel": (0.5, 0.35, 0.25),
    "progressive": (0.9, 0.7, 0.5),
    "hierarchical": (0.5, 0.25, 0.125, 0.0625),
}
FORM_FACTOR_SAMPLES = 4


def measure_solve(prep, params):
    """One solve: a row of patches, seconds, peak MB, sweeps and links."""
    tracemalloc.start()
    t0 = time.perf_counter()
    sol = solve_scene(prep, params)
    seconds = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return dict(solver=params.solver, patch_size=params.patch_size,
                patches=sol.stats["radiosity_patch_count"], seconds=seconds, peak_mb=peak / 1e6,
                iterations=sol.stats.get("radiosity_iterations", 0),
                links=sol.stats.get("radiosity_links", ""))


def scaling(sizes=SIZES, progress=print):
    """Rows of :func:`measure_solve` for every solver and size, and each solver's exponent."""
    prep = prepare(cornell_box(8, 8, "area"))
    rows, exponents = [], {}
    for solver, patch_sizes in sizes.items():
        for h in patch_sizes:
            stage(f"{solver}, patch size {h}")
            params = RadiosityParams(solver=solver, patch_size=h,
                                     form_factor_samples=FORM_FACTOR_SAMPLES, tolerance=1e-3)
            rows.append(measure_solve(prep, params))
            progress(rows[-1])
        mine = [r for r in rows if r["solver"] == solver]
        if len(mine) >= 2:
            exponents[solver] = float(np.polyfit(np.log([r["patches"] for r in mine]),
                                                 np.log([r["seconds"] for r in mine]), 1)[0])
    return rows, exponents


def room(size):
    """The equal-time scene: the Cornell box under its area lamp, the lamp hidden from view."""
    scene = cornell_box(size[0], size[1], "area")
    scene.lights.visible_camera[:] = False
    return scene


def equal_time(size=(64, 64), seconds=10.0, reference_seconds=120.0, cycles=True,
               patch_size=0.125, gather_patch_size=0.25, max_bounces=8, threads=2,
               progress=print):
    """Rows of every method at ``seconds`` of wall clock against a long path trace."""
    scene = room(size)
    stage(f"reference: path tracing for {reference_seconds:g} s")
    ref = render(scene, RenderSettings(spp=0, time_limit=reference_seconds,
                                       **uniform_limits(max_bounces), seed=999, threads=threads))
    ref_img = ref.film.mean()
    rows = []

    def add(method, img, spp, wall, extra=""):
        rows.append(dict(method=method, spp=spp, seconds=wall, rel_mse=rel_mse(img, ref_img),
                         mean_ratio=float(img.mean() / ref_img.mean()), notes=extra))
        progress(rows[-1])

    for display, h in (("gouraud", patch_size), ("final_gather", gather_patch_size)):
        stage(f"radiosity ({display}, patch size {h}) for {seconds:g} s")
        settings = RenderSettings(integrator="radiosity", radiosity_solver="hierarchical",
                                  radiosity_patch_size=h, radiosity_display=display,
                                  radiosity_samples=FORM_FACTOR_SAMPLES, threads=threads,
                                  spp=0, time_limit=seconds)
        t0 = time.perf_counter()
        solve = solve_scene(prepare(scene), RadiosityParams(
            solver="hierarchical", patch_size=h, form_factor_samples=FORM_FACTOR_SAMPLES))
        solve_s = time.perf_counter() - t0
        # The budget covers the solve: what is left of it renders camera samples.
        settings.time_limit = max(seconds - solve_s, 0.05)
        t0 = time.perf_counter()
        res = render(scene, settings)
        add(f"radiosity, {display.replace('_', ' ')}", res.film.mean(), res.stats["spp"],
            time.perf_counter() - t0,
            f"{solve.stats['radiosity_patch_count']} patches, solve {solve_s:.1f} s")
    stage(f"path tracing for {seconds:g} s")
    t0 = time.perf_counter()
    res = render(scene, RenderSettings(spp=0, time_limit=seconds, **uniform_limits(max_bounces),
                                       seed=1, threads=threads))
    add("path tracing", res.film.mean(), res.stats["spp"], time.perf_counter() - t0)
    if cycles:
        from .cycles_runner import CyclesRunner

        stage(f"Cycles for {seconds:g} s")
        cy = CyclesRunner(scene, threads, max_bounces)
        cy.measure_fixed_cost(1)
        cy.measure_fixed_spp(16, 1)
        spp, wall, img = cy.equal_time(seconds, 1)
        add("Cycles", np.asarray(img, np.float64)[..., :3], spp, wall)
    return rows, ref.stats["spp"]


FIGURE = "images/radiosity_displays.png"


def displays_figure(path, size=128, spp=64, patch_size=0.35):
    """One row of the Cornell box (area lamp) by radiosity: flat, Gouraud, final gather,
    Gouraud after adaptive subdivision (threshold 0.05), and that render's Radiosity Patches
    pass; written as an sRGB PNG (row 0 at the bottom, as every image here)."""
    from ..core.exr import write_png_preview

    scene = cornell_box(size, size, "area")
    images = []
    for display, adaptive in (("flat", 0.0), ("gouraud", 0.0), ("final_gather", 0.0),
                              ("gouraud", 0.05)):
        res = render(scene, RenderSettings(integrator="radiosity", spp=spp,
                                           radiosity_patch_size=patch_size,
                                           radiosity_display=display,
                                           radiosity_adaptive=adaptive,
                                           radiosity_patches=True))
        images.append(res.combined()[..., :3])
    images.append(res.layers()["Radiosity Patches"])
    os.makedirs(os.path.dirname(path), exist_ok=True)
    write_png_preview(path, np.concatenate(images, axis=1))


def run(size=(64, 64), seconds=10.0, reference_seconds=120.0, cycles=True, sizes=SIZES,
        output="out/bench-radiosity", progress=print, figure=True):
    """Both parts; prints the figures and writes ``output/RADIOSITY_BENCH.md``, CSVs and (with
    ``figure``) ``output/images/radiosity_displays.png``."""
    machine = machine_summary()
    scale_rows, exponents = scaling(sizes, progress)
    time_rows, ref_spp = equal_time(size, seconds, reference_seconds, cycles, progress=progress)
    lines = _report(machine, scale_rows, exponents, time_rows, size, seconds, reference_seconds,
                    ref_spp)
    progress("\n".join(lines))
    if output:
        os.makedirs(output, exist_ok=True)
        write_csv(os.path.join(output, "radiosity_scaling.csv"), scale_rows)
        write_csv(os.path.join(output, "radiosity_equal_time.csv"), time_rows)
        path = os.path.join(output, REPORT)
        with open(path + ".tmp", "w") as f:
            f.write("\n".join(lines) + "\n")
        os.replace(path + ".tmp", path)
        progress(f"wrote {path}")
        if figure:
            stage("figure of the displays")
            displays_figure(os.path.join(output, FIGURE))
    return scale_rows, exponents, time_rows


def _report(machine, scale_rows, exponents, time_rows, size, seconds, reference_seconds,
            ref_spp):
    w, h = size
    lines = [
        "# Radiosity: solve cost and equal-time error",
        "",
        f"Generated by `python -m sampling_lab bench-radiosity` (tools/radiosity.py) on "
        f"{machine['date']}, {machine['cpu']} ({machine['cpus']} CPUs), load average "
        f"{machine['load_start']} at the start and {loadavg()} at the end (shared machine: "
        f"times are noisy, ratios within one run are what to compare).",
        "",
        f"## Solve time and peak memory (Cornell box, area lamp, {FORM_FACTOR_SAMPLES} "
        f"form-factor samples, tolerance 1e-3)",
        "",
        "| solver | patches | seconds | peak MB | sweeps / shots | links |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for r in scale_rows:
        lines.append(f"| {r['solver']} | {r['patches']:,} | {r['seconds']:.2f} | "
                     f"{r['peak_mb']:.0f} | {r['iterations']} | {r['links']} |")
    lines += ["", "Fitted exponent (time ~ patches^k): " + ", ".join(
        f"{k} {v:.2f}" for k, v in exponents.items()), "",
        f"## Equal time: {seconds:g} s each, {w}x{h}, lamp hidden from the camera", "",
        f"Reference: our path tracer for {reference_seconds:g} s ({ref_spp} spp, another "
        f"seed). Radiosity's budget includes its solve.", "",
        "| method | spp | seconds | relMSE | mean / ref | notes |",
        "|---|---:|---:|---:|---:|---|"]
    for r in time_rows:
        lines.append(f"| {r['method']} | {r['spp']} | {r['seconds']:.1f} | {r['rel_mse']:.4g} "
                     f"| {r['mean_ratio']:.4f} | {r['notes']} |")
    return lines
