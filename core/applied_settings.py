"""Which settings a render applies: the strategy options its integrator reads, and what it uses
instead of the others (``'n/a'``: nothing). The render stats report them, the add-on greys out
the options a render ignores, and the command line warns about them."""

from __future__ import annotations

import dataclasses

from .integrators import integrator_class
from .passes import thread_count
from .sampling.mis import HEURISTICS

# Integrators that estimate by photon density (biased, consistent): their own settings apply.
PHOTON_INTEGRATORS = ("photon", "sppm")

# Integrators whose work units can run in worker processes (their state is rebuilt from the
# scene and the settings): the others render whole passes or solve a system in this process.
PROCESS_INTEGRATORS = ("path", "light", "bdpt")


def worker_mode(settings):
    """Where a render's work units run: ``('processes', '')``, or ``('threads', why)`` with why
    processes were not used (``''`` when threads were asked for)."""
    if settings.workers != "processes":
        return "threads", ""
    if settings.integrator not in PROCESS_INTEGRATORS:
        return "threads", (f"{settings.integrator} keeps threads: it renders whole passes or "
                           f"solves in one process")
    if thread_count(settings) == 1:
        return "threads", "one thread needs no worker process"
    return "processes", ""


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
        estimators use no MIS: one strategy per light contribution), and ``workers``
        (``'processes'`` or ``'threads'``: :func:`worker_mode`); ``connection_roulette``
        (Russian roulette of connections) and ``light_points`` (where strategy ``s = 1``
        takes its points) for BDPT alone.
    """
    return {**_used_settings(settings), "workers": worker_mode(settings)[0]}


def _used_settings(settings):
    """:func:`used_settings` but ``workers``."""
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
        # Russian roulette of connections before their shadow rays: BDPT's alone; 0 is off.
        "connection_roulette": (settings.connection_roulette
                                if settings.integrator == "bdpt" else na),
        # Where BDPT's s = 1 takes its points on lights; no other integrator has s = 1.
        "light_points": settings.light_points if settings.integrator == "bdpt" else na,
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
        "connection_roulette": na,
        "light_points": na,
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
        unused.update(max_bounces=na, use_russian_roulette=na, rr_min_bounces=na, rr_survival=na)
    if integrator in PHOTON_INTEGRATORS:
        unused.update(use_russian_roulette=na, rr_min_bounces=na, rr_survival=na)
    if not settings.use_russian_roulette:
        unused.update(rr_min_bounces=na, rr_survival=na)
    views = integrator_class(integrator).strategy_views
    if not views:
        unused["strategy_views"] = na
    if not (views and settings.strategy_views):
        unused["strategy_max_length"] = na
    return unused
