"""Speed against error on the Cornell box: raw embreex, our path tracer and Cycles in one run.

``python -m sampling_lab bench`` calls :func:`run`. On the Cornell box (mesh light, 8 bounces) it
measures, in this order and in one process:

1. *The ceiling*: raw embreex closest-hit throughput (``EmbreeScene.run(..., output=1)``) on the
   same triangles, for incoherent rays (origins uniform in the box, directions uniform on the
   sphere), with 1 and 2 threads each tracing a disjoint part of one batch. Best of 3, repeats
   interleaved so that a load spike on the machine hits both thread counts alike.
2. *Our path tracer* at a fixed sample count: rays/s and camera samples/s from its own stats, and
   its rays/s as a fraction of the 2-thread ceiling.
3. *Cycles* on the same scene (:mod:`.blender_scene`), same ``bpy`` process, CPU, 2 threads: a
   cold 1-spp render (kernel loading), warm 1-spp renders (the fixed cost of every render:
   sync, BVH, film, EXR), and the fixed sample count. Camera samples/s gross
   (``w * h * spp / wall time``) and net of the fixed cost (the marginal rate). Steps 2 and 3
   run interleaved, twice, and keep the faster run: the machine may be shared.
4. *Error at equal time*: both renderers get ``seconds`` of wall clock. Ours through its time
   limit; Cycles at the sample count its measured rate fits into that time, fixed cost
   included (a time-limited Cycles render does not report how many samples it took), planned
   again once if the render misses the budget by more than 15 %. Their relMSE is measured
   against a reference rendered by our path tracer with another seed, and against a Cycles
   reference at the same sample count. Reference noise adds to any relMSE measured against
   it; our reference carries its per-pixel variance, so that part is subtracted ("corrected",
   an unbiased estimate of the error against the converged image), and the corrected error
   is scaled by ``time / seconds`` to the exact budget (error ~ 1 / time for unbiased
   estimators). The two references are compared with each other against what their noise
   alone would give: a consistency check of the renderers, not only of the bench.
   Then *light tracing and BDPT* at fixed sample counts (``BIDIR_SPP``), each round
   interleaved with a path-tracer render, best of two rounds: their camera samples/s and
   their ratio to our path tracer's in the same rounds, and each round's own ratio (the
   spread that the machine's drift puts on the best-of-two figure).
5. The targets (issue 12's): our samples/s >= 1.0 x Cycles' net samples/s, light tracing
   >= 0.5 x and BDPT >= 0.3 x our path tracer's samples/s, our equal-time relMSE <= 1.0 x
   Cycles'; our rays/s as a fraction of raw embreex (2 threads), 0.35 x expected at that
   sample rate. Reported as figures, never asserted.

Everything printed is also written to ``output/`` as CSV, with a PNG of the four images.
"""

from __future__ import annotations

import os
import statistics
import sys
import threading
import time
import traceback

import numpy as np

from ..core.exr import write_png_preview
from ..core.metrics import rel_mse
from ..core.render import RenderSettings, render
from ..core.scenes import cornell_box
from .common import EPS, loadavg, machine_summary, mean_ratio, stage, write_csv
from .cycles_runner import CyclesRunner
from ..core.integrators.bounces import uniform_limits

# Rays in the raw embreex batch, and how often each thread count is timed (best is kept).
EMBREE_RAYS = 1 << 21
EMBREE_REPEATS = 3
# The fixed-sample-count runs that measure throughput.
FIXED_SPP = 16
# Our reference gets reference_spp samples or this much time, whichever comes first (at least
# REFERENCE_MIN_SECONDS, else REFERENCE_TIME_FACTOR x the equal-time budget).
REFERENCE_MIN_SECONDS = 60.0
REFERENCE_TIME_FACTOR = 6.0
# Targets: our camera samples/s over Cycles' net rate, our equal-time relMSE over Cycles', and
# the rays/s over raw embreex's that those samples/s were expected to need.
SAMPLES_TARGET = 1.0
ERROR_TARGET = 1.0
RAYS_EXPECTED = 0.35
# Light tracing and BDPT: samples per pixel of their fixed-count runs, and their targets as
# fractions of our path tracer's camera samples/s on the same scene.
BIDIR_SPP = {"light": 8, "bdpt": 4}
BIDIR_TARGETS = {"light": 0.5, "bdpt": 0.3}


