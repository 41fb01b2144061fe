"""Area lights: squares and rectangles (parallelograms when the object is sheared), disks and
ellipses.

Radiance S / (pi A), emitted from one side toward the light's local -Z (``direction``); for a
disk or ellipse A is the bounding square's area times pi / 4. Next-event estimation samples a
point uniformly by area, or (``light_sampling='solid_angle'``) a rectangle uniformly by the solid
angle it subtends (spherical rectangles, Urena et al. 2013) where that warp is well conditioned.
Light paths leave a uniform point by a cosine about the emitting side.
"""

from __future__ import annotations

import numpy as np

from ..sampling import warps
from ..scene import LIGHT_DISK, LIGHT_RECT, Lights
from .base import LUMINANCE, LightFamily, batch_rows, dot, light_row, set_batch_rows, unit
from .shapes import ray_parallelogram
from ..quiet import quiet


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
    # A light of zero area emits nothing (its radiance would be infinite): zero power keeps
    # light selection from choosing it.
    radiance = s / (np.pi * area) if area > 0 else np.zeros(3)
    return light_row(kind, name, visible_camera, position=m[:3, 3], axis_x=axis_x,
                     axis_y=axis_y, direction=-unit(normal), radiance=radiance,
                     power=float(LUMINANCE @ s) if area > 0 else 0.0)


def area_point_pdf(m, p, q, normal, area, emitted, pmf, one_sided, out):
    """Fill rows ``m`` of ``out`` (:class:`~.base.LiSamples`) for points ``q (k, 3)`` sampled
    uniformly by area on emitters of ``area (k,)`` and unit ``normal (k, 3)``, seen from
    ``p[m]``: the solid-angle pdf ``d^2 / (cos A)`` times the selection ``pmf[m]``."""
    d = q - batch_rows(p, m)
    d2 = dot(d, d)
    r = np.sqrt(d2)
    w = d / np.maximum(r, 1e-300)[:, None]
    cos_l = -dot(w, normal)
    if not one_sided:
        cos_l = np.abs(cos_l)
    ok = (cos_l > 1e-12) & (area > 0) & (r > 0)
    with quiet("divide", "invalid"):
        sa = np.where(ok, d2 / (cos_l * area), 0.0)
    out.put("wi", m, w)
    out.put("dist", m, r)
    out.put("radiance", m, emitted if ok.all() else np.where(ok[:, None], emitted, 0.0))
    out.put("pdf", m, sa * batch_rows(pmf, m))
    out.put("light_normal", m, normal)


def solid_angle_pdf(m, sph, omega, pmf, pdf):
    """Replace the area pdf of the rows ``m[sph]`` sampled by solid angle with pmf / omega."""
    if sph.size and sph.all():
        # Every row by solid angle (no mask gathers; m as in base.batch_rows).
        area_pdf = batch_rows(pdf, m)
        set_batch_rows(pdf, m, np.where(area_pdf > 0, batch_rows(pmf, m) / omega, 0.0))
    elif sph.any():
        rows = m[sph]
        pdf[rows] = np.where(pdf[rows] > 0, pmf[rows] / omega[sph], 0.0)


