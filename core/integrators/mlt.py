"""Metropolis light transport in primary sample space (Kelemen et al. 2002), over the path tracer.

What it estimates
    The same pixel measurement as the path tracer, by Markov chains over the path tracer's own
    random numbers. A path-tracing sample is a deterministic function of its primary vector
    ``u`` in ``[0, 1)^D`` (:mod:`core.sampling.primary_space`): the first two numbers choose
    the pixel and the film position inside it (the pixel filter's importance sample, as the
    path tracer draws it), the rest drive the path tracer (NEE, BSDF sampling, MIS, roulette)
    unchanged. Its radiance ``L(u)`` (RGB) has luminance ``f(u)``. The chains sample ``u`` with
    density ``f / b``, ``b = integral of f``: each mutation proposes a large step (all numbers
    fresh, probability ``mlt_large_step``) or Kelemen's small step of every number, accepted
    with ``min(1, f' / f)``. Every mutation splats the proposal with weight ``a`` and the
    current state with ``1 - a`` (Veach's expected values), each as ``L / f``; pixel ``j``'s
    image is ``b * pixels / mutations`` times the sum of its splats.
Bias and consistency
    **Consistent, with b estimated.** ``b`` is the mean of ``f`` over ``mlt_bootstrap``
    independent uniform paths (unbiased; the stats give it with its standard error), and each
    chain starts from a bootstrap path chosen in proportion to ``f`` (importance resampling).
    Because the start states and ``b`` come from the same bootstrap, ``b`` times a chain's
    average of ``L / f`` has the expectation of the exact measurement (Veach's start-up
    weighting: no start-up bias, no burn-in thrown away), so renders with different seeds
    average to the path tracer's image; within one render every pixel is scaled by the same
    estimate of ``b``, so a whole image is brighter or darker by ``b``'s relative error
    (``mlt_b_rel_se`` in the stats), and the error vanishes as the bootstrap and the mutations
    grow. Pixels are correlated (one chain visits many), so the film's Variance pass is zero
    (not estimated); compare renders with different seeds instead.
Parameters
    ``spp`` is mutations per pixel (one pass = as many mutations as the film has pixels);
    ``mlt_large_step`` (large-step probability, 0.3), ``mlt_bootstrap`` (paths that estimate
    ``b`` and start the chains), ``mlt_chains`` (the most chains per batch;
    :data:`CHAIN_BATCHES` batches run side by side on the worker threads; :meth:`MLT.chain_count`
    picks enough chains for each to run about :data:`TARGET_STEPS` mutations of the budget, at
    least :data:`MIN_BATCH` per batch, never more than pixels, and fewer per batch when a
    batch's numbers could pass :data:`STATE_BYTES`). The path tracer's
    settings (bounces, MIS, light sampling) apply as they do to ``path``. A chain stores only
    the dimensions some path has read (:data:`START_WIDTH` at first, more on demand,
    :class:`core.sampling.primary_space.Chains`), so long bounce limits cost memory only where
    paths are long.
When to use it
    Meant for light that reaches the camera through narrow openings (a room lit through a gap,
    light around a corner), where uniform paths rarely find the light but a chain that found it
    keeps exploring its neighbourhood. Measured so far it has not paid at equal time: on the
    gap room of ``bench-mlt`` its relMSE was 3.4x the path tracer's (level per mutation, but
    each mutation cost 5.6x a path sample; docs/INTEGRATORS.md). For teaching and comparison.
When it fails
    Brightness is uneven at low mutation counts: chains stay in regions for a while, so the
    image shows blotches and streaks instead of fine noise, and small, rarely visited
    features converge late. Too many chains for the mutation budget make it worse: a chain
    should take many more steps than it needs to forget its start, so small budgets get small
    batches although they use the CPU less well. The samplers' stratification
    is lost (chains move freely), so on
    easy scenes path tracing wins at equal time. Every pixel shares ``b``'s error.
Film > Transparent
    The alpha does not follow the chains: their pixels are visited in proportion to
    luminance, and the share of a pixel's camera rays that reach the background is not
    luminance-weighted. Each pass traces one stratified camera sample per pixel of its own
    (the sampler's sample ``pass``, as the path tracer's camera rays) and takes what reaches
    the background, also through transparent surfaces, in expectation
    (:mod:`.camera_alpha`): the alpha has the path tracer's expectation, and equals it bit for
    bit where no transparent surface is crossed. The world seen directly (by camera rays, also
    through transparent passes) is *removed from the target function*: the path tracer the
    chains explore leaves it out on a transparent film, so ``f`` is the luminance of the
    transparent film's measurement and the chains estimate exactly that, with the start-up
    weighting above (any non-negative ``f`` will do). Subtracting it afterwards would also be
    unbiased in expectation, but the chains would spend mutations on the sky in proportion to
    its brightness, and a pixel's difference of two noisy estimates can go negative, which
    the film's clamp to zero would bias. The world still lights the scene.

Render loop: :meth:`MLT.render_pass` (``whole_passes``, like SPPM). The first pass traces the
bootstrap in chunks on the worker threads; every pass then runs each batch of chains for its
share of the pass's mutations, the batches in one ``map_chunks`` call (cancel polled between
them and, through the stream's ``abort``, at every bounce of every mutation).
"""

