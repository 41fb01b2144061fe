"""Transparent passes on the photon estimators' paths: a pass straight through is not a bounce.

Photons, the camera paths to visible points and final gathering's rays go straight through
surfaces with transparent components (Transparent BSDF, a Principled BSDF's Alpha, a Mix with a
Transparent BSDF; per hit where the alpha is a texture, :mod:`core.alpha`) as light tracing's and
BDPT's walks do (:mod:`core.integrators.transparent_passes`, whose :class:`Passes` this module
calls): at such a hit the path chooses a mixture component with probability its weight; the
pass-through goes on straight with the component's colour and is no bounce (not counted against
Max Bounces, no photon stored there, no visible point made there, not a specular bounce of a
caustic path). The next-event estimation of the visible points crosses such surfaces with
their transmittance (:func:`core.integrators.shadows.shadow_transmittance`), as the path
tracer's shadow rays do.

The Transparent limit ``T`` counts the passes of each side: a photon ends at its ``T + 1``-th
pass, a camera path (and the final-gather rays after it) likewise, and the shadow rays of a
visible point may cross ``T`` minus the passes its camera path made. Light tracing and BDPT
count a whole path's passes together; here a photon's passes and the camera path's are counted
apart (a stored photon does not record its passes), so a path may pass up to ``2 T``
surfaces, one side at most ``T`` (the same image wherever no path meets more than ``T``
transparent surfaces, as with the default limit of 8 in most scenes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..integrators.transparent_passes import Passes, has_passes


@dataclass
class _Limits:
    """The one setting :meth:`Passes.resolve` reads."""

    transparent_max_bounces: int


@dataclass
class _Context:
    """What :meth:`Passes.resolve` reads of a walk's context."""

    prep: object
    settings: _Limits
    counters: object


class PassWalk:
    """The transparent passes of one batch of photon-estimator paths (struct-of-arrays over its
    live rows); None of :func:`pass_walk` where every surface is opaque.

    Attributes
    ----------
    passed : (m,) int32
        Transparent surfaces each path passed so far (its camera path's too for gather rays).
    """

    def __init__(self, prep, limit, counters, m, passed=None):
        self._ctx = _Context(prep, _Limits(int(limit)), counters)
        self._passes = Passes(m)
        if passed is not None:
            self._passes.passed = np.asarray(passed, np.int32).copy()

    @property
    def passed(self):
        return self._passes.passed

    def take(self, rows):
        """Keep the paths ``rows (k,)`` (index compaction)."""
        self._passes.take(rows)

    def resolve(self, bounce, rows, o, d, tmax, hits, beta, vis, stream, dim, on_segment=None):
        """Stage *pass transparent surfaces*: follow the rays ``o, d (m, 3)`` of the paths
        ``rows (m,)`` (entries of ``stream``; their first ``hits`` already traced) straight
        through the surfaces where they choose the pass-through, to the surface that scatters
        them.

        Parameters
        ----------
        bounce : int
            Bounce number (handed to :meth:`Passes.resolve` as the step).
        tmax : (m,) float64 or None
        beta : (m, 3) float64
        vis : (m,) int
            Visibility classes of the rays.
        stream : SampleStream
            Entries ``rows`` of it are the paths; the component choices draw dimension ``dim``
            (the numbers the path's own lobe choice draws there).
        on_segment : callable or None
            ``on_segment(rows, o, d, hits, beta)`` for every segment after a pass (``rows``
            are entries of ``stream``, ``beta`` the throughput through the passes).

        Returns
        -------
        hits : core.accel.Hits
            Where the rays end, ``t`` from ``o``; no hit for paths that met a pass beyond the
            limit or one of colour zero.
        beta : (m, 3) float64
        u_pass : (m,) float64 or None
            The lobe number of each final hit, NaN where the path's own draw is it
            (:func:`lobe_numbers`).
        """
        def segment(_j, seg_rows, so, sd, shits, sbeta, _pdf, _delta, _t0):
            on_segment(seg_rows, so, sd, shits, sbeta)

        zeros = np.zeros(rows.size)
        return self._passes.resolve(self._ctx, bounce, rows, o, d, tmax, hits, beta,
                                    np.asarray(vis), stream, dim,
                                    None if on_segment is None else segment, zeros,
                                    np.zeros(rows.size, bool))


def transparent_limit(limit):
    """``limit`` as an int, or where None the Transparent option's default (callers outside a
    render, such as the tools' stage timings)."""
    if limit is None:
        from ..options import DEFAULTS  # core.options imports the integrators, which use this
        return int(DEFAULTS["transparent_max_bounces"])
    return int(limit)


def pass_walk(prep, limit, counters, m, passed=None):
    """A :class:`PassWalk` of ``m`` paths with the Transparent limit ``limit`` (None: the
    option's default; ``passed (m,)`` their passes so far, None: none), or None if no material
    passes rays."""
    if not has_passes(prep):
        return None
    return PassWalk(prep, transparent_limit(limit), counters, m, passed)


def lobe_numbers(u_lobe, u_pass, live):
    """The lobe numbers ``(k,)`` of the hits ``live (k,)``: the path's own draw ``u_lobe
    (k,)``, or where the hit was reached through a surface with a transparent component the
    number its component choice left (``u_pass (m,)``, NaN elsewhere; None: no pass)."""
    if u_pass is None:
        return u_lobe
    chosen = u_pass[live]
    return np.where(np.isnan(chosen), u_lobe, chosen)
