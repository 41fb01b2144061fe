"""The render loop: progressive passes of wavefront batches on worker threads.

A pass adds ``spp_per_pass`` samples to every pixel. Each pass is cut into work units (a range of
pixels times a range of sample indices) that worker threads (``threads``, one per core by default)
run concurrently; Embree and large NumPy operations release the GIL. Units cover disjoint pixels and their results are accumulated in
unit order, and every random number is a function of (pixel, sample index, dimension, seed), so the
same seed gives a bit-identical image whatever the thread count or timing.

Render region: with ``settings.region`` only the pixels of that window of the frame are traced
(camera samples ``region pixels x spp``), and the film is that window. Sample streams are indexed
by frame pixel and passes hold as many samples per pixel as the whole frame's would, so a region
pixel is bit-identical to the same pixel of a full-frame render with the same seed (for camera
samples; light tracing and BDPT trace one light path per region camera sample, see
:mod:`core.integrators.bdpt`).

Halting: after ``spp`` samples per pixel, or when ``time_limit`` seconds have passed (then the pass
under way is finished unit by unit until the clock runs out), or when ``cancel()`` says so; a
cancelled render keeps every work unit it finished (pixels may then hold different sample
counts). ``cancel()`` is polled from the thread that called :func:`render` (Blender's
``test_break`` must not be called from worker threads) every :data:`POLL_S` seconds while
units run; once it says so, the units in flight stop at their next bounce
(:class:`core.sampling.stream.Aborted`) and their unfinished paths are dropped, so a render
answers a cancel within a bounce's time rather than a whole unit's.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import os
import threading
import time
import traceback
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass, field

import numpy as np

from .errors import RenderRefused
from .film import Film, PixelFilter, check_film_memory, to_float32
from .integrators import integrator_class
from .integrators.adjoint_normals import unsampled_bent_mirrors
from .integrators.base import UNIT_PATHS, Counters
from .options import DEFAULTS, validate
from .prepare import PreparedScene, prepare
from .sampling.mis import HEURISTICS
from .sampling.samplers import make_sampler
from .sampling.stream import Aborted
from .scene import VIS_DIFFUSE, VIS_GLOSSY, VIS_TRANSMISSION

# Integrators that estimate by photon density (biased, consistent): their own settings apply.
PHOTON_INTEGRATORS = ("photon", "sppm")
# Integrators whose camera paths honour Film > Transparent (alpha from the camera rays that
# escape, the world they see left out).
FILM_TRANSPARENT_INTEGRATORS = ("path", "light", "bdpt", *PHOTON_INTEGRATORS, "mlt",
                                "radiosity")

# Seconds between polls of ``cancel()`` while work units run.
POLL_S = 0.05

# Work units per pass when the image is small: a pass keeps several threads busy. The pass size
# must not depend on the thread count, or the film's sums would be added in another order.
PASS_UNITS = 8

# Work units submitted per worker thread at a time (see _Passes._run_pass).
IN_FLIGHT = 2


@dataclass
class RenderSettings:
    """What to render and how. Every field but ``region`` is an option of
    :data:`core.options.OPTIONS` (its values, range, default and description; the add-on's
    properties and the CLI flags are made from it), checked by :func:`check_settings`.

    Sampling strategies of the path tracer (see :mod:`core.sampling.mis` and
    :class:`core.lights.LightSampler`): ``mis_heuristic`` in ``MIS_SETTINGS`` ('balance',
    'power', 'maximum', 'cutoff', 'none', 'bsdf', 'light'), ``mis_beta`` (power heuristic
    exponent, > 0), ``mis_alpha`` (cutoff fraction in [0, 1]), ``light_selection`` ('power' or
    'uniform'), ``light_sampling`` ('area' or 'solid_angle') and ``distribution`` ('cdf' or
    'alias': how discrete choices such as the light are drawn).

    ``strategy_views`` asks BDPT for one image per strategy ``(s, t)`` (its own estimate and its
    MIS-weighted share) for path lengths up to ``strategy_max_length`` segments, see
    :func:`core.integrators.common.strategy_pass_names`.

    ``threads`` is the number of worker threads, 0 for one per CPU core (Blender's Auto).

    Radiosity (``integrator='radiosity'``, :mod:`core.integrators.radiosity`):
    ``radiosity_solver``, ``radiosity_patch_size``, ``radiosity_samples`` (form-factor and
    lamp samples), ``radiosity_adaptive`` (threshold of adaptive subdivision, 0 off),
    ``radiosity_display`` and ``radiosity_patches`` (the patches pass).

    ``region`` is a render region ``(x0, y0, x1, y1)``: frame pixels ``x0 <= x < x1`` (from the
    left) and ``y0 <= y < y1`` (from the bottom); None renders the whole frame.
    """

    integrator: str = DEFAULTS["integrator"]
    sampler: str = DEFAULTS["sampler"]
    spp: int = DEFAULTS["spp"]
    time_limit: float = DEFAULTS["time_limit"]
    seed: int = DEFAULTS["seed"]
    max_bounces: int = DEFAULTS["max_bounces"]
    diffuse_bounces: int = DEFAULTS["diffuse_bounces"]
    glossy_bounces: int = DEFAULTS["glossy_bounces"]
    transmission_bounces: int = DEFAULTS["transmission_bounces"]
    transparent_max_bounces: int = DEFAULTS["transparent_max_bounces"]
    use_russian_roulette: bool = DEFAULTS["use_russian_roulette"]
    rr_min_bounces: int = DEFAULTS["rr_min_bounces"]
    mis_heuristic: str = DEFAULTS["mis_heuristic"]
    mis_beta: float = DEFAULTS["mis_beta"]
    mis_alpha: float = DEFAULTS["mis_alpha"]
    light_selection: str = DEFAULTS["light_selection"]
    light_sampling: str = DEFAULTS["light_sampling"]
    distribution: str = DEFAULTS["distribution"]
    filter_type: str = DEFAULTS["filter_type"]
    filter_width: float = DEFAULTS["filter_width"]
    threads: int = DEFAULTS["threads"]
    strategy_views: bool = DEFAULTS["strategy_views"]
    strategy_max_length: int = DEFAULTS["strategy_max_length"]
    photons: int = DEFAULTS["photons"]
    photon_radius: float = DEFAULTS["photon_radius"]
    sppm_alpha: float = DEFAULTS["sppm_alpha"]
    photon_lookup: str = DEFAULTS["photon_lookup"]
    photon_k: int = DEFAULTS["photon_k"]
    photon_kernel: str = DEFAULTS["photon_kernel"]
    gather_rays: int = DEFAULTS["gather_rays"]
    photon_memory: float = DEFAULTS["photon_memory"]
    photon_surface_test: bool = DEFAULTS["photon_surface_test"]
    sppm_coverage: bool = DEFAULTS["sppm_coverage"]
    sppm_radius: str = DEFAULTS["sppm_radius"]
    radiosity_solver: str = DEFAULTS["radiosity_solver"]
    radiosity_patch_size: float = DEFAULTS["radiosity_patch_size"]
    radiosity_samples: int = DEFAULTS["radiosity_samples"]
    radiosity_adaptive: float = DEFAULTS["radiosity_adaptive"]
    radiosity_display: str = DEFAULTS["radiosity_display"]
    radiosity_patches: bool = DEFAULTS["radiosity_patches"]
    mlt_large_step: float = DEFAULTS["mlt_large_step"]
    mlt_bootstrap: int = DEFAULTS["mlt_bootstrap"]
    mlt_chains: int = DEFAULTS["mlt_chains"]
    region: tuple = None


@dataclass
class RenderResult:
    """A finished (or cancelled) render.

    Attributes
    ----------
    film : core.film.Film
    stats : dict
        ``time_s``, ``spp`` (completed passes' samples per pixel), ``samples`` (camera samples),
        ``samples_per_s``, ``rays``, ``rays_per_s``, ``prepare_s``, ``triangles``,
        ``emitters``; the light sampler's ``distribution`` ('cdf' or 'alias'),
        ``distribution_build_s`` (building its tables, once per render),
        ``distribution_sample_s`` (drawing from them, summed over batches and threads),
        ``distribution_samples`` (draws) and ``distribution_ns_per_sample``; how Embree's
        BVH was built (``core.accel.Accel.build_stats``: ``bvh_build``, ``'ctypes'`` when a
        cancel can stop it, else ``'embreex: <why>'``; ``bvh_build_s``, ``bvh_scenes``).
    cancelled : bool
        Whether the render stopped before its sample count or time limit (cancel, or an
        error).
    error : str or None
        Why a render failed part-way (``"TypeName: message"``); the film keeps every work
        unit finished before it.
    messages : list of str
    traceback : str or None
        The traceback of the exception behind ``error`` when it was not a
        :class:`core.errors.RenderRefused` (a bug, for the console).
    prepared : core.prepare.PreparedScene or None
        What the render derived from the scene (acceleration structure, light tables), to
        pass as ``prepared`` to the next render of the same scene (see :func:`render`).
    """

    film: Film
    stats: dict = field(default_factory=dict)
    cancelled: bool = False
    error: str = None
    messages: list = field(default_factory=list)
    layer_names: list = field(default_factory=list)
    traceback: str = None
    prepared: PreparedScene = None

    def combined(self):
        """``(h, w, 4)`` float32 RGBA, row 0 at the bottom."""
        return self.film.combined()

    def variance(self):
        """``(h, w, 3)`` float32 variance of each pixel estimate."""
        return to_float32(self.film.variance())

    def sample_count(self):
        """``(h, w)`` float32 samples per pixel."""
        return self.film.sample_count()

    def layers(self):
        """Extra images by pass name, ``(h, w, 3)`` float32 each (BDPT's per-strategy views,
        in :func:`core.integrators.common.strategy_pass_names` order); empty if none."""
        return {name: to_float32(self.film.layer_mean(name))
                for name in self.layer_names}


def _units(n_pixels, first_sample, spp_in_pass, unit_paths=UNIT_PATHS):
    """Work units of a pass: (pixel_start, pixel_stop, first_sample, n_samples).

    Units hold at most ``unit_paths`` paths (one pixel at least) and are of equal size, so no
    small leftover unit runs alone at the end of a pass. The split does not depend on the
    thread count: splats from several units reach the same pixels, and their sums must be
    added in the same order whatever the threads.
    """
    count = -(-n_pixels * spp_in_pass // max(1, unit_paths))
    per_unit = -(-n_pixels // max(1, min(count, n_pixels)))
    return [(p, min(p + per_unit, n_pixels), first_sample, spp_in_pass)
            for p in range(0, n_pixels, per_unit)]


def used_settings(settings):
    """The sampling-strategy settings a render really uses; ``'n/a'`` where its integrator has
    nothing to apply them to.

    Light tracing has one strategy per path (no MIS weights); light and BDPT paths start on
    emitters sampled by area (a light vertex needs no receiving point, and BDPT's MIS weights
    use area densities), so ``light_sampling`` is ``'area'`` for them, and they choose those
    emitters by power when ``light_selection`` is ``'tree'`` (which needs a receiving point);
    the path tracer's ``bsdf`` setting never samples lights (``distribution`` still draws mixed
    materials' components). The render stats report these values, and the add-on greys out
    the same options. Radiosity weighs no strategies and samples lights only for its final
    gather (uniformly over what the light sampler offers, without MIS); its own options are
    ``'n/a'`` for every other integrator.

    Parameters
    ----------
    settings : RenderSettings

    Returns
    -------
    dict
        ``mis_heuristic``, ``mis_beta``, ``mis_alpha``, ``light_selection``,
        ``light_sampling``, ``distribution``, the photon-mapping settings ``photons``,
        ``sppm_alpha``, ``photon_memory``, ``photon_lookup``, ``photon_k``, ``photon_radius``,
        ``photon_kernel``, ``gather_rays``, the ``radiosity_*`` options and the per-kind
        bounce limits ``diffuse_bounces``, ``glossy_bounces``, ``transmission_bounces`` and
        ``transparent_max_bounces`` (path tracing only, and the transparent limit for light
        tracing, BDPT, photon mapping and SPPM: the other integrators stop paths at
        ``max_bounces`` alone) (``'n/a'`` where the integrator does not read them; the photon
        estimators use no MIS: one strategy per light contribution).
    """
    if settings.integrator == "radiosity":
        return _radiosity_used(settings)
    if settings.integrator == "mlt":
        # Metropolis explores the path tracer's numbers: the path tracer's settings apply.
        path = used_settings(dataclasses.replace(settings, integrator="path"))
        return {**path, **{name: getattr(settings, name) for name in MLT_OPTIONS}}
    photon = settings.integrator in PHOTON_INTEGRATORS
    jensen = settings.integrator == "photon"
    # Photon mapping's next-event estimation at visible points samples lights as the path
    # tracer does (with the tree, from the point); it has one strategy, so no MIS.
    path = settings.integrator == "path" or photon
    weighs = (settings.integrator != "light" and not photon
              and settings.mis_heuristic in HEURISTICS)
    samples_lights = not (settings.integrator == "path" and settings.mis_heuristic == "bsdf")
    na = "n/a"
    return {
        "mis_heuristic": (settings.mis_heuristic if settings.integrator != "light" and not photon
                          else na),
        "mis_beta": settings.mis_beta if weighs and settings.mis_heuristic == "power" else na,
        "mis_alpha": settings.mis_alpha if weighs and settings.mis_heuristic == "cutoff" else na,
        "light_selection": ((settings.light_selection
                             if path or settings.light_selection != "tree" else "power")
                            if samples_lights else na),
        "light_sampling": ((settings.light_sampling if path else "area")
                           if samples_lights else na),
        "distribution": settings.distribution,
        "photons": settings.photons if photon else na,
        "sppm_alpha": settings.sppm_alpha if settings.integrator == "sppm" else na,
        "photon_memory": settings.photon_memory if photon else na,
        "photon_lookup": settings.photon_lookup if jensen else na,
        "photon_k": settings.photon_k if jensen and settings.photon_lookup == "knn" else na,
        # SPPM counts photons (uniform); k nearest ignores the radius setting.
        "photon_radius": (settings.photon_radius if settings.integrator == "sppm"
                          or (jensen and settings.photon_lookup == "radius") else na),
        "photon_kernel": settings.photon_kernel if jensen else na,
        "photon_surface_test": settings.photon_surface_test if photon else na,
        "sppm_coverage": settings.sppm_coverage if settings.integrator == "sppm" else na,
        # Footprint radii replace the automatic initial radius only (Radius 0).
        "sppm_radius": (settings.sppm_radius if settings.integrator == "sppm"
                        and not settings.photon_radius else na),
        "gather_rays": settings.gather_rays if jensen else na,
        **{name: na for name in RADIOSITY_OPTIONS},
        **{name: na for name in MLT_OPTIONS},
        # Per-kind bounce limits count sampled lobes along one camera path: the path tracer's;
        # light tracing's and BDPT's subpaths and connections cross at most the Transparent
        # limit's surfaces (core.integrators.transparent_passes), photons and the photon
        # estimators' camera paths each as many (core.photons.passes).
        **{name: getattr(settings, name) if settings.integrator == "path"
           or (settings.integrator in ("light", "bdpt", *PHOTON_INTEGRATORS)
               and name == "transparent_max_bounces")
           else na for name in BOUNCE_KIND_OPTIONS},
    }


PHOTON_OPTIONS = ("photons", "sppm_alpha", "photon_memory", "photon_lookup", "photon_k",
                  "photon_radius", "photon_kernel", "gather_rays")
BOUNCE_KIND_OPTIONS = ("diffuse_bounces", "glossy_bounces", "transmission_bounces",
                       "transparent_max_bounces")
MLT_OPTIONS = ("mlt_large_step", "mlt_bootstrap", "mlt_chains")
RADIOSITY_OPTIONS = ("radiosity_solver", "radiosity_patch_size", "radiosity_samples",
                     "radiosity_adaptive", "radiosity_display", "radiosity_patches")


def _radiosity_used(settings):
    """:func:`used_settings` of a radiosity render: MIS never applies; the light sampler's
    settings only with the final gather's next-event estimation (which draws no MIS weights)."""
    na = "n/a"
    gather = settings.radiosity_display == "final_gather"
    return {
        "mis_heuristic": na, "mis_beta": na, "mis_alpha": na,
        "light_selection": settings.light_selection if gather else na,
        "light_sampling": settings.light_sampling if gather else na,
        "distribution": settings.distribution,
        **{name: na for name in PHOTON_OPTIONS},
        **{name: na for name in BOUNCE_KIND_OPTIONS},
        **{name: na for name in MLT_OPTIONS},
        **{name: getattr(settings, name) for name in RADIOSITY_OPTIONS},
        # Hierarchical radiosity's links adapt instead; its leaves stay uniform.
        "radiosity_adaptive": (settings.radiosity_adaptive
                               if settings.radiosity_solver != "hierarchical" else na),
    }


def unused_options(settings):
    """The options a render with ``settings`` ignores, each with the value it uses instead
    (``'n/a'``: nothing): :func:`used_settings`' strategy options, and the light-path options
    the add-on greys out too (radiosity has no path bounces; photon mapping's paths use no
    Russian roulette settings; the roulette threshold needs roulette; strategy views are
    BDPT's alone and their path length needs them on).

    Returns
    -------
    dict
        Option name -> the value used instead, or ``'n/a'``; options that apply are absent.
    """
    unused = {name: value for name, value in used_settings(settings).items()
              if value != getattr(settings, name)}
    na = "n/a"
    integrator = settings.integrator
    if integrator == "radiosity":
        unused.update(max_bounces=na, use_russian_roulette=na, rr_min_bounces=na)
    if integrator in PHOTON_INTEGRATORS:
        unused.update(use_russian_roulette=na, rr_min_bounces=na)
    if not settings.use_russian_roulette:
        unused["rr_min_bounces"] = na
    views = integrator_class(integrator).strategy_views
    if not views:
        unused["strategy_views"] = na
    if not (views and settings.strategy_views):
        unused["strategy_max_length"] = na
    return unused


def check_settings(scene, settings):
    """Raise :class:`core.errors.RenderRefused` (a ``ValueError``) with a user-facing message
    for settings that cannot render."""
    if scene.camera is None:
        raise RenderRefused("the scene has no camera: add one and make it the scene camera")
    # Each option against its menu or range (core.options), then what options need together.
    try:
        validate(settings)
    except ValueError as exc:
        raise RenderRefused(str(exc)) from None
    if settings.spp <= 0 and settings.time_limit <= 0:
        raise RenderRefused("set a sample count or a time limit")
    if scene.camera.width <= 0 or scene.camera.height <= 0:
        raise RenderRefused("the resolution must be at least 1 x 1 pixel")
    if settings.region is not None:
        x0, y0, x1, y1 = settings.region
        if not (0 <= x0 < x1 <= scene.camera.width and 0 <= y0 < y1 <= scene.camera.height):
            raise RenderRefused(f"the render region {tuple(settings.region)} is not a "
                                f"non-empty window of the {scene.camera.width} x "
                                f"{scene.camera.height} frame")
    check_film_memory(scene.camera.width, scene.camera.height, settings.region)
    if settings.integrator == "bdpt" and settings.mis_heuristic not in HEURISTICS:
        raise RenderRefused(f"BDPT weighs all its strategies with one heuristic: choose "
                            f"from {', '.join(HEURISTICS)}, not {settings.mis_heuristic!r}")
    if settings.integrator in ("light", "bdpt") and scene.camera.type != "PERSP":
        raise RenderRefused(f"{settings.integrator} needs a perspective camera: light "
                            f"paths cannot reach an orthographic one")


def render(scene, settings: RenderSettings, progress=None, cancel=None, on_update=None,
           prepared=None, unit_paths=None):
    """Render ``scene`` with ``settings``.

    Parameters
    ----------
    scene : core.scene.Scene
    settings : RenderSettings
    progress : callable(fraction: float, text: str) or None
        Called after every work unit.
    cancel : callable() -> bool or None
        Polled between the stages of preparing the scene and between work units; True stops
        the render, keeping finished samples (none when it stops while preparing).
    on_update : callable(RenderResult) or None
        Called after every pass (to show the image so far).
    prepared : core.prepare.PreparedScene or None
        ``RenderResult.prepared`` of an earlier render whose :func:`preparation_key` equals
        this one's (the same scene but for the camera, e.g. the previous frame of an
        animation): reused instead of building the acceleration structure and light tables
        again (Blender's Persistent Data). The stats say ``prepared_reused``.

    unit_paths : int or None
        Paths per work unit; None: the integrator's own (``unit_paths``). Smaller units answer
        ``cancel`` sooner at some cost in speed (the rendered viewport); the pass size follows
        it, so the same seed gives the same image only with the same unit size.

    Returns
    -------
    RenderResult
    """
    check_settings(scene, settings)
    t0 = time.perf_counter()
    used = used_settings(settings)
    cam = scene.camera
    x0, y0, x1, y1 = region_bounds(cam, settings.region)
    if prepared is not None:
        prep = with_camera(prepared, scene.camera)
    else:
        try:
            # Light and BDPT paths start by area whatever the setting (see used_settings).
            prep = prepare(scene, settings.light_selection,
                           "solid_angle" if used["light_sampling"] == "solid_angle" else "area",
                           settings.distribution, cancel=cancel)
        except Aborted:
            return _cancelled_while_preparing(scene, Film(x1 - x0, y1 - y0, x0, y0), used,
                                              time.perf_counter() - t0)
    prepare_s = time.perf_counter() - t0
    film = Film(x1 - x0, y1 - y0, x0, y0)
    sampler = make_sampler(settings.sampler, seed=settings.seed,
                           spp=settings.spp if settings.spp > 0 else None, width=cam.width)
    integrator = integrator_class(settings.integrator)(prep, settings)
    # Work done once before the first unit (radiosity's solve), with progress and cancel.
    solve_cancelled = integrator.prepare_render(progress, cancel)
    result = RenderResult(film, messages=list(scene.messages) + _scene_notes(scene, prep)
                          + _messages(scene, settings, integrator),
                          layer_names=list(integrator.layers), prepared=prep)
    keep_freed_memory()
    passes = _Passes(settings, integrator, sampler, film, cam, progress, cancel, unit_paths)
    try:
        result.cancelled = solve_cancelled or passes.run(
            lambda: on_update is not None and on_update(result))
    except Exception as exc:  # noqa: BLE001 - a failed unit must not lose the finished ones
        result.cancelled = True
        result.error = f"{type(exc).__name__}: {exc}"
        if not isinstance(exc, RenderRefused):
            result.traceback = traceback.format_exc()
    t = passes.elapsed()
    counters = passes.counters
    result.stats = {
        "time_s": t,
        "prepare_s": prepare_s,
        "prepared_reused": prepared is not None,
        "threads": passes.threads,
        "spp": passes.done_spp,
        "samples": counters.camera_samples,
        "samples_per_s": counters.camera_samples / t if t > 0 else 0.0,
        "rays": counters.rays,
        "rays_per_s": counters.rays / t if t > 0 else 0.0,
        "triangles": scene.n_triangles,
        "emitters": prep.lights.n_emitters,
        **used,
        "distribution_build_s": prep.lights.build_s,
        **prep.accel.build_stats(),
        "distribution_sample_s": counters.distribution_s,
        "distribution_samples": counters.distribution_samples,
        "distribution_ns_per_sample": (1e9 * counters.distribution_s
                                       / max(counters.distribution_samples, 1)),
        **integrator.stats(),
    }
    if integrator.whole_passes:
        result.stats.update(integrator.render_stats(t))
    return result


def _cancelled_while_preparing(scene, film, used, seconds):
    """The result of a render cancelled before its first sample: an empty ``film``."""
    stats = {"time_s": seconds, "prepare_s": seconds, "prepared_reused": False, "threads": 0,
             "spp": 0, "samples": 0, "samples_per_s": 0.0, "rays": 0, "rays_per_s": 0.0,
             "triangles": scene.n_triangles, **used}
    return RenderResult(film, stats=stats, cancelled=True, messages=list(scene.messages))


def _scene_notes(scene, prep):
    """What preparing left out of a scene (:func:`core.prepare.drop_nonfinite`) and what it
    lacks that leaves the image empty: geometry, or any light at all."""
    notes = list(prep.notes)
    if prep.scene.n_triangles == 0:
        notes.append("the scene has no geometry: the camera sees only lights and the world")
    if prep.lights.n_emitters == 0:
        notes.append("the scene emits no light (no lamps, no emission shaders, a black "
                     "world): the image is black")
    return notes


def _messages(scene, settings, integrator):
    """What a render with light paths tells the user once about the scene (and what the
    integrator itself reports, :meth:`core.integrators.base.Integrator.messages`)."""
    messages = list(integrator.messages())
    # Photon mapping's photons leave the lamps as light paths do.
    if (integrator.splats or settings.integrator in PHOTON_INTEGRATORS) and len(scene.lights):
        soft = [name for name, flag in zip(scene.lights.names, scene.lights.soft_falloff) if flag]
        if soft:
            messages.append(f"{settings.integrator}: Soft Falloff of {', '.join(soft)} "
                            f"is rendered as a plain sphere light")
    if integrator.splats or settings.integrator in PHOTON_INTEGRATORS:
        bent = unsampled_bent_mirrors(integrator.prep)
        if bent:
            messages.append(f"{settings.integrator}: light paths do not sample the bent "
                            f"mirror normal (Bump Map Correction, smooth shading) of the "
                            f"roughness-0 glossy and glass lobes of {', '.join(bent)}: where it bends, "
                            f"their light-path reflections are missing (biased darker)")
    bounce_bits = VIS_DIFFUSE | VIS_GLOSSY | VIS_TRANSMISSION
    if (integrator.splats and len(scene.visibility)
            and np.any((np.asarray(scene.visibility) & bounce_bits) != bounce_bits)):
        messages.append(f"{settings.integrator}: Diffuse, Glossy and Transmission ray "
                        f"visibility are honoured by path tracing only; camera paths "
                        f"bounce with Camera visibility, light paths with Shadow")
    if scene.film_transparent and settings.integrator not in FILM_TRANSPARENT_INTEGRATORS:
        messages.append(f"{settings.integrator}: Film > Transparent is not honoured; the "
                        f"background is rendered opaque")
    return messages


class _Passes:
    """The passes of one render: work units run on worker threads, accumulated into the film
    in unit order, with progress, cancel and the time limit checked between units."""

    def __init__(self, settings, integrator, sampler, film, cam, progress, cancel,
                 unit_paths=None):
        self.settings, self.integrator = settings, integrator
        self.sampler, self.film = sampler, film
        self.frame_width = cam.width
        self.progress, self.cancel = progress, cancel
        self.pixel_filter = PixelFilter(settings.filter_type, settings.filter_width)
        self.total_spp = settings.spp if settings.spp > 0 else None
        # Integrators whose samples cost more (BDPT) ask for smaller units: cancel stays prompt.
        self.unit_paths = unit_paths or integrator.unit_paths
        # Final renders may run several units as one batch; passes keep the units' size.
        self.batch_paths = self.unit_paths * (1 if unit_paths else integrator.batch_units)
        # Sized by the whole frame, so a region's pixels sum their samples in the same passes as
        # a full-frame render (bit-identical pixels).
        self.spp_per_pass = max(1, min(self.unit_paths * PASS_UNITS // (cam.width * cam.height),
                                       64))
        self.threads = thread_count(settings)
        self.counters = Counters()
        self.done_spp = 0
        self.unshown = 0  # units added to the film since on_pass() was last called
        self.t_start = time.perf_counter()
        # Set once cancel() says so: the units in flight stop at their next bounce.
        self.stop = threading.Event()

    def elapsed(self):
        return time.perf_counter() - self.t_start

    def out_of_time(self):
        return self.settings.time_limit > 0 and self.elapsed() >= self.settings.time_limit

    def run_unit(self, unit):
        """Render one work unit ``(pixel_start, pixel_stop, first_sample, n_samples)``."""
        film = self.film
        p0, p1, s0, k = unit
        pixels = np.repeat(np.arange(p0, p1, dtype=np.int64), k)
        samples = np.tile(np.arange(s0, s0 + k, dtype=np.int64), p1 - p0)
        # Streams and camera rays are indexed by frame pixel, the film by window pixel.
        frame_pixels = ((film.y0 + pixels // film.width) * self.frame_width + film.x0
                        + pixels % film.width)
        local = Counters()
        stream = self.sampler.stream(frame_pixels, samples)
        stream.abort = self.stop.is_set
        try:
            out = self.integrator.render_samples(stream, self.pixel_filter, local)
        except Aborted:
            return None
        # The filter taps of the light-path splats are made here, on the worker: the render
        # loop, whose thread the next unit waits for, only adds them up.
        taps = (film.splat_taps(out.splats.xy, out.splats.value, self.pixel_filter)
                if out.splats is not None and len(out.splats.xy) else None)
        return pixels, out, local, taps

    def accumulate(self, pixels, out, local, taps=None):
        """Add one unit's output to the film (in unit order: the image is deterministic);
        ``taps``: the splats' filter taps if :meth:`run_unit` made them."""
        film, pixel_filter = self.film, self.pixel_filter
        self.unshown += 1
        self.counters.add(local)
        film.add_samples(pixels, out.radiance, out.transparency)
        if taps is not None:
            film.add_splat_taps(*taps)
        elif out.splats is not None and len(out.splats.xy):
            film.splat(out.splats.xy, out.splats.value, pixel_filter)
        film.add_splat_paths(out.light_paths)
        for name, values in out.camera_layers.items():
            film.add_layer(name, pixels, values)
        for name, splats in out.splat_layers.items():
            film.splat_layer(name, splats.xy, splats.value, pixel_filter)

    def report(self, fraction):
        if self.progress is None:
            return
        el = self.elapsed()
        counters = self.counters
        sps = counters.camera_samples / el if el > 0 else 0.0
        spp_txt = f"{self.done_spp}/{self.total_spp}" if self.total_spp else f"{self.done_spp}"
        self.progress(min(fraction, 1.0),
                      f"Sample {spp_txt} | {sps / 1e6:.2f} M samples/s | "
                      f"{counters.rays / max(el, 1e-9) / 1e6:.2f} M rays/s | "
                      f"{distribution_text(self.integrator.prep.lights, counters)}")

    def run(self, on_pass):
        """Run passes until the sample count, the time limit or ``cancel``; calls ``on_pass()``
        after every pass. Returns whether the render was cancelled."""
        if self.integrator.whole_passes:
            return self.run_whole_passes(on_pass)
        return self._run_unit_passes(on_pass)

    def _run_unit_passes(self, on_pass):
        """:meth:`run` for integrators that render work units."""
        pool = ThreadPoolExecutor(max_workers=self.threads)
        try:
            return self._run_units(pool, on_pass)
        except BaseException:
            self.stop.set()  # a unit failed: the others stop at their next bounce
            raise
        finally:
            pool.shutdown(wait=True)

    def _planned_units(self):
        """Every work unit of the render, pass after pass: ``(k, unit, index, count)``, ``k``
        the pass's samples per pixel, ``index`` the unit's place among the pass's ``count``
        units (an endless sequence under a time limit alone)."""
        done = self.done_spp
        while self.total_spp is None or done < self.total_spp:
            k = (self.spp_per_pass if self.total_spp is None
                 else min(self.spp_per_pass, self.total_spp - done))
            units = _units(self.film.n_pixels, done, k, self.batch_paths)
            for index, unit in enumerate(units):
                yield k, unit, index, len(units)
            done += k

    def _run_units(self, pool, on_pass):
        """Run the planned units, up to :data:`IN_FLIGHT` per thread at a time, and add them
        to the film in plan order (the image does not depend on timing). The next pass's units
        start while the last ones of a pass run, so no worker idles at a pass's end (small
        images have few units per pass). A render stopped part-way calls ``on_pass()`` once
        more for the units it kept. Returns whether the render was cancelled."""
        planned, pending = self._planned_units(), []
        while True:
            while len(pending) < IN_FLIGHT * self.threads and not self.out_of_time():
                nxt = next(planned, None)
                if nxt is None:
                    break
                pending.append((pool.submit(self.run_unit, nxt[1]), nxt))
            if not pending:
                return False
            future, (k, _, index, count) = pending.pop(0)
            futures = [f for f, _ in pending]
            if self._cancelled_while_waiting(future):
                self._abort([future] + futures)
                break
            self.accumulate(*future.result())
            self._unit_done(k, index + 1, count, on_pass)
            if self.cancel is not None and self.cancel():
                self._abort(futures)
                break
            if self.out_of_time():
                for f in _started(futures):  # finish what runs; its samples are kept
                    self.accumulate(*f.result())
                self._show(on_pass)
                return False
        self._show(on_pass)
        return True

    def _unit_done(self, k, finished, count, on_pass):
        """Report progress after the ``finished``-th of a pass's ``count`` units; at the last,
        count the pass's ``k`` samples per pixel as done and call ``on_pass()``."""
        total_spp = self.total_spp
        if finished < count:
            self.report((self.done_spp + k * finished / count) / total_spp if total_spp
                        else self.elapsed() / self.settings.time_limit)
            return
        self.done_spp += k
        self.report(self.done_spp / total_spp if total_spp
                    else self.elapsed() / self.settings.time_limit)
        self._show(on_pass)

    def _show(self, on_pass):
        """``on_pass()`` if units were added to the film since it was last called."""
        if self.unshown:
            self.unshown = 0
            on_pass()

    def run_whole_passes(self, on_pass):
        """Passes of an integrator that renders a whole pass itself (``whole_passes``, SPPM):
        one pass is one sample per pixel; the film shows the integrator's image after each.
        The time limit is checked between passes (a pass under way is finished); cancel is
        polled between the pass's chunks, and a cancelled pass is dropped."""
        film, integrator = self.film, self.integrator
        pixels = np.arange(film.n_pixels, dtype=np.int64)
        frame_pixels = ((film.y0 + pixels // film.width) * self.frame_width + film.x0
                        + pixels % film.width)
        sampler = _AbortingSampler(self.sampler, self.stop.is_set)
        with ThreadPoolExecutor(max_workers=self.threads) as pool:
            while self.total_spp is None or self.done_spp < self.total_spp:
                if self.out_of_time():
                    break
                image = integrator.render_pass(
                    self.done_spp, frame_pixels, sampler, self.pixel_filter,
                    self.counters, lambda fn, items: self._map_chunks(pool, fn, items))
                if image is None:
                    return True
                self.done_spp += 1
                show_estimate(film, image, self.done_spp, integrator.pass_sum_sq(),
                              integrator.pass_transparency())
                self.report(self.done_spp / self.total_spp if self.total_spp
                            else self.elapsed() / self.settings.time_limit)
                on_pass()
        return False

    def _map_chunks(self, pool, fn, items):
        """``[fn(item) for item in items]`` on the worker threads (at most ``threads`` in
        flight, results in order); None as soon as ``cancel()`` says so."""
        items, results, pending = list(items), [], []
        i = 0
        while i < len(items) or pending:
            while i < len(items) and len(pending) < self.threads:
                pending.append(pool.submit(fn, items[i]))
                i += 1
            cancelled = self._cancelled_while_waiting(pending[0])
            if not cancelled:
                results.append(pending.pop(0).result())
                cancelled = self.cancel is not None and self.cancel()
            if cancelled:
                self.stop.set()
                for f in pending:  # they stop at their next bounce
                    try:
                        f.result()
                    except Aborted:
                        pass
                return None
        return results

    def _cancelled_while_waiting(self, future):
        """Wait for ``future``, polling ``cancel()`` every :data:`POLL_S` s; True if it said so
        first."""
        while not wait([future], timeout=POLL_S, return_when=FIRST_COMPLETED)[0]:
            if self.cancel is not None and self.cancel():
                return True
        return False

    def _abort(self, pending):
        """Stop the units in flight at their next bounce; keep those that finished first."""
        self.stop.set()
        for f in _started(pending):
            out = f.result()
            if out is not None:
                self.accumulate(*out)
        return True


def _started(pending):
    """The futures of ``pending`` (in submission order) that a worker has started; the rest
    are cancelled. The pool starts them first in, first out, so the started ones come first
    and the accumulation order is kept."""
    for j, f in enumerate(pending):
        if f.cancel():
            for rest in pending[j + 1:]:
                rest.cancel()
            return pending[:j]
    return pending


class _AbortingSampler:
    """``sampler`` whose streams stop at their next bounce once ``abort()`` says so (the
    whole-pass integrators make their own streams from the sampler they are given)."""

    def __init__(self, sampler, abort):
        self.sampler, self.abort = sampler, abort

    def stream(self, pixel, sample_index):
        stream = self.sampler.stream(pixel, sample_index)
        stream.abort = self.abort
        return stream

    def __getattr__(self, name):
        return getattr(self.sampler, name)


def show_estimate(film, image, passes, sum_sq=None, transparency=None):
    """Make ``film`` show ``image (n_pixels, 3)`` as the estimate of ``passes`` samples per
    pixel (integrators with ``whole_passes``: the film's sums are replaced). ``sum_sq
    (n_pixels, 3)``: the sum of the squared per-pass estimates whose mean ``image`` is (SPPM),
    which gives the Variance pass; None: the variance is zero (not estimated).
    ``transparency (n_pixels,)``: the sum over the passes of what reached a transparent film's
    background (the alpha); None: an opaque film."""
    film.count[:] = passes
    film.sum[:] = image * passes
    film.sum_sq[:] = image * image * passes if sum_sq is None else sum_sq
    if transparency is not None:
        film.transparency = np.array(transparency, np.float64)


def preparation_key(scene, settings):
    """A digest of everything :func:`core.prepare.prepare` derives its tables from: the scene
    but its camera and messages, and the light-sampling settings. Two renders with the same key
    can share one prepared scene (:func:`render`'s ``prepared``).

    Returns
    -------
    str
        Hex digest (BLAKE2b of the arrays' dtypes, shapes and bytes).
    """
    h = hashlib.blake2b(digest_size=20)
    used = used_settings(settings)
    h.update(repr((settings.light_selection, used["light_sampling"] == "solid_angle",
                   settings.distribution)).encode())
    for f in dataclasses.fields(scene):
        if f.name not in ("camera", "messages"):
            h.update(f.name.encode())
            _digest(h, getattr(scene, f.name))
    return h.hexdigest()


def _digest(h, value):
    """Feed ``value`` (arrays, dataclasses of them, lists, scalars) into the hash ``h``."""
    if dataclasses.is_dataclass(value):
        for f in dataclasses.fields(value):
            h.update(f.name.encode())
            _digest(h, getattr(value, f.name))
    elif isinstance(value, np.ndarray) and value.dtype != object:
        h.update(f"{value.dtype.str}{value.shape}".encode())
        h.update(np.ascontiguousarray(value).data)
    elif isinstance(value, (list, tuple, np.ndarray)):
        h.update(f"[{len(value)}".encode())
        for item in value:
            _digest(h, item)
    else:
        h.update(repr(value).encode())


def with_camera(prepared, camera):
    """``prepared`` (a :class:`core.prepare.PreparedScene`) seen through ``camera`` (world
    space; moved into the prepared scene's recentred frame). Everything else is shared."""
    to_world = np.array(camera.to_world, np.float64)
    to_world[:3, 3] -= prepared.shift
    out = copy.copy(prepared)
    out.scene = dataclasses.replace(prepared.scene,
                                    camera=dataclasses.replace(camera, to_world=to_world))
    return out


def region_bounds(cam, region):
    """``(x0, y0, x1, y1)`` frame pixels a render covers: ``region``, or the whole frame."""
    if region is None:
        return 0, 0, int(cam.width), int(cam.height)
    return tuple(int(v) for v in region)


_allocator_tuned = []


def keep_freed_memory():
    """Let glibc's malloc keep freed work buffers for reuse (once per process): by default it
    maps each array of more than 128 KB afresh and unmaps it when freed, and re-faulting those
    pages took a fifth of the path tracer's time (600 k page faults on the bench Cornell box).
    Now blocks under 32 MB come from the heap, which keeps up to 256 MB free. No effect
    where malloc is not glibc's (macOS, Windows, an allocator such as jemalloc)."""
    if _allocator_tuned:
        return
    _allocator_tuned.append(True)
    try:
        import ctypes
        mallopt = getattr(ctypes.CDLL(None), "mallopt", None)
    except (OSError, TypeError):
        return
    if mallopt is not None:
        mallopt(-3, 32 << 20)  # M_MMAP_THRESHOLD (glibc's largest)
        mallopt(-1, 256 << 20)  # M_TRIM_THRESHOLD


def thread_count(settings):
    """Worker threads of a render: ``settings.threads``, or one per CPU core if it is 0."""
    return settings.threads if settings.threads > 0 else max(1, os.cpu_count() or 1)


def distribution_text(lights, counters):
    """One phrase on the light choice's cost: table kind, build time, sampling time so far."""
    kind = "alias table" if lights.method == "alias" else "CDF"
    return (f"lights by {kind}: build {1e3 * lights.build_s:.2f} ms, "
            f"sampling {1e3 * counters.distribution_s:.1f} ms")
