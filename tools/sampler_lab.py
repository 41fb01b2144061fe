"""The sampler lab's report: CSV files, PNG plots and a markdown table of every sampler.

``python -m sampling_lab samplers [--n 256] [--quick] [--output DIR] [--update-docs]`` (and, in a
source checkout, Blender's "Sampler Lab" operator) measures every sampler that
:func:`core.sampling.samplers.available` lists with :func:`core.sampling.lab.measure_sampler`
and writes, into one folder laid out as ``docs/`` (``DIR/SAMPLERS.md`` and ``DIR/samplers/``):

``points_<name>.csv`` / ``.png``
    The first N 2-D points of pixel 0, dimension 0, and their scatter plot.
``spectrum_<name>.csv`` / ``.png``
    The radially averaged periodogram with its standard error (frequencies also in units of
    ``sqrt(N)``, the mean point spacing's frequency).
``checkerboard.csv`` / ``.png``
    The variance of the checkerboard estimate against the sample count n.
``summary.csv``, ``points.png``, ``spectra.png`` and the markdown table (``SAMPLERS.md``)
    Per sampler the star discrepancy (pixel 0, and the mean over realizations), the
    checkerboard slope with its standard error (:func:`core.metrics.convergence_slope`), and
    the mean periodogram in the low-frequency band ``0 < |k| <= sqrt(N) / 2``.

``--update-docs`` copies the table and the five figures ``docs/SAMPLERS.md`` shows
(:data:`DOCS_FILES`) into the repository's ``docs/``; the per-sampler files stay in the output
folder. Matplotlib (Agg) draws the PNGs when it is installed; without it (Blender does not ship
it) the CSV files and the table are still written and the result says that the plots were
skipped.
"""

from __future__ import annotations

import csv
import math
import os

import numpy as np

from ..core.sampling.lab import FULL, LOW_BAND, QUICK, STAR_MAX_POINTS, measure_sampler
from ..core.sampling.samplers import available
from .outputs import add_output_arguments, publish

# What docs/ shows, relative to the output folder (and to docs/).
DOCS_FILES = ("SAMPLERS.md", "samplers/summary.csv", "samplers/checkerboard.csv",
              "samplers/points.png", "samplers/spectra.png", "samplers/checkerboard.png")


def _write_csv(path, header, rows):
    tmp = path + ".tmp"
    with open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for r in rows:
            w.writerow([_fmt(v) for v in r])
    os.replace(tmp, path)


def _fmt(v):
    if isinstance(v, float):
        return f"{v:.9g}"
    return v


def _pyplot():
    try:
        import matplotlib
    except ImportError:
        return None
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _plot_points(plt, m, path):
    fig, ax = plt.subplots(figsize=(4, 4.3))
    _draw_points(ax, m)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _draw_points(ax, m):
    p = m["points"]
    ax.scatter(p[:, 0], p[:, 1], s=max(2.0, 600.0 / m["n"]), c="k", linewidths=0)
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_aspect("equal")
    ax.set_xticks([0, 0.5, 1])
    ax.set_yticks([0, 0.5, 1])
    ax.set_title(f"{m['label']} (N={m['n']})", fontsize=9)


