"""Lights in Cycles' units, light selection, next-event sampling and emitter hits.

Constructors (:func:`point_light`, :func:`sun_light`, :func:`area_light`) turn Blender's light
settings (S = color x energy, in W or W/m^2) into the radiometric quantities of
:class:`core.scene.Lights`:

- point / spot of radius 0: intensity S / (4 pi) W/sr (spot: times its smoothstep cone falloff,
  not renormalised); radius r > 0: a sphere of radiance S / (4 pi^2 r^2);
- sun: irradiance S W/m^2; with angular diameter a > 0, a disk of radiance S / (pi sin^2(a/2));
- area: radiance S / (pi A), one-sided toward the light's local -Z (A x pi/4 for disk, ellipse).

:class:`LightSampler` gathers every emitter of a scene (these lights, emissive triangles and the
world) into one table, chooses among them (in proportion to estimated power, or uniformly over
lights; by CDF inversion or an alias table), samples a point or direction on the chosen one
(next-event estimation; area emitters by area or by solid angle), and evaluates the solid-angle
density of the same choice for emitters found by BSDF sampling, so that the two strategies can be
combined by MIS.
The world is one emitter: a constant background is sampled uniformly on the sphere; an
equirectangular environment map (:attr:`core.scene.Scene.world_map`) is importance-sampled by a
:class:`~core.sampling.distributions.PiecewiseConstant2D` over its luminance x sin(theta)
(:func:`environment_importance`), with the solid-angle pdf ``pdf_uv / (2 pi^2 sin theta)``.
Area and sphere lights are not occluders: as in Cycles, they emit toward rays that pass through
them and never block light.
"""

from __future__ import annotations

import time

import numpy as np

from ..sampling import warps
from ..sampling.distributions import (
    DISTRIBUTION_METHODS,
    PiecewiseConstant2D,
    Segmented1D,
    make_distribution,
)
from ..scene import LIGHT_DISK, LIGHT_POINT, LIGHT_RECT, LIGHT_SUN, Lights

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])

# How next-event estimation chooses a light, and how it samples a point on an area emitter.
LIGHT_SELECTIONS = ("power", "uniform")
LIGHT_SAMPLINGS = ("area", "solid_angle")


def _row(kind, name, visible_camera, position=(0, 0, 0), axis_x=(0, 0, 0), axis_y=(0, 0, 0),
         direction=(0, 0, -1), radius=0.0, angle=0.0, radiance=(0, 0, 0), spot_cos_half=-1.0,
         spot_smooth=np.inf, power=0.0, soft_falloff=False) -> Lights:
    v3 = lambda a: np.asarray(a, np.float64).reshape(1, 3)  # noqa: E731
    v1 = lambda a: np.asarray([a], np.float64)  # noqa: E731
    return Lights(
        kind=np.asarray([kind], np.int32), position=v3(position), axis_x=v3(axis_x),
        axis_y=v3(axis_y), direction=v3(direction), radius=v1(radius), angle=v1(angle),
        radiance=v3(radiance), spot_cos_half=v1(spot_cos_half), spot_smooth=v1(spot_smooth),
        power=v1(power), visible_camera=np.asarray([bool(visible_camera)]),
        soft_falloff=np.asarray([bool(soft_falloff)]), names=[name],
    )


def _unit(v):
    v = np.asarray(v, np.float64)
    n = np.linalg.norm(v)
    return v / n if n > 0 else np.array([0.0, 0.0, -1.0])


def point_light(position, color, energy, radius=0.0, name="Point", visible_camera=True,
                spot_direction=None, spot_size=None, spot_blend=0.0, soft_falloff=False) -> Lights:
    """A Blender point light, or a spot light when ``spot_direction`` is given.

    With a radius, the lamp is a sphere of radiance S / (4 pi^2 r^2) that also lights points
    inside it; with ``soft_falloff`` (Blender's default) it is instead a disk of the same radius
    and radiance facing each receiving point, so light falls off as S / (4 pi (d^2 + r^2)) on its
    axis rather than rising sharply near the lamp.

    Parameters
    ----------
    position : (3,) float
    color : (3,) float
    energy : float
        Power in W (already times 2**exposure).
    radius : float
        Blender's ``shadow_soft_size``; 0 makes a delta light.
    spot_direction : (3,) float or None
        The spot's local -Z in world space.
    spot_size, spot_blend : float
        Full cone angle in radians and blend in [0, 1].
    soft_falloff : bool
        Blender's ``use_soft_falloff`` (only matters with a radius).
    """
    s = np.asarray(color, np.float64) * float(energy)
    radius = max(float(radius), 0.0)
    radiance = s / (4 * np.pi**2 * radius**2) if radius > 0 else s / (4 * np.pi)
    cos_half, smooth, direction = -1.0, np.inf, (0.0, 0.0, -1.0)
    if spot_direction is not None:
        cos_half = float(np.cos(0.5 * float(spot_size)))
        denom = (1.0 - cos_half) * float(spot_blend)
        smooth = 1.0 / denom if denom > 0 else np.inf
        direction = _unit(spot_direction)
    return _row(LIGHT_POINT, name, visible_camera, position=position, direction=direction,
                radius=radius, radiance=radiance, spot_cos_half=cos_half, spot_smooth=smooth,
                power=float(LUMINANCE @ s), soft_falloff=soft_falloff and radius > 0)