def run(resolution=(256, 256), seconds=10.0, reference_spp=1024, cycles=True,
        output="out/bench", *, reference_seconds=None, threads=2, max_bounces=8, seed=0,
        workers="processes"):
    """Run the Cornell box benchmark, print its figures and write them to ``output``.

    Parameters
    ----------
    resolution : (int, int)
        Width and height in pixels.
    seconds : float
        Equal-time budget per renderer.
    reference_spp : int
        Samples per pixel of the references (a cap: see ``reference_seconds``).
    cycles : bool
        Include Cycles (imports ``bpy``).
    output : str
        Folder for ``cornell_*.csv`` and ``cornell_images.png`` (created).
    reference_seconds : float or None
        Time cap of our reference render; None picks ``max(60, 6 * seconds)``, 0 removes the
        cap (a 1024-spp reference at 256 x 256 then takes several minutes). The Cycles
        reference uses the sample count our reference reached.
    threads, max_bounces, seed : int
    workers : str
        Where our renders' work units run (``RenderSettings.workers``): the product's default,
        processes, or threads.

    Returns
    -------
    int
        Exit code: 0, 1 if Cycles was asked for and failed, 2 for bad arguments.
    """
    width, height = (int(x) for x in resolution)
    if width < 1 or height < 1 or not seconds > 0 or reference_spp < 1:
        print("sampling_lab bench: resolution, --seconds and --reference-spp must be positive",
              file=sys.stderr)
        return 2
    if reference_seconds is None:
        reference_seconds = max(REFERENCE_MIN_SECONDS, REFERENCE_TIME_FACTOR * seconds)
    os.makedirs(output, exist_ok=True)
    t_bench = time.perf_counter()
    bench = _Bench(cornell_box(width, height, light="mesh"), seconds, reference_spp,
                   reference_seconds, threads, max_bounces, seed)
    bench.workers = workers
    bench.summary.update(resolution=f"{width}x{height}", max_bounces=max_bounces,
                         threads=threads, workers=workers, equal_time_s=seconds,
                         reference_spp_requested=reference_spp,
                         reference_seconds_cap=reference_seconds,
                         triangles=bench.scene.n_triangles)
    print(f"Sampling Lab bench: Cornell box (mesh light), {width}x{height}, {max_bounces} bounces, "
          f"{threads} cores (ours on {'worker processes' if workers == 'processes' else 'threads'}, "
          f"Cycles on threads)\nmachine: {bench.summary['cpu']}, {bench.summary['cpus']} CPUs, "
          f"load average at start {bench.summary['load_start']}; {bench.summary['date']}")
    ceiling = bench.ceiling()
    bench.fixed_spp(cycles)
    bench.bidirectional()
    bench.equal_time_and_references()
    bench.errors()
    print()
    _print_table(bench.rows, seconds)
    bench.targets(ceiling[threads]["rays_per_s"])
    bench.summary.update(load_end=loadavg(), bench_seconds=time.perf_counter() - t_bench)
    write_csv(os.path.join(output, "cornell_embree.csv"),
              [dict(threads=k, **v) for k, v in ceiling.items()])
    write_csv(os.path.join(output, "cornell_renderers.csv"), bench.rows)
    write_csv(os.path.join(output, "cornell_summary.csv"),
              [{"key": k, "value": v} for k, v in bench.summary.items()])
    _write_montage(os.path.join(output, "cornell_images.png"), bench.images)
    print(f"\nwrote {output}/cornell_{{embree,renderers,summary}}.csv and cornell_images.png "
          f"(top: PT ref | Cycles ref; bottom: equal time PT | Cycles); bench took "
          f"{bench.summary['bench_seconds']:.0f} s, load average at end "
          f"{bench.summary['load_end']}")
    return bench.status