def _plot_spectrum(plt, m, path):
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(9, 4))
    k = m["k_max"]
    img = m["power_mean"].copy()
    img[k, k] = np.nan  # k = 0 holds N, not noise
    a0.imshow(img, origin="lower", extent=(-k - 0.5, k + 0.5, -k - 0.5, k + 0.5),
              cmap="magma", vmin=0, vmax=2.5)
    a0.set_title(f"{m['label']}: periodogram (mean)", fontsize=9)
    a0.set_xlabel("k_x")
    a0.set_ylabel("k_y")
    f = m["radius"] / math.sqrt(m["n"])
    a1.plot(f, m["radial_mean"], "k-", lw=1)
    a1.fill_between(f, m["radial_mean"] - 2 * m["radial_se"], m["radial_mean"] + 2 * m["radial_se"],
                    color="0.7", lw=0)
    a1.axhline(1.0, color="tab:red", lw=0.8, ls="--", label="white noise")
    a1.axvline(LOW_BAND, color="tab:blue", lw=0.8, ls=":", label="low band edge")
    a1.set_xlabel("|k| / sqrt(N)")
    a1.set_ylabel("radially averaged power")
    a1.set_ylim(0, max(2.5, float(np.nanmax(m["radial_mean"])) * 1.05))
    a1.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _plot_overview(plt, results, out):
    cols = min(5, len(results))
    rows = -(-len(results) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(2.6 * cols, 2.8 * rows), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, m in zip(axes.ravel(), results):
        ax.axis("on")
        _draw_points(ax, m)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "points.png"), dpi=100)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for m in results:
        ax.plot(m["radius"] / math.sqrt(m["n"]), m["radial_mean"], lw=1, label=m["label"])
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.set_xlabel("|k| / sqrt(N)")
    ax.set_ylabel("radially averaged power")
    ax.set_ylim(0, 3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "spectra.png"), dpi=100)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 5))
    for m in results:
        rs = [r for r in m["checkerboard"] if r["variance"] > 0]
        ns = np.array([r["n"] for r in rs], float)
        v = np.array([r["variance"] for r in rs])
        e = np.array([r["variance_se"] for r in rs])
        ax.errorbar(ns, v, yerr=2 * e, marker="o", ms=3, lw=1, capsize=2,
                    label=f"{m['label']} ({m['slope']:.2f})")
    ns = np.array(sorted({r["n"] for m in results for r in m["checkerboard"]}), float)
    ax.plot(ns, 0.25 / ns, "k--", lw=0.8, label="1/(4n): independent")
    ax.plot(ns, 0.25 / ns[0] ** -0.5 * ns ** -1.5, "k:", lw=0.8, label="slope -1.5")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("samples per pixel n")
    ax.set_ylabel("variance of the pixel estimate")
    ax.set_title("tilted checkerboard (I = 1/2)", fontsize=9)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "checkerboard.png"), dpi=100)
    plt.close(fig)


def _markdown(results, failures, cfg, quick, out, md_path):
    rel = os.path.relpath(out, os.path.dirname(os.path.abspath(md_path)))
    n = cfg["n"]
    lines = [
        "# Samplers measured",
        "",
        "Written by `python -m sampling_lab samplers` (`tools/sampler_lab.py`; "
        f"{'quick' if quick else 'full'} settings). N = {n} points of pixel 0, dimension 0; "
        f"star discrepancy exact (pixel 0, and mean over {cfg['star_realizations']} pixels); "
        "checkerboard: variance of the pixel estimate of the tilted checkerboard "
        f"(I = 1/2) over {cfg['pixels']} pixels for n = {', '.join(map(str, cfg['ns']))}"
        + (f" (and {', '.join(map(str, cfg['progressive_ns']))} for progressive samplers)"
           if cfg["progressive_ns"] else "")
        + ", log-log slope fitted over n >= 16 ± its standard error (independent sampling: -1; "
        "n = 4 is in the CSV and the plot: there near-regular patterns alias with the board); "
        "low-frequency "
        f"power: mean periodogram over 0 < |k| <= sqrt(N)/2 and {cfg['realizations']} pixels "
        "(white noise: 1).",
        "",
        f"| sampler | star discrepancy (N={n}) | checkerboard slope ± se "
        f"| variance × n at n={cfg['ns'][-1]} | low-frequency power |",
        "|---|---|---|---|---|",
    ]
    for m in results:
        last = [r for r in m["checkerboard"] if r["n"] == cfg["ns"][-1]]
        vn = f"{last[0]['variance'] * last[0]['n']:.3g}" if last else "-"
        slope = "-" if math.isnan(m["slope"]) else f"{m['slope']:.2f} ± {m['slope_se']:.2f}"
        lines.append(f"| {m['label']} (`{m['name']}`) | {m['star_pixel0']:.4f} "
                     f"(mean {m['star_mean']:.4f}) | {slope} | {vn} | "
                     f"{m['low_power']:.3f} ± {m['low_power_se']:.3f} |")
    for name, err in failures:
        lines.append(f"| `{name}` | failed: {err} | | | |")
    lines += [
        "",
        "Reading it: the slope's ± is the fit's scatter (`convergence_slope`); "
        "`summary.csv` also gives the error propagated from the variances alone. Samplers that "
        "serve one point set per n shifted from pixel to pixel (the blue-noise ones) show the "
        "spectrum of that set, so their low-frequency power has no spread. A blue-noise "
        "set's variance follows its residual power at the board's own frequencies "
        "(|k| of 1 to 3): Lloyd's 20 steps leave that power high for large N, so its slope "
        "flattens (see `core/sampling/samplers/lloyd.py`).",
    ]
    lines += ["", f"![points]({rel}/points.png)", "", f"![spectra]({rel}/spectra.png)", "",
              f"![checkerboard]({rel}/checkerboard.png)", ""]
    tmp = md_path + ".tmp"
    with open(tmp, "w") as f:
        f.write("\n".join(lines))
    os.replace(tmp, md_path)


