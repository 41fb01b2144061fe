"""Samplers: one module per family. :func:`make_sampler` builds one by name.

A sampler makes :class:`core.sampling.stream.SampleStream` batches: ``sampler.stream(pixel,
sample_index)`` returns a stream whose ``sample(dimension, count)`` gives the ``count``-dimensional
point (count is 1 or 2: ``next_1d`` / ``next_2d``) of each (pixel, sample index) for the dimension
slot starting at ``dimension``, as a deterministic function of (pixel, sample index, dimension,
seed). Every sampler class has ``name``, ``label`` (UI name), ``description`` (tooltip),
``needs_spp`` (it must know the sample count ahead of time) and ``__init__(seed=0, spp=None)``.
A 1-D and a 2-D request at the same dimension are different slots: an integrator must always
draw a given dimension the same way.

``SAMPLERS`` lists them in the order the UI shows them; each module is imported on first use.
"""

from __future__ import annotations

import importlib
import importlib.util

# name -> (module, class name)
SAMPLERS = {
    "independent": ("independent", "IndependentSampler"),
    "stratified": ("stratified", "StratifiedSampler"),
    "multijitter": ("multijitter", "MultiJitterSampler"),
    "halton": ("halton", "HaltonSampler"),
    "hammersley": ("hammersley", "HammersleySampler"),
    "sobol": ("sobol", "SobolSampler"),
    "pmj02": ("pmj02", "PMJ02Sampler"),
    "poisson_disk": ("poisson_disk", "PoissonDiskSampler"),
    "lloyd": ("lloyd", "LloydSampler"),
    "cvt": ("cvt", "CVTSampler"),
}


def sampler_class(name):
    """The class of sampler ``name``; ``ValueError`` for an unknown or missing one."""
    try:
        module_name, class_name = SAMPLERS[name.lower()]
    except KeyError:
        raise ValueError(f"unknown sampler {name!r}; choose from {', '.join(available())}") from None
    try:
        module = importlib.import_module(f"{__name__}.{module_name}")
    except ModuleNotFoundError as exc:
        if exc.name != f"{__name__}.{module_name}":
            raise
        raise ValueError(f"sampler {name!r} is not available in this build") from None
    return getattr(module, class_name)


def available():
    """Names of the samplers whose modules exist, in UI order."""
    out = []
    for name, (module_name, _) in SAMPLERS.items():
        if importlib.util.find_spec(f"{__name__}.{module_name}") is not None:
            out.append(name)
    return out


def make_sampler(name, seed=0, spp=None, width=None):
    """Sampler called ``name`` (see ``SAMPLERS``), for renders of ``spp`` samples if known.

    ``width`` (image width in pixels) reaches the samplers that declare ``screen_space``
    (blue-noise masks laid over the image); the others take samples by pixel index alone.
    """
    cls = sampler_class(name)
    if cls.screen_space:
        return cls(seed=seed, spp=spp, width=width)
    return cls(seed=seed, spp=spp)
