"""Soak: many renders in one Blender session, with memory and time per render over time.

``python -m sampling_lab bench-soak [--minutes 30] [--size 96x72] [--spp 8] [--output DIR]``

The add-on is registered in a ``bpy`` session once; then, until the time is up, each round
renders every (scene, integrator) pair of :data:`JOBS` through Blender's own render operator
(export, render, passes written back, as pressing F12 does), each in a freshly emptied file
built with the data API. After every render the process's resident set size (``VmRSS``, not
the peak) and the render's wall time are recorded. The report lists RSS by round and its
growth from round 1 (after a warm-up round) and from the middle round to the last (the
allocator settles in the first rounds; a leak keeps growing), and each job's time in the last
round over round 1.
Figures only, never asserted (the machine's load changes times); ``tests/addon/test_soak.py``
runs a few renders and bounds the growth loosely, so that only a leak fails it.
"""

from __future__ import annotations

import csv
import ctypes
import gc
import os
import resource
import statistics
import time

JOBS = (
    ("cornell_point", "path"), ("cornell_mesh", "light"), ("cornell_area", "bdpt"),
    ("cornell_point", "photon"), ("cornell_mesh", "sppm"), ("cornell_area", "radiosity"),
    ("plane_under_sun", "path"), ("glass_sphere", "bdpt"),
)
"""(scene builder of :mod:`tools.bpy_scenes`, integrator) rendered in every round."""


def rss_mb():
    """Current resident set size in MB (Linux ``/proc``; elsewhere the peak, ``ru_maxrss``),
    after collecting garbage cycles and handing the allocator's free blocks back to the system
    (glibc's ``malloc_trim``):
    otherwise the up to 256 MB of freed blocks glibc keeps for reuse
    (:func:`core.render.keep_freed_memory`) would hide a leak until they are used up."""
    _trim()
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _trim():
    gc.collect()  # reference cycles holding a render's arrays are garbage, not a leak
    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError, TypeError):
        pass  # not glibc: nothing to trim


def ensure_engine():
    """Register the add-on in this ``bpy`` session (once): Blender's renders then use it."""
    from . import blender_scene

    bpy = blender_scene.import_bpy()
    engines = {getattr(e, "bl_idname", None) for e in bpy.types.RenderEngine.__subclasses__()}
    if "SAMPLING_LAB" not in engines:
        from .. import register
        register()
    return bpy


def build(bpy, scene_name, size):
    """An emptied file holding the scene ``scene_name`` at ``size``: the bpy scene."""
    from . import bpy_scenes

    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    if scene_name == "glass_sphere":
        bpy_scenes.cornell_sphere(scene, bpy_scenes.glass_material("Glass"), resolution=size)
    else:
        getattr(bpy_scenes, {"cornell_point": "cornell_box_point_light",
                             "cornell_mesh": "cornell_box_mesh_light",
                             "cornell_area": "cornell_box_area_light",
                             "plane_under_sun": "plane_under_sun"}[scene_name])(
            scene, resolution=size)
    return scene


def render_once(bpy, scene_name, integrator, size, spp):
    """Build and render one job through ``bpy.ops.render.render``: seconds taken."""
    scene = build(bpy, scene_name, size)
    scene.render.engine = "SAMPLING_LAB"
    settings = scene.sampling_lab
    settings.integrator = integrator.upper()
    settings.samples = spp
    if integrator in ("photon", "sppm"):
        settings.photons = 20_000
    # Radiosity's default 0.5 m patches (992 of them) take 13 s to solve: 1 m, 276 patches.
    settings.radiosity_patch_size = 1.0
    t0 = time.perf_counter()
    bpy.ops.render.render(scene=scene.name)
    return time.perf_counter() - t0


