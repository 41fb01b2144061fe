"""Scenes with transparent surfaces, and an equal-time benchmark of path tracing, light tracing,
BDPT, photon mapping and SPPM on them (a measurement, not a test;
``python -m sampling_lab.tools.transparent``).

:func:`transparent_scene` builds a diffuse floor under a square area light (or a sun) with one
sheet: (``sheet_between_light_and_floor``) a Transparent BSDF sheet between the light and the
floor, the camera below it; (``alpha_plane``) a Principled Alpha 0.5 plane and (``leaf``) an
alpha-textured leaf (a 2 x 2 opacity checker, :mod:`core.alpha`) between the light and the
floor and in front of the camera; (``sheet_before_camera``) a Transparent BSDF sheet in front
of the camera only. ``tests/core/test_transparent_bidir.py`` checks light tracing and BDPT
against the path tracer on them, ``tests/core/test_photon_transparent.py`` photon mapping and
SPPM (biased: their relMSE below includes their blur).

The benchmark renders each case with each integrator for the same wall-clock time,
interleaved (so that a load spike hits all alike), against a path-traced reference, and prints
samples per second, relMSE and the image-mean ratio::

    PYTHONPATH=/path/to/parent python -m sampling_lab.tools.transparent --seconds 3
"""

from __future__ import annotations

import argparse

import numpy as np

from ..core import scenes
from ..core.lights import area_light, sun_light
from ..core.materials.bsdf import KIND_DIELECTRIC
from ..core.scene import Camera, Materials, Scene

CASES = ("sheet_between_light_and_floor", "alpha_plane", "leaf", "sheet_before_camera")
RHO_FLOOR = 0.5
SUN = 3.0
# Floor, sheet (mixture row), then the sheet's components: a diffuse and a transparent one.
_KINDS = dict(kinds=[0, 0, 0, KIND_DIELECTRIC], roughness=[0.5, 0.5, 0.5, 0.0],
              ior=[1.5, 1.5, 1.5, 1.0], mix_rows=[[0, 0], [2, 3], [2, 2], [3, 3]])


def _quad(z, half):
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def _sheet_materials(opacity, clear_color, textured):
    """Rows: floor, sheet (a mixture of ``opacity`` diffuse of albedo 0.8 and ``1 - opacity``
    Transparent BSDF of ``clear_color``; laid out for 0.5 and re-weighted per hit by a
    checker texture if ``textured``), the two components."""
    weights = [[1, 0], [0.5, 0.5] if textured else [opacity, 1.0 - opacity], [1, 0], [1, 0]]
    return Materials.from_lists(
        ["floor", "sheet", "sheet diffuse", "sheet clear"],
        [(RHO_FLOOR,) * 3, (1,) * 3, (0.8,) * 3, (clear_color,) * 3], np.zeros((4, 3)),
        mix_weights=weights, alpha_texture=[-1, 0 if textured else -1, -1, -1],
        alpha_invert=[False] * 4, alpha_clear=[False, False, False, True], **_KINDS)


def transparent_scene(case, light="area", size=16):
    """The floor (z = 0), the sheet of ``case`` (one of :data:`CASES`) and the light: a square
    area light of 15 W facing down (``"area"``) or a sun of ``SUN`` W/m^2 straight down."""
    fv, ff = _quad(0.0, 1.5)
    sheet_z, camera_pos = 0.5, (0.3, -0.2, 3.0)
    if case == "sheet_between_light_and_floor":
        mats, camera_pos = _sheet_materials(0.0, 0.6, False), (0.0, -1.0, 0.45)
    elif case == "alpha_plane":
        mats = _sheet_materials(0.5, 1.0, False)
    elif case == "leaf":
        mats = _sheet_materials(0.5, 1.0, True)
    elif case == "sheet_before_camera":
        mats, sheet_z = _sheet_materials(0.0, 0.6, False), 2.0
    else:
        raise ValueError(f"unknown case {case!r}: one of {', '.join(CASES)}")
    sv, sf = _quad(sheet_z, 2.0)
    corner_uvs = np.zeros((4, 3, 2), np.float32)
    corner_uvs[2:] = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)[sf]
    checker = np.array([[0.0, 0.3], [0.75, 1.0]], np.float32)[..., None]
    matrix = np.eye(4)
    matrix[:3, 3] = (0.2, 0.1, 1.0 if sheet_z < 1.0 else 0.9)
    lamp = (area_light(matrix, "SQUARE", 0.7, 0.7, (1, 1, 1), 15.0) if light == "area"
            else sun_light((0, 0, -1), (1, 1, 1), SUN))
    below = case == "sheet_between_light_and_floor"
    camera = Camera(to_world=scenes.look_at(camera_pos, (0, 0.3 if below else 0, 0),
                                            up=(0, 0, 1) if below else (0, 1, 0)),
                    width=size, height=size, lens=50.0, sensor_width=36.0, clip_start=0.1,
                    clip_end=100.0)
    return Scene(np.concatenate([fv, sv]).astype(np.float32),
                 np.concatenate([ff, sf + 4]).astype(np.int32), np.array([0, 0, 1, 1]), mats,
                 lamp, camera, textures=[checker], texture_interpolation=["Closest"],
                 corner_uvs=corner_uvs)


def _settings(**kw):
    from ..core.render import RenderSettings
    return RenderSettings(sampler="independent", light_selection="power", max_bounces=4,
                          diffuse_bounces=4, glossy_bounces=4, transmission_bounces=4,
                          transparent_max_bounces=8, **kw)


INTEGRATORS = ("path", "light", "bdpt", "photon", "sppm")


def bench(size=64, seconds=3.0, ref_spp=1024, threads=2, cases=CASES, integrators=INTEGRATORS):
    """Rows (dicts) of ``case``, ``integrator``, ``spp``, ``samples_per_s``, ``rel_mse`` and
    ``mean_ratio`` (to the reference) at equal time, the integrators interleaved per case."""
    from .common import equal_time_row, stage
    from ..core.render import render

    rows = []
    for case in cases:
        scene = transparent_scene(case, size=size)
        stage(f"{case}: path-traced reference, {ref_spp} spp")
        ref = render(scene, _settings(spp=ref_spp, seed=99, threads=threads)).film.mean()
        for integrator in integrators:
            stage(f"{case}: {integrator}, {seconds} s")
            row = equal_time_row(scene, _settings(integrator=integrator, spp=1 << 20,
                                                  time_limit=seconds, threads=threads), ref)
            rows.append(dict(case=case, integrator=integrator, **row))
    return rows


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", type=int, default=64, help="image width and height")
    p.add_argument("--seconds", type=float, default=3.0, help="time per render")
    p.add_argument("--ref-spp", type=int, default=1024, help="reference samples per pixel")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--case", action="append", choices=CASES, help="cases (default: all)")
    p.add_argument("--integrator", action="append", choices=INTEGRATORS,
                   help="integrators (default: all)")
    args = p.parse_args(argv)
    from .common import loadavg
    print(f"load average at start: {loadavg()}")
    rows = bench(args.size, args.seconds, args.ref_spp, args.threads, args.case or CASES,
                 args.integrator or INTEGRATORS)
    print("| case | integrator | spp | samples/s | relMSE | mean ratio |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['case']} | {r['integrator']} | {r['spp']} | {r['samples_per_s']:.0f} | "
              f"{r['rel_mse']:.4g} | {r['mean_ratio']:.4f} |")
    print(f"load average at end: {loadavg()}")


if __name__ == "__main__":
    main()
