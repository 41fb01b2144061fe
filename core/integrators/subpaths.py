"""Subpaths of the bidirectional estimators (light tracing, BDPT): their vertices, the random
walk that makes them, and the densities in area measure that MIS compares.

A :class:`Subpath` holds a batch of subpaths depth-major; :func:`walk` extends one from its
endpoint (the pinhole, or a point on an emitter) by BSDF sampling, in radiance mode from the
camera and in importance mode from the lights; :class:`Gathered` is one vertex of it, gathered
for the rows of a connection.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from ..materials.bsdf import (IMPORTANCE, KIND_DIFFUSE, OPTIONAL_GROUPS, BSDFParams,
                              BSDFSample, eval_bsdf, pdf_bsdf, pdf_plain_diffuse, sample_bsdf,
                              sample_plain_diffuse)
from ..materials.bsdf_values import eval_with_pdfs
from ..materials.frame import shading_frame, to_local, to_world
from ..rows import dots, norms, put_rows
from .adjoint_normals import VertexNormals
from .common import (bends_normals, coat_normals_in_front, finite_rows, intersect_by_class,
                     max_component, ray_class, roulette_at, russian_roulette,
                     shading_tangents, surface_hits, surface_interaction, take_rows,
                     with_bump_normals, with_coat_normals)
from .transparent_passes import Passes, has_passes
from .vertex_frames import gather_frames


def dot(a, b):
    return dots(a, b)


def _empty_params(n):
    # The base columns only: an optional group (coat, sheen, anisotropy, bump) is added when a
    # stored vertex has it (Subpath.store_params), so that a scene whose materials use none
    # gathers and evaluates none.
    return BSDFParams(np.zeros(n, np.int32), np.zeros((n, 3)), np.ones(n), np.ones(n),
                      np.zeros((n, 3)))


# Columns a diffuse BSDF never reads, and the constant stand-ins a Lambert gather gives them.
_NOT_LAMBERT = {"alpha": 1.0, "eta": 1.0, "tint": 0.0}


def take_params(params, rows, lambert=False):
    """The rows ``rows (k,)`` of ``params`` (as :meth:`BSDFParams.take`, gathered by
    ``np.take``: several times faster for the ``(n, 3)`` columns).

    ``lambert``: every row is a plain diffuse BSDF (``PreparedScene.lambert_only``, as the
    path tracer's Lambert shading assumes): ``alpha``, ``eta`` and ``tint``, which Lambert's
    eval and pdf never read, are not gathered but read-only constant views."""
    # Straight over the instance's columns: BSDFParams.map_columns walks every field by name,
    # a per-call cost that showed in light tracing (several calls per vertex).
    out = {}
    for name, c in vars(params).items():
        if c is None:
            out[name] = None
        elif lambert and name in _NOT_LAMBERT:
            out[name] = np.broadcast_to(_NOT_LAMBERT[name], (rows.size,) + c.shape[1:])
        else:
            out[name] = c.take(rows, axis=0)
    return BSDFParams(**out)


# Columns that walk() stores at every vertex it makes (``wo`` and ``nm`` with smooth shading
# only: Gathered reads them only then; ``ng`` not where Subpath.by_triangle says its readers
# gather it by triangle), so that a reset may leave vertices 1..D-1 alone; each
# with its value before any vertex is made (Subpath.empty's). The densities, edges and
# triangles (pdf_fwd, d_prev, cos_prev, prim: (depth, n) tables a recycle filled whole) are
# among them: readers look at made vertices only. So is pdf_rev, written at a vertex when the
# next one is sampled from it: readers look at it only there (the MIS sums and weights end a
# path's stored factors before its last vertex, the connection supplies that one's).
_STORED = {"p": 0.0, "ng": 0.0, "fs": 0.0, "ft": 0.0, "fn": 0.0, "wo": 0.0, "wo_local": 0.0,
           "wo_z": 0.0, "beta": 0.0, "nm": 0.0, "pdf_fwd": 0.0, "d_prev": np.inf, "cos_prev": 1.0,
           "prim": 0, "pdf_rev": 0.0}


def _table_base(table):
    """The BSDF table's base columns with their values before any vertex is stored."""
    return ((table.kind, 0), (table.color, 0.0), (table.alpha, 1.0), (table.eta, 1.0),
            (table.tint, 0.0))


def _vertex_views(table, depth, n):
    """Per vertex ``j``, rows ``j * n .. (j + 1) * n`` of ``table`` as views."""
    return [table.take(slice(j * n, (j + 1) * n)) for j in range(depth)]


@dataclass
class Subpath:
    """Vertices of a batch of subpaths, depth-major: arrays of shape ``(D, n, ...)``.

    Vertex 0 is the endpoint (the pinhole, or the point on the emitter); vertices ``1..D-1``
    are surface hits. ``pdf_fwd`` is the density with which the subpath's own sampling made
    the vertex, ``pdf_rev`` the density with which the other side would make it (known once
    the next vertex is sampled); both are in area measure, solid angle for infinite light
    endpoints, and one next to a delta vertex (the discrete choices cancel in MIS ratios).
    ``d_prev`` and ``cos_prev`` are the distance to the previous vertex and the cosine there
    (along the edge, geometric normal; one for points, the pinhole and infinite endpoints),
    used to turn solid-angle densities at this vertex into area densities at the previous one.
    ``nm`` is the perturbed shading normal before the view's fallback, for light paths' choice
    of normal (:mod:`.adjoint_normals`; smooth-shaded scenes only). ``passed`` counts the
    transparent surfaces the subpath passed straight through before each vertex (not vertices:
    :mod:`.transparent_passes`).

    ``p``, ``beta`` and ``wo_z`` are float32 (everything else float64): every connection
    gathers positions and throughputs from these tables, at half the bytes, and the plain
    Lambert connection ends (:mod:`.lambert_vertices`) compute in float32 from them (BDPT 3 %
    less CPU per sample on the bench box, docs/BENCHMARKS.md, twelfth round). A position is
    then within half a float32 ulp of the hit, as Embree itself traces (float32 rays), and far
    below the 64-ulp offsets of the shadow rays that leave it (:mod:`core.accel`).
    """

    valid: np.ndarray
    p: np.ndarray
    ng: np.ndarray
    prim: np.ndarray
    fs: np.ndarray
    ft: np.ndarray
    fn: np.ndarray
    wo: np.ndarray
    wo_local: np.ndarray
    params: list
    connectible: np.ndarray
    delta: np.ndarray
    beta: np.ndarray
    pdf_fwd: np.ndarray
    pdf_rev: np.ndarray
    d_prev: np.ndarray
    cos_prev: np.ndarray
    all_params: BSDFParams = None
    nm: np.ndarray = None
    passed: np.ndarray = None

    # Set by empty(): whether fn is ng itself (flat shading: the frame's normal is the
    # geometric normal, one column stored), and whether only Lambert BSDFs are stored (their
    # alpha, eta and tint are not: every gather then stands constants in for them,
    # take_params with lambert=True). tri_frames: the walk's frames are each hit triangle's
    # own (vertex_frames.triangle_frames; fs and ft are then not stored but gathered by prim).
    flat_frames: bool = False
    lambert: bool = False
    tri_frames: tuple = None
    # Per triangle, its geometric normal (PreparedScene.tri_normal), what ng holds at every
    # vertex a walk makes, and (None unless every material is plain diffuse and untextured)
    # the BSDF colour of every vertex on it (PreparedScene.tri_albedo): a connection may
    # gather them by prim instead (LambertVertices.at), and where every reader does, the
    # walks store neither (by_triangle).
    tri_normals: np.ndarray = None
    tri_colors: np.ndarray = None
    # The same two tables in float32, for the float32 Lambert ends (made by empty()).
    tri_normals32: np.ndarray = None
    tri_colors32: np.ndarray = None
    # Whether a walk stored transparent passes in ``passed`` since the last recycle (which
    # then clears it; a scene without transparent surfaces never does: no fill per batch).
    passes_stored: bool = False
    # Where by_triangle: the z of wo_local (all that plain diffuse BSDFs read of it), stored
    # instead of wo_local: (depth, n).
    wo_z: np.ndarray = None

    @property
    def by_triangle(self):
        """Whether the walks leave ``ng`` (and ``fn``, the same array), the BSDF table and
        ``wo_local`` (but its z, :attr:`wo_z`) unwritten at vertices ``1..D-1``: under flat
        shading with every material plain
        diffuse and untextured (``tri_colors`` given) and a table of the base columns only,
        every reader gathers a vertex's normal and colour by its triangle (:meth:`normals`;
        :class:`.lambert_vertices.LambertVertices`, which
        :func:`.lambert_vertices.all_lambert` then picks for every connection end)."""
        return (self.flat_frames and self.tri_colors is not None
                and not any(self.all_params.has(group) for group in OPTIONAL_GROUPS))

    def vertex_rows(self, index, lambert=False):
        """Geometric normals ``(m, 3)``, BSDF rows (:func:`take_params`, ``lambert`` as there)
        and ``wo_local`` ``(m, 3)`` of the surface vertices ``index (m,)`` (rows of
        :meth:`flat`): the stored ones, or where the walks store none (:attr:`by_triangle`)
        their triangles' (plain diffuse rows of the triangles' colours, the values
        choose_bsdf gave them) and ``wo_local`` of x and y zero (which such rows never
        read)."""
        params = take_params(self.all_params, index, lambert)
        if not self.by_triangle:
            return take_rows(self.flat("ng"), index), params, take_rows(self.flat("wo_local"),
                                                                        index)
        prim = self.prim.reshape(-1).take(index)
        params.kind = np.full(index.size, KIND_DIFFUSE, params.kind.dtype)
        params.color = take_rows(self.tri_colors, prim)
        wo_l = np.zeros((index.size, 3))
        wo_l[:, 2] = self.wo_z.reshape(-1).take(index)
        return take_rows(self.tri_normals, prim), params, wo_l

    def normals(self, j, rows):
        """Geometric normals ``(k, 3)`` of vertex ``j`` of the subpaths ``rows (k,)``: at
        surface vertices (``j >= 1``) their triangles' (the values ``ng`` stores), gathered by
        ``prim``."""
        if j == 0:
            return take_rows(self.ng[0], rows)
        return take_rows(self.tri_normals, self.prim[j].take(rows))

    @staticmethod
    def empty(depth, n, flat_frames=False, lambert=False, tri_frames=None,
              tri_normals=None, tri_colors=None):
        """Subpaths of ``depth`` vertices for ``n`` samples, none made yet. ``params[j]`` are
        views of one table ``all_params`` of ``depth * n`` rows (vertex ``j`` of subpath ``i``
        is row ``j * n + i``, as in :meth:`flat`), with the base columns only: a group of
        optional columns (coat, sheen, ...) is added by :meth:`store_params` when a vertex
        has it. ``flat_frames``: the walk's frames are around the geometric normal (no
        smooth shading), so ``fn`` is the same array as ``ng``; ``lambert``: every BSDF is
        a plain diffuse one (``PreparedScene.lambert_only``), whose glossy columns are not
        stored; ``tri_frames``: :func:`.vertex_frames.triangle_frames` when the walk uses
        them (``fs`` and ``ft`` are then not stored: :class:`Gathered` gathers them by
        triangle); ``tri_normals``, ``tri_colors``: the triangles' geometric normals and
        colours (:attr:`tri_normals`)."""
        z3 = lambda dtype=np.float64: np.zeros((depth, n, 3), dtype)  # noqa: E731
        f32 = lambda a: None if a is None else a.astype(np.float32)  # noqa: E731
        table = _empty_params(depth * n)
        params = _vertex_views(table, depth, n)
        ng = z3()
        return Subpath(np.zeros((depth, n), bool), z3(np.float32), ng,
                       np.zeros((depth, n), np.int32),
                       z3(), z3(), ng if flat_frames else z3(), z3(), z3(), params,
                       np.zeros((depth, n), bool), np.zeros((depth, n), bool), z3(np.float32),
                       np.zeros((depth, n)), np.zeros((depth, n)), np.full((depth, n), np.inf),
                       np.ones((depth, n)), table, z3(), np.zeros((depth, n), np.int32),
                       flat_frames, lambert, tri_frames, tri_normals, tri_colors,
                       f32(tri_normals), f32(tri_colors), wo_z=np.zeros((depth, n), np.float32))

    def reset(self):
        """Make this as :meth:`empty` made it (no vertex), reusing its memory: a new
        allocation would page its memory in again for every batch."""
        self.recycle()
        self.passed.fill(0)  # recycle clears it only after a walk's stores
        for name, value in _STORED.items():
            getattr(self, name).fill(value)
        table = self.all_params
        for column, value in _table_base(table):
            column.fill(value)
        return self

    def recycle(self):
        """:meth:`reset` for the next batch's walk, at a fraction of its memory traffic: the
        columns that say which vertices exist (``valid``, ``connectible``, ``delta``, ...) are
        reset; the columns that :func:`walk` writes whole at every vertex it makes
        (:data:`_STORED`, the BSDF table) keep the last batch's values at vertices
        ``1..D-1`` where no vertex is now. No reader looks there (they gather valid vertices
        only; ``tests/core/test_subpath_tables.py`` fills them with NaN to check it).

        Vertex 0 (the pinhole or the emitter point) is written whole by the subpath's setup
        (``bidir._camera_subpath``, ``_light_subpath``: the same columns every batch) or
        never (its frame, directions and BSDF rows keep :meth:`empty`'s values), except
        ``pdf_rev``, which the walk writes for the subpaths it extends: only that row is
        reset (the others were 5 MB of fills per side and batch)."""
        for name, value in (("valid", False), ("connectible", False), ("delta", False)):
            getattr(self, name).fill(value)
        if self.passes_stored:  # else still all zero (no walk stored a pass count)
            self.passed.fill(0)
            self.passes_stored = False
        self.pdf_rev[0].fill(0.0)
        table = self.all_params
        if any(table.has(group) for group in OPTIONAL_GROUPS):
            # Back to the base columns, as empty() makes them: the next batch adds what it uses.
            self._set_table(BSDFParams(table.kind, table.color, table.alpha, table.eta,
                                       table.tint))
        return self

    def store_params(self, j, rows, params):
        """Store BSDF ``params`` as vertex ``j`` of the subpaths ``rows (k,)``. An optional
        column group of ``params`` that the table lacks is added first (neutral elsewhere);
        rows without a group the table has get its neutral values (as
        :meth:`BSDFParams.scatter`)."""
        table = self.all_params
        missing = [g for g in OPTIONAL_GROUPS if params.has(g) and not table.has(g)]
        if missing:
            for group in missing:
                table = table.with_neutral(group)
            self._set_table(table)
        view = self.params[j]
        for group in OPTIONAL_GROUPS:
            if view.has(group) and not params.has(group):
                params = params.with_neutral(group)
        skip = _NOT_LAMBERT if self.lambert else ()
        for name, src in vars(params).items():
            dst = getattr(view, name)
            if dst is not None and name not in skip:
                put_rows(dst, rows, src)

    def _set_table(self, table):
        depth, n = self.valid.shape
        self.all_params = table
        self.params = _vertex_views(table, depth, n)

    def flat(self, name):
        """Column ``name`` with vertices and subpaths in one axis: ``(depth * n, ...)``, row
        ``j * n + i`` for vertex ``j`` of subpath ``i`` (a view)."""
        a = getattr(self, name)
        return a.reshape((-1,) + a.shape[2:])


class Gathered:
    """Vertex ``j`` of a subpath for the rows of one connection: what evaluating its BSDF
    needs, gathered once (parameters, shading frame, incoming direction)."""

    def __init__(self, ctx, sub, j, rows, mode):
        self.smooth, self.mode, self.lambert = ctx.smooth, mode, ctx.prep.lambert_only
        self.ng, self.params, self.wo_l = sub.vertex_rows(j * sub.valid.shape[1] + rows,
                                                          self.lambert)
        self.wo = take_rows(sub.wo[j], rows) if ctx.smooth else None
        self.fs, self.ft, self.fn = gather_frames(
            sub, lambda name: take_rows(getattr(sub, name)[j], rows), self.ng)
        self.nm = take_rows(sub.nm[j], rows) if self.smooth else None
        self.bends = (bends_normals(ctx.prep.scene, take_rows(sub.prim[j], rows))
                      if self.smooth else None)
        self.normals = None

    @staticmethod
    def at(ctx, sub, index, mode):
        """Vertices ``index (m,)`` of ``sub`` as rows of :meth:`Subpath.flat` (each any vertex
        of any subpath), gathered once."""
        lambert = ctx.prep.lambert_only
        ng, params, wo_l = sub.vertex_rows(index, lambert)
        return Gathered.of(ctx.smooth, mode, params,
                           gather_frames(sub, lambda name: take_rows(sub.flat(name), index), ng),
                           take_rows(sub.flat("wo"), index) if ctx.smooth else None, wo_l, ng,
                           take_rows(sub.flat("nm"), index) if ctx.smooth else None, lambert,
                           bends_normals(ctx.prep.scene, take_rows(sub.flat("prim"), index))
                           if ctx.smooth else None)

    @staticmethod
    def of(smooth, mode, params, frame, wo, wo_l, ng, nm=None, lambert=False, bends=None):
        """Vertices from arrays already gathered: BSDF ``params``, shading ``frame`` (three
        (m, 3) axes), ``wo`` (None unless ``smooth``), ``wo_l`` (in the frame), ``ng`` and
        (smooth shading) ``nm`` and ``bends`` (:func:`.common.bends_normals` of the hits);
        ``lambert`` as :func:`take_params` (their later gathers take no more than that)."""
        out = object.__new__(Gathered)
        out.smooth, out.mode, out.params, out.lambert = smooth, mode, params, lambert
        out.fs, out.ft, out.fn = frame
        out.wo, out.wo_l, out.ng, out.nm, out.bends = wo, wo_l, ng, nm, bends
        out.normals = None
        return out

    def take(self, idx):
        """The rows ``idx`` of this gather (after shadow rays removed some)."""
        out = Gathered.of(self.smooth, self.mode, take_params(self.params, idx, self.lambert),
                          [take_rows(a, idx) for a in (self.fs, self.ft, self.fn)],
                          None if self.wo is None else take_rows(self.wo, idx),
                          take_rows(self.wo_l, idx), take_rows(self.ng, idx),
                          None if self.nm is None else take_rows(self.nm, idx), self.lambert,
                          None if self.bends is None else self.bends[idx])
        if self.normals is not None:
            out.normals = self.normals.take(idx)
        return out

    def for_densities(self, idx):
        """The rows ``idx`` for densities only: :meth:`pdf_toward`, :meth:`pdf_back` and
        ``ng`` (no frame: no :meth:`local` or :meth:`f`); fewer gathers than :meth:`take`.
        With smooth shading the densities need the frames (:mod:`.adjoint_normals`)."""
        if self.smooth:
            return self.take(idx)
        return Gathered.of(self.smooth, self.mode, take_params(self.params, idx, self.lambert),
                           [None] * 3, None, take_rows(self.wo_l, idx), take_rows(self.ng, idx),
                           None, self.lambert)

    def _adjoint(self):
        """The rows' :class:`.adjoint_normals.VertexNormals` (smooth shading), made once."""
        if self.normals is None:
            self.normals = VertexNormals(self.params, (self.fs, self.ft, self.fn), self.ng,
                                         self.nm, self.bends)
        return self.normals

    def _world(self, w_l):
        return to_world(w_l, self.fs, self.ft, self.fn)

    def local(self, w):
        """World directions ``w (m, 3)`` in the vertices' shading frames."""
        return to_local(w, self.fs, self.ft, self.fn)

    def cos_ng(self, w, w_l, rows):
        """``ng . w`` ``(k,)`` at the rows ``rows (k,)`` of world directions ``w (m, 3)``
        whose :meth:`local` is ``w_l``: read from ``w_l`` where the frame's normal is ``ng``
        (flat shading: the same dot product)."""
        if self.fn is self.ng:
            return w_l[rows, 2]
        return dot(take_rows(self.ng, rows), take_rows(w, rows))

    def f(self, w, w_l):
        """``f |cos|`` toward ``w`` (world) / ``w_l`` (local), with the geometric-side rule and,
        with smooth shading, the camera side's BSDF (Cycles' rule where its direction falls
        below the shading normal) and in importance mode its adjoint with Veach's correction
        (:mod:`.adjoint_normals`)."""
        if self.smooth:
            if self.mode == IMPORTANCE:
                return self._adjoint().f_importance(self.wo, w)
            return self._adjoint().f_radiance(self.wo, w)
        return eval_bsdf(self.params, self.wo_l, w_l, self.mode)

    def values(self, w, w_l):
        """:meth:`f`, :meth:`pdf_toward` and :meth:`pdf_back` of ``w`` / ``w_l`` in one call
        (under flat shading one dispatch and one gather per BSDF family,
        :func:`core.materials.bsdf_values.eval_with_pdfs`): ``(m, 3), (m,), (m,)``."""
        if self.smooth:
            return self.f(w, w_l), self.pdf_toward(w_l), self.pdf_back(w_l)
        return eval_with_pdfs(self.params, self.wo_l, w_l, self.mode)

    def pdf_toward(self, w_l):
        """Solid-angle density of sampling ``w_l`` given the incoming direction (this side's
        sampling: the mixture of :mod:`.adjoint_normals` on smooth light vertices)."""
        if self.smooth:
            w = self._world(w_l)
            if self.mode == IMPORTANCE:
                return self._adjoint().pdf_light(self.wo, w)
            return self._adjoint().pdf_camera(self.wo, w)
        return pdf_bsdf(self.params, self.wo_l, w_l)

    def pdf_back(self, w_l):
        """Solid-angle density of sampling the incoming direction given ``w_l`` (the other
        side's sampling)."""
        if self.smooth:
            w = self._world(w_l)
            if self.mode == IMPORTANCE:
                return self._adjoint().pdf_camera(w, self.wo)
            return self._adjoint().pdf_light(w, self.wo)
        return pdf_bsdf(self.params, w_l, self.wo_l)


def to_area(pdf_sa, cos_at, dist):
    """Solid-angle density -> area density at a point ``dist`` away (cosine ``cos_at`` there);
    unchanged toward infinite endpoints (``dist = inf``)."""
    finite = np.isfinite(dist)
    if finite.all():  # the usual case: no selection (the same values)
        return pdf_sa * np.abs(cos_at) / np.maximum(dist * dist, 1e-300)
    d2 = np.where(finite, dist * dist, 1.0)
    return np.where(finite, pdf_sa * np.abs(cos_at) / np.maximum(d2, 1e-300), pdf_sa)


def walk(ctx, sub, o, d, tmax, beta, pdf_prev, prev_delta, vis, rows, stream, mode, dims_of,
         depth, on_segment=None, on_vertex=None):
    """Stage *random walk*: extend ``sub`` from vertex 0 with the rays ``o, d`` of ``rows``.

    Vertices ``1..depth-1`` are made. ``pdf_prev (m,)`` is the solid-angle density of the first
    ray (the disk's area density for infinite light endpoints, whose ``d_prev`` is inf),
    ``prev_delta`` whether it came from a delta lobe, ``beta (m, 3)`` its throughput. With
    ``on_segment(j, rows, o, d, hits, beta, pdf_prev, prev_delta)`` (the camera side, for
    ``s = 0``) one more segment is traced after the last vertex, for the emitters it finds.
    With ``on_vertex(j, rows, si, frame, wo_l, params, delta_only, beta)`` each vertex is
    handed over as it is made (the subpaths ``rows (k,)``, their
    :class:`.common.Interaction`, shading frame, BSDF and throughput); with ``sub`` None
    nothing is stored (light tracing connects every vertex as it is made, so it keeps none).
    ``stream`` itself is not advanced: the walk draws from a copy. Transparent surfaces on the
    way are passed straight through, not made vertices (:mod:`.transparent_passes`; the
    segments after a pass go to ``on_segment`` too).

    Russian roulette weighs a path's throughput relative to its first ray's (``1`` for camera
    rays; the emitted power over its density for light paths, in Watts): survival then
    follows what the BSDFs have absorbed, whatever the scene's size and power. On absolute
    throughput a light path of a small or dim scene (throughput << 1 at its start) would be
    killed with probability near one and the few survivors weighted by hundreds: unbiased,
    but so heavy-tailed that an estimate from thousands of paths reads low.
    """
    prep, settings = ctx.prep, ctx.settings
    path_stream = None
    start = max_component(beta)
    # None where every first ray's throughput is one (camera rays): the roulette's scaling by
    # one would change no value, and its gathers per bounce are saved.
    rr_scale = (None if (start == 1.0).all()
                else np.where(start > 0, 1.0 / np.where(start > 0, start, 1.0), 1.0))
    last = depth + int(on_segment is not None)
    passes = Passes(rows.size) if has_passes(prep) else None
    # Plain diffuse BSDFs under flat shading choose no lobe, component or pass: the lobe's
    # number is not drawn (its dimension is skipped, as the path tracer skips it).
    draws_lobe = not (prep.lambert_only and not ctx.smooth and passes is None)
    # ng . d of the rays' origins (j >= 2), from their offsets: |ng . wo| at the hits' previous
    # vertex, for _store_vertex (the same dot product per row, and wo = -d changes only its
    # sign).
    cos_origin = None
    # The survivors of the last roulette, not yet taken from path_stream: its compactions are
    # composed with the next hits' (one gather of its per-path arrays per bounce, not two).
    pending = None
    for j in range(1, last):
        hits = intersect_by_class(prep.accel, o, d, tmax, vis)
        ctx.counters.rays += o.shape[0]
        if on_segment is not None:
            on_segment(j, rows, o, d, hits, beta, pdf_prev, prev_delta)
        u_pass = None
        if passes is not None:
            # Straight through transparent surfaces to the next vertex (not vertices).
            hits, beta, u_pass = passes.resolve(ctx, j, rows, o, d, tmax, hits, beta, vis,
                                                stream, dims_of(j), on_segment, pdf_prev,
                                                prev_delta)
        if j == depth:
            break
        live = surface_hits(prep, hits)
        if live.size == 0:
            break
        # Smooth shading: frames around the shading normal as the path tracer's (nm); flat
        # shading's frames are around ng (si.ns is not formed).
        si = surface_interaction(prep, hits, d, live, keep_below=True, shading=ctx.smooth)
        r = rows[live]
        # Draw for the live paths only (a copy of the stream compacted along with them).
        if path_stream is None:
            path_stream = copy.copy(stream)
            path_stream.compact(r)
        else:
            path_stream.compact(live if pending is None else pending[live])
            pending = None
        path_stream.skip_to(dims_of(j))
        # Lobe (or skipped), BSDF and roulette (or skipped) numbers in one call.
        u_lobe, u_bsdf, u_rr = path_stream.next_slots(
            (int(draws_lobe), 2, int(roulette_at(settings, j - 1))))
        if u_lobe is None:
            u_lobe = np.zeros(r.size)
        if u_pass is not None:  # the number left after the choices of the passes
            u_lobe = np.where(np.isnan(u_pass[live]), u_lobe, u_pass[live])
        params, delta_only, u_lobe = prep.choose_bsdf(si.prim, u_lobe, si.u, si.v)
        tangent = shading_tangents(prep, si)
        if ctx.smooth:
            front = np.where(dot(si.ns, si.ng) < 0, -1.0, 1.0)
            fs, ft, fn = shading_frame(si.ns * front[:, None], tangent)
        elif ctx.triangle_frames is not None:  # the hit triangles' own (.vertex_frames)
            fs, ft, fn = (take_rows(ctx.triangle_frames[0], si.prim),
                          take_rows(ctx.triangle_frames[1], si.prim), si.ng)
        else:
            fs, ft, fn = shading_frame(si.ng, tangent)
        if sub is not None and on_vertex is None and sub.by_triangle:
            # Its z alone (the frame's normal is ng): all that is stored and read of it.
            wo_l = np.zeros((r.size, 3))
            dots(si.wo, fn, out=wo_l[:, 2])
        else:
            wo_l = to_local(si.wo, fs, ft, fn)
        params = with_bump_normals(params, si, (fs, ft, fn))
        params = with_coat_normals(params, coat_normals_in_front(si), (fs, ft, fn))
        beta = take_rows(beta, live)
        if passes is not None:
            passes.take(live)
            ctx.vertex_passes = passes.passed
        if on_vertex is not None:
            on_vertex(j, r, si, (fs, ft, fn), wo_l, params, delta_only, beta)
        if sub is not None:
            dist, cos_prev, d2 = _store_vertex(sub, j, r, si, hits, live, (fs, ft, fn), wo_l,
                                               params, delta_only, beta, pdf_prev, prev_delta,
                                               cos_origin)
            if passes is not None:
                sub.passed[j][r] = passes.passed
                sub.passes_stored = True
        if j == depth - 1 and on_segment is None:
            break

        # Sample the BSDF for the next vertex; the reverse density goes to vertex j - 1.
        smp, wi, weight, back = _scatter(ctx.smooth, mode, si, (fs, ft, fn), wo_l, params,
                                         u_lobe, u_bsdf, sub is not None,
                                         bends_normals(prep.scene, si.prim) if ctx.smooth
                                         else None, prep.lambert_only)
        if sub is not None:
            # As to_area, with the squared distances the forward density took.
            back = (to_area(back, cos_prev, dist) if d2 is None
                    else back * np.abs(cos_prev) / d2)
            if smp.delta.any():  # else every flag stays as recycle() cleared it
                back = np.where(smp.delta, 1.0, back)
                sub.delta[j][r] = smp.delta
            put_rows(sub.pdf_rev[j - 1], r, back)
        beta = beta * weight
        alive = (smp.pdf > 0) & finite_rows(beta)
        if rr_scale is not None:
            rr_scale = rr_scale[live]
        alive, beta = russian_roulette(beta, alive, u_rr, settings, j - 1, rr_scale)
        keep = alive.nonzero()[0]
        if keep.size == 0:
            break
        if keep.size == alive.size:  # every path goes on: no compaction (same arrays)
            cos_origin = dot(si.ng, wi)
            rows, d, o = r, wi, prep.accel.offset_origin(si.p, si.ng, si.prim, wi, cos_origin)
            pdf_prev, prev_delta, vis = smp.pdf, smp.delta, ray_class(smp.lobe)
            tmax = np.full(keep.size, np.inf)
            continue
        rows = r[keep]
        if rr_scale is not None:
            rr_scale = rr_scale[keep]
        if passes is not None:
            passes.take(keep)
        pending = keep
        beta = take_rows(beta, keep)
        d = take_rows(wi, keep)
        ng = take_rows(si.ng, keep)
        cos_origin = dot(ng, d)
        o = prep.accel.offset_origin(take_rows(si.p, keep), ng, si.prim[keep], d, cos_origin)
        tmax = np.full(keep.size, np.inf)
        pdf_prev = smp.pdf[keep]
        prev_delta = smp.delta[keep]
        vis = ray_class(smp.lobe[keep])


def _scatter(smooth, mode, si, frame, wo_l, params, u_lobe, u_bsdf, reverse, bends=None,
             lambert=False):
    """Stage *sample BSDF* of a walk: the sample, its world direction ``wi``, its weight and
    (``reverse``) the other side's solid-angle density of ``si.wo`` given ``wi``. With smooth
    shading, camera paths sample as the path tracer does (Cycles' rule where the view falls
    below the shading normal) and report the light side's density, light paths sample and
    weigh as its adjoint (:mod:`.adjoint_normals`; ``bends``: :func:`.common.bends_normals`
    of the hits). ``lambert``: every material is plain diffuse
    (``PreparedScene.lambert_only``)."""
    normals = VertexNormals(params, frame, si.ng, si.nm, bends) if smooth else None
    if normals is not None and mode == IMPORTANCE:
        wi, weight, pdf, delta, lobe = normals.sample_importance(si.wo, u_lobe, u_bsdf)
        smp = BSDFSample(to_local(wi, *frame), weight, pdf, delta, lobe)
        back = normals.pdf_camera(wi, si.wo) if reverse else None
        return smp, wi, weight, back
    if normals is not None:
        smp, wi, weight = normals.sample_radiance(si.wo, u_lobe, u_bsdf)
        back = normals.pdf_light(wi, si.wo) if reverse else None
        return smp, wi, weight, back
    # Plain diffuse rows (no bump or coat normals either) skip the BSDF dispatch.
    plain = lambert and not any(params.has(group) for group in OPTIONAL_GROUPS)
    smp = (sample_plain_diffuse(params, wo_l, u_bsdf, mode) if plain
           else sample_bsdf(params, wo_l, u_lobe, u_bsdf, mode))
    wi = to_world(smp.wi, *frame)
    pdf = pdf_plain_diffuse if plain else pdf_bsdf
    back = pdf(params, smp.wi, wo_l) if reverse else None
    return smp, wi, smp.weight, back


def _store_vertex(sub, j, r, si, hits, live, frame, wo_l, params, delta_only, beta, pdf_prev,
                  prev_delta, cos_origin=None):
    """Store the surface hits ``live`` as vertex ``j`` of the subpaths ``r`` of ``sub``, with the
    shading ``frame`` (three (k, 3) axes), ``wo_l`` in it and the chosen BSDF ``params``;
    ``beta`` is the hits' throughput, ``pdf_prev`` and ``prev_delta`` those of the rays that
    found them (all the rays, ``live`` picks the hits), ``cos_origin`` (all the rays, ``j >= 2``)
    ``ng . d`` at their origins (else gathered by :meth:`Subpath.normals`). Returns
    the distances ``(k,)`` from vertex ``j - 1`` (inf after an infinite light endpoint),
    the cosines ``(k,)`` stored there as ``cos_prev`` and, where every distance is finite,
    the clamped squared distances ``(k,)`` that :func:`to_area` divides by (else None)."""
    # The edge from vertex j - 1, then the forward density in area measure (times the cosine
    # alone after an infinite endpoint, whose rays are parallel).
    if j == 1:
        dist = norms(si.p - take_rows(sub.p[0], r))
        dist = np.where(np.isfinite(sub.d_prev[0][r]), dist, np.inf)
        cos_prev = sub.cos_prev[0][r]
    else:
        dist = hits.t[live]
        cos_prev = np.abs(dot(sub.normals(j - 1, r), si.wo) if cos_origin is None
                          else cos_origin[live])
    sub.cos_prev[j][r] = cos_prev
    # Where the frame's normal is ng (flat shading), wo_l's z is already that cosine.
    cos_here = np.abs(wo_l[:, 2] if frame[2] is si.ng else dot(si.ng, si.wo))
    pdf_sa = pdf_prev[live]
    if np.isfinite(dist).all():  # to_area's values; its d2 kept for the reverse density
        d2 = np.maximum(dist * dist, 1e-300)
        fwd = pdf_sa * cos_here / d2  # cos_here is non-negative: to_area's abs is a no-op
    else:
        d2 = None
        fwd = to_area(pdf_sa, cos_here, dist)
        inf = np.isinf(dist)
        if inf.any():
            fwd = np.where(inf, pdf_sa * cos_here, fwd)
    # Stores go through the vertex's own rows (sub.x[j], contiguous): faster than sub.x[j, r].
    sub.valid[j][r] = True
    for name, value in (("p", si.p), ("prim", si.prim), ("connectible", ~delta_only),
                        ("beta", beta), ("d_prev", dist),
                        ("pdf_fwd", np.where(prev_delta[live], 1.0, fwd) if prev_delta.any()
                         else fwd)):
        put_rows(getattr(sub, name)[j], r, value)
    # Else ng, fn (flat shading: ng), the BSDF rows and the whole of wo_local are stored.
    by_triangle = sub.by_triangle
    if by_triangle:
        put_rows(sub.wo_z[j], r, wo_l[:, 2])
    else:
        put_rows(sub.ng[j], r, si.ng)
        put_rows(sub.wo_local[j], r, wo_l)
    if sub.tri_frames is None:  # else gathered by prim (gather_frames)
        put_rows(sub.fs[j], r, frame[0])
        put_rows(sub.ft[j], r, frame[1])
    if not sub.flat_frames:  # else fn is ng, stored above (the frame's normal is si.ng)
        put_rows(sub.fn[j], r, frame[2])
    if si.nm is not None:  # smooth shading (corner normals): what Gathered reads then
        put_rows(sub.wo[j], r, si.wo)
        put_rows(sub.nm[j], r, si.nm)
    if not by_triangle:
        sub.store_params(j, r, params)
    return dist, cos_prev, d2