def sun_light(direction, color, strength, angle=0.0, name="Sun", visible_camera=True) -> Lights:
    """A Blender sun: ``direction`` is where the light travels (the object's local -Z).

    ``strength`` is the irradiance in W/m^2 on a surface facing the sun; ``angle`` the angular
    diameter in radians. The power used for light selection is filled in by :class:`LightSampler`
    from the scene's size.
    """
    s = np.asarray(color, np.float64) * float(strength)
    angle = max(float(angle), 0.0)
    radiance = s / (np.pi * np.sin(0.5 * angle) ** 2) if angle > 0 else s
    return _row(LIGHT_SUN, name, visible_camera, direction=_unit(direction), angle=angle,
                radiance=radiance, power=float(LUMINANCE @ s))


def area_light(matrix_world, shape, size_x, size_y, color, energy, name="Area",
               visible_camera=True) -> Lights:
    """A Blender area light of ``shape`` in {'SQUARE', 'RECTANGLE', 'DISK', 'ELLIPSE'}.

    Parameters
    ----------
    matrix_world : (4, 4) float
        Object matrix (object scale stretches the light as in Blender).
    size_x, size_y : float
        Light size; ``size_y`` is ignored for SQUARE and DISK.
    energy : float
        Power in W (already times 2**exposure).
    """
    m = np.asarray(matrix_world, np.float64)
    if shape in ("SQUARE", "DISK"):
        size_y = size_x
    axis_x = m[:3, 0] * float(size_x)
    axis_y = m[:3, 1] * float(size_y)
    normal = np.cross(axis_x, axis_y)
    area = float(np.linalg.norm(normal))
    kind = LIGHT_RECT
    if shape in ("DISK", "ELLIPSE"):
        area *= np.pi / 4
        kind = LIGHT_DISK
    s = np.asarray(color, np.float64) * float(energy)
    radiance = s / (np.pi * area) if area > 0 else np.zeros(3)
    return _row(kind, name, visible_camera, position=m[:3, 3], axis_x=axis_x, axis_y=axis_y,
                direction=-_unit(normal), radiance=radiance, power=float(LUMINANCE @ s))


def spot_attenuation(lights: Lights, index, w_out):
    """Cycles' smoothstep cone falloff for the lights ``index (n,)`` toward ``w_out (n, 3)``.

    ``w_out`` is the unit direction light travels, from the lamp to the receiver. Point lights
    (``spot_cos_half == -1``) give one.
    """
    cos_half = lights.spot_cos_half[index]
    smooth = lights.spot_smooth[index]
    cos = np.einsum("ij,ij->i", w_out, lights.direction[index])
    with np.errstate(invalid="ignore", over="ignore"):
        x = np.where(np.isinf(smooth), np.where(cos > cos_half, 1.0, 0.0),
                     (cos - cos_half) * np.where(np.isinf(smooth), 0.0, smooth))
    x = np.clip(x, 0.0, 1.0)
    att = x * x * (3.0 - 2.0 * x)
    return np.where(cos_half <= -1.0, 1.0, att)


def _dot(a, b):
    return np.einsum("ij,ij->i", a, b)


def _normalize(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-300)


# ------------------------------------------------------------------ environment maps
def equirect_uv(d):
    """Cycles' ``direction_to_equirectangular``: world directions to map coordinates.

    ``u = 0.5 - atan2(y, x) / (2 pi)`` (u = 0.5 faces +X, 0.25 faces +Y, 0 and 1 face -X) and
    ``v = 0.5 + atan2(z, hypot(x, y)) / pi`` (v = 1 is the zenith +Z, v = 0 the nadir).

    Parameters
    ----------
    d : (n, 3) float
        Directions (need not be unit length).

    Returns
    -------
    uv : (n, 2) float64
        In [0, 1)^2 for u, [0, 1] for v.
    """
    d = np.asarray(d, np.float64)
    rho = np.hypot(d[:, 0], d[:, 1])
    u = np.mod(0.5 - np.arctan2(d[:, 1], d[:, 0]) / (2 * np.pi), 1.0)
    v = 0.5 + np.arctan2(d[:, 2], rho) / np.pi
    return np.stack([u, np.clip(v, 0.0, 1.0)], axis=-1)


def equirect_direction(uv):
    """Inverse of :func:`equirect_uv`: ``uv (n, 2)`` -> unit ``d (n, 3)``, ``sin_theta (n,)``."""
    uv = np.asarray(uv, np.float64)
    phi = np.pi - 2 * np.pi * uv[:, 0]
    theta = np.pi * (1.0 - uv[:, 1])
    sin_t = np.sin(theta)
    d = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), np.cos(theta)], axis=-1)
    return d, sin_t


def environment_lookup(world_map, uv):
    """Radiance of an equirectangular map at ``uv (n, 2)``: ``(n, 3)`` float64.

    Bilinear between pixel centres with wrap-around on both axes, as Cycles' Environment
    Texture with its default Linear interpolation and Repeat extension (so the half row next
    to each pole blends with the opposite pole's row, as in Cycles). Row 0 of ``world_map
    (h, w, 3)`` is v = 0 (the nadir).
    """
    h, w = world_map.shape[:2]
    x = np.asarray(uv[:, 0], np.float64) * w - 0.5
    y = np.asarray(uv[:, 1], np.float64) * h - 0.5
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = (x - x0)[:, None]
    fy = (y - y0)[:, None]
    ix0 = np.mod(x0.astype(np.int64), w)
    iy0 = np.mod(y0.astype(np.int64), h)
    ix1 = np.mod(ix0 + 1, w)
    iy1 = np.mod(iy0 + 1, h)
    m = world_map
    bottom = (1 - fx) * m[iy0, ix0] + fx * m[iy0, ix1]
    top = (1 - fx) * m[iy1, ix0] + fx * m[iy1, ix1]
    return (1 - fy) * bottom + fy * top


