"""The bidirectional estimators' common driver: light tracing (:mod:`.light`) and BDPT
(:mod:`.bdpt`) are :class:`Bidirectional` integrators.

Per sample, a camera subpath and a light subpath (:mod:`.subpaths`); the strategies every
bidirectional estimator uses, ``s = 0`` (emitters the camera subpath finds,
:mod:`.camera_hits`) and ``t = 1`` (light vertices seen by the pinhole, :mod:`.connections`);
a subclass adds its own (:meth:`Bidirectional.connect`). Batches are cut into chunks of
``CHUNK`` paths (an integrator's ``chunk_paths``) so that the stored subpath arrays stay small
(light tracing, which stores none, walks a work unit whole).
"""

from __future__ import annotations

import threading
from typing import ClassVar

import numpy as np

from ..camera import camera_pdf, camera_position
from ..materials.bsdf import IMPORTANCE, RADIANCE
from ..rows import combine_rows
from ..sampling.mis import MIS
from ..scene import VIS_CAMERA, VIS_SHADOW
from .base import Integrator, render_in_chunks
from .camera_hits import camera_emission
from .common import camera_rays, finite_rows, max_component, strategy_pass_names, take_rows
from .connections import camera_splatter, connect_cameras
from .strategy_views import Tally
from .subpaths import Subpath, walk
from .vertex_frames import triangle_frames
from ..quiet import quiet

# Paths per chunk: keeps the subpath arrays (depth x paths) small.
CHUNK = 8192
# Sample dimensions: 0-1 pixel filter; per camera vertex: BSDF lobe, BSDF 2-D, roulette, light
# selection, light point 2-D (for s = 1); then the light subpath: selection, point 2-D,
# direction 2-D, and per light vertex: lobe, BSDF 2-D, roulette.
DIMS_CAMERA = 2
DIMS_PER_CAMERA_VERTEX = 7
DIMS_LIGHT_START = 5
DIMS_PER_LIGHT_VERTEX = 4


class _Context:
    """What the stages of one chunk share: the integrator's per-render constants, this
    batch's counters and the light subpaths' endpoints once sampled."""

    def __init__(self, integrator, counters, pixel_filter):
        self.prep = integrator.prep
        self.settings = integrator.settings
        self.counters = counters
        self.emission = integrator.emission
        self.cam = integrator.cam
        self.cam_pos = integrator.cam_pos
        self.smooth = integrator.smooth
        self.mis = integrator.mis
        self.weighs = integrator.weighs
        self.view_length = integrator.view_length
        # Light paths reach edge pixels through the filter's reach outside the image.
        self.film_margin = 0.5 * pixel_filter.support
        self.window = integrator.window
        self.film_pixels = integrator.film_pixels
        self.light_points = None  # the light subpaths' endpoints, once sampled
        # BDPT's Connection Roulette of this batch (set by BDPT.connect; None: off).
        self.roulette = None
        # Transparent passes of the walk's live paths before their current vertex
        # (:class:`.transparent_passes.Passes`; None while every surface is opaque).
        self.vertex_passes = None
        self.buffers = integrator.buffers
        self.triangle_frames = integrator.triangle_frames

    def subpath(self, side, depth, n):
        """An empty :class:`Subpath` of ``depth`` vertices for ``n`` samples: this thread's
        buffer for ``side`` (``"camera"`` or ``"light"``) if it has that shape."""
        sub = getattr(self.buffers, side, None)
        if sub is None or sub.valid.shape != (depth, n):
            prep = self.prep
            # Plain untextured diffuse BSDFs take their colour from the triangle's material
            # (PreparedScene.choose_bsdf), as the path tracer's Lambert shading does.
            colors = prep.tri_albedo if prep.plain_diffuse else None
            sub = Subpath.empty(depth, n, not self.smooth, prep.lambert_only,
                                self.triangle_frames, prep.tri_normal, colors)
            setattr(self.buffers, side, sub)
            return sub
        return sub.recycle()


