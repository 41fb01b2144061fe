"""Per-render derived data: Embree scenes, triangle normals and areas, the light tables.

Everything here is built once per render, before any worker thread starts, and only read
afterwards."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .accel import Accel
from .lights import Emission, LightSampler
from .materials.bsdf import KIND_DIELECTRIC, KIND_DIFFUSE, BSDFParams, is_delta_only, kind_rows
from .materials.microfacet import alpha_from_roughness
from .alpha import AlphaTextures, alpha_textures
from .metallic import MetallicTextures, metallic_textures
from .reweighting import choose_reweighted
from .scalar_textures import apply_scalar_textures
from .sampling.distributions import Segmented1D
from .sampling.stream import Aborted
from .scene import Scene
from .textures import material_base_color, material_roughness, textured_base_color


def drop_nonfinite(scene: Scene):
    """``scene`` without the triangles that have a NaN or infinite vertex coordinate.

    Such triangles have no area, normal or place: Embree and the bounding box would take in
    their coordinates and every later computation would turn to NaN. Vertices no remaining
    triangle uses are moved onto a finite one, so that they leave the bounding box alone.

    Returns
    -------
    scene : Scene
        ``scene`` itself when every vertex is finite.
    notes : list of str
        One message naming how many triangles were dropped (empty when none).
    """
    bad_vertex = ~np.isfinite(scene.vertices).all(axis=1)
    if not bad_vertex.any():
        return scene, []
    bad = bad_vertex[scene.triangles].any(axis=1)
    keep = ~bad
    vertices = scene.vertices.copy()
    good = np.flatnonzero(~bad_vertex)
    vertices[bad_vertex] = vertices[good[0]] if len(good) else 0.0

    def rows(a):
        return None if a is None else a[keep]

    clean = dataclasses.replace(scene, vertices=vertices, triangles=scene.triangles[keep],
                                material=scene.material[keep], visibility=scene.visibility[keep],
                                corner_uvs=rows(scene.corner_uvs),
                                corner_normals=rows(scene.corner_normals),
                                aniso_tangents=rows(scene.aniso_tangents),
                                corner_tangents=rows(scene.corner_tangents))
    return clean, [f"{int(bad.sum()):,} triangle(s) with NaN or infinite vertex coordinates "
                   f"were left out"]


def recentred(scene: Scene):
    """A copy of ``scene`` translated so that its bounding box is centred on the origin.

    Float32 precision is relative to a coordinate's magnitude, so a compact scene far from the
    origin loses precision (and needs larger ray offsets) for no reason. Rendering is invariant
    under translation, so the renderer works in this local frame.

    Returns
    -------
    local : Scene
    shift : (3,) float64
        What was subtracted from every position.
    """
    if scene.n_triangles == 0:
        return scene, np.zeros(3)
    v = scene.vertices.astype(np.float64)
    shift = 0.5 * (v.min(axis=0) + v.max(axis=0))
    if np.abs(shift).max() == 0:
        return scene, shift
    lights = dataclasses.replace(scene.lights, position=scene.lights.position - shift)
    camera = scene.camera
    if camera is not None:
        to_world = np.array(camera.to_world, np.float64)
        to_world[:3, 3] -= shift
        camera = dataclasses.replace(camera, to_world=to_world)
    local = dataclasses.replace(scene, vertices=(v - shift).astype(np.float32), lights=lights,
                                camera=camera)
    return local, shift


@dataclass
class PreparedScene:
    """A :class:`Scene` plus what every integrator derives from it once.

    Attributes
    ----------
    scene : Scene
    accel : Accel
    tri_v0, tri_e1, tri_e2 : (t, 3) float64
        First vertex and the two edges from it, so that a hit at barycentrics (u, v) is
        ``v0 + u e1 + v e2`` without gathering three vertices.
    tri_normal : (t, 3) float64
        Unit geometric normals (right-hand rule on the vertex order; zero for degenerate ones).
    tri_area : (t,) float64
    tri_albedo : (t, 3) float64
        Diffuse albedo per triangle.
    tri_emission : (t, 3) float64
        Emitted radiance per triangle.
    tri_material : (t,) int64
        Material row per triangle.
    material_bsdf : core.materials.bsdf.BSDFParams
        One row per material; shading gathers ``material_bsdf.take(tri_material[prim])``.
    material_delta_only : (m,) bool
        Materials whose BSDF is a pure delta distribution (next-event estimation skips them).
    material_mix_rows : (m, c) int64
        Component rows of each material (``Materials.mix_rows``; a single row is its own).
    material_mix : core.sampling.distributions.Segmented1D or None
        One segment of ``c`` mixing weights per material (zero on the padding), drawn from by
        CDF inversion or an alias table as the ``distribution`` setting says; None if no
        material mixes (``c == 1``).
    material_mix_count : (m,) int64
        Components of positive weight per material (1 for plain rows, which keep their number).
    lambert_only : bool
        Every material a triangle uses is a single diffuse BSDF (no mixtures): integrators may
        take a world-space Lambert path.
    lights : LightSampler
        Next-event estimation and the emitters rays find.
    emission : core.lights.Emission
        How light paths leave the same emitters (light tracing, BDPT).
    metallic : core.metallic.MetallicTextures or None
        Re-weighting of the mixtures whose Metallic is a texture; None when none is.
    alpha : core.alpha.AlphaTextures or None
        Per-hit transparency of the mixtures whose alpha is a texture; None when none is.
    material_mix_weights : (m, c) float64
        The mixing weights of ``material_mix_rows`` (what textures re-weight per hit).
    material_transparency : (m, 3) float64 or None
        What a shadow ray keeps when it crosses each material: the summed weight times colour
        of its transparent components (:func:`transparency_table`); None when no material a
        triangle uses has any (shadow rays are then plain occlusion queries).
    notes : list of str
        What preparing changed in the scene, for the user (:func:`drop_nonfinite`).
    shift : (3,) float64
        World position of the local frame's origin: everything above is in world space minus
        ``shift`` (see :func:`recentred`).
    """

    scene: Scene
    accel: Accel
    tri_v0: np.ndarray
    tri_e1: np.ndarray
    tri_e2: np.ndarray
    tri_normal: np.ndarray
    tri_area: np.ndarray
    tri_albedo: np.ndarray
    tri_emission: np.ndarray
    lights: LightSampler
    shift: np.ndarray
    tri_material: np.ndarray = None
    material_bsdf: BSDFParams = None
    material_delta_only: np.ndarray = None
    material_mix_rows: np.ndarray = None
    material_mix: Segmented1D = None
    material_mix_count: np.ndarray = None
    lambert_only: bool = False
    emission: Emission = None
    material_transparency: np.ndarray = None
    notes: list = dataclasses.field(default_factory=list)
    metallic: MetallicTextures = None
    alpha: AlphaTextures = None
    material_mix_weights: np.ndarray = None

    @property
    def plain_diffuse(self):
        """Every material a triangle uses is one untextured diffuse BSDF (``lambert_only``
        without textures): a vertex's BSDF is its triangle's colour (``tri_albedo``)."""
        return self.lambert_only and not self.scene.textures

    def bsdf(self, prim):
        """BSDF parameters of the hit triangles' own material rows ``(k,)`` and whether each
        is delta-only. A mixture row's own parameters are not what shades it: integrators use
        :meth:`choose_bsdf`."""
        rows = self.tri_material[prim]
        return self.material_bsdf.take(rows), self.material_delta_only[rows]

    def choose_material(self, prim, u_lobe, u=None, v=None):
        """Material row shading each hit ``prim (k,)``: a mixture's component, chosen with
        probability its weight by ``u_lobe (k,)`` in [0, 1) (weights re-computed from the
        metallic and alpha textures at barycentrics ``u, v (k,)`` where a row has one,
        :mod:`core.reweighting`).

        Returns
        -------
        material : (k,) int64
        u_lobe : (k,) float64
            ``(u - cdf_lo) / weight`` of the chosen component: uniform in [0, 1) again, and
            independent of the choice, for the chosen BSDF's own lobe choice. Unchanged on
            single-component rows.
        """
        rows = self.tri_material[prim]
        u_in = np.asarray(u_lobe, np.float64).reshape(-1)
        material = self.material_mix_rows[rows, 0]
        if self.material_mix is None:
            return material, u_in
        mixed = np.nonzero(self.material_mix_count[rows] > 1)[0]
        out = u_in.copy()
        # Zero-weight components (and the padding) are never chosen, by either method.
        index, _, out[mixed] = self.material_mix.sample(rows[mixed], out[mixed])
        material[mixed] = self.material_mix_rows.reshape(-1)[index]
        sources = [s for s in (self.metallic, self.alpha) if s is not None]
        if sources and u is not None:
            choose_reweighted(sources, self.scene, self.material_mix_rows,
                              self.material_mix_weights, rows, prim, u, v, u_in, material, out)
        return material, out

    def transparency(self, prim, u, v):
        """What a shadow ray keeps crossing hits ``prim, u, v (k,)``: ``(k, 3)``, the
        material's transparency (:func:`transparency_table`), per hit where its alpha is a
        texture (:mod:`core.alpha`). Requires ``material_transparency``."""
        rows = self.tri_material[prim]
        value = self.material_transparency[rows]
        if self.alpha is not None:
            hit, per_hit = self.alpha.transparency(self.scene, rows, prim, u, v)
            value[hit] = per_hit
        return value

    def choose_bsdf(self, prim, u_lobe, u=None, v=None):
        """BSDF of the hit triangles ``prim (k,)`` for one path vertex each.

        Materials that mix several BSDF kinds choose one component per vertex with ``u_lobe
        (k,)`` (probability = its mixing weight, see :meth:`choose_material`); the remapped
        number is returned for the chosen BSDF's own lobe choice. Every integrator calls this
        once per vertex and uses the chosen BSDF for all its evaluations there (next-event
        estimation and BSDF sampling alike): the expectation over the choice of the chosen
        ``f_k`` is the mixture, so estimates stay unbiased.

        Given the hits' barycentrics ``u, v (k,)``, textured components get their looked-up
        base colour, roughness, Specular IOR Level and Coat Weight (a texture belongs to the
        component it feeds, so mixtures need this rather than :meth:`textured_base_color`).

        Returns
        -------
        params : core.materials.bsdf.BSDFParams
            Where every material is plain diffuse and untextured (:attr:`plain_diffuse`), the
            columns diffuse BSDFs never read (``alpha``, ``eta``, ``tint``) are read-only
            constants (:func:`core.materials.bsdf.kind_rows`), not the table's rows.
        delta_only : (k,) bool
            Whether the chosen BSDF is a pure delta distribution.
        u_lobe : (k,) float64
        """
        if self.plain_diffuse and self.material_mix is None:
            # Each triangle's one material from a table made once (choose_material's two
            # gathers in one), the constant columns sliced from read-only views: about half
            # this call's cost on the bench box (7 -> 3.5 us per 1,000 rows and call).
            material = self._single_materials().take(prim)
            table, k = self.material_bsdf, material.size
            params = BSDFParams(table.kind.take(material), table.color.take(material, axis=0),
                                _ONES[:k], _ONES[:k], _ZEROS3[:k])
            return (params, self.material_delta_only.take(material),
                    np.asarray(u_lobe, np.float64).reshape(-1))
        material, u_lobe = self.choose_material(prim, u_lobe, u, v)
        if self.plain_diffuse:
            # Plain diffuse BSDFs read their colour alone: the other columns are constants.
            params = kind_rows(self.material_bsdf, KIND_DIFFUSE, material)
        else:
            params = self.material_bsdf.take(material)
        delta_only = self.material_delta_only[material]
        if u is not None and self.scene.textures:
            rows, color = material_base_color(self.scene, material, prim, u, v)
            params.color[rows] = color
            rows, roughness = material_roughness(self.scene, material, prim, u, v)
            if rows.size:
                # A textured roughness may make a smooth row rough, or the other way round.
                params.alpha[rows] = alpha_from_roughness(roughness)
                delta_only = delta_only.copy()
                delta_only[rows] = is_delta_only(params.take(rows))
            apply_scalar_textures(self.scene, params, material, prim, u, v)
        return params, delta_only, u_lobe

    def _single_materials(self):
        """The material row of each triangle where no material mixes: ``(t,)``, as
        :meth:`choose_material` gives it (``material_mix_rows[tri_material, 0]``), made once
        for these two tables."""
        cached = self.__dict__.get("_single_material_cache")
        if (cached is None or cached[0] is not self.tri_material
                or cached[1] is not self.material_mix_rows):
            cached = (self.tri_material, self.material_mix_rows,
                      self.material_mix_rows[self.tri_material, 0])
            self.__dict__["_single_material_cache"] = cached
        return cached[2]

    def textured_base_color(self, prim, u, v):
        """Base colour of hits ``prim, u, v (k,)`` on textured materials: ``rows (j,)`` into
        ``prim`` and ``color (j, 3)`` (see :func:`core.textures.textured_base_color`)."""
        return textured_base_color(self.scene, self.tri_material, prim, u, v)


# Read-only constant columns of any length up to 2^40 rows (slices of zero-stride views, the
# values kind_rows gives plain diffuse rows' alpha, eta and tint without a broadcast_to call).
_ONES = np.broadcast_to(1.0, (1 << 40,))
_ZEROS3 = np.broadcast_to(0.0, (1 << 40, 3))

TABLE_CHUNK = 1 << 16
"""Triangles per step of :func:`triangle_tables` (cancel is polled between steps)."""


def triangle_tables(scene: Scene, poll=None, chunk=TABLE_CHUNK):
    """First vertex, edges, unit normal and area of every triangle, in float64, computed
    ``chunk`` triangles at a time with ``poll()`` after each (a 3 M triangle scene's tables
    took 16 s in one step on a loaded machine).

    Returns
    -------
    v0, e1, e2, normal : (t, 3) float64
        ``normal`` is zero for a zero-area triangle.
    area : (t,) float64
    """
    v = scene.vertices.astype(np.float64)
    n = scene.n_triangles
    v0, e1, e2, normal = (np.empty((n, 3)) for _ in range(4))
    area = np.empty(n)
    for start in range(0, n, chunk):
        rows = slice(start, min(start + chunk, n))
        tri = v[scene.triangles[rows]]
        v0[rows], e1[rows], e2[rows] = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        cross = np.cross(e1[rows], e2[rows])
        length = np.linalg.norm(cross, axis=1)
        normal[rows] = np.where(length[:, None] > 0,
                                cross / np.maximum(length, 1e-300)[:, None], 0.0)
        area[rows] = 0.5 * length
        if poll is not None:
            poll()
    return v0, e1, e2, normal, area


def prepare(scene: Scene, light_selection="power", light_sampling="area",
            distribution="cdf", cancel=None) -> PreparedScene:
    """Build the acceleration structure and light tables for ``scene`` (in a recentred frame).

    ``light_selection`` (``'power' | 'uniform' | 'tree'``), ``light_sampling`` (``'area' |
    'solid_angle'``) and ``distribution`` (``'cdf' | 'alias'``) configure the
    :class:`core.lights.LightSampler` (and the :class:`core.lights.Emission` of light paths over
    it; with ``'tree'`` the light tree is built here, once per render); ``distribution`` also
    draws mixed materials' components.
    Unknown values raise ``ValueError``. ``cancel`` (a callable, or None) is polled between
    the stages, every :data:`TABLE_CHUNK` triangles of the tables and every
    ``core.embree_commit.POLL_S`` s while Embree builds its BVH: once it says so,
    ``core.sampling.stream.Aborted`` is raised. A scene of at most :data:`TABLE_CHUNK`
    triangles is prepared in milliseconds and not polled (so the polls a render makes are
    its work units', as before, for such scenes).
    """
    polled = cancel is not None and scene.n_triangles > TABLE_CHUNK

    def stage_done():
        if polled and cancel():
            raise Aborted("cancelled while preparing the scene")

    scene, notes = drop_nonfinite(scene)
    stage_done()
    scene, shift = recentred(scene)
    stage_done()
    v0, e1, e2, normal, area = triangle_tables(scene, stage_done)
    accel = Accel(scene.vertices, scene.triangles, scene.visibility)
    # Embree's BVH: cancellable, the GIL released (core.embree_commit).
    accel.build(cancel if polled else None)
    stage_done()
    mats = scene.materials
    albedo = np.clip(mats.base_color[scene.material].astype(np.float64), 0.0, 1.0)
    emission = np.maximum(mats.emission[scene.material].astype(np.float64), 0.0)
    lights = LightSampler(scene, area, normal, v0, e1, e2, selection=light_selection,
                          sampling=light_sampling, method=distribution)
    stage_done()
    # BSDF parameters per material, gathered by triangle at shading time.
    bsdf = BSDFParams.from_materials(mats, np.arange(len(mats.kind)))
    mix_rows, mix_weights = mixture_table(mats.mix_weights, mats.mix_rows)
    m, width = mix_rows.shape
    mix = (Segmented1D(mix_weights.reshape(-1), np.arange(m + 1) * width, method=distribution)
           if width > 1 else None)
    used = np.unique(scene.material)
    lambert_only = bool(np.all(mats.kind[used] == 0) and not np.any(mats.mixed[used])
                        and not np.any(mats.coat_weight[used] > 0)
                        and not np.any(mats.sheen_weight[used] > 0)
                        and not np.any(mats.bump_correction[used]))
    transparency = transparency_table(bsdf, mix_rows, mix_weights)
    alpha = alpha_textures(mats, mix_rows, mix_weights, pass_colors(bsdf))
    return PreparedScene(scene, accel, v0, e1, e2, normal, area, albedo, emission, lights, shift,
                         np.asarray(scene.material, np.int64), bsdf, is_delta_only(bsdf),
                         mix_rows, mix, (mix_weights > 0).sum(axis=1), lambert_only,
                         Emission(lights, scene.vertices),
                         transparency if np.any(transparency[used] > 0) else None, notes,
                         metallic_textures(mats, bsdf, mix_rows, mix_weights), alpha,
                         mix_weights)


def passes_straight(bsdf):
    """``(m,)`` bool: the rows that pass rays straight through (a smooth dielectric of IOR
    exactly 1: Transparent BSDF, Principled Alpha's pass-through)."""
    return (bsdf.kind == KIND_DIELECTRIC) & (bsdf.eta == 1.0)


def pass_colors(bsdf):
    """``(m, 3)`` colour of every row that passes rays straight through
    (:func:`passes_straight`), zero for others."""
    return bsdf.color * passes_straight(bsdf)[:, None]


def transparency_table(bsdf, mix_rows, mix_weights):
    """Transparency ``(m, 3)`` of every material: ``sum_c w_c color_c`` over its components
    that pass rays straight through (smooth dielectrics of IOR exactly 1: Transparent BSDF,
    Principled Alpha), as Cycles' transparent shadows attenuate by the transparent closures'
    weight. Zero for opaque materials."""
    return np.einsum("mc,mcj->mj", mix_weights, pass_colors(bsdf)[mix_rows])


def mixture_table(weights, rows):
    """Component rows ``(m, c) int64`` and mixing weights ``(m, c) float64`` of a material
    table's mixtures, positive weights first in each row (so column 0 is a row's only
    component when it has one), trimmed to the widest mixture (``c >= 1``)."""
    w = np.asarray(weights, np.float64)
    rows = np.asarray(rows, np.int64)
    if w.size == 0:
        return rows.reshape(0, 1), np.ones((0, 1))
    order = np.argsort(w <= 0, axis=1, kind="stable")
    w, rows = np.take_along_axis(w, order, 1), np.take_along_axis(rows, order, 1)
    width = max(1, int((w > 0).sum(axis=1).max()))
    return rows[:, :width], w[:, :width]
