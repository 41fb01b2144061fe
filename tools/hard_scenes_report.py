"""The hard-scenes benchmark's printout, montage and markdown report (:mod:`.hard_scenes`)."""

from __future__ import annotations

import math
import os

import numpy as np

from ..core.exr import write_png_preview
from .common import EPS
from .hard_scenes_reference import CHUNKS, NOISE_FLAG, flagged

# Marks a figure whose reference is too noisy to judge it.
FLAG = "(!)"


def summarise(rows):
    """One summary per scene and renderer, in the rows' order, over its repeated renders.

    Each summary has the scene, the renderer, ``renders`` (their count), the mean of every
    numeric figure of the rows (the mean error at the budget estimates the expected error at
    equal time), ``at_budget_min`` / ``at_budget_max`` (the spread) and ``at_budget_each`` (each
    render's error at the budget, in render order); ``noise_flag`` is the flag of the mean.
    """
    groups = {}
    for r in rows:
        groups.setdefault((r["scene"], r["renderer"]), []).append(r)
    out = []
    for (scene, renderer), group in groups.items():
        mean = {k: float(np.mean([g[k] for g in group])) for k, v in group[0].items()
                if isinstance(v, (int, float)) and k not in ("repeat", "seed", "noise_flag")}
        each = [g["relmse_at_budget"] for g in group]
        mean.update(scene=scene, renderer=renderer, renders=len(group), at_budget_each=each,
                    at_budget_min=min(each), at_budget_max=max(each),
                    noise_flag=int(flagged(group[0]["reference_noise"],
                                           mean["relmse_corrected"])))
        out.append(mean)
    return out


def print_scene(info, rows, seconds):
    print(f"\n{info['scene']}: our reference ({info['reference_integrator']}) "
          f"{info['pt_reference_spp']:.0f} spp "
          f"({info['pt_reference_s']:.1f} s), its noise {info['pt_reference_noise']:.2e}")
    if "reference_mean_ratio_pt_over_cycles" in info:
        print(f"   Cycles reference {info['cycles_reference_spp']} spp "
              f"({info['cycles_reference_s']:.1f} s), its noise "
              f"{info['cycles_reference_noise']:.2e}; image mean ours / Cycles = "
              f"{info['reference_mean_ratio_pt_over_cycles']:.4f} (RGB "
              f"{info['reference_channel_ratios']}); relMSE between them "
              f"{info['reference_consistency_relmse']:.2e}, noise alone "
              f"{info['reference_consistency_noise_only']:.2e}: "
              f"{_verdict(info)}")
    print(f"   reference noise {info['reference_noise']:.2e} ({FLAG}: a row whose error is "
          f"under {1 / NOISE_FLAG:.3g} x that)")
    for r in rows:
        print(f"   {r['renderer']:<8} {r['spp']:8.1f} spp {r['time_s']:6.2f} s "
              f"{r['samples_per_s'] / 1e6:7.3f} M samples/s  relMSE {r['relmse_vs_ref']:.3e} "
              f"corrected {r['relmse_corrected']:.3e}  @{seconds:g} s "
              f"{r['relmse_at_budget']:.3e}{_flag(r)}  vs Cycles ref "
              f"{r['relmse_vs_cycles_ref']:.3e}  (seed {r.get('seed', '-')})")
    for m in summarise(rows):
        if m["renders"] > 1:
            print(f"   {m['renderer']:<8} mean of {m['renders']} renders @{seconds:g} s "
                  f"{m['relmse_at_budget']:.3e}{_flag(m)} (min {m['at_budget_min']:.3e}, max "
                  f"{m['at_budget_max']:.3e})")


def _verdict(info):
    """How the reference was made, in words."""
    if info.get("references_agree"):
        return (f"they agree, reference = {info['reference_weight_ours']:.2f} x ours + "
                f"{1 - info['reference_weight_ours']:.2f} x Cycles'")
    return (f"they DISAGREE (excess {info['reference_bias_excess']:.2e} +- "
            f"{info['reference_bias_excess_se']:.1e}), reference = ours alone")


