"""Bidirectional path tracing: every connection strategy (s, t), combined by MIS.

What it estimates
    The same pixel measurement as :mod:`.path`. For each sample it traces a camera subpath
    ``z_0 (camera), z_1, ...`` and a light subpath ``y_0 (on an emitter), y_1, ...`` and forms
    every path of ``k`` segments from ``s`` light and ``t`` camera vertices, ``s + t = k + 1``:
    ``s = 0`` (the camera subpath hits an emitter), ``s = 1`` (a fresh point on an emitter is
    connected to ``z_{t-1}``: next-event estimation), ``s >= 2, t >= 2`` (``y_{s-1}`` is
    connected to ``z_{t-1}`` by a shadow ray) and ``t = 1`` (``y_{s-1}`` is connected to the
    pinhole and splatted onto the film where it lands; ``s = 1, t = 1`` connects the light
    subpath's point on an emitter to the pinhole, so small lamps seen directly are not left
    to camera rays alone).
Bias and consistency
    Unbiased for paths of up to ``max_bounces + 1`` scattering vertices, as the path tracer.
    MIS weights are computed from each path's per-vertex densities, in area measure (solid angle
    toward infinite emitters), as Veach's ratio recurrence (pbrt's ``MISWeight``): the weights of
    all strategies that can make a path sum to one for every heuristic, so every setting of
    ``mis_heuristic`` is unbiased: ``balance``, ``power`` (``mis_beta``), ``maximum``,
    ``cutoff`` (``mis_alpha``), or ``none`` (every strategy that can make the path gets the same
    weight). For the connections ``s >= 1, t >= 2`` under ``balance``, ``power`` and ``none``
    the same weights (to rounding) come from running sums along the subpaths
    (:mod:`.mis_sums`), one pass for every strategy of a batch. Strategies next to a delta BSDF vertex, and ``s = 0`` for delta lights, cannot make
    a path and get weight zero; so do strategies whose density is zero.
    Densities used for MIS ignore Russian roulette, and light points for ``s = 1`` are sampled
    by area (not by solid angle as the path tracer's ``solid_angle`` setting does).
    Transparent surfaces (Transparent BSDF, Alpha) are not path vertices: subpaths pass them
    straight through and connections cross them, dimmed by their transparency, within the
    Transparent limit (:mod:`.transparent_passes`, which argues why the MIS weights still sum
    to one).
Parameters
    ``max_bounces``, ``transparent_max_bounces``, ``use_russian_roulette``,
    ``rr_min_bounces``, ``mis_heuristic``, ``mis_beta``, ``mis_alpha``; light selection and
    the world's importance map as :class:`core.lights.LightSampler`; ``strategy_views`` and
    ``strategy_max_length`` write one image per strategy (its own estimate, and its
    MIS-weighted share).
Limitations
    Perspective cameras only (light subpaths must be able to reach the film). Object ray
    visibility is honoured for camera rays and shadow rays; light subpath rays trace every
    object. Soft Falloff point lights are rendered as spheres, and sphere lights shine on
    points inside them only through ``s <= 1`` strategies (:mod:`core.lights.emission`).
Render region
    A region is rendered as a smaller film: camera subpaths start in the region's pixels only,
    each with its one light subpath as in a full render (so the region costs its share of the
    time), and ``t = 1`` connections are made only toward film positions whose splats reach a
    region pixel (the window plus the filter's reach). Splats are divided by the light subpaths
    traced, so each is still an unbiased estimate; MIS weights use the density of camera rays
    over the region (``1 / (A_region cos^3)``), the sample counts this render really has. Camera
    strategies give the same samples as the full render's pixels; the light strategies have
    ``region / frame`` as many light paths behind each pixel, so pixels that light paths
    dominate (caustics) are noisier than in a full-frame render of the same ``spp``.
When to use it
    Caustics (small lights seen through glass or mirrors on diffuse receivers) and scenes lit
    indirectly, where camera paths rarely find the light and light paths rarely find the
    camera but connections between them do.

Stages: generate camera subpath (with ``s = 0`` emission) -> generate light subpath ->
connect ``s = 1`` -> connect ``s, t >= 2`` -> connect ``s = 1, t = 1`` -> connect ``t = 1``
(splat). The subpaths, the ``s = 0`` and ``t = 1`` strategies and the chunking are shared with
light tracing (:mod:`.bidir`, :mod:`.subpaths`, :mod:`.camera_hits`, :mod:`.connections`); the
MIS densities of every strategy are in :mod:`.mis_densities`, the per-strategy images in
:mod:`.strategy_views`.
"""

from __future__ import annotations

import numpy as np

from ..lights.emission import EmitterPoints
from .bidir import DIMS_CAMERA, DIMS_PER_CAMERA_VERTEX, Bidirectional
from .common import nonzero_rows, take_rows
from .connection_roulette import for_batch as roulette_for_batch
from .connections import Fresh, connect_all, connect_emitter_to_camera


