"""Error against time of every sampler, MIS setting and light-sampling switch on the Cornell box.

``python -m sampling_lab bench-strategies`` calls :func:`run`. For the Cornell box with its mesh
light and with its square area light (``core.scenes.cornell_box``), it renders every *setting*:

- every sampler of ``core.sampling.samplers.available()`` (path tracing, power heuristic);
- every MIS setting of ``core.sampling.mis.MIS_SETTINGS`` (independent sampler);
- the light-sampling switches: solid-angle sampling of area emitters, and alias tables for the
  discrete choices (uniform light selection is left out: with one light it is power selection);

each at a geometric series of sample counts (so samplers that want a power of two or a square
get one), timing every render by the CPU time of the process (all threads, building tables
included): on a shared machine, wall-clock time measures the neighbours' load as much as the
renderer, while CPU time measures the work done. Wall-clock times are kept in the CSV.
Each image's relMSE is measured against a reference rendered by the path tracer with the
independent sampler and the power heuristic at high spp, cached under ``output`` (delete the
``.npz`` to re-render it). The reference's own noise adds its variance to every squared error;
its Variance pass estimates that, so it is subtracted ("corrected" relMSE, an unbiased estimate
of the error against the converged image).

*Equal-time relMSE*: each setting's convergence curve (log relMSE against log time) is
interpolated, piecewise linearly in log-log and extended by its last segment, at one budget per
scene: the time the baseline (independent sampler, power heuristic) took at the largest sample
count. *Efficiency* is ``1 / (relMSE x time)`` of the largest render relative to the baseline's
(above 1: better than the baseline; for a 1/N estimator it does not depend on N).

Outputs, all in ``output`` (default ``out/bench-strategies``): ``strategies.csv`` (every
render), ``strategies_summary.csv`` (the equal-time table), the reference cache, and the
markdown report ``STRATEGIES.md`` with its log-log curves in ``images/strategies_<scene>.png``
(laid out as in ``docs/``, where ``update_docs`` copies them: :data:`DOCS_FILES`). Figures only,
never asserted; ``quick`` is a seconds-long smoke run at a tiny resolution.
"""

from __future__ import annotations

import csv
import datetime
import os
import platform
import sys
import time
import traceback

import numpy as np

from ..core.render import RenderSettings, render
from ..core.sampling.mis import MIS_SETTINGS
from ..core.sampling.samplers import available as available_samplers
from ..core.scenes import cornell_box
from .outputs import publish
from ..core.integrators.bounces import uniform_limits

# relMSE regulariser, as tools/common.py: (img - ref)^2 / (ref^2 + EPS).
EPS = 1e-2
SCENES = {"cornell_mesh": "mesh", "cornell_area": "area"}
# What docs/ shows, relative to the output folder (and to docs/).
DOCS_FILES = ("STRATEGIES.md",) + tuple(f"images/strategies_{name}.png" for name in SCENES)
FULL = dict(resolution=(128, 128), spps=(4, 16, 64), reference_spp=1024)
QUICK = dict(resolution=(32, 32), spps=(2, 8), reference_spp=64)
MAX_BOUNCES = 8
THREADS = 2
BASELINE = "sampler=independent"
# What every setting changes one option of (spelled out, so the tables keep their meaning when
# the defaults change); the reference uses it too, whose variance needs independent samples.
BASE_SETTINGS = dict(sampler="independent", light_selection="power", light_sampling="area")


def settings_list():
    """``(group, name, overrides)`` of every setting the bench renders, baseline first."""
    out = [("sampler", f"sampler={name}", dict(sampler=name)) for name in available_samplers()]
    out += [("mis", f"mis={h}", dict(mis_heuristic=h)) for h in MIS_SETTINGS if h != "power"]
    out += [("light", "light_sampling=solid_angle", dict(light_sampling="solid_angle")),
            ("light", "distribution=alias", dict(distribution="alias")),
            ("light", "solid_angle+alias", dict(light_sampling="solid_angle",
                                                distribution="alias"))]
    out.sort(key=lambda row: row[1] != BASELINE)
    return out


