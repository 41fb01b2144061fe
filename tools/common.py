"""What the benchmarks share: the relMSE regulariser, CSV rows, stage logging, the machine's
description and load, image-mean ratios."""

from __future__ import annotations

import csv
import datetime
import os
import platform
import sys
import time
from importlib import metadata

import numpy as np

# relMSE regulariser (core.metrics.rel_mse's default): (img - ref)^2 / (ref^2 + EPS).
EPS = 1e-2


def write_csv(path, rows):
    keys = []
    for r in rows:
        keys += [k for k in r if k not in keys and not k.startswith("_")]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()
                        if not k.startswith("_")})


def equal_time_row(scene, settings, ref_img):
    """Render ``scene`` with ``settings`` (a time limit) against the reference image ``ref_img``:
    a row of ``spp``, ``time_s``, ``samples_per_s``, ``rel_mse`` and ``mean_ratio``."""
    from ..core.metrics import rel_mse
    from ..core.render import render

    res = render(scene, settings)
    img = res.film.mean()
    return dict(spp=res.stats["spp"], time_s=res.stats["time_s"],
                samples_per_s=res.stats["samples_per_s"], rel_mse=rel_mse(img, ref_img),
                mean_ratio=float(img.mean() / ref_img.mean()))


def mean_ratio(a, b):
    return float(np.mean(np.asarray(a)[..., :3], dtype=np.float64)
                 / np.mean(np.asarray(b)[..., :3], dtype=np.float64))


def stage(text):
    print(f"[bench {time.strftime('%H:%M:%S')}] {text} ...", file=sys.stderr, flush=True)


def loadavg():
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "n/a"


def machine_summary():
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            names = [ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")]
        cpu = names[0] if names else cpu
    except OSError:
        pass
    out = {"date": datetime.datetime.now().astimezone().isoformat(timespec="minutes"),
           "cpu": cpu, "cpus": os.cpu_count(), "python": platform.python_version(),
           "numpy": np.__version__, "load_start": loadavg(),
           "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS", "unset")}
    for package in ("embreex", "bpy"):
        try:
            out[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            out[package] = "n/a"
    return out