from __future__ import annotations

import numpy as np

from ..sampling.primary_space import (Chains, PrimarySampleStream, chain_random, luminance,
                                      metropolis_step, normalisation, resample,
                                      uniform_vectors)
from .base import Counters, Integrator
from .camera_alpha import pass_transparency

# Batches of chains: fixed (not the thread count), so the image does not depend on threads.
CHAIN_BATCHES = 4
# Fewest chains worth a batch of their own: the path tracer's per-call cost dominates below.
MIN_BATCH = 256
# Mutations each chain should run: a chain needs many more steps than it takes to forget its
# start (on the gap room, 1,024 chains of 600 steps gave a 7.7x lower error than 19,200 of 32).
TARGET_STEPS = 512
# Mutations per pixel the chain count plans for when only a time limit is set.
TIME_LIMIT_SPP = 64
# Largest primary-sample state of one batch of chains (current and proposed vectors).
STATE_BYTES = 32 << 20
# Bootstrap paths per task on the worker threads.
BOOTSTRAP_CHUNK = 1 << 13
# Dimensions stored at first (the camera's and four bounces'); more as paths read them.
START_WIDTH = 30
# Keys of the chains' random streams besides (seed, batch, pass).
_RESAMPLE_KEY = 0x5EED


def film_position(u, width, height):
    """Film pixel and position inside it of the first two primary numbers.

    Parameters
    ----------
    u : (n, 2) float64
        In ``[0, 1)``.

    Returns
    -------
    pixel : (n,) int64
        Window pixel ``y * width + x``.
    inside : (n, 2) float64
        Position inside that pixel, in ``[0, 1)`` (the pixel filter's sample).
    """
    xy = u * np.array([width, height], np.float64)
    ij = np.minimum(np.floor(xy), np.array([width - 1, height - 1])).astype(np.int64)
    inside = np.clip(xy - ij, 0.0, np.nextafter(1.0, 0.0))
    return ij[:, 1] * width + ij[:, 0], inside