def _config(n, quick):
    cfg = dict(QUICK if quick else FULL)
    if n is not None:
        if int(n) < 2:
            raise ValueError("the lab needs at least 2 points per set")
        if int(n) > STAR_MAX_POINTS:
            raise ValueError(f"at most {STAR_MAX_POINTS} points (exact star discrepancy)")
        cfg["n"] = int(n)
    return cfg


def _write_sampler(plt, m, out):
    """The per-sampler files of one measured sampler ``m``; returns their paths."""
    name, files = m["name"], []
    p = os.path.join(out, f"points_{name}.csv")
    _write_csv(p, ["i", "x", "y"], [(i, float(x), float(y)) for i, (x, y) in enumerate(m["points"])])
    files.append(p)
    p = os.path.join(out, f"spectrum_{name}.csv")
    _write_csv(p, ["k", "k_over_sqrt_n", "power", "power_se", "frequencies"],
               [(float(k), float(k / math.sqrt(m["n"])), float(v), float(e), int(c))
                for k, v, e, c in zip(m["radius"], m["radial_mean"], m["radial_se"],
                                      m["ring_count"])])
    files.append(p)
    if plt is not None:
        for kind, fn in (("points", _plot_points), ("spectrum", _plot_spectrum)):
            p = os.path.join(out, f"{kind}_{name}.png")
            fn(plt, m, p)
            files.append(p)
    return files


def _write_tables(results, out):
    """``checkerboard.csv`` and ``summary.csv`` of all samplers; returns their paths."""
    board = os.path.join(out, "checkerboard.csv")
    _write_csv(board, ["sampler", "n", "pixels", "mean", "variance", "variance_se",
                       "independent_variance"],
               [(r["sampler"], r["n"], r["pixels"], r["mean"], r["variance"], r["variance_se"],
                 r["independent_variance"]) for m in results for r in m["checkerboard"]])
    summary = os.path.join(out, "summary.csv")
    _write_csv(summary, ["sampler", "n", "star_discrepancy", "star_discrepancy_mean",
                         "star_discrepancy_se", "checkerboard_slope", "checkerboard_slope_se",
                         "checkerboard_slope_se_sampling", "low_frequency_power",
                         "low_frequency_power_se", "seconds"],
               [(m["name"], m["n"], m["star_pixel0"], m["star_mean"], m["star_se"], m["slope"],
                 m["slope_se"], m["slope_se_sampling"], m["low_power"], m["low_power_se"],
                 m["seconds"]) for m in results])
    return [board, summary]


