"""Photon tracing: particles from the lights, stored where they land on non-specular surfaces.

A photon starts as a light subpath does in light tracing and BDPT: an emitter chosen with the
light sampler's selection, a point and a direction on it (:class:`core.lights.Emission`,
``sample_le``), power ``Le cos / (pdf_origin pdf_dir)``. It then scatters by BSDF sampling in
importance mode (with smooth shading: the adjoint of the camera side's BSDF,
:class:`core.integrators.adjoint_normals.VertexNormals`, as light tracing's) and
is continued by Russian roulette *by albedo*: it survives with probability
``q = min(1, max(beta') / max(beta))`` and its power is divided by ``q``, so surviving photons
keep roughly the power they had (Jensen's photon tracing) and the estimate stays unbiased.

Transparent surfaces (Transparent BSDF, Principled Alpha, a Mix with a Transparent BSDF) are
passed straight through, as light tracing's walks do: a pass is no hit (:mod:`.passes`).
Every hit on a surface that is not purely specular (a delta BSDF cannot be density-estimated)
is a stored photon: its position, the geometric normal of the surface it landed on, the
direction back toward where it came from, its power, the number of the hit along the path (1:
direct from the light), whether every earlier bounce was specular (``caustic``: a path
``L S+ D``) and whether no two neighbours on the path so far are both non-specular
(``unconnectable``: ``L S+ (D S+)* D``, the light subpaths no connection of BDPT can join when
the light is a point). Storage is float32 (positions relative to the
prepared scene's origin, which :func:`core.prepare.recentred` puts at the scene's centre), and
the number of photons a setting may store is bounded by a memory cap (:func:`check_memory`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import RenderRefused
from ..integrators.adjoint_normals import VertexNormals
from ..integrators.base import Counters
from ..integrators.common import (bends_normals, intersect_by_class, max_component, ray_class,
                                  shading_tangents, surface_hits, surface_interaction,
                                  with_bump_normals, with_coat_normals,
                                  coat_normals_in_front)
from ..materials.bsdf import IMPORTANCE, BSDFSample, sample_bsdf
from ..materials.frame import shading_frame, to_local, to_world
from ..sampling.samplers import make_sampler
from ..scene import VIS_SHADOW
from .lookup import require_scipy
from .passes import lobe_numbers, pass_walk

# Sample dimensions of a photon: emitter choice, point 2-D, direction 2-D; then per hit the
# BSDF lobe, the BSDF direction 2-D and Russian roulette.
DIMS_START = 5
DIMS_PER_HIT = 4
# Bytes per stored photon: float32 position, normal, direction and power, int16 hit number, bool
# caustic and unconnectable flags; plus the kd-tree's float64 copy of the position and its int64
# index.
BYTES_PER_PHOTON = 4 * 12 + 2 + 2 + 24 + 8
FIELDS = ("p", "n", "wi", "power", "hit", "caustic", "unconnectable")


@dataclass
class Photons:
    """Stored photons, struct-of-arrays.

    Attributes
    ----------
    p : (m, 3) float32
        Positions (prepared frame).
    n : (m, 3) float32
        Unit geometric normal of the surface at each position (the side as stored; the
        surface-compatibility test of :mod:`.compatible` compares it with a visible point's).
    wi : (m, 3) float32
        Unit direction from the position back toward where the photon came from.
    power : (m, 3) float32
        Power (flux) carried, per emitted photon: an estimate divides by photons emitted.
    hit : (m,) int16
        Number of the hit along the light path (1: straight from the emitter).
    caustic : (m,) bool
        Every earlier bounce was specular, and there was at least one (``L S+ D``).
    unconnectable : (m,) bool
        No two consecutive vertices of the path from the light up to here (the light and this
        photon's surface included) are both non-specular: ``L S+ (D S+)* D``. With a delta
        light (a point) and a camera path ``E S+`` to the same point through a pinhole, the
        whole path has no edge between two non-delta vertices, so no strategy of BDPT (nor
        path or light tracing) can sample it: SPPM's reference tool
        (``tools/photons_reference.py``) adds this light to a BDPT reference.
    """

    p: np.ndarray
    n: np.ndarray
    wi: np.ndarray
    power: np.ndarray
    hit: np.ndarray
    caustic: np.ndarray
    unconnectable: np.ndarray

    @staticmethod
    def join(parts):
        """The photons of ``parts`` in order (an empty store if there are none)."""
        parts = list(parts)
        if not parts:
            z3 = np.zeros((0, 3), np.float32)
            return Photons(z3, z3, z3, z3, np.zeros(0, np.int16), np.zeros(0, bool),
                           np.zeros(0, bool))
        return Photons(*(np.concatenate([getattr(p, name) for p in parts]) for name in FIELDS))

    def take(self, rows):
        """The photons ``rows`` (index array or mask)."""
        return Photons(*(getattr(self, name)[rows] for name in FIELDS))

    def __len__(self):
        return self.p.shape[0]

    @property
    def nbytes(self):
        """Bytes the arrays hold (without a kd-tree)."""
        return sum(getattr(self, name).nbytes for name in FIELDS)


def worst_case_bytes(photons, max_bounces):
    """Bytes needed if each of ``photons`` emitted photons were stored at every one of its
    ``max_bounces + 1`` possible hits (with the kd-tree's copy)."""
    return int(photons) * (int(max_bounces) + 1) * BYTES_PER_PHOTON


def check_memory(photons, max_bounces, cap_mb):
    """Raise ``RenderRefused`` if ``photons`` photons with ``max_bounces`` could need more than
    ``cap_mb`` megabytes of photon storage (the message names the settings to change)."""
    need = worst_case_bytes(photons, max_bounces)
    if need > cap_mb * (1 << 20):
        raise RenderRefused(
            f"photon storage: {photons:,} photons x up to {max_bounces + 1} stored hits each "
            f"may need {need / (1 << 20):,.0f} MB, more than the Photon Memory cap of "
            f"{cap_mb:,.0f} MB: lower Photons or Max Bounces, or raise Photon Memory")


def trace_photons(prep, stream, max_bounces, counters, min_hit=1,
                  transparent=None):
    """Stage *photon tracing*: one photon per entry of ``stream``, stored at every
    non-specular hit from hit ``min_hit`` up to ``max_bounces + 1`` hits. Transparent
    surfaces are passed straight through (not hits, :mod:`.passes`), up to ``transparent``.

    Parameters
    ----------
    prep : core.prepare.PreparedScene
    stream : core.sampling.stream.SampleStream
        One sample vector per photon (dimensions :data:`DIMS_START` + :data:`DIMS_PER_HIT`
        per hit); compacted to the photons still travelling (consumed).
    max_bounces : int
    counters : core.integrators.base.Counters
    min_hit : int
        First hit stored (2: leave out the photons straight from a light, which SPPM does not
        use: its direct light comes from next-event estimation).
    transparent : int or None
        The Transparent limit: a photon ends at its pass beyond it (None: the option's
        default).

    Returns
    -------
    Photons
    """
    em = prep.emission
    stream.skip_to(0)
    u_sel, u_pos, u_dir = stream.next_1d(), stream.next_2d(), stream.next_2d()
    pts = em.sample_points(u_sel, u_pos, counters)
    origin, w, pdf_dir, cos_l, le = em.sample_directions(pts, u_dir)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        beta = le * (cos_l / (pts.pdf_origin * pdf_dir))[:, None]
    good = (pts.index >= 0) & (pdf_dir > 0) & (pts.pdf_origin > 0) & np.isfinite(beta).all(1)
    rows = np.nonzero(good & (max_component(np.where(good[:, None], beta, 0.0)) > 0))[0]
    o = _leave_emitters(prep, pts, origin, w, rows)
    stream.compact(rows)
    return _walk(prep, stream, o, w[rows], beta[rows], max_bounces, counters, min_hit,
                 transparent)


def _leave_emitters(prep, pts, origin, w, rows):
    """Ray origins of the photons ``rows``: lamps emit from the point itself, emissive
    triangles from a point pushed off their surface toward ``w``."""
    o = origin[rows]
    k = prep.lights.n_lights
    tri = np.nonzero((pts.index[rows] >= k) & ~pts.infinite[rows])[0]
    if tri.size:
        prim = prep.lights.emissive_tris[pts.index[rows][tri] - k]
        o[tri] = prep.accel.offset_origin(o[tri], pts.normal[rows][tri], prim, w[rows][tri])
    return o


def _walk(prep, stream, o, d, beta, max_bounces, counters, min_hit, transparent):
    """Scatter the photons of ``stream`` from ``o`` along ``d``; store every non-specular hit
    from hit ``min_hit`` on, passing transparent surfaces (up to ``transparent``) on the way.
    The stream is compacted as photons leave (so that later bounces draw samples for the
    survivors only: the values do not change)."""
    smooth = prep.scene.corner_normals is not None
    n = beta.shape[0]
    vis = np.full(n, VIS_SHADOW, np.int32)
    specular = np.zeros(n, bool)  # every bounce so far was specular (and one happened)
    unconnectable = np.ones(n, bool)  # no two non-specular neighbours so far (light: delta)
    last_rough = np.zeros(n, bool)  # the previous hit was not purely specular
    walk = pass_walk(prep, transparent, counters, n)
    parts = []
    for hit in range(1, max_bounces + 2):
        if beta.shape[0] == 0:
            break
        hits = intersect_by_class(prep.accel, o, d, None, vis)
        counters.rays += beta.shape[0]
        dim = DIMS_START + (hit - 1) * DIMS_PER_HIT
        u_pass = None
        if walk is not None:  # straight through transparent surfaces (no hits)
            hits, beta, u_pass = walk.resolve(hit, np.arange(beta.shape[0]), o, d, None, hits,
                                              beta, vis, stream, dim)
        live = surface_hits(prep, hits)
        si = surface_interaction(prep, hits, d, live)
        stream.compact(live)
        if walk is not None:
            walk.take(live)
        stream.skip_to(dim)
        u_lobe, u_bsdf, u_rr = stream.next_1d(), stream.next_2d(), stream.next_1d()
        u_lobe = lobe_numbers(u_lobe, u_pass, live)
        params, delta_only, u_lobe = prep.choose_bsdf(si.prim, u_lobe, hits.u[live],
                                                      hits.v[live])
        beta, specular = beta[live], specular[live]
        # A rough hit straight from the light (NEE's edge) or after a rough hit is an edge
        # BDPT can connect.
        rough = ~delta_only
        unconnectable = unconnectable[live] & ~(rough & (last_rough[live] | (hit == 1)))
        last_rough = rough
        store = np.nonzero(rough)[0] if hit >= min_hit else np.zeros(0, np.int64)
        parts.append(Photons(si.p[store].astype(np.float32), si.ng[store].astype(np.float32),
                             si.wo[store].astype(np.float32),
                             beta[store].astype(np.float32),
                             np.full(store.size, hit, np.int16), specular[store],
                             unconnectable[store]))
        if hit == max_bounces + 1:
            break
        # Importance-mode BSDF sampling, then roulette by albedo. Smooth shading: the
        # adjoint of the camera side's BSDF, as light paths (adjoint_normals).
        smp, wi = _scatter(prep, si, params, u_lobe, u_bsdf, smooth)
        new = beta * smp.weight
        with np.errstate(divide="ignore", invalid="ignore"):
            q = np.minimum(1.0, max_component(new) / max_component(beta))
        alive = (smp.pdf > 0) & np.isfinite(new).all(axis=1) & (u_rr < q) & (q > 0)
        keep = np.nonzero(alive)[0]
        stream.compact(keep)
        if walk is not None:
            walk.take(keep)
        beta = new[keep] / q[keep, None]
        specular = np.where(hit == 1, smp.delta, specular & smp.delta)[keep]
        unconnectable, last_rough = unconnectable[keep], last_rough[keep]
        o = prep.accel.offset_origin(si.p[keep], si.ng[keep], si.prim[keep], wi[keep])
        d = wi[keep]
        vis = ray_class(smp.lobe[keep])
    return Photons.join(parts)


def _scatter(prep, si, params, u_lobe, u_bsdf, smooth):
    """Stage *sample BSDF* of a photon at the hits ``si``: the sample (its weight with the
    shading-normal correction) and its world direction. With smooth shading the photon samples
    the adjoint of the camera side's BSDF (:class:`.adjoint_normals.VertexNormals`), as light
    tracing and BDPT's light subpaths."""
    tangent = shading_tangents(prep, si)
    if smooth:
        frame = shading_frame(si.nm, tangent)
        params = with_bump_normals(params, si, frame)
        params = with_coat_normals(params, coat_normals_in_front(si), frame)
        normals = VertexNormals(params, frame, si.ng, si.nm, bends_normals(prep.scene, si.prim))
        wi, weight, pdf, delta, lobe = normals.sample_importance(si.wo, u_lobe, u_bsdf)
        return BSDFSample(None, weight, pdf, delta, lobe), wi
    frame = shading_frame(si.ng, tangent)
    params = with_bump_normals(params, si, frame)
    smp = sample_bsdf(params, to_local(si.wo, *frame), u_lobe, u_bsdf, IMPORTANCE)
    return smp, to_world(smp.wi, *frame)


# Photons or camera paths per chunk: the unit of work a worker thread runs.
CHUNK = 1 << 15


def spans(n, parts, most=CHUNK):
    """``[(start, stop), ...]``: ``range(n)`` cut into near-equal spans, at least ``parts``
    (so that every worker thread gets one) and none longer than ``most``."""
    count = min(n, max(int(parts), -(-n // most))) if n > 0 else 0
    edges = np.linspace(0, n, count + 1).round().astype(np.int64)
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


def scene_diagonal(prep):
    """Length of the diagonal of the scene's bounding box (1 for a scene without vertices)."""
    v = np.asarray(prep.scene.vertices, np.float64).reshape(-1, 3)
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0))) if v.size else 1.0


def auto_radius(prep):
    """Photon Mapping's radius when the setting is 0: 1/100 of the scene's bounding-box
    diagonal."""
    return 0.01 * scene_diagonal(prep)


# SPPM's initial radius when the setting is 0, in units of diagonal / larger image side (chosen
# by a sweep, docs/PHOTONS.md; Mitsuba 0.6's SPPM guesses 2.5 of them).
SPPM_RADIUS_PIXELS = 1.25


def sppm_auto_radius(prep):
    """SPPM's initial radius when the setting is 0: :data:`SPPM_RADIUS_PIXELS` times the scene's
    bounding-box diagonal over the larger side of the image in pixels, so that the first
    passes blur over a few pixels at any resolution (the radius then shrinks)."""
    camera = prep.scene.camera
    return SPPM_RADIUS_PIXELS * scene_diagonal(prep) / max(camera.width, camera.height, 1)


def photon_seed(seed):
    """Seed of the photons' sample streams: another stream family than the camera's."""
    return (int(seed) * 2654435761 + 0x9E3779B9) % ((1 << 31) - 1)


def photon_setup(prep, settings, default_radius=auto_radius):
    """What both photon estimators take from the settings, checked before a render starts
    (scipy importable, the photons within the memory cap): ``(photons, radius, sampler)``, the
    photon count, the given radius or ``default_radius(prep)``, and :func:`photon_sampler`."""
    require_scipy()
    check_memory(settings.photons, settings.max_bounces, settings.photon_memory)
    radius = float(settings.photon_radius) or default_radius(prep)
    return int(settings.photons), radius, photon_sampler(settings, prep.scene.camera.width)


def photon_sampler(settings, width):
    """The sampler of the photons (the render's kind, its own seed); photon ``i`` of pass
    ``k`` is its 'pixel' ``i``, sample ``k``."""
    return make_sampler(settings.sampler, seed=photon_seed(settings.seed),
                        spp=settings.spp if settings.spp > 0 else None, width=width)


def photon_chunk(prep, settings, sampler, pass_index, span, min_hit=1):
    """Photons ``span = (start, stop)`` of pass ``pass_index`` (streams of ``sampler``, see
    :func:`photon_sampler`): ``(Photons, Counters)``. The photons do not depend on how a pass
    is cut into spans."""
    ids = np.arange(*span, dtype=np.int64)
    local = Counters()
    stream = sampler.stream(ids, np.full(ids.size, pass_index, np.int64))
    return trace_photons(prep, stream, settings.max_bounces, local, min_hit,
                         settings.transparent_max_bounces), local


def trace_photon_chunks(prep, settings, sampler, n, pass_index, map_chunks, counters):
    """``n`` photons of pass ``pass_index`` (:func:`photon_chunk`), traced in chunks (one per
    worker thread at least, :func:`spans`) by ``map_chunks`` (the render loop's worker
    threads); None if the render was cancelled meanwhile."""
    from ..passes import thread_count  # the render loop imports the integrators

    parts = map_chunks(lambda span: photon_chunk(prep, settings, sampler, pass_index, span),
                       spans(n, thread_count(settings)))
    if parts is None:
        return None
    for _, local in parts:
        counters.add(local)
    return Photons.join(p for p, _ in parts)
