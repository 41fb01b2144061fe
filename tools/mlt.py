"""Equal-time error of Metropolis light transport against path tracing, where MLT should help.

``python -m sampling_lab bench-mlt`` calls :func:`run`. The scene (:func:`gap_room`) is two
white rooms side by side, joined only by a vertical slit in the wall between them; the lamp (an
emissive quad lying on the far room's floor, facing up) is in the far room, and the camera in
the near one: every path that carries light passes the slit, which uniform camera paths rarely
find and a Markov chain, once it has found it, keeps exploring.

In one run, on the same machine state: a reference (the path tracer, two seeds of
``reference_seconds / 2`` each, averaged; a quarter of the relMSE between the two halves is the
reference's own noise, subtracted from every figure), then path tracing and MLT for the same
wall-clock ``seconds`` (MLT's bootstrap included), ``seeds`` renders each. relMSE = mean over
pixels and RGB of ``(x - ref)^2 / (ref^2 + 0.01)`` (:func:`core.metrics.rel_mse`). The table
``MLT_BENCH.md`` goes into ``output`` (default ``out/bench-mlt``) with the load average at the
start and the end. Figures only, never asserted.
"""

from __future__ import annotations

import os
import time

import numpy as np

from ..core.integrators.bounces import uniform_limits
from ..core.metrics import rel_mse
from ..core.render import RenderSettings, render
from ..core.scene import Camera, Lights, Materials, Scene
from ..core.scenes import WHITE, _Builder, _quad, look_at

GAP = 0.04  # slit width in metres (the rooms are 2 m and 1 m wide, 2 m high)


def gap_room(width=160, height=120, gap=GAP, radiance=40.0):
    """Two closed rooms joined by a vertical slit ``gap`` wide; the lamp in the far one.

    The near room spans x in [-1, 1], the far room x in [1, 2] (y in [-1, 1], z in [0, 2] for
    both); the wall at x = 1 is open for ``|y| < gap / 2``. The lamp, a 0.6 m emissive square
    of ``radiance`` (two-sided), lies 1 cm above the far room's floor. The camera stands by the
    slit's wall and looks away from it, into the near room, which only the slit lights.
    """
    b = _Builder()
    x0, x1, x2, y0, y1, z1 = -1.0, 1.0, 2.0, -1.0, 1.0, 2.0
    for xa, xb in ((x0, x1), (x1, x2)):
        b.add(*_quad((xa, y0, 0), (xb, y0, 0), (xb, y1, 0), (xa, y1, 0)), 0)     # floor
        b.add(*_quad((xa, y0, z1), (xa, y1, z1), (xb, y1, z1), (xb, y0, z1)), 0)  # ceiling
        b.add(*_quad((xa, y1, 0), (xb, y1, 0), (xb, y1, z1), (xa, y1, z1)), 0)    # back
        b.add(*_quad((xa, y0, 0), (xa, y0, z1), (xb, y0, z1), (xb, y0, 0)), 0)    # front
    b.add(*_quad((x0, y0, 0), (x0, y1, 0), (x0, y1, z1), (x0, y0, z1)), 0)        # near end
    b.add(*_quad((x2, y0, 0), (x2, y0, z1), (x2, y1, z1), (x2, y1, 0)), 0)        # far end
    h = 0.5 * gap
    b.add(*_quad((x1, y0, 0), (x1, -h, 0), (x1, -h, z1), (x1, y0, z1)), 0)        # wall with
    b.add(*_quad((x1, h, 0), (x1, y1, 0), (x1, y1, z1), (x1, h, z1)), 0)          # the slit
    s, zl = 0.3, 0.01
    b.add(*_quad((1.5 - s, -s, zl), (1.5 + s, -s, zl), (1.5 + s, s, zl), (1.5 - s, s, zl)), 1)
    v, f, m = b.arrays()
    materials = Materials.from_lists(["White", "Lamp"], [WHITE, (0, 0, 0)],
                                     [(0, 0, 0), (radiance,) * 3])
    camera = Camera(to_world=look_at((0.9, -0.9, 1.6), (-1.0, 0.6, 0.4)), width=width,
                    height=height, lens=24.0, sensor_width=36.0, clip_start=0.01,
                    clip_end=100.0)
    return Scene(v, f, m, materials, Lights.empty(), camera)


def _settings(integrator, seconds, seed, max_bounces):
    return RenderSettings(integrator=integrator, spp=0, time_limit=seconds, seed=seed,
                          sampler="independent", **uniform_limits(max_bounces))


