"""Equal-time error of SPPM, photon mapping, path tracing, BDPT and Cycles on point-light
caustics, with photon throughput and memory, in one run.

``python -m sampling_lab bench-photons`` calls :func:`run`. Two built-in scenes, each lit by a
point light (radius 0) and seen through a pinhole:

- ``point_mirror`` (:func:`core.scenes.mirror_point_light`, one bounce): the floor receives
  the light directly and reflected by a mirror above it. Reference: the closed form (the
  light's mirror image, :func:`core.scenes.mirror_point_light_reference`), exact.
- ``point_mirror_seen``: the same, seen *in the mirror* (two bounces): the reflected light
  reaches the camera through the mirror twice (``L S D S E``), which neither path tracing nor
  BDPT can sample. Reference: the same closed form, through the mirror.
- ``point_glass`` (:func:`core.scenes.cornell_sphere` with a glass ball and a point light, 8
  bounces): a refracted caustic on the floor.
- ``point_mirror_glass`` (:func:`core.scenes.mirror_point_light` with ``glass=True``, 8
  bounces): the mirror scene with a glass ball (radius 0.3) on the floor: the mirror's
  reflected light and the ball's caustic on one floor, part of the caustic seen through the
  ball.

The glass scenes' reference is complete (:func:`.photons_reference.complete_reference`): BDPT
for ``reference_seconds`` (another seed) finds every path but ``L S+ (D S+)* D S+ E`` (light
that reached a diffuse surface through the ball and is seen through it: a point light and a
pinhole both behind specular bounces), which a long SPPM render of those paths alone adds
(``reference_seconds / 2`` for each of two initial radii, whose difference bounds its bias).
The run reports each reference's noise and bias as relMSE against the truth, checks it per
pixel group against the full SPPM image of the same long run (and shows BDPT alone failing
that check), and flags rows whose error is not well above the reference's uncertainty. The
table also gives relMSE over the *pixels seen directly* (:func:`direct_pixels`: no specular
bounce before the first rough surface in any of 16 samples of the pixel).

Every renderer gets the same wall-clock budget: ours with ``RenderSettings(spp=0,
time_limit=seconds)`` (SPPM and photon mapping finish the pass under way), Cycles the sample
count its measured rate fits into it (:class:`.cycles.CyclesRunner`; the scene is rebuilt in
``bpy`` with a Glossy mirror of roughness 0 and a Glass BSDF, IOR 1.5). relMSE = mean over
pixels and RGB of ``(x - ref)^2 / (ref^2 + 0.01)`` (``core.metrics.rel_mse``). For the photon
estimators the table adds photons emitted, M photons/s (photon tracing time only) and the
photon memory peak. :func:`lookup_timing` times SPPM's lookup both ways, the kd-tree
(``scipy.spatial.cKDTree``, what SPPM uses) and pbrt-v4's uniform grid over the visible points
(:class:`core.photons.grid.PointGrid`), on one pass of each scene. Output: ``PHOTONS_BENCH.md``
and ``photons_bench.csv`` in ``output`` (default ``out/bench-photons``); with ``update_docs``
the markdown goes to ``docs/``. ``bench-photons --sweep`` runs :func:`sweep` instead: SPPM's
photons per pass, initial radius and alpha against BDPT at equal time, the measurement behind
SPPM's defaults (``photons_sweep.csv``). Figures, never asserted.
"""

from __future__ import annotations

import os
import time
import traceback

import numpy as np

from ..core.integrators.base import Counters
from ..core.metrics import rel_mse
from ..core.photons.grid import PointGrid
from ..core.photons.lookup import PhotonTree
from ..core.photons.tracing import scene_diagonal, sppm_auto_radius, trace_photons
from ..core.photons.visible import trace_visible_points
from ..core.prepare import prepare
from ..core.sampling.samplers import make_sampler
from ..core.film import PixelFilter
from ..core.options import DEFAULTS
from ..core.render import RenderSettings, render
from ..core.scenes import BUILTIN, mirror_point_light_reference
from .common import loadavg, machine_summary, stage, write_csv
from .outputs import publish
from .photons_reference import complete_reference, group_se, reference_check
from ..core.integrators.bounces import uniform_limits

