"""Speed of light tracing and BDPT on a normal-mapped Cornell box (a measurement, not a test).

Every surface of the bench's Cornell box gets a constant normal map tilted 40 degrees, so
that every hit takes the smooth-shading stages, and on light paths the adjoint of the camera
side's choice of normal (:mod:`core.integrators.adjoint_normals`). Prints seconds per sample
of the path tracer, light tracing and BDPT, best of ``--repeats`` interleaved renders each,
so that a load spike hits all three alike, and their ratios to the path tracer; wall-clock
and process CPU time (the latter less disturbed by other processes on a loaded machine).

It imports the package by its absolute name: run it once per tree, each from its own
checkout's parent, to compare two trees on the same machine::

    PYTHONPATH=/path/to/parent python tools/bench_normal_maps.py --threads 1
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from sampling_lab.core.render import RenderSettings, render
from sampling_lab.core.scenes import cornell_box

TILT_DEG = 40.0
SPP = {"path": 8, "light": 8, "bdpt": 4}


def normal_mapped_box(size):
    """The Cornell box of ``size`` pixels with a constant 40-degree normal map on every
    material (tangent +X)."""
    box = cornell_box(size, size, "area")
    t = np.radians(TILT_DEG)
    color = 0.5 * (np.array([np.sin(t), 0.0, np.cos(t)]) + 1.0)
    rows = len(box.materials.kind)
    tangents = np.zeros((box.n_triangles, 3, 4), np.float32)
    tangents[..., 0] = tangents[..., 3] = 1.0
    materials = dataclasses.replace(box.materials, normal_texture=np.full(rows, len(box.textures),
                                                                          np.int32),
                                    normal_strength=np.ones(rows, np.float32))
    return dataclasses.replace(
        box, materials=materials,
        textures=list(box.textures) + [np.tile(color.astype(np.float32), (4, 4, 1))],
        corner_uvs=np.zeros((box.n_triangles, 3, 2), np.float32),
        texture_interpolation=None, texture_extension=None, corner_tangents=tangents)


def seconds_per_sample(scene, integrator, threads, seed):
    spp = SPP[integrator]
    settings = RenderSettings(integrator=integrator, spp=spp, max_bounces=3, seed=seed,
                              threads=threads, sampler="independent")
    start, cpu = time.perf_counter(), time.process_time()
    render(scene, settings)
    return (time.perf_counter() - start) / spp, (time.process_time() - cpu) / spp


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    scene = normal_mapped_box(args.size)
    for integrator in SPP:  # warm-up: imports, Embree scene, tables
        render(scene, RenderSettings(integrator=integrator, spp=1, max_bounces=3,
                                     threads=args.threads))
    best = {name: np.array([np.inf, np.inf]) for name in SPP}
    for r in range(args.repeats):
        for name in SPP:
            best[name] = np.minimum(best[name], seconds_per_sample(scene, name, args.threads, r))
    for name, (wall, cpu) in best.items():
        print(f"{name:6s} wall {wall * 1e3:7.1f} ms per sample ({wall / best['path'][0]:.2f} x "
              f"path), CPU {cpu * 1e3:7.1f} ms ({cpu / best['path'][1]:.2f} x path)")


if __name__ == "__main__":
    main()
