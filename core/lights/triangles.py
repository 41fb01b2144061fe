"""Emissive triangles: mesh faces whose material has an Emission (Strength is radiance,
emitted from both faces).

All triangles that share an emission material form one light, as an emissive object would:
light selection chooses the material first, then one of its triangles in proportion to its power
(area x luminance). Next-event estimation samples a point uniformly by area, or
(``light_sampling='solid_angle'``) uniformly over the spherical triangle it subtends (Arvo 1995)
where that warp is well conditioned. Light paths leave a uniform point by a cosine about either
face (probability 1/2 each). Emissive triangles are scene geometry: Embree finds them, and
:meth:`EmissiveTriangles.pdf_li` gives a hit the density next-event estimation would have.
"""

from __future__ import annotations

import numpy as np

from ..materials.coat import coat_attenuation
from ..materials.microfacet import alpha_from_roughness
from ..rows import put_rows
from ..sampling import warps
from .area import area_point_pdf, cosine_directions, pick_face, solid_angle_pdf
from .base import LUMINANCE, LightFamily, batch_rows, dot, set_batch_rows
from ..quiet import quiet


class EmissiveTriangles(LightFamily):
    """The emissive triangles of a scene, grouped by material (see :class:`~.base.LightFamily`).

    Emitter rows ``k + i`` of the sampler (after its ``k`` lamps) are ``emissive[i]``.

    Attributes
    ----------
    emissive : (e,) int64
        Triangle rows of the emitters, contiguous per emission material.
    tri_emitter : (t,) int64
        Emitter row of every triangle (-1 for triangles that do not emit).
    n_groups : int
        Emission materials (lights) among them.
    group_start : (n_groups,) int64
        First emitter of each group.
    emit_group : (e,) int64
        Group of each emitter.
    emit_power : (e,) float64
        Power of each emitter (area x luminance x 2 pi: both faces).
    emit_v0, emit_e1, emit_e2, emit_normal : (e, 3) float64
    emit_area : (e,) float64
    emit_radiance : (e, 3) float64
        The emitters' own copies, so that sampling gathers from small arrays.
    """

    def __init__(self, sampler, scene, tri_area, tri_normal, tri_v0, tri_e1, tri_e2):
        super().__init__(sampler)
        k = len(scene.lights)
        emission = scene.materials.emission[scene.material].astype(np.float64)
        tri_power = (emission @ LUMINANCE) * (2 * np.pi * tri_area)
        emissive = np.nonzero((emission.max(axis=1) > 0) & (tri_area > 0))[0]
        # One light per emission material: its triangles are contiguous rows.
        emissive = emissive[np.argsort(scene.material[emissive], kind="stable")]
        groups, group_start = np.unique(scene.material[emissive], return_index=True)
        self.n_groups = groups.size
        self.group_start = group_start
        self.emissive = emissive
        self.tri_emitter = np.full(scene.n_triangles, -1, np.int64)
        self.tri_emitter[emissive] = k + np.arange(emissive.size)
        self.first_emitter = k
        self.tri_area = tri_area
        self.tri_normal = tri_normal
        self.tri_emission = emission
        self.tri_v0, self.tri_e1, self.tri_e2 = tri_v0, tri_e1, tri_e2
        self.emit_v0 = tri_v0[emissive]
        self.emit_e1 = tri_e1[emissive]
        self.emit_e2 = tri_e2[emissive]
        self.emit_normal = tri_normal[emissive]
        self.emit_area = tri_area[emissive]
        self.emit_radiance = emission[emissive]
        self.emit_power = tri_power[emissive]
        self.emit_group = np.repeat(np.arange(groups.size),
                                    np.diff(np.append(group_start, emissive.size)))
        self.emit_coat = _emitter_coats(scene.materials, scene.material[emissive])
        # Row 2 i + f: face f (0 front, 1 back) of emitter i, its normal and the tangents
        # warps.frame_from_normal makes around it: light paths gather them per sample instead
        # of building a frame per sample (the same values: the frame is a function of the row).
        self.face_normal = np.stack([self.emit_normal, -self.emit_normal], axis=1).reshape(-1, 3)
        self.face_s, self.face_t = warps.frame_from_normal(self.face_normal)
        # The corners' components as rows (3 corners x 3 axes, e): a light path's point is
        # formed axis by axis from 1-D gathers (_points_of), not from (m, 3) row gathers.
        self.corner_axes = np.ascontiguousarray(
            np.stack([self.emit_v0, self.emit_e1, self.emit_e2]).transpose(0, 2, 1))

    def coat_factor(self, e, cos):
        """What the Principled Coat over emitters ``e (j,)`` leaves of their emission seen at
        ``cos (j,)`` to the normal (Cycles attenuates emission below the coat as the layers
        below it, :func:`core.materials.coat.coat_attenuation`): ``(j, 3)``, or None when no
        emitter has a coat."""
        if self.emit_coat is None:
            return None
        weight, eta, tint, alpha = (c.take(e, axis=0) for c in self.emit_coat)
        return coat_attenuation(weight, eta, tint, np.abs(cos), alpha)

    def hit_emission(self, prim, cos):
        """Radiance ``(j, 3)`` of emissive triangles ``prim (j,)`` seen at ``cos (j,)``."""
        le = self.tri_emission.take(prim, axis=0)
        factor = self.coat_factor(self.tri_emitter[prim] - self.first_emitter, cos)
        return le if factor is None else le * factor

    def group_power(self):
        """Power ``(n_groups,)`` of each emission material's triangles together."""
        if not self.emissive.size:
            return np.zeros(0)
        return np.add.reduceat(self.emit_power, self.group_start)

    def use_spherical(self, a, b, c, p):
        """Solid angles ``(n,)`` of triangles ``a, b, c (n, 3)`` from ``p (n, 3)`` and where the
        spherical-triangle warp is used, ``(n,)`` bool.

        Area sampling never needs the solid angle: it is not computed then (zeros).
        """
        if not self.sampler.solid_angle:
            return np.zeros(p.shape[0]), np.zeros(p.shape[0], bool)
        omega = warps.spherical_triangle_solid_angle(a, b, c, p)
        use = ((omega >= warps.MIN_SPHERICAL_SOLID_ANGLE)
               & (omega <= warps.MAX_SPHERICAL_SOLID_ANGLE))
        return omega, use

    def _corners(self, e):
        """First vertex and edges ``(m, 3)`` of emitters ``e (m,)``."""
        return (self.emit_v0.take(e, axis=0), self.emit_e1.take(e, axis=0),
                self.emit_e2.take(e, axis=0))

    # ------------------------------------------------------------------ next-event estimation
    def sample_li(self, m, e, p, u, pmf, out, counters=None):
        """Uniformly by area or by solid angle; both faces emit."""
        pm, um = batch_rows(p, m), batch_rows(u, m)
        if self.sampler.solid_angle:
            v0, e1, e2 = self._corners(e)
            b, c = v0 + e1, v0 + e2
            omega, sph = self.use_spherical(v0, b, c, pm)
        else:
            # Area sampling needs no corner rows: the points are formed axis by axis.
            omega, sph = self.use_spherical(None, None, None, pm)
        every = sph.size > 0 and sph.all()
        # Area points only where the spherical warp is not used (none when it always is).
        q = None if every else self._points_of(e, um)
        normal = self.emit_normal.take(e, axis=0)
        if sph.any():
            arrays = (um, pm, normal, v0, b, c)
            if not every:
                idx = sph.nonzero()[0]
                arrays = [x.take(idx, axis=0) for x in arrays]
            us, ps, nrm, a, bs, cs = arrays
            w = warps.sample_spherical_triangle(us, a, bs, cs, ps)
            # The sampled point is where the direction meets the triangle's plane.
            with quiet("divide", "invalid"):
                t = dot(a - ps, nrm) / dot(w, nrm)
            qs = ps + w * np.where(np.isfinite(t) & (t > 0), t, 0.0)[:, None]
            if every:
                q = qs
            else:
                q[idx] = qs
        emitted = self.emit_radiance.take(e, axis=0)
        if self.emit_coat is not None:
            to_p = pm - q
            cos = dot(to_p, normal) / np.maximum(np.linalg.norm(to_p, axis=1), 1e-300)
            emitted = emitted * self.coat_factor(e, cos)
        area_point_pdf(m, p, q, normal, self.emit_area[e], emitted, pmf, False, out)
        solid_angle_pdf(m, sph, omega, pmf, out.pdf)

    def pdf_li(self, prim, p_prev, dist, cos_light, n_prev=None):
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
        n_prev : (n, 3) float64 or None
            Shading normal at ``p_prev`` (for the light tree).
        """
        ls = self.sampler
        e = self.tri_emitter[prim]
        sel = ls.nee_pmf(e, p_prev, n_prev)
        with quiet("divide", "invalid"):
            pdf = sel * dist * dist / (np.abs(cos_light) * self.tri_area[prim])
        if ls.solid_angle and prim.size:
            # The same decision as sample_li: by solid angle where the warp is well conditioned.
            v0 = self.tri_v0[prim]
            omega, sph = self.use_spherical(v0, v0 + self.tri_e1[prim], v0 + self.tri_e2[prim],
                                            p_prev)
            with quiet("divide", "invalid"):
                pdf = np.where(sph, sel / omega, pdf)
        return np.where(np.isfinite(pdf), pdf, 0.0)

    # ------------------------------------------------------------------ light paths
    def sample_le_origin(self, m, e, u, pmf, out):
        # Row gathers and scatters (np.take, put_rows): the values of fancy indexing, faster.
        # Where every row of the batch chose an emissive triangle (a scene whose only lights
        # are emissive meshes), the arrays are made whole, without gathers or scatters.
        if m.size == out.pdf.size:  # m is then 0..n-1 (families_of's rows are sorted)
            out.p = self._points_of(e, u)
            out.normal = self.emit_normal.take(e, axis=0)
            out.pdf = pmf / self.emit_area.take(e)
            return
        put_rows(out.p, m, self._points_of(e, u.take(m, axis=0)))
        put_rows(out.normal, m, self.emit_normal.take(e, axis=0))
        out.pdf[m] = pmf[m] / self.emit_area[e]

    def _points_of(self, e, u):
        """Uniform points ``(m, 3)`` on emitters ``e (m,)`` by ``u (m, 2)``: on each axis
        ``v0 + b1 e1 + b2 e2``, added in that order, from 1-D gathers of :attr:`corner_axes`
        (not three ``(m, 3)`` row gathers)."""
        _, b1, b2 = warps.uniform_triangle_barycentrics(u)
        out = np.empty((e.size, 3))
        v0, e1, e2 = self.corner_axes
        for c in range(3):
            column = out[:, c]
            np.multiply(b1, e1[c].take(e), out=column)
            np.add(v0[c].take(e), column, out=column)
            column += b2 * e2[c].take(e)
        return out

    def sample_le_direction(self, m, e, pts, u, out):
        """A cosine about either face, each with probability 1/2 (the first number picks the
        face, :func:`.area.pick_face`), the frame of each face gathered from :attr:`face_s`,
        :attr:`face_t` and :attr:`face_normal`."""
        uu = u.take(m, axis=0)
        back, uu[:, 0] = pick_face(uu[:, 0])
        face = 2 * e + back
        cosine_directions(m, [a.take(face, axis=0)
                              for a in (self.face_s, self.face_t, self.face_normal)], uu, 0.5, out)

    def le(self, m, e, cos, w, receiver, out):
        cos_m = batch_rows(cos, m)
        le = self.emit_radiance.take(e, axis=0)
        lit = cos_m != 0
        if not lit.all():  # (where every row is lit, the product by one would change nothing)
            le *= lit[:, None]
        if self.emit_coat is not None:
            le *= self.coat_factor(e, cos_m)
        set_batch_rows(out, m, le)

    def pdf_le_origin(self, m, e, sel, w, out):
        out[m] = sel[m] / self.emit_area[e]

    def pdf_le_direction(self, m, e, cos, w, out):
        out[m] = 0.5 * np.abs(cos[m]) / np.pi


def _emitter_coats(materials, rows):
    """``(weight, eta, tint, alpha)`` of the Coat over each emitter's material row
    ``rows (e,)``, or None when none is coated."""
    weight = np.asarray(materials.coat_weight, np.float64)[rows]
    if not np.any(weight > 0):
        return None
    return (weight, np.maximum(np.asarray(materials.coat_ior, np.float64)[rows], 1.0),
            np.asarray(materials.coat_tint, np.float64)[rows],
            alpha_from_roughness(np.asarray(materials.coat_roughness, np.float64)[rows]))
