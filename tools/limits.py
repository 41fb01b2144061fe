"""Limits of every integrator: cancel latency and peak memory (``bench-limits``).

``python -m sampling_lab bench-limits [--integrators ...] [--repeats 5] [--cancel-size
640x360] [--rss-size 1920x1080] [--no-cli] [--no-rss] [--bvh | --bvh-sizes N ...]
[--bvh-only] [--output DIR]``

- *cancel*: the core's cancel hook, as Esc in Blender sets it (``engine.test_break()``): a
  render of the Cornell box (unlimited samples) runs on a thread; after a random 0.3 to 2 s the
  flag is set, and the time until ``render()`` returns is the latency (it includes finishing
  the work units in flight, whose samples are kept). Radiosity is cancelled inside its solve
  when the delay falls there.
- *cli*: the same through the command line: ``render`` in a child process, SIGINT after a
  random delay, time until the process has written its partial EXR and exited (code 130).
- *rss*: each integrator renders one pass of the Cornell box at ``--rss-size`` with its
  default settings, in a child process that prints its peak resident set size during the
  render (Linux: ``VmHWM``, reset just before the render; elsewhere ``ru_maxrss``) and its RSS
  before (the interpreter with NumPy, SciPy and Embree loaded, and the scene).
- *bvh* (``--bvh-sizes``, default none; ``--bvh`` for 1, 3 and 10 M triangles): in a child
  process per size, the BVH of a plane of that many triangles built through
  ``core.embree_commit`` and by embreex alone (time, and the longest time a Python thread
  could not run: Blender's interface stalls as long), then renders cancelled at a random
  moment of the build (time until ``render()`` returns, and how many the progress monitor
  stopped), and the command line: SIGINT during the build, time until it exits (code 130,
  no file written: no sample was taken).

Figures are printed and written to ``LIMITS.md`` (never asserted: they depend on the machine
and its load, which the report states). ``tests/core/test_cancel.py`` checks what cancel
keeps, with a bound only a hang would break.
"""

from __future__ import annotations

import json
import math
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
from ..core import workers as workers_mod
from ..core.applied_settings import PROCESS_INTEGRATORS
from ..core.integrators import INTEGRATORS
from ..core.render import RenderSettings, render

CANCEL_DELAY = (0.3, 2.0)


def cancel_latency(integrator, size, delay, threads=2, workers="processes"):
    """Seconds from setting the cancel flag ``delay`` s into a render to ``render()``
    returning, and the samples per pixel it kept (finished passes); ``workers`` as the
    product's final renders (processes where they apply)."""
    scene = scenes.cornell_box(*size)
    settings = RenderSettings(integrator=integrator, spp=1 << 20, threads=threads,
                              workers=workers)
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