class MLT(Integrator):
    """Primary-sample-space Metropolis light transport (see the module docstring)."""

    whole_passes = True

    def __init__(self, prep, settings):
        super().__init__(prep, settings)
        # The path tracer is the estimator the chains explore (no estimator module imports
        # another: it comes from the registry).
        from . import INTEGRATORS, integrator_class

        self.path = integrator_class("path")(prep, settings)
        module = INTEGRATORS["path"]
        self.dims = module.DIMS_CAMERA + self.path.limits.steps * module.DIMS_PER_BOUNCE
        self.large_step = float(settings.mlt_large_step)
        self.n_bootstrap = int(settings.mlt_bootstrap)
        self.max_batch = max(1, min(int(settings.mlt_chains), STATE_BYTES // (16 * self.dims)))
        self.spp = int(settings.spp)
        self.seed = int(settings.seed)
        self.batches = None
        self.b = self.b_se = 0.0
        self.sums = None
        self.clear = None  # Film > Transparent: the passes' transparency summed per pixel
        self.mutations = 0
        self.bootstrap_rays = 0

    # Evaluation of primary vectors ------------------------------------------------------------

    def _evaluate(self, u, grow, window, pixel_filter, counters, abort):
        """``L (m, 3)`` and window pixel ``(m,)`` of primary vectors ``u (m, width)``;
        ``grow(w)``: the vectors with ``w`` dimensions, when a path reads past ``width``."""
        width, height, frame_pixels = window
        pixel, inside = film_position(u[:, :2], width, height)
        stream = PrimarySampleStream(u, inside, frame_pixels[pixel], grow, self.dims, self.seed)
        stream.abort = abort
        out = self.path.render_samples(stream, pixel_filter, counters)
        return out.radiance, pixel

    # Bootstrap ------------------------------------------------------------------------------

    def _bootstrap(self, window, pixel_filter, map_chunks, abort):
        """Stage *bootstrap*: ``b`` from uniform paths, and each chain's start state resampled
        from them in proportion to ``f``. False if cancelled."""
        n = self.n_bootstrap
        # Fewer paths per task when their vectors could pass STATE_BYTES (long bounce limits).
        chunk = max(1, min(BOOTSTRAP_CHUNK, STATE_BYTES // (8 * self.dims)))
        spans = [(i, min(i + chunk, n)) for i in range(0, n, chunk)]

        def trace(span):
            local = Counters()
            index = np.arange(*span)
            vectors = [uniform_vectors(self.seed, index, min(self.dims, START_WIDTH))]

            def grow(w):
                # Dimensions past the stored ones, from the same hash: vector i stays a
                # function of i, so a chain started from it can rebuild it.
                have = vectors[0].shape[1]
                more = uniform_vectors(self.seed, index, w - have, have)
                vectors[0] = np.concatenate([vectors[0], more], axis=1)
                return vectors[0]

            L, pixel = self._evaluate(vectors[0], grow, window, pixel_filter, local, abort)
            return L, pixel, local.rays, vectors[0].shape[1]

        parts = map_chunks(trace, spans)
        if parts is None:
            return False
        L = np.concatenate([p[0] for p in parts])
        pixel = np.concatenate([p[1] for p in parts])
        self.bootstrap_rays = sum(p[2] for p in parts)
        width = max(p[3] for p in parts)
        f = luminance(L)
        self.b, self.b_se = normalisation(f)
        n_chains = self.chain_count(window[2].size)
        picks = resample(f, n_chains, chain_random(self.seed, _RESAMPLE_KEY))
        self.batches = []
        if picks is None:
            return True
        batches = min(CHAIN_BATCHES, max(1, n_chains // MIN_BATCH))
        for rows in np.array_split(picks, batches):
            self.batches.append(Chains(uniform_vectors(self.seed, rows, width), L[rows],
                                       pixel[rows]))
        return True

    def chain_count(self, pixels):
        """Chains of a render of ``pixels``: enough that each runs about
        :data:`TARGET_STEPS` mutations of the budget (``spp`` per pixel, or
        :data:`TIME_LIMIT_SPP` under a time limit alone), at least :data:`MIN_BATCH` and at
        most ``mlt_chains`` per batch, and never more than pixels."""
        budget = pixels * (self.spp if self.spp > 0 else TIME_LIMIT_SPP)
        per_batch = -(-budget // (CHAIN_BATCHES * TARGET_STEPS))
        per_batch = min(self.max_batch, max(MIN_BATCH, per_batch))
        return min(CHAIN_BATCHES * per_batch, pixels)

    # Passes ---------------------------------------------------------------------------------

    def render_pass(self, pass_index, frame_pixels, sampler, pixel_filter, counters,
                    map_chunks):
        """One pass: as many mutations as the film has pixels; returns the image ``(n_pixels,
        3)`` after it, or None if the render was cancelled (the pass is then dropped).

        Parameters are those of :meth:`core.integrators.sppm.SPPM.render_pass`; ``sampler``
        only lends its ``abort`` (the chains make their own numbers).
        """
        n = frame_pixels.size
        width = int(frame_pixels[-1] % self.prep.scene.camera.width
                    - frame_pixels[0] % self.prep.scene.camera.width + 1)
        window = (width, n // width, frame_pixels)
        abort = getattr(sampler, "abort", None)
        if self.batches is None:
            if not self._bootstrap(window, pixel_filter, map_chunks, abort):
                return None
            self.sums = np.zeros((n, 3))
            counters.rays += self.bootstrap_rays
        clear = None
        if self.prep.scene.film_transparent:
            clear = pass_transparency(self.prep, self.settings, pass_index, frame_pixels,
                                      sampler, pixel_filter, counters, map_chunks)
            if clear is None:
                return None
        if self.batches:
            tasks = self._schedule(pass_index, n)
            done = map_chunks(lambda task: self._run_batch(task, window, pixel_filter, abort),
                              tasks)
            if done is None:
                return None
            for sums, local in done:
                self.sums += sums
                counters.add(local)
        else:
            counters.camera_samples += n  # no bootstrap path carried light: a black image
        if clear is not None:
            self.clear = clear if self.clear is None else self.clear + clear
        self.mutations += n
        return self.image()

    def pass_transparency(self):
        """Per-pixel sum ``(n_pixels,)`` over the passes of the camera samples' transparency
        on a transparent film (the alpha, :mod:`.camera_alpha`); None on an opaque one."""
        return self.clear

    def _schedule(self, pass_index, n):
        """Tasks ``(batch, pass, steps, extra rows)``: every chain mutates ``n // chains``
        times, and ``n % chains`` of them (a window that moves every pass) once more, so that
        the pass makes exactly ``n`` mutations."""
        total = sum(len(c) for c in self.batches)
        steps, extra = divmod(n, total)
        first = (pass_index * extra) % total
        chosen = (first + np.arange(extra)) % total
        tasks, start = [], 0
        for i, chains in enumerate(self.batches):
            mine = chosen[(chosen >= start) & (chosen < start + len(chains))] - start
            tasks.append((i, pass_index, steps, np.sort(mine)))
            start += len(chains)
        return tasks

    def _run_batch(self, task, window, pixel_filter, abort):
        """Mutate one batch of chains; its splat sums ``(n_pixels, 3)`` and counters."""
        i, pass_index, steps, extra = task
        chains, local = self.batches[i], Counters()
        rng = chain_random(self.seed, i, pass_index)

        def evaluate(u, grow):
            return self._evaluate(u, grow, window, pixel_filter, local, abort)

        keys, values = [], []
        for rows in [None] * steps + ([extra] if extra.size else []):
            k, v = metropolis_step(chains, evaluate, rng, self.large_step, rows)
            keys.append(k)
            values.append(v)
        n = window[2].size
        sums = np.zeros((n, 3))
        if keys:
            k, v = np.concatenate(keys), np.concatenate(values)
            v[~np.isfinite(v).all(axis=1)] = 0.0
            for c in range(3):
                sums[:, c] = np.bincount(k, v[:, c], minlength=n)
        return sums, local

    def image(self):
        """The current estimate ``(n_pixels, 3)``: ``b * pixels / mutations`` times the splat
        sums; finite and non-negative."""
        n = self.sums.shape[0]
        img = self.sums * (self.b * n / max(self.mutations, 1))
        img[~np.isfinite(img).all(axis=1)] = 0.0
        return np.maximum(img, 0.0)

    def messages(self):
        return ["mlt: Metropolis light transport is consistent with b estimated from the "
                "bootstrap; pixels are correlated, so the Variance pass is zero"]

    def render_stats(self, seconds):
        """Metropolis figures for the render stats."""
        chains = self.batches or []
        proposed = sum(c.proposed for c in chains)
        return {"estimator_bias": "consistent, b estimated (unbiased over seeds)",
                "mlt_b": self.b, "mlt_b_se": self.b_se,
                "mlt_b_rel_se": self.b_se / self.b if self.b > 0 else None,
                "mlt_bootstrap_paths": self.n_bootstrap,
                "mlt_chains": sum(len(c) for c in chains),
                "mlt_mutations": self.mutations,
                "mlt_acceptance": (sum(c.accepted for c in chains) / proposed
                                   if proposed else 0.0),
                "variance_pass": "zero: MLT's pixels are correlated (compare seeds instead)"}