def reference(scene_name, light, resolution, spp, output, seed=12345):
    """Mean and per-pixel variance of the reference render, cached as ``.npz`` in ``output``."""
    w, h = resolution
    path = os.path.join(output, f"strategies_reference_{scene_name}_{w}x{h}_{spp}spp_"
                                f"b{MAX_BOUNCES}.npz")
    if os.path.isfile(path):
        data = np.load(path)
        print(f"  reference {scene_name}: cached {path}")
        return data["mean"], data["variance"]
    t0 = time.perf_counter()
    res = render(cornell_box(w, h, light), RenderSettings(spp=spp, seed=seed,
                                                          **uniform_limits(MAX_BOUNCES),
                                                          threads=THREADS, **BASE_SETTINGS))
    mean = res.combined()[..., :3].astype(np.float64)
    var = res.variance().astype(np.float64)
    tmp = path + ".tmp.npz"
    np.savez_compressed(tmp, mean=mean, variance=var)
    os.replace(tmp, path)
    print(f"  reference {scene_name}: {spp} spp in {time.perf_counter() - t0:.1f} s -> {path}")
    return mean, var


def rel_mse_corrected(img, ref, ref_var):
    """relMSE against the reference minus the reference's own noise (both (h, w, 3))."""
    err = (img - ref) ** 2 - ref_var
    return float(np.mean(err / (ref * ref + EPS))), float(np.mean((img - ref) ** 2
                                                                 / (ref * ref + EPS)))


def equal_time(times, errors, budget):
    """relMSE at ``budget`` seconds, piecewise linear in log-log through the measured points."""
    t = np.log(np.asarray(times, np.float64))
    e = np.log(np.maximum(np.asarray(errors, np.float64), 1e-300))
    order = np.argsort(t)
    t, e = t[order], e[order]
    x = np.log(budget)
    if t.size == 1:
        return float(np.exp(e[0] - (x - t[0])))  # assume 1 / time
    i = int(np.clip(np.searchsorted(t, x) - 1, 0, t.size - 2))
    slope = (e[i + 1] - e[i]) / max(t[i + 1] - t[i], 1e-12)
    return float(np.exp(e[i] + slope * (x - t[i])))


