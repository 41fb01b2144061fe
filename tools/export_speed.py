"""Export speed: triangles per second from Blender's depsgraph to a core scene.

``python -m sampling_lab bench-export`` calls :func:`run`: a grid mesh of about ``triangles``
triangles (quads, triangulated by the exporter as Blender's loop triangles), a camera and a
lamp are built in an empty file; :func:`addon.export.export_scene` then exports the evaluated
depsgraph ``repeats`` times (a fresh depsgraph evaluation each time) and the best and median
times give triangles per second. Figures only, never asserted; ``docs/BENCHMARKS.md`` quotes
a run.
"""

from __future__ import annotations

import math
import statistics
import time

from .common import loadavg, machine_summary


def build(triangles):
    """An empty file with one grid of about ``triangles`` triangles, a camera and a sun:
    the triangle count of the grid."""
    from . import blender_scene, bpy_scenes

    bpy = blender_scene.import_bpy()
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    cuts = max(1, int(math.sqrt(triangles / 2)))
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=cuts, y_subdivisions=cuts, size=2.0)
    grid = bpy.context.active_object
    grid.data.materials.append(bpy_scenes.diffuse_material("Grey", (0.5, 0.5, 0.5)))
    bpy_scenes.add_camera(scene, (0.0, -3.0, 2.0), (0.9, 0.0, 0.0))
    bpy_scenes.add_light(scene, 'SUN', "Sun")
    return 2 * len(grid.data.polygons)


def run(triangles=1_000_000, repeats=5, progress=print):
    """Build, export ``repeats`` times and print the rates: a dict of the figures."""
    from ..addon.export import export_scene
    from . import blender_scene

    bpy = blender_scene.import_bpy()
    summary = machine_summary()
    n = build(triangles)
    times = []
    for _ in range(repeats):
        bpy.context.view_layer.update()
        t0 = time.perf_counter()
        scene = export_scene(bpy.context.evaluated_depsgraph_get())
        times.append(time.perf_counter() - t0)
    if scene.n_triangles != n:
        raise RuntimeError(f"exported {scene.n_triangles} triangles, the grid has {n}")
    out = dict(triangles=n, best_s=min(times), median_s=statistics.median(times),
               best_mtri_per_s=n / min(times) / 1e6,
               median_mtri_per_s=n / statistics.median(times) / 1e6,
               load_start=summary["load_start"], load_end=loadavg())
    progress(f"export of {n:,} triangles: best {out['best_s']:.3f} s "
             f"({out['best_mtri_per_s']:.2f} M triangles/s), median {out['median_s']:.3f} s "
             f"({out['median_mtri_per_s']:.2f} M/s) over {repeats}; load "
             f"{out['load_start']} -> {out['load_end']}")
    return out
