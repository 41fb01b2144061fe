"""Lamps and the world as radiosity sources: the irradiance each patch receives from them
directly, shot once before the solve.

Lamps (point, spot, sun, area) and the world are not patches: they emit but do not reflect.
Each patch receives ``H_d = (1 / A) int_patch int L_i cos dw dA`` from them, estimated with
``samples`` stratified points per patch and one sample of every lamp per point (the light
families' own ``sample_li``, so every lamp kind is modelled as the path tracer models it; a
constant world by cosine-distributed directions), with a shadow ray. The reflected part
``rho H_d`` then joins the patches' own emission as the source term of the radiosity
system: the lamps' light is "shot" directly, and only its reflections travel through form
factors. The estimate is unbiased for the patch's mean irradiance; its noise stays in the
solution as a fixed error (it does not average out across pixels).
"""

from __future__ import annotations

import numpy as np

from ..lights.base import LiSamples
from ..lights.sampler import AREA, POINT, SUN, WORLD
from ..sampling.warps import (sample_cosine_hemisphere, sample_uniform_triangle,
                              to_world_around)
from ..scene import VIS_SHADOW
from .form_factors import RAYS_PER_BATCH, pair_uniforms, stratified_points


def lamp_families(lights):
    """``(family, local row)`` of every lamp and of the world, as NEE samples them."""
    kinds = lights.emitter_family[:lights.n_lights]
    out = [(lights.families[int(f)], li) for li, f in enumerate(kinds) if f in (POINT, SUN,
                                                                                    AREA)]
    if lights.has_world:
        out.append((lights.families[WORLD], 0))
    return out


def lamp_irradiance(mesh, prep, samples=8, seed=0, check=None):
    """Mean irradiance ``(p, 3)`` of every patch from the lamps and the world, and its standard
    error ``(p, 3)``.

    Parameters
    ----------
    mesh : core.radiosity.mesh.PatchMesh
    prep : core.prepare.PreparedScene
    samples : int
        Points per patch (one light sample of every lamp each).
    check : callable(fraction) -> bool or None
        Called between blocks of patches (about :data:`.form_factors.RAYS_PER_BATCH` rays
        each); True stops, leaving the rest zero.
    """
    p = mesh.n_patches
    sources = lamp_families(prep.lights)
    H, se = np.zeros((p, 3)), np.zeros((p, 3))
    if not sources or p == 0:
        return H, se
    step = max(1, RAYS_PER_BATCH // samples)
    for a in range(0, p, step):
        patch = np.arange(a, min(a + step, p))
        H[patch], se[patch] = _block(mesh, prep, patch, sources, samples, seed)
        if check is not None and check(min(a + step, p) / p):
            break
    return H, se


def _block(mesh, prep, patch, sources, samples, seed):
    """Irradiance and standard error ``(k, 3)`` of the patches ``patch (k,)``."""
    u = stratified_points(patch, patch, seed + 101, samples).reshape(-1, 2)
    x = np.einsum("nv,nvi->ni", sample_uniform_triangle(u),
                  np.repeat(mesh.patch_corners(patch), samples, axis=0))
    n = np.repeat(mesh.normal[patch], samples, axis=0)
    prim = np.repeat(mesh.sub_tri[patch // 2], samples)
    total = np.zeros((x.shape[0], 3))
    for k, (family, li) in enumerate(sources):
        u_light = np.stack([pair_uniforms(patch, patch, seed + 211 + k, samples, 0),
                            pair_uniforms(patch, patch, seed + 211 + k, samples, 1)],
                           axis=2).reshape(-1, 2)
        if family is prep.lights.families[WORLD] and family.dist is None:
            total += _constant_world(prep, family.color, x, n, prim, u_light)
        else:
            total += _one_lamp(prep, family, li, x, n, prim, u_light)
    per = total.reshape(patch.size, samples, 3)
    se = (per.std(axis=1, ddof=1) / np.sqrt(samples) if samples > 1
          else np.zeros((patch.size, 3)))
    return per.mean(axis=1), se


def _constant_world(prep, color, x, n, prim, u):
    """Irradiance estimates ``(k, 3)`` from a constant world: cosine-distributed directions,
    each worth ``pi L`` if it escapes (no noise where the sky is unobstructed; the light
    sampler's uniform sphere would waste half its samples below the horizon)."""
    wi = to_world_around(sample_cosine_hemisphere(u), n)
    o = prep.accel.offset_origin(x, n, prim, wi)
    escaped = ~prep.accel.occluded(o, wi, np.full(x.shape[0], np.inf), VIS_SHADOW)
    return np.where(escaped[:, None], np.pi * np.asarray(color, np.float64)[None, :], 0.0)


def _one_lamp(prep, family, li, x, n, prim, u):
    """Irradiance estimates ``(k, 3)`` at points ``x`` with normals ``n`` from one lamp."""
    k = x.shape[0]
    out = LiSamples.empty(k)
    rows = np.arange(k)
    family.sample_li(rows, np.full(k, li, np.int64), x, u, np.ones(k), out)
    cos = np.einsum("ij,ij->i", out.wi, n)
    live = np.nonzero((out.pdf > 0) & (cos > 0))[0]
    value = np.zeros((k, 3))
    if live.size == 0:
        return value
    o, d, tmax = prep.accel.shadow_rays(x[live], n[live], prim[live], out.wi[live],
                                        out.dist[live], out.light_normal[live])
    seen = ~prep.accel.occluded(o, d, tmax, VIS_SHADOW)
    live = live[seen]
    value[live] = out.radiance[live] * (cos[live] / out.pdf[live])[:, None]
    return value
