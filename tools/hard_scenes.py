"""Equal-time error of our integrators and of Cycles on hard scenes, in one run.

``python -m sampling_lab bench-scenes`` calls :func:`run`. For every scene of :data:`SCENES`
(built in ``bpy`` by :mod:`.bpy_scenes`, the builders of the Cycles agreement tests), in one
process:

1. The scene is built in an empty file and exported as the add-on exports it
   (``addon.export.export_scene``): both renderers see the same Blender scene.
2. *Cycles calibration*: a cold 1-spp render, the fixed cost of a render (best of two 1-spp
   renders) and its rate at a sample count of about 2^18 camera samples, as in
   :class:`.cornell.CyclesRunner`.
3. *Equal time*: each of our integrators (every key of ``core.integrators.INTEGRATORS`` unless
   told otherwise) renders with ``RenderSettings(spp=0, time_limit=seconds)``; Cycles renders
   the sample count its measured rate fits into ``seconds`` of wall clock, fixed cost included
   (planned again once if it misses by more than 15 %). Times are wall clock of the whole
   render call: scene preparation for ours; synchronisation, BVH and EXR writing for Cycles.
4. *References*: our reference integrator (``path``) with another seed, to ``reference_spp``
   or a time cap, carrying its per-pixel variance; and Cycles at the same sample count (capped
   by the same time), another seed. Their agreement is reported: image-mean ratio and
   relMSE between the two against what their noise alone would give.
5. *Errors*: ``relMSE = mean (x - ref)^2 / (ref^2 + 0.01)`` (``core.metrics.rel_mse``) against
   our reference, minus that reference's own noise ("corrected", an unbiased estimate of the
   error against the converged image), scaled to exactly the budget by
   ``(time - fixed) / (seconds - fixed)`` (error ~ 1 / sampling time for an unbiased
   estimator; ``fixed`` is our scene preparation or Cycles' fixed cost of a render); and, as a
   cross-check, the raw relMSE against the Cycles reference.

Output: ``hard_scenes.csv`` (one row per scene and render) and ``hard_scenes_summary.csv``
(references, agreement, machine, load averages) in ``output`` (default ``out/bench-scenes``),
and the markdown report ``HARD_SCENES.md`` with its montage in ``images/hard_scenes.png``, laid
out as in ``docs/``, where ``update_docs`` copies them. Figures, never asserted (``docs/CONVENTIONS.md``, "Tests").
"""

from __future__ import annotations

import datetime
import math
import os
import sys
import time
import traceback

import numpy as np

from ..core.exr import write_png_preview
from ..core.integrators import INTEGRATORS
from ..core.metrics import rel_mse
from ..core.render import RenderSettings, render
from ..core.sampling.samplers import available as available_samplers
from .cornell import (
    EPS,
    CyclesRunner,
    _loadavg,
    _machine_summary,
    _mean_ratio,
    _stage,
    _write_csv,
)
from .outputs import publish


def _glossy_plates(bs, scene, size):
    bs.glossy_plates(scene, size, roughness=(0.05, 0.2, 0.6))


def _glass_sphere(bs, scene, size):
    bs.cornell_sphere(scene, bs.glass_material("Glass", (1.0, 1.0, 1.0), 1.5, 0.0), size,
                      light_size=0.5)


def _mirror_ball(bs, scene, size):
    bs.cornell_sphere(scene, bs.glossy_material("Mirror", (0.9, 0.9, 0.9), 0.0), size,
                      light_size=0.3)


def _environment(bs, scene, size):
    world, _, _ = bs.environment_scene(scene, size)
    # Cycles importance-samples the world at the image's own resolution.
    world.cycles.sampling_method = "AUTOMATIC"


def _cornell(bs, scene, size):
    bs.cornell_box(scene, "area", size)