DOCS_FILES = ("PHOTONS_BENCH.md",)
# scene -> max bounces (the mirror's closed form holds for one bounce).
SCENES = {"point_mirror": 1, "point_mirror_seen": 2, "point_glass": 8, "point_mirror_glass": 8}
INTEGRATORS = ("sppm", "sppm adaptive", "photon", "path", "bdpt")
# Rows that are an integrator with other settings: label -> (integrator, settings).
RENDERERS = {"sppm adaptive": ("sppm", dict(sppm_radius="adaptive"))}
# What each scene's reference holds (the glass scenes' notes add the figures of the run).
REFERENCES = {
    "point_mirror": "closed form: direct light and the light's mirror image (every path "
                    "within one bounce; exact but for 8x8 rays per pixel)",
    "point_mirror_seen": "closed form traced through the mirror (every path within two "
                         "bounces: the camera sees the mirror or nothing)",
    "point_glass": "complete: BDPT + SPPM of the paths BDPT cannot sample",
    "point_mirror_glass": "complete: BDPT + SPPM of the paths BDPT cannot sample",
}
# A row whose relMSE is below this many times its reference's uncertainty is flagged.
UNCERTAIN = 5.0


def run(scenes=tuple(SCENES), integrators=INTEGRATORS, size=(64, 64), seconds=8.0,
        reference_seconds=120.0, photons=None, cycles=True, threads=2,
        output="out/bench-photons", update_docs=False):
    """Render, print and write the table; returns the rows. ``photons`` None: the render
    default (``Photons``)."""
    w, h = size
    photons = int(photons or DEFAULTS["photons"])
    summary = machine_summary()
    rows = []
    for name in scenes:
        scene = BUILTIN[name](w, h)
        bounces = SCENES[name]
        full = _reference(name, scene, bounces, reference_seconds, threads, cache=output,
                          photons=photons)
        ref = full["image"]
        mask = direct_pixels(scene, bounces)
        summary[f"reference_{name}"] = _reference_report(full, mask)
        print(f"{name}: reference {summary[f'reference_{name}']}")
        scene_rows = [_ours(name, scene, integ, bounces, seconds, photons, threads, ref, mask)
                      for integ in integrators]
        if cycles:
            scene_rows.append(_cycles(name, scene, bounces, seconds, threads, ref, mask))
        for row in filter(None, scene_rows):
            row.update(ref_uncertainty=full["uncertainty"],
                       uncertain=row["rel_mse"] < UNCERTAIN * full["uncertainty"])
            rows.append(row)
            print(_line(row))
    for name in scenes:
        timing = lookup_timing(BUILTIN[name](w, h), SCENES[name], photons)
        summary[f"lookup_{name}"] = timing
        print(f"{name}: lookup of one pass: {timing}")
    summary.update(load_end=loadavg())
    os.makedirs(output, exist_ok=True)
    write_csv(os.path.join(output, "photons_bench.csv"), rows)
    _write_markdown(os.path.join(output, DOCS_FILES[0]), rows, summary, size, seconds,
                    reference_seconds, photons, threads)
    print(f"wrote {output}/photons_bench.csv and {DOCS_FILES[0]}")
    if update_docs:
        publish(output, DOCS_FILES)
    return rows


def sweep(scenes=tuple(SCENES), size=(64, 64), seconds=6.0, reference_seconds=120.0,
          photons=(25_000, 100_000), radius_pixels=(0.64, 1.25, 2.5), alphas=(0.5, 0.7),
          threads=2, output="out/bench-photons"):
    """SPPM's settings at equal time: every combination of photons per pass, initial radius
    (``radius_pixels`` scene diagonals over the larger image side, as
    :func:`core.photons.tracing.sppm_auto_radius`) and alpha, between two BDPT renders (the
    second shows how the machine's load drifted). Writes ``photons_sweep.csv``; returns the
    rows."""
    w, h = size
    rows = []
    for name in scenes:
        scene = BUILTIN[name](w, h)
        bounces = SCENES[name]
        ref = _reference(name, scene, bounces, reference_seconds, threads)["image"]
        mask = direct_pixels(scene, bounces)
        unit = scene_diagonal(prepare(scene)) / max(w, h)
        runs = [dict(integrator="bdpt")]
        runs += [dict(integrator="sppm", photons=n, photon_radius=k * unit, sppm_alpha=a,
                      radius_pixels=k)
                 for n in photons for k in radius_pixels for a in alphas]
        for run in runs + [dict(integrator="bdpt")]:
            extra = {key: v for key, v in run.items()
                     if key in ("photon_radius", "sppm_alpha")}
            k = run.get("radius_pixels", "")
            row = _ours(name, scene, run["integrator"], bounces, seconds, run.get("photons"),
                        threads, ref, mask, **extra)
            row.update(radius_pixels=k, photons=run.get("photons", ""),
                       photon_radius=run.get("photon_radius", ""),
                       sppm_alpha=run.get("sppm_alpha", ""), load=loadavg())
            rows.append(row)
            print(_line(row) + (f" [photons {row['photons']}, radius {k} px-diagonals, "
                                f"alpha {row['sppm_alpha']}]" if k != "" else ""))
    os.makedirs(output, exist_ok=True)
    write_csv(os.path.join(output, "photons_sweep.csv"), rows)
    print(f"wrote {output}/photons_sweep.csv")
    return rows