def peak_rss(integrator, size, workers="threads"):
    """Peak RSS in MB of a child rendering one pass at ``size``, and its RSS before.

    The child reads its own high-water mark (Linux: ``VmHWM``, reset before the render
    through ``/proc/self/clear_refs``): ``ru_maxrss`` would not do, since Linux carries the
    forking process's high-water mark into the child, so every child reported at least this
    tool's own peak (541 MB after the SPPM cancels: radiosity's peak was hidden under it)."""
    code = ("import json, resource, sys; from sampling_lab.tools.limits import _child_rss; "
            f"print(json.dumps(_child_rss({integrator!r}, {tuple(size)!r}, {workers!r})))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=3600)
    if done.returncode:
        return {"error": done.stderr.strip().splitlines()[-1]}
    return json.loads(done.stdout.strip().splitlines()[-1])


def _status_mb(field, pid="self"):
    """``field`` (``'VmRSS'``, ``'VmHWM'``) of ``/proc/<pid>/status`` in MB, None elsewhere."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return None


def _reset_peak():
    """Set this process's RSS high-water mark to its current RSS (Linux 4.0+); whether it
    could."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def _peak_mb():
    hwm = _status_mb("VmHWM")
    return hwm if hwm is not None else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _child_rss(integrator, size, workers="threads"):
    """In the child: build the scene, reset the high-water mark, render one pass, return
    the RSS before and the peak during the render (``peak_source`` says how it was read);
    with worker processes (started by this render) also their peaks (``workers_mb``, each
    process's ``VmHWM``) and ``total_mb``, this process's peak plus theirs (an upper bound:
    the peaks need not coincide)."""
    import embreex.mesh_construction  # noqa: F401 - loaded before: not the render's memory
    import embreex.rtcore_scene  # noqa: F401
    import scipy.spatial  # noqa: F401

    scene = scenes.cornell_box(*size)
    reset = _reset_peak()
    before = _status_mb("VmRSS") if reset else _peak_mb()
    t0 = time.perf_counter()
    result = render(scene, RenderSettings(integrator=integrator, spp=1, workers=workers))
    peak = _peak_mb()
    children = [_status_mb("VmHWM", child.proc.pid) for child in workers_mod.pool().children]
    children = [mb for mb in children if mb is not None]
    return {"before_mb": before, "peak_mb": peak, "seconds": time.perf_counter() - t0,
            "photon_mb": result.stats.get("photon_memory_peak_mb"),
            "workers": result.stats.get("workers_text"),
            "workers_mb": children, "total_mb": peak + sum(children),
            "peak_source": "VmHWM reset before the render" if reset else "ru_maxrss"}


def _ms(values):
    return f"{1e3 * statistics.median(values):.0f} / {1e3 * max(values):.0f} ms"


def _summary(values):
    values = sorted(values)
    return (f"median {1e3 * statistics.median(values):.0f} ms, "
            f"max {1e3 * values[-1]:.0f} ms")


def run(integrators=tuple(INTEGRATORS), repeats=5, cancel_size=(640, 360),
        rss_size=(1920, 1080), cli=True, rss=True, output="out/bench-limits", seed=1,
        progress=print, bvh_sizes=()):
    """Measure, print and write ``output/LIMITS.md``; returns the rows by integrator (and
    by triangle count under ``'bvh'`` for the ``bvh_sizes`` measured)."""
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
            if name in PROCESS_INTEGRATORS:
                row["rss_processes"] = peak_rss(name, rss_size, "processes")
                progress(f"{name}: peak RSS with worker processes {row['rss_processes']}")
    bvh = bvh_rows(bvh_sizes, repeats, cli, seed, progress) if bvh_sizes else {}
    load1 = os.getloadavg()
    if output:
        os.makedirs(output, exist_ok=True)
        with open(os.path.join(output, "LIMITS.md"), "w") as f:
            f.write(_report(rows, repeats, cancel_size, rss_size, load0, load1))
            if bvh:
                f.write(_bvh_report(bvh))
        progress(os.path.join(output, "LIMITS.md"))
    if bvh:
        rows["bvh"] = bvh
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
        f"(the peak: `VmHWM`, reset just before the render; 'before': the RSS then, with "
        f"NumPy, SciPy and Embree loaded and the scene built), on threads; 'with 2 worker "
        f"processes': the same render's peak in the rendering process plus each worker "
        f"process's peak (path, light, BDPT; the default of final renders). Cancels run with "
        f"worker processes where they apply, as final renders do.",
        "",
        "| integrator | cancel (median / max) | CLI SIGINT: stopped | CLI: exited, EXR "
        "written | peak RSS | RSS before render | render time | with 2 worker processes: "
        "total (process + workers) |",
        "|---|---|---|---|---|---|---|---|",
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
            f"{rss.get('seconds', float('nan')):.1f} s | {_processes_text(row)} |")
    return "\n".join(lines) + "\n"


def _processes_text(row):
    rss = row.get("rss_processes")
    if not rss or "total_mb" not in rss:
        return "threads" if not rss else rss.get("error", "")
    workers = " + ".join(f"{mb:.0f}" for mb in rss["workers_mb"])
    return f"{rss['total_mb']:.0f} MB ({rss['peak_mb']:.0f} + {workers})"


# --- Embree's BVH build: cancel latency at 1, 3 and 10 M triangles (``--bvh``) ---