class AreaLights(LightFamily):
    """The rectangle, disk and ellipse lamps of a :class:`~.sampler.LightSampler` (see
    :class:`~.base.LightFamily` for the contract).

    Attributes
    ----------
    rect_spherical : (k,) bool
        Per light row: a rectangle (not sheared, not degenerate) that solid-angle sampling may
        sample as a spherical rectangle.
    """

    def __init__(self, sampler):
        super().__init__(sampler)
        lights = self.lights
        # Sheared rectangles are parallelograms: the spherical-rectangle warp does not apply.
        ax, ay = lights.axis_x, lights.axis_y
        cross = np.linalg.norm(ax, axis=1) * np.linalg.norm(ay, axis=1)
        self.rect_spherical = (lights.kind == LIGHT_RECT) & (
            np.abs(dot(ax, ay)) <= 1e-6 * cross) & (cross > 0)
        # Per-lamp tables, so that a batch gathers (or broadcasts) rows instead of recomputing.
        area = np.linalg.norm(np.cross(ax, ay), axis=1)
        self.area = np.where(lights.kind == LIGHT_DISK, area * np.pi / 4, area)
        self.any_disk = bool((lights.kind == LIGHT_DISK).any())
        self.any_spherical = bool(self.rect_spherical.any()) and sampler.solid_angle
        is_area = (lights.kind == LIGHT_RECT) | (lights.kind == LIGHT_DISK)
        # The one area lamp of the scene (then every row of a batch chose it), or None.
        self.only = int(is_area.nonzero()[0][0]) if is_area.sum() == 1 else None
        # Per lamp, the tangents warps.frame_from_normal makes around its emitting normal:
        # light paths gather them instead of building a frame per sample (the same values:
        # the frame is a function of the row; lamps that are not area lights get unused rows).
        with quiet("divide", "invalid"):
            self.le_s, self.le_t = warps.frame_from_normal(lights.direction)

    def _points(self, li, u):
        """Uniform points ``(m, 3)`` on lights ``li`` by ``u (m, 2)``, their areas ``(m,)`` and
        which are disks."""
        lights = self.lights
        if self.any_disk:
            disk = lights.kind[li] == LIGHT_DISK
            local = np.where(disk[:, None], 0.5 * warps.sample_uniform_disk_concentric(u),
                             u - 0.5)
        else:
            disk, local = np.zeros(li.shape[0], bool), u - 0.5
        if self.only is None:
            q = (lights.position.take(li, axis=0)
                 + local[:, 0:1] * lights.axis_x.take(li, axis=0)
                 + local[:, 1:2] * lights.axis_y.take(li, axis=0))
            return q, self._area(li), disk
        # One lamp: the same sums axis by axis, with its numbers instead of broadcast rows.
        pos, ax, ay = (table[self.only] for table in (lights.position, lights.axis_x,
                                                      lights.axis_y))
        q = np.empty((li.shape[0], 3))
        for c in range(3):
            column = q[:, c]
            np.multiply(local[:, 0], ax[c], out=column)
            column += pos[c]
            column += local[:, 1] * ay[c]
        return q, self._area(li), disk

    def _area(self, li):
        """Areas ``(m,)`` of lights ``li`` (a disk's or ellipse's is pi / 4 of its square's)."""
        return self.area.take(li)

    def _rows(self, table, li):
        """``table[li]`` for a per-lamp table ``(k, ...)``: one row broadcast (read-only, no
        copy) when the scene has a single area lamp, so every ``li`` is that lamp."""
        if self.only is not None:
            return np.broadcast_to(table[self.only], (li.shape[0],) + table.shape[1:])
        return table.take(li, axis=0)

    def use_spherical(self, li, p):
        """Solid angles ``(n,)`` of lights ``li`` from ``p (n, 3)``, their corners ``(n, 3)``,
        and where the spherical-rectangle warp is used ``(n,)`` bool."""
        lights = self.lights
        if not self.any_spherical:
            # No rectangle is sampled by solid angle: nothing below would be used.
            n = p.shape[0]
            return np.zeros(n), None, np.zeros(n, bool)
        corner = lights.position[li] - 0.5 * (lights.axis_x[li] + lights.axis_y[li])
        # Only rectangles sampled by solid angle need it; the rest skip the arithmetic.
        use = self.rect_spherical[li] & self.sampler.solid_angle
        omega = np.zeros(p.shape[0])
        rows = use.nonzero()[0]
        if rows.size:
            lr = li[rows]
            omega[rows] = warps.spherical_rectangle_solid_angle(
                corner[rows], lights.axis_x[lr], lights.axis_y[lr], p[rows])
        front = dot(p - lights.position[li], lights.direction[li]) > 0
        use &= front & (omega >= warps.MIN_SPHERICAL_SOLID_ANGLE) & (
            omega <= warps.MAX_SPHERICAL_SOLID_ANGLE)
        return omega, corner, use

    # ------------------------------------------------------------------ next-event estimation
    def sample_li(self, m, li, p, u, pmf, out, counters=None):
        """Uniformly by area, or rectangles by solid angle."""
        lights = self.lights
        uu = batch_rows(u, m)
        q, area, _ = self._points(li, uu)
        omega, corner, sph = self.use_spherical(li, batch_rows(p, m))
        if sph.any():
            q[sph] = warps.sample_spherical_rectangle(uu[sph], corner[sph],
                                                      lights.axis_x[li[sph]],
                                                      lights.axis_y[li[sph]], p[m[sph]])
        area_point_pdf(m, p, q, self._rows(lights.direction, li), area,
                       self._rows(lights.radiance, li), pmf, True, out)
        solid_angle_pdf(m, sph, omega, pmf, out.pdf)

    # ------------------------------------------------------------------ rays that find the lamp
    def _hit(self, li, o, d, tmax):
        lights = self.lights
        return ray_parallelogram(o, d, lights.position[li], lights.direction[li],
                                 lights.axis_x[li], lights.axis_y[li], tmax,
                                 lights.kind[li] == LIGHT_DISK)

    def intersect(self, li, o, d, tmax, pmf):
        """Rays ``(rows, radiance, pdf_li)`` that see the emitting face of light ``li``, or
        None."""
        lights = self.lights
        hit = self._hit(li, o, d, tmax)
        if hit is None or hit[0].size == 0:
            return None  # a light of zero size emits nothing
        rows, t, denom, _ = hit
        ax, ay = lights.axis_x[li], lights.axis_y[li]
        area = np.linalg.norm(np.cross(ax, ay))
        if lights.kind[li] == LIGHT_DISK:
            area = area * np.pi / 4
        cos_l = -denom[rows]
        pdf = pmf * t[rows] ** 2 / (cos_l * area)
        if self.sampler.solid_angle and lights.kind[li] == LIGHT_RECT:
            omega, _, sph = self.use_spherical(np.full(rows.size, li), o[rows])
            pdf = np.where(sph, pmf / np.where(sph, omega, 1.0), pdf)
        return rows, np.broadcast_to(lights.radiance[li], (rows.size, 3)), pdf

    def surface_points(self, li, o, d, tmax):
        """Light-path view of rays meeting light ``li``: ``(rows, point, emitting normal,
        distance)`` or None."""
        hit = self._hit(li, o, d, tmax)
        if hit is None or hit[0].size == 0:
            return None
        rows, t, _, q = hit
        n_l = self.lights.direction[li]
        return rows, q, np.broadcast_to(n_l, (rows.size, 3)).copy(), t[rows]

    # ------------------------------------------------------------------ light paths
    def sample_le_origin(self, m, li, u, pmf, out):
        if m.size == out.pdf.size:  # every row chose an area lamp (m is 0..n-1): whole arrays
            out.p, area, _ = self._points(li, u)
            out.normal = self.lights.direction.take(li, axis=0)
            out.pdf = np.where(area > 0, pmf / np.maximum(area, 1e-300), 0.0)
            return
        out.p[m], area, _ = self._points(li, u[m])
        out.normal[m] = self.lights.direction[li]
        out.pdf[m] = np.where(area > 0, pmf[m] / np.maximum(area, 1e-300), 0.0)

    def sample_le_direction(self, m, li, pts, u, out):
        """A cosine about the emitting side (the lamp's frame, :attr:`le_s`, :attr:`le_t`)."""
        uu = u.copy() if m.size == out.pdf.size else u[m]
        uu[:, 0] = np.minimum(uu[:, 0], 1 - 1e-16)
        frame = [a.take(li, axis=0) for a in (self.le_s, self.le_t, self.lights.direction)]
        cosine_directions(m, frame, uu, 1.0, out)

    def le(self, m, li, cos, w, receiver, out):
        out[m] = self.lights.radiance[li] * (cos[m] > 0)[:, None]

    def pdf_le_origin(self, m, li, sel, w, out):
        area = self._area(li)
        out[m] = np.where(area > 0, sel[m] / np.maximum(area, 1e-300), 0.0)

    def pdf_le_direction(self, m, li, cos, w, out):
        out[m] = np.maximum(cos[m], 0.0) / np.pi


def pick_face(u0):
    """The face a number ``u0 (k,)`` picks, each with probability 1/2: ``back (k,)`` (True for
    the back face) and the number rescaled to ``[0, 1)`` for the direction's sample."""
    back = u0 >= 0.5
    return back, np.minimum(np.where(back, 2 * u0 - 1, 2 * u0), 1 - 1e-16)


def cosine_directions(m, frame, uu, face_prob, out):
    """Fill rows ``m`` of ``out`` (:class:`~.base.LeDirections`) with cosine-distributed
    directions by ``uu (k, 2)`` about the normals of ``frame`` (``s, t, n``, each ``(k, 3)``),
    whose face was chosen with probability ``face_prob``."""
    local = warps.sample_cosine_hemisphere(uu)
    w, pdf = warps.to_world(local, *frame), warps.cosine_hemisphere_pdf(local[:, 2]) * face_prob
    if m.size == out.pdf.size:  # every row (m is then 0..n-1): whole arrays, no scatters
        out.w, out.pdf, out.cos_l = w, pdf, local[:, 2].copy()
        return
    out.w[m], out.pdf[m], out.cos_l[m] = w, pdf, local[:, 2]
