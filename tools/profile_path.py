"""Stage profile of the path tracer on the bench Cornell box (a measurement, not a test).

Wraps the named stages of :class:`core.integrators.path.PathTracer` with exclusive timers
(a stage's time excludes the stages it calls), renders the 36-triangle Cornell box of
``python -m sampling_lab bench`` at a fixed sample count, and prints each stage's share of the
summed worker-thread CPU time (``time.thread_time``: since issue 12's second round, so that the
shares hold on a loaded machine; earlier tables used wall-clock time per thread), after the
camera samples/s and rays/s of a second, untimed render.
"Other" is what the named stages leave: the bookkeeping of ``render_samples`` itself (gathers,
compaction, throughput updates) and the render loop around it.
``--cpu-repeats N`` adds the process CPU time per sample of N one-thread renders, each run with
the part spent outside the render's worker threads (the render loop, and library helper
threads: OpenBLAS's pool, which spins on the cores after a multi-threaded call).

Run it from a checkout's parent so that ``sampling_lab`` resolves to the tree to measure::

    PYTHONPATH=/path/to/parent python tools/profile_path.py --threads 2 --spp 16

It imports the package by its absolute name (not relatively, as the CLI's tools do), so the
same file profiles an older worktree of the renderer when ``PYTHONPATH`` names that one.

``--gil-check`` asks what limits the speed-up from one thread to two: it times the same
render with one thread, with ``--threads`` threads in one process, and as ``--threads``
one-thread processes at once (their samples summed over the slowest one's time). Processes
share the cores and memory but not the GIL, the allocator or the render loop: if processes
scale much better than threads, what is shared inside the process is the limit. Each line
also gives the process CPU seconds per wall second (1 and 2 on a quiet machine: lower, the
load took the rest, and the ratios mean nothing). The scene is built once and sent to the
processes (a spawned child cannot import ``bpy``). A fourth line times the product's
worker processes (``RenderSettings(workers='processes')``, :mod:`core.workers`) through
``render()``, their CPU included; ``--integrator light`` or ``bdpt`` checks those.

Figures that hold better under load (a shared machine): ``--busy`` (how much of the time the worker
threads spend in work units), ``--counts`` (Python and C-function calls per camera sample,
and ``tracemalloc``'s peak per work unit), and ``--once`` (one render, nothing else) for
``valgrind --tool=cachegrind --D1=49152,12,64 --LL=1048576,16,64 python tools/profile_path.py
--scene bench --threads 1 --once ...`` (instructions and cache misses; subtract a 1-spp run
for the process's fixed part). ``--unit-paths N`` sets the path tracer's units.
"""

from __future__ import annotations

import argparse
import dataclasses
import multiprocessing
import os
import time

# From the script's own folder (tools/), whichever tree PYTHONPATH puts first.
from stage_timer import TOTALS as _TOTALS, patch as _patch, timed as _timed
from stage_timer import uniform_bounces as _bounces


def install_timers():
    """Wrap the stages; the names are the rows of the profile table."""
    from sampling_lab.core import accel, film, passes
    from sampling_lab.core.integrators import path
    from sampling_lab.core.lights import sampler
    from sampling_lab.core.sampling import mis, stream

    _patch(passes.Passes, "run_unit", "other (render_samples bookkeeping, render loop)")
    _patch(path, "camera_rays", "generate camera rays")
    _patch(accel.Accel, "intersect", "intersect (Embree closest hit + hit arrays)")
    _patch(path, "intersect_by_class", "intersect (Embree closest hit + hit arrays)")
    _patch(path, "_add_emitters", "emission (escaped + emitters hit, MIS)")
    _patch(path, "surface_hits", "compaction (surface hits)")
    _patch(path, "surface_interaction", "gather shading data (surface interaction)")
    _patch(path.PathTracer, "_shading", "gather shading data (surface interaction)")
    for cls in (path._LambertShading, path._BSDFShading):
        _patch(cls, "eval_pdf", "BSDF eval + pdf (NEE)")
        _patch(cls, "sample", "BSDF sample")
    _patch(sampler.LightSampler, "sample", "light sampling (select + sample_li)")
    _patch(path, "_next_event", "NEE bookkeeping + MIS + accumulation")
    _patch(accel.Accel, "shadow_rays", "shadow rays (offsets + Embree occluded)")
    _patch(accel.Accel, "occluded", "shadow rays (offsets + Embree occluded)")
    _patch(mis.MIS, "light_weight", "NEE bookkeeping + MIS + accumulation")
    _patch(path, "russian_roulette", "Russian roulette")
    _patch(accel.Accel, "offset_origin", "next rays (offset origins)")
    for attr in ("next_1d", "next_2d", "skip_to", "compact"):
        _patch(stream.SampleStream, attr, "sample stream (draws, compaction)")
    _patch(passes.Passes, "accumulate", "film accumulation")
    _patch(film.Film, "add_samples", "film accumulation")


