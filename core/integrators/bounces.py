"""Bounce limits per kind of bounce, as Cycles' Light Paths > Max Bounces panel.

A path counts its bounces by the *sampled* lobe (the ``LOBE_*`` label of
:func:`core.materials.bsdf.sample_bsdf`), as Cycles' ``path_state_next`` does:

- a pass straight through a transparent surface (Transparent BSDF, Principled Alpha) counts only
  as a *transparent* bounce;
- every other bounce counts toward the *total*, and toward one kind: *diffuse* (a diffuse
  reflection), *glossy* (a glossy or mirror reflection) or *transmission* (any transmission
  that is not a transparent pass).

When a count exceeds its limit after a bounce, the path is *finishing* (Cycles'
``PATH_RAY_TERMINATE_AFTER_TRANSPARENT``): the next surface still adds its emission (with the
same MIS weight as before, so that next-event estimation at the previous vertex stays
balanced), and the path may still pass through transparent surfaces, but it samples no light
and scatters no more. Limits of ``n`` therefore allow ``n`` bounces of a kind and the light
arriving after them, as Cycles' (whose kernel stores ``n + 1`` and tests ``>=``).

The transparent limit ``T`` counts differently, as in Cycles 4 and 5 (whose kernel stores
``T`` itself: "0 means no transparent bounce"): once a path has passed ``max(T, 1)`` transparent
surfaces, the next surface adds its emission and the path ends there
(``PATH_RAY_TERMINATE_ON_NEXT_SURFACE``); a shadow ray from a vertex whose path has passed
``k`` transparent surfaces may cross ``T - k`` more (see :mod:`.shadows`). Measured with
Blender 5.0's Cycles (direct light, sheets of Transparent BSDF): an emitter behind ``n`` sheets
shows iff ``n <= max(T, 1)``; a floor seen through ``n`` sheets and lit by a sun through the
same ``n`` is lit iff ``2 n <= T``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..materials.bsdf import LOBE_DIFFUSE, LOBE_REFLECT, LOBE_TRANSMIT


@dataclass(frozen=True)
class BounceLimits:
    """The five limits of a render (see the module docstring)."""

    total: int
    diffuse: int
    glossy: int
    transmission: int
    transparent: int

    @staticmethod
    def from_settings(settings):
        """Limits of a ``core.render.RenderSettings``."""
        return BounceLimits(int(settings.max_bounces), int(settings.diffuse_bounces),
                            int(settings.glossy_bounces), int(settings.transmission_bounces),
                            int(settings.transparent_max_bounces))

    @property
    def steps(self):
        """Segments a path can trace at most: every bounce of the total, every transparent pass,
        and the last segment that only gathers emission (one bound for the depth loop)."""
        return self.total + self.transparent + 2


class BounceCounts:
    """Per-path bounce counts of a batch, struct-of-arrays.

    Each count is an ``(n,)`` int32 array, or one int while it is the same on every path of
    the batch: a batch starts at zero, and a count stays one int while every path adds the same
    to it (a diffuse-only scene without transparent surfaces never needs the arrays, which
    compaction would otherwise gather twice a bounce).

    Attributes
    ----------
    total, diffuse, glossy, transmission, transparent : (n,) int32 or int
    finishing : (n,) bool
        Paths past one of the limits (total, diffuse, glossy, transmission): their next surface
        only adds emission and lets them pass if it is transparent.
    """

    def __init__(self, n):
        self.total = self.diffuse = self.glossy = self.transmission = self.transparent = 0
        self.finishing = np.zeros(n, bool)

    _COUNTS = ("total", "diffuse", "glossy", "transmission", "transparent")

    def take(self, rows):
        """Keep the paths ``rows (k,)`` (index compaction)."""
        for name in self._COUNTS:
            count = getattr(self, name)
            if isinstance(count, np.ndarray):
                setattr(self, name, count[rows])
        self.finishing = self.finishing[rows]

    def advance(self, lobe, through, limits):
        """Count the bounce each path just sampled.

        Parameters
        ----------
        lobe : (n,) uint8
            ``LOBE_*`` label of the sample (0 for a failed one: those paths end anyway).
        through : (n,) bool
            Samples that passed straight through a transparent surface.
        limits : BounceLimits

        Returns
        -------
        stop_next : (n,) bool
            Paths whose transparent pass just now brought the transparent count to its limit:
            their next surface adds its emission, then they end.
        """
        lobe = np.asarray(lobe)
        scatter = ~through
        transmit = scatter & ((lobe & LOBE_TRANSMIT) != 0)
        reflect = scatter & ((lobe & LOBE_REFLECT) != 0)
        diffuse = reflect & ((lobe & LOBE_DIFFUSE) != 0)
        self.transparent = _counted(self.transparent, through)
        self.total = _counted(self.total, scatter)
        self.diffuse = _counted(self.diffuse, diffuse)
        self.glossy = _counted(self.glossy, reflect & ~diffuse)
        self.transmission = _counted(self.transmission, transmit)
        self.finishing |= ((self.total > limits.total) | (self.diffuse > limits.diffuse)
                           | (self.glossy > limits.glossy)
                           | (self.transmission > limits.transmission))
        return through & (self.transparent >= limits.transparent)

    def shadow_budget(self, limits, rows=None):
        """Transparent surfaces a shadow ray from each path's vertex may cross: ``(k,)``, or
        one int for every path."""
        used = self.transparent
        if rows is not None and isinstance(used, np.ndarray):
            used = used[rows]
        return np.maximum(limits.transparent - used, 0)


def _counted(count, mask):
    """``count + mask`` for a count (``(n,)`` int32 or one int) and ``mask (n,)`` bool; an
    int stays one where the mask is the same on every path."""
    if isinstance(count, np.ndarray):
        count += mask
        return count
    if not mask.any():
        return count
    if mask.all():
        return count + 1
    return np.add(count, mask, dtype=np.int32)


def uniform_limits(total):
    """Render options setting every bounce limit to ``total`` (a dict of keyword arguments of
    ``core.render.RenderSettings``): what ``tools.blender_scene.configure_cycles`` sets in
    Cycles, and what the benchmarks use to compare integrators that do not count bounces by
    kind with the path tracer."""
    total = int(total)
    return dict(max_bounces=total, diffuse_bounces=total, glossy_bounces=total,
                transmission_bounces=total, transparent_max_bounces=total)