BVH_SIZES = (1_000_000, 3_000_000, 10_000_000)


class _Stalls:
    """The longest time a Python thread waking every millisecond could not run (a stand-in
    for Blender's interface, whose panels are drawn by Python) while the block runs."""

    def __enter__(self):
        self.ticks, self.running = [time.perf_counter()], True
        self.thread = threading.Thread(target=self._tick, daemon=True)
        self.thread.start()
        return self

    def _tick(self):
        while self.running:
            time.sleep(0.001)
            self.ticks.append(time.perf_counter())

    def __exit__(self, *exc):
        self.running = False
        self.thread.join()
        self.longest = max(b - a for a, b in zip(self.ticks, self.ticks[1:]))


def _child_bvh(n, repeats, seed):
    """In a child: the BVH of a plane of ``n`` triangles built through
    ``core.embree_commit`` and by embreex alone (time, longest stall of Python), then
    ``repeats`` renders cancelled at a random moment of the build."""
    import numpy as np
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    from ..core import embree_commit
    from ..core.hard_cases import many_triangles

    rng = random.Random(seed)
    scene = many_triangles(n, 8, 8)
    out = {"triangles": scene.n_triangles}
    with _Stalls() as ours:
        t0 = time.perf_counter()
        built, report = embree_commit.build_scene(scene.vertices, scene.triangles)
        out["build_s"] = time.perf_counter() - t0
    out.update(stall_s=ours.longest, monitor_calls=report.monitor_calls, method=report.method)
    del built
    with _Stalls() as theirs:
        t0 = time.perf_counter()
        ref = rtcore_scene.EmbreeScene()
        TriangleMesh(ref, scene.vertices, scene.triangles)
        ref.run(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32))
        out["embreex_build_s"] = time.perf_counter() - t0
    out["embreex_stall_s"] = theirs.longest
    del ref
    runs = [_cancel_during_build(scene, rng.uniform(0.05, 0.8) * out["build_s"])
            for _ in range(repeats)]
    # Latencies of the cancels that the monitor stopped (the others came after the build).
    out["cancel"] = [t for t, stopped in runs if stopped]
    out["cancel_after_build"] = [t for t, stopped in runs if not stopped]
    out["stopped_by_monitor"] = len(out["cancel"])
    return out


def _cancel_during_build(scene, delay):
    """Seconds from a cancel ``delay`` s into the BVH build to ``render()`` returning, and
    whether Embree's progress monitor stopped the build."""
    from ..core import accel, embree_commit

    started, reports = threading.Event(), []
    build_scene, commit = accel.build_scene, embree_commit.commit

    def starting(*args, **kw):
        started.set()
        return build_scene(*args, **kw)

    def recording(lib, handle, device, cancel=None, report=None, keep=None):
        reports.append(report or embree_commit.BuildReport("ctypes"))
        return commit(lib, handle, device, cancel, reports[-1], keep)

    accel.build_scene, embree_commit.commit = starting, recording
    try:
        flag, out = threading.Event(), {}

        def work():
            out["result"] = render(scene, RenderSettings(spp=1 << 20), cancel=flag.is_set)
            out["end"] = time.perf_counter()

        thread = threading.Thread(target=work, daemon=True)
        thread.start()
        started.wait(600.0)
        time.sleep(delay)
        asked = time.perf_counter()
        flag.set()
        thread.join(600.0)
    finally:
        accel.build_scene, embree_commit.commit = build_scene, commit
    embree_commit.wait_abandoned()  # a build left to stop by itself: its report is complete
    stopped = bool(reports) and reports[0].error == embree_commit.RTC_ERROR_CANCELLED
    return out["end"] - asked, stopped