def _scene_and_settings(args):
    from sampling_lab.core.render import RenderSettings

    scene = load_scene(args.scene, args.width, args.height)
    extra = {k: v for k, v in (("sampler", args.sampler),
                               ("light_selection", args.light_selection),
                               ("light_sampling", args.light_sampling)) if v}
    settings = RenderSettings(spp=args.spp, threads=args.threads, integrator=args.integrator,
                              workers=args.workers, **_bounces(RenderSettings, 8), seed=0,
                              **extra)
    return scene, settings


def load_scene(name, width, height):
    """The bench's Cornell box (``bench``: 36 triangles, mesh light) or a scene of
    ``bench-scenes`` (``tools.hard_scenes.SCENES``: built in ``bpy`` and exported as the add-on
    exports it, so this needs ``bpy``)."""
    if name == "bench":
        from sampling_lab.core.scenes import cornell_box

        return cornell_box(width, height, light="mesh")
    from sampling_lab.tools.hard_scenes import build_scene

    return build_scene(name, (width, height))[1]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--width", type=int, default=256)
    parser.add_argument("--height", type=int, default=256)
    parser.add_argument("--scene", default="bench",
                        help="bench (the bench's mesh-light box) or a bench-scenes scene "
                             "(cornell, glass_sphere, ...; needs bpy)")
    parser.add_argument("--no-profile", action="store_true", help="speed figures only")
    parser.add_argument("--integrator", default="path",
                        help="path (default; the stage profile knows its stages only), light "
                             "or bdpt: for the speed figures and --gil-check")
    parser.add_argument("--workers", default="threads", choices=("threads", "processes"),
                        help="where the timed render's units run (the stage profile sees "
                             "threads only); --gil-check times both")
    parser.add_argument("--sampler", help="instead of the default (e.g. independent)")
    parser.add_argument("--light-selection", help="instead of the default (e.g. power)")
    parser.add_argument("--light-sampling", help="instead of the default (e.g. solid_angle)")
    parser.add_argument("--cpu-repeats", type=int, default=0,
                        help="also print CPU microseconds per sample of N one-thread renders "
                             "(the best and each run; hardly moved by other processes' load)")
    parser.add_argument("--gil-check", action="store_true",
                        help="one thread, --threads threads, and --threads one-thread "
                             "processes at once: samples/s of each (see the module's doc)")
    parser.add_argument("--startup", action="store_true",
                        help="the worker pool's start-up and per-render shipping cost "
                             "(see startup())")
    parser.add_argument("--busy", action="store_true",
                        help="how busy the worker threads stay (see busy())")
    parser.add_argument("--counts", action="store_true",
                        help="calls and traced memory per camera sample, one thread "
                             "(see counts())")
    parser.add_argument("--once", action="store_true",
                        help="one render, no warm-up, no profile (under valgrind)")
    parser.add_argument("--unit-paths", type=int,
                        help="paths per work unit instead of the path tracer's own")
    args = parser.parse_args(argv)
    set_unit_paths(args.unit_paths)

    from sampling_lab.core.render import render

    if args.gil_check:
        gil_check(args)
        return
    if args.busy:
        busy(args)
        return
    if args.startup:
        startup(args)
        return
    if args.counts:
        counts(args)
        return
    scene, settings = _scene_and_settings(args)
    if args.once:
        res = render(scene, settings)
        print(f"one render: {res.stats['samples']} samples")
        return
    render(scene, settings)  # warm-up: imports, Embree build, table caches
    res = render(scene, settings)
    s = res.stats
    print(f"threads={args.threads} spp={args.spp}: {s['samples_per_s'] / 1e6:.3f} M samples/s, "
          f"{s['rays_per_s'] / 1e6:.3f} M rays/s, {s['time_s']:.2f} s")
    if args.cpu_repeats:
        cpu_per_sample(scene, dataclasses.replace(settings, threads=1), args.cpu_repeats)
    if args.no_profile:
        return
    install_timers()
    _TOTALS.clear()
    res = render(scene, settings)
    total = sum(_TOTALS.values())
    n = res.stats["samples"]
    print(f"stage profile (exclusive thread CPU seconds, total {total:.2f} s, "
          f"{1e6 * total / n:.3f} us per camera sample):")
    for name, sec in sorted(_TOTALS.items(), key=lambda kv: -kv[1]):
        print(f"  {100 * sec / total:5.1f} %  {sec:6.3f} s  {1e9 * sec / n:6.1f} ns/sample  {name}")


