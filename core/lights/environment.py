"""The world: a constant background or an equirectangular environment map, one emitter.

The Background's Color x Strength is radiance. A constant world is sampled uniformly on the
sphere; an environment map (:attr:`core.scene.Scene.world_map`) is importance-sampled by a
:class:`~core.sampling.distributions.PiecewiseConstant2D` over its luminance x sin(theta)
(:func:`environment_importance`), with the solid-angle pdf ``pdf_uv / (2 pi^2 sin theta)``.
Light paths from the world enter the scene through a disk of its bounding sphere (see
:class:`~.emission.Emission`).
"""

from __future__ import annotations

import time

import numpy as np

from ..sampling import warps
from ..sampling.distributions import PiecewiseConstant2D
from .base import LUMINANCE, LightFamily
from ..quiet import quiet


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


class World(LightFamily):
    """The world emitter of a :class:`~.sampler.LightSampler` (see :class:`~.base.LightFamily`).

    Attributes
    ----------
    color : (3,) float64
        The constant world's radiance.
    world_map : (h, w, 3) float32 or None
        The scene's environment map (non-finite and negative texels set to 0), or None for a
        constant (or black) world.
    dist : core.sampling.distributions.PiecewiseConstant2D or None
        Over :func:`environment_importance` of ``world_map``; u along columns, v along rows.
    emits : bool
        Whether the world is an emitter at all (a black world or map is not).
    build_s : float
        Seconds spent building ``dist``.
    """

    infinite = True

    def __init__(self, sampler, scene, method):
        super().__init__(sampler)
        self.color = np.asarray(scene.world_color, np.float64)
        self.world_map = None
        self.dist = None
        self.build_s = 0.0
        world_map = getattr(scene, "world_map", None)
        if world_map is None:
            self.emits = bool(self.color.max() > 0)
            return
        world_map = np.asarray(world_map, np.float32)
        # No NaN reaches the film, and negative radiance is not light.
        world_map = np.where(np.isfinite(world_map), np.maximum(world_map, 0.0),
                             0.0).astype(np.float32)
        importance = environment_importance(world_map)
        # A black map is no emitter: no environment sampling for a black world.
        self.emits = bool(importance.max() > 0)
        if self.emits:
            self.world_map = world_map
            t0 = time.perf_counter()
            self.dist = PiecewiseConstant2D(importance, method)
            self.build_s = time.perf_counter() - t0

    def power(self, radius):
        """Estimated power through a scene of bounding ``radius``, for light selection."""
        if self.dist is not None:
            # Mean luminance over the sphere: (1 / 4 pi) sum f 2 pi^2 / (h w) = pi / 2 mean(f).
            world_lum = 0.5 * np.pi * self.dist.integral
        else:
            world_lum = float(LUMINANCE @ self.color)
        return 4 * np.pi**2 * radius**2 * world_lum

    def sample_map(self, u):
        """Directions ``(k, 3)``, radiance ``(k, 3)`` and solid-angle pdf ``(k,)`` (selection
        excluded) drawn from the environment map's distribution with ``u (k, 2)``.

        The pdf is ``pdf_uv / (2 pi^2 sin theta)`` (d omega = 2 pi^2 sin theta du dv); a
        direction exactly at a pole (sin theta = 0) is a failed sample (pdf 0, no radiance).
        """
        uv, pdf_uv = self.dist.sample_continuous(u)
        w, sin_t = equirect_direction(uv)
        ok = sin_t > 0
        with quiet("divide", "invalid"):
            sa_pdf = np.where(ok, pdf_uv / (2 * np.pi**2 * sin_t), 0.0)
        ok &= np.isfinite(sa_pdf) & (sa_pdf > 0)
        le = np.where(ok[:, None], environment_lookup(self.world_map, uv), 0.0)
        return w, le, np.where(ok, sa_pdf, 0.0)

    def sample_li(self, m, li, p, u, pmf, out, counters=None):
        """An environment map by its importance, a constant world uniformly."""
        if self.dist is not None:
            t0 = time.perf_counter()
            w, le, sa_pdf = self.sample_map(u[m])
            if counters is not None:
                # The map's row and column draws count as the distributions' work.
                counters.distribution_s += time.perf_counter() - t0
                counters.distribution_samples += 2 * m.size
            out.wi[m] = w
            out.radiance[m] = le
            out.pdf[m] = sa_pdf * pmf[m]
        else:
            out.wi[m] = warps.sample_uniform_sphere(u[m])
            out.radiance[m] = self.color
            out.pdf[m] = warps.uniform_sphere_pdf(m.size) * pmf[m]

    def pdf_li(self, d):
        """Solid-angle density ``(n,)`` of NEE choosing the world and then direction ``d (n, 3)``
        (selection included); zero without a world."""
        n = d.shape[0]
        if not self.emits:
            return np.zeros(n)
        sel = self.sampler.world_select_prob
        if self.dist is None:
            return sel * warps.uniform_sphere_pdf(n)
        d = np.asarray(d, np.float64)
        sin_t = np.hypot(d[:, 0], d[:, 1]) / np.maximum(np.linalg.norm(d, axis=1), 1e-300)
        pdf_uv = self.dist.pdf(equirect_uv(d))
        with quiet("divide", "invalid"):
            pdf = np.where(sin_t > 0, sel * pdf_uv / (2 * np.pi**2 * sin_t), 0.0)
        return np.where(np.isfinite(pdf), pdf, 0.0)

    def radiance(self, d):
        """Radiance ``(n, 3)`` arriving from directions ``d (n, 3)`` (zero without a world)."""
        n = d.shape[0]
        if not self.emits:
            return np.zeros((n, 3))
        if self.dist is None:
            return np.broadcast_to(self.color, (n, 3)).copy()
        return environment_lookup(self.world_map, equirect_uv(d))

    # ------------------------------------------------------------------ light paths
    def sample_le_origin(self, m, li, u, pmf, out):
        """The direction light travels, by the density next-event estimation uses."""
        if self.dist is not None:
            d, _, sa_pdf = self.sample_map(u[m])
        else:
            d = warps.sample_uniform_sphere(u[m])
            sa_pdf = warps.uniform_sphere_pdf(m.size)
        out.w_inf[m] = -d
        out.pdf[m] = sa_pdf * pmf[m]

    def le(self, m, li, cos, w, receiver, out):
        out[m] = self.radiance(-w[m])

    def pdf_le_origin(self, m, li, sel, w, out):
        out[m] = self.pdf_li(-w[m])