def _flag(row):
    return f" {FLAG}" if row.get("noise_flag") else ""


def write_montage(path, montage):
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


def write_report(path, image_rel, rows, scene_rows, summary, integrators, cycles, seconds,
                 command, descriptions):
    """The markdown report at ``path``; ``image_rel`` is the montage relative to it,
    ``descriptions`` each scene's one-line description."""
    means = summarise(rows)
    lines = (_header(summary, seconds, command) + _equal_time_table(means, seconds)
             + _relative_to_cycles(means, scene_rows, integrators) + _references(scene_rows)
             + _scenes(scene_rows, descriptions, integrators, cycles, seconds, image_rel))
    with open(path + ".tmp", "w") as f:
        f.write("\n".join(lines))
    os.replace(path + ".tmp", path)


def _header(summary, seconds, command):
    cmd = command or "python -m sampling_lab bench-scenes"
    return [
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
        f"Reference: our {summary['reference_integrator']} integrator ({summary['sampler']} "
        f"sampler) and Cycles, each to {summary['reference_spp_requested']} spp or "
        f"{summary['reference_seconds_cap']:g} s, each as {CHUNKS} renders with other seeds: "
        "the spread of the chunks measures each reference's noise whatever the sampler. When "
        "the two agree (their difference is what their noise explains; below), the reference "
        "is their average weighted by inverse noise, otherwise ours alone "
        "(`tools/hard_scenes_reference.py`). relMSE = mean over pixels and RGB of (x − ref)² / "
        f"(ref² + {EPS:g}). *corrected*: minus the reference's own noise, an "
        f"unbiased estimate of the error against the converged image; *@{seconds:g} s*: "
        f"corrected × (time − fixed) / ({seconds:g} s − fixed), the error at exactly the "
        "budget, where *fixed* is the part of a render that takes no samples (our scene "
        "preparation, Cycles' fixed cost of a render, measured on a 1-spp render): the column "
        "to compare; *ref noise*: the reference's noise on the same scale, and "
        f"{FLAG} where it exceeds {NOISE_FLAG:g} × the figure (too noisy a reference to judge "
        "it); *vs Cycles ref*: corrected relMSE against the Cycles reference alone (a "
        "cross-check that does not depend on ours); *mean / ref*: image mean over the "
        "reference's. On the caustic scenes (glass sphere, mirror ball) one render's error "
        "scatters by up to ten times between seeds (heavy tails: rare paths through the mirror "
        "or the glass to the lamp; docs/BENCHMARKS.md, \"Eighth round\"), so every equal-time "
        f"render is repeated *renders* times ({summary.get('repeats', '1')}; scene:renders) "
        "with seeds no reference uses, ours and Cycles alike: each line gives the *mean* of "
        "the renders' figures (the mean @ budget estimates the expected error at equal time, "
        "and the ratios to Cycles below are ratios of these means), their spread *min–max* and "
        "each render's figure (all of them are in `hard_scenes.csv`, one row per render). "
        "Even a mean of three renders of a heavy-tailed error is itself noisy: compare ratios "
        "between runs before trusting one.",
    ]


def _equal_time_table(means, seconds):
    """One line per scene and renderer (:func:`summarise`): means over its renders, the
    spread and each render's error at the budget."""
    lines = [
        "",
        "| scene | renderer | renders | spp | time s | M samples/s | relMSE | corrected | "
        f"@{seconds:g} s (mean) | min–max | each render @{seconds:g} s | ref noise | "
        "vs Cycles ref | mean / ref |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|---:|---:|---:|",
    ]
    for r in means:
        spread = (f"{_fmt(r['at_budget_min'])}–{_fmt(r['at_budget_max'])}"
                  if r["renders"] > 1 else "–")
        lines.append(
            f"| {r['scene']} | {r['renderer']} | {r['renders']} | {r['spp']:.1f} | "
            f"{r['time_s']:.2f} | {r['samples_per_s'] / 1e6:.3f} | "
            f"{_fmt(r['relmse_vs_ref'])} | {_fmt(r['relmse_corrected'])} | "
            f"**{_fmt(r['relmse_at_budget'])}**{_flag(r)} | {spread} | "
            f"{' '.join(_fmt(x) for x in r['at_budget_each'])} | "
            f"{_fmt(r.get('reference_noise'))} | {_fmt(r['relmse_vs_cycles_ref'])} | "
            f"{r['mean_over_ref']:.4f} |")
    return lines


