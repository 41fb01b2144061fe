"""Point and spot lights: delta points of radius 0, spheres of radius r > 0, and Soft Falloff
disks.

A point of radius 0 radiates intensity S / (4 pi) W/sr (a spot times its smoothstep cone
falloff, not renormalised). With a radius, the lamp is a sphere of radiance S / (4 pi^2 r^2)
that also lights points inside it; with Soft Falloff (Blender's default) it is instead a disk of
the same radius and radiance facing each receiving point, as Cycles does.

Next-event estimation samples a sphere by the cone it subtends (uniformly over all directions
from inside it) and a Soft Falloff disk by area. Light paths leave a sphere by a cosine about its
outward normal, a point uniformly over the sphere of directions or the spot's cone (Soft Falloff
lamps are spheres on light paths, an approximation the render reports).
"""

from __future__ import annotations

import numpy as np

from ..sampling import warps
from ..scene import LIGHT_POINT, Lights
from .base import LUMINANCE, LightFamily, dot, length_and_direction, light_row, unit
from .shapes import ray_facing_disk, ray_sphere, sphere_roots
from ..quiet import quiet


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
        direction = unit(spot_direction)
    return light_row(LIGHT_POINT, name, visible_camera, position=position, direction=direction,
                     radius=radius, radiance=radiance, spot_cos_half=cos_half,
                     spot_smooth=smooth, power=float(LUMINANCE @ s),
                     soft_falloff=soft_falloff and radius > 0)


def spot_attenuation(lights: Lights, index, w_out):
    """Cycles' smoothstep cone falloff for the lights ``index (n,)`` toward ``w_out (n, 3)``.

    ``w_out`` is the unit direction light travels, from the lamp to the receiver. Point lights
    (``spot_cos_half == -1``) give one.
    """
    cos_half = lights.spot_cos_half[index]
    smooth = lights.spot_smooth[index]
    cos = np.einsum("ij,ij->i", w_out, lights.direction[index])
    with quiet("invalid", "over"):
        x = np.where(np.isinf(smooth), np.where(cos > cos_half, 1.0, 0.0),
                     (cos - cos_half) * np.where(np.isinf(smooth), 0.0, smooth))
    x = np.clip(x, 0.0, 1.0)
    att = x * x * (3.0 - 2.0 * x)
    return np.where(cos_half <= -1.0, 1.0, att)