def run(output, n=None, quick=False, markdown=None, samplers=None, seed=0, log=print):
    """Measure every available sampler and write the files listed in the module docstring.

    Parameters
    ----------
    output : str
        Folder for CSV and PNG files (created).
    n : int or None
        Points per set (default 256, or 64 with ``quick``).
    quick : bool
        Fewer realizations, pixels and sample counts (for tests and previews).
    markdown : str or None
        Path of the markdown table; default ``SAMPLERS.md`` in the output folder.
    samplers : list of str or None
        Names to measure (default: all available).
    seed : int
    log : callable(str)

    Returns
    -------
    dict
        ``results`` (per-sampler measures), ``failures`` (name, message), ``files``,
        ``plots`` (False when matplotlib is missing), ``markdown``.
    """
    cfg = _config(n, quick)
    out = os.path.abspath(output)
    os.makedirs(out, exist_ok=True)
    md_path = os.path.abspath(markdown) if markdown else os.path.join(out, "SAMPLERS.md")
    plt = _pyplot()
    if plt is None:
        log("sampler lab: matplotlib is not installed; writing CSV files and the table only")
    results, failures, files = [], [], []
    for name in list(samplers) if samplers else available():
        try:
            m = measure_sampler(name, cfg, seed=seed)
        except Exception as exc:  # one broken sampler must not hide the others' results
            failures.append((name, f"{type(exc).__name__}: {exc}"))
            log(f"sampler lab: {name}: {type(exc).__name__}: {exc}")
            continue
        results.append(m)
        log(f"sampler lab: {name}: star {m['star_pixel0']:.4f}, slope {m['slope']:.2f} ± "
            f"{m['slope_se']:.2f}, low power {m['low_power']:.3f} ({m['seconds']:.1f} s)")
        files += _write_sampler(plt, m, out)
    files += _write_tables(results, out)
    if plt is not None and results:
        _plot_overview(plt, results, out)
        files += [os.path.join(out, f) for f in ("points.png", "spectra.png", "checkerboard.png")]
    _markdown(results, failures, cfg, quick, out, md_path)
    files.append(md_path)
    return {"results": results, "failures": failures, "files": files, "plots": plt is not None,
            "markdown": md_path}


def add_arguments(parser):
    """The ``samplers`` command's arguments."""
    parser.add_argument("--n", type=int, default=None,
                        help="points per set (default: 256; 64 with --quick)")
    parser.add_argument("--quick", action="store_true",
                        help="small sizes: seconds instead of about a minute, noisier figures")
    parser.add_argument("--sampler", action="append", default=None, metavar="NAME",
                        help=f"measure only this sampler, repeatable (default: all of "
                             f"{', '.join(available())})")
    parser.add_argument("--seed", type=int, default=0, help="seed of the point sets "
                        "(default: %(default)s; docs/ shows seed 0)")
    add_output_arguments(parser, "samplers", "SAMPLERS.md and the figures it shows")
    return parser


def main(args):
    """The ``samplers`` command: ``args`` from :func:`add_arguments`; returns the exit code.
    ``ValueError`` for bad arguments (the command line turns it into a usage error)."""
    unknown = [s for s in (args.sampler or []) if s not in available()]
    if unknown:
        raise ValueError(f"unknown sampler(s) {', '.join(unknown)}; choose from "
                         f"{', '.join(available())}")
    if args.update_docs and (args.quick or args.n not in (None, FULL["n"]) or args.sampler
                             or args.seed != 0):
        raise ValueError("--update-docs needs the full run docs/ shows: no --quick, --n, "
                         "--sampler or --seed")
    res = run(output=os.path.join(args.output, "samplers"), n=args.n, quick=args.quick,
              markdown=os.path.join(args.output, "SAMPLERS.md"), samplers=args.sampler,
              seed=args.seed)
    print(f"sampler lab: wrote {len(res['files'])} files to {os.path.abspath(args.output)}")
    if args.update_docs and not res["failures"]:
        publish(args.output, DOCS_FILES)
    return 1 if res["failures"] else 0
