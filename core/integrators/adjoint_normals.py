"""Shading normals on subpaths: the camera side's BSDF (Cycles' rule) and its adjoint.

The camera side (the path tracer, BDPT's camera subpaths and the camera ends of its
connections) shades a smooth hit in the frame of its perturbed normal ``nm`` (interpolated
corner normals, Normal Map, Bump; :attr:`.common.Interaction.nm`), whatever the direction
toward the camera ``wc``; where ``wc`` sees ``nm`` and the geometric normal ``ng`` from
different sides, the row is replaced by Cycles' lower-view variant
(:func:`..materials.lower_view.lower_view_params`: Lambert around ``nm``, scaled by kind).
The scene's BSDF is therefore

    f(wc, wl) = f_nm(wc, wl)            where (wc . nm) (wc . ng) > 0,
                f_nm^below(wc', wl)     else (wc' = wc mirrored through nm's plane),

times the geometric-side rule, with a variant that depends on the camera-side direction.
:meth:`VertexNormals.camera_side`, :meth:`~VertexNormals.f_radiance`,
:meth:`~VertexNormals.sample_radiance` and :meth:`~VertexNormals.pdf_camera` are that BSDF.

A light path (light tracing, BDPT's light subpaths, photons) arrives from ``wl`` and samples
``wc``; it uses the adjoint:

- evaluation in ``nm``'s frame with the variant of ``wc``, in importance mode, times Veach's
  shading-normal factor ``|wl . nm| |wc . ng| / (|wl . ng| |wc . nm|)`` (thesis section 5.3;
  pbrt-v4's ``CorrectShadingNormal``) and the geometric-side rule;
- sampling ``wc`` from the mixture ``(1 - q) p_nm(wl -> wc) + q p_ng(wl -> wc)`` of the BSDF
  sampled in either frame, ``q = min(1/2, |nm x ng|)`` (zero where the two agree): the ``ng``
  proposal covers the wedge below ``nm`` where the lower-view variant (a cosine lobe around
  ``ng`` once Veach's factor is in) is non-zero. A non-delta sample weighs ``f / mixture``; a
  delta sample counts only where drawn in ``nm``'s frame and the camera side keeps that delta
  lobe (not where ``wc`` is below ``nm``, except a Transparent BSDF), divided by ``1 - q``;
- BDPT's MIS reads the mixture as the light side's density and the camera side's pdf (the
  lower-view pdf where ``wc`` is below ``nm``) as the camera side's, at light and camera
  vertices alike.

Both frames are rebuilt from the stored frame of a vertex (its ``s`` axis is the tangent of
anisotropic rows; exact for the stored normal, the other frame's tangent is that ``s``
projected).

Where the material bends glossy normals for valid reflections (``bends``,
:func:`.common.valid_reflection_normals`), the camera side's frame of a glossy or glass row is
around the normal bent for ``wc`` (:meth:`VertexNormals.bent_rows`; a layered row keeps its
base around ``nm``), as the path tracer's: the BSDF then depends on ``wc``, which a light path
samples. Evaluation in that frame is exact (Veach's factor with the bent normal); sampling
stays the mixture above (its ``ng`` share covers the bent lobe, since only rows with
``nm != ng`` bend) with every non-delta sample weighed by the exact ``f``. A delta sample of a
row the camera side bends for its ``wc`` counts zero: light paths do not sample the bent
mirror, and renders report those materials (:func:`unsampled_bent_mirrors`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..materials.bsdf import (IMPORTANCE, KIND_DIFFUSE, RADIANCE, crosses_surface, eval_bsdf,
                              pdf_bsdf, sample_bsdf)
from ..materials.frame import shading_frame, to_local, to_world
from ..materials.lower_view import lower_view_params, shaded_below, view_below
from ..materials.microfacet import is_smooth
from ..sampling.warps import remap_after_choice
from .common import (geometric_side_valid, materials_bending, valid_reflection_normals,
                     with_base_normals)

# The largest share of light-path samples drawn in the geometric normal's frame.
MAX_NG_SHARE = 0.5


def dot(a, b):
    return np.einsum("ij,ij->i", a, b)


def mixture_share(nm, ng):
    """``q (k,)``: the share of light-path samples drawn in ``ng``'s frame, ``min(1/2,
    |nm x ng|)`` (zero where the normals agree, so that nothing changes there)."""
    return np.minimum(MAX_NG_SHARE, np.linalg.norm(np.cross(nm, ng), axis=1))


def unsampled_bent_mirrors(prep):
    """Names of the materials whose smooth (delta) glossy lobes the camera side may bend
    (:meth:`VertexNormals.bent_rows`) on a smooth-shaded scene: light paths sample the mirror
    of the unbent normal only and count it where the camera side keeps it; where the camera
    side bends, there is no exact adjoint sample and the light side's strategies miss those
    paths (light tracing and photons darker there; BDPT keeps them through camera subpaths
    only with their MIS share). Empty on flat-shaded scenes."""
    scene = prep.scene
    if scene.corner_normals is None or prep.material_bsdf is None:
        return []
    p = prep.material_bsdf
    delta = (p.kind != KIND_DIFFUSE) & is_smooth(p.alpha)
    if p.coat_weight is not None and p.coat_alpha is not None:
        delta |= (p.coat_weight > 0) & is_smooth(p.coat_alpha)
    rows = np.nonzero(delta & materials_bending(scene.materials))[0]
    names = list(scene.materials.names)
    return [names[i] if i < len(names) else f"material {i}" for i in rows]


def _pick(mask, a, b):
    return np.where(mask[:, None], a, b)


class VertexNormals:
    """Hits with both candidate frames: the BSDF of their rows as light paths see it.

    Parameters
    ----------
    params : BSDFParams
        ``k`` rows, ``bump_normal`` (if any) in the local ``frame``.
    frame : tuple of three (k, 3) float64
        The frame the rows were stored in (around ``nm`` or ``ng``).
    ng : (k, 3) float64
        Stored geometric normals (not flipped).
    nm : (k, 3) float64
        Perturbed normals on ``ng``'s front side (:attr:`.common.Interaction.nm`).
    bends : (k,) bool, optional
        Rows whose material lets glossy closures bend their normal for a valid reflection
        (:func:`.common.bends_normals`); the camera side bends the non-diffuse ones among them
        as the path tracer does. None: no row bends.
    """

    def __init__(self, params, frame, ng, nm, bends=None):
        self.tangent = frame[0] if params.aniso_scale is not None else None
        self.ng, self.nm = ng, nm
        self.q = mixture_share(nm, ng)
        self.frame_m = shading_frame(nm, self.tangent)
        self.frame_g = shading_frame(ng, self.tangent)
        self.params = params
        self.bump = self.bump_world = None
        if params.bump_normal is not None:
            self.bump_world = to_world(params.bump_normal, *frame)
            self.bump = tuple(to_local(self.bump_world, *f) for f in (self.frame_m, self.frame_g))
        self.coat = self.coat_world = None
        if params.coat_normal is not None:  # the coat's own normal (core.materials.coat)
            world = to_world(params.coat_normal, *frame)
            # Rows without a coat normal keep a zero column in every frame.
            self.coat_world = world * np.any(params.coat_normal != 0.0, axis=1)[:, None]
            self.coat = tuple(to_local(self.coat_world, *f) for f in (self.frame_m, self.frame_g))
        # Normals that agree (q = 0) always give a valid reflection: nothing to bend there.
        self.bend = None
        if bends is not None:
            self.bend = np.asarray(bends, bool) & (params.kind != KIND_DIFFUSE) & (self.q > 0)

    def take(self, rows):
        """The rows ``rows`` (an index array)."""
        out = object.__new__(VertexNormals)
        out.ng, out.nm, out.q = self.ng[rows], self.nm[rows], self.q[rows]
        out.frame_m = tuple(a[rows] for a in self.frame_m)
        out.frame_g = tuple(a[rows] for a in self.frame_g)
        out.params = self.params.take(rows)
        out.bump = None if self.bump is None else tuple(b[rows] for b in self.bump)
        out.coat = None if self.coat is None else tuple(c[rows] for c in self.coat)
        out.coat_world = None if self.coat_world is None else self.coat_world[rows]
        out.tangent = None if self.tangent is None else self.tangent[rows]
        out.bump_world = None if self.bump_world is None else self.bump_world[rows]
        out.bend = None if self.bend is None else self.bend[rows]
        return out

    def _in(self, use_m):
        """Frame and params of each row: ``nm``'s where ``use_m (k,)``, else ``ng``'s."""
        every = use_m.all()
        if every or not use_m.any():
            frame = self.frame_m if every else self.frame_g
            bump = None if self.bump is None else self.bump[0 if every else 1]
            coat = None if self.coat is None else self.coat[0 if every else 1]
        else:
            frame = tuple(_pick(use_m, a, b) for a, b in zip(self.frame_m, self.frame_g))
            bump = None if self.bump is None else _pick(use_m, *self.bump)
            coat = None if self.coat is None else _pick(use_m, *self.coat)
        params = self.params if bump is None else replace(self.params, bump_normal=bump)
        params = params if coat is None else replace(params, coat_normal=coat)
        return frame, params

    def bent_rows(self, wc):
        """The rows whose glossy normal the camera side bends for ``wc (k, 3)`` (Cycles'
        ``ensure_valid_specular_reflection``, :func:`.common.valid_reflection_normals`, as
        the path tracer): ``rows (b,)`` and their bent normals ``(b, 3)`` on ``ng``'s front
        side. Rows whose normal the rule leaves as it is are not among them."""
        if self.bend is None or not self.bend.any():
            return np.zeros(0, np.int64), np.zeros((0, 3))
        rows = np.nonzero(self.bend)[0]
        ng, w = self.ng[rows], wc[rows]
        side = np.where(dot(ng, w) >= 0, 1.0, -1.0)[:, None]
        bent = valid_reflection_normals(ng, w, self.nm[rows] * side)
        bent = bent * np.where(dot(bent, ng) < 0, -1.0, 1.0)[:, None]
        moved = np.any(bent != self.nm[rows], axis=1)
        return rows[moved], bent[moved]

    def _camera_frame(self, wc):
        """The camera side's frame and params before the lower-view rule: ``nm``'s, with the
        bent normal of :meth:`bent_rows` on the rows that bend (their bump normal moved into
        that frame, layered rows keeping their base around ``nm``, as the path tracer)."""
        frame, params = self._in(np.ones(self.q.size, bool))
        rows, bent = self.bent_rows(wc)
        if rows.size == 0:
            return frame, params
        frame = tuple(a.copy() for a in frame)
        tangent = None if self.tangent is None else self.tangent[rows]
        for axis, value in zip(frame, shading_frame(bent, tangent)):
            axis[rows] = value
        if self.bump_world is not None:
            params = replace(params, bump_normal=to_local(self.bump_world, *frame))
        if self.coat_world is not None:  # the coat keeps its own (unbent) normal
            params = replace(params, coat_normal=to_local(self.coat_world, *frame))
        return frame, with_base_normals(params, self.nm, frame)

    def camera_side(self, wc):
        """The camera side's BSDF for directions toward the camera ``wc (k, 3)``: the ``nm``
        frame (bent as :meth:`bent_rows` says), the rows' params there (the lower-view variant
        of :mod:`..materials.lower_view` where ``wc`` lies below the frame's normal) and
        ``wc`` in that frame (mirrored on those rows)."""
        frame, params = self._camera_frame(wc)
        wc_l = to_local(wc, *frame)
        below = view_below(dot(wc, self.ng), wc_l[:, 2])
        params, wc_l = lower_view_params(params, wc_l, below)
        return frame, params, wc_l

    def has_camera_deltas(self, wc):
        """Whether the camera side's BSDF at ``wc (k, 3)`` keeps its delta lobes: ``(k,)``
        bool (False where the lower-view variant replaced the row, and where the row's normal
        is bent for ``wc``: its mirror is then another than ``nm``'s, and light paths do not
        sample it, see :func:`unsampled_bent_mirrors`)."""
        wc_l = to_local(wc, *self.frame_m)
        keeps = ~shaded_below(self.params, view_below(dot(wc, self.ng), wc_l[:, 2]))
        keeps[self.bent_rows(wc)[0]] = False
        return keeps

    def f_importance(self, wl, wc):
        """``f(wc, wl) |cos|`` read from the light side (toward ``wc``, world directions), with
        the geometric-side rule and Veach's factor. ``(k, 3)``."""
        frame, params, wc_l = self.camera_side(wc)
        wl_l = to_local(wl, *frame)
        f = eval_bsdf(params, wl_l, wc_l, IMPORTANCE)
        f *= self._factor(wl, wc, wl_l, wc_l, frame[2], params)[:, None]
        if params.base_normal is not None or params.coat_normal is not None:
            # Bent layered rows and coats on their own normal: the lobes have different
            # normals, so no single Veach factor applies; the adjoint is the camera side's
            # f |wc.ng| / |wl.ng|.
            own = np.zeros(len(params), bool)
            for column in (params.base_normal, params.coat_normal):
                if column is not None:
                    own |= np.any(column != 0.0, axis=1)
            rows = own.nonzero()[0]
            if rows.size:
                f[rows] = self._adjoint_of_radiance(params.take(rows), wl[rows], wc[rows],
                                                    wl_l[rows], wc_l[rows], rows)
        return f

    def _own_normals(self):
        """Rows whose coat has a normal of its own: ``(k,)`` bool."""
        if self.coat_world is None:
            return np.zeros(self.q.size, bool)
        return np.any(self.coat_world != 0.0, axis=1)

    def _adjoint_of_radiance(self, params, wl, wc, wl_l, wc_l, rows):
        """``f(wc, wl) |cos| |wc.ng| / |wl.ng|`` (the camera side's ``eval``, its own cosines)
        with the geometric-side rule, on ``rows``."""
        f = eval_bsdf(params, wc_l, wl_l, RADIANCE)
        num, den = np.abs(dot(wc, self.ng[rows])), np.abs(dot(wl, self.ng[rows]))
        ratio = np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
        side = geometric_side_valid(self.ng[rows], wl, wc, crosses_surface(params, wl_l, wc_l))
        return f * (ratio * side)[:, None]

    def f_radiance(self, wc, wl):
        """``f(wc, wl) |cos|`` read from the camera side (as the path tracer evaluates it),
        with the geometric-side rule. ``(k, 3)``."""
        frame, params, wc_l = self.camera_side(wc)
        wl_l = to_local(wl, *frame)
        f = eval_bsdf(params, wc_l, wl_l, RADIANCE)
        return f * self._side(wl, wc, wl_l, wc_l, params)[:, None]

    def sample_radiance(self, wc, u_lobe, u):
        """Sample ``wl`` from the camera side's BSDF given ``wc (k, 3)`` (as the path tracer
        does). Returns the :class:`BSDFSample` (``wi`` local to the camera side's frame), ``wl``
        (world) and the weight with the geometric-side rule."""
        frame, params, wc_l = self.camera_side(wc)
        smp = sample_bsdf(params, wc_l, u_lobe, u, RADIANCE)
        wl = to_world(smp.wi, *frame)
        weight = smp.weight * self._side(wl, wc, smp.wi, wc_l, params)[:, None]
        return smp, wl, weight

    def _side(self, wl, wc, wl_l, wc_l, params=None):
        """The geometric-side rule, ``(k,)`` 0 or 1 (transmission read from the local sides,
        as :func:`..materials.bsdf.crosses_surface` of ``params`` when given)."""
        if params is None:
            transmit = wl_l[:, 2] * wc_l[:, 2] < 0
        else:
            transmit = crosses_surface(params, wl_l, wc_l)
        return geometric_side_valid(self.ng, wl, wc, transmit).astype(np.float64)

    def _factor(self, wl, wc, wl_l, wc_l, n=None, params=None):
        """Geometric-side rule times Veach's shading-normal factor with the frame's normal
        ``n (k, 3)`` (default ``nm``; ``params`` as :meth:`_side`)."""
        n = self.nm if n is None else n
        num = np.abs(dot(wl, n)) * np.abs(dot(wc, self.ng))
        den = np.abs(dot(wl, self.ng)) * np.abs(dot(wc, n))
        veach = np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
        return self._side(wl, wc, wl_l, wc_l, params) * veach

    def pdf_light(self, wl, wc):
        """The light side's solid-angle density of sampling ``wc`` from ``wl``: the mixture
        of :meth:`sample_importance`, each frame with its own bump and coat normals."""
        frame, params = self._in(np.ones(self.q.size, bool))
        pm = pdf_bsdf(params, to_local(wl, *frame), to_local(wc, *frame))
        rows = np.nonzero(self.q > 0)[0]
        if rows.size == 0:
            return pm
        g, params_g = self.take(rows)._in(np.zeros(rows.size, bool))
        pg = pdf_bsdf(params_g, to_local(wl[rows], *g), to_local(wc[rows], *g))
        out = pm.copy()
        out[rows] = (1.0 - self.q[rows]) * pm[rows] + self.q[rows] * pg
        return out

    def pdf_camera(self, wc, wl):
        """The camera side's solid-angle density of sampling ``wl`` from ``wc`` (its BSDF of
        :meth:`camera_side`)."""
        frame, params, wc_l = self.camera_side(wc)
        return pdf_bsdf(params, wc_l, to_local(wl, *frame))

    def sample_importance(self, wl, u_lobe, u):
        """Sample ``wc`` from the mixture, given ``wl (k, 3)`` (world, toward the light side).

        Returns
        -------
        wc : (k, 3) float64
            World directions (zero where the sample failed).
        weight : (k, 3) float64
            ``f |cos| / pdf`` with the factors of :meth:`f_importance` (zero where invalid).
        pdf : (k,) float64
            The mixture density (non-delta samples), or the chance of the delta lobe times
            the chance of the ``nm`` frame.
        delta : (k,) bool
        lobe : (k,) uint8
        """
        use_g = u_lobe < self.q
        u_lobe = remap_after_choice(u_lobe, self.q, use_g)
        frame, params = self._in(~use_g)
        wl_l = to_local(wl, *frame)
        smp = sample_bsdf(params, wl_l, u_lobe, u, IMPORTANCE)
        wc = to_world(smp.wi, *frame)
        chance = np.where(use_g, self.q, 1.0 - self.q)
        # Drawn from the camera side's own BSDF: in nm's frame, where wc does not see the row
        # from below nm. Only those delta samples count (the camera side has no other delta
        # lobes); the other rows are evaluated by the camera side's rule below.
        same = ~use_g & self.has_camera_deltas(wc)
        factor = self._factor(wl, wc, wl_l, smp.wi) * same
        weight = smp.weight * (factor / np.where(chance > 0, chance, 1.0))[:, None]
        pdf = smp.pdf * chance
        smooth = ~smp.delta & (smp.pdf > 0)
        if smooth.any():
            self._mixture_weights(wl, wc, smp, smooth, same, factor, use_g, weight, pdf)
        return wc, weight, pdf, smp.delta, smp.lobe

    def _mixture_weights(self, wl, wc, smp, smooth, same, factor, use_g, weight, pdf):
        """Set ``weight`` and ``pdf`` of the non-delta samples ``smooth (k,)`` to ``f / mixture``
        and the mixture, in place: ``f`` is the sample's own ``eval`` (``weight x pdf``) where
        it was drawn from the camera side's BSDF (``same``) with one normal for all its lobes,
        else :meth:`f_importance` (a coat on its own normal has no single Veach factor)."""
        f = smp.weight * (smp.pdf * factor)[:, None]
        mix = smp.pdf.copy()  # rows of q = 0: one frame, drawn with chance one
        mixed = np.nonzero(smooth & (self.q > 0))[0]
        if mixed.size:
            part = self.take(mixed)
            other, other_params = part._in(use_g[mixed])
            p_other = pdf_bsdf(other_params, to_local(wl[mixed], *other),
                               to_local(wc[mixed], *other))
            q = self.q[mixed]
            mix[mixed] = np.where(use_g[mixed], q * smp.pdf[mixed] + (1.0 - q) * p_other,
                                  (1.0 - q) * smp.pdf[mixed] + q * p_other)
        moved = np.nonzero(smooth & (~same | self._own_normals()))[0]
        if moved.size:
            f[moved] = self.take(moved).f_importance(wl[moved], wc[moved])
        rows = smooth.nonzero()[0]
        weight[rows] = f[rows] / np.where(mix[rows] > 0, mix[rows], np.inf)[:, None]
        pdf[rows] = mix[rows]