# name -> (builder(bpy_scenes module, bpy scene, (w, h)), description for the report).
SCENES = {
    "glossy_plates": (_glossy_plates, "three GGX Glossy plates (roughness 0.05, 0.2, 0.6) on a "
                      "grey floor under a 0.1 m (10 W) and a 1 m (50 W) square area light"),
    "glass_sphere": (_glass_sphere, "smooth glass sphere (IOR 1.5) in the Cornell box without "
                     "blocks, 0.5 m 50 W area light: a refractive caustic on the floor"),
    "mirror_ball": (_mirror_ball, "perfect mirror ball (Glossy, roughness 0) in the Cornell box "
                    "without blocks, small 0.3 m 50 W area light"),
    "environment": (_environment, "diffuse plane and sphere under a 64 x 32 equirectangular "
                    "environment map with a small bright spot (the sky is visible)"),
    "cornell": (_cornell, "Lambertian Cornell box with its two blocks, 0.5 m 50 W square area "
                "light under the ceiling"),
}
# Glossy, glass and mirror materials and an environment map: hard for camera-side sampling of
# materials and lights.
MATERIAL_SCENES = ("glossy_plates", "glass_sphere", "mirror_ball", "environment")
# Diffuse interreflection and the two caustics: where light tracing and BDPT differ most from
# path tracing.
# What docs/ shows, relative to the output folder (and to docs/).
DOCS_FILES = ("HARD_SCENES.md", "images/hard_scenes.png")
INTEGRATOR_SCENES = ("cornell", "glass_sphere", "mirror_ball")
# Cycles' rate is measured on about this many camera samples.
CALIBRATION_SAMPLES = 1 << 18
REFERENCE_MIN_SECONDS = 30.0
REFERENCE_TIME_FACTOR = 8.0
REFERENCE_INTEGRATOR = "path"


