"""The BSDF interface: per-row parameters, and eval / pdf / sample over batches of mixed kinds.

Every integrator talks to materials through this module; the families live one per module
(:mod:`.lambert`, :mod:`.conductor` + :mod:`.mirror`, :mod:`.dielectric`, :mod:`.layered`),
the kind codes, lobe labels and per-kind adapters in :mod:`.families`, the Principled coat
over any kind in :mod:`.coat`.

Frames and directions
    All directions are **local**: ``(k, 3)`` float64 unit vectors in a frame whose +Z is the
    shading normal *as stored in the mesh* (pointing to the front / exterior, **not** flipped
    toward the viewer; build it with :func:`.frame.shading_frame` and :func:`.frame.to_local`).
    ``wo`` points toward the previous vertex (the camera side on camera paths), ``wi`` toward
    the next one (the light side); both point away from the surface. The sign of ``wo.z`` is
    the side the path is on: dielectrics use it to tell entering from leaving; reflection-only
    kinds (diffuse, conductor, layered) are two-sided and mirror everything to ``wo``'s side,
    as Cycles does by flipping the normal of back faces.
Functions
    ``eval_bsdf(params, wo, wi, mode) -> (k, 3)``
        ``f(wo, wi) |cos theta_i|``, the non-delta part only (zero for delta lobes).
    ``pdf_bsdf(params, wo, wi) -> (k,)``
        The solid-angle density with which ``sample_bsdf`` produces ``wi`` as a *non-delta*
        sample, lobe-selection probabilities included (zero for delta lobes). It integrates to
        the probability that a sample is non-delta and valid (< 1 where rough microfacet
        samples can scatter to the wrong side, or a delta lobe can be chosen).
    ``sample_bsdf(params, wo, u_lobe, u, mode) -> BSDFSample(wi, weight, pdf, delta, lobe)``
        ``u_lobe (k,)`` chooses a lobe (Fresnel, coat vs base), ``u (k, 2)`` the direction.
        ``weight = f |cos theta_i| / pdf`` (k, 3). For non-delta samples ``pdf`` is the same
        density :func:`pdf_bsdf` returns and ``weight == eval_bsdf / pdf_bsdf``. For delta
        samples (``delta`` True) ``pdf`` is the *discrete* probability of the chosen lobe and
        ``weight`` the lobe's full contribution over it; never use it for MIS. A failed sample
        (scattered to the wrong side, ``wo`` in the tangent plane) has ``wi = 0``,
        ``weight = 0``, ``pdf = 0``.
        ``lobe (k,) uint8`` labels the sampled lobe with ``LOBE_*`` bits, as Cycles' closure
        labels: ``REFLECT`` or ``TRANSMIT``, and ``DIFFUSE``, ``GLOSSY`` or ``SINGULAR`` (delta);
        0 for a failed sample. Integrators use it for per-type bounce limits and for object ray
        visibility (a diffuse bounce traces with ``VIS_DIFFUSE``, glossy and singular
        reflections with ``VIS_GLOSSY``, transmissions with ``VIS_TRANSMISSION``).
    ``is_delta_only(params) -> (k,) bool``
        Rows whose ``eval``/``pdf`` vanish everywhere (smooth mirrors and glass): next-event
        estimation can skip them.
Transport mode
    ``mode='radiance'`` on camera paths; ``mode='importance'`` on light paths (light tracing,
    BDPT light subpaths, photons), where ``wo`` points back toward the light. The modes differ
    for refraction (radiance is scaled by ``1 / etap^2``, see :mod:`.dielectric`) and for the
    non-reciprocal layered base (importance mode evaluates the adjoint). ``pdf`` and the sampled
    directions do not depend on the mode.
Guarantees
    Outputs are finite for any unit ``wo``, ``wi`` (grazing, tangent, below the surface) and
    any parameters in range (roughness 0..1, IOR > 0 including exactly 1); ``eval >= 0``,
    ``pdf >= 0``, ``weight >= 0``.
Kinds and parameters (:class:`BSDFParams`, one row per shading point)
    ``KIND_DIFFUSE``: ``color`` = albedo (two-sided Lambert).
    ``KIND_CONDUCTOR``: ``color`` = F0 (Schlick), ``alpha``; a perfect mirror below the smooth
    threshold (:data:`.microfacet.ALPHA_SMOOTH`).
    ``KIND_CONDUCTOR_MS``: the same conductor with Cycles' Multiscatter GGX energy compensation
    (:mod:`.multiscatter`; not reciprocal: importance mode evaluates the adjoint). A material
    table marks it with its ``multiscatter`` column on a conductor row, not with a kind code
    of its own: :meth:`BSDFParams.from_materials` maps those rows to this kind, so that every
    copy of the parameters (which copies ``kind``) keeps it.
    ``KIND_DIELECTRIC``: ``eta`` (interior / exterior), ``alpha``, ``tint`` = reflection tint,
    ``color`` = transmission tint (Glass BSDF: both the colour). Smooth below the threshold or
    for ``|eta - 1| < 1e-4``.
    ``KIND_LAYERED``: ``color`` = diffuse base, ``alpha`` and ``eta`` of the coat, ``tint`` =
    coat tint (Principled non-metallic opaque: Specular IOR Level folded into ``eta``,
    Specular Tint as Cycles' generalized Schlick Fresnel).
    ``KIND_LAYERED_MS``: the same with Multiscatter GGX on its specular lobe (from the
    ``multiscatter`` column of a layered row, as ``KIND_CONDUCTOR_MS``).
    ``KIND_DIELECTRIC_MS``: the dielectric with Multiscatter GGX (:mod:`.glass_albedo`;
    from the ``multiscatter`` column of a dielectric row).
    Coat: any row may carry a Principled Coat (``coat_*`` columns, :mod:`.coat`), layered
    over its kind by :func:`eval_bsdf`, :func:`pdf_bsdf` and :func:`sample_bsdf`.
    Sheen: any row may carry a microfiber sheen (``sheen_*`` columns, :mod:`.sheen`), layered
    over the coat and the kind (the Principled BSDF's Sheen, the Sheen BSDF node).
    Emission is not a BSDF: it stays a column of the material table.
In an integrator (one bounce, world-space arrays of the live paths)::

    s, t, n = shading_frame(ng)                      # the stored normal, not flipped
    params = BSDFParams.from_materials(scene.materials, scene.material[prim])
    wo = to_local(-d, s, t, n)
    f = eval_bsdf(params, wo, to_local(wi_light, s, t, n))     # NEE: f cos, MIS with pdf_bsdf
    smp = sample_bsdf(params, wo, stream.next_1d(), stream.next_2d())
    wi = to_world(smp.wi, s, t, n)
    beta *= smp.weight; pdf_prev = smp.pdf; use_mis = ~smp.delta; alive &= smp.pdf > 0
    o = accel.offset_origin(p, ng, prim, wi)         # to wi's side: through on refraction
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from ..rows import put_rows
from . import bump_correction, coat, dielectric, sheen
from .coat import DEFAULT_COAT_IOR, DEFAULT_COAT_ROUGHNESS, coat_rows
from .dielectric import IMPORTANCE, RADIANCE, TRANSPORT_MODES, _check_mode, is_smooth_dielectric
from .families import (FAMILIES, KIND_CONDUCTOR, KIND_CONDUCTOR_MS, KIND_DIELECTRIC,
                       KIND_DIELECTRIC_MS, KIND_DIFFUSE, KIND_LAYERED, KIND_LAYERED_MS, KIND_NAMES,
                       KINDS, LOBE_DIFFUSE, LOBE_GLOSSY, LOBE_REFLECT, LOBE_SINGULAR,
                       LOBE_TRANSMIT)
from .fresnel import adjust_ior_for_specular_level
from .microfacet import alpha_from_roughness, is_smooth

__all__ = [
    "KIND_DIFFUSE", "KIND_CONDUCTOR", "KIND_DIELECTRIC", "KIND_LAYERED", "KIND_CONDUCTOR_MS",
    "KIND_LAYERED_MS", "KIND_DIELECTRIC_MS",
    "KINDS", "KIND_NAMES",
    "RADIANCE", "IMPORTANCE", "TRANSPORT_MODES", "LOBE_REFLECT", "LOBE_TRANSMIT", "LOBE_DIFFUSE",
    "LOBE_GLOSSY", "LOBE_SINGULAR", "BSDFParams", "OPTIONAL_GROUPS", "BSDFSample", "make_params",
    "eval_bsdf", "pdf_bsdf", "sample_bsdf", "sample_plain_diffuse", "pdf_plain_diffuse",
    "is_delta_only",
]


# Blender's defaults for material-table columns a scene does not provide.
DEFAULT_ROUGHNESS = 0.5
DEFAULT_IOR = 1.5
DEFAULT_SPECULAR_IOR_LEVEL = 0.5
# Indices are clamped to this range: beyond it Fresnel is 0 or 1 to float precision anyway.
ETA_RANGE = (1e-3, 1e3)


@dataclass
class BSDFParams:
    """Per-row BSDF parameters, struct-of-arrays; row ``i`` shades the point of ``wo[i]``.

    Attributes
    ----------
    kind : (k,) int32
        ``KIND_*`` code.
    color : (k, 3) float64
        Albedo (diffuse, layered base), F0 (conductor) or transmission tint (dielectric), in
        [0, 1].
    alpha : (k,) float64
        GGX alpha = roughness^2, >= ``microfacet.ALPHA_MIN``.
    eta : (k,) float64
        Interior over exterior index (dielectric), coat index (layered).
    tint : (k, 3) float64
        Reflection tint (dielectric), coat tint (layered), in [0, 1].
    coat_weight, coat_alpha, coat_eta : (k,) float64 or None
        Principled Coat over any kind (:mod:`.coat`): weight in [0, 1] (0: no coat), GGX
        alpha, IOR (>= 1). None (all four) when no row has a coat.
    coat_tint : (k, 3) float64 or None
        Coat Tint (>= 0).
    sheen_color : (k, 3) float64 or None
        Sheen Weight x Sheen Tint (>= 0; 0: no sheen, :mod:`.sheen`). None (with
        ``sheen_roughness``) when no row has a sheen.
    sheen_roughness : (k,) float64 or None
        Sheen Roughness in [0, 1].
    aniso_scale, aniso_rotation : (k,) float64 or None
        Anisotropic GGX of conductor and specular-layer rows (:mod:`.anisotropic`): ``alpha_x = alpha k``,
        ``alpha_y = alpha / k`` for the scale ``k > 0`` (1: isotropic), in the shading frame's
        tangent turned by ``aniso_rotation`` radians about the normal. None when every row is
        isotropic.
    bump_normal : (k, 3) float64 or None
        Bump Map Correction (:mod:`.bump_correction`): the smooth, unmapped normal in the
        row's local frame, whose diffuse part is then shadowed; zero rows: no correction.
        None when no row has it (set by the integrators at normal-mapped hits).
    base_normal : (k, 3) float64 or None
        Layered kinds: the unit normal of the diffuse base in the row's local frame, when the
        frame was bent for the specular layer only (:mod:`.layered`, "base normal"); zero
        rows: the base keeps +Z. None when no row has it.
    coat_normal : (k, 3) float64 or None
        Coated rows: the unit normal the coat shades around, in the row's local frame (the
        Coat Normal input, or the smooth normal; :mod:`.coat`); zero rows: +Z. None when no
        coated row's coat normal differs from its shading normal.
    coat_flip : (k,) float64 or None
        With ``coat_normal``: 1 on the rows whose view :mod:`.lower_view` mirrored while it
        lies above the coat normal (the coat then sees the real view), else 0.
    """

    kind: np.ndarray
    color: np.ndarray
    alpha: np.ndarray
    eta: np.ndarray
    tint: np.ndarray
    coat_weight: np.ndarray = None
    coat_alpha: np.ndarray = None
    coat_eta: np.ndarray = None
    coat_tint: np.ndarray = None
    sheen_color: np.ndarray = None
    sheen_roughness: np.ndarray = None
    aniso_scale: np.ndarray = None
    aniso_rotation: np.ndarray = None
    bump_normal: np.ndarray = None
    base_normal: np.ndarray = None
    coat_normal: np.ndarray = None
    coat_flip: np.ndarray = None

    def __len__(self):
        return self.kind.shape[0]

    def has(self, group):
        """Whether the columns of ``group`` (``'coat'``, ``'sheen'``, ``'aniso'``) are present
        (they are None when no row uses the layer)."""
        return getattr(self, _GROUPS[group][0][0]) is not None

    @property
    def has_coat(self):
        """Whether the coat columns are present (they are None when no row has a coat)."""
        return self.has("coat")

    @property
    def has_sheen(self):
        """Whether the sheen columns are present (None when no row has a sheen)."""
        return self.has("sheen")

    def map_columns(self, fn):
        """A new :class:`BSDFParams` of ``fn(column)`` for every column present."""
        return BSDFParams(*(None if c is None else fn(c) for c in self.columns()))

    def columns(self):
        """The columns in field order (an absent group's are None)."""
        return tuple(getattr(self, name) for name in _FIELDS)

    def take(self, rows):
        """The rows ``rows`` (index array, mask or slice) as a new :class:`BSDFParams`."""
        if isinstance(rows, np.ndarray) and rows.dtype.kind in "iu":
            # np.take gathers rows several times faster than fancy indexing (same values).
            return self.map_columns(lambda c: c.take(rows, axis=0))
        return self.map_columns(lambda c: c[rows])

    def scatter(self, rows, src):
        """Store the rows of ``src`` at ``rows`` of this table (adding a group's columns, at
        their neutral values, when ``src`` has them and this table does not)."""
        for group, cols in _GROUPS.items():
            if src.has(group) and not self.has(group):
                self._set_neutral(group)
            elif self.has(group) and not src.has(group):
                for name, value, _ in cols:
                    getattr(self, name)[rows] = value
        for name, value in zip(_FIELDS, src.columns()):
            column = getattr(self, name)
            if value is not None and column is not None:
                column[rows] = value

    @staticmethod
    def concat(parts):
        """The rows of ``parts`` (a non-empty list of :class:`BSDFParams`) in order."""
        for group in _GROUPS:
            if any(p.has(group) for p in parts):
                parts = [p if p.has(group) else p.with_neutral(group) for p in parts]
        return BSDFParams(*(None if cols[0] is None else np.concatenate(cols)
                            for cols in zip(*(p.columns() for p in parts))))

    def _set_neutral(self, group):
        for name, value, shape in _GROUPS[group]:
            setattr(self, name, np.full((len(self),) + shape, value, np.float64))

    def with_neutral(self, group):
        """These rows with explicit columns of ``group`` at values that change nothing."""
        out = BSDFParams(*self.columns())
        out._set_neutral(group)
        return out

    def with_all_groups(self):
        """These rows with every optional group present (absent ones neutral)."""
        out = self
        for group in _GROUPS:
            out = out if out.has(group) else out.with_neutral(group)
        return out

    def fill_neutral(self):
        """Set every present optional group's columns to their neutral values, in place."""
        for group, cols in _GROUPS.items():
            if self.has(group):
                for name, value, _ in cols:
                    getattr(self, name).fill(value)

    def with_no_coat(self):
        """These rows with explicit coat columns of weight zero."""
        return self.with_neutral("coat")

    def with_no_sheen(self):
        """These rows with explicit sheen columns of colour zero (no sheen)."""
        return self.with_neutral("sheen")

    @staticmethod
    def from_materials(materials, mat_ids):
        """Gather the rows ``mat_ids (k,)`` of a material table.

        Reads the table's ``kind`` and ``base_color`` and, when present, ``roughness (m,)``,
        ``ior (m,)``, ``specular_ior_level (m,)``, ``specular_tint (m, 3)`` and
        ``multiscatter (m,)`` and the coat's ``coat_weight``, ``coat_roughness``, ``coat_ior``
        ``(m,)`` and ``coat_tint (m, 3)``, the sheen's ``sheen_weight``, ``sheen_roughness``
        ``(m,)`` and ``sheen_tint (m, 3)``, the anisotropy's ``aniso_scale`` and
        ``aniso_rotation`` ``(m,)`` (in turns, as Blender's Anisotropic Rotation) (Blender's
        defaults otherwise: 0.5, 1.5, 0.5, white, single scattering, no coat, no sheen,
        isotropic). Layered rows fold Specular IOR Level
        into the coat index; dielectric rows use the IOR as is; conductor, layered and (not
        index-matched) dielectric rows marked ``multiscatter`` become ``KIND_*_MS``.
        """
        ids = np.asarray(mat_ids, np.int64)
        kind = np.asarray(materials.kind, np.int32)[ids]

        def column(name, default, shape=()):
            values = getattr(materials, name, None)
            if values is None:
                return np.full((ids.size,) + shape, default, np.float64)
            return np.asarray(values, np.float64)[ids]

        multiscatter = getattr(materials, "multiscatter", None)
        if multiscatter is not None:
            ms = np.asarray(multiscatter, bool)[ids]
            kind = np.where(ms & (kind == KIND_CONDUCTOR), KIND_CONDUCTOR_MS, kind)
            kind = np.where(ms & (kind == KIND_LAYERED), KIND_LAYERED_MS, kind)
            # Index-matched glass stays a pass-through: smooth, nothing to compensate.
            matched = np.abs(column("ior", DEFAULT_IOR) - 1.0) < dielectric.ETA_SMOOTH
            kind = np.where(ms & (kind == KIND_DIELECTRIC) & ~matched, KIND_DIELECTRIC_MS, kind)

        return make_params(kind, np.asarray(materials.base_color, np.float64)[ids],
                           roughness=column("roughness", DEFAULT_ROUGHNESS),
                           ior=column("ior", DEFAULT_IOR),
                           specular_ior_level=column("specular_ior_level",
                                                     DEFAULT_SPECULAR_IOR_LEVEL),
                           tint=column("specular_tint", 1.0, (3,)), k=ids.size,
                           coat_weight=column("coat_weight", 0.0),
                           coat_roughness=column("coat_roughness", DEFAULT_COAT_ROUGHNESS),
                           coat_ior=column("coat_ior", DEFAULT_COAT_IOR),
                           coat_tint=column("coat_tint", 1.0, (3,)),
                           sheen_weight=column("sheen_weight", 0.0),
                           sheen_roughness=column("sheen_roughness",
                                                  sheen.DEFAULT_SHEEN_ROUGHNESS),
                           sheen_tint=column("sheen_tint", 1.0, (3,)),
                           aniso_scale=column("aniso_scale", 1.0),
                           aniso_rotation=2.0 * np.pi * column("aniso_rotation", 0.0))


def make_params(kind, color=1.0, roughness=DEFAULT_ROUGHNESS, ior=DEFAULT_IOR,
                specular_ior_level=DEFAULT_SPECULAR_IOR_LEVEL, tint=1.0, k=None,
                coat_weight=0.0, coat_roughness=DEFAULT_COAT_ROUGHNESS,
                coat_ior=DEFAULT_COAT_IOR, coat_tint=1.0, sheen_weight=0.0,
                sheen_roughness=sheen.DEFAULT_SHEEN_ROUGHNESS, sheen_tint=1.0, aniso_scale=1.0,
                aniso_rotation=0.0):
    """Build :class:`BSDFParams` from Blender-style inputs, broadcasting scalars to ``k`` rows.

    Parameters
    ----------
    kind : int or (k,) int
    color : float, (3,) or (k, 3) float
    roughness, ior, specular_ior_level : float or (k,) float
        Roughness in [0, 1] (alpha = roughness^2); IOR > 0; Specular IOR Level in [0, 1]
        (layered rows only; 0.5 keeps the IOR).
    tint : float, (3,) or (k, 3) float
    k : int, optional
        Row count when every input is a scalar.
    coat_weight, coat_roughness, coat_ior : float or (k,) float
        Principled Coat (:mod:`.coat`): weight clipped to [0, 1], roughness, IOR (below one:
        one, as Cycles). The coat columns are left None when every weight is zero.
    coat_tint : float, (3,) or (k, 3) float
        Coat Tint, clipped to >= 0.
    sheen_weight, sheen_roughness : float or (k,) float
        Sheen (:mod:`.sheen`): weight clipped to >= 0, roughness to [0, 1]. The sheen
        columns are left None when no row has a sheen.
    sheen_tint : float, (3,) or (k, 3) float
        Sheen Tint, clipped to >= 0.
    aniso_scale, aniso_rotation : float or (k,) float
        Anisotropic GGX of conductor and specular-layer rows (:mod:`.anisotropic`):
        ``alpha_x = alpha k``, ``alpha_y = alpha / k`` (``k`` clipped to [1e-3, 1e3]; 1 on
        other kinds), the tangent turned by ``aniso_rotation`` radians. Columns left None
        when all isotropic.
    """
    if k is None:
        k = max(np.size(kind), np.size(roughness), np.size(ior), np.size(specular_ior_level),
                np.shape(color)[0] if np.ndim(color) == 2 else 1,
                np.shape(tint)[0] if np.ndim(tint) == 2 else 1)
    kind = np.broadcast_to(np.asarray(kind, np.int32), (k,)).copy()
    color = np.clip(np.broadcast_to(np.asarray(color, np.float64), (k, 3)), 0.0, 1.0)
    tint = np.clip(np.broadcast_to(np.asarray(tint, np.float64), (k, 3)), 0.0, 1.0)
    alpha = alpha_from_roughness(np.broadcast_to(np.asarray(roughness, np.float64), (k,)))
    ior = np.nan_to_num(np.broadcast_to(np.asarray(ior, np.float64), (k,)), nan=DEFAULT_IOR)
    eta = np.clip(ior, *ETA_RANGE)
    layered_rows = (kind == KIND_LAYERED) | (kind == KIND_LAYERED_MS)
    if layered_rows.any():
        level = np.broadcast_to(np.asarray(specular_ior_level, np.float64), (k,))
        eta = np.where(layered_rows, adjust_ior_for_specular_level(eta, level), eta)
        eta = np.clip(eta, *ETA_RANGE)
    params = BSDFParams(kind, color.copy(), alpha, eta, tint.copy())
    weight = np.clip(np.nan_to_num(np.broadcast_to(np.asarray(coat_weight, np.float64), (k,))),
                     0.0, 1.0)
    if np.any(weight > 0.0):
        params.coat_weight = weight.copy()
        params.coat_alpha = alpha_from_roughness(
            np.broadcast_to(np.asarray(coat_roughness, np.float64), (k,)))
        coat_eta = np.nan_to_num(np.broadcast_to(np.asarray(coat_ior, np.float64), (k,)),
                                 nan=DEFAULT_COAT_IOR)
        params.coat_eta = np.clip(coat_eta, 1.0, ETA_RANGE[1])
        params.coat_tint = np.maximum(
            np.nan_to_num(np.broadcast_to(np.asarray(coat_tint, np.float64), (k, 3))), 0.0)
    params = _with_sheen(params, k, sheen_weight, sheen_roughness, sheen_tint)
    return _with_aniso(params, k, aniso_scale, aniso_rotation)


def _with_aniso(params, k, scale, rotation):
    """``params`` with the anisotropy columns when any conductor or specular-layer row is
    anisotropic."""
    glossy = np.isin(params.kind, (KIND_CONDUCTOR, KIND_CONDUCTOR_MS, KIND_LAYERED,
                                   KIND_LAYERED_MS))
    scale = np.clip(np.nan_to_num(np.broadcast_to(np.asarray(scale, np.float64), (k,)), nan=1.0),
                    1e-3, 1e3)
    rotation = np.nan_to_num(np.broadcast_to(np.asarray(rotation, np.float64), (k,)))
    scale = np.where(glossy, scale, 1.0)
    rotation = np.where(glossy & (scale != 1.0), rotation, 0.0)
    if np.any(scale != 1.0):
        params.aniso_scale, params.aniso_rotation = scale, rotation
    return params


def _with_sheen(params, k, weight, roughness, tint):
    """``params`` with the sheen columns of ``weight x tint`` when any row has a sheen."""
    def rows(value, shape):
        return np.nan_to_num(np.broadcast_to(np.asarray(value, np.float64), (k,) + shape))

    color = np.maximum(rows(weight, ())[:, None], 0.0) * np.maximum(rows(tint, (3,)), 0.0)
    if np.any(color > 0.0):
        params.sheen_color = color
        params.sheen_roughness = np.clip(rows(roughness, ()), 0.0, 1.0).copy()
    return params


_FIELDS = tuple(f.name for f in fields(BSDFParams))
# Optional column groups: (name, neutral value, trailing shape) per column; the first column
# says whether the group is present.
_GROUPS = {
    "coat": (("coat_weight", 0.0, ()), ("coat_alpha", 1.0, ()), ("coat_eta", 1.0, ()),
             ("coat_tint", 1.0, (3,))),
    "sheen": (("sheen_color", 0.0, (3,)), ("sheen_roughness", 1.0, ())),
    "aniso": (("aniso_scale", 1.0, ()), ("aniso_rotation", 0.0, ())),
    "bump": (("bump_normal", 0.0, (3,)),),
    "base": (("base_normal", 0.0, (3,)),),
    "coatn": (("coat_normal", 0.0, (3,)), ("coat_flip", 0.0, ())),
}
# Their names: what BSDFParams.has / with_neutral take.
OPTIONAL_GROUPS = tuple(_GROUPS)


class BSDFSample(NamedTuple):
    """Result of :func:`sample_bsdf` (see the module docstring)."""

    wi: np.ndarray      # (k, 3) float64, zero where the sample failed
    weight: np.ndarray  # (k, 3) float64, f |cos theta_i| / pdf
    pdf: np.ndarray     # (k,) float64, solid-angle density or discrete lobe probability
    delta: np.ndarray   # (k,) bool
    lobe: np.ndarray    # (k,) uint8, LOBE_* bits; 0 where the sample failed


def kind_groups(params):
    """``(kind, rows)`` per kind present; ``rows`` is None when one kind covers the batch."""
    kind = params.kind
    if kind.size == 0:
        return []
    lo, hi = int(kind.min()), int(kind.max())
    if lo < min(KINDS) or hi > max(KINDS):  # KINDS are the consecutive codes 0..6
        unknown = ~np.isin(kind, KINDS)
        raise ValueError(f"unknown BSDF kind codes {np.unique(kind[unknown]).tolist()}")
    first = kind[0]
    if lo == hi:
        return [(int(first), None)]
    # Kind by kind in ascending order (as np.unique would give them, without its sort).
    groups = [(c, np.nonzero(kind == c)[0]) for c in range(lo, hi + 1)]
    return [(c, rows) for c, rows in groups if rows.size]


def kind_rows(params, kind, rows):
    """``params.take(rows)`` for the family of ``kind`` (:data:`.families.FAMILIES`): the
    diffuse family reads the colour alone, so its other columns are not gathered but
    read-only constants (its values are the same; several gathers fewer on the diffuse rows
    of every mixed batch)."""
    if kind != KIND_DIFFUSE:
        return params.take(rows)
    k = rows.size
    return BSDFParams(params.kind.take(rows), params.color.take(rows, axis=0),
                      np.broadcast_to(1.0, (k,)), np.broadcast_to(1.0, (k,)),
                      np.broadcast_to(0.0, (k, 3)))


def check_rows(params, wo, mode=RADIANCE):
    """Raise ``ValueError`` unless ``mode`` is known and ``wo`` is ``(len(params), 3)``."""
    _check_mode(mode)
    if wo.shape != (len(params), 3):
        raise ValueError(f"wo has shape {wo.shape}, expected ({len(params)}, 3)")


def eval_bsdf(params, wo, wi, mode=RADIANCE):
    """``f(wo, wi) |cos theta_i|`` of the non-delta lobes.

    Parameters
    ----------
    params : BSDFParams
        ``k`` rows.
    wo, wi : (k, 3) float
        Unit local directions.
    mode : {'radiance', 'importance'}

    Returns
    -------
    (k, 3) float64, >= 0 and finite.
    """
    wo, wi = np.asarray(wo, np.float64), np.asarray(wi, np.float64)
    check_rows(params, wo, mode)
    out = _eval_below_sheen(params, wo, wi, mode)
    rows = sheen.sheen_rows(params)
    if rows.size:
        p = params.take(rows)
        out[rows] = sheen.eval_sheened(p, wo[rows], wi[rows], out[rows], mode)
        if p.bump_normal is not None:
            # The sheen is a diffuse closure in Cycles: its lobe gets the correction too.
            lobe = sheen.eval_sheened(p, wo[rows], wi[rows], np.zeros((rows.size, 3)), mode)
            out[rows] = bump_correction.correct_sheen(p, wo[rows], wi[rows], mode,
                                                      out[rows], lobe)
    return out


def _eval_kinds(params, wo, wi, mode):
    """:func:`eval_bsdf` of the rows' own kinds, without coat, sheen or bump correction."""
    out = np.zeros((len(params), 3))
    for kind, rows in kind_groups(params):
        fn = FAMILIES[kind][0]
        if rows is None:
            out = fn(params, wo, wi, mode)
        else:
            out[rows] = fn(kind_rows(params, kind, rows), wo[rows], wi[rows], mode)
    return out


def _eval_below_sheen(params, wo, wi, mode):
    """:func:`eval_bsdf` of the coat over the (bump-corrected) kinds, without any sheen."""
    out = _eval_kinds(params, wo, wi, mode)
    if params.bump_normal is not None:
        out = bump_correction.correct_eval(params, wo, wi, mode, out, _eval_kinds)
    coated = coat_rows(params)
    if coated.size:
        out[coated] = coat.eval_coated(params.take(coated), wo[coated], wi[coated],
                                       out[coated], mode)
    return out


def pdf_bsdf(params, wo, wi):
    """Solid-angle density of :func:`sample_bsdf`'s non-delta samples at ``wi``. ``(k,)``."""
    wo, wi = np.asarray(wo, np.float64), np.asarray(wi, np.float64)
    check_rows(params, wo)
    out = _pdf_below_sheen(params, wo, wi)
    rows = sheen.sheen_rows(params)
    if rows.size:
        out[rows] = sheen.pdf_sheened(params.take(rows), wo[rows], wi[rows], out[rows])
    return out


def _pdf_below_sheen(params, wo, wi):
    """:func:`pdf_bsdf` of the coat over the kinds, without any sheen."""
    out = np.zeros(len(params))
    for kind, rows in kind_groups(params):
        fn = FAMILIES[kind][1]
        if rows is None:
            out = fn(params, wo, wi)
        else:
            out[rows] = fn(kind_rows(params, kind, rows), wo[rows], wi[rows])
    coated = coat_rows(params)
    if coated.size:
        out[coated] = coat.pdf_coated(params.take(coated), wo[coated], wi[coated], out[coated])
    return out


def sample_bsdf(params, wo, u_lobe, u, mode=RADIANCE):
    """Sample ``wi`` for every row.

    Parameters
    ----------
    params : BSDFParams
    wo : (k, 3) float
    u_lobe : (k,) float in [0, 1)
    u : (k, 2) float in [0, 1)^2
    mode : {'radiance', 'importance'}

    Returns
    -------
    BSDFSample
        ``wi (k, 3)``, ``weight (k, 3)``, ``pdf (k,)``, ``delta (k,)``, ``lobe (k,)``.
    """
    wo = np.asarray(wo, np.float64)
    check_rows(params, wo, mode)
    u_lobe = np.asarray(u_lobe, np.float64).reshape(-1)
    u = np.asarray(u, np.float64)
    rows = sheen.sheen_rows(params)
    if rows.size:
        smp = BSDFSample(*sheen.sample_sheened(params, rows, wo, u_lobe, u, mode,
                                               _sample_below_sheen, eval_bsdf, pdf_bsdf))
    else:
        smp = _sample_below_sheen(params, wo, u_lobe, u, mode)
    return _bump_corrected_weight(params, wo, smp, mode)


def sample_plain_diffuse(params, wo, u, mode=RADIANCE):
    """:func:`sample_bsdf` of rows that are all plain diffuse (``KIND_DIFFUSE``, no optional
    group): the same sample, without the dispatch over kinds, layers and bump correction.

    A diffuse direction is drawn on ``wo``'s side of the surface (it never crosses it), so
    the lobe is a diffuse reflection wherever the density is positive, as
    :func:`_sample_bases` labels it.
    """
    wi, weight, pdf, delta = FAMILIES[KIND_DIFFUSE][2](params, wo, None, u, mode)
    lobe = np.where(pdf > 0.0, LOBE_REFLECT | LOBE_DIFFUSE, 0).astype(np.uint8)
    return BSDFSample(wi, weight, pdf, delta, lobe)


def pdf_plain_diffuse(params, wo, wi):
    """:func:`pdf_bsdf` of rows that are all plain diffuse (as :func:`sample_plain_diffuse`):
    ``(k,)``, the same values."""
    return FAMILIES[KIND_DIFFUSE][1](params, wo, wi)


def _bump_corrected_weight(params, wo, smp, mode):
    """``smp`` with the weight of bump-corrected rows' non-delta samples recomputed as
    ``eval_bsdf / pdf`` (the correction scales eval, not the pdf, as in Cycles)."""
    rows = bump_correction.bumped_rows(params)
    if rows.size:
        rows = rows[~smp.delta[rows] & (smp.pdf[rows] > 0.0)]
    if rows.size == 0:
        return smp
    f = eval_bsdf(params.take(rows), wo[rows], smp.wi[rows], mode)
    weight = smp.weight.copy()
    weight[rows] = f / smp.pdf[rows][:, None]
    return smp._replace(weight=weight)


def _sample_below_sheen(params, wo, u_lobe, u, mode):
    """:func:`sample_bsdf` of the coat over the kinds, ignoring any sheen."""
    coated = coat_rows(params)
    if coated.size:
        return BSDFSample(*coat.sample_coated(params, coated, wo, u_lobe, u, mode,
                                              _sample_bases, _eval_below_sheen,
                                              _pdf_below_sheen))
    return _sample_bases(params, wo, u_lobe, u, mode)


def _sample_bases(params, wo, u_lobe, u, mode):
    """:func:`sample_bsdf` of the rows' own kinds, ignoring any coat."""
    k = len(params)
    wi = np.zeros((k, 3))
    weight = np.zeros((k, 3))
    pdf = np.zeros(k)
    delta = np.zeros(k, bool)
    kind_bits = np.zeros(k, np.uint8)
    for kind, rows in kind_groups(params):
        sample, label = FAMILIES[kind][2:]
        if rows is None:
            wi, weight, pdf, delta = sample(params, wo, u_lobe, u, mode)
            kind_bits = label(params, wo, u_lobe, delta)
        else:
            p = kind_rows(params, kind, rows)
            wo_k, u_lobe_k = wo.take(rows, axis=0), u_lobe[rows]
            wi_k, weight_k, pdf[rows], delta[rows] = sample(p, wo_k, u_lobe_k,
                                                            u.take(rows, axis=0), mode)
            put_rows(wi, rows, wi_k)
            put_rows(weight, rows, weight_k)
            kind_bits[rows] = label(p, wo_k, u_lobe_k, delta[rows])
    side = np.where(crosses_surface(params, wo, wi), LOBE_TRANSMIT,
                    LOBE_REFLECT).astype(np.uint8)
    lobe = np.where(pdf > 0.0, side | kind_bits, 0).astype(np.uint8)
    return BSDFSample(wi, weight, pdf, np.asarray(delta, bool), lobe)


def crosses_surface(params, wo, wi):
    """Whether ``wi`` leaves on the other side of the surface than ``wo`` (a transmission):
    ``(k,)`` bool, from the sides of the local frame, except on layered rows with a base
    normal (:mod:`.layered`), reflections whose base lobe may dip below the bent frame, and on
    opaque rows with a coat normal (:mod:`.coat`), whose coat reflects around its own."""
    crossed = wi[:, 2] * wo[:, 2] < 0.0
    if params.base_normal is not None:
        crossed &= ~np.any(params.base_normal != 0.0, axis=1)
    if params.coat_normal is not None:
        opaque = (params.kind != KIND_DIELECTRIC) & (params.kind != KIND_DIELECTRIC_MS)
        crossed &= ~(opaque & np.any(params.coat_normal != 0.0, axis=1))
    return crossed


def is_delta_only(params):
    """Rows whose BSDF is a pure delta distribution (``eval`` and ``pdf`` always zero). ``(k,)``."""
    conductor_rows = (params.kind == KIND_CONDUCTOR) | (params.kind == KIND_CONDUCTOR_MS)
    smooth_conductor = conductor_rows & is_smooth(params.alpha)
    dielectric_rows = (params.kind == KIND_DIELECTRIC) | (params.kind == KIND_DIELECTRIC_MS)
    smooth_dielectric = dielectric_rows & is_smooth_dielectric(params.eta, params.alpha)
    delta_only = smooth_conductor | smooth_dielectric
    coated = coat_rows(params)
    if coated.size:
        delta_only[coated] &= is_smooth(params.coat_alpha[coated])
    delta_only[sheen.sheen_rows(params)] = False
    return delta_only
