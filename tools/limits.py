"""Limits of every integrator: cancel latency and peak memory (``bench-limits``).

``python -m sampling_lab bench-limits [--integrators ...] [--repeats 5] [--cancel-size
640x360] [--rss-size 1920x1080] [--cli] [--output DIR] [--update-docs]``

- *cancel*: the core's cancel hook, as Esc in Blender sets it (``engine.test_break()``): a
  render of the Cornell box (unlimited samples) runs on a thread; after a random 0.3 to 2 s the
  flag is set, and the time until ``render()`` returns is the latency (it includes finishing
  the work units in flight, whose samples are kept). Radiosity is cancelled inside its solve
  when the delay falls there.
- *cli*: the same through the command line: ``render`` in a child process, SIGINT after a
  random delay, time until the process has written its partial EXR and exited (code 130).
- *rss*: each integrator renders one pass of the Cornell box at ``--rss-size`` with its
  default settings, in a child process that prints its peak resident set size (``ru_maxrss``):
  what the render takes on top of the interpreter and its libraries (the child's RSS before
  rendering is printed too).

Figures are printed and written to ``LIMITS.md`` (never asserted: they depend on the machine
and its load, which the report states). ``tests/core/test_cancel.py`` checks what cancel
keeps, with a bound only a hang would break.
"""

from __future__ import annotations

import json
import os
import pty
import random
import resource
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time

from ..core import scenes
from ..core.integrators import INTEGRATORS
from ..core.render import RenderSettings, render

CANCEL_DELAY = (0.3, 2.0)


def cancel_latency(integrator, size, delay, threads=2):
    """Seconds from setting the cancel flag ``delay`` s into a render to ``render()``
    returning, and the samples per pixel it kept (finished passes)."""
    scene = scenes.cornell_box(*size)
    settings = RenderSettings(integrator=integrator, spp=1 << 20, threads=threads)
    flag = threading.Event()
    out = {}

    def work():
        out["result"] = render(scene, settings, cancel=flag.is_set)
        out["end"] = time.perf_counter()

    thread = threading.Thread(target=work, daemon=True)
    thread.start()
    time.sleep(delay)
    asked = time.perf_counter()
    flag.set()
    thread.join(600.0)
    if thread.is_alive():
        raise RuntimeError(f"{integrator}: render did not stop within 600 s of cancel")
    return out["end"] - asked, out["result"].stats["spp"]


def cli_latency(integrator, size, delay):
    """SIGINT to the CLI ``delay`` s after it started rendering: seconds until it says it was
    cancelled (the render has stopped), until it exits (the partial EXR written), the exit
    code and whether the EXR exists."""
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "partial.exr")
        cmd = [sys.executable, "-m", "sampling_lab", "render", "cornell", "--integrator",
               integrator, "--spp", str(1 << 20), "--resolution", f"{size[0]}x{size[1]}",
               "-o", path]
        # On a terminal the progress bar redraws after every work unit: its first output
        # says the render has started (and Ctrl-C is handled by then).
        master, slave = pty.openpty()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=slave)
        os.close(slave)
        os.read(master, 1)
        said = {}
        drain = threading.Thread(target=_drain, args=(master, said), daemon=True)
        drain.start()
        time.sleep(delay)
        asked = time.perf_counter()
        proc.send_signal(signal.SIGINT)
        proc.wait(600.0)
        exited = time.perf_counter() - asked
        drain.join(5.0)
        answered = said.get("cancelled", float("nan")) - asked
        return answered, exited, proc.returncode, os.path.exists(path)


def _drain(fd, said):
    """Read a terminal's output until the child closes it; note when it says 'cancelled'."""
    seen = b""
    try:
        while True:
            data = os.read(fd, 4096)
            if not data:
                break
            seen = (seen + data)[-256:]
            if b"cancelled" in seen and "cancelled" not in said:
                said["cancelled"] = time.perf_counter()
    except OSError:
        pass
    finally:
        os.close(fd)