class PointLights(LightFamily):
    """The point, spot and sphere lamps of a :class:`~.sampler.LightSampler` (see
    :class:`~.base.LightFamily` for the contract)."""

    def is_delta(self, li):
        """Points of radius 0."""
        return self.lights.radius[li] <= 0

    # ------------------------------------------------------------------ next-event estimation
    def sample_li(self, m, li, p, u, pmf, out, counters=None):
        """Delta points; spheres by their cone of directions (or uniformly from inside);
        soft-falloff disks facing the receiver by area."""
        lights = self.lights
        c = lights.position[li]
        r = lights.radius[li]
        to_c = c - p[m]
        d_c, axis = length_and_direction(to_c)
        point = r <= 0
        soft = lights.soft_falloff[li] & ~point
        sphere = ~point & ~soft
        inside = sphere & (d_c <= r)
        s_, t_ = warps.frame_from_normal(axis)
        uu = u[m]
        cc = d_c * d_c - r * r
        # Sphere seen from outside: the cone it subtends, up to its near side.
        sin2 = np.clip((r / np.maximum(d_c, 1e-300)) ** 2, 0.0, 1.0)
        cos_max = np.minimum(np.sqrt(1.0 - sin2), 1 - 1e-12)
        w_cone = warps.to_world(warps.sample_uniform_cone(uu, cos_max), s_, t_, axis)
        t_cone = sphere_roots(dot(w_cone, to_c), cc)[1]
        # Sphere seen from inside: every direction meets its inner surface.
        w_in = warps.sample_uniform_sphere(uu)
        t_in = sphere_roots(dot(w_in, to_c), cc)[2]
        # Soft falloff: a uniform point on the disk of radius r facing the receiver.
        disk = warps.sample_uniform_disk_concentric(uu) * r[:, None]
        q = c + disk[:, 0:1] * s_ + disk[:, 1:2] * t_
        t_disk, w_disk = length_and_direction(q - p[m])
        cos_disk = dot(w_disk, axis)
        with quiet("divide", "invalid"):
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
        out.wi[m] = w
        out.dist[m] = t_hit
        out.radiance[m] = np.where(ok[:, None], lum, 0.0)
        out.pdf[m] = np.where(ok, sa_pdf * pmf[m], 0.0)
        # Lamps are not geometry, so shadow rays need no offset at their end.
        out.light_normal[m] = 0.0

    # ------------------------------------------------------------------ rays that find the lamp
    def intersect(self, li, o, d, tmax, pmf):
        """Rays ``(rows, radiance, pdf_li)`` that see lamp ``li`` (a sphere, or the Soft
        Falloff disk facing their origin, as next-event estimation sampled it from there), or
        None."""
        lights = self.lights
        r = lights.radius[li]
        if lights.soft_falloff[li]:
            rows, t, denom = ray_facing_disk(o, d, lights.position[li], r, tmax)
            if rows.size == 0:
                return None
            pdf = pmf * t[rows] ** 2 / (np.pi * r * r * -denom[rows])
        else:
            rows, t, outside, to_c = ray_sphere(o, d, lights.position[li], r, tmax)
            if rows.size == 0:
                return None
            dc2 = dot(to_c[rows], to_c[rows])
            cos_max = np.sqrt(np.maximum(0.0, 1.0 - r * r / dc2))
            pdf = pmf * np.where(outside[rows],
                                 warps.uniform_cone_pdf(np.minimum(cos_max, 1 - 1e-12)),
                                 warps.uniform_sphere_pdf(rows.size))
        att = spot_attenuation(lights, np.full(rows.size, li), -d[rows])
        return rows, lights.radiance[li] * att[:, None], pdf

    def surface_points(self, li, o, d, tmax):
        """Light-path view of rays meeting sphere ``li`` (Soft Falloff lamps are spheres on
        light paths): ``(rows, point, outward normal, distance)`` or None."""
        c, r = self.lights.position[li], self.lights.radius[li]
        rows, t, _, _ = ray_sphere(o, d, c, r, tmax)
        if rows.size == 0:
            return None
        q = o[rows] + d[rows] * t[rows, None]
        return rows, q, (q - c) / r, t[rows]

    # ------------------------------------------------------------------ light paths
    def sample_le_origin(self, m, li, u, pmf, out):
        """Uniform on the sphere (the point itself for radius 0, a delta origin)."""
        lights = self.lights
        r = lights.radius[li]
        nrm = warps.sample_uniform_sphere(u[m])
        out.p[m] = lights.position[li] + nrm * r[:, None]
        out.normal[m] = np.where((r > 0)[:, None], nrm, 0.0)
        with quiet("divide"):
            out.pdf[m] = np.where(r > 0, pmf[m] / (4 * np.pi * r * r), pmf[m])

    def _lobe(self, li):
        """Radius, spot cone cosine and whether it is a spot, of lamps ``li (m,)``: spheres
        (radius > 0) emit by cosine about their normal, points into the sphere or the spot's
        cone."""
        cos_half = self.lights.spot_cos_half[li]
        return self.lights.radius[li], cos_half, cos_half > -1.0

    def sample_le_direction(self, m, li, pts, u, out):
        lights = self.lights
        r, cos_half, spot = self._lobe(li)
        axis = np.where((r > 0)[:, None], pts.normal[m],
                        np.where(spot[:, None], lights.direction[li], [0.0, 0.0, 1.0]))
        s_, t_ = warps.frame_from_normal(axis)
        # Spheres: cosine about the outward normal; points: the sphere, or the spot's cone.
        cosine = warps.sample_cosine_hemisphere(u[m])
        cone = warps.sample_uniform_cone(u[m], np.where(spot, cos_half, -1.0))
        local = np.where((r > 0)[:, None], cosine, cone)
        out.w[m] = warps.to_world(local, s_, t_, axis)
        out.pdf[m] = np.where(r > 0, warps.cosine_hemisphere_pdf(cosine[:, 2]),
                              warps.uniform_cone_pdf(np.where(spot, cos_half, -1.0)))
        out.cos_l[m] = np.where(r > 0, cosine[:, 2], 1.0)

    def le(self, m, li, cos, w, receiver, out):
        """Intensity (radius 0) or radiance along ``w``: spheres light points outside them from
        their outer face and points inside from their inner face; with ``receiver`` None only
        the outer face emits (light paths)."""
        lights = self.lights
        r = lights.radius[li]
        att = spot_attenuation(lights, li, w[m])
        face = cos[m] > 0
        if receiver is not None:
            inside = np.linalg.norm(receiver[m] - lights.position[li], axis=1) < r
            face = np.where(inside, cos[m] < 0, face)
        ok = (r <= 0) | face
        out[m] = lights.radiance[li] * (att * ok)[:, None]

    def pdf_le_origin(self, m, li, sel, w, out):
        r = self.lights.radius[li]
        with quiet("divide"):
            out[m] = np.where(r > 0, sel[m] / (4 * np.pi * r * r), sel[m])

    def pdf_le_direction(self, m, li, cos, w, out):
        r, cos_half, spot = self._lobe(li)
        in_cone = ~spot | (dot(w[m], self.lights.direction[li]) > cos_half)
        cone_pdf = warps.uniform_cone_pdf(np.where(spot, cos_half, -1.0)) * in_cone
        out[m] = np.where(r > 0, np.maximum(cos[m], 0.0) / np.pi, cone_pdf)
