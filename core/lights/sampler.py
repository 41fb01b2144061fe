"""The light sampler: every emitter of a scene in one table, and the one place that dispatches
a batch to the light families."""

from __future__ import annotations

import numpy as np

from ..sampling.distributions import DISTRIBUTION_METHODS
from ..scene import LIGHT_DISK, LIGHT_POINT, LIGHT_RECT, LIGHT_SUN
from .area import AreaLights
from .base import LiSamples
from .environment import World
from .point import PointLights
from .selection import SELECTIONS, PowerSelection, TreeSelection
from .sun import SunLights
from .triangles import EmissiveTriangles

# How next-event estimation chooses a light, and how it samples a point on an area emitter.
LIGHT_SELECTIONS = tuple(SELECTIONS)
# Every selection class LightSampler can build (the tree before the registry offers it).
_SELECTION_CLASSES = {**SELECTIONS, TreeSelection.name: TreeSelection}
LIGHT_SAMPLINGS = ("area", "solid_angle")

# Family of each lamp kind (rows of LightSampler.families).
POINT, SUN, AREA, TRIANGLES, WORLD = range(5)
_LAMP_FAMILY = {LIGHT_POINT: POINT, LIGHT_SUN: SUN, LIGHT_RECT: AREA, LIGHT_DISK: AREA}


def _tree_as_power_note(n_emitters):
    """What a render whose light tree steers nothing tells the user."""
    which = ("the scene has one finite emitter, so the tree has nothing to choose"
             if n_emitters == 1 else
             f"the scene's {n_emitters} finite emitters share one bounding box and cone, so no "
             f"shading point changes the tree's choice")
    return (f"Light Tree: {which}: lights are chosen by power (the tree's own probabilities, "
            f"without its per-sample work)")