def run(quick=False, resolution=None, seconds=None, output="out/bench-strategies",
        settings=None, update_docs=False):
    """Run the strategies benchmark; print the table and write CSV, plots and the report.

    Parameters
    ----------
    quick : bool
        Tiny resolution and sample counts (a smoke run of a few seconds).
    resolution : (int, int) or None
        Override of the resolution.
    seconds : float or None
        Equal-time budget in CPU seconds; None uses the baseline's CPU time at the largest
        sample count.
    output : str
        Folder of everything written: CSV, reference cache, report and its figures.
    settings : list or None
        Subset of :func:`settings_list` (for tests).
    update_docs : bool
        Also copy the report and its figures (:data:`DOCS_FILES`) into the repository's docs/.

    Returns
    -------
    int
        Exit code: 0, or 1 if some setting failed to render (reported, the rest still runs).
    """
    cfg = dict(QUICK if quick else FULL)
    if resolution is not None:
        cfg["resolution"] = tuple(int(x) for x in resolution)
    if seconds is not None and not seconds > 0:
        print("sampling_lab bench-strategies: --seconds must be positive", file=sys.stderr)
        return 2
    os.makedirs(os.path.join(output, "images"), exist_ok=True)
    w, h = cfg["resolution"]
    rows, summary, failures = [], [], []
    todo = settings or settings_list()
    t_bench = time.perf_counter()
    print(f"Sampling Lab bench-strategies: Cornell box (mesh and area light), {w}x{h}, "
          f"{MAX_BOUNCES} bounces, {THREADS} threads, spp {list(cfg['spps'])}, reference "
          f"{cfg['reference_spp']} spp ({platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} CPUs)")
    for scene_name, light in SCENES.items():
        ref, ref_var = reference(scene_name, light, (w, h), cfg["reference_spp"], output)
        scene = cornell_box(w, h, light)
        curves = {}
        for group, name, overrides in todo:
            points = _curve(scene, scene_name, group, name, overrides, cfg, ref, ref_var, rows,
                            failures)
            if points:
                curves[(group, name)] = points
                spp, t, err = points[-1]
                print(f"  {scene_name:13s} {name:28s} {spp:4d} spp {t:7.2f} s CPU  "
                      f"relMSE {err:.3e}")
        base = curves.get(("sampler", BASELINE))
        if base is None:
            failures.append(f"{scene_name}: the baseline failed; no equal-time table")
            continue
        summary += _equal_time_rows(scene_name, curves, seconds or base[-1][1])
        _plot(scene_name, curves, os.path.join(output, "images", f"strategies_{scene_name}.png"),
              (w, h), cfg["reference_spp"])

    _write_csv(os.path.join(output, "strategies.csv"), rows)
    _write_csv(os.path.join(output, "strategies_summary.csv"), summary)
    print()
    print(_markdown_table(summary))
    report = os.path.join(output, "STRATEGIES.md")
    _write_docs(report, summary, cfg, (w, h), time.perf_counter() - t_bench)
    print(f"\nwrote {report}")
    if update_docs and not failures:
        publish(output, DOCS_FILES)
    for f in failures:
        print(f"FAILED: {f}", file=sys.stderr)
    print(f"bench-strategies: {time.perf_counter() - t_bench:.0f} s")
    return 1 if failures else 0


def _curve(scene, scene_name, group, name, overrides, cfg, ref, ref_var, rows, failures):
    """One setting rendered at every sample count: ``[(spp, cpu_s, rel_mse)]`` (empty if it
    failed: the failure is recorded and the other settings still run); rows go to ``rows``."""
    points = []
    for k, spp in enumerate(cfg["spps"]):
        try:
            cpu0 = time.process_time()
            res = render(scene, RenderSettings(spp=spp, seed=1 + k, **uniform_limits(MAX_BOUNCES),
                                               threads=THREADS,
                                               **{**BASE_SETTINGS, **overrides}))
            t = time.process_time() - cpu0
        except Exception as exc:  # noqa: BLE001 - one broken setting must not stop all
            traceback.print_exc()
            failures.append(f"{scene_name} {name}: {type(exc).__name__}: {exc}")
            return []
        s = res.stats
        err, raw = rel_mse_corrected(res.combined()[..., :3].astype(np.float64), ref, ref_var)
        points.append((spp, t, err))
        rows.append(dict(scene=scene_name, group=group, setting=name, spp=spp,
                         cpu_s=round(t, 5), wall_s=round(s["time_s"] + s["prepare_s"], 5),
                         rel_mse=err, rel_mse_raw=raw, samples_per_s=s["samples_per_s"],
                         distribution_build_ms=1e3 * s["distribution_build_s"],
                         distribution_ns_per_sample=s["distribution_ns_per_sample"]))
    return points


def _equal_time_rows(scene_name, curves, budget):
    """The equal-time table's rows of one scene: each setting at ``budget`` CPU seconds, and
    its efficiency relative to the baseline."""
    base = curves[("sampler", BASELINE)]
    base_eff = 1.0 / (base[-1][2] * base[-1][1])
    out = []
    for (group, name), points in curves.items():
        spp, t, err = points[-1]
        out.append(dict(
            scene=scene_name, group=group, setting=name,
            equal_time_rel_mse=equal_time([p[1] for p in points], [p[2] for p in points], budget),
            budget_cpu_s=round(budget, 3), spp=spp, cpu_s=round(t, 3), rel_mse=err,
            efficiency_vs_baseline=(1.0 / (err * t)) / base_eff if err > 0 else float("nan")))
    return out