# SPPM settings compared by ``bench-photons --variants`` (name -> render settings; the key
# ``footprint_pixels`` sets core.integrators.sppm.FOOTPRINT_PIXELS for that render).
VARIANTS = {
    "sppm": dict(),
    "sppm, no edge correction": dict(sppm_coverage=False),
    "sppm, no surface test": dict(photon_surface_test=False),
    "sppm, neither": dict(photon_surface_test=False, sppm_coverage=False),
    "sppm, footprint 1": dict(sppm_radius="pixel", footprint_pixels=1.0),
    "sppm, footprint 1.5": dict(sppm_radius="pixel", footprint_pixels=1.5),
    "sppm, 25k photons": dict(photons=25_000),
    "sppm, adaptive radius": dict(sppm_radius="adaptive"),
    "sppm, adaptive radius, alpha 0.8": dict(sppm_radius="adaptive", sppm_alpha=0.8),
    "sppm, adaptive radius, 25k photons": dict(sppm_radius="adaptive", photons=25_000),
}


def variants(scenes=tuple(SCENES), names=tuple(VARIANTS), size=(64, 64), seconds=8.0,
             reference_seconds=120.0, threads=2, output="out/bench-photons", rounds=2):
    """SPPM's lookup and radius options (:data:`VARIANTS`) at equal time, each round of them
    after a BDPT render (the rounds show how the machine's load drifted), in one run. Writes
    ``photons_variants.csv``; returns the rows."""
    from ..core.integrators import sppm

    w, h = size
    rows = []
    for name in scenes:
        scene = BUILTIN[name](w, h)
        bounces = SCENES[name]
        ref = _reference(name, scene, bounces, reference_seconds, threads, cache=output)["image"]
        mask = direct_pixels(scene, bounces)
        for label in (("bdpt",) + tuple(names)) * rounds:
            extra = dict(VARIANTS.get(label, {}))
            old = sppm.FOOTPRINT_PIXELS
            sppm.FOOTPRINT_PIXELS = extra.pop("footprint_pixels", old)
            try:
                row = _ours(name, scene, "bdpt" if label == "bdpt" else "sppm", bounces,
                            seconds, extra.pop("photons", None), threads, ref, mask, **extra)
            finally:
                sppm.FOOTPRINT_PIXELS = old
            row.update(renderer=label, load=loadavg())
            rows.append(row)
            print(_line(row))
    os.makedirs(output, exist_ok=True)
    write_csv(os.path.join(output, "photons_variants.csv"), rows)
    print(f"wrote {output}/photons_variants.csv")
    return rows


def lookup_timing(scene, bounces, photons, repeats=3):
    """Seconds of SPPM's gather lookup on one pass (one visible point per pixel, ``photons``
    photons, the initial radius), best of ``repeats``: kd-tree and grid, and the pair count."""
    prep = prepare(scene)
    n = scene.camera.width * scene.camera.height
    sampler = make_sampler("independent", seed=3)
    points = trace_visible_points(prep, sampler.stream(np.arange(n), np.zeros(n, np.int64)),
                                  PixelFilter("box", 1.0), bounces, Counters(), np.zeros((n, 3)))
    ph = trace_photons(prep, sampler.stream(np.arange(photons), np.ones(photons, np.int64)),
                       bounces, Counters(), min_hit=2)
    radii = np.full(points.rows.size, sppm_auto_radius(prep))
    times = {"kdtree": np.inf, "grid": np.inf}
    for _ in range(repeats):
        t0 = time.perf_counter()
        tree = PhotonTree(ph.p, origin=np.zeros(3))
        pairs = tree.pairs_within(points.p, radii)
        times["kdtree"] = min(times["kdtree"], time.perf_counter() - t0)
        t0 = time.perf_counter()
        PointGrid(points.p, radii).pairs_within(ph.p.astype(np.float64))
        times["grid"] = min(times["grid"], time.perf_counter() - t0)
    return (f"kd-tree {times['kdtree']:.3f} s, grid {times['grid']:.3f} s "
            f"({points.rows.size} points, {len(ph)} photons, {pairs[0].size} pairs)")


