"""Emission for light paths: a point and a direction on every kind of emitter.

Light tracing and BDPT start paths at the lights. :class:`Emission` chooses emitters with the
selection of a :class:`~.sampler.LightSampler` (same probabilities as next-event estimation) and
asks each light family how a light path leaves it:

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

from ..sampling import warps
from .base import LeDirections, LeOrigins, dot


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
    """How light paths leave the emitters of a :class:`~.sampler.LightSampler`; built once per
    render by :func:`core.prepare.prepare`.

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
            pts.append(lights.lights.position[~lights.is_infinite(np.arange(lights.n_lights))])
        pts = np.concatenate(pts)
        if pts.size:
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            self.center = 0.5 * (lo + hi)
            self.radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3) * 1.01
        else:
            self.center, self.radius = np.zeros(3), 1.0
        self.disk_pdf = 1.0 / (np.pi * self.radius**2)

    def is_infinite(self, index):
        """Whether emitter rows ``index (n,)`` are the world or suns."""
        return self.ls.is_infinite(index)

    def sample_points(self, u_select, u, counters=None) -> EmitterPoints:
        """Choose emitters (as next-event estimation does) and a point or direction on each.

        Parameters
        ----------
        u_select : (n,) float
        u : (n, 2) float
        """
        ls = self.ls
        n = u.shape[0]
        out = LeOrigins.empty(n)
        if ls.light_dist is None or n == 0:
            z = np.zeros(n, bool)
            return EmitterPoints(np.full(n, -1, np.int64), out.p, out.normal, out.w_inf,
                                 out.pdf, z, z)
        index, pmf = ls.choose(u_select, counters)
        for family, m, local in ls.families_of(index):
            family.sample_le_origin(m, local, u, pmf, out)
        return EmitterPoints(index, out.p, out.normal, out.w_inf, out.pdf, ls.delta[index],
                             ls.is_infinite(index))

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
        n = u.shape[0]
        w = np.zeros((n, 3))
        w[:, 2] = 1.0
        out = LeDirections(pts.p.copy(), w, np.zeros(n), np.ones(n))
        for family, m, local in self.ls.families_of(pts.index):
            if not family.infinite:
                family.sample_le_direction(m, local, pts, u, out)
        # Infinite emitters: light enters through the scene's disk facing the direction.
        m = np.nonzero(pts.infinite)[0]
        if m.size:
            out.w[m] = pts.w_inf[m]
            s_, t_ = warps.frame_from_normal(out.w[m])
            d = warps.sample_uniform_disk_concentric(u[m]) * self.radius
            out.origin[m] = (self.center + d[:, 0:1] * s_ + d[:, 1:2] * t_
                             - out.w[m] * self.radius)
            out.pdf[m] = self.disk_pdf
        le = self.radiance(pts.index, out.origin, pts.normal, out.w, None)
        ok = out.pdf > 0
        if ok.all():  # the usual batch: the selections below would keep every value
            return out.origin, out.w, out.pdf, out.cos_l, le
        return (out.origin, out.w, np.where(ok, out.pdf, 0.0), out.cos_l,
                np.where(ok[:, None], le, 0.0))

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
        out = np.zeros((w.shape[0], 3))
        cos = dot(w, normal)
        for family, m, local in self.ls.families_of(index):
            family.le(m, local, cos, w, receiver, out)
        return out

    def pdf_origin(self, index, w):
        """``pdf_origin`` (as :meth:`sample_points`) of emitter points found by rays.

        ``w (n, 3)`` is the direction light travels (used by infinite emitters only).
        Finite emitters give their selection probability over their area.
        """
        ls = self.ls
        out = np.zeros(index.shape[0])
        sel = np.where(index >= 0, ls.select_prob[np.maximum(index, 0)] if ls.n_emitters else 0.0,
                       0.0)
        for family, m, local in ls.families_of(index):
            family.pdf_le_origin(m, local, sel, w, out)
        return out

    def pdf_direction(self, index, normal, w):
        """``pdf_dir`` (as :meth:`sample_directions`) of direction ``w`` leaving the emitter
        points with emitting ``normal``; the disk density for infinite emitters."""
        out = np.zeros(index.shape[0])
        cos = dot(w, normal)
        for family, m, local in self.ls.families_of(index):
            if not family.infinite:
                family.pdf_le_direction(m, local, cos, w, out)
        out[np.nonzero(self.ls.is_infinite(index))[0]] = self.disk_pdf
        return out
