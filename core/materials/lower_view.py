"""Shading from below the shading normal: what Cycles' closures do where the viewer sees the
front of the geometry but the back of a smooth or normal-mapped shading normal (near the
silhouettes of smooth faces).

Cycles (Blender 5.0) keeps the shading normal there, closure by closure
(``kernel/closure/bsdf_diffuse.h``, ``bsdf_microfacet.h``, ``svm/closure.h``; behaviour
matched, the code is ours; see ``docs/SHADING_NORMALS.md``):

- a diffuse closure ignores the view: ``f cos = albedo max(N . wi, 0) / pi``;
- a microfacet closure whose normal the view falls below (``cos_NI <= 0``) evaluates and
  samples nothing (unless Bump Map Correction bent its normal first; the integrators bend the
  frame of such rows before this rule applies);
- the Principled BSDF's diffuse base under its specular layer is attenuated by the layer's
  albedo estimate, read from tables whose cosine axis is clamped to [0, 1]: at ``cos = 0``.

Here a row whose view lies below its frame's +Z is shaded by a Lambert BSDF around that normal
(the view mirrored through the tangent plane, which a Lambert lobe does not see): the diffuse
kind with its own albedo, a layered (Principled) row with its base albedo times
``1 - max_c E_t(0)`` (:func:`.layered.specular_albedo` at grazing), and conductors and
dielectrics with albedo 0. Each is an ordinary Lambert lobe, so sampling, evaluation and pdf
stay consistent. A Transparent BSDF (a smooth dielectric of index 1, which passes light
straight through whatever its normal, as Cycles' transparent closure) is left as it is.

A Coat on such a row is a microfacet closure too: its lobe gives nothing, but it still
attenuates what lies below it, by Cycles' estimate of its albedo (its table read at the
cosine clamped to 0: the grazing albedo) and its tint at ``|cos|`` (the tint's path length
depends on ``cos^2``): the row's Lambert colour is multiplied by
:func:`.coat.coat_attenuation` at the real view's (negative) cosine with the coat's normal and
its coat weight set to zero. A coat with its own normal (the smooth one
under a normal map) that the real view lies above keeps its lobe and attenuation, judged at
the real view (``coat_flip``, :mod:`.coat`), as Cycles' coat closure does. A Sheen keeps its lobe, as Cycles' does (its
tables are read at ``cos = 0`` there, ours at the mirrored view's ``|cos|``, small near a
silhouette).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .coat import coat_attenuation
from .families import KIND_DIELECTRIC, KIND_DIFFUSE, KIND_LAYERED, KIND_LAYERED_MS
from .layered import specular_albedo
from .microfacet import is_smooth


def view_below(cos_g, cos_s):
    """Rows whose view lies on one side of the geometric normal and on the other side of, or
    in the plane of, the shading normal: ``(k,)`` bool from the view's cosines with the two,
    ``cos_g, cos_s (k,)`` (False where the view grazes the geometry)."""
    return (cos_g != 0.0) & (cos_g * cos_s <= 0.0)


def lower_view_params(params, wo, below):
    """``(params, wo)`` with the rows ``below (k,)`` shaded as seen from below their normal.

    Parameters
    ----------
    params : core.materials.bsdf.BSDFParams
    wo : (k, 3) float64
        Local view directions (frame +Z = the shading normal on the stored front side).
    below : (k,) bool
        Rows to change (:func:`view_below`).

    Returns
    -------
    params : BSDFParams
        Rows ``below`` turned into Lambert rows (module docstring); the others unchanged.
    wo : (k, 3) float64
        ``wo`` mirrored through the tangent plane on the rows ``below`` (a copy).
    """
    below = shaded_below(params, below)
    if not below.any():
        return params, wo
    wo = wo.copy()
    wo[below, 2] = -wo[below, 2]
    scale = np.zeros(below.size)
    scale[params.kind == KIND_DIFFUSE] = 1.0
    for kind, ms in ((KIND_LAYERED, False), (KIND_LAYERED_MS, True)):
        rows = np.nonzero(below & (params.kind == kind))[0]
        if rows.size:
            grazing = specular_albedo(np.zeros(rows.size), params.alpha[rows],
                                      params.eta[rows], params.tint[rows], ms)
            scale[rows] = np.maximum(0.0, 1.0 - grazing.max(axis=1))
    color = np.where(below[:, None], params.color * scale[:, None], params.color)
    kind = np.where(below, KIND_DIFFUSE, params.kind).astype(params.kind.dtype)
    params = replace(params, kind=kind, color=color)
    return _coat_below(params, wo, below), wo


def _coat_below(params, wo, below):
    """``params`` whose coated rows ``below`` lose the coat's lobe but keep its attenuation,
    folded into their colour (module docstring)."""
    if not params.has_coat:
        return params
    params = _coat_sees_the_view(params, wo, below)
    kept = np.zeros(below.size, bool) if params.coat_flip is None else params.coat_flip != 0.0
    rows = np.nonzero(below & ~kept & (params.coat_weight > 0.0))[0]
    if rows.size == 0:
        return params
    color = params.color.copy()
    color[rows] *= coat_attenuation(params.coat_weight[rows], params.coat_eta[rows],
                                    params.coat_tint[rows], _real_view_cos(params, wo, rows),
                                    params.coat_alpha[rows])
    weight = params.coat_weight.copy()
    weight[rows] = 0.0
    return replace(params, color=color, coat_weight=weight)


def _real_view_cos(params, wo, rows):
    """Cosine ``(j,)`` of the real view (``wo`` mirrored back) with the coat's normal on
    ``rows``: the row's +Z, or its own ``coat_normal`` where it has one; negative (the view
    is below it), so :func:`.coat.coat_attenuation` reads its albedo at grazing."""
    real = wo[rows] * np.array([1.0, 1.0, -1.0])
    n = np.zeros((rows.size, 3)) if params.coat_normal is None else params.coat_normal[rows]
    n = np.where(np.any(n != 0.0, axis=1)[:, None], n, np.array([0.0, 0.0, 1.0]))
    return np.sum(real * n, axis=1)


def _coat_sees_the_view(params, wo, below):
    """``params`` with ``coat_flip`` 1 on the coated rows ``below`` whose own coat normal
    (:mod:`.coat`) the real view (``wo`` mirrored back) lies above: their coat keeps its lobe
    and attenuation there, as Cycles' coat closure around its own normal."""
    n = params.coat_normal
    if n is None:
        return params
    seen = below & (params.coat_weight > 0.0) & np.any(n != 0.0, axis=1)
    seen &= wo[:, 0] * n[:, 0] + wo[:, 1] * n[:, 1] - wo[:, 2] * n[:, 2] > 0.0
    if not seen.any():
        return params
    return replace(params, coat_flip=np.where(seen, 1.0, params.coat_flip))


def shaded_below(params, below):
    """The rows of ``below (k,)`` that :func:`lower_view_params` changes: all but a
    Transparent BSDF's. ``(k,)`` bool."""
    return below & ~_pass_through(params)


def _pass_through(params):
    """Rows of a Transparent BSDF (smooth dielectric of index 1): ``(k,)`` bool."""
    return (params.kind == KIND_DIELECTRIC) & (params.eta == 1.0) & is_smooth(params.alpha)
