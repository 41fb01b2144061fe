"""Emission sampling for light paths: a point and a direction on every kind of emitter.

Light tracing and BDPT start paths at the lights. :class:`Emission` uses the selection tables of
a :class:`core.lights.LightSampler` (same probabilities as next-event estimation) and adds, per
emitter kind, how a light path leaves it:

========================  ===============================  ====================================
emitter                   origin (``pdf_origin``)           direction (``pdf_direction``)
========================  ===============================  ====================================
point / spot, radius 0    the point (delta: 1)              uniform sphere, or uniform in the
                                                            spot's cone
sphere (point radius>0)   uniform on the sphere, 1/4 pi r^2  cosine about the outward normal
area (rect, disk)         uniform on the shape, 1 / A        cosine about the emitting side
emissive triangle         uniform, 1 / A                    cosine about either face (1/2 each)
sun (angle 0)             the direction (delta: 1)          uniform on the scene's disk
sun disk, world           direction by the NEE density      uniform on the scene's disk
========================  ===============================  ====================================

Every pdf includes the emitter's selection probability in ``pdf_origin``. Densities are in
area measure for finite emitters and in solid angle for the direction of infinite ones (the sun
and the world, whose light enters through a disk of the scene's bounding sphere, area measure
``1 / (pi R^2)``), as pbrt's BDPT does; MIS converts them with the same conventions.

Approximations (reported by the render): Soft Falloff point lights are spheres here, and sphere
lights emit outward only on light paths (points inside a sphere light receive its light only
from the camera side: BDPT's s = 0 and s = 1 strategies, which keep :meth:`Emission.radiance`'s
inside rule; light tracing alone misses it).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .lights import spot_attenuation
from .sampling import warps
from .scene import LIGHT_DISK, LIGHT_POINT, LIGHT_RECT, LIGHT_SUN


def _dot(a, b):
    return np.einsum("ij,ij->i", a, b)


class EmitterPoints(NamedTuple):
    """Sampled light-path origins (the light endpoint ``x_0`` of a light subpath).

    Attributes
    ----------
    index : (n,) int64
        Emitter rows of the light sampler; -1 where nothing was sampled (no emitters).
    p : (n, 3) float64
        Points on finite emitters (zero for infinite ones).
    normal : (n, 3) float64
        Unit emitting normal (area lights: the emitting side; triangles: the stored normal;
        spheres: outward); zero for points and infinite emitters.
    w_inf : (n, 3) float64
        Direction light travels from an infinite emitter (zero for finite ones).
    pdf_origin : (n,) float64
        Selection probability times the area density of ``p`` (finite), or times the solid-angle
        density of ``w_inf`` (infinite); delta origins count their selection probability only.
    delta_light : (n,) bool
        Points of radius 0 and suns of angle 0: no ray can hit them.
    infinite : (n,) bool
    """

    index: np.ndarray
    p: np.ndarray
    normal: np.ndarray
    w_inf: np.ndarray
    pdf_origin: np.ndarray
    delta_light: np.ndarray
    infinite: np.ndarray


class Emission:
    """How light paths leave the emitters of a :class:`core.lights.LightSampler`.

    Parameters
    ----------
    lights : core.lights.LightSampler
    vertices : (v, 3) float
        Scene vertices (prepared frame): their bounding sphere, together with the lamps'
        positions, is where light from infinite emitters enters the scene.
    """

    def __init__(self, lights, vertices):
        self.ls = lights
        pts = [np.asarray(vertices, np.float64).reshape(-1, 3)]
        if lights.n_lights:
            pts.append(lights.lights.position[lights.lights.kind != LIGHT_SUN])
        pts = np.concatenate(pts)
        if pts.size:
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            self.center = 0.5 * (lo + hi)
            self.radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3) * 1.01
        else:
            self.center, self.radius = np.zeros(3), 1.0
        self.disk_pdf = 1.0 / (np.pi * self.radius**2)

    # ----------------------------------------------------------------------------- kinds
    def _kinds(self, index):
        """Per row: light row (or 0), light kind (or -1), triangle row (or -1), is-world."""
        ls = self.ls
        k = ls.n_lights
        is_light = (index >= 0) & (index < k)
        lidx = np.where(is_light, index, 0)
        kind = np.where(is_light, ls.lights.kind[lidx] if k else 0, -1)
        world = (index == ls.world_index) & ls.has_world
        tri = np.where((index >= k) & ~world, index - k, -1)
        return lidx, kind, tri, world

    def is_infinite(self, index):
        """Whether emitter rows ``index (n,)`` are the world or suns."""
        _, kind, _, world = self._kinds(index)
        return world | (kind == LIGHT_SUN)

    # ----------------------------------------------------------------------------- origins
    def sample_points(self, u_select, u, counters=None) -> EmitterPoints:
        """Choose emitters (as next-event estimation does) and a point or direction on each.

        Parameters
        ----------
        u_select : (n,) float
        u : (n, 2) float
        """
        ls = self.ls
        n = u.shape[0]
        p = np.zeros((n, 3))
        normal = np.zeros((n, 3))
        w_inf = np.zeros((n, 3))
        pdf = np.zeros(n)
        if ls.light_dist is None or n == 0:
            z = np.zeros(n, bool)
            return EmitterPoints(np.full(n, -1, np.int64), p, normal, w_inf, pdf, z, z)
        index, pmf = ls.choose(u_select, counters)
        lidx, kind, tri, world = self._kinds(index)
        lights = ls.lights
        delta = ls.delta[index]

        m = np.nonzero(kind == LIGHT_POINT)[0]
        if m.size:
            li = lidx[m]
            r = lights.radius[li]
            nrm = warps.sample_uniform_sphere(u[m])
            p[m] = lights.position[li] + nrm * r[:, None]
            normal[m] = np.where((r > 0)[:, None], nrm, 0.0)
            with np.errstate(divide="ignore"):
                pdf[m] = np.where(r > 0, pmf[m] / (4 * np.pi * r * r), pmf[m])

        m = np.nonzero((kind == LIGHT_RECT) | (kind == LIGHT_DISK))[0]
        if m.size:
            li = lidx[m]
            disk = kind[m] == LIGHT_DISK
            local = np.where(disk[:, None], 0.5 * warps.sample_uniform_disk_concentric(u[m]),
                             u[m] - 0.5)
            p[m] = (lights.position[li] + local[:, 0:1] * lights.axis_x[li]
                    + local[:, 1:2] * lights.axis_y[li])
            normal[m] = lights.direction[li]
            area = self._lamp_area(li, disk)
            pdf[m] = np.where(area > 0, pmf[m] / np.maximum(area, 1e-300), 0.0)

        m = np.nonzero(tri >= 0)[0]
        if m.size:
            e = tri[m]
            b = warps.sample_uniform_triangle(u[m])
            p[m] = ls.emit_v0[e] + b[:, 1:2] * ls.emit_e1[e] + b[:, 2:3] * ls.emit_e2[e]
            normal[m] = ls.emit_normal[e]
            pdf[m] = pmf[m] / ls.emit_area[e]

        m = np.nonzero(kind == LIGHT_SUN)[0]
        if m.size:
            li = lidx[m]
            axis = lights.direction[li]
            cos_max = np.cos(0.5 * lights.angle[li])
            s_, t_ = warps.frame_from_normal(axis)
            cone = warps.to_world(warps.sample_uniform_cone(u[m], cos_max), s_, t_, axis)
            is_d = lights.angle[li] <= 0
            w_inf[m] = np.where(is_d[:, None], axis, cone)
            pdf[m] = pmf[m] * np.where(is_d, 1.0, warps.uniform_cone_pdf(
                np.minimum(cos_max, 1 - 1e-12)))

        m = np.nonzero(world)[0]
        if m.size:
            if ls.world_dist is not None:
                d, _, sa_pdf = ls._sample_world_map(u[m])
            else:
                d = warps.sample_uniform_sphere(u[m])
                sa_pdf = warps.uniform_sphere_pdf(m.size)
            w_inf[m] = -d
            pdf[m] = sa_pdf * pmf[m]
        return EmitterPoints(index, p, normal, w_inf, pdf, delta, world | (kind == LIGHT_SUN))

    def _point_lobe(self, li):
        """Radius, spot cone cosine and whether it is a spot, of point lights ``li (m,)``:
        spheres (radius > 0) emit by cosine about their normal, points into the sphere or the
        spot's cone."""
        lights = self.ls.lights
        cos_half = lights.spot_cos_half[li]
        return lights.radius[li], cos_half, cos_half > -1.0

    def _lamp_area(self, li, disk):
        lights = self.ls.lights
        area = np.linalg.norm(np.cross(lights.axis_x[li], lights.axis_y[li]), axis=1)
        return np.where(disk, area * np.pi / 4, area)

    # ----------------------------------------------------------------------------- directions
    def sample_directions(self, pts: EmitterPoints, u):
        """Directions in which light leaves the sampled origins.

        Returns
        -------
        origin : (n, 3) float64
            Where the light ray starts: the point, or a point on the scene's disk for infinite
            emitters.
        w : (n, 3) float64
            Unit direction of travel.
        pdf_dir : (n,) float64
            Solid-angle density of ``w`` (finite), or the disk's area density (infinite).
        cos_l : (n,) float64
            ``|cos|`` between ``w`` and the emitting normal (one for points and infinite).
        le : (n, 3) float64
            Radiance (intensity for points) carried along ``w``.
        """
        ls = self.ls
        n = u.shape[0]
        origin = pts.p.copy()
        w = np.zeros((n, 3))
        w[:, 2] = 1.0
        pdf = np.zeros(n)
        cos_l = np.ones(n)
        lidx, kind, tri, world = self._kinds(pts.index)
        lights = ls.lights

        m = np.nonzero(kind == LIGHT_POINT)[0]
        if m.size:
            li = lidx[m]
            r, cos_half, spot = self._point_lobe(li)
            axis = np.where((r > 0)[:, None], pts.normal[m],
                            np.where(spot[:, None], lights.direction[li], [0.0, 0.0, 1.0]))
            s_, t_ = warps.frame_from_normal(axis)
            # Spheres: cosine about the outward normal; points: the sphere, or the spot's cone.
            cosine = warps.sample_cosine_hemisphere(u[m])
            cone = warps.sample_uniform_cone(u[m], np.where(spot, cos_half, -1.0))
            local = np.where((r > 0)[:, None], cosine, cone)
            w[m] = warps.to_world(local, s_, t_, axis)
            pdf[m] = np.where(r > 0, warps.cosine_hemisphere_pdf(cosine[:, 2]),
                              warps.uniform_cone_pdf(np.where(spot, cos_half, -1.0)))
            cos_l[m] = np.where(r > 0, cosine[:, 2], 1.0)

        m = np.nonzero((kind == LIGHT_RECT) | (kind == LIGHT_DISK) | (tri >= 0))[0]
        if m.size:
            nrm = pts.normal[m]
            uu = u[m].copy()
            # Triangles emit from both faces: pick one with the first number, then rescale it.
            two = tri[m] >= 0
            back = two & (uu[:, 0] >= 0.5)
            uu[:, 0] = np.where(two, np.where(back, 2 * uu[:, 0] - 1, 2 * uu[:, 0]), uu[:, 0])
            uu[:, 0] = np.minimum(uu[:, 0], 1 - 1e-16)
            nrm = np.where(back[:, None], -nrm, nrm)
            s_, t_ = warps.frame_from_normal(nrm)
            local = warps.sample_cosine_hemisphere(uu)
            w[m] = warps.to_world(local, s_, t_, nrm)
            pdf[m] = warps.cosine_hemisphere_pdf(local[:, 2]) * np.where(two, 0.5, 1.0)
            cos_l[m] = local[:, 2]

        m = np.nonzero(pts.infinite)[0]
        if m.size:
            w[m] = pts.w_inf[m]
            s_, t_ = warps.frame_from_normal(w[m])
            d = warps.sample_uniform_disk_concentric(u[m]) * self.radius
            origin[m] = (self.center + d[:, 0:1] * s_ + d[:, 1:2] * t_
                         - w[m] * self.radius)
            pdf[m] = self.disk_pdf
        le = self.radiance(pts.index, origin, pts.normal, w, None)
        ok = pdf > 0
        return origin, w, np.where(ok, pdf, 0.0), cos_l, np.where(ok[:, None], le, 0.0)

    # ----------------------------------------------------------------------------- evaluation
    def radiance(self, index, p, normal, w, receiver):
        """Radiance (intensity for points) leaving emitter points ``p (n, 3)`` along ``w``.

        Parameters
        ----------
        index : (n,) int
        p, normal : (n, 3) float64
            Emitter points and their emitting normals (as :class:`EmitterPoints`).
        w : (n, 3) float64
            Unit direction of travel (for infinite emitters: the direction light travels).
        receiver : (n, 3) float64 or None
            Where the light arrives. Sphere lights light points outside them from their outer
            face and points inside from their inner face (as next-event estimation does); with
            ``None`` only the outer face emits (light paths).
        """
        ls = self.ls
        n = w.shape[0]
        out = np.zeros((n, 3))
        lidx, kind, tri, world = self._kinds(index)
        lights = ls.lights
        cos = _dot(w, normal)

        m = np.nonzero(kind == LIGHT_POINT)[0]
        if m.size:
            li = lidx[m]
            r = lights.radius[li]
            att = spot_attenuation(lights, li, w[m])
            face = cos[m] > 0
            if receiver is not None:
                inside = np.linalg.norm(receiver[m] - lights.position[li], axis=1) < r
                face = np.where(inside, cos[m] < 0, face)
            ok = (r <= 0) | face
            out[m] = lights.radiance[li] * (att * ok)[:, None]

        m = np.nonzero((kind == LIGHT_RECT) | (kind == LIGHT_DISK))[0]
        if m.size:
            out[m] = lights.radiance[lidx[m]] * (cos[m] > 0)[:, None]

        m = np.nonzero(tri >= 0)[0]
        if m.size:
            out[m] = ls.emit_radiance[tri[m]] * (cos[m] != 0)[:, None]

        m = np.nonzero(kind == LIGHT_SUN)[0]
        if m.size:
            li = lidx[m]
            cos_max = np.cos(0.5 * lights.angle[li])
            inside = (lights.angle[li] <= 0) | (_dot(w[m], lights.direction[li]) > cos_max)
            out[m] = lights.radiance[li] * inside[:, None]

        m = np.nonzero(world)[0]
        if m.size:
            out[m] = ls.world_radiance(-w[m])[0]
        return out

    def pdf_origin(self, index, w):
        """``pdf_origin`` (as :meth:`sample_points`) of emitter points found by rays.

        ``w (n, 3)`` is the direction light travels (used by infinite emitters only).
        Finite emitters give their selection probability over their area.
        """
        ls = self.ls
        n = index.shape[0]
        out = np.zeros(n)
        lidx, kind, tri, world = self._kinds(index)
        lights = ls.lights
        sel = np.where(index >= 0, ls.select_prob[np.maximum(index, 0)] if ls.n_emitters else 0.0,
                       0.0)
        m = np.nonzero(kind == LIGHT_POINT)[0]
        if m.size:
            r = lights.radius[lidx[m]]
            with np.errstate(divide="ignore"):
                out[m] = np.where(r > 0, sel[m] / (4 * np.pi * r * r), sel[m])
        m = np.nonzero((kind == LIGHT_RECT) | (kind == LIGHT_DISK))[0]
        if m.size:
            area = self._lamp_area(lidx[m], kind[m] == LIGHT_DISK)
            out[m] = np.where(area > 0, sel[m] / np.maximum(area, 1e-300), 0.0)
        m = np.nonzero(tri >= 0)[0]
        if m.size:
            out[m] = sel[m] / ls.emit_area[tri[m]]
        m = np.nonzero(kind == LIGHT_SUN)[0]
        if m.size:
            li = lidx[m]
            cos_max = np.cos(0.5 * lights.angle[li])
            inside = _dot(w[m], lights.direction[li]) > cos_max
            out[m] = np.where(lights.angle[li] <= 0, sel[m], np.where(
                inside, sel[m] * warps.uniform_cone_pdf(np.minimum(cos_max, 1 - 1e-12)), 0.0))
        m = np.nonzero(world)[0]
        if m.size:
            out[m] = ls.world_pdf(-w[m])
        return out

    def pdf_direction(self, index, normal, w):
        """``pdf_dir`` (as :meth:`sample_directions`) of direction ``w`` leaving the emitter
        points with emitting ``normal``; the disk density for infinite emitters."""
        n = index.shape[0]
        out = np.zeros(n)
        lidx, kind, tri, world = self._kinds(index)
        lights = self.ls.lights
        cos = _dot(w, normal)
        m = np.nonzero(kind == LIGHT_POINT)[0]
        if m.size:
            li = lidx[m]
            r, cos_half, spot = self._point_lobe(li)
            in_cone = ~spot | (_dot(w[m], lights.direction[li]) > cos_half)
            cone_pdf = warps.uniform_cone_pdf(np.where(spot, cos_half, -1.0)) * in_cone
            out[m] = np.where(r > 0, np.maximum(cos[m], 0.0) / np.pi, cone_pdf)
        m = np.nonzero((kind == LIGHT_RECT) | (kind == LIGHT_DISK))[0]
        if m.size:
            out[m] = np.maximum(cos[m], 0.0) / np.pi
        m = np.nonzero(tri >= 0)[0]
        if m.size:
            out[m] = 0.5 * np.abs(cos[m]) / np.pi
        m = np.nonzero(world | (kind == LIGHT_SUN))[0]
        out[m] = self.disk_pdf
        return out