def _light_subpath(ctx, stream, n, base, depth, on_vertex=None):
    """Stage *generate light subpath*: emitter point and direction, then the random walk.

    With ``on_vertex`` (see :func:`.subpaths.walk`) the vertices are handed to it and none is
    stored (light tracing): None is returned."""
    em, prep = ctx.emission, ctx.prep
    L = ctx.subpath("light", depth, n) if on_vertex is None else None
    stream.skip_to(base)
    u_sel, u_pos, u_dir = stream.next_slots((1, 2, 2))
    pts = em.sample_points(u_sel, u_pos, ctx.counters)
    origin, w, pdf_dir, cos_l, le = em.sample_directions(pts, u_dir)
    ctx.light_points = pts
    if L is not None:
        L.valid[0] = pts.index >= 0
        L.p[0] = np.where(pts.infinite[:, None], origin, pts.p) if pts.infinite.any() else pts.p
        L.ng[0] = pts.normal
        L.pdf_fwd[0] = pts.pdf_origin
        L.cos_prev[0] = np.where(pts.infinite | pts.delta_light, 1.0, cos_l)
        L.d_prev[0] = np.where(pts.infinite, np.inf, 0.0)
    with quiet("divide", "invalid", "over"):
        beta = combine_rows(((cos_l / (pts.pdf_origin * pdf_dir), le),))
    good = (pts.index >= 0) & (pdf_dir > 0) & (pts.pdf_origin > 0) & finite_rows(beta)
    rows = good.nonzero()[0]
    rows = rows[max_component(take_rows(beta, rows)) > 0]
    if depth < 2 or rows.size == 0:
        return L
    # Rays leave lamps (not geometry) from the point itself, emissive triangles pushed off.
    # Where every path goes on (the usual case), the arrays themselves (walk writes none of
    # them), not gathered copies.
    every = rows.size == n
    pick = (lambda a: a) if every else (lambda a: take_rows(a, rows))  # noqa: E731
    o, w = pick(origin), pick(w)
    index = pick(pts.index)
    k = prep.lights.n_lights
    tri = np.nonzero((index >= k) & ~pick(pts.infinite))[0]
    if tri.size == rows.size:  # every path leaves an emissive triangle: no row selections
        o = prep.accel.offset_origin(o, pick(pts.normal), prep.lights.emissive_tris[index - k],
                                     w)
    elif tri.size:
        o = o.copy() if every else o  # (origin is the light points' own array)
        prim = prep.lights.emissive_tris[index[tri] - k]
        o[tri] = prep.accel.offset_origin(take_rows(o, tri), take_rows(pts.normal, rows[tri]),
                                          prim, take_rows(w, tri))
    walk(ctx, L if on_vertex is None else None, o, w, np.full(rows.size, np.inf),
         pick(beta), pick(pdf_dir), np.zeros(rows.size, bool),
         np.full(rows.size, VIS_SHADOW, np.int32), rows, stream, IMPORTANCE,
         lambda j: base + DIMS_LIGHT_START + (j - 1) * DIMS_PER_LIGHT_VERTEX, depth,
         on_vertex=on_vertex)
    return L


def _camera_subpath(ctx, pixel_filter, stream, n, depth, out):
    """Stage *generate camera subpath*, adding the emitters it finds (``s = 0``) to ``out``."""
    prep, cam = ctx.prep, ctx.cam
    C = ctx.subpath("camera", depth, n)
    o, d, tmax = camera_rays(prep, pixel_filter, stream)
    C.valid[0] = True
    C.p[0] = ctx.cam_pos
    C.d_prev[0] = 0.0
    C.beta[0] = 1.0
    m = np.asarray(cam.to_world, np.float64)
    axis = -m[:3, 2] / np.linalg.norm(m[:3, 2])
    # einsum, not `@`: a (n, 3) x (3,) product wakes multi-threaded BLAS (see core.camera).
    pdf_cam = camera_pdf(cam, np.einsum("ij,j->i", d, axis), ctx.film_pixels)
    walk(ctx, C, o, d, tmax, np.ones((n, 3)), pdf_cam, np.zeros(n, bool),
         np.full(n, VIS_CAMERA, np.int32), np.arange(n), stream, RADIANCE,
         lambda j: DIMS_CAMERA + (j - 1) * DIMS_PER_CAMERA_VERTEX, depth,
         camera_emission(ctx, C, out))
    return C