class LightSampler:
    """Every emitter of a scene in one selection table, and each family's light.

    Emitter rows are the scene's lights (rows ``0..k-1``), then the emissive triangles (grouped
    by material), then the world (if its radiance is not black). ``selection`` says how
    next-event estimation chooses emitter ``i`` (see :mod:`.selection`), and :meth:`nee_pmf`
    gives that probability, for the pdfs of emitters found by rays. Light paths (light
    tracing, BDPT), which start without a receiving point, choose with :meth:`choose` and the
    table ``select_prob``: the same strategy for ``power`` and ``uniform``, power selection when
    next-event estimation uses the tree. A batch is handed to each family (:mod:`.point`,
    :mod:`.sun`, :mod:`.area`, :mod:`.triangles`, :mod:`.environment`) for the rows that chose
    one of its emitters, so that no kind switch lives outside this class.

    ``sampling`` picks how a point on an area emitter is chosen: ``'area'`` (uniform on the
    surface) or ``'solid_angle'`` (uniform over the solid angle it subtends: spherical
    triangles for emissive triangles, spherical rectangles for square and rectangular area
    lights). Disk and ellipse lights, sheared rectangles, and emitters that subtend less than
    ``MIN_SPHERICAL_SOLID_ANGLE`` or more than ``MAX_SPHERICAL_SOLID_ANGLE`` (where the spherical
    warps lose precision) are sampled by area; the pdfs of emitters found by rays make the same
    decision from the same point, so MIS sees the density actually used.

    Parameters
    ----------
    scene : core.scene.Scene
    tri_area : (t,) float64
    tri_normal : (t, 3) float64
        Unit geometric normals.
    tri_v0, tri_e1, tri_e2 : (t, 3) float64
        First vertex and edges of every triangle.
    selection : str
        ``'power'``, ``'uniform'`` or ``'tree'``.
    sampling : str
        ``'area'`` or ``'solid_angle'``.
    method : str
        ``'cdf'`` or ``'alias'`` (also for the environment map's 2D distribution).

    Attributes
    ----------
    build_s : float
        Seconds spent building the selection distributions.
    world_map, world_dist
        The world's map and its distribution (see :class:`.environment.World`).
    """

    def __init__(self, scene, tri_area, tri_normal, tri_v0, tri_e1, tri_e2, selection="power",
                 sampling="area", method="cdf"):
        for value, allowed, what in ((selection, tuple(_SELECTION_CLASSES), "light selection"),
                                     (sampling, LIGHT_SAMPLINGS, "light sampling"),
                                     (method, DISTRIBUTION_METHODS, "distribution")):
            if value not in allowed:
                raise ValueError(f"unknown {what} {value!r}; choose from {', '.join(allowed)}")
        self.selection = selection
        self.sampling = sampling
        self.solid_angle = sampling == "solid_angle"
        self.method = method
        self.lights = lights = scene.lights
        self.n_lights = k = len(lights)
        tris = EmissiveTriangles(self, scene, tri_area, tri_normal, tri_v0, tri_e1, tri_e2)
        world = World(self, scene, method)
        self.families = (PointLights(self), SunLights(self), AreaLights(self), tris, world)
        self.triangles, self.world_light = tris, world
        # The tables integrators and tests read, under their long-standing names.
        self.emissive_tris, self.tri_emitter, self.n_groups = (tris.emissive, tris.tri_emitter,
                                                               tris.n_groups)
        self.rect_spherical = self.families[AREA].rect_spherical
        self.world_map, self.world_dist = world.world_map, world.dist
        self.has_world = world.emits
        self.n_emitters = k + tris.emissive.size + int(world.emits)
        self.emitter_family = np.concatenate([
            np.array([_LAMP_FAMILY[int(kind)] for kind in lights.kind], np.int64),
            np.full(tris.emissive.size, TRIANGLES), np.full(int(world.emits), WORLD)])
        self.delta = np.zeros(self.n_emitters, bool)
        for family, rows in self._lamp_families():
            self.delta[rows] = family.is_delta(rows)
        # Lights a ray can hit: spheres, area lights and sun disks.
        self.shape_lights = np.nonzero(~self.delta[:k])[0]
        # Row of each family's first emitter: what a family's own rows are counted from.
        self.family_first = np.array([0, 0, 0, k, 0])
        self.present_families = np.unique(self.emitter_family)

        power = self._power(scene)
        self.notes = []
        if selection == TreeSelection.name:
            self.selector = TreeSelection(power, lights, self.emitter_family[:k] == SUN, tris,
                                          world.emits, method)
            self.path_selector = PowerSelection(power, k, tris, world.emits, method)
            if self.selector.tree is not None and not self.selector.steers:
                # The same probabilities without the tree's per-sample work.
                self.notes.append(_tree_as_power_note(self.selector.tree.leaf_rows.size))
                self.selector = self.path_selector
        else:
            self.selector = self.path_selector = SELECTIONS[selection](power, k, tris,
                                                                       world.emits, method)
        # Light paths' choice (see the class docstring).
        self.light_dist = self.path_selector.light_dist
        self.triangle_dist = self.path_selector.triangle_dist
        self.select_prob = self.path_selector.select_prob
        self.world_index = self.path_selector.world_index
        # Next-event estimation's probability of the world, which is independent of the point.
        self.world_select_prob = (self.selector.pmf(np.array([self.world_index]))[0]
                                  if self.has_world else 0.0)
        self.build_s = (self.selector.build_s + world.build_s
                        + (self.path_selector.build_s if self.path_selector is not self.selector
                           else 0.0))

    def _power(self, scene):
        """Estimated power per light (lamps, emission materials, world), for selection."""
        # Scene radius, for the power of distant emitters.
        if scene.vertices.size:
            lo, hi = scene.vertices.min(axis=0), scene.vertices.max(axis=0)
            radius = 0.5 * float(np.linalg.norm(hi.astype(np.float64) - lo))
        else:
            radius = 1.0
        radius = max(radius, 1e-3)
        power = np.array(self.lights.power, np.float64)
        for family, rows in self._lamp_families():
            power[rows] = family.lamp_power(rows, radius)
        power = np.concatenate([power, self.triangles.group_power()])
        if self.has_world:
            power = np.concatenate([power, [self.world_light.power(radius)]])
        return power

    # ------------------------------------------------------------------ emitter rows
    def _lamp_families(self):
        """``(family, lamp rows)`` of each lamp family."""
        lamp_family = self.emitter_family[:self.n_lights]
        for f in (POINT, SUN, AREA):
            yield self.families[f], np.nonzero(lamp_family == f)[0]

    def families_of(self, index):
        """``(family, rows, local index)`` for every family that emitter rows ``index (n,)``
        (-1: none) use: the batch rows that chose it and their rows in its own table."""
        present = self.present_families
        if present.size == 1:
            # One family (a single lamp, or only emissive meshes): no per-row lookup.
            groups = [(present[0], np.nonzero(index >= 0)[0])]
        else:
            fam = self.emitter_family[np.maximum(index, 0)] if present.size else index
            if present.size and (index < 0).any():
                fam = np.where(index >= 0, fam, -1)
            groups = [(f, np.nonzero(fam == f)[0]) for f in present]
        for f, m in groups:
            if m.size:
                yield self.families[f], m, index[m] - self.family_first[f]

    def is_infinite(self, index):
        """Whether emitter rows ``index (n,)`` are the world or suns."""
        if not self.emitter_family.size:
            return np.zeros(index.shape[0], bool)
        fam = np.where(index >= 0, self.emitter_family[np.maximum(index, 0)], -1)
        return (fam == SUN) | (fam == WORLD)

    # ------------------------------------------------------------------ next-event estimation
    def choose(self, u_select, counters=None):
        """Choose emitters for light paths (no receiving point): ``(index, pmf)``, see
        :meth:`.selection.LightSelection.choose`."""
        return self.path_selector.choose(u_select, counters)

    def nee_pmf(self, index, p, n=None):
        """Probability ``(m,)`` that next-event estimation from ``p (m, 3)`` (shading normals
        ``n (m, 3)`` or None) chooses emitter rows ``index (m,)``; 0 where ``index`` is -1."""
        if not self.selector.point_dependent:
            return np.where(index >= 0, self.select_prob[np.maximum(index, 0)]
                            if self.n_emitters else 0.0, 0.0)
        if not self.n_emitters:
            return np.zeros(index.shape[0])
        return np.where(index >= 0, self.selector.pmf(np.maximum(index, 0), p, n), 0.0)

    def sample(self, p, u_select, u, counters=None, n=None):
        """Sample an emitter and a point or direction on it, as seen from ``p``.

        Parameters
        ----------
        p : (n, 3) float64
            Receiving points.
        u_select : (n,) float
        u : (n, 2) float
        counters : core.integrators.base.Counters or None
            Receives the time spent choosing emitters.
        n : (n, 3) float64 or None
            Shading normals at ``p``, for the light tree's importance; rays that find
            emitters must then give :meth:`hit_shapes` and :meth:`triangle_pdf` the normal at
            their origin too, so that MIS sees the same probabilities.

        Returns
        -------
        wi, dist, radiance, pdf, delta, light_normal
            As :class:`.base.LiSamples`, with ``delta (n,) bool``: delta lights.
        """
        n_rows = p.shape[0]
        out = LiSamples.empty(n_rows)
        if self.selector.light_dist is None or n_rows == 0:
            return (out.wi, out.dist, out.radiance, out.pdf, np.zeros(n_rows, bool),
                    out.light_normal)
        index, pmf = self.selector.choose(u_select, counters, p, n)
        delta = self.delta[index]
        for family, m, local in self.families_of(index):
            family.sample_li(m, local, p, u, pmf, out, counters)
        return out.wi, out.dist, out.radiance, out.pdf, delta, out.light_normal

    def _sample_world_map(self, u):
        """See :meth:`.environment.World.sample_map`."""
        return self.world_light.sample_map(u)

    # ------------------------------------------------------------------ emitters found by rays
    def world_pdf(self, d):
        """Solid-angle density ``(n,)`` of NEE choosing the world and then direction ``d (n, 3)``
        (selection included); zero without a world."""
        return self.world_light.pdf_li(d)

    def world_radiance(self, d):
        """Background radiance ``(n, 3)`` for escaped rays ``d (n, 3)`` and NEE's pdf ``(n,)``
        for the same direction (selection included)."""
        return self.world_light.radiance(d), self.world_light.pdf_li(d)

    def triangle_pdf(self, prim, p_prev, dist, cos_light, n_prev=None):
        """See :meth:`.triangles.EmissiveTriangles.pdf_li`."""
        return self.triangles.pdf_li(prim, p_prev, dist, cos_light, n_prev)

    def _lamps(self, camera):
        """Lamps a ray can hit; camera rays see only lamps with ``visible_camera``."""
        for li in self.shape_lights:
            if not (camera and not self.lights.visible_camera[li]):
                yield li, self.families[self.emitter_family[li]]

    def hit_shapes(self, o, d, tmax, camera, n=None, tmin=None):
        """Emission from the light shapes (spheres, area lights, sun disks) rays pass, lamp by
        lamp in row order.

        Parameters
        ----------
        o, d : (n, 3) float64
            Ray origins and unit directions.
        tmax : (n,) float64
            Distance to the first surface (inf when the ray escapes).
        camera : bool
            Camera rays see only lights with ``visible_camera``.
        n : (n, 3) float64 or None
            Shading normals at the origins (as given to :meth:`sample` there).
        tmin : (n,) float64 or None
            Lamps met before this distance are left out (a path that passed a transparent
            surface found them on its earlier segment; its MIS origin stays behind it).

        Yields
        ------
        rows : (m,) int
            Rays that receive light from one lamp.
        radiance : (m, 3) float64
        pdf : (m,) float64
            Solid-angle density of NEE picking the same direction (selection included).
        """
        tree = self.selector.point_dependent
        for li, family in self._lamps(camera):
            hit = family.intersect(li, o, d, tmax, 1.0 if tree else self.select_prob[li])
            if hit is not None and tmin is not None:
                before = family.intersect(li, o, d, np.minimum(tmin, tmax), 1.0)
                if before is not None:
                    after = ~np.isin(hit[0], before[0])
                    hit = tuple(x[after] for x in hit) if after.any() else None
            if hit is not None and tree:
                rows, radiance, pdf = hit
                sel = self.selector.pmf(np.full(rows.size, li), o[rows],
                                        None if n is None else n[rows])
                hit = rows, radiance, pdf * sel
            if hit is not None:
                yield hit

    def lamp_points(self, o, d, tmax, camera):
        """Points where rays meet lamp surfaces (spheres, area lights) before ``tmax``, as light
        paths see them: a list of ``(rows, emitter index, point, normal, distance)``."""
        out = []
        for li, family in self._lamps(camera):
            hit = family.surface_points(li, o, d, tmax)
            if hit is not None:
                rows, q, normal, t = hit
                out.append((rows, np.full(rows.size, li), q, normal, t))
        return out

    def infinite_lamps(self, camera):
        """Sun lamps with a disk (no delta), which rays that escape the scene can see."""
        return [li for li, family in self._lamps(camera) if family is self.families[SUN]]