def direct_pixels(scene, bounces, samples=16):
    """``(h, w)`` bool: pixels none of whose ``samples`` camera paths (independent sampler, box
    filter of one pixel) meets a specular surface before its first rough one."""
    prep = prepare(scene)
    n = scene.camera.width * scene.camera.height
    through = np.zeros(n, bool)
    sampler = make_sampler("independent", seed=7)
    for k in range(samples):
        stream = sampler.stream(np.arange(n), np.full(n, k, np.int64))
        points = trace_visible_points(prep, stream, PixelFilter("box", 1.0), bounces, Counters(),
                                      np.zeros((n, 3)))
        through[points.rows[points.bounces > 0]] = True
    return ~through.reshape(scene.camera.height, scene.camera.width)


def _errors(img, ref, mask):
    """relMSE over every pixel and over the pixels of ``mask``."""
    return rel_mse(img, ref), rel_mse(img[mask], ref[mask])


# The worst pixels whose share of the squared error :func:`error_breakdown` reports.
WORST_PIXELS = 16


def error_breakdown(img, ref):
    """How the relMSE is spread over the pixels: ``(median, share)``, the median of the
    per-pixel relMSE (RGB mean) over the pixels lit in the image or the reference (the black
    background would make it zero) and the share of the total held by the
    :data:`WORST_PIXELS` worst pixels (near 1: a handful of pixels decide the relMSE)."""
    per_pixel = ((img - ref) ** 2 / (ref ** 2 + 1e-2)).mean(axis=-1)
    lit = (ref.max(axis=-1) > 0) | (img.max(axis=-1) > 0)
    total = per_pixel.sum()
    worst = np.sort(per_pixel.ravel())[-WORST_PIXELS:].sum()
    median = float(np.median(per_pixel[lit])) if lit.any() else 0.0
    return median, float(worst / total) if total > 0 else 0.0


def _reference(name, scene, bounces, seconds, threads, cache=None, photons=None):
    """The scene's reference: a dict with ``image`` ``(h, w, 3)``, its ``noise`` and ``bias``
    (relMSE against the truth: expected from its variance; the missing part's difference
    between two radii), ``uncertainty`` (their sum), ``notes`` and, for the glass scenes, the
    parts of :func:`.photons_reference.complete_reference` (kept in the folder ``cache`` when
    given, and read from there by the next run with the same size and time). ``photons``:
    the SPPM part's photons per pass (None: the default)."""
    if name in ("point_mirror", "point_mirror_seen"):
        direct, reflected, _ = mirror_point_light_reference(scene)
        return dict(image=np.repeat((direct + reflected)[..., None], 3, axis=2), noise=0.0,
                    bias=0.0, uncertainty=0.0, notes=REFERENCES[name])
    cam = scene.camera
    path = (os.path.join(cache, f"reference_{name}_{cam.width}x{cam.height}_{seconds:g}s.npz")
            if cache else None)
    if path and os.path.exists(path):
        stage(f"{name}: complete reference from {path}")
        with np.load(path) as f:
            ref = {key: (f[key].item() if f[key].ndim == 0 else f[key]) for key in f.files}
    else:
        stage(f"{name}: complete reference, BDPT {seconds:g} s + SPPM 2 x {seconds / 2:g} s")
        ref = complete_reference(scene, bounces, seconds, seconds / 2, threads, log=stage,
                                 photons=photons)
        if path:
            os.makedirs(cache, exist_ok=True)
            np.savez(path, **ref)
    img, k = ref["image"], len(ref["passes"])
    var = ref["variance"] + (ref["passes"].var(axis=0, ddof=1) / k if k > 1 else 0.0)
    ref["noise"] = rel_mse_expected(var, img)
    # The missing part with two radii: their difference holds its bias (and both noises).
    ref["bias"] = (float(np.mean((ref["missing"] - ref["missing_half"]) ** 2 / (img ** 2 + 1e-2)))
                   if "missing_half" in ref else 0.0)
    ref["uncertainty"] = ref["noise"] + ref["bias"]
    return ref