def _write_csv(path, rows):
    if not rows:
        return
    tmp = path + ".tmp"
    with open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    os.replace(tmp, path)


def _plot(scene_name, curves, path, resolution, reference_spp):
    """Log-log relMSE against time, samplers on the left, MIS and light switches on the right."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("  (matplotlib is not installed: no plot)")
        return
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2), sharey=True)
    panels = {"sampler": axes[0], "mis": axes[1], "light": axes[1]}
    base = curves.get(("sampler", BASELINE))
    for (group, name), points in curves.items():
        ax = panels[group]
        t = [p[1] for p in points]
        e = [max(p[2], 1e-12) for p in points]
        style = "-" if group != "light" else "--"
        lw = 2.5 if name == BASELINE else 1.3
        ax.loglog(t, e, style, marker="o", ms=3, lw=lw, label=name.split("=")[-1]
                  if group != "light" else name)
    if base is not None:
        # The baseline on the right panel too, and a 1/time guide through it.
        t = np.array([p[1] for p in base])
        e = np.array([p[2] for p in base])
        axes[1].loglog(t, e, "k-", lw=2.5, label="power (baseline)")
        for ax in axes:
            ax.loglog(t, e[0] * t[0] / t, ":", color="gray", lw=1, label="1 / time")
    axes[0].set_title("Samplers (path tracing, power heuristic)")
    axes[1].set_title("MIS settings and light sampling (independent sampler)")
    for ax in axes:
        ax.set_xlabel("render CPU time (s, all threads)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
    axes[0].set_ylabel("relMSE (reference noise subtracted)")
    w, h = resolution
    fig.suptitle(f"{scene_name}: relMSE vs time, {w}x{h}, reference {reference_spp} spp")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _markdown_table(summary):
    lines = ["| scene | setting | equal-time relMSE | vs baseline | efficiency | spp | CPU (s) |",
             "|---|---|---:|---:|---:|---:|---:|"]
    base = {r["scene"]: r["equal_time_rel_mse"] for r in summary if r["setting"] == BASELINE}
    for r in summary:
        ratio = r["equal_time_rel_mse"] / base[r["scene"]] if r["scene"] in base else float("nan")
        lines.append(f"| {r['scene']} | {r['setting']} | {r['equal_time_rel_mse']:.3e} | "
                     f"{ratio:.2f}x | {r['efficiency_vs_baseline']:.2f} | {r['spp']} | "
                     f"{r['cpu_s']:.2f} |")
    return "\n".join(lines)


def _notes(summary):
    """Observations computed from this run's table, and what explains them."""
    by = {(r["scene"], r["setting"]): r for r in summary}
    lines = []
    for scene_name in SCENES:
        rows = [r for r in summary if r["scene"] == scene_name]
        samplers = [r for r in rows if r["group"] == "sampler" and r["setting"] != BASELINE]
        if samplers:
            best = max(samplers, key=lambda r: r["efficiency_vs_baseline"])
            worst = min(samplers, key=lambda r: r["efficiency_vs_baseline"])
            lines.append(f"- {scene_name}: the most efficient sampler is `{best['setting']}` "
                         f"({best['efficiency_vs_baseline']:.2f} x the independent sampler's "
                         f"efficiency), the least `{worst['setting']}` "
                         f"({worst['efficiency_vs_baseline']:.2f} x).")
        mis = [r for r in rows if r["group"] == "mis"]
        if mis:
            text = ", ".join(f"`{r['setting'][4:]}` {r['efficiency_vs_baseline']:.2f}"
                             for r in mis)
            lines.append(f"- {scene_name}: efficiency of the MIS settings relative to the power "
                         f"heuristic: {text}.")
        sa = by.get((scene_name, "light_sampling=solid_angle"))
        al = by.get((scene_name, "distribution=alias"))
        if sa and al:
            lines.append(f"- {scene_name}: solid-angle sampling {sa['efficiency_vs_baseline']:.2f}"
                         f", alias tables {al['efficiency_vs_baseline']:.2f} x the baseline's "
                         f"efficiency.")
    lines += [
        "",
        "What explains them:",
        "",
        "- Every setting is unbiased (`tests/core/test_strategies.py`), so the differences are "
        "variance per unit of work. Differences of ~20 % in efficiency are within the noise of "
        "one render per sample count (fireflies dominate relMSE) and of the CPU-time "
        "measurement.",
        "- `bsdf` (no light sampling) and `none` (light and BSDF samples averaged with weight "
        "1/2) are an order of magnitude worse: the lights are small, so a BSDF-sampled ray "
        "rarely finds them, and averaging keeps half of that noise. `balance`, `power`, "
        "`maximum`, `cutoff` stay close to each other: for diffuse surfaces lit by a small "
        "light, light sampling dominates every heuristic's weights.",
        "- `light` (NEE only) is fine for the one-sided area light but erratic on the mesh "
        "light: the mesh light hangs 1 mm below the ceiling and emits from both faces, and the "
        "camera sees into that gap, where the light's back face fills almost the whole "
        "hemisphere. Area-sampled NEE there has enormous variance (a heavy tail that a few "
        "hundred samples rarely reach, so its images look darker at the gap); BSDF sampling "
        "finds the light with probability ~1, which is what MIS keeps. This is the lecture's "
        "case for MIS.",
        "- Solid-angle sampling pays where lights are large or close as seen from the receiver "
        "(the gap above, and the test `test_solid_angle_sampling_has_lower_variance_near_a_"
        "large_light`, where the variance falls several times); for the box's small lights "
        "seen from afar it changes little per sample and costs more arithmetic per sample.",
        "- With one or two emitters the light choice costs microseconds either way; "
        "`strategies.csv` lists the tables' build time and ns per draw. Alias tables matter "
        "for environment maps and scenes with many lights, which this benchmark does not "
        "render.",
        "- Uniform light selection is not benchmarked here: with one light it is power "
        "selection.",
    ]
    return "\n".join(lines)


