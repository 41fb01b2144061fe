"""Finite-element radiosity, displayed by camera rays (or one final-gather bounce).

What it estimates
    The radiosity equation ``B = E + rho F B`` on patches of constant radiosity: the rendering
    equation restricted to diffuse reflection and discretised on a mesh (:mod:`core.radiosity`).
    The solve runs once per render, before the first work unit (:meth:`Radiosity.
    prepare_render`, with progress and cancel); camera rays then look the solution up.
Bias and consistency
    **Biased, and not consistent unless the mesh refines.** More samples per pixel only
    antialias the image of a fixed solution: the patches' constant (or interpolated)
    radiosity, the form factors' treatment of partial occlusion and the Monte Carlo noise of
    form factors and lamp irradiance are frozen into it. The error shrinks as the patch size
    shrinks (``tests/core/test_radiosity_convergence.py`` measures the rate against a long
    path-traced reference).
Display (``radiosity_display``)
    ``gouraud``: the reflected radiosity interpolated across each patch from its corners
    (area-weighted means of the patches sharing a corner and facing the same way); ``flat``:
    each patch's own value, the mesh shows; ``final_gather``: one bounce of path tracing into
    the solution, with next-event estimation for direct light, so shadows are as sharp as the
    path tracer's and only the indirect part comes from the patches. Emitters seen by camera
    rays (emissive surfaces, visible lamps, the world) are added exactly in every mode.
Film > Transparent
    The camera rays that escape give alpha 0 and do not add the world (which still lights
    the scene through the solve and, in ``final_gather``, next-event estimation): a pixel's
    alpha is the share of its camera samples that hit a surface, as the path tracer's where
    no transparent surface is in view. Radiosity renders every surface diffuse, transparent
    ones too (reported), so its camera rays stop at a Transparent BSDF or an Alpha sheet and
    the alpha behind one is 1 (the path tracer's passes through it).
Materials
    Every surface is diffuse with its Base Color as albedo: glossy, metal and glass materials,
    and image textures, are approximated this way and the render says so once.
Parameters
    ``radiosity_solver`` (Jacobi, Gauss-Seidel, progressive refinement, hierarchical),
    ``radiosity_patch_size``, ``radiosity_samples`` (form-factor and lamp samples),
    ``radiosity_adaptive`` (adaptive subdivision's threshold; not with hierarchical),
    ``radiosity_display``, ``radiosity_patches`` (the "Radiosity Patches" pass). The path
    tracer's bounce limit, Russian roulette and MIS settings do not apply.
When to use it
    Diffuse interiors where a solution is reused across views, and to see, in numbers, what an
    estimator that is neither unbiased nor consistent does (``docs/RADIOSITY.md``).
"""

from __future__ import annotations

import numpy as np

from ..radiosity.system import BIAS_NOTE, RadiosityParams, solve_scene
from ..sampling.mis import MIS
from ..sampling.warps import sample_cosine_hemisphere, to_world_around
from ..scene import MAT_DIFFUSE, VIS_CAMERA, VIS_DIFFUSE, VIS_SHADOW
from .base import BatchOutput, Integrator
from .common import (add_emitters_along_rays, camera_rays, intersect_by_class, surface_hits,
                     surface_interaction, take_rows)

PATCHES_PASS = "Radiosity Patches"
DISPLAYS = ("gouraud", "flat", "final_gather")

# Sample dimensions: 0-1 pixel filter, 2 light choice, 3-4 light point, 5-6 gather direction.
DIMS_LIGHT = 2
DIMS_GATHER = 5


def params_from_settings(settings):
    """The :class:`core.radiosity.system.RadiosityParams` of a render's settings."""
    return RadiosityParams(solver=settings.radiosity_solver,
                           patch_size=settings.radiosity_patch_size,
                           form_factor_samples=settings.radiosity_samples,
                           adaptive=(settings.radiosity_adaptive
                                     if settings.radiosity_solver != "hierarchical" else 0.0),
                           seed=settings.seed)