def rel_mse_expected(variance, ref):
    """Expected relMSE of an unbiased image with per-pixel ``variance`` around ``ref``."""
    return float(np.mean(variance / (ref ** 2 + 1e-2)))


def _reference_report(ref, mask):
    """One line on a reference: what it holds, its noise and bias (relMSE), and, for the
    complete ones, :func:`.photons_reference.reference_check` of it and of BDPT alone against
    the full SPPM image of the same long run, over the pixels seen directly and the rest."""
    text = f"{ref['notes']}; noise relMSE {ref['noise']:.2g}, bias relMSE {ref['bias']:.2g}"
    if "sppm" not in ref:
        return text
    groups = {"seen directly": mask, "through specular surfaces": ~mask}
    se_sppm = {k: group_se(m, passes=ref["sppm_passes"]) for k, m in groups.items()}
    for label, img, se in (
            ("this reference", ref["image"],
             {k: group_se(m, ref["variance"], ref["passes"]) for k, m in groups.items()}),
            ("BDPT alone", ref["bdpt"], {k: group_se(m, ref["variance"]) for k, m in groups.items()})):
        found = reference_check(img, ref["sppm"], groups, se, se_sppm)
        text += f"; {label} against the long SPPM image: " + ", ".join(
            f"{k} {d:+.2%} ({'ok' if ok else 'FAILS'})" for k, (d, ok) in found.items())
    return text


def _ours(name, scene, integ, bounces, seconds, photons, threads, ref, mask, **settings):
    """One equal-time render of ours (``photons`` None: the default; ``settings``: more
    render settings) and its errors."""
    stage(f"{name}: {integ}, {seconds:g} s")
    label = integ
    integ, extra = RENDERERS.get(label, (label, {}))
    settings = {**extra, **settings}
    if photons is not None:
        settings["photons"] = photons
    t0 = time.perf_counter()
    res = render(scene, RenderSettings(integrator=integ, spp=0, time_limit=seconds,
                                       **uniform_limits(bounces), seed=1, threads=threads,
                                       filter_type="box", filter_width=1.0, **settings))
    wall = time.perf_counter() - t0
    img = res.film.mean()
    st = res.stats
    err, err_direct = _errors(img, ref, mask)
    median, worst = error_breakdown(img, ref)
    return dict(scene=name, renderer=label, spp=st["spp"], time_s=wall,
                rel_mse=err, rel_mse_direct=err_direct, median=median, worst_share=worst,
                mean_ratio=float(img.mean() / ref.mean()),
                photons_emitted=st.get("photons_emitted", ""),
                m_photons_per_s=(st["photons_per_s"] / 1e6 if "photons_per_s" in st else ""),
                photon_memory_peak_mb=st.get("photon_memory_peak_mb", ""))


