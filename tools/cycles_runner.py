"""Cycles inside the same ``bpy``, measured as the benchmarks need it: kernel loading, the fixed
cost of a render, its sampling rate, renders at a sample count or a time budget."""

from __future__ import annotations

import os
import tempfile

import numpy as np


class CyclesRunner:
    """The benchmark's Cycles scene and its measured costs: cold start, fixed cost, rate.

    ``blender_scene`` renders a scene already built in ``bpy`` (``core_scene`` is then its
    export, for the pixel count); by default ``core_scene`` is rebuilt in a new empty file.
    """

    def __init__(self, core_scene, threads, max_bounces, blender_scene=None):
        from . import blender_scene as bs

        self.bs = bs
        if blender_scene is None:
            bs.import_bpy().ops.wm.read_homefile(use_empty=True)
            blender_scene = bs.build_blender_scene(core_scene)
        # A scene built elsewhere may still name another engine (EEVEE in an empty file).
        blender_scene.render.engine = "CYCLES"
        self.scene = blender_scene
        self.threads = threads
        self.max_bounces = max_bounces
        self.pixels = core_scene.camera.width * core_scene.camera.height
        self.tmp = tempfile.TemporaryDirectory(prefix="sampling_lab_bench_")
        self.t_fixed = np.inf
        self.last_times = {}

    def render(self, spp, seed):
        """Render ``spp`` samples: (wall seconds, (h, w, 4) float32 Combined)."""
        self.bs.configure_cycles(self.scene, spp, seed=seed, threads=self.threads,
                                 max_bounces=self.max_bounces)
        t, passes, self.last_times = self.bs.render_cycles(
            self.scene, os.path.join(self.tmp.name, "cycles.exr"))
        return t, passes["Combined"]

    def measure_fixed_cost(self, seed):
        """Cold first render, then the cost of a 1-spp render (sync, BVH, kernels, film, EXR)."""
        self.t_cold, _ = self.render(1, seed)
        self.t_one = min(self.render(1, seed)[0] for _ in range(2))

    def measure_fixed_spp(self, spp, seed):
        """Time ``spp`` samples; the fastest of repeated calls is kept."""
        t, img = self.render(spp, seed)
        if t < self.t_fixed:
            self.fixed_spp, self.t_fixed, self.fixed_image = spp, t, img
            clock = self.last_times.get("render_time", float("nan"))
            self.clock_sps = self.pixels * spp / clock if clock > 0 else float("nan")

    @property
    def gross_sps(self):
        return self.pixels * self.fixed_spp / self.t_fixed

    @property
    def net_sps(self):
        marginal = self.t_fixed - self.t_one
        return self.pixels * (self.fixed_spp - 1) / marginal if marginal > 0 else self.gross_sps

    def spp_for(self, seconds, rate=None):
        """Sample count whose render, fixed cost included, should take ``seconds``."""
        rate = self.net_sps if rate is None else rate
        return max(1, int(round(1 + (seconds - self.t_one) * rate / self.pixels)))

    def equal_time(self, seconds, seed, tolerance=0.15):
        """Render about ``seconds`` of wall clock: (spp, seconds taken, image).

        The sample count comes from the measured rate; if the render misses the budget by more
        than ``tolerance`` (the machine got busier or quieter), it is planned again from the
        rate that render showed, once, and the render closer to the budget is kept.
        """
        spp = self.spp_for(seconds)
        t, img = self.render(spp, seed)
        if abs(t / seconds - 1) > tolerance and t > self.t_one and spp > 1:
            rate = self.pixels * (spp - 1) / (t - self.t_one)
            spp2 = self.spp_for(seconds, rate)
            t2, img2 = self.render(spp2, seed)
            if abs(t2 - seconds) < abs(t - seconds):
                spp, t, img = spp2, t2, img2
        return spp, t, img
