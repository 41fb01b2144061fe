"""The render loop: prepare the scene, run progressive passes (:mod:`core.passes`), report.

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
``test_break`` must not be called from worker threads) every :data:`core.passes.POLL_S` seconds while
units run; once it says so, the units in flight stop at their next bounce
(:class:`core.sampling.stream.Aborted`) and their unfinished paths are dropped, so a render
answers a cancel within a bounce's time rather than a whole unit's.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import time
import traceback
from dataclasses import dataclass, field

import numpy as np

from .errors import RenderRefused
from .applied_settings import PHOTON_INTEGRATORS, used_settings, worker_mode
from .film import Film, check_film_memory, to_float32
from .integrators import integrator_class
from .integrators.adjoint_normals import unsampled_bent_mirrors
from .options import DEFAULTS, validate
from .allocator import keep_freed_batches
from .passes import Passes, thread_count
from .prepare import PreparedScene, prepare
from .sampling.mis import HEURISTICS
from .sampling.samplers import make_sampler
from .sampling.stream import Aborted
from .scene import VIS_DIFFUSE, VIS_GLOSSY, VIS_TRANSMISSION

# Integrators whose camera paths honour Film > Transparent (alpha from the camera rays that
# escape, the world they see left out).
FILM_TRANSPARENT_INTEGRATORS = ("path", "light", "bdpt", *PHOTON_INTEGRATORS, "mlt",
                                "radiosity")

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
    ``workers`` is where path, light and BDPT units run: ``'threads'`` (the default here) or
    ``'processes'`` (:mod:`core.workers`, one per thread; same image bit for bit).

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
    rr_survival: str = DEFAULTS["rr_survival"]
    connection_roulette: float = DEFAULTS["connection_roulette"]
    light_points: str = DEFAULTS["light_points"]
    mis_heuristic: str = DEFAULTS["mis_heuristic"]
    mis_beta: float = DEFAULTS["mis_beta"]
    mis_alpha: float = DEFAULTS["mis_alpha"]
    light_selection: str = DEFAULTS["light_selection"]
    light_sampling: str = DEFAULTS["light_sampling"]
    distribution: str = DEFAULTS["distribution"]
    filter_type: str = DEFAULTS["filter_type"]
    filter_width: float = DEFAULTS["filter_width"]
    threads: int = DEFAULTS["threads"]
    # The core's default is threads, not the registry's processes (the add-on's and the command
    # line's): a library caller or a test that patches core functions sees its patch only in
    # this process. Final renders in Blender and the CLI, bench and bench-scenes use processes.
    workers: str = "threads"
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
    result = RenderResult(film, messages=list(scene.messages) + _scene_notes(scene, prep, used)
                          + _messages(scene, settings, integrator),
                          layer_names=list(integrator.layers), prepared=prep)
    keep_freed_batches()
    processes, workers = _worker_processes(scene, settings, film) if not solve_cancelled else (
        None, {})
    passes = Passes(settings, integrator, sampler, film, cam, progress, cancel, unit_paths,
                    processes)
    try:
        result.cancelled = solve_cancelled or passes.run(
            lambda: on_update is not None and on_update(result))
    except Exception as exc:  # noqa: BLE001 - a failed unit must not lose the finished ones
        result.cancelled = True
        # A worker process's exception: its own message and traceback.
        result.error = getattr(exc, "error", None) or f"{type(exc).__name__}: {exc}"
        if not isinstance(exc, RenderRefused):
            result.traceback = (getattr(exc, "remote_traceback", None)
                                or traceback.format_exc())
    finally:
        if processes is not None:
            processes.release()
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
        **workers,
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


def _worker_processes(scene, settings, film):
    """The :class:`core.workers.ProcessUnits` of a render whose units run in worker processes
    (None: threads), and the stats saying which ran and why: ``workers`` ('processes' or
    'threads'), ``workers_text`` ('2 worker processes'), ``workers_note`` (why processes were
    not used), ``workers_start_s`` and ``workers_ship_s`` (starting workers, and hashing and
    sending the scene), ``workers_shipped`` (workers sent the scene)."""
    count = thread_count(settings)
    mode, why = worker_mode(settings)
    processes = None
    if mode == "processes":
        from . import workers

        why = workers.memory_note(scene.n_triangles, count)
        mode = "threads" if why else mode
    if mode == "processes":
        t0 = time.perf_counter()
        try:
            key = preparation_key(scene, settings)
            processes = workers.ProcessUnits(count, scene, settings, key,
                                             (film.x0, film.y0, film.width, film.height),
                                             scene.camera.width)
        except workers.WorkersBusy as exc:
            why = f"{exc}: threads were used"
        except (OSError, workers.WorkerDied) as exc:
            why = f"worker processes could not start ({exc}); threads were used"
    if processes is None:
        return None, {"workers": "threads", "workers_note": why,
                      "workers_text": f"{count} thread{'s' if count > 1 else ''}"}
    return processes, {
        "workers": "processes", "workers_note": "",
        "workers_text": f"{count} worker processes",
        "workers_start_s": processes.start_s,
        "workers_ship_s": time.perf_counter() - t0 - processes.start_s,
        "workers_shipped": processes.shipped}


def _cancelled_while_preparing(scene, film, used, seconds):
    """The result of a render cancelled before its first sample: an empty ``film``."""
    stats = {"time_s": seconds, "prepare_s": seconds, "prepared_reused": False, "threads": 0,
             "spp": 0, "samples": 0, "samples_per_s": 0.0, "rays": 0, "rays_per_s": 0.0,
             "triangles": scene.n_triangles, **used}
    return RenderResult(film, stats=stats, cancelled=True, messages=list(scene.messages))


def _scene_notes(scene, prep, used):
    """What preparing left out of a scene (:func:`core.prepare.drop_nonfinite`), what it
    lacks that leaves the image empty (geometry, or any light at all), and how the light
    selection in ``used`` (:func:`used_settings`) applies to its lights."""
    notes = list(prep.notes)
    if used["light_selection"] == "tree":
        notes += prep.lights.notes
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