def environment_importance(world_map):
    """Sampling weights ``(h, w)`` of a map's cells: mean luminance of the interpolated map
    over each pixel's cell, times sin(theta) at the row's centre.

    The cell mean of the bilinear interpolant weighs the pixel by 3/4 and each neighbour by
    1/8 per axis (wrapping as :func:`environment_lookup`), so every cell where the looked-up
    radiance is non-zero has a non-zero weight: sampling stays unbiased around a single bright
    pixel. sin(theta) makes the density uniform in solid angle for a constant map.
    """
    lum = np.asarray(world_map, np.float64) @ LUMINANCE
    lum = 0.75 * lum + 0.125 * (np.roll(lum, 1, axis=1) + np.roll(lum, -1, axis=1))
    lum = 0.75 * lum + 0.125 * (np.roll(lum, 1, axis=0) + np.roll(lum, -1, axis=0))
    h = lum.shape[0]
    sin_row = np.sin(np.pi * (np.arange(h) + 0.5) / h)
    return np.maximum(lum, 0.0) * sin_row[:, None]


class LightSampler:
    """Every emitter of a scene in one selection table.

    Emitter rows are the scene's lights (rows ``0..k-1``), then the emissive triangles (grouped
    by material), then the world (if its radiance is not black). ``select_prob[i]`` is the
    probability that next-event estimation chooses emitter ``i``.

    The choice is made in two steps, each a discrete distribution built with ``method``
    (``'cdf'`` or ``'alias'``, see :mod:`core.sampling.distributions`):

    1. a *light*: each lamp, each emission material (all triangles that share it form one light,
       as an emissive object would) and the world. ``selection='power'`` chooses them in
       proportion to their estimated power; ``'uniform'`` chooses every light that emits with
       the same probability;
    2. for an emission material, one of its triangles in proportion to its power
       (area x luminance of its radiance), with the remapped random number of step 1.

    With ``'power'`` the product is each emitter's share of the total power, as a single table
    would give. Both rules are unbiased: the pdfs reported to MIS use the same probabilities.

    ``sampling`` picks how a point on an area emitter is chosen: ``'area'`` (uniform on the
    surface) or ``'solid_angle'`` (uniform over the solid angle it subtends: spherical triangles,
    Arvo 1995, for emissive triangles; spherical rectangles, Ureña et al. 2013, for square and
    rectangular area lights). Disk and ellipse lights, sheared rectangles, and emitters that
    subtend less than ``MIN_SPHERICAL_SOLID_ANGLE`` or more than ``MAX_SPHERICAL_SOLID_ANGLE``
    (where the spherical warps lose precision) are sampled by area; the pdfs of emitters found
    by rays make the same decision from the same point, so MIS sees the density actually used.

    Parameters
    ----------
    scene : core.scene.Scene
    tri_area : (t,) float64
        Triangle areas.
    tri_normal : (t, 3) float64
        Unit geometric normals.
    tri_v0, tri_e1, tri_e2 : (t, 3) float64
        First vertex and edges of every triangle.
    selection : str
        ``'power'`` or ``'uniform'``.
    sampling : str
        ``'area'`` or ``'solid_angle'``.
    method : str
        ``'cdf'`` or ``'alias'`` (also for the environment map's 2D distribution).

    Attributes
    ----------
    build_s : float
        Seconds spent building the selection distributions.
    world_map : (h, w, 3) float32 or None
        The scene's environment map (non-finite and negative texels set to 0), or None for a
        constant (or black) world.
    world_dist : core.sampling.distributions.PiecewiseConstant2D or None
        Over :func:`environment_importance` of ``world_map``; u along columns, v along rows.
    """

    def __init__(self, scene, tri_area, tri_normal, tri_v0, tri_e1, tri_e2, selection="power",
                 sampling="area", method="cdf"):
        for value, allowed, what in ((selection, LIGHT_SELECTIONS, "light selection"),
                                     (sampling, LIGHT_SAMPLINGS, "light sampling"),
                                     (method, DISTRIBUTION_METHODS, "distribution")):
            if value not in allowed:
                raise ValueError(f"unknown {what} {value!r}; choose from {', '.join(allowed)}")
        self.selection = selection
        self.sampling = sampling
        self.solid_angle = sampling == "solid_angle"
        self.method = method
        self.lights = scene.lights
        k = len(scene.lights)
        emission = scene.materials.emission[scene.material].astype(np.float64)
        tri_power = (emission @ LUMINANCE) * (2 * np.pi * tri_area)
        emissive = np.nonzero((emission.max(axis=1) > 0) & (tri_area > 0))[0]
        # One light per emission material: its triangles are contiguous rows.
        emissive = emissive[np.argsort(scene.material[emissive], kind="stable")]
        groups, group_start = np.unique(scene.material[emissive], return_index=True)
        self.n_groups = groups.size
        self.emissive_tris = emissive
        self.tri_emitter = np.full(scene.n_triangles, -1, np.int64)
        self.tri_emitter[emissive] = k + np.arange(emissive.size)
        self.tri_area = tri_area
        self.tri_normal = tri_normal
        self.tri_emission = emission
        self.tri_v0, self.tri_e1, self.tri_e2 = tri_v0, tri_e1, tri_e2
        # Emitters' own copies, so that sampling gathers from small arrays.
        self.emit_v0 = tri_v0[emissive]
        self.emit_e1 = tri_e1[emissive]
        self.emit_e2 = tri_e2[emissive]
        self.emit_normal = tri_normal[emissive]
        self.emit_area = tri_area[emissive]
        self.emit_radiance = emission[emissive]
        self.emit_group = np.repeat(np.arange(groups.size),
                                    np.diff(np.append(group_start, emissive.size)))
        self.world = np.asarray(scene.world_color, np.float64)
        self.world_map = None
        self.world_dist = None
        world_map = getattr(scene, "world_map", None)
        if world_map is not None:
            world_map = np.asarray(world_map, np.float32)
            # No NaN reaches the film, and negative radiance is not light.
            world_map = np.where(np.isfinite(world_map), np.maximum(world_map, 0.0),
                                 0.0).astype(np.float32)
            importance = environment_importance(world_map)
            # A black map is no emitter: no environment sampling for a black world.
            self.has_world = bool(importance.max() > 0)
            if self.has_world:
                self.world_map = world_map
                t0 = time.perf_counter()
                self.world_dist = PiecewiseConstant2D(importance, method)
                world_build_s = time.perf_counter() - t0
        else:
            self.has_world = bool(self.world.max() > 0)
        self.n_lights = k
        self.world_index = k + emissive.size if self.has_world else -1

        # Scene radius, for the power of distant emitters.
        if scene.vertices.size:
            lo, hi = scene.vertices.min(axis=0), scene.vertices.max(axis=0)
            radius = 0.5 * float(np.linalg.norm(hi.astype(np.float64) - lo))
        else:
            radius = 1.0
        radius = max(radius, 1e-3)
        power = np.array(self.lights.power, np.float64)
        power[self.lights.kind == LIGHT_SUN] *= np.pi * radius**2
        group_power = (np.add.reduceat(tri_power[emissive], group_start) if emissive.size
                       else np.zeros(0))
        power = np.concatenate([power, group_power])
        if self.world_dist is not None:
            # Mean luminance over the sphere: (1 / 4 pi) sum f 2 pi^2 / (h w) = pi / 2 mean(f).
            world_lum = 0.5 * np.pi * self.world_dist.integral
        else:
            world_lum = float(LUMINANCE @ self.world)
        if self.has_world:
            power = np.concatenate([power, [4 * np.pi**2 * radius**2 * world_lum]])
        self.n_emitters = k + emissive.size + int(self.has_world)
        self.delta = np.zeros(self.n_emitters, bool)
        self.delta[:k] = ((self.lights.kind == LIGHT_POINT) & (self.lights.radius <= 0)) | (
            (self.lights.kind == LIGHT_SUN) & (self.lights.angle <= 0))
        # Sheared rectangles are parallelograms: the spherical-rectangle warp does not apply.
        ax, ay = self.lights.axis_x, self.lights.axis_y
        cross = np.linalg.norm(ax, axis=1) * np.linalg.norm(ay, axis=1)
        self.rect_spherical = (self.lights.kind == LIGHT_RECT) & (
            np.abs(_dot(ax, ay)) <= 1e-6 * cross) & (cross > 0)

        t0 = time.perf_counter()
        weights = power if selection == "power" else (power > 0).astype(np.float64)
        self.light_dist = make_distribution(weights, method) if weights.size else None
        self.triangle_dist = (Segmented1D(tri_power[emissive], np.append(group_start,
                                                                         emissive.size), method)
                              if emissive.size else None)
        self.build_s = time.perf_counter() - t0
        if self.world_dist is not None:
            self.build_s += world_build_s
        if self.light_dist is not None:
            light_pmf = self.light_dist.pmf_table
            tri_prob = (light_pmf[k + self.emit_group] * self.triangle_dist.pmf_table
                        if emissive.size else np.zeros(0))
            self.select_prob = np.concatenate([light_pmf[:k], tri_prob,
                                               light_pmf[k + groups.size:]])
        else:
            self.select_prob = np.zeros(0)
        # Lights a ray can hit: spheres, area lights and sun disks.
        self.shape_lights = np.nonzero(~self.delta[:k])[0]

    # ------------------------------------------------------------------ emitter choice
    def choose(self, u_select, counters=None):
        """Choose emitters for next-event estimation.

        Parameters
        ----------
        u_select : (n,) float
            Uniform in [0, 1): picks the light, and its remapped value the triangle.
        counters : core.integrators.common.Counters or None
            Receives the time spent and the number of discrete draws.

        Returns
        -------
        index : (n,) int64
            Emitter rows.
        pmf : (n,) float64
            Their selection probabilities (``select_prob[index]``).
        """
        t0 = time.perf_counter()
        k = self.n_lights
        light, pmf, u_next = self.light_dist.sample(u_select)
        index = light.copy()
        draws = light.size
        m = np.nonzero((light >= k) & (light < k + self.n_groups))[0]
        if m.size:
            e, pmf_tri, _ = self.triangle_dist.sample(light[m] - k, u_next[m])
            index[m] = k + e
            pmf[m] = pmf[m] * pmf_tri
            draws += m.size
        if self.has_world:
            index[light == k + self.n_groups] = self.world_index
        if counters is not None:
            counters.distribution_s += time.perf_counter() - t0
            counters.distribution_samples += draws
        return index, pmf

    def _use_spherical_triangle(self, a, b, c, p):
        """Solid angles ``(n,)`` and where the spherical-triangle warp is used, ``(n,)`` bool.

        Area sampling never needs the solid angle: it is not computed then (zeros).
        """
        if not self.solid_angle:
            return np.zeros(p.shape[0]), np.zeros(p.shape[0], bool)
        omega = warps.spherical_triangle_solid_angle(a, b, c, p)
        use = ((omega >= warps.MIN_SPHERICAL_SOLID_ANGLE)
               & (omega <= warps.MAX_SPHERICAL_SOLID_ANGLE))
        return omega, use

    def _use_spherical_rectangle(self, li, p):
        """Solid angles ``(n,)`` of area lights ``li`` from ``p`` and where the warp is used."""
        lights = self.lights
        corner = lights.position[li] - 0.5 * (lights.axis_x[li] + lights.axis_y[li])
        # Only rectangles sampled by solid angle need it; the rest skip the arithmetic.
        use = self.rect_spherical[li] & self.solid_angle
        omega = np.zeros(p.shape[0])
        rows = np.nonzero(use)[0]
        if rows.size:
            lr = li[rows]
            omega[rows] = warps.spherical_rectangle_solid_angle(
                corner[rows], lights.axis_x[lr], lights.axis_y[lr], p[rows])
        front = _dot(p - lights.position[li], lights.direction[li]) > 0
        use &= front & (omega >= warps.MIN_SPHERICAL_SOLID_ANGLE) & (
            omega <= warps.MAX_SPHERICAL_SOLID_ANGLE)
        return omega, corner, use

    # ------------------------------------------------------------------ next-event estimation
    def sample(self, p, u_select, u, counters=None):
        """Sample an emitter and a point or direction on it, as seen from ``p``.

        Parameters
        ----------
        p : (n, 3) float64
            Receiving points.
        u_select : (n,) float
        u : (n, 2) float
        counters : core.integrators.common.Counters or None
            Receives the time spent choosing emitters (see :meth:`choose`).

        Returns
        -------
        wi : (n, 3) float64
            Unit direction from ``p`` toward the light.
        dist : (n,) float64
            Distance to the sampled point (inf for sun and world).
        radiance : (n, 3) float64
            Arriving radiance (for delta lights: intensity / dist^2 or irradiance).
        pdf : (n,) float64
            Solid-angle density times the selection probability (for delta lights: the
            selection probability alone). Zero marks a failed sample.
        delta : (n,) bool
        light_normal : (n, 3) float64
            Normal of the sampled emitter point (zero for delta, sun and world), for offsets.
        """
        n = p.shape[0]
        wi = np.zeros((n, 3))
        wi[:, 2] = 1.0
        dist = np.full(n, np.inf)
        radiance = np.zeros((n, 3))
        pdf = np.zeros(n)
        light_normal = np.zeros((n, 3))
        if self.light_dist is None or n == 0:
            return wi, dist, radiance, pdf, np.zeros(n, bool), light_normal
        index, pmf = self.choose(u_select, counters)
        delta = self.delta[index]
        lights = self.lights
        k = self.n_lights

        is_light = index < k
        lidx = np.where(is_light, index, 0)
        kind = np.where(is_light, lights.kind[lidx] if k else 0, -1)

        # Point and spot lights: delta points; spheres sampled by their cone of directions (or
        # uniformly from inside); soft-falloff disks facing the receiver sampled by area.
        m = np.nonzero(kind == LIGHT_POINT)[0]
        if m.size:
            li = lidx[m]
            c = lights.position[li]
            r = lights.radius[li]
            to_c = c - p[m]
            d_c = np.sqrt(_dot(to_c, to_c))
            axis = to_c / np.maximum(d_c, 1e-300)[:, None]
            point = r <= 0
            soft = lights.soft_falloff[li] & ~point
            sphere = ~point & ~soft
            inside = sphere & (d_c <= r)
            s_, t_ = warps.frame_from_normal(axis)
            uu = u[m]
            # Sphere seen from outside: the cone it subtends.
            sin2 = np.clip((r / np.maximum(d_c, 1e-300)) ** 2, 0.0, 1.0)
            cos_max = np.minimum(np.sqrt(1.0 - sin2), 1 - 1e-12)
            w_cone = warps.to_world(warps.sample_uniform_cone(uu, cos_max), s_, t_, axis)
            b = _dot(w_cone, to_c)
            t_cone = b - np.sqrt(np.maximum(b * b - (d_c * d_c - r * r), 0.0))
            # Sphere seen from inside: every direction meets its inner surface.
            w_in = warps.sample_uniform_sphere(uu)
            b_in = _dot(w_in, to_c)
            t_in = b_in + np.sqrt(np.maximum(b_in * b_in - (d_c * d_c - r * r), 0.0))
            # Soft falloff: a uniform point on the disk of radius r facing the receiver.
            disk = warps.sample_uniform_disk_concentric(uu) * r[:, None]
            q = c + disk[:, 0:1] * s_ + disk[:, 1:2] * t_
            to_q = q - p[m]
            t_disk = np.sqrt(_dot(to_q, to_q))
            w_disk = to_q / np.maximum(t_disk, 1e-300)[:, None]
            cos_disk = _dot(w_disk, axis)
            with np.errstate(divide="ignore", invalid="ignore"):
                pdf_disk = t_disk**2 / (np.pi * r * r * cos_disk)

            w = np.where(point[:, None], axis, np.where(soft[:, None], w_disk,
                         np.where(inside[:, None], w_in, w_cone)))
            t_hit = np.where(point, d_c, np.where(soft, t_disk, np.where(inside, t_in, t_cone)))
            sa_pdf = np.where(point, 1.0, np.where(
                soft, pdf_disk, np.where(inside, warps.uniform_sphere_pdf(m.size),
                                         warps.uniform_cone_pdf(cos_max))))
            att = spot_attenuation(lights, li, -w)
            lum = lights.radiance[li] * att[:, None]
            lum = np.where(point[:, None], lum / np.maximum(d_c * d_c, 1e-300)[:, None], lum)
            ok = (d_c > 0) & np.isfinite(sa_pdf) & (sa_pdf > 0) & ~(soft & (cos_disk <= 0))
            wi[m] = w
            dist[m] = t_hit
            radiance[m] = np.where(ok[:, None], lum, 0.0)
            pdf[m] = np.where(ok, sa_pdf * pmf[m], 0.0)
            # Lamps are not geometry, so shadow rays need no offset at their end.
            light_normal[m] = 0.0

        # Suns: a direction, or a cone of directions toward the disk.
        m = np.nonzero(kind == LIGHT_SUN)[0]
        if m.size:
            li = lidx[m]
            axis = -lights.direction[li]
            ang = lights.angle[li]
            cos_max = np.cos(0.5 * ang)
            s_, t_ = warps.frame_from_normal(axis)
            w_loc = warps.sample_uniform_cone(u[m], cos_max)
            is_d = ang <= 0
            wi[m] = np.where(is_d[:, None], axis, warps.to_world(w_loc, s_, t_, axis))
            radiance[m] = lights.radiance[li]
            pdf[m] = np.where(is_d, 1.0, warps.uniform_cone_pdf(np.minimum(cos_max, 1 - 1e-12))) * pmf[m]

        # Area lights: uniformly by area, or rectangles by solid angle.
        m = np.nonzero((kind == LIGHT_RECT) | (kind == LIGHT_DISK))[0]
        if m.size:
            li = lidx[m]
            disk = kind[m] == LIGHT_DISK
            uu = u[m]
            local = np.where(disk[:, None], 0.5 * warps.sample_uniform_disk_concentric(uu), uu - 0.5)
            q = (lights.position[li] + local[:, 0:1] * lights.axis_x[li]
                 + local[:, 1:2] * lights.axis_y[li])
            area = np.linalg.norm(np.cross(lights.axis_x[li], lights.axis_y[li]), axis=1)
            area = np.where(disk, area * np.pi / 4, area)
            omega, corner, sph = self._use_spherical_rectangle(li, p[m])
            if sph.any():
                q[sph] = warps.sample_spherical_rectangle(uu[sph], corner[sph],
                                                          lights.axis_x[li[sph]],
                                                          lights.axis_y[li[sph]], p[m[sph]])
            self._area_point_sample(m, p, q, lights.direction[li], area, lights.radiance[li], pmf,
                                    True, wi, dist, radiance, pdf, light_normal)
            self._solid_angle_pdf(m, sph, omega, pmf, pdf)

        # Emissive triangles, uniformly by area or by solid angle; they emit from both faces.
        m = np.nonzero((index >= k) & (index != self.world_index))[0]
        if m.size:
            e = index[m] - k
            v0, e1, e2 = self.emit_v0[e], self.emit_e1[e], self.emit_e2[e]
            b = warps.sample_uniform_triangle(u[m])
            q = v0 + b[:, 1:2] * e1 + b[:, 2:3] * e2
            omega, sph = self._use_spherical_triangle(v0, v0 + e1, v0 + e2, p[m])
            if sph.any():
                ps, nrm = p[m[sph]], self.emit_normal[e[sph]]
                w = warps.sample_spherical_triangle(u[m[sph]], v0[sph], v0[sph] + e1[sph],
                                                    v0[sph] + e2[sph], ps)
                # The sampled point is where the direction meets the triangle's plane.
                with np.errstate(divide="ignore", invalid="ignore"):
                    t = _dot(v0[sph] - ps, nrm) / _dot(w, nrm)
                q[sph] = ps + w * np.where(np.isfinite(t) & (t > 0), t, 0.0)[:, None]
            self._area_point_sample(m, p, q, self.emit_normal[e], self.emit_area[e],
                                    self.emit_radiance[e], pmf, False, wi, dist, radiance, pdf,
                                    light_normal)
            self._solid_angle_pdf(m, sph, omega, pmf, pdf)

        # The world: an environment map by its importance, a constant one uniformly.
        if self.has_world:
            m = np.nonzero(index == self.world_index)[0]
            if self.world_dist is not None:
                t0 = time.perf_counter()
                w, le, sa_pdf = self._sample_world_map(u[m])
                if counters is not None:
                    # The map's row and column draws count as the distributions' work.
                    counters.distribution_s += time.perf_counter() - t0
                    counters.distribution_samples += 2 * m.size
                wi[m] = w
                radiance[m] = le
                pdf[m] = sa_pdf * pmf[m]
            else:
                wi[m] = warps.sample_uniform_sphere(u[m])
                radiance[m] = self.world
                pdf[m] = warps.uniform_sphere_pdf(m.size) * pmf[m]
        return wi, dist, radiance, pdf, delta, light_normal

    def _sample_world_map(self, u):
        """Directions ``(k, 3)``, radiance ``(k, 3)`` and solid-angle pdf ``(k,)`` (selection
        excluded) drawn from the environment map's distribution with ``u (k, 2)``.

        The pdf is ``pdf_uv / (2 pi^2 sin theta)`` (d omega = 2 pi^2 sin theta du dv); a
        direction exactly at a pole (sin theta = 0) is a failed sample (pdf 0, no radiance).
        """
        uv, pdf_uv = self.world_dist.sample_continuous(u)
        w, sin_t = equirect_direction(uv)
        ok = sin_t > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            sa_pdf = np.where(ok, pdf_uv / (2 * np.pi**2 * sin_t), 0.0)
        ok &= np.isfinite(sa_pdf) & (sa_pdf > 0)
        le = np.where(ok[:, None], environment_lookup(self.world_map, uv), 0.0)
        return w, le, np.where(ok, sa_pdf, 0.0)

    def world_pdf(self, d):
        """Solid-angle density ``(n,)`` of NEE choosing the world and then direction ``d (n, 3)``
        (selection included); zero without a world."""
        n = d.shape[0]
        if not self.has_world:
            return np.zeros(n)
        sel = self.select_prob[self.world_index]
        if self.world_dist is None:
            return sel * warps.uniform_sphere_pdf(n)
        d = np.asarray(d, np.float64)
        sin_t = np.hypot(d[:, 0], d[:, 1]) / np.maximum(np.linalg.norm(d, axis=1), 1e-300)
        pdf_uv = self.world_dist.pdf(equirect_uv(d))
        with np.errstate(divide="ignore", invalid="ignore"):
            pdf = np.where(sin_t > 0, sel * pdf_uv / (2 * np.pi**2 * sin_t), 0.0)
        return np.where(np.isfinite(pdf), pdf, 0.0)

    @staticmethod
    def _solid_angle_pdf(m, sph, omega, pmf, pdf):
        """Replace the area pdf of the rows ``m[sph]`` sampled by solid angle with 1 / omega."""
        if sph.any():
            rows = m[sph]
            pdf[rows] = np.where(pdf[rows] > 0, pmf[rows] / omega[sph], 0.0)

    @staticmethod
    def _area_point_sample(m, p, q, normal, area, emitted, pmf, one_sided, wi, dist, radiance,
                           pdf, light_normal):
        d = q - p[m]
        d2 = _dot(d, d)
        r = np.sqrt(d2)
        w = d / np.maximum(r, 1e-300)[:, None]
        cos_l = -_dot(w, normal)
        if not one_sided:
            cos_l = np.abs(cos_l)
        ok = (cos_l > 1e-12) & (area > 0) & (r > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            sa = np.where(ok, d2 / (cos_l * area), 0.0)
        wi[m] = w
        dist[m] = r
        radiance[m] = np.where(ok[:, None], emitted, 0.0)
        pdf[m] = sa * pmf[m]
        light_normal[m] = normal

    # ------------------------------------------------------------------ emitters found by rays
    def triangle_pdf(self, prim, p_prev, dist, cos_light):
        """Solid-angle pdf with which NEE from ``p_prev`` picks the hit point on triangle ``prim``.

        Parameters
        ----------
        prim : (n,) int
            Hit triangles (emissive ones; others give 0).
        p_prev : (n, 3) float64
        dist : (n,) float64
            Distance from ``p_prev`` to the hit.
        cos_light : (n,) float64
            |cos| between the ray and the triangle normal.
        """
        e = self.tri_emitter[prim]
        sel = np.where(e >= 0, self.select_prob[np.maximum(e, 0)] if self.n_emitters else 0.0, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            pdf = sel * dist * dist / (np.abs(cos_light) * self.tri_area[prim])
        if self.solid_angle and prim.size:
            # The same decision as sample(): by solid angle where the warp is well conditioned.
            v0 = self.tri_v0[prim]
            omega, sph = self._use_spherical_triangle(v0, v0 + self.tri_e1[prim],
                                                      v0 + self.tri_e2[prim], p_prev)
            with np.errstate(divide="ignore", invalid="ignore"):
                pdf = np.where(sph, sel / omega, pdf)
        return np.where(np.isfinite(pdf), pdf, 0.0)

    def world_radiance(self, d):
        """Background radiance for escaped rays and NEE's pdf for the same direction.

        Parameters
        ----------
        d : (n, 3) float64
            Ray directions.

        Returns
        -------
        radiance : (n, 3) float64
            The environment map's looked-up radiance, or the constant world colour.
        pdf : (n,) float64
            Solid-angle density with which :meth:`sample` picks ``d`` (selection included).
        """
        n = d.shape[0]
        if not self.has_world:
            return np.zeros((n, 3)), np.zeros(n)
        if self.world_dist is None:
            return np.broadcast_to(self.world, (n, 3)).copy(), self.world_pdf(d)
        return environment_lookup(self.world_map, equirect_uv(d)), self.world_pdf(d)

    def hit_shapes(self, o, d, tmax, camera):
        """Emission from the light shapes (spheres, area lights, sun disks) a ray passes.

        Parameters
        ----------
        o, d : (n, 3) float64
            Ray origins and unit directions.
        tmax : (n,) float64
            Distance to the first surface (inf when the ray escapes).
        camera : bool
            Camera rays see only lights with ``visible_camera``.

        Yields
        ------
        rows : (m,) int
            Rays that receive light from one lamp.
        radiance : (m, 3) float64
        pdf : (m,) float64
            Solid-angle density of NEE picking the same direction (selection included).
        """
        lights = self.lights
        for li in self.shape_lights:
            if camera and not lights.visible_camera[li]:
                continue
            kind = lights.kind[li]
            pmf = self.select_prob[li]
            if kind == LIGHT_POINT and lights.soft_falloff[li]:
                # The disk of radius r facing the ray's origin, as NEE sampled it from there.
                c = lights.position[li]
                r = lights.radius[li]
                oc = o - c
                d_o = np.sqrt(_dot(oc, oc))
                light_n = oc / np.maximum(d_o, 1e-300)[:, None]
                denom = _dot(d, light_n)
                with np.errstate(divide="ignore", invalid="ignore"):
                    t = -d_o / denom
                hit = (denom < 0) & (t > 0) & (t < tmax) & (d_o > 0)
                h = oc + d * np.where(hit, t, 0.0)[:, None]
                rows = np.nonzero(hit & (_dot(h, h) <= r * r))[0]
                if rows.size == 0:
                    continue
                pdf = pmf * t[rows] ** 2 / (np.pi * r * r * -denom[rows])
                att = spot_attenuation(lights, np.full(rows.size, li), -d[rows])
                yield rows, lights.radiance[li] * att[:, None], pdf
            elif kind == LIGHT_POINT:
                c = lights.position[li]
                r = lights.radius[li]
                oc = o - c
                b = _dot(oc, d)
                cc = _dot(oc, oc) - r * r
                disc = b * b - cc
                outside = cc > 0
                # From outside the nearer intersection; from inside the sphere's far wall.
                t = np.where(outside, -b - np.sqrt(np.maximum(disc, 0.0)),
                             -b + np.sqrt(np.maximum(disc, 0.0)))
                rows = np.nonzero((disc > 0) & (t > 0) & (t < tmax))[0]
                if rows.size == 0:
                    continue
                dc2 = _dot(oc[rows], oc[rows])
                cos_max = np.sqrt(np.maximum(0.0, 1.0 - r * r / dc2))
                pdf = pmf * np.where(outside[rows],
                                     warps.uniform_cone_pdf(np.minimum(cos_max, 1 - 1e-12)),
                                     warps.uniform_sphere_pdf(rows.size))
                att = spot_attenuation(lights, np.full(rows.size, li), -d[rows])
                yield rows, lights.radiance[li] * att[:, None], pdf
            elif kind == LIGHT_SUN:
                cos_max = np.cos(0.5 * lights.angle[li])
                rows = np.nonzero(np.isinf(tmax) & (_dot(d, -lights.direction[li][None]) > cos_max))[0]
                if rows.size == 0:
                    continue
                pdf = np.full(rows.size, pmf * warps.uniform_cone_pdf(min(cos_max, 1 - 1e-12)))
                yield rows, np.broadcast_to(lights.radiance[li], (rows.size, 3)), pdf
            else:
                n_l = lights.direction[li]
                ax, ay = lights.axis_x[li], lights.axis_y[li]
                denom = np.einsum("ij,j->i", d, n_l)
                with np.errstate(divide="ignore", invalid="ignore"):
                    t = np.einsum("ij,j->i", lights.position[li] - o, n_l) / denom
                # One-sided: the ray must arrive at the emitting face (travel against its normal).
                front = denom < 0
                hit = front & (t > 0) & (t < tmax)
                q = o + d * np.where(hit, t, 0.0)[:, None] - lights.position[li]
                # Coordinates along the two axes by the dual basis, so that sheared lights
                # (parallelograms, which area sampling covers) are hit where they are.
                gram = np.array([[ax @ ax, ax @ ay], [ax @ ay, ay @ ay]])
                if not np.linalg.det(gram) > 0:
                    continue  # a light of zero size emits nothing
                x, y = np.linalg.solve(gram, np.stack([np.einsum("ij,j->i", q, ax),
                                                       np.einsum("ij,j->i", q, ay)]))
                if kind == LIGHT_RECT:
                    inside = (np.abs(x) <= 0.5) & (np.abs(y) <= 0.5)
                    area = np.linalg.norm(np.cross(ax, ay))
                else:
                    inside = x * x + y * y <= 0.25
                    area = np.linalg.norm(np.cross(ax, ay)) * np.pi / 4
                rows = np.nonzero(hit & inside)[0]
                if rows.size == 0:
                    continue
                cos_l = -denom[rows]
                pdf = pmf * t[rows] ** 2 / (cos_l * area)
                if self.solid_angle and kind == LIGHT_RECT:
                    omega, _, sph = self._use_spherical_rectangle(np.full(rows.size, li), o[rows])
                    pdf = np.where(sph, pmf / np.where(sph, omega, 1.0), pdf)
                yield rows, np.broadcast_to(lights.radiance[li], (rows.size, 3)), pdf