def soak(minutes=None, rounds=None, size=(96, 72), spp=8, jobs=JOBS, progress=print):
    """Render rounds of ``jobs`` until ``minutes`` have passed or ``rounds`` are done: one
    row per render (round, scene, integrator, seconds, rss_mb, elapsed_s)."""
    bpy = ensure_engine()
    rows, t_start, r = [], time.perf_counter(), 0
    while True:
        for scene_name, integrator in jobs:
            seconds = render_once(bpy, scene_name, integrator, size, spp)
            rows.append(dict(round=r, scene=scene_name, integrator=integrator,
                             seconds=seconds, rss_mb=rss_mb(),
                             elapsed_s=time.perf_counter() - t_start))
        progress(f"round {r}: RSS {rows[-1]['rss_mb']:.1f} MB, "
                 f"{sum(x['seconds'] for x in rows if x['round'] == r):.1f} s")
        r += 1
        if rounds is not None and r >= rounds:
            break
        if minutes is not None and time.perf_counter() - t_start >= 60 * minutes:
            break
    return rows


def growth(rows):
    """RSS (median of a round) of round 1 (after the warm-up round 0), of the middle round and
    of the last, and each job's time in the last round over round 1:
    ``(first_mb, middle_mb, last_mb, ratios)``. Growth from round 1 to the middle is the
    allocator settling (glibc keeps up to 256 MB of freed blocks for reuse,
    :func:`core.render.keep_freed_memory`); growth from the middle on is what a leak shows."""
    last = max(x["round"] for x in rows)
    first = min(1, last)

    def of(r):
        return [x for x in rows if x["round"] == r]

    def mb(r):
        return statistics.median(x["rss_mb"] for x in of(r))

    ratios = {(a["scene"], a["integrator"]): b["seconds"] / a["seconds"]
              for a, b in zip(of(first), of(last))}
    return mb(first), mb((first + last) // 2), mb(last), ratios


def report(rows, minutes, size, spp, load0, load1):
    """The markdown of a soak run."""
    first_mb, middle_mb, last_mb, ratios = growth(rows)
    rounds = max(x["round"] for x in rows) + 1
    per_round = ", ".join(f"{statistics.median(x['rss_mb'] for x in rows if x['round'] == r):.0f}"
                          for r in range(rounds))
    lines = [
        "# Soak: repeated renders in one Blender session",
        "",
        f"Generated by `python -m sampling_lab bench-soak --minutes {minutes:g}` "
        f"(tools/soak.py) on {time.strftime('%Y-%m-%d %H:%M')} UTC: {len(rows)} renders in "
        f"{rows[-1]['elapsed_s'] / 60:.1f} min, {rounds} rounds of "
        f"{len({(x['scene'], x['integrator']) for x in rows})} jobs at {size[0]}x{size[1]}, "
        f"{spp} spp. Load average {load0[0]:.2f} at the start, {load1[0]:.2f} at the end.",
        "",
        f"RSS by round (MB, median): {per_round}.",
        "",
        f"Round 1 to the last: {last_mb - first_mb:+.1f} MB "
        f"({100 * (last_mb / first_mb - 1):+.2f} %); from the middle round on: "
        f"{last_mb - middle_mb:+.1f} MB ({100 * (last_mb / middle_mb - 1):+.2f} %).",
        "",
        "| scene | integrator | time, last round / round 1 |",
        "|---|---|---|",
    ]
    lines += [f"| {s} | {i} | {ratio:.2f} |" for (s, i), ratio in ratios.items()]
    return "\n".join(lines) + "\n"


def run(minutes=30.0, size=(96, 72), spp=8, output="out/bench-soak", progress=print):
    """Soak for ``minutes``, print and write ``SOAK.md`` and ``soak.csv`` into ``output``."""
    load0 = os.getloadavg()
    rows = soak(minutes=minutes, size=size, spp=spp, progress=progress)
    load1 = os.getloadavg()
    text = report(rows, minutes, size, spp, load0, load1)
    if output:
        os.makedirs(output, exist_ok=True)
        with open(os.path.join(output, "SOAK.md"), "w") as f:
            f.write(text)
        with open(os.path.join(output, "soak.csv"), "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    progress(text)
    return rows