def _relative_to_cycles(rows, scene_rows, integrators):
    lines = []
    lines += ["", "Error at equal time relative to Cycles (means over the renders @ budget, "
              "ours / Cycles; above 1: Cycles is better):", ""]
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
                parts.append(f"`{integ}` {r['relmse_at_budget'] / cy['relmse_at_budget']:.3g} ×"
                             + _flag(r) + ("" if r is cy else _flag(cy)))
            else:
                parts.append(f"`{integ}` –")
        k = max((r["renders"] for r in rows if r["scene"] == s["scene"]), default=1)
        lines.append(f"- {s['scene']}" + (f" (means of {k} renders each)" if k > 1 else "")
                     + ": " + ", ".join(parts))
    return lines


def _references(scene_rows):
    lines = []
    lines += ["", "## References and their agreement", "",
              "| scene | triangles | ours: spp | s | noise | Cycles: spp | s | noise | mean ours / "
              "Cycles (RGB) | relMSE between | noise alone | reference | its noise | "
              "load at start / end |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---|---:|---|"]
    for s in scene_rows:
        cells = [s["scene"], str(s["triangles"]), f"{s['pt_reference_spp']:.0f}",
                 f"{s['pt_reference_s']:.1f}", _fmt(s["pt_reference_noise"])]
        if "cycles_reference_s" in s:
            cells += [str(s["cycles_reference_spp"]), f"{s['cycles_reference_s']:.1f}",
                      _fmt(s["cycles_reference_noise"])]
        else:
            cells += ["–", "–", "–"]
        if "reference_mean_ratio_pt_over_cycles" in s:
            cells += [f"{s['reference_mean_ratio_pt_over_cycles']:.4f} "
                      f"({s['reference_channel_ratios']})",
                      _fmt(s["reference_consistency_relmse"]),
                      _fmt(s["reference_consistency_noise_only"]),
                      (f"{s['reference_weight_ours']:.2f} {s['reference_integrator']} + "
                       f"{1 - s['reference_weight_ours']:.2f} Cycles" if s["references_agree"]
                       else f"{s['reference_integrator']} alone (they disagree)")]
        else:
            cells += ["–", "–", "–", f"{s['reference_integrator']} alone"]
        cells += [_fmt(s["reference_noise"]), f"{s['load_start']} / {s['load_end']}"]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _scenes(scene_rows, descriptions, integrators, cycles, seconds, image_rel):
    lines = []
    lines += ["", "*noise*: each reference's noise measured from the spread of its chunks "
              "(relMSE scale). If the relMSE between the references is close to what their "
              "noise alone gives and the mean ratio is close to 1, the two renderers converge "
              "to the same image, the equal-time figures compare like with like, and the "
              "reference is the two averaged (*reference*, weights by inverse noise; *its "
              "noise*: the noise of what every render was judged against).", "",
              "## Scenes", ""]
    for s in scene_rows:
        lines.append(f"- `{s['scene']}`: {descriptions[s['scene']]}."
                     + (f" Export notes: {s['notes']}." if s["notes"] else ""))
    columns = ["our reference", "Cycles reference"] + [f"`{i}` at {seconds:g} s"
                                                        for i in integrators]
    if cycles:
        columns.append(f"Cycles at {seconds:g} s")
    lines += ["", f"![hard scenes]({image_rel})", "",
              "One row per scene, in the order of the table; columns: " + ", ".join(columns)
              + " (linear values, sRGB-encoded, no tone mapping).", ""]
    return lines