def _cycles(name, scene, bounces, seconds, threads, ref, mask):
    """Cycles at equal time on the scene rebuilt in ``bpy`` with its mirror and glass."""
    from . import blender_scene as bs
    from . import bpy_scenes
    from .cycles_runner import CyclesRunner

    stage(f"{name}: Cycles, {seconds:g} s")
    try:
        bpy = bs.import_bpy()
        bpy.ops.wm.read_homefile(use_empty=True)
        bl_scene = bs.build_blender_scene(scene)
        replacements = {"Mirror": bpy_scenes.glossy_material("Mirror", (1.0, 1.0, 1.0), 0.0),
                        "Ball": bpy_scenes.glass_material("Ball", (1.0, 1.0, 1.0), 1.5, 0.0),
                        "Glass": bpy_scenes.glass_material("Glass", (1.0, 1.0, 1.0), 1.5, 0.0)}
        for ob in bl_scene.collection.objects:
            mat = ob.active_material
            if mat is not None and mat.name.split(".")[0] in replacements:
                ob.data.materials[0] = replacements[mat.name.split(".")[0]]
        cy = CyclesRunner(scene, threads, bounces, blender_scene=bl_scene)
        cy.measure_fixed_cost(1)
        cy.measure_fixed_spp(max(1, (1 << 16) // (scene.camera.width * scene.camera.height)), 1)
        spp, t, img = cy.equal_time(seconds, 1)
    except Exception:  # noqa: BLE001 - report and carry on
        traceback.print_exc()
        return None
    img = img[..., :3].astype(np.float64)
    err, err_direct = _errors(img, ref, mask)
    median, worst = error_breakdown(img, ref)
    return dict(scene=name, renderer="Cycles", spp=spp, time_s=t, rel_mse=err,
                rel_mse_direct=err_direct, median=median, worst_share=worst,
                mean_ratio=float(img.mean() / ref.mean()), photons_emitted="",
                m_photons_per_s="", photon_memory_peak_mb="")


def _line(row):
    extra = (f", {row['m_photons_per_s']:.2f} M photons/s, {row['photon_memory_peak_mb']:.1f} MB"
             if row["m_photons_per_s"] != "" else "")
    return (f"{row['scene']} {row['renderer']}: {row['spp']} spp in {row['time_s']:.1f} s, "
            f"relMSE {row['rel_mse']:.4g} (pixels seen directly {row['rel_mse_direct']:.4g}; "
            f"median {row['median']:.3g}, worst {WORST_PIXELS} px "
            f"{100 * row['worst_share']:.0f} %),"
            f" mean/ref {row['mean_ratio']:.4f}{extra}")


def _write_markdown(path, rows, summary, size, seconds, reference_seconds, photons, threads):
    lines = [
        "# Point-light caustics: equal-time error of the photon estimators",
        "",
        f"Generated by `python -m sampling_lab bench-photons` (tools/photons.py) on "
        f"{summary['date']}: {size[0]}x{size[1]}, box filter, {threads} threads, "
        f"{seconds:g} s per render, {photons:,} photons per SPPM pass (and in photon "
        f"mapping's maps); references: closed form (point_mirror, point_mirror_seen), BDPT for "
        f"{reference_seconds:g} s plus SPPM of the paths BDPT cannot sample for 2 x "
        f"{reference_seconds / 2:g} s (point_glass, point_mirror_glass). "
        f"CPU {summary['cpu']}, load average "
        f"{summary['load_start']} at the start, {summary['load_end']} at the end.",
        "",
        "References (uncertainty: relMSE of the reference against the truth, its expected "
        "noise plus its bias bound; a row is marked *uncertain* when its relMSE is below "
        f"{UNCERTAIN:g} times that):",
        "",
        *[f"- {k.removeprefix('reference_')}: {v}" for k, v in summary.items()
          if k.startswith("reference_")],
        "",
        f"relMSE as the issue asks; beside it the median of the per-pixel relMSE over the lit "
        f"pixels and the share of the relMSE held by the {WORST_PIXELS} worst pixels (near "
        f"100 %: a handful of pixels decide it).",
        "",
        "| scene | renderer | spp | time s | relMSE | relMSE / SPPM's | relMSE, pixels seen "
        "directly | its / SPPM's | median | worst px share | mean / ref | M photons/s "
        "| photon MB | ref. uncertainty / relMSE |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in rows:
        sppm = next((r for r in rows if r["scene"] == row["scene"] and r["renderer"] == "sppm"),
                    None)
        base = ((sppm["rel_mse"] or np.nan, sppm["rel_mse_direct"] or np.nan) if sppm
                else (np.nan, np.nan))
        mps = row["m_photons_per_s"]
        mb = row["photon_memory_peak_mb"]
        lines.append(
            f"| {row['scene']} | {row['renderer']} | {row['spp']} | {row['time_s']:.1f} "
            f"| {row['rel_mse']:.4g} | {row['rel_mse'] / base[0]:.2f} "
            f"| {row['rel_mse_direct']:.4g} | {row['rel_mse_direct'] / base[1]:.2f} "
            f"| {row['median']:.2g} | {100 * row['worst_share']:.0f} % "
            f"| {row['mean_ratio']:.4f} "
            f"| {'' if mps == '' else f'{mps:.2f}'} | {'' if mb == '' else f'{mb:.1f}'} "
            f"| {row['ref_uncertainty'] / row['rel_mse']:.1%}"
            f"{' uncertain' if row['uncertain'] else ''} |")
    lines += ["", "SPPM's lookup on one pass (best of 3, building included; SPPM uses the "
              "kd-tree):", ""]
    lines += [f"- {k.removeprefix('lookup_')}: {v}" for k, v in summary.items()
              if k.startswith("lookup_")]
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