# Where strategy ``s = 1`` finds its point on an emitter (the Direct Light Points option):
# the light subpath's own first vertex, or a fresh sample for every camera vertex.
LIGHT_POINTS = ("light_path", "fresh")


class BDPT(Bidirectional):
    """Bidirectional path tracing (see the module docstring)."""

    # A BDPT sample costs several path-tracing samples (about 7 x the CPU time on the bench's
    # Cornell box), so units are smaller than the path tracer's to keep cancel and progress
    # within a second. A call has a few milliseconds of fixed cost (7 ms for 256 paths, one
    # core, 2026-11-25), and NumPy's per-call cost falls with larger batches: much smaller
    # units would be slower. The class's figure sizes viewport units (core.progressive); a
    # render's units and chunks are sized by its depth (_unit_paths).
    unit_paths = 1 << 13
    strategy_views = True

    def __init__(self, prep, settings):
        super().__init__(prep, settings)
        self.unit_paths = self.chunk_paths = _unit_paths(settings.max_bounces + 2)

    def connect(self, ctx, stream, C, L, out):
        """Strategies ``s >= 1, t >= 2`` (for ``s = 1`` the light subpath's first vertex or a
        fresh emitter point, :data:`LIGHT_POINTS`; under the Connection Roulette,
        :mod:`.connection_roulette`), then ``s = 1, t = 1``."""
        ctx.roulette = roulette_for_batch(self.settings, stream)
        points = (_fresh_points(ctx, stream, C) if self.settings.light_points == "fresh"
                  else _light_path_points(ctx, C))
        connect_all(ctx, L, C, points, out)
        connect_emitter_to_camera(ctx, L, out)


# Most subpath vertices per chunk and side (_unit_paths): at about 330 bytes a vertex, at
# most 90 MB of subpath arrays per side and worker thread.
UNIT_VERTICES = 1 << 18


def _unit_paths(depth):
    """Paths per work unit (and chunk) for subpaths of ``depth`` vertices: a power of two
    between ``2^13`` and ``2^14`` with at most :data:`UNIT_VERTICES` vertices per subpath
    table. Each chunk has a fixed cost per vertex depth and strategy (NumPy calls on few
    rows): 16,384 paths took 0.8 x the CPU per sample of 8,192 on the bench box (8 bounces,
    one thread, 2026-11-26; docs/BENCHMARKS.md), 32,768 0.7 x but with 3 x the memory."""
    paths = 1 << 14
    while paths > 1 << 13 and paths * depth > UNIT_VERTICES:
        paths >>= 1
    return paths


def _light_path_points(ctx, C):
    """Strategy ``s = 1`` as Veach (1997, ch. 10) builds it: every connectible camera vertex
    joined to its light subpath's first vertex (the point on an emitter that the light path
    starts from). Its density is the one a fresh point would have (the MIS weights are the
    same functions of the path); the joins of one sample share the point, which costs no
    sampling but correlates them a little."""
    level, rows = nonzero_rows(C.valid[1:] & C.connectible[1:])
    if rows.size == 0:
        return None
    return _with_emitter(level + 1, rows,
                         EmitterPoints(*(take_rows(a, rows) for a in ctx.light_points)))


def _with_emitter(zj, rows, pts):
    """:class:`Fresh` of the joins whose point ``pts`` lies on an emitter (``index >= 0``)."""
    got = np.nonzero(pts.index >= 0)[0]
    if got.size == rows.size:  # every point is on an emitter (any scene with one)
        return Fresh(zj, rows, pts)
    return Fresh(zj[got], rows[got], EmitterPoints(*(take_rows(a, got) for a in pts)))


def _fresh_points(ctx, stream, C):
    """Strategy ``s = 1``: a fresh point on an emitter for every connectible camera vertex
    (drawn from that vertex's dimensions of the stream, so each is the same whichever other
    vertices exist), sampled for all vertices in one call."""
    # Depth-major, as a loop over the vertices would list them; each row's numbers from its
    # vertex's dimensions, drawn for these rows only (Stream.slots_of_rows: the numbers of
    # compacted copies of the stream, without hashing the dead paths' numbers).
    level, rows = nonzero_rows(C.valid[1:] & C.connectible[1:])
    if rows.size == 0:
        return None
    zj = level + 1
    u_sel, u_pos = stream.slots_of_rows(
        rows, DIMS_CAMERA + level * DIMS_PER_CAMERA_VERTEX + 4, (1, 2))
    return _with_emitter(zj, rows, ctx.emission.sample_points(u_sel, u_pos, ctx.counters))


# One work unit without a render loop (tests, one-off use); a render builds BDPT once.
