"""Stages shared by the integrators: camera rays, surface interactions, emitter hits."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..accel import Hits
from ..camera import generate_rays
from ..materials.bsdf import KIND_LAYERED, KIND_LAYERED_MS, LOBE_DIFFUSE, LOBE_TRANSMIT
from ..materials.frame import to_local
from ..bump import bump_mapped
from ..normal_maps import normal_mapped
from ..rows import combine_rows, divide_rows, put_rows
from ..scene import VIS_DIFFUSE, VIS_GLOSSY, VIS_TRANSMISSION


def take_rows(a, rows):
    """``a[rows]`` for an ndarray ``a`` and an index array ``rows (k,)``: ``ndarray.take``
    gathers the rows of an ``(n, 3)`` array about three times faster than fancy indexing (same
    values; the method, not ``np.take``, whose Python wrapper costs about 0.6 us a call)."""
    return a.take(rows, axis=0)


def add_rows(L, rows, value):
    """``L[rows] += value`` for ``L (N, 3)``, distinct ``rows (k,)``, ``value (k, 3)`` (the same
    sums; a take and a scatter of whole rows, :func:`core.rows.put_rows`, are faster than the
    fancy-index update)."""
    acc = L.take(rows, axis=0)
    acc += value
    put_rows(L, rows, acc)


def nonzero_rows(mask):
    """``np.nonzero`` of a 2-D mask ``(a, n)``: its ``(index, row)`` pairs in the same order
    (row-major), formed through ``np.flatnonzero``, about 2-3 x faster than the two-axis
    form."""
    return np.divmod(np.flatnonzero(mask), mask.shape[1])


def max_component(v):
    """Largest of the three channels of ``v (n, 3)`` (much faster than ``v.max(axis=1)``)."""
    return np.maximum(np.maximum(v[:, 0], v[:, 1]), v[:, 2])


def finite_rows(v):
    """Whether every channel of each row of ``v (n, 3)`` is finite: ``(n,)`` bool (about ten
    times faster than ``np.isfinite(v).all(axis=1)``, whose reduction over a short axis is
    slow)."""
    f = np.isfinite(v)
    return f[:, 0] & f[:, 1] & f[:, 2]


def next_1d_if(stream, needed):
    """``stream.next_1d()`` if ``needed``, else None with the dimension skipped all the same
    (samplers give every dimension its own values, so skipping one changes no other)."""
    if needed:
        return stream.next_1d()
    stream.skip_to(stream.dimension + 1)
    return None


# How Russian roulette turns a path's throughput into its survival probability (the
# ``rr_survival`` setting): pbrt's and Mitsuba's rule, or Cycles' gentler square root.
ROULETTE_SURVIVALS = ("throughput", "square_root")


def roulette_at(settings, bounce):
    """Whether :func:`russian_roulette` draws on its random number after ``bounce``."""
    return settings.use_russian_roulette and bounce >= settings.rr_min_bounces


def russian_roulette(beta, alive, u_rr, settings, bounce, eta_scale=None):
    """Stage *Russian roulette*: unbiased termination of low-throughput paths.

    After ``settings.rr_min_bounces`` bounces (if ``use_russian_roulette``) a path survives
    with probability ``q = min(1, t)`` of its throughput ``t = max(beta) * eta_scale``
    (``rr_survival`` ``'throughput'``, pbrt's rule) or ``q = min(1, sqrt(t))``
    (``'square_root'``, Cycles' rule: paths end later, with less noise per sample), and its
    throughput is divided by ``q``; paths of zero throughput end. ``eta_scale (k,)`` (None:
    1) scales the throughput looked at: the path tracer's undoes the ``1 / etap^2`` of
    refractions in radiance mode (the throughput a path will have once it has left the
    glass); random walks' divide by the first ray's throughput (:func:`.subpaths.walk`). Any
    ``q`` in (0, 1] keeps the estimate unbiased. Returns the new ``alive (k,)`` mask and
    ``beta (k, 3)``.
    """
    if roulette_at(settings, bounce):
        largest = max_component(beta)
        q = largest if eta_scale is None else largest * eta_scale
        if settings.rr_survival == "square_root":
            q = np.sqrt(q)
        q = np.minimum(1.0, q)
        alive = alive & (u_rr < q)
        beta = divide_rows(beta, np.maximum(q, 1e-12))
        # Whether the divided throughput is positive, read before the division: dividing by
        # a q in [1e-12, 1] keeps every sign, zero and NaN (and where q is NaN, u_rr < q
        # already ended the path), so the mask is max_component(beta) > 0's after it.
        return alive & (largest > 0), beta
    return alive & (max_component(beta) > 0), beta


def _ray_class_rule(lobe):
    return np.where((lobe & LOBE_TRANSMIT) != 0, VIS_TRANSMISSION,
                    np.where((lobe & LOBE_DIFFUSE) != 0, VIS_DIFFUSE, VIS_GLOSSY)).astype(np.int32)


# ray_class of every uint8 lobe value: one gather instead of six passes over the rows.
_RAY_CLASS_OF_LOBE = _ray_class_rule(np.arange(256))


def ray_class(lobe):
    """Object ray visibility class of rays leaving a vertex by the sampled ``lobe (k,)`` bits.

    As Cycles: transmissions trace with ``VIS_TRANSMISSION``, diffuse reflections with
    ``VIS_DIFFUSE``, glossy and singular reflections with ``VIS_GLOSSY``. ``(k,)`` int32.
    """
    lobe = np.asarray(lobe)
    if lobe.dtype == np.uint8:  # BSDFSample's lobes: looked up in the table of the rule
        return _RAY_CLASS_OF_LOBE.take(lobe)
    return _ray_class_rule(lobe)


def geometric_side_valid(ng, wo, wi, transmit):
    """Whether ``wi (k, 3)`` leaves on the intended side of the *geometric* surface.

    Shading normals tilt BSDF lobes away from the true surface, so a direction can be above the
    shading hemisphere yet below the geometry: light would leak through, or paths continue
    inside closed objects (pbrt's and Cycles' light-leak rule). A reflection (``transmit``
    false) is valid only if ``wi . ng`` has the sign of ``wo . ng``, a transmission only if the
    opposite sign. ``wo`` may be any vector on the viewer's side of ``ng`` (the incoming
    direction, or ``ns`` already flipped toward it). Contributions of invalid directions are
    zeroed; pdfs are left as they are (MIS weights of other strategies are unaffected).
    """
    cos_o = np.einsum("ij,ij->i", ng, wo)
    cos_i = np.einsum("ij,ij->i", ng, wi)
    same = cos_o * cos_i > 0
    opposite = cos_o * cos_i < 0
    return np.where(transmit, opposite, same)


def valid_reflection_normals(ng, wo, ns):
    """Shading normals bent so that the mirror reflection of ``wo`` stays above the geometry.

    On a smooth-shaded coarse mesh the interpolated normal ``ns`` can tilt so far that the
    mirror direction ``2 (ns . wo) ns - wo`` points below the geometric surface: the
    geometric-side rule (:func:`geometric_side_valid`) then drops the reflection and glossy
    silhouettes turn black. Cycles avoids that by bending the normal of its glossy closures
    (``ensure_valid_specular_reflection`` in its kernel; behaviour matched, the construction
    below is ours): where the reflection lies below ``t = min(0.9 wo . ng, 0.01)`` above the
    surface, the normal is replaced by the one in the plane of ``ns`` and ``ng`` whose
    reflection of ``wo`` rises exactly ``t`` above it.

    That normal is the half vector of ``wo`` and the wanted reflection ``r``: ``r`` keeps the
    component of ``wo`` outside the plane (negated) and, inside it, has height ``t`` and the
    in-plane length of ``wo``; of the two such ``r`` the one whose half vector is closer to
    ``ns`` is taken (the smallest bend).

    Parameters
    ----------
    ng : (k, 3) float64
        Unit geometric normals, any side.
    wo : (k, 3) float64
        Unit directions toward the viewer (the previous path vertex).
    ns : (k, 3) float64
        Unit shading normals on ``wo``'s side of ``ng`` (:attr:`Interaction.ns`).

    Returns
    -------
    (k, 3) float64
        ``ns`` where its reflection is valid, the bent normal elsewhere (unit, on ``wo``'s side).
    """
    g = ng * np.where(np.einsum("ij,ij->i", ng, wo) < 0, -1.0, 1.0)[:, None]
    cos_o = np.maximum(np.einsum("ij,ij->i", wo, g), 0.0)
    t = np.minimum(0.9 * cos_o, 0.01)
    cos_s = np.einsum("ij,ij->i", ns, wo)
    reflected_height = 2.0 * cos_s * np.einsum("ij,ij->i", ns, g) - np.einsum("ij,ij->i", wo, g)
    bad = np.nonzero(reflected_height < t)[0]
    if bad.size == 0:
        return ns
    g_b, wo_b, ns_b, t_b, z = g[bad], wo[bad], ns[bad], t[bad], cos_o[bad]
    # Tangent of ns in the plane it spans with ng (x); wo's in-plane coordinates (x, z).
    x = ns_b - np.einsum("ij,ij->i", ns_b, g_b)[:, None] * g_b
    length = np.linalg.norm(x, axis=1)
    x = np.where(length[:, None] > 1e-12, x / np.maximum(length, 1e-300)[:, None], 0.0)
    wx = np.einsum("ij,ij->i", wo_b, x)
    rx = np.sqrt(np.maximum(wx * wx + z * z - t_b * t_b, 0.0))
    best, best_cos = ns_b, np.full(bad.size, -np.inf)
    for sign in (1.0, -1.0):
        h = (sign * rx + wx)[:, None] * x + (t_b + z)[:, None] * g_b
        h_len = np.linalg.norm(h, axis=1)
        h = h / np.maximum(h_len, 1e-300)[:, None]
        cos = np.where(h_len > 1e-12, np.einsum("ij,ij->i", h, ns_b), -np.inf)
        better = cos > best_cos
        best = np.where(better[:, None], h, best)
        best_cos = np.where(better, cos, best_cos)
    out = ns.copy()
    out[bad] = np.where((length > 1e-12)[:, None], best, g_b)
    return out


def bends_normals(scene, prim):
    """Whether the glossy closures at hits on triangles ``prim (k,)`` bend their normal for a
    valid reflection (:func:`valid_reflection_normals`): ``(k,)`` bool. Cycles bends only
    where the material's Bump Map Correction is on (``maybe_ensure_valid_specular_reflection``);
    the exporter records that setting for materials with a normal map or bump
    (``materials.bump_correction``), so only those can turn it off here (a plain smooth
    material with the setting off is bent all the same)."""
    return materials_bending(scene.materials)[scene.material[prim]]


def materials_bending(m):
    """:func:`bends_normals` per material of the table ``m``: ``(m,)`` bool."""
    return ~mapped_materials(m) | np.asarray(m.bump_correction, bool)


def mapped_materials(m):
    """The materials of the table ``m`` with a Normal Map or Bump: ``(m,)`` bool."""
    mapped = np.zeros(len(m.bump_correction), bool)
    for column in ("normal_texture", "bump_texture"):
        values = getattr(m, column, None)
        if values is not None:
            mapped |= np.asarray(values) >= 0
    return mapped


def strategies(max_length):
    """BDPT strategies ``(s, t)`` shown as images, for path lengths 1..``max_length`` segments.

    A path of ``k`` segments has ``k + 1`` vertices, ``s`` from the light and ``t`` from the
    camera: ``s = 0..k`` with ``t = k + 1 - s >= 1`` (``t = 1``: a light-subpath vertex
    connected to the pinhole; ``t = 0`` would need a light path to hit the pinhole).
    """
    return [(s, k + 1 - s) for k in range(1, int(max_length) + 1) for s in range(k + 1)]


def strategy_pass_names(max_length):
    """Render pass names of the per-strategy images: for every :func:`strategies` ``(s, t)``
    the strategy's own estimate ``"Strategy s<s> t<t>"`` (as if it were the only one) and its
    MIS-weighted share of the image ``"Strategy s<s> t<t> weighted"``."""
    names = []
    for s, t in strategies(max_length):
        names += [f"Strategy s{s} t{t}", f"Strategy s{s} t{t} weighted"]
    return names


def camera_rays(prep, pixel_filter, stream):
    """Stage *generate camera rays*: filter-importance-sampled film positions -> rays.

    Consumes dimensions 0-1 of ``stream``. Returns ``origins, directions, tmax`` as
    :func:`core.camera.generate_rays`.
    """
    cam = prep.scene.camera
    x = (stream.pixel % cam.width).astype(np.float64)
    y = (stream.pixel // cam.width).astype(np.float64)
    offset = pixel_filter.sample(stream.next_2d())
    film_xy = np.stack([x + 0.5, y + 0.5], axis=-1) + offset
    return generate_rays(cam, film_xy)


def intersect_by_class(accel, o, d, tmax, vis):
    """Closest hits of rays whose object-visibility class ``vis (n,)`` (``VIS_*`` bit) varies.

    Rays of one class are traced together against the triangles visible to that class.
    """
    first = vis[0] if vis.size else 0
    if vis.size == 0 or accel.visible_to_all or np.all(vis == first):
        # One class, or one Embree scene for every class: a single query (same hits).
        return accel.intersect(o, d, tmax, int(first) if vis.size else 1)
    n = o.shape[0]
    hits = Hits(np.full(n, -1, np.int32), np.full(n, np.inf), np.zeros(n), np.zeros(n))
    for cls in np.unique(vis):
        rows = np.nonzero(vis == cls)[0]
        h = accel.intersect(o[rows], d[rows], None if tmax is None else tmax[rows], int(cls))
        hits.prim[rows], hits.t[rows], hits.u[rows], hits.v[rows] = h.prim, h.t, h.u, h.v
    return hits


def surface_hits(prep, hits):
    """Stage *compact*: the rows ``(k,)`` of ``hits`` on a surface; rays that escaped or hit a
    degenerate (zero-area) triangle end their paths."""
    live = hits.hit.nonzero()[0]
    if _every_area_positive(prep):  # no degenerate triangle to drop (no gathers per bounce)
        return live
    return live[prep.tri_area[hits.prim[live]] > 0]


def _every_area_positive(prep):
    """Whether every triangle of ``prep`` has a positive area (``tri_area``), found once per
    table."""
    cached = prep.__dict__.get("_every_area_positive")
    if cached is None or cached[0] is not prep.tri_area:
        cached = (prep.tri_area, bool(np.all(prep.tri_area > 0)))
        prep.__dict__["_every_area_positive"] = cached
    return cached[1]


@dataclass
class Interaction:
    """Surface points of a batch of hits.

    Attributes
    ----------
    p : (k, 3) float64
        Hit points, interpolated from the triangle's vertices.
    ng : (k, 3) float64
        Unit geometric normals.
    ns : (k, 3) float64
        Shading normals, flipped toward the side the ray came from (two-sided surfaces):
        ``ng`` itself for flat meshes, else the interpolated corner normals
        (:func:`shading_normals`). ``ns . wo > 0`` wherever ``ng . wo != 0``, unless the
        interaction was built with ``keep_below`` (the path tracer's: Cycles' rule, see
        :mod:`core.materials.lower_view`). None where built with ``shading=False``
        (:func:`surface_interaction`).
    wo : (k, 3) float64
        Unit direction back along the incoming ray.
    prim : (k,) int32
    n_bump : (k, 3) float64 or None
        Bump Map Correction (:func:`bump_reference_normals`): the smooth normal before normal
        maps and bumps, flipped as ``ns``, at hits whose material corrects; zero elsewhere.
        None when no material of the scene corrects.
    nm : (k, 3) float64 or None
        The shading normal before the view's fallback (:func:`perturbed_normals`), on the
        stored ``ng``'s front side (not flipped); None when the scene has no corner normals.
        Subpaths and photons shade in its frame by Cycles' rule and its adjoint
        (:mod:`.adjoint_normals`).
    n_coat : (k, 3) float64 or None
        The smooth normal before normal maps and bumps, flipped as ``ns``, at hits whose
        material has a coat and a normal map or bump (the Principled coat shades around it,
        :mod:`core.materials.coat`; :func:`coat_reference_normals`); zero elsewhere. None
        when no such hit.
    u, v : (k,) float64 or None
        The hits' barycentrics (weights of vertices 1 and 2), as :func:`surface_interaction`
        gathered them (None where an Interaction is built otherwise).
    """

    p: np.ndarray
    ng: np.ndarray
    ns: np.ndarray
    wo: np.ndarray
    prim: np.ndarray
    n_bump: np.ndarray = None
    nm: np.ndarray = None
    n_coat: np.ndarray = None
    u: np.ndarray = None
    v: np.ndarray = None


def surface_interaction(prep, hits, d, rows, keep_below=False, shading=True):
    """Build the :class:`Interaction` of the hit rays ``rows`` for directions ``d (n, 3)``
    (``keep_below``: see :func:`shading_normals`; ``shading=False`` leaves ``ns`` None, for
    callers that never read it)."""
    prim = hits.prim[rows]
    u, v = hits.u[rows], hits.v[rows]
    p = combine_rows(((u, take_rows(prep.tri_e1, prim)), (v, take_rows(prep.tri_e2, prim))),
                     base=take_rows(prep.tri_v0, prim))
    ng = take_rows(prep.tri_normal, prim)
    wo = take_rows(d, rows)
    np.negative(wo, out=wo)
    if prep.scene.corner_normals is None:
        # Each of them is None without corner normals (flat shading): not asked one by one
        # (their material tests cost about 20 us a call, several calls per bounce).
        nm = n_bump = n_coat = None
    else:
        nm = perturbed_normals(prep, prim, u, v, ng)
        n_bump = bump_reference_normals(prep, prim, u, v, ng)
        n_coat = coat_reference_normals(prep, prim, u, v, ng)
    ns = None
    if shading or n_bump is not None or n_coat is not None:
        side = np.where(np.einsum("ij,ij->i", ng, wo) >= 0, 1.0, -1.0)
        if shading:
            ns = ng if nm is None else nm if keep_below else view_fallback(nm, ng, wo)
            ns = combine_rows(((side, ns),))
        if n_bump is not None:
            n_bump *= side[:, None]
        if n_coat is not None:
            n_coat *= side[:, None]
    return Interaction(p, ng, ns, wo, prim, n_bump, nm, n_coat, u, v)


def bump_reference_normals(prep, prim, u, v, ng):
    """The smooth normals ``(k, 3)`` before normal maps and bumps (on ``ng``'s side) at the
    hits whose triangle's own material row has ``bump_correction``, zero at the others; None
    when no row of the scene has it (:mod:`core.materials.bump_correction`)."""
    return _smooth_normals_where(prep, prim, u, v, ng, prep.scene.materials.bump_correction)


def coat_reference_normals(prep, prim, u, v, ng):
    """The smooth normals ``(k, 3)`` (on ``ng``'s side) at the hits whose material has a coat
    (a Coat Weight or its texture) and a normal map or bump, which the coat does not follow
    (Cycles' coat normal when the Coat Normal input is unlinked; ``coat_mapped`` rows follow
    it); zero at the others; None when no material of the scene has both."""
    m = prep.scene.materials
    coated = m.coat_weight > 0.0
    if m.coat_weight_texture is not None:
        coated = coated | (m.coat_weight_texture >= 0)
    if m.coat_mapped is not None:
        coated = coated & ~m.coat_mapped
    return _smooth_normals_where(prep, prim, u, v, ng, coated & mapped_materials(m))


def _smooth_normals_where(prep, prim, u, v, ng, flags):
    """The interpolated corner normals ``(k, 3)`` on ``ng``'s side at the hits whose material
    has ``flags (m,)``, zero elsewhere; None when the scene has no such material."""
    corner = prep.scene.corner_normals
    if corner is None or not flags.any():
        return None
    on = flags[prep.scene.material[prim]]
    if not on.any():
        return None
    c = corner[prim].astype(np.float64)
    w1, w2 = np.asarray(u, np.float64)[:, None], np.asarray(v, np.float64)[:, None]
    raw = (1.0 - w1 - w2) * c[:, 0] + w1 * c[:, 1] + w2 * c[:, 2]
    raw *= np.where(np.einsum("ij,ij->i", raw, ng) < 0, -1.0, 1.0)[:, None]
    length = np.linalg.norm(raw, axis=1)
    n = np.where((length > 1e-12)[:, None], raw / np.maximum(length, 1e-12)[:, None], ng)
    return np.where(on[:, None], n, 0.0)


def with_bump_normals(params, si, frame):
    """``params`` with their ``bump_normal`` column: ``si.n_bump`` in the local ``frame =
    (s, t, n)`` (unchanged when ``si.n_bump`` is None)."""
    if si.n_bump is None:
        return params
    return replace(params, bump_normal=to_local(si.n_bump, *frame))


def with_coat_normals(params, n_coat, frame):
    """``params`` with a ``coat_normal`` column (:mod:`core.materials.coat`) on the coated
    rows whose coat normal ``n_coat (k, 3)`` (world, on the frame's side; zero rows: none;
    :attr:`Interaction.n_coat`) differs from the ``frame = (s, t, n)``'s +Z, in that frame;
    unchanged when there is none (``n_coat`` None)."""
    if n_coat is None or not params.has_coat:
        return params
    n = n_coat
    rows = np.nonzero((params.coat_weight > 0.0) & np.any(n != 0.0, axis=1))[0]
    rows = rows[np.any(n[rows] != frame[2][rows], axis=1)]
    if rows.size == 0:
        return params
    local = np.zeros((len(params), 3))
    local[rows] = to_local(n[rows], *(f[rows] for f in frame))
    return replace(params, coat_normal=local, coat_flip=np.zeros(len(params)))


def coat_normals_in_front(si):
    """``si.n_coat`` on the stored geometric normal's front side (as ``si.nm``), or None."""
    n = si.n_coat
    if n is None:
        return None
    return n * np.where(np.einsum("ij,ij->i", n, si.ng) < 0, -1.0, 1.0)[:, None]


def with_base_normals(params, unbent, frame):
    """``params`` with a ``base_normal`` column (:mod:`core.materials.layered`) on the layered
    rows whose frame ``frame = (s, t, n)`` was bent away from their shading normal ``unbent
    (k, 3)`` (on the frame's side of the surface) for a valid specular reflection: Cycles
    bends the specular closure's normal only, the diffuse base keeps ``unbent``. Unchanged
    when no such row exists."""
    layered = (params.kind == KIND_LAYERED) | (params.kind == KIND_LAYERED_MS)
    rows = layered.nonzero()[0]
    rows = rows[np.any(unbent[rows] != frame[2][rows], axis=1)]
    if rows.size == 0:
        return params
    local = np.zeros((len(params), 3))
    local[rows] = to_local(unbent[rows], *(f[rows] for f in frame))
    return replace(params, base_normal=local)


def shading_tangents(prep, si):
    """Tangents ``(k, 3)`` at the hits of ``si`` for anisotropic BSDFs, or None when the
    scene has none (``prep.scene.aniso_tangents``): the corner tangents interpolated with the
    barycentrics of ``si.p`` in its triangle (exact for Cycles' radial tangent, which is
    affine in the position); :func:`core.materials.frame.shading_frame` projects them."""
    corner = prep.scene.aniso_tangents
    if corner is None:
        return None
    prim = si.prim
    e1, e2 = take_rows(prep.tri_e1, prim), take_rows(prep.tri_e2, prim)
    d = si.p - take_rows(prep.tri_v0, prim)
    a, b, c = (np.einsum("ij,ij->i", x, y) for x, y in ((e1, e1), (e1, e2), (e2, e2)))
    p1, p2 = np.einsum("ij,ij->i", d, e1), np.einsum("ij,ij->i", d, e2)
    det = a * c - b * b
    ok = det > 0.0
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    u, v = (c * p1 - b * p2) * inv, (a * p2 - b * p1) * inv
    t = corner[prim].astype(np.float64)
    return (1.0 - u - v)[:, None] * t[:, 0] + u[:, None] * t[:, 1] + v[:, None] * t[:, 2]


def shading_normals(prep, prim, u, v, ng, wo, keep_below=False):
    """Smooth-shading normals at hits, on the front side of the stored geometric normal.

    The corner normals of ``prep.scene.corner_normals`` are interpolated with the hit
    barycentrics (weights ``1 - u - v, u, v`` for corners 0, 1, 2, as Embree's ``u, v``) and
    normalised; a normal pointing behind ``ng`` is mirrored to its side. Where ``wo`` sees the
    geometric front but the shading back (or the reverse, near silhouettes of coarse meshes),
    or the interpolation vanishes, the geometric normal is used instead: BSDFs then never see an
    incoming direction from the "wrong" side of their frame, and the geometric-side test of the
    integrators (see :mod:`.path`) keeps shading normals from leaking light through surfaces.
    Materials with a Normal Map or Bump node perturb the normal first
    (:func:`core.normal_maps.normal_mapped`, then :func:`core.bump.bump_mapped`), and the
    same fallbacks apply to the perturbed normal. With ``keep_below`` (the path tracer) a
    normal that the view falls below is kept, as Cycles keeps it: the BSDF then shades those
    rows by Cycles' rule (:mod:`core.materials.lower_view`); BDPT, light tracing and photons
    use it too, through :mod:`.adjoint_normals`. Returns ``ng`` itself when the scene has no corner normals
    (every face flat; a scene with normal maps or bumps always has them).

    Parameters
    ----------
    prim : (k,) int
    u, v : (k,) float
    ng : (k, 3) float64
        Unit geometric normals as stored (not flipped).
    wo : (k, 3) float64
    keep_below : bool
        Keep normals the view falls below (see above).

    Returns
    -------
    (k, 3) float64
        Unit normals ``n`` with ``n . ng >= 0``.
    """
    n = perturbed_normals(prep, prim, u, v, ng)
    if n is None:
        return ng
    return n if keep_below else view_fallback(n, ng, wo)


def perturbed_normals(prep, prim, u, v, ng):
    """The shading normals of :func:`shading_normals` before the fallback that depends on the
    view: unit, on ``ng``'s front side, ``ng`` where the interpolation vanishes or the
    perturbed normal points behind ``ng``; None when the scene has no corner normals."""
    corner = prep.scene.corner_normals
    if corner is None:
        return None
    c = corner[prim].astype(np.float64)
    u = np.asarray(u, np.float64)[:, None]
    v = np.asarray(v, np.float64)[:, None]
    raw = (1.0 - u - v) * c[:, 0] + u * c[:, 1] + v * c[:, 2]
    raw *= np.where(np.einsum("ij,ij->i", raw, ng) < 0, -1.0, 1.0)[:, None]
    length = np.linalg.norm(raw, axis=1)
    good = length > 1e-12
    n = raw / np.where(good, length, 1.0)[:, None]
    n = normal_mapped(prep.scene, prim, u[:, 0], v[:, 0], raw, n)
    n = bump_mapped(prep.scene, prim, u[:, 0], v[:, 0], n)
    good &= np.isfinite(n).all(axis=1) & (np.einsum("ij,ij->i", n, ng) >= 0)
    return np.where(good[:, None], n, ng)


def view_fallback(n, ng, w):
    """``n (k, 3)`` where ``w (k, 3)`` sees ``n`` and ``ng`` from the same side, else ``ng``: the
    facet fallback of the integrators that do not keep normals the view falls below
    (radiosity, SPPM's and photon mapping's visible points)."""
    cos_g = np.einsum("ij,ij->i", ng, w)
    cos_s = np.einsum("ij,ij->i", n, w)
    return np.where((cos_g * cos_s > 0)[:, None], n, ng)


def add_emitters_along_rays(prep, L, beta, o, d, hits, rows_of, pdf_prev, use_mis, camera, mis,
                            n_prev=None, mis_origin=None, mis_offset=None, world=True):
    """Stage *handle escaped + handle emission*: light reaching the ray's origin along it.

    Adds ``beta * Le * w`` to ``L[rows_of]`` for the world (escaped rays), light shapes before the
    hit, and emissive triangles hit. ``w`` is the MIS weight against next-event estimation from
    the previous vertex (``pdf_prev (n,)`` is the BSDF's solid-angle pdf there); where
    ``use_mis (n,)`` is false (camera rays, previous delta BSDF) the weight is one.

    Parameters
    ----------
    L : (N, 3) float64
        Radiance accumulators of all paths; ``rows_of (n,)`` maps this batch's rays to them.
    beta : (n, 3) float64
        Path throughput up to the ray's origin.
    o, d : (n, 3) float64
    hits : core.accel.Hits
    camera : bool
        Whether these are camera rays (lamps show only if visible to the camera).
    mis : core.sampling.mis.MIS
        The render's MIS (any setting); see :meth:`core.sampling.mis.MIS.bsdf_weight`.
    n_prev : (n, 3) float64 or None
        Shading normals at the origins, as next-event estimation gave them to the light
        selection there (a light tree); None when the selection does not use them.
    mis_origin : (n, 3) float64 or None
        Where the rays' MIS densities are measured from (None: ``o``): the last vertex that
        scattered, when a ray went on straight through transparent surfaces since; it lies
        ``mis_offset (n,)`` behind ``o`` along ``d``. Next-event estimation there reached the
        same emitters through the same surfaces (:mod:`.shadows`), so the weights compare the
        densities of that vertex.
    world : bool
        Whether escaped rays add the world's radiance (not camera rays on a transparent film).
    """
    lights = prep.lights
    tmin = None
    if mis_origin is not None and np.any(mis_offset > 0):
        o, tmin = mis_origin, mis_offset
        hits = Hits(hits.prim, hits.t + mis_offset, hits.u, hits.v)

    def weight(rows, pdf_light):
        w = mis.bsdf_weight(pdf_prev[rows], pdf_light)
        return np.where(use_mis[rows], w, 1.0)

    escaped = np.nonzero(~hits.hit)[0]
    if escaped.size and lights.has_world and world:
        le, pdf_l = lights.world_radiance(d[escaped])
        add_rows(L, rows_of[escaped],
                 take_rows(beta, escaped) * le * weight(escaped, pdf_l)[:, None])
    for rows, le, pdf_l in lights.hit_shapes(o, d, hits.t, camera, n_prev, tmin):
        add_rows(L, rows_of[rows], take_rows(beta, rows) * le * weight(rows, pdf_l)[:, None])
    hit_rows = np.nonzero(hits.hit)[0]
    if hit_rows.size and lights.emissive_tris.size:
        prim = hits.prim[hit_rows]
        emissive = lights.tri_emitter[prim] >= 0
        rows = hit_rows[emissive]
        if rows.size:
            prim = prim[emissive]
            cos_l = np.einsum("ij,ij->i", take_rows(d, rows), take_rows(prep.tri_normal, prim))
            pdf_l = lights.triangle_pdf(prim, take_rows(o, rows), hits.t[rows], cos_l,
                                        None if n_prev is None else take_rows(n_prev, rows))
            le = lights.triangles.hit_emission(prim, cos_l)
            add_rows(L, rows_of[rows], take_rows(beta, rows) * le * weight(rows, pdf_l)[:, None])