class _Bench:
    """One run of the benchmark: its scene and settings, the rows, the summary, the Cycles
    runner; one method per step of the module docstring."""

    def __init__(self, scene, seconds, reference_spp, reference_seconds, threads, max_bounces,
                 seed):
        self.scene, self.seconds, self.seed = scene, seconds, seed
        self.reference_spp, self.reference_seconds = reference_spp, reference_seconds
        self.threads, self.max_bounces = threads, max_bounces
        self.workers = "processes"
        self.pixels = scene.camera.width * scene.camera.height
        self.summary = machine_summary()
        self.rows, self.status, self.cy = [], 0, None

    def settings(self, **kw):
        return RenderSettings(**{**dict(seed=self.seed, **uniform_limits(self.max_bounces),
                                        threads=self.threads, workers=self.workers), **kw})

    def ceiling(self):
        """1. Raw embreex on the same triangles: rates by thread count."""
        stage("raw embreex throughput")
        ceiling = embree_throughput(self.scene, EMBREE_RAYS,
                                    (1, self.threads) if self.threads > 1 else (1,),
                                    EMBREE_REPEATS, self.seed)
        print("\n1. Raw embreex closest-hit throughput (incoherent rays, best of "
              f"{EMBREE_REPEATS}, {EMBREE_RAYS} rays)")
        for k, row in ceiling.items():
            print(f"   {k} thread{'s' if k > 1 else ' '}: {row['rays_per_s'] / 1e6:7.2f} M rays/s "
                  f"(median {row['rays'] / row['median_s'] / 1e6:.2f}; hit fraction "
                  f"{row['hit_fraction']:.3f})")
        self.ceiling_rps = ceiling[self.threads]["rays_per_s"]
        return ceiling

    def fixed_spp(self, cycles):
        """2 and 3. Throughput at a fixed sample count, ours and Cycles interleaved, best of
        two: the machine may be shared, and a load spike should not decide the comparison."""
        fixed = self.settings(spp=FIXED_SPP)
        stage(f"our path tracer, {FIXED_SPP} spp")
        ours = render(self.scene, fixed)
        if cycles:
            stage(f"Cycles: kernel loading, fixed cost, {FIXED_SPP} spp")
            try:
                self.cy = CyclesRunner(self.scene, self.threads, self.max_bounces)
                self.cy.measure_fixed_cost(self.seed)
                self.cy.measure_fixed_spp(FIXED_SPP, self.seed)
            except Exception:  # noqa: BLE001 - report and carry on with the other figures
                traceback.print_exc()
                print("\nCycles failed (traceback above); continuing without it")
                self.cy, self.status = None, 1
        stage(f"our path tracer, {FIXED_SPP} spp, again")
        again = render(self.scene, fixed)
        if again.stats["time_s"] < ours.stats["time_s"]:
            ours = again
        if self.cy is not None:
            stage(f"Cycles, {FIXED_SPP} spp, again")
            self.cy.measure_fixed_spp(FIXED_SPP, self.seed)
        self.rows.append(_ours_row("fixed spp", ours, self.pixels))
        self.ours_rps, self.ours_sps = ours.stats["rays_per_s"], ours.stats["samples_per_s"]
        print(f"\n2. Our path tracer, {FIXED_SPP} spp, {self.threads} threads (best of 2)")
        print(f"   {self.ours_sps / 1e6:.3f} M samples/s, {self.ours_rps / 1e6:.2f} M rays/s "
              f"({ours.stats['rays'] / max(ours.stats['samples'], 1):.2f} rays per "
              f"sample), {ours.stats['time_s']:.2f} s")
        print(f"   = {self.ours_rps / self.ceiling_rps:.3f} x raw embreex ({self.threads} threads)")
        if self.cy is not None:
            self._print_cycles_fixed(ours)

    def bidirectional(self):
        """2b. Light tracing and BDPT against our path tracer, interleaved, best of two."""
        best, rounds = {}, []
        for round_ in range(2):
            rounds.append({})
            for name in ("path", *BIDIR_SPP):
                stage(f"{name}, {BIDIR_SPP.get(name, FIXED_SPP)} spp, round {round_ + 1} of 2")
                res = render(self.scene, self.settings(integrator=name,
                                                       spp=BIDIR_SPP.get(name, FIXED_SPP)))
                rounds[-1][name] = res.stats["samples_per_s"]
                if name not in best or res.stats["time_s"] < best[name].stats["time_s"]:
                    best[name] = res
        path_sps = best["path"].stats["samples_per_s"]
        print(f"\n2b. Light tracing and BDPT, {self.threads} threads (best of 2, each round "
              f"interleaved with a {FIXED_SPP}-spp path-tracer render: "
              f"{path_sps / 1e6:.3f} M samples/s)")
        self.bidir_ratios = {}
        for name in BIDIR_SPP:
            stats = best[name].stats
            ratio = stats["samples_per_s"] / max(path_sps, 1e-300)
            self.bidir_ratios[name] = ratio
            # Each round's ratio to its own path-tracer render: the spread a load change or
            # the machine's drift puts on the best-of-two figure.
            per_round = [r[name] / max(r["path"], 1e-300) for r in rounds]
            print(f"   {name:<6} {stats['samples_per_s'] / 1e6:.4f} M samples/s, "
                  f"{stats['rays_per_s'] / 1e6:.2f} M rays/s, {stats['time_s']:.2f} s "
                  f"= {ratio:.3f} x our path tracer (rounds: "
                  f"{', '.join(f'{x:.3f}' for x in per_round)})")
            self.summary[f"{name}_over_path_samples_rounds"] = per_round
            row = _ours_row("fixed spp", best[name], self.pixels)
            row["renderer"] = f"ours {name}"
            self.rows.append(row)
            self.summary[f"{name}_samples_per_s"] = stats["samples_per_s"]
            self.summary[f"{name}_over_path_samples"] = ratio
        self.summary["path_samples_per_s_interleaved"] = path_sps

    def _print_cycles_fixed(self, ours):
        cy = self.cy
        self.rows.append(_cycles_row("fixed spp", FIXED_SPP, cy.t_fixed, self.pixels,
                                     cy.fixed_image))
        print(f"\n3. Cycles (bpy {self.summary.get('bpy', '')}), CPU, {self.threads} threads, "
              f"{FIXED_SPP} spp (best of 2)")
        print(f"   first render in the process (1 spp, kernel loading): {cy.t_cold:.2f} s; "
              f"fixed cost of a render (1 spp, best of 2): {cy.t_one:.2f} s")
        print(f"   {cy.gross_sps / 1e6:.3f} M samples/s gross ({cy.t_fixed:.2f} s wall), "
              f"{cy.net_sps / 1e6:.3f} M net of the fixed cost, "
              f"{cy.clock_sps / 1e6:.3f} M by Cycles' own render-time clock")
        ratio = mean_ratio(ours.combined(), cy.fixed_image)
        print(f"   image mean, ours / Cycles at {FIXED_SPP} spp: {ratio:.4f}")
        self.summary.update(cycles_cold_s=cy.t_cold, cycles_fixed_cost_s=cy.t_one,
                            cycles_gross_samples_per_s=cy.gross_sps,
                            cycles_net_samples_per_s=cy.net_sps,
                            cycles_clock_samples_per_s=cy.clock_sps,
                            mean_ratio_ours_over_cycles_fixed_spp=ratio)

    def equal_time_and_references(self):
        """4. Equal time, then the references (longest last)."""
        stage(f"equal time, {self.seconds:g} s each")
        ours_eq = render(self.scene, self.settings(spp=0, time_limit=self.seconds))
        self.rows.append(_ours_row("equal time", ours_eq, self.pixels))
        img_cy_eq = None
        if self.cy is not None:
            spp_eq, t_eq, img_cy_eq = self.cy.equal_time(self.seconds, self.seed)
            self.rows.append(_cycles_row("equal time", spp_eq, t_eq, self.pixels, img_cy_eq))
        stage(f"our reference: {self.reference_spp} spp or {self.reference_seconds:g} s")
        # Independent samples: the reference's variance is its noise floor.
        self.ours_ref = render(self.scene, self.settings(
            spp=self.reference_spp, time_limit=self.reference_seconds, seed=self.seed + 1,
            sampler="independent"))
        self.rows.append(_ours_row("reference", self.ours_ref, self.pixels))
        self.ref = self.ours_ref.combined()[..., :3].astype(np.float64)
        ref_var = self.ours_ref.variance().astype(np.float64)
        self.ref_floor = float(np.mean(ref_var / (self.ref * self.ref + EPS)))
        self.ref_spp = self.ours_ref.stats["samples"] / self.pixels
        self.cy_ref = None
        if self.cy is not None:
            spp_ref = max(1, int(self.ours_ref.stats["samples"] // self.pixels))
            if self.reference_seconds > 0:
                spp_ref = min(spp_ref, self.cy.spp_for(self.reference_seconds))
            stage(f"Cycles reference: {spp_ref} spp")
            self.t_cy_ref, cy_ref = self.cy.render(spp_ref, self.seed + 1)
            self.spp_cy_ref = spp_ref
            self.rows.append(_cycles_row("reference", spp_ref, self.t_cy_ref, self.pixels, cy_ref))
            self.cy_ref = cy_ref[..., :3].astype(np.float64)
        self.images = [self.ref, self.cy_ref, ours_eq.combined()[..., :3], img_cy_eq]

    def errors(self):
        """4. Each image's error against the references, and the references' agreement."""
        for row in self.rows:
            img = row.pop("_image")
            if row["run"] == "reference":
                continue
            row["relmse_vs_pt_ref"] = rel_mse(img, self.ref, EPS)
            row["relmse_vs_pt_ref_corrected"] = row["relmse_vs_pt_ref"] - self.ref_floor
            # Unbiased Monte Carlo error falls as 1 / time: scale to exactly the budget.
            row["relmse_at_budget"] = (row["relmse_vs_pt_ref_corrected"] * row["time_s"]
                                       / self.seconds)
            if self.cy_ref is not None:
                row["relmse_vs_cycles_ref"] = rel_mse(img, self.cy_ref, EPS)
        print(f"\n4. Error at equal time ({self.seconds:g} s each; relMSE = mean (x - ref)^2 / "
              f"(ref^2 + {EPS:g}) over pixels and RGB)")
        print(f"   PT reference: {self.ref_spp:.1f} spp in {self.ours_ref.stats['time_s']:.1f} s "
              f"(seed {self.seed + 1}); its own noise (mean variance / (ref^2 + eps)) = "
              f"{self.ref_floor:.3e}, subtracted in 'corrected'")
        eq_spp = max(r["spp"] for r in self.rows if r["run"] == "equal time")
        if self.ref_spp < 2 * eq_spp:
            print(f"   warning: the reference has {self.ref_spp:.0f} spp, less than twice the "
                  f"{eq_spp:.0f} spp of the equal-time images: the corrected errors are noisy")
        if self.cy is not None:
            self._agreement()
        self.summary.update(pt_reference_spp=self.ref_spp, pt_reference_noise=self.ref_floor)

    def _cycles_equal_time_row(self):
        return next(r for r in self.rows if r["renderer"] == "Cycles" and r["run"] == "equal time")

    def _agreement(self):
        cy_eq_row = self._cycles_equal_time_row()
        consistency = rel_mse(self.cy_ref, self.ref, EPS)
        # Noise alone gives our reference's noise plus the Cycles reference's, estimated from
        # the equal-time Cycles error scaled by its sample count (variance ~ 1 / spp).
        noise_only = self.ref_floor + max(cy_eq_row["relmse_vs_pt_ref_corrected"], 0.0) * (
            cy_eq_row["spp"] / self.spp_cy_ref)
        ratio = mean_ratio(self.ref, self.cy_ref)
        print(f"   Cycles reference: {self.spp_cy_ref} spp in {self.t_cy_ref:.1f} s (seed "
              f"{self.seed + 1})")
        print(f"   consistency of the references: relMSE(Cycles ref, PT ref) = {consistency:.3e}, "
              f"noise alone ~ {noise_only:.3e}; image mean PT / Cycles = {ratio:.4f}")
        self.summary.update(reference_consistency_relmse=consistency,
                            reference_consistency_noise_only=noise_only,
                            reference_mean_ratio_pt_over_cycles=ratio,
                            cycles_reference_spp=self.spp_cy_ref)

    def targets(self, ceiling_rps):
        """5. Targets (figures, not asserts)."""
        print("\n5. Targets")
        ours_rps, ours_sps = self.ours_rps, self.ours_sps
        hold = ours_rps >= RAYS_EXPECTED * ceiling_rps
        print(f"   rays/s: {ours_rps / 1e6:.2f} M = {ours_rps / ceiling_rps:.3f} x raw embreex "
              f"({self.threads} threads; {RAYS_EXPECTED} x expected: "
              f"{'reached' if hold else 'below'})")
        self.summary.update(target_rays_ratio=ours_rps / ceiling_rps, target_rays_holds=hold)
        for name, fraction in BIDIR_TARGETS.items():
            ratio = self.bidir_ratios[name]
            met = ratio >= fraction
            print(f"   {name} samples/s >= {fraction} x our path tracer's: {ratio:.3f} -> "
                  f"{'met' if met else 'MISSED'}")
            self.summary[f"target_{name}_met"] = met
        if self.cy is None:
            return
        cy = self.cy
        hold_s = ours_sps >= SAMPLES_TARGET * cy.net_sps
        print(f"   samples/s >= {SAMPLES_TARGET} x Cycles (net): {ours_sps / 1e6:.3f} M vs "
              f"{SAMPLES_TARGET * cy.net_sps / 1e6:.3f} M needed -> "
              f"{'met' if hold_s else 'MISSED'} (ratio {ours_sps / cy.net_sps:.3f}; "
              f"{ours_sps / cy.gross_sps:.3f} of Cycles' gross rate)")
        pt_eq = next(r for r in self.rows if r["renderer"] == "ours" and r["run"] == "equal time")
        cy_eq_row = self._cycles_equal_time_row()
        if pt_eq["relmse_at_budget"] > 0 and cy_eq_row["relmse_at_budget"] > 0:
            eff = pt_eq["relmse_at_budget"] / cy_eq_row["relmse_at_budget"]
            print(f"   equal-time relMSE <= {ERROR_TARGET} x Cycles': {eff:.2f} -> "
                  f"{'met' if eff <= ERROR_TARGET else 'MISSED'}")
            self.summary.update(equal_time_error_ours_over_cycles=eff,
                                target_error_met=eff <= ERROR_TARGET)
        self.summary.update(target_samples_ratio_net=ours_sps / cy.net_sps,
                            target_samples_ratio_gross=ours_sps / cy.gross_sps,
                            target_samples_holds=hold_s)


# --------------------------------------------------------------------------- raw embreex


def embree_throughput(scene, n_rays, thread_counts=(1, 2), repeats=3, seed=0):
    """Closest-hit rays/s of raw embreex on ``scene``'s triangles.

    Origins are uniform in the scene's bounding box, directions uniform on the sphere (float32).
    With ``k`` threads the batch is cut into ``k`` disjoint slices traced concurrently
    (``EmbreeScene.run`` releases the GIL); the time is from the first start to the last join.

    Returns
    -------
    dict of int -> dict
        Per thread count: ``rays``, ``best_s``, ``median_s``, ``rays_per_s`` (best),
        ``hit_fraction``.
    """
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    emb = rtcore_scene.EmbreeScene()
    TriangleMesh(emb, scene.vertices, scene.triangles)
    lo = scene.vertices.min(axis=0).astype(np.float64)
    hi = scene.vertices.max(axis=0).astype(np.float64)
    rng = np.random.default_rng(seed)
    origins = np.ascontiguousarray(lo + (hi - lo) * rng.random((n_rays, 3)), np.float32)
    d = rng.standard_normal((n_rays, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    directions = np.ascontiguousarray(d, np.float32)
    hit_fraction = float(np.mean(emb.run(origins, directions, output=1)["primID"] >= 0))

    times = {k: [] for k in thread_counts}
    for _ in range(repeats):
        for k in thread_counts:  # interleaved, so load changes hit every thread count
            times[k].append(_trace_parallel(emb, origins, directions, k))
    return {k: {"rays": n_rays, "best_s": min(ts), "median_s": statistics.median(ts),
                "rays_per_s": n_rays / min(ts), "hit_fraction": hit_fraction}
            for k, ts in times.items()}


def _trace_parallel(emb, origins, directions, k):
    bounds = np.linspace(0, origins.shape[0], k + 1).astype(int)

    def work(a, b):
        emb.run(origins[a:b], directions[a:b], output=1)

    workers = [threading.Thread(target=work, args=(bounds[i], bounds[i + 1])) for i in range(k)]
    t0 = time.perf_counter()
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    return time.perf_counter() - t0


# --------------------------------------------------------------------------- rows and files


def _ours_row(run_name, result, pixels):
    s = result.stats
    return {"renderer": "ours", "run": run_name, "spp": s["samples"] / pixels,
            "time_s": s["time_s"], "samples_per_s": s["samples_per_s"],
            "rays_per_s": s["rays_per_s"], "_image": result.combined()[..., :3]}


def _cycles_row(run_name, spp, seconds, pixels, image):
    return {"renderer": "Cycles", "run": run_name, "spp": float(spp), "time_s": seconds,
            "samples_per_s": pixels * spp / seconds, "rays_per_s": float("nan"),
            "_image": image[..., :3]}


def _print_table(rows, seconds):
    head = (f"   {'renderer':<10} {'run':<11} {'spp':>6} {'time s':>7} {'M samp/s':>9} "
            f"{'M rays/s':>9} {'relMSE':>9} {'corrected':>9} {f'@{seconds:g} s':>9} "
            f"{'vs Cycles':>9}")
    print(head)
    print("   " + "-" * (len(head) - 3))

    def fmt(row, key):
        v = row.get(key)
        return "-" if v is None or np.isnan(v) else f"{v:.2e}"

    for r in rows:
        rays = "-" if np.isnan(r["rays_per_s"]) else f"{r['rays_per_s'] / 1e6:.2f}"
        print(f"   {r['renderer']:<10} {r['run']:<11} {r['spp']:>6.1f} {r['time_s']:>7.2f} "
              f"{r['samples_per_s'] / 1e6:>9.3f} {rays:>9} {fmt(r, 'relmse_vs_pt_ref'):>9} "
              f"{fmt(r, 'relmse_vs_pt_ref_corrected'):>9} {fmt(r, 'relmse_at_budget'):>9} "
              f"{fmt(r, 'relmse_vs_cycles_ref'):>9}")
    print("   relMSE: against our reference; corrected: minus that reference's own noise; "
          f"@{seconds:g} s: corrected x time / {seconds:g} s\n"
          "   (error scaled to exactly the budget); vs Cycles: raw relMSE against the Cycles "
          "reference")


def _write_montage(path, images):
    """2 x 2 montage (row 0 at the bottom): ``images`` = [top-left, top-right, bottom-left,
    bottom-right]; missing images are black."""
    h, w = images[0].shape[:2]
    tiles = [np.zeros((h, w, 3)) if im is None else np.asarray(im, np.float64)[..., :3]
             for im in images]
    gap_v = np.ones((h, 2, 3))
    gap_h = np.ones((2, 2 * w + 2, 3))
    top = np.concatenate([tiles[0], gap_v, tiles[1]], axis=1)
    bottom = np.concatenate([tiles[2], gap_v, tiles[3]], axis=1)
    write_png_preview(path, np.concatenate([bottom, gap_h, top], axis=0))