def peak_rss(integrator, size):
    """Peak RSS in MB of a child rendering one pass at ``size``, and its RSS before."""
    code = ("import json, resource, sys; from sampling_lab.tools.limits import _child_rss; "
            f"print(json.dumps(_child_rss({integrator!r}, {tuple(size)!r})))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=3600)
    if done.returncode:
        return {"error": done.stderr.strip().splitlines()[-1]}
    return json.loads(done.stdout.strip().splitlines()[-1])


def _child_rss(integrator, size):
    """In the child: build the scene, note RSS, render one pass, return both peaks."""
    scene = scenes.cornell_box(*size)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    t0 = time.perf_counter()
    result = render(scene, RenderSettings(integrator=integrator, spp=1))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"before_mb": before, "peak_mb": peak, "seconds": time.perf_counter() - t0,
            "photon_mb": result.stats.get("photon_memory_peak_mb")}


def _ms(values):
    return f"{1e3 * statistics.median(values):.0f} / {1e3 * max(values):.0f} ms"


def _summary(values):
    values = sorted(values)
    return (f"median {1e3 * statistics.median(values):.0f} ms, "
            f"max {1e3 * values[-1]:.0f} ms")


def run(integrators=tuple(INTEGRATORS), repeats=5, cancel_size=(640, 360),
        rss_size=(1920, 1080), cli=True, rss=True, output="out/bench-limits", seed=1,
        progress=print):
    """Measure, print and write ``output/LIMITS.md``; returns the rows by integrator."""
    rng = random.Random(seed)
    load0 = os.getloadavg()
    rows = {}
    for name in integrators:
        row = rows.setdefault(name, {})
        core = [cancel_latency(name, cancel_size, rng.uniform(*CANCEL_DELAY))
                for _ in range(repeats)]
        row["cancel"] = [t for t, _ in core]
        progress(f"{name}: cancel {_summary(row['cancel'])} (kept spp: "
                 f"{[spp for _, spp in core]})")
        if cli:
            runs = [cli_latency(name, cancel_size, rng.uniform(*CANCEL_DELAY))
                    for _ in range(max(1, repeats // 2))]
            row["cli"] = [t for t, _, _, _ in runs]
            row["cli_exit"] = [t for _, t, _, _ in runs]
            row["cli_ok"] = all(code == 130 and exists for _, _, code, exists in runs)
            progress(f"{name}: CLI SIGINT: stopped {_summary(row['cli'])}; exited (EXR "
                     f"written) {_summary(row['cli_exit'])}; exit 130 and EXR: "
                     f"{row['cli_ok']}")
        if rss:
            row["rss"] = peak_rss(name, rss_size)
            progress(f"{name}: peak RSS {row['rss']}")
    load1 = os.getloadavg()
    if output:
        os.makedirs(output, exist_ok=True)
        with open(os.path.join(output, "LIMITS.md"), "w") as f:
            f.write(_report(rows, repeats, cancel_size, rss_size, load0, load1))
        progress(os.path.join(output, "LIMITS.md"))
    return rows


def _report(rows, repeats, cancel_size, rss_size, load0, load1):
    lines = [
        "# Limits: cancel latency and peak memory",
        "",
        f"Generated by `python -m sampling_lab bench-limits` (tools/limits.py) on "
        f"{time.strftime('%Y-%m-%d %H:%M')} UTC, {os.cpu_count()} cores, load average "
        f"{load0[0]:.2f} at the start and {load1[0]:.2f} at the end. Cancel: the Cornell box "
        f"at {cancel_size[0]}x{cancel_size[1]}, default settings, {repeats} cancels per "
        f"integrator at a random 0.3-2 s (median / max); CLI: SIGINT to `render`, time until it "
        f"prints that it was cancelled (the render has stopped) and until it has exited (the "
        f"partial EXR written, the interpreter closed). RSS: one pass at "
        f"{rss_size[0]}x{rss_size[1]}, default settings, each in a fresh process "
        f"(`ru_maxrss`; the interpreter with NumPy and Embree loaded is the 'before' "
        f"column).",
        "",
        "| integrator | cancel (median / max) | CLI SIGINT: stopped | CLI: exited, EXR "
        "written | peak RSS | RSS before render | render time |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, row in rows.items():
        cancel = row.get("cancel") or [float("nan")]
        cli = row.get("cli") or [float("nan")]
        cli_exit = row.get("cli_exit") or [float("nan")]
        rss = row.get("rss") or {}
        lines.append(
            f"| {name} | {_ms(cancel)} | {_ms(cli)} | {_ms(cli_exit)} | "
            f"{rss.get('peak_mb', float('nan')):.0f} MB | "
            f"{rss.get('before_mb', float('nan')):.0f} MB | "
            f"{rss.get('seconds', float('nan')):.1f} s |")
    return "\n".join(lines) + "\n"