def cpu_per_sample(scene, settings, repeats):
    """Print the process CPU time per camera sample of ``repeats`` renders (the best, and each
    run), with the part spent by threads that outlive the render: the calling thread and
    library helper threads. OpenBLAS's pool spins on the cores for a while after a
    multi-threaded call, on and off, so the best run can hide it: read each run. The
    render's own workers exit with it and are not in that part (Linux only: 0 elsewhere)."""
    from sampling_lab.core.render import render

    runs = []
    for _ in range(repeats):
        before, t0 = _lasting_threads_cpu(), time.process_time()
        res = render(scene, settings)
        cpu, after = time.process_time() - t0, _lasting_threads_cpu()
        lasting = sum(after[k] - before[k] for k in after.keys() & before.keys())
        runs.append((cpu, lasting))
    us = 1e6 / res.stats["samples"]
    each = " / ".join(f"{us * cpu:.3f} ({us * lasting:.3f})" for cpu, lasting in runs)
    print(f"CPU per camera sample, {settings.threads} thread(s), best of {repeats}: "
          f"{us * min(runs)[0]:.3f} us; each run: {each} us (in brackets: outside the "
          f"render's worker threads)")


def _lasting_threads_cpu():
    """CPU seconds (user + system) of each thread of this process, by thread id."""
    out = {}
    try:
        hz, tids = os.sysconf("SC_CLK_TCK"), os.listdir("/proc/self/task")
    except (AttributeError, ValueError, OSError):
        return out  # not Linux
    for tid in tids:
        try:
            with open(f"/proc/self/task/{tid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue  # the thread ended meanwhile
        out[tid] = (int(fields[11]) + int(fields[12])) / hz
    return out


def _timed_render(scene, settings, threads, barrier=None, workers="threads"):
    """Camera samples, wall seconds and CPU seconds (this process's and its worker
    processes') of one render (after a warm-up render), started together with the other
    processes when ``barrier`` is given."""
    from sampling_lab.core.render import render

    settings = dataclasses.replace(settings, threads=threads, workers=workers)
    render(scene, settings)
    if barrier is not None:
        barrier.wait()
    w0, t0, c0 = _workers_cpu(), time.perf_counter(), time.process_time()
    res = render(scene, settings)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return res.stats["samples"], wall, cpu + _workers_cpu() - w0


def _workers_cpu():
    """CPU seconds (user + system) of this process's live worker processes (core.workers)."""
    from sampling_lab.core import workers

    hz, total = os.sysconf("SC_CLK_TCK"), 0.0
    for child in workers.pool().children:
        try:
            with open(f"/proc/{child.proc.pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += (int(fields[11]) + int(fields[12])) / hz
    return total


def set_unit_paths(paths):
    """Give the path tracer ``paths`` per work unit (None: keep its own)."""
    if paths:
        from sampling_lab.core.integrators.path import PathTracer

        PathTracer.unit_paths = paths


def _process_render(scene, settings, barrier, queue, unit_paths=None):
    set_unit_paths(unit_paths)
    try:
        queue.put(_timed_render(scene, settings, 1, barrier))
    except BaseException as exc:  # the parent must not wait for a result forever
        barrier.abort()
        queue.put(exc)
        raise


def gil_check(args, repeats=2):
    """Print samples/s and CPU use (process CPU seconds per wall second: at most the thread
    count) of one thread, of ``args.threads`` threads in one process and of ``args.threads``
    one-thread processes at once (best of ``repeats`` each, interleaved). The scene is built
    once, here, and sent to the processes (``bpy`` cannot be imported in a spawned child)."""
    n = args.threads
    scene, settings = _scene_and_settings(args)
    ctx = multiprocessing.get_context("spawn")
    labels = ("1 thread", f"{n} threads, one process", f"{n} processes of 1 thread",
              f"{n} worker processes (render)")
    best = {label: (0.0, 0.0) for label in labels}
    for _ in range(repeats):
        runs = [_timed_render(scene, settings, 1), _timed_render(scene, settings, n),
                _processes_render(ctx, scene, settings, n, args.unit_paths),
                _timed_render(scene, settings, n, workers="processes")]
        for label, (samples, wall, cpu) in zip(labels, runs):
            best[label] = max(best[label], (samples / wall, cpu / wall))
    one = best["1 thread"][0]
    for label, (sps, cores) in best.items():
        print(f"{label:>26}: {sps / 1e6:.3f} M samples/s ({sps / one:.2f} x one thread), "
              f"CPU {cores:.2f} s per wall s")


def _processes_render(ctx, scene, settings, n, unit_paths=None):
    """``(samples, wall, cpu)`` of ``n`` one-thread processes rendering at once: their samples
    and CPU summed, over the slowest one's wall time."""
    barrier, queue = ctx.Barrier(n), ctx.Queue()
    procs = [ctx.Process(target=_process_render, args=(scene, settings, barrier, queue, unit_paths))
             for _ in range(n)]
    for p in procs:
        p.start()
    out = [queue.get(timeout=600) for _ in procs]
    for p in procs:
        p.join()
    failed = [o for o in out if isinstance(o, BaseException)]
    if failed:
        raise RuntimeError(f"a render process failed: {failed[0]!r}")
    return (sum(s for s, _, _ in out), max(w for _, w, _ in out), sum(c for _, _, c in out))


def startup(args, repeats=3):
    """Print what worker processes cost besides rendering: a fresh pool's first render against
    the next ones (the children's start-up: interpreter, imports, preparing the scene), the
    seconds spent spawning them and hashing and sending the scene (``workers_start_s``,
    ``workers_ship_s``), and a render of a changed scene (shipped and prepared again)."""
    from sampling_lab.core import workers
    from sampling_lab.core.render import render

    scene, settings = _scene_and_settings(args)
    settings = dataclasses.replace(settings, workers="processes")
    other = dataclasses.replace(scene, film_transparent=not scene.film_transparent)
    for _ in range(repeats):
        workers.shutdown()
        rows = []
        for label, sc in (("fresh pool", scene), ("kept pool", scene), ("kept pool", scene),
                          ("changed scene", other)):
            t0 = time.perf_counter()
            s = render(sc, settings).stats
            rows.append(f"{label}: {time.perf_counter() - t0:.3f} s (spawn "
                        f"{1e3 * s['workers_start_s']:.1f} ms, key + send "
                        f"{1e3 * s['workers_ship_s']:.1f} ms, shipped to "
                        f"{s['workers_shipped']})")
        print(" | ".join(rows))


def busy(args):
    """Print how busy the worker threads stay: the share of ``threads x`` the wall time from
    the first unit's start to the last one's end that they spend in work units (the rest:
    waiting at a pass's end, or for the render loop to hand them a unit)."""
    from sampling_lab.core import passes as passes_mod
    from sampling_lab.core import render as render_mod

    scene, settings = _scene_and_settings(args)
    units = []
    run_unit = passes_mod.Passes.run_unit

    def timed_unit(self, unit):
        t0 = time.perf_counter()
        try:
            return run_unit(self, unit)
        finally:
            units.append((t0, time.perf_counter()))

    passes_mod.Passes.run_unit = timed_unit
    try:
        render_mod.render(scene, settings)  # warm-up
        units.clear()
        res = render_mod.render(scene, settings)
    finally:
        passes_mod.Passes.run_unit = run_unit
    n = settings.threads
    span = max(t for _, t in units) - min(t for t, _ in units)
    work = sum(t1 - t0 for t0, t1 in units)
    print(f"busy: {len(units)} units, {res.stats['samples']} samples, {span:.3f} s; workers "
          f"in units {100 * work / (n * span):.1f} % of {n} x that time, idle "
          f"{100 * (1 - work / (n * span)):.1f} %")


def counts(args):
    """Print, per camera sample of a one-thread render: Python function calls and calls of
    C functions and methods (``sys.setprofile``; NumPy's operators and ufunc calls are not
    C-function calls and are not counted: a lower bound of NumPy calls), and the peak of
    memory traced by ``tracemalloc`` (NumPy's arrays included) above what the render held
    before its first unit, per work unit."""
    import tracemalloc

    from sampling_lab.core.render import render

    scene, settings = _scene_and_settings(args)
    settings = dataclasses.replace(settings, threads=1)
    render(scene, settings)
    tally = {"call": 0, "c_call": 0}

    def profiler(frame, event, arg):
        if event in tally:
            tally[event] += 1

    threading_profile(profiler)
    try:
        res = render(scene, settings)
    finally:
        threading_profile(None)
    n = res.stats["samples"]
    print(f"per camera sample: {tally['call'] / n:.4f} Python calls, "
          f"{tally['c_call'] / n:.4f} C-function calls ({n} samples)")
    from sampling_lab.core import passes as passes_mod

    run_unit, units = passes_mod.Passes.run_unit, []
    passes_mod.Passes.run_unit = lambda self, unit: units.append(unit) or run_unit(self, unit)
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        res = render(scene, settings)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
        passes_mod.Passes.run_unit = run_unit
    paths = res.stats["samples"] / max(1, len(units))
    print(f"tracemalloc peak above the start: {peak / 2**20:.1f} MiB "
          f"(about {peak / paths:.0f} bytes per path of a {paths:.0f}-path unit)")


def threading_profile(fn):
    """``sys.setprofile`` in this thread and in threads started from now on."""
    import sys
    import threading

    sys.setprofile(fn)
    threading.setprofile(fn)


if __name__ == "__main__":
    main()