_CLI_BVH = """
import runpy
import sys
from sampling_lab import cli
from sampling_lab.core import accel
from sampling_lab.core.hard_cases import many_triangles
cli.builtin_scenes.BUILTIN["plane"] = lambda w, h: many_triangles({n}, w, h)
build_scene = accel.build_scene
def starting(*args, **kw):
    print("BVH build started", file=sys.stderr, flush=True)
    return build_scene(*args, **kw)
accel.build_scene = starting
sys.argv = ["sampling_lab", "render", "plane", "--resolution", "8x8", "--spp", "1", "--quiet",
            "-o", {path!r}]
runpy.run_module("sampling_lab", run_name="__main__")  # as python -m sampling_lab
"""


def bvh_cli_latency(n, delay):
    """SIGINT to the command line ``delay`` s into the BVH build of ``n`` triangles: seconds
    until it has exited, its exit code and whether it wrote a file (it should not: no
    sample was taken)."""
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "never.exr")
        proc = subprocess.Popen([sys.executable, "-c", _CLI_BVH.format(n=n, path=path)],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        for line in proc.stderr:
            if "BVH build started" in line:
                break
        time.sleep(delay)
        asked = time.perf_counter()
        proc.send_signal(signal.SIGINT)
        err = proc.stderr.read()
        proc.wait(600.0)
        return time.perf_counter() - asked, proc.returncode, os.path.exists(path), err


def bvh_rows(sizes=BVH_SIZES, repeats=5, cli=True, seed=1, progress=print):
    """The BVH figures of every size, each measured in a fresh child process."""
    rng = random.Random(seed)
    rows = {}
    for n in sizes:
        code = ("import json; from sampling_lab.tools.limits import _child_bvh; "
                f"print(json.dumps(_child_bvh({n}, {repeats}, {seed})))")
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              timeout=3600)
        if done.returncode:
            rows[n] = {"error": done.stderr.strip().splitlines()[-1]}
            progress(f"BVH {n:,}: {rows[n]['error']}")
            continue
        row = rows[n] = json.loads(done.stdout.strip().splitlines()[-1])
        if cli:
            runs = [bvh_cli_latency(n, rng.uniform(0.05, 0.95) * row["build_s"])
                    for _ in range(max(1, repeats // 2))]
            row["cli_exit"] = [t for t, _, _, _ in runs]
            row["cli_ok"] = all(code == 130 and not wrote for _, code, wrote, _ in runs)
        progress(f"BVH {n:,}: {_bvh_line(row)}")
    return rows


def _bvh_line(row):
    cli = (f"; CLI SIGINT: exited {_summary(row['cli_exit'])}, exit 130 and nothing "
           f"written: {row['cli_ok']}" if "cli_exit" in row else "")
    return (f"build {row['build_s']:.2f} s ({row['method']}; embreex alone "
            f"{row['embreex_build_s']:.2f} s), longest stall of Python "
            f"{1e3 * row['stall_s']:.0f} ms (embreex alone {1e3 * row['embreex_stall_s']:.0f} "
            f"ms), cancel in the build {_summary(row['cancel'] or [math.nan])}, stopped by "
            f"the monitor {row['stopped_by_monitor']} of {_tries(row)}{cli}")


def _tries(row):
    return len(row["cancel"]) + len(row["cancel_after_build"])


def _bvh_report(rows):
    lines = ["", "| triangles | BVH build: ours / embreex alone | longest stall of Python: "
             "ours / embreex alone | cancel in the build (median / max) | stopped by the "
             "monitor | CLI SIGINT: exited | exit 130, nothing written |",
             "|---|---|---|---|---|---|---|"]
    for n, row in rows.items():
        if "error" in row:
            lines.append(f"| {n:,} | {row['error']} | | | | | |")
            continue
        cli = row.get("cli_exit")
        lines.append(
            f"| {row['triangles']:,} | {row['build_s']:.2f} / {row['embreex_build_s']:.2f} s "
            f"| {1e3 * row['stall_s']:.0f} / {1e3 * row['embreex_stall_s']:.0f} ms | "
            f"{_ms(row['cancel'] or [math.nan])} | {row['stopped_by_monitor']} of "
            f"{_tries(row)} | "
            f"{_ms(cli) if cli else '-'} | {row.get('cli_ok', '-')} |")
    return "\n".join(lines) + "\n"
