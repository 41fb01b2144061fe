"""One radiosity solve of a prepared scene: mesh, sources, form factors, solver.

:func:`solve_scene` is what the radiosity integrator runs once per render. It meshes the
scene (:mod:`.mesh`), shoots the lamps and the world onto the patches (:mod:`.sources`), and
solves ``B = E + rho F B`` with the chosen solver (:mod:`.solvers`, :mod:`.hierarchical`):
Jacobi and Gauss-Seidel on a dense form-factor matrix (refused above
:data:`MAX_DENSE_PATCHES`), progressive refinement on columns computed on demand, hierarchical
radiosity on links between elements of a patch hierarchy.

The result is biased, and not consistent unless the mesh refines: radiosity is constant per
patch (or interpolated), form factors under partial occlusion are approximations, and the
noise of the Monte Carlo form factors and lamp irradiance is frozen into the solution.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import RenderRefused
from . import adaptive
from . import form_factors as ff
from .mesh import build_mesh
from .solvers import SOLVERS, gauss_seidel, jacobi, southwell
from .sources import lamp_irradiance

# Jacobi and Gauss-Seidel store a dense float64 matrix: 8192^2 doubles are 512 MB.
MAX_DENSE_PATCHES = 8192
# Any solver: beyond this many patches the mesh itself (and per-patch tables) gets too large.
MAX_PATCHES = 4_000_000

BIAS_NOTE = ("radiosity is biased and not consistent unless the mesh refines: patches are "
             "constant (or interpolated), so error remains at any sample count")


@dataclass
class RadiosityParams:
    """Settings of one solve.

    Attributes
    ----------
    solver : str
        One of :data:`core.radiosity.solvers.SOLVERS`.
    patch_size : float
        Target patch edge length (Blender units).
    form_factor_samples : int
        Points per patch pair (form factors) and per patch (lamp irradiance).
    tolerance : float
        Relative residual at which a solver stops.
    epsilon : float
        Hierarchical radiosity's form-factor threshold: pairs whose estimated form factor is
        below it are linked as they are, others subdivided.
    adaptive : float
        Adaptive subdivision's threshold (:mod:`.adaptive`): split the patches whose relative
        radiosity gradient exceeds it and solve again (at most two rounds); 0 keeps the
        uniform mesh. Not with the hierarchical solver (its links already adapt).
    seed : int
    """

    solver: str = "gauss_seidel"
    patch_size: float = 0.25
    form_factor_samples: int = 16
    tolerance: float = 1e-4
    epsilon: float = 0.02
    adaptive: float = 0.0
    seed: int = 0


@dataclass
class RadiositySolution:
    """A solved scene.

    Attributes
    ----------
    mesh : core.radiosity.mesh.PatchMesh
    B : (p, 3) float64
        Radiosity per patch (W / m^2), emission included.
    emission : (p, 3) float64
        The patches' own emitted radiosity (``pi Le``).
    corner_B : (p, 3, 3) float64
        Gouraud corner radiosities (patch, corner, channel).
    stats : dict
    cancelled : bool
    """

    mesh: object
    B: np.ndarray
    emission: np.ndarray
    corner_B: np.ndarray
    stats: dict = field(default_factory=dict)
    cancelled: bool = False


def progress_check(progress, cancel, start, span, what):
    """``check(fraction)`` for a solver step: reports ``start + span * fraction`` of the solve
    and returns whether the render was cancelled."""
    def check(fraction):
        if progress is not None:
            progress(start + span * fraction, f"Radiosity: {what} {100 * fraction:.0f} %")
        return cancel is not None and bool(cancel())
    return check


def solve_scene(prep, params: RadiosityParams, progress=None, cancel=None, mesh=None):
    """Mesh ``prep``'s scene and solve its radiosity.

    Parameters
    ----------
    prep : core.prepare.PreparedScene
    params : RadiosityParams
    progress : callable(fraction, text) or None
    cancel : callable() -> bool or None
    mesh : PatchMesh or None
        A mesh to solve instead of meshing at ``params.patch_size`` (adaptive refinement).

    Returns
    -------
    RadiositySolution
    """
    if params.solver not in SOLVERS:
        raise ValueError(f"radiosity solver {params.solver!r} is not one of {', '.join(SOLVERS)}")
    if not (prep.tri_area > 0).any():
        return _nothing_to_solve(prep, params)
    if params.solver == "hierarchical":
        from .hierarchical import solve_hierarchical
        return solve_hierarchical(prep, params, progress, cancel)
    sol = _solve_mesh(prep, params, progress, cancel, mesh)
    limit = MAX_DENSE_PATCHES if params.solver in ("jacobi", "gauss_seidel") else MAX_PATCHES
    rounds = 0
    while params.adaptive > 0 and rounds < adaptive.ROUNDS and not sol.cancelled:
        finer = adaptive.refine(sol.mesh, sol.B, params.adaptive, limit)
        if finer is None:
            break
        rounds += 1
        sol = _solve_mesh(prep, params, progress, cancel, finer)
    sol.stats["radiosity_adaptive_rounds"] = rounds
    return sol


def _solve_mesh(prep, params, progress, cancel, mesh):
    """One solve of ``mesh`` (None: the uniform mesh at ``params.patch_size``)."""
    t0 = time.perf_counter()
    dense = params.solver in ("jacobi", "gauss_seidel")
    if mesh is None:
        mesh = build_mesh(prep, params.patch_size,
                          MAX_DENSE_PATCHES if dense else MAX_PATCHES)
    elif dense and mesh.n_patches > MAX_DENSE_PATCHES:
        raise RenderRefused(f"radiosity: {mesh.n_patches:,} patches are more than the "
                            f"{MAX_DENSE_PATCHES:,} a dense solver can hold")
    E, lamp_se = source_term(mesh, prep, params,
                             progress_check(progress, cancel, 0.0, 0.05, "lamps"))
    t_mesh = time.perf_counter()
    rho = mesh.albedo
    S, seed = params.form_factor_samples, params.seed
    stats = {"radiosity_patch_count": mesh.n_patches, "radiosity_solver": params.solver}
    if dense:
        F = ff.form_factor_matrix(mesh, prep.accel, S, seed,
                                  progress_check(progress, cancel, 0.0, 0.5, "form factors"))
        t_ff = time.perf_counter()
        if F is None:
            return _cancelled(mesh, E, stats)
        run = jacobi if params.solver == "jacobi" else gauss_seidel
        name = params.solver.replace("_", "-")
        sol = run(F, rho, E, params.tolerance,
                  check=progress_check(progress, cancel, 0.5, 0.5, name))
        stats["radiosity_matrix_mb"] = F.nbytes / 1e6
    else:
        t_ff = t_mesh
        sol = southwell(lambda i: ff.form_factor_column(mesh, prep.accel, i, S, seed),
                        mesh.area, rho, E, params.tolerance,
                        check=progress_check(progress, cancel, 0.0, 1.0, "progressive refinement"))
        stats["radiosity_unshot_start"] = sol.unshot[0] if sol.unshot else 0.0
    _check_converged(sol, E)
    t_end = time.perf_counter()
    stats.update({"radiosity_iterations": sol.iterations, "radiosity_residual": sol.residual,
                  "radiosity_mesh_s": t_mesh - t0, "radiosity_form_factor_s": t_ff - t_mesh,
                  "radiosity_solve_s": t_end - t_ff, "radiosity_lamp_se": float(lamp_se.max())
                  if lamp_se.size else 0.0, "radiosity_bias": BIAS_NOTE})
    return RadiositySolution(mesh, sol.B, mesh.emission, mesh.corner_values(sol.B), stats,
                             sol.cancelled)


# A residual this many times the largest source term means the iteration ran away.
DIVERGED = 1e6


def _check_converged(sol, E):
    """Refuse a solve that diverged: with a patch that reflects all it receives (albedo one)
    the sampled form factors, whose rows may sum past one, make ``rho F`` no contraction and
    the iteration grows without bound (Inf, then NaN, in the image)."""
    scale = max(float(np.abs(E).max()), 1e-30)
    if not (np.isfinite(sol.B).all() and sol.residual <= DIVERGED * scale):
        raise ValueError("radiosity: the solve diverged: a surface reflects all the light it "
                         "receives (a Base Color of 1, e.g. a white Glass or Metal that "
                         "radiosity treats as diffuse); lower its Base Color below 1")


def source_term(mesh, prep, params, check=None):
    """``E (p, 3)``: each patch's emission plus the reflected direct light of the lamps and the
    world, and the lamp part's standard error ``(p, 3)`` (``check`` as
    :func:`.sources.lamp_irradiance`'s)."""
    H, se = lamp_irradiance(mesh, prep, params.form_factor_samples, params.seed, check)
    return mesh.emission + mesh.albedo * H, mesh.albedo * se


def _nothing_to_solve(prep, params):
    """The solution of a scene without surfaces: no patches."""
    mesh = build_mesh(prep, params.patch_size)
    E = np.zeros((0, 3))
    stats = {"radiosity_patch_count": 0, "radiosity_solver": params.solver,
             "radiosity_iterations": 0, "radiosity_residual": 0.0, "radiosity_bias": BIAS_NOTE}
    return RadiositySolution(mesh, E, E, np.zeros((0, 3, 3)), stats)


def _cancelled(mesh, E, stats):
    return RadiositySolution(mesh, E, mesh.emission, mesh.corner_values(E), stats, True)