def run(scenes=tuple(SCENES), integrators=None, seconds=4.0, size=(64, 64), reference_spp=1024,
        cycles=True, output="out/bench-scenes", report=True, update_docs=False, *,
        reference_seconds=None, sampler="independent", threads=2, max_bounces=8, seed=0,
        command=None):
    """Render every scene with each integrator and Cycles for ``seconds``; write the figures.

    Parameters
    ----------
    scenes : sequence of str
        Keys of :data:`SCENES` (default all; :data:`MATERIAL_SCENES` and
        :data:`INTEGRATOR_SCENES` are the material and the integrator sets).
    integrators : sequence of str or None
        Keys of ``core.integrators.INTEGRATORS``; None takes all of them.
    seconds : float
        Equal wall-clock budget of every render.
    size : (int, int)
        Image width and height.
    reference_spp : int
        Samples per pixel of the references, capped by ``reference_seconds``.
    cycles : bool
        Include Cycles (renders; the scenes are built in ``bpy`` either way).
    output : str
        Folder of everything written: ``hard_scenes.csv``, ``hard_scenes_summary.csv``, the
        report ``HARD_SCENES.md`` and its montage ``images/hard_scenes.png``.
    report : bool
        Write the markdown report.
    update_docs : bool
        Also copy the report and its figure (:data:`DOCS_FILES`) into the repository's docs/.
    reference_seconds : float or None
        Time cap of each reference render; None picks ``max(30, 8 * seconds)``, 0 removes it.
    sampler : str
        Sampler of our equal-time renders (the reference always uses ``independent``).
    threads, max_bounces, seed : int
    command : str or None
        The command line, quoted in the report.

    Returns
    -------
    int
        Exit code: 0; 1 if a render failed (the others are still reported); 2 for bad
        arguments.
    """
    integrators = list(INTEGRATORS) if integrators is None else list(integrators)
    unknown = ([s for s in scenes if s not in SCENES]
               + [i for i in integrators if i not in INTEGRATORS]
               + ([] if sampler in available_samplers() else [sampler]))
    width, height = (int(x) for x in size)
    if unknown or not scenes or not integrators:
        print(f"sampling_lab bench-scenes: unknown or missing names {unknown}; scenes: "
              f"{', '.join(SCENES)}; integrators: {', '.join(INTEGRATORS)}; samplers: "
              f"{', '.join(available_samplers())}", file=sys.stderr)
        return 2
    if width < 1 or height < 1 or not seconds > 0 or reference_spp < 1:
        print("sampling_lab bench-scenes: --size, --seconds and --reference-spp must be positive",
              file=sys.stderr)
        return 2
    if reference_seconds is None:
        reference_seconds = max(REFERENCE_MIN_SECONDS, REFERENCE_TIME_FACTOR * seconds)
    os.makedirs(output, exist_ok=True)
    from . import blender_scene
    bpy = blender_scene.import_bpy()
    from ..addon.export import export_scene
    from . import bpy_scenes

    t_bench = time.perf_counter()
    summary = _machine_summary()
    summary.update(resolution=f"{width}x{height}", max_bounces=max_bounces, threads=threads,
                   equal_time_s=seconds, reference_spp_requested=reference_spp,
                   reference_seconds_cap=reference_seconds, integrators=" ".join(integrators),
                   reference_integrator=REFERENCE_INTEGRATOR, scenes=" ".join(scenes),
                   sampler=sampler)
    print(f"Sampling Lab bench-scenes: {', '.join(scenes)}; integrators {', '.join(integrators)}"
          f"{' and Cycles' if cycles else ''}; {width}x{height}, {seconds:g} s each, "
          f"{max_bounces} bounces, {threads} threads")
    print(f"machine: {summary['cpu']}, {summary['cpus']} CPUs, load average at start "
          f"{summary['load_start']}; {summary['date']}")
    rows, scene_rows, montage, status = [], [], [], 0
    for name in scenes:
        builder, _ = SCENES[name]
        _stage(f"{name}: build and export")
        bpy.ops.wm.read_homefile(use_empty=True)
        bl_scene = bpy.context.scene
        builder(bpy_scenes, bl_scene, (width, height))
        core_scene = export_scene(bpy.context.evaluated_depsgraph_get())
        pixels = width * height
        info = {"scene": name, "triangles": core_scene.n_triangles,
                "load_start": _loadavg(), "notes": "; ".join(core_scene.messages)}
        settings = dict(seed=seed, max_bounces=max_bounces, threads=threads)

        cy = None
        if cycles:
            _stage(f"{name}: Cycles calibration")
            try:
                cy = CyclesRunner(core_scene, threads, max_bounces, blender_scene=bl_scene)
                cy.measure_fixed_cost(seed)
                cy.measure_fixed_spp(max(1, CALIBRATION_SAMPLES // pixels), seed)
                info.update(cycles_cold_s=cy.t_cold, cycles_fixed_cost_s=cy.t_one,
                            cycles_net_samples_per_s=cy.net_sps)
            except Exception:  # noqa: BLE001 - report and carry on with our integrators
                traceback.print_exc()
                print(f"{name}: Cycles failed (traceback above); continuing without it")
                cy, status = None, 1

        images = {}
        scene_out = []
        for integ in integrators:
            _stage(f"{name}: {integ}, {seconds:g} s")
            try:
                t0 = time.perf_counter()
                res = render(core_scene, RenderSettings(integrator=integ, spp=0,
                                                        time_limit=seconds, sampler=sampler,
                                                        **settings))
                wall = time.perf_counter() - t0
            except Exception:  # noqa: BLE001 - an integrator in progress must not stop the rest
                traceback.print_exc()
                print(f"{name}: integrator {integ!r} failed (traceback above)")
                status = 1
                continue
            img = res.combined()[..., :3]
            images[integ] = img
            scene_out.append(_row(name, integ, "equal time", res.stats["samples"] / pixels,
                                  wall, res.stats["samples"], img,
                                  wall - res.stats.get("time_s", wall)))
        if cy is not None:
            _stage(f"{name}: Cycles, {seconds:g} s")
            try:
                spp_eq, t_eq, img = cy.equal_time(seconds, seed)
                images["Cycles"] = img[..., :3]
                scene_out.append(_row(name, "Cycles", "equal time", spp_eq, t_eq,
                                      spp_eq * pixels, img[..., :3], cy.t_one))
            except Exception:  # noqa: BLE001
                traceback.print_exc()
                status = 1

        # References: ours with its variance, then Cycles at the sample count ours reached.
        _stage(f"{name}: reference ({REFERENCE_INTEGRATOR}), {reference_spp} spp or "
               f"{reference_seconds:g} s")
        t0 = time.perf_counter()
        ref_res = render(core_scene, RenderSettings(
            integrator=REFERENCE_INTEGRATOR, spp=reference_spp, time_limit=reference_seconds,
            **dict(settings, seed=seed + 1)))
        ref_wall = time.perf_counter() - t0
        ref = ref_res.combined()[..., :3].astype(np.float64)
        ref_floor = float(np.mean(ref_res.variance().astype(np.float64) / (ref * ref + EPS)))
        ref_spp = ref_res.stats["samples"] / pixels
        info.update(pt_reference_spp=ref_spp, pt_reference_s=ref_wall,
                    pt_reference_noise=ref_floor)
        cy_ref = None
        if cy is not None:
            spp_ref = max(1, int(ref_res.stats["samples"] // pixels))
            if reference_seconds > 0:
                spp_ref = min(spp_ref, cy.spp_for(reference_seconds))
            _stage(f"{name}: Cycles reference, {spp_ref} spp")
            try:
                t_ref, cy_ref = cy.render(spp_ref, seed + 1)
                cy_ref = cy_ref[..., :3].astype(np.float64)
                info.update(cycles_reference_spp=spp_ref, cycles_reference_s=t_ref)
            except Exception:  # noqa: BLE001
                traceback.print_exc()
                status = 1

        for row in scene_out:
            img = row.pop("_image")
            raw = rel_mse(img, ref, EPS)
            row["relmse_vs_ref"] = raw
            row["relmse_corrected"] = raw - ref_floor
            # Unbiased Monte Carlo error falls as 1 / (sampling time): scale to exactly the
            # budget, the fixed cost of the render excluded from both times.
            sampling, budget = row["time_s"] - row["fixed_s"], seconds - row["fixed_s"]
            row["relmse_at_budget"] = (row["relmse_corrected"] * sampling / budget
                                       if sampling > 0 and budget > 0 else float("nan"))
            row["relmse_vs_cycles_ref"] = (rel_mse(img, cy_ref, EPS) if cy_ref is not None
                                           else float("nan"))
            row["mean_over_ref"] = _mean_ratio(img, ref)
        if cy_ref is not None:
            cy_row = next((r for r in scene_out if r["renderer"] == "Cycles"), None)
            info["reference_consistency_relmse"] = rel_mse(cy_ref, ref, EPS)
            # Noise alone: our reference's, plus the Cycles reference's estimated from the
            # equal-time Cycles error scaled by sample count (variance ~ 1 / spp).
            info["reference_consistency_noise_only"] = ref_floor + (
                max(cy_row["relmse_corrected"], 0.0) * cy_row["spp"] / spp_ref
                if cy_row is not None else float("nan"))
            info["reference_mean_ratio_pt_over_cycles"] = _mean_ratio(ref, cy_ref)
            info["reference_channel_ratios"] = " ".join(
                f"{a / b:.4f}" for a, b in zip(ref.mean(axis=(0, 1)), cy_ref.mean(axis=(0, 1))))
        info["load_end"] = _loadavg()
        rows += scene_out
        scene_rows.append(info)
        montage.append([ref, cy_ref] + [images.get(k) for k in integrators + ["Cycles"]])
        _print_scene(info, scene_out, seconds)

    summary.update(load_end=_loadavg(), bench_seconds=time.perf_counter() - t_bench)
    _write_csv(os.path.join(output, "hard_scenes.csv"), rows)
    _write_csv(os.path.join(output, "hard_scenes_summary.csv"),
               [{"key": k, "value": v} for k, v in summary.items()]
               + [{"key": f"{s['scene']}.{k}", "value": v} for s in scene_rows
                  for k, v in s.items() if k != "scene"])
    os.makedirs(os.path.join(output, "images"), exist_ok=True)
    _write_montage(os.path.join(output, DOCS_FILES[1]), montage)
    if report:
        _write_report(os.path.join(output, DOCS_FILES[0]), rows, scene_rows, summary,
                      integrators, cycles, seconds, command)
    print(f"\nwrote {output}/hard_scenes.csv, hard_scenes_summary.csv, {DOCS_FILES[1]}"
          f"{' and ' + DOCS_FILES[0] if report else ''}; took {summary['bench_seconds']:.0f} s, "
          f"load average at end {summary['load_end']}")
    if update_docs and report and status == 0:
        publish(output, DOCS_FILES)
    return status


def _row(scene, renderer, run_name, spp, seconds, samples, image, fixed_s):
    """A render's figures; ``fixed_s`` is the part of ``seconds`` that takes no samples
    (our scene preparation, Cycles' fixed cost of a render)."""
    return {"scene": scene, "renderer": renderer, "run": run_name, "spp": float(spp),
            "time_s": seconds, "fixed_s": fixed_s,
            "samples_per_s": samples / seconds if seconds > 0 else math.nan, "_image": image}


def _print_scene(info, rows, seconds):
    print(f"\n{info['scene']}: reference {info['pt_reference_spp']:.0f} spp "
          f"({info['pt_reference_s']:.1f} s), its noise {info['pt_reference_noise']:.2e}")
    if "reference_mean_ratio_pt_over_cycles" in info:
        print(f"   references: image mean ours / Cycles = "
              f"{info['reference_mean_ratio_pt_over_cycles']:.4f} (RGB "
              f"{info['reference_channel_ratios']}); relMSE between them "
              f"{info['reference_consistency_relmse']:.2e}, noise alone ~ "
              f"{info['reference_consistency_noise_only']:.2e}")
    for r in rows:
        print(f"   {r['renderer']:<8} {r['spp']:8.1f} spp {r['time_s']:6.2f} s "
              f"{r['samples_per_s'] / 1e6:7.3f} M samples/s  relMSE {r['relmse_vs_ref']:.3e} "
              f"corrected {r['relmse_corrected']:.3e}  @{seconds:g} s "
              f"{r['relmse_at_budget']:.3e}  vs Cycles ref {r['relmse_vs_cycles_ref']:.3e}")


def _write_montage(path, montage):
    """One row per scene (first scene on top): references, then the equal-time images."""
    if not montage:
        return
    h, w = next(im for im in montage[0] if im is not None).shape[:2]
    gap_v = np.ones((h, 2, 3))
    strips = []
    for tiles in montage:
        parts = []
        for im in tiles:
            parts += [np.zeros((h, w, 3)) if im is None else np.asarray(im, np.float64)[..., :3],
                      gap_v]
        strips.append(np.concatenate(parts[:-1], axis=1))
    gap_h = np.ones((2, strips[0].shape[1], 3))
    # Row 0 is the bottom of the image: stack the last scene first.
    out = []
    for strip in reversed(strips):
        out += [strip, gap_h]
    write_png_preview(path, np.concatenate(out[:-1], axis=0))


def _fmt(v, digits=2):
    return "–" if v is None or (isinstance(v, float) and not math.isfinite(v)) else \
        f"{v:.{digits}e}"


def _write_report(path, rows, scene_rows, summary, integrators, cycles, seconds, command):
    image_rel = DOCS_FILES[1]
    cmd = command or "python -m sampling_lab bench-scenes"
    lines = [
        "# Hard scenes: equal-time error against Cycles",
        "",
        f"Generated by `{cmd}` ({summary['date']}, {summary['bench_seconds']:.0f} s in all). "
        f"Machine: {summary['cpu']}, {summary['cpus']} CPUs, Python {summary['python']}, NumPy "
        f"{summary['numpy']}, embreex {summary['embreex']}, bpy {summary['bpy']}; "
        f"**load average {summary['load_start']} at the start and {summary['load_end']} at the "
        "end** (1, 5, 15 min; the machine is shared, so every rate is a lower bound).",
        "",
        f"Every render gets **{seconds:g} s of wall clock** ({summary['resolution']}, "
        f"{summary['max_bounces']} bounces, {summary['threads']} threads, Blackman-Harris 1.5, "
        f"{summary['sampler']} sampler for ours, Cycles' defaults otherwise under "
        "`tools.blender_scene.configure_cycles`: no clamping, no glossy blur, no light "
        "threshold, no adaptive sampling, no denoising, caustics on). Times are the wall clock "
        "of the whole render call (ours: scene preparation included; Cycles: synchronisation, "
        "BVH and EXR writing included). Cycles renders the sample count its rate, measured on "
        "the same scene just before, fits into the budget. See `tools/hard_scenes.py` for the "
        "method.",
        "",
        f"Reference: our `{summary['reference_integrator']}` integrator with another seed, to "
        f"{summary['reference_spp_requested']} spp or {summary['reference_seconds_cap']:g} s; "
        "Cycles rendered the same sample count (another seed) as a second reference, and the "
        "two are compared below. relMSE = mean over pixels and RGB of (x − ref)² / (ref² + "
        f"{EPS:g}). *corrected*: minus the reference's own noise (its per-pixel variance), an "
        f"unbiased estimate of the error against the converged image; *@{seconds:g} s*: "
        f"corrected × (time − fixed) / ({seconds:g} s − fixed), the error at exactly the "
        "budget, where *fixed* is the part of a render that takes no samples (our scene "
        "preparation, Cycles' fixed cost of a render, measured on a 1-spp render): the column "
        "to compare; *vs Cycles ref*: raw relMSE against the Cycles reference (a cross-check "
        "that does not depend on our reference); *mean / ref*: image mean over the "
        "reference's.",
        "",
        "| scene | renderer | spp | time s | M samples/s | relMSE | corrected | "
        f"@{seconds:g} s | vs Cycles ref | mean / ref |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['scene']} | {r['renderer']} | {r['spp']:.1f} | {r['time_s']:.2f} | "
            f"{r['samples_per_s'] / 1e6:.3f} | {_fmt(r['relmse_vs_ref'])} | "
            f"{_fmt(r['relmse_corrected'])} | **{_fmt(r['relmse_at_budget'])}** | "
            f"{_fmt(r['relmse_vs_cycles_ref'])} | {r['mean_over_ref']:.4f} |")
    lines += ["", "Error at equal time relative to Cycles (@ budget, ours / Cycles; above 1: "
              "Cycles is better):", ""]
    for s in scene_rows:
        cy = next((r for r in rows if r["scene"] == s["scene"] and r["renderer"] == "Cycles"),
                  None)
        parts = []
        for integ in integrators:
            r = next((r for r in rows if r["scene"] == s["scene"] and r["renderer"] == integ),
                     None)
            if r is None:
                parts.append(f"`{integ}` failed")
            elif cy is not None and cy["relmse_at_budget"] > 0 and math.isfinite(
                    r["relmse_at_budget"]):
                parts.append(f"`{integ}` {r['relmse_at_budget'] / cy['relmse_at_budget']:.3g} ×")
            else:
                parts.append(f"`{integ}` –")
        lines.append(f"- {s['scene']}: " + ", ".join(parts))
    lines += ["", "## References and their agreement", "",
              "| scene | triangles | ours: spp | s | noise | Cycles: spp | s | mean ours / "
              "Cycles (RGB) | relMSE between | noise alone | load at start / end |",
              "|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---|"]
    for s in scene_rows:
        cells = [s["scene"], str(s["triangles"]), f"{s['pt_reference_spp']:.0f}",
                 f"{s['pt_reference_s']:.1f}", _fmt(s["pt_reference_noise"])]
        if "cycles_reference_s" in s:
            cells += [str(s["cycles_reference_spp"]), f"{s['cycles_reference_s']:.1f}"]
        else:
            cells += ["–", "–"]
        if "reference_mean_ratio_pt_over_cycles" in s:
            cells += [f"{s['reference_mean_ratio_pt_over_cycles']:.4f} "
                      f"({s['reference_channel_ratios']})",
                      _fmt(s["reference_consistency_relmse"]),
                      _fmt(s["reference_consistency_noise_only"])]
        else:
            cells += ["–", "–", "–"]
        cells.append(f"{s['load_start']} / {s['load_end']}")
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", "If the relMSE between the references is close to what their noise alone "
              "gives and the mean ratio is close to 1, the two renderers converge to the same "
              "image and the equal-time figures compare like with like.", "", "## Scenes", ""]
    for s in scene_rows:
        lines.append(f"- `{s['scene']}`: {SCENES[s['scene']][1]}."
                     + (f" Export notes: {s['notes']}." if s["notes"] else ""))
    columns = ["our reference", "Cycles reference"] + [f"`{i}` at {seconds:g} s"
                                                        for i in integrators]
    if cycles:
        columns.append(f"Cycles at {seconds:g} s")
    lines += ["", f"![hard scenes]({image_rel})", "",
              "One row per scene, in the order of the table; columns: " + ", ".join(columns)
              + " (linear values, sRGB-encoded, no tone mapping).", ""]
    with open(path, "w") as f:
        f.write("\n".join(lines))