def _write_docs(docs, summary, cfg, resolution, elapsed):
    folder = os.path.dirname(os.path.abspath(docs))
    figures = [f"![{scene_name}](images/strategies_{scene_name}.png)" for scene_name in SCENES
               if os.path.isfile(os.path.join(folder, "images", f"strategies_{scene_name}.png"))]
    w, h = resolution
    text = f"""# Sampling strategies: error at equal time

Generated by `python -m sampling_lab bench-strategies` ({datetime.date.today()}, {elapsed:.0f} s,
{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, {THREADS} render threads). Times are
the process's CPU seconds (both threads, table building included): the machine may be shared,
and CPU time measures the work rather than the neighbours' load; they still carry some noise.
See `tools/strategies.py` for the method.

Scenes: the Cornell box of `core.scenes.cornell_box` with its mesh light (an emissive quad, two
triangles) and with its square area light, {w}x{h}, {MAX_BOUNCES} bounces. Every setting is
rendered at {', '.join(str(s) for s in cfg['spps'])} spp; relMSE (`(img - ref)^2 / (ref^2 + {EPS:g})`, reference
noise subtracted) is measured against a {cfg['reference_spp']}-spp path-traced reference (independent
sampler, power heuristic), cached in the output folder. *Equal-time relMSE* interpolates each
setting's log-log curve at the baseline's CPU time at {cfg['spps'][-1]} spp; *vs baseline* is its ratio
to the baseline's (below 1 is better); *efficiency* is `1 / (relMSE x CPU time)` at {cfg['spps'][-1]} spp
relative to the baseline (above 1 is better). Baseline: `sampler=independent` (power heuristic,
power light selection, area sampling, CDF).

{chr(10).join(figures)}

{_markdown_table(summary)}

## Reading the table

{_notes(summary)}
"""
    tmp = docs + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, docs)
