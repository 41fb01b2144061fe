"""Samplers: one module per family. :func:`make_sampler` builds one by name."""

from __future__ import annotations

from .independent import IndependentSampler

SAMPLERS = {"independent": IndependentSampler}


def make_sampler(name, seed=0, spp=None):
    """Sampler called ``name`` (see ``SAMPLERS``), for renders of ``spp`` samples if known."""
    try:
        cls = SAMPLERS[name.lower()]
    except KeyError:
        raise ValueError(f"unknown sampler {name!r}; choose from {', '.join(SAMPLERS)}") from None
    return cls(seed=seed, spp=spp)