class Bidirectional(Integrator):
    """The estimators built from a camera and a light subpath per sample (light tracing and
    BDPT): subpaths, the strategies every one of them uses (emitters seen by the camera
    subpath, ``s = 0``; light vertices seen by the pinhole, ``t = 1``), and the chunking.

    A subclass says how many camera vertices it traces (:meth:`camera_depth`), whether it
    weighs its strategies by MIS (``weighs``) and which strategies it adds
    (:meth:`connect`).
    """

    splats = True
    weighs: ClassVar[bool] = True
    # Whether the light subpaths are kept for connections (BDPT); without them (light tracing)
    # every light vertex is connected to the pinhole as the walk makes it (same splats, same
    # order, no stored vertices).
    stores_light_subpaths: ClassVar[bool] = True
    # Paths per chunk of :meth:`render_samples` (an instance may set its own; None: the whole
    # work unit at once).
    chunk_paths: ClassVar[int | None] = CHUNK

    def __init__(self, prep, settings):
        super().__init__(prep, settings)
        self.cam = prep.scene.camera
        if self.cam.type != "PERSP":
            raise ValueError("light tracing and BDPT need a perspective camera "
                             "(an orthographic camera cannot be reached from the lights)")
        self.cam_pos = camera_position(self.cam)
        self.emission = prep.emission  # built by core.prepare.prepare
        self.smooth = prep.scene.corner_normals is not None
        self.mis = MIS.from_settings(settings)
        self.view_length = (int(settings.strategy_max_length)
                            if self.strategy_views and settings.strategy_views else 0)
        if self.view_length:
            self.layers = tuple(strategy_pass_names(self.view_length))
        # A render region is a smaller film: splats outside it are not traced, and camera rays
        # are drawn over its pixels only (their density, for MIS, is over the region's area).
        self.window = settings.region
        self.film_pixels = (None if self.window is None else
                            (self.window[2] - self.window[0]) * (self.window[3] - self.window[1]))
        # Each worker thread's subpath arrays, reused from one chunk to the next.
        self.buffers = threading.local()
        # The walks' shading frames of flat triangles (None with smooth shading or tangents).
        self.triangle_frames = triangle_frames(prep)

    def camera_depth(self, depth):
        """Vertices of the camera subpaths when light subpaths have ``depth``."""
        return depth

    def connect(self, ctx, stream, C, L, out):
        """Strategies beyond ``s = 0`` and ``t = 1``: none here."""

    def render_samples(self, stream, pixel_filter, counters):
        """Image contributions of one sample (a camera and a light subpath) per entry of
        ``stream``, in chunks of at most ``chunk_paths`` paths."""
        n, chunk = len(stream), self.chunk_paths
        if chunk is not None and n > chunk:
            return render_in_chunks(self.render_samples, stream, chunk, pixel_filter, counters)
        settings = self.settings
        ctx = _Context(self, counters, pixel_filter)
        counters.camera_samples += n
        depth = settings.max_bounces + 2  # vertices per subpath (endpoint included)
        out = Tally(n, ctx.view_length)
        C = _camera_subpath(ctx, pixel_filter, stream, n, self.camera_depth(depth), out)
        base = DIMS_CAMERA + (depth + 1) * DIMS_PER_CAMERA_VERTEX
        if not self.stores_light_subpaths:
            _light_subpath(ctx, stream, n, base, depth, camera_splatter(ctx, out))
            return out.output(n)
        L = _light_subpath(ctx, stream, n, base, depth)
        stream.check_abort()  # the connections are most of BDPT's time
        self.connect(ctx, stream, C, L, out)
        stream.check_abort()
        connect_cameras(ctx, L, out)  # t = 1, every s >= 2
        return out.output(n)