def approximation_messages(scene):
    """What radiosity approximates in ``scene``: non-diffuse materials, textures (one line)."""
    used = np.unique(scene.material)
    mats = scene.materials
    odd = [mats.names[m] if m < len(mats.names) else f"#{m}" for m in used
           if mats.kind[m] != MAT_DIFFUSE or mats.mixed[m]]
    messages = []
    if odd:
        messages.append(f"radiosity: {', '.join(odd)} treated as diffuse with the Base Color as "
                        f"albedo (radiosity models diffuse reflection only)")
    if scene.textures:
        messages.append("radiosity: image textures are ignored; each material's Base Color is "
                        "its albedo")
    return messages


class Radiosity(Integrator):
    """Radiosity solved once per render, shown by camera rays (see the module docstring)."""

    def __init__(self, prep, settings):
        super().__init__(prep, settings)
        self.params = params_from_settings(settings)
        self.display = settings.radiosity_display
        self.mis = MIS.from_settings(settings)
        self.solution = None
        self.reflected = None
        self.corner_reflected = None
        if settings.radiosity_patches:
            self.layers = (PATCHES_PASS,)

    # ------------------------------------------------------------------ the solve
    def prepare_render(self, progress=None, cancel=None):
        """Solve the radiosity system (once): returns whether ``cancel`` stopped it.

        The solution does not depend on the camera, so it is kept with the prepared scene:
        a render that reuses it (Persistent Data, the next viewport redraw) reuses the
        solution of the same parameters too."""
        if self.solution is None:
            cache = self.prep.__dict__.setdefault("radiosity_solutions", {})
            key = repr(self.params)
            sol = cache.get(key)
            if sol is None:
                sol = solve_scene(self.prep, self.params, progress, cancel)
                if not sol.cancelled:
                    cache[key] = sol
            self.solution = sol
            # Emission is added exactly along rays; what the patches carry is reflected light.
            self.reflected = np.maximum(sol.B - sol.emission, 0.0)
            self.corner_reflected = sol.mesh.corner_values(self.reflected)
        return self.solution.cancelled

    def messages(self):
        """Approximations, what was solved (Blender's stats line has no room for it), bias."""
        out = approximation_messages(self.prep.scene)
        st = self.solution.stats if self.solution is not None else {}
        if st:
            out.append(f"radiosity: {st.get('radiosity_patch_count', 0):,} patches, "
                       f"{st.get('radiosity_solver', '')}, "
                       f"{st.get('radiosity_iterations', 0)} sweeps or shots, residual "
                       f"{st.get('radiosity_residual', 0.0):.3g}")
        return out + [f"radiosity: {BIAS_NOTE}"]

    def stats(self):
        return dict(self.solution.stats) if self.solution is not None else {}

    # ------------------------------------------------------------------ lookups
    def radiosity_at(self, prim, u, v, back, smooth=True):
        """Reflected radiosity ``(k, 3)`` of hits ``prim, u, v (k,)`` on their ``back`` side."""
        mesh = self.solution.mesh
        patch, w = mesh.locate(prim, u, v, back)
        if not smooth:
            return self.reflected[patch]
        return np.einsum("kc,kcl->kl", w, self.corner_reflected[patch])

    def render_samples(self, stream, pixel_filter, counters):
        """Radiance per camera sample from the solved radiosity (finite, non-negative)."""
        if self.solution is None:
            self.prepare_render()
        prep = self.prep
        n = len(stream)
        counters.camera_samples += n
        L = np.zeros((n, 3))
        o, d, tmax = camera_rays(prep, pixel_filter, stream)
        hits = intersect_by_class(prep.accel, o, d, tmax, np.full(n, VIS_CAMERA, np.int32))
        counters.rays += n
        clear_film = prep.scene.film_transparent
        add_emitters_along_rays(prep, L, np.ones((n, 3)), o, d, hits, np.arange(n),
                                np.zeros(n), np.zeros(n, bool), True, self.mis,
                                world=not clear_film)
        # Film > Transparent: a camera ray that escapes reaches the background (alpha 0).
        clear = (~hits.hit).astype(np.float64) if clear_film else None
        live = surface_hits(prep, hits)
        layers = {}
        if self.layers:
            layers[PATCHES_PASS] = self._patch_colors(hits, d, live, n)
        if live.size == 0:
            return BatchOutput(L, camera_layers=layers, transparency=clear)
        back = np.einsum("ij,ij->i", d[live], prep.tri_normal[hits.prim[live]]) > 0
        if self.display == "final_gather":
            si = surface_interaction(prep, hits, d, live)
            L[live] += self._gather(si, stream, live, counters)
        else:
            B = self.radiosity_at(hits.prim[live], hits.u[live], hits.v[live], back,
                                  smooth=self.display == "gouraud")
            L[live] += B / np.pi
        return BatchOutput(np.nan_to_num(np.maximum(L, 0.0), nan=0.0, posinf=0.0),
                           camera_layers=layers, transparency=clear)

    def _patch_colors(self, hits, d, live, n):
        """The "Radiosity Patches" pass: a random colour per patch, dimmed by its radiosity."""
        out = np.zeros((n, 3))
        if live.size == 0:
            return out
        prim = hits.prim[live]
        back = np.einsum("ij,ij->i", d[live], self.prep.tri_normal[prim]) > 0
        patch, _ = self.solution.mesh.locate(prim, hits.u[live], hits.v[live], back)
        h = (patch // 2).astype(np.uint64) * np.uint64(2654435761) % np.uint64(1 << 24)
        rgb = np.stack([(h >> np.uint64(s)) & np.uint64(255) for s in (0, 8, 16)], axis=1)
        out[live] = 0.25 + 0.75 * rgb.astype(np.float64) / 255.0
        return out

    # ------------------------------------------------------------------ final gather
    def _gather(self, si, stream, live, counters):
        """One bounce at the camera hits ``si``: NEE of every emitter plus a cosine-sampled ray
        that reads the reflected radiosity where it lands. Returns ``(k, 3)`` radiance."""
        prep = self.prep
        stream.compact(live)
        stream.skip_to(DIMS_LIGHT)
        u_sel, u_light = stream.next_1d(), stream.next_2d()
        stream.skip_to(DIMS_GATHER)
        u_dir = stream.next_2d()
        albedo = take_rows(prep.tri_albedo, si.prim)
        out = self._direct(si, u_sel, u_light, counters)
        wi = to_world_around(sample_cosine_hemisphere(u_dir), si.ns)
        o = prep.accel.offset_origin(si.p, si.ng, si.prim, wi)
        hits = prep.accel.intersect(o, wi, None, VIS_DIFFUSE)
        counters.rays += o.shape[0]
        rows = surface_hits(prep, hits)
        if rows.size:
            back = np.einsum("ij,ij->i", wi[rows], prep.tri_normal[hits.prim[rows]]) > 0
            B = self.radiosity_at(hits.prim[rows], hits.u[rows], hits.v[rows], back)
            # Cosine sampling: f cos / pdf = albedo, and L = B / pi on a diffuse patch.
            out[rows] += albedo[rows] * B / np.pi
        return out

    def _direct(self, si, u_sel, u_light, counters):
        """Direct light by next-event estimation (every emitter), diffuse BSDF."""
        prep = self.prep
        wi, dist, radiance, pdf, _, light_n = prep.lights.sample(si.p, u_sel, u_light, counters)
        cos = np.einsum("ij,ij->i", wi, si.ns)
        ok = np.nonzero((pdf > 0) & (cos > 0))[0]
        out = np.zeros((si.p.shape[0], 3))
        if ok.size == 0:
            return out
        o, d, tmax = prep.accel.shadow_rays(si.p[ok], si.ng[ok], si.prim[ok], wi[ok], dist[ok],
                                            light_n[ok])
        counters.rays += ok.size
        seen = ok[~prep.accel.occluded(o, d, tmax, VIS_SHADOW)]
        albedo = take_rows(prep.tri_albedo, si.prim[seen])
        out[seen] = albedo / np.pi * radiance[seen] * (cos[seen] / pdf[seen])[:, None]
        return out