def _reference(scene, seconds, max_bounces, progress):
    """The averaged reference image and its own noise in relMSE units."""
    halves = []
    for seed in (1001, 1002):
        res = render(scene, _settings("path", seconds / 2, seed, max_bounces))
        halves.append(res.film.mean())
        progress(f"reference half: path, {res.stats['spp']} spp, seed {seed}")
    ref = 0.5 * (halves[0] + halves[1])
    return ref, 0.25 * rel_mse(halves[0], halves[1]), halves


def run(size=(160, 120), seconds=15.0, seeds=3, reference_seconds=240.0, max_bounces=8,
        output="out/bench-mlt", progress=print):
    """Render, print and write ``output/MLT_BENCH.md`` (None: no file); returns the rows."""
    w, h = size
    scene = gap_room(w, h)
    load0 = os.getloadavg()
    ref, noise, _ = _reference(scene, reference_seconds, max_bounces, progress)
    rows = []
    for seed in range(seeds):
        for name in ("path", "mlt"):
            res = render(scene, _settings(name, seconds, seed, max_bounces))
            img = res.film.mean()
            row = dict(integrator=name, seed=seed, spp=res.stats["spp"],
                       time_s=res.stats["time_s"], samples_per_s=res.stats["samples_per_s"],
                       rel_mse=rel_mse(img, ref) - noise,
                       mean_ratio=float(img.mean() / ref.mean()),
                       b_rel_se=res.stats.get("mlt_b_rel_se", float("nan")),
                       chains=res.stats.get("mlt_chains", 0))
            rows.append(row)
            progress(f"{name} seed {seed}: {row}")
    load1 = os.getloadavg()
    summary = _summary(rows)
    if output:
        _write(output, summary, dict(size=size, seconds=seconds, seeds=seeds,
                                     reference_seconds=reference_seconds,
                                     max_bounces=max_bounces, noise=noise, load=(load0, load1)))
    return rows


def _summary(rows):
    """Per integrator: mean spp, samples/s, relMSE (mean and its standard error over seeds),
    mean ratio and b's relative standard error."""
    out = {}
    for name in ("path", "mlt"):
        mine = [r for r in rows if r["integrator"] == name]
        errs = np.array([r["rel_mse"] for r in mine])
        out[name] = dict(
            spp=float(np.mean([r["spp"] for r in mine])),
            samples_per_s=float(np.mean([r["samples_per_s"] for r in mine])),
            rel_mse=float(errs.mean()),
            rel_mse_se=float(errs.std(ddof=1) / np.sqrt(errs.size)) if errs.size > 1 else 0.0,
            mean_ratio=float(np.mean([r["mean_ratio"] for r in mine])),
            b_rel_se=float(np.mean([r["b_rel_se"] for r in mine])),
            chains=int(np.mean([r["chains"] for r in mine])))
    return out


def _write(output, summary, info):
    w, h = info["size"]
    (l0, l1) = info["load"]
    base = summary["path"]["rel_mse"]
    lines = [
        "# Metropolis light transport: equal-time error on the gap room",
        "",
        f"Generated by `python -m sampling_lab bench-mlt` (tools/mlt.py) on "
        f"{time.strftime('%Y-%m-%d %H:%M')} UTC: `gap_room` (light from the next room through "
        f"a {GAP * 100:g} cm slit), {w}x{h}, {info['max_bounces']} bounces, independent "
        f"sampler, all cores, {info['seconds']:g} s per render (MLT's bootstrap included), "
        f"{info['seeds']} seeds each; reference: path tracing, 2 x "
        f"{info['reference_seconds'] / 2:g} s, its own noise ({info['noise']:.3g} relMSE) "
        f"subtracted. Load average {l0[0]:.2f} at the start, {l1[0]:.2f} at the end.",
        "",
        "| integrator | samples (mutations) per pixel | M samples/s | relMSE (± se over seeds) "
        "| relMSE / path's | mean / ref | b rel. se | chains |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name, s in summary.items():
        lines.append(f"| {name} | {s['spp']:.0f} | {s['samples_per_s'] / 1e6:.3f} | "
                     f"{s['rel_mse']:.3g} ± {s['rel_mse_se']:.2g} | {s['rel_mse'] / base:.3g} "
                     f"| {s['mean_ratio']:.4f} | "
                     + ("n/a | n/a" if name == "path"
                        else f"{s['b_rel_se']:.3%} | {s['chains']}") + " |")
    lines.append("")
    os.makedirs(output, exist_ok=True)
    path = os.path.join(output, "MLT_BENCH.md")
    with open(path + ".tmp", "w") as f:
        f.write("\n".join(lines))
    os.replace(path + ".tmp", path)
    print(f"wrote {path}")
