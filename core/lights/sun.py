"""Sun lights: light from one direction, or from a disk of angular diameter ``angle``.

Blender's Strength S is the irradiance in W/m^2 on a surface facing the sun; a disk of angle
a > 0 has radiance S / (pi sin^2(a / 2)). Next-event estimation samples the cone of the disk
uniformly; rays that escape the scene inside the cone see it. Light paths enter the scene along
the sampled direction through a disk of the scene's bounding sphere (see
:class:`~.emission.Emission`), so suns are *infinite* emitters.
"""

from __future__ import annotations

import numpy as np

from ..sampling import warps
from ..scene import LIGHT_SUN, Lights
from .base import LUMINANCE, LightFamily, dot, light_row, unit


def sun_light(direction, color, strength, angle=0.0, name="Sun", visible_camera=True) -> Lights:
    """A Blender sun: ``direction`` is where the light travels (the object's local -Z).

    ``strength`` is the irradiance in W/m^2 on a surface facing the sun; ``angle`` the angular
    diameter in radians. The power used for light selection is filled in by
    :class:`~.sampler.LightSampler` from the scene's size.
    """
    s = np.asarray(color, np.float64) * float(strength)
    angle = max(float(angle), 0.0)
    radiance = s / (np.pi * np.sin(0.5 * angle) ** 2) if angle > 0 else s
    return light_row(LIGHT_SUN, name, visible_camera, direction=unit(direction), angle=angle,
                     radiance=radiance, power=float(LUMINANCE @ s))


def _cone_pdf(cos_max):
    """Uniform density on a cone of directions, kept finite for a degenerate cone."""
    return warps.uniform_cone_pdf(np.minimum(cos_max, 1 - 1e-12))


class SunLights(LightFamily):
    """The suns of a :class:`~.sampler.LightSampler` (see :class:`~.base.LightFamily`)."""

    infinite = True

    def is_delta(self, li):
        """Suns of angle 0."""
        return self.lights.angle[li] <= 0

    def lamp_power(self, li, radius):
        """Irradiance times the cross-section of the scene's bounding sphere."""
        return self.lights.power[li] * (np.pi * radius**2)

    def _cone(self, li, axis, u):
        """Directions about ``axis`` (the sun's direction, or its reverse) by ``u``: the axis
        for angle 0, else uniform in the disk's cone; and the pdf of each."""
        ang = self.lights.angle[li]
        cos_max = np.cos(0.5 * ang)
        s_, t_ = warps.frame_from_normal(axis)
        cone = warps.to_world(warps.sample_uniform_cone(u, cos_max), s_, t_, axis)
        is_d = ang <= 0
        return np.where(is_d[:, None], axis, cone), np.where(is_d, 1.0, _cone_pdf(cos_max))

    def sample_li(self, m, li, p, u, pmf, out, counters=None):
        """A direction, or a cone of directions toward the disk."""
        out.wi[m], pdf = self._cone(li, -self.lights.direction[li], u[m])
        out.radiance[m] = self.lights.radiance[li]
        out.pdf[m] = pdf * pmf[m]

    def intersect(self, li, o, d, tmax, pmf):
        """Escaping rays ``(rows, radiance, pdf_li)`` inside the disk of sun ``li``, or None."""
        lights = self.lights
        cos_max = np.cos(0.5 * lights.angle[li])
        rows = np.nonzero(np.isinf(tmax) & (dot(d, -lights.direction[li][None]) > cos_max))[0]
        if rows.size == 0:
            return None
        pdf = np.full(rows.size, pmf * warps.uniform_cone_pdf(min(cos_max, 1 - 1e-12)))
        return rows, np.broadcast_to(lights.radiance[li], (rows.size, 3)), pdf

    def surface_points(self, li, o, d, tmax):
        """Suns have no surface (camera paths find them by escaping: see
        :meth:`~.sampler.LightSampler.infinite_lamps`)."""
        return None

    # ------------------------------------------------------------------ light paths
    def sample_le_origin(self, m, li, u, pmf, out):
        """The direction light travels (the origin is chosen with it, on the scene's disk)."""
        out.w_inf[m], pdf = self._cone(li, self.lights.direction[li], u[m])
        out.pdf[m] = pmf[m] * pdf

    def le(self, m, li, cos, w, receiver, out):
        lights = self.lights
        cos_max = np.cos(0.5 * lights.angle[li])
        inside = (lights.angle[li] <= 0) | (dot(w[m], lights.direction[li]) > cos_max)
        out[m] = lights.radiance[li] * inside[:, None]

    def pdf_le_origin(self, m, li, sel, w, out):
        lights = self.lights
        cos_max = np.cos(0.5 * lights.angle[li])
        inside = dot(w[m], lights.direction[li]) > cos_max
        out[m] = np.where(lights.angle[li] <= 0, sel[m], np.where(
            inside, sel[m] * _cone_pdf(cos_max), 0.0))
