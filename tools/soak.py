"""Soak: many renders in one Blender session, with memory and time per render over time.

``python -m sampling_lab bench-soak [--minutes 30] [--size 96x72] [--spp 8] [--output DIR]``

The add-on is registered in a ``bpy`` session once; then, until the time is up, each round
renders every (scene, integrator) pair of :data:`JOBS` through Blender's own render operator
(export, render, passes written back, as pressing F12 does), each built with the data API in
the same scene, emptied of the last job's data-blocks (:func:`clear`). After every render the
process's resident set size (``VmRSS``, not the peak), the C heap in use (glibc's
``mallinfo2``: what is allocated, without the free blocks a fragmented heap keeps) and the
render's wall time are recorded. The report lists RSS by round and its growth from round 1
(after a warm-up round), from round 10 and from the middle round to the last (the allocator
settles in the first rounds; a leak keeps growing), and each job's time in the last round over
round 1.

``--new-file`` builds every job in a new file instead (``read_homefile``), as the tool did
first: Blender itself then keeps about 5 kB for every file read and rendered (Cycles about
8 kB; its guarded allocator's total, ``bpy.ops.wm.memory_statistics``), which showed as a slow
creep of the soak's RSS that was neither the engine's nor the tool's data.
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


class _MallInfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        "arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks",
        "fordblks", "keepcost")]


def heap_mb():
    """Bytes of the C heap in use, in MB (glibc's ``mallinfo2``: allocated blocks, mapped and
    not; Python's small-object arenas are not in it), or NaN without glibc 2.33. A leak grows
    it; a heap that only fragments grows RSS but not this."""
    try:
        fn = ctypes.CDLL(None).mallinfo2
    except (OSError, AttributeError):
        return float("nan")
    fn.restype = _MallInfo2
    info = fn()
    return (info.uordblks + info.hblkhd) / (1 << 20)


def rss_mb():
    """Current resident set size in MB (Linux ``/proc``; elsewhere the peak, ``ru_maxrss``),
    after collecting garbage cycles and handing the allocator's free blocks back to the system
    (glibc's ``malloc_trim``):
    otherwise the up to 256 MB of freed blocks glibc keeps for reuse
    (:func:`core.allocator.keep_freed_batches`) would hide a leak until they are used up."""
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


CLEARED = ("objects", "meshes", "materials", "lights", "cameras", "worlds", "images",
           "node_groups")
"""``bpy.data`` collections :func:`clear` empties (all that :mod:`tools.bpy_scenes` makes)."""


def clear(bpy):
    """The current scene, emptied of every data-block of :data:`CLEARED` and with its Sampling
    Lab settings back to their defaults (the builders set the camera, world and resolution)."""
    data = bpy.data
    data.batch_remove([block for name in CLEARED for block in getattr(data, name)])
    scene = bpy.context.scene
    scene.property_unset("sampling_lab")
    return scene


def build(bpy, scene_name, size, new_file=False):
    """The scene ``scene_name`` at ``size``, built in the emptied current scene (or in a new
    empty file: ``new_file``): the bpy scene."""
    from . import bpy_scenes

    if new_file:
        bpy.ops.wm.read_homefile(use_empty=True)
    scene = clear(bpy)
    if scene_name == "glass_sphere":
        bpy_scenes.cornell_sphere(scene, bpy_scenes.glass_material("Glass"), resolution=size)
    else:
        getattr(bpy_scenes, {"cornell_point": "cornell_box_point_light",
                             "cornell_mesh": "cornell_box_mesh_light",
                             "cornell_area": "cornell_box_area_light",
                             "plane_under_sun": "plane_under_sun"}[scene_name])(
            scene, resolution=size)
    return scene


def render_once(bpy, scene_name, integrator, size, spp, new_file=False):
    """Build and render one job through ``bpy.ops.render.render``: seconds taken."""
    scene = build(bpy, scene_name, size, new_file)
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


def soak(minutes=None, rounds=None, size=(96, 72), spp=8, jobs=JOBS, progress=print,
         new_file=False):
    """Render rounds of ``jobs`` until ``minutes`` have passed or ``rounds`` are done: one
    row per render (round, scene, integrator, seconds, rss_mb, heap_mb, elapsed_s)."""
    bpy = ensure_engine()
    bpy.ops.wm.read_homefile(use_empty=True)
    rows, t_start, r = [], time.perf_counter(), 0
    while True:
        for scene_name, integrator in jobs:
            seconds = render_once(bpy, scene_name, integrator, size, spp, new_file)
            rows.append(dict(round=r, scene=scene_name, integrator=integrator,
                             seconds=seconds, rss_mb=rss_mb(), heap_mb=heap_mb(),
                             elapsed_s=time.perf_counter() - t_start))
        progress(f"round {r}: RSS {rows[-1]['rss_mb']:.1f} MB, "
                 f"heap {rows[-1]['heap_mb']:.1f} MB, "
                 f"{sum(x['seconds'] for x in rows if x['round'] == r):.1f} s")
        r += 1
        if rounds is not None and r >= rounds:
            break
        if minutes is not None and time.perf_counter() - t_start >= 60 * minutes:
            break
    return rows


def _round_median(rows, r, key):
    return statistics.median(x[key] for x in rows if x["round"] == r)


def growth(rows, key="rss_mb"):
    """The median of ``key`` over a round at the rounds growth is measured from, and at the
    last: ``({"round 1": mb, "round 10": mb, "middle round": mb}, last_mb)`` (rounds the run
    did not reach are left out). Round 0 is the warm-up; from round 1 to about round 10 the
    allocator settles (glibc keeps up to 256 MB of freed blocks for reuse,
    :func:`core.allocator.keep_freed_batches`); growth from then on is what a leak shows."""
    last = max(x["round"] for x in rows)
    starts = {"round 1": min(1, last), "round 10": 10, "middle round": (min(1, last) + last) // 2}
    return ({name: _round_median(rows, r, key) for name, r in starts.items() if r <= last},
            _round_median(rows, last, key))


def time_ratios(rows):
    """Each job's time in the last round over its time in round 1."""
    last = max(x["round"] for x in rows)
    of = [[x for x in rows if x["round"] == r] for r in (min(1, last), last)]
    return {(a["scene"], a["integrator"]): b["seconds"] / a["seconds"] for a, b in zip(*of)}


def _growth_line(rows, key, what):
    starts, last_mb = growth(rows, key)
    parts = [f"from {name} {last_mb - mb:+.1f} MB ({100 * (last_mb / mb - 1):+.2f} %)"
             for name, mb in starts.items()]
    return f"{what}, to the last round ({last_mb:.1f} MB): " + "; ".join(parts) + "."


def report(rows, minutes, size, spp, load0, load1, new_file=False):
    """The markdown of a soak run."""
    rounds = max(x["round"] for x in rows) + 1

    def per_round(key):
        return ", ".join(f"{_round_median(rows, r, key):.0f}" for r in range(rounds))

    lines = [
        "# Soak: repeated renders in one Blender session",
        "",
        f"Generated by `python -m sampling_lab bench-soak --minutes {minutes:g}"
        f"{' --new-file' if new_file else ''}` "
        f"(tools/soak.py) on {time.strftime('%Y-%m-%d %H:%M')} UTC: {len(rows)} renders in "
        f"{rows[-1]['elapsed_s'] / 60:.1f} min, {rounds} rounds of "
        f"{len({(x['scene'], x['integrator']) for x in rows})} jobs at {size[0]}x{size[1]}, "
        f"{spp} spp, each job built {'in a new file' if new_file else 'in the emptied scene'}. "
        f"Load average {load0[0]:.2f} at the start, {load1[0]:.2f} at the end.",
        "",
        f"RSS by round (MB, median): {per_round('rss_mb')}.",
        "",
        f"C heap in use by round (MB, median): {per_round('heap_mb')}.",
        "",
        _growth_line(rows, "rss_mb", "RSS"),
        "",
        _growth_line(rows, "heap_mb", "C heap in use"),
        "",
        "| scene | integrator | time, last round / round 1 |",
        "|---|---|---|",
    ]
    lines += [f"| {s} | {i} | {ratio:.2f} |" for (s, i), ratio in time_ratios(rows).items()]
    return "\n".join(lines) + "\n"


def run(minutes=30.0, size=(96, 72), spp=8, output="out/bench-soak", progress=print,
        new_file=False):
    """Soak for ``minutes``, print and write ``SOAK.md`` and ``soak.csv`` into ``output``."""
    load0 = os.getloadavg()
    rows = soak(minutes=minutes, size=size, spp=spp, progress=progress, new_file=new_file)
    load1 = os.getloadavg()
    text = report(rows, minutes, size, spp, load0, load1, new_file)
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
