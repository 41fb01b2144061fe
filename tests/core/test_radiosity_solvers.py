"""Radiosity solvers (core/radiosity/solvers.py, system.py): the furnace, lamps shot as sources,
agreement of every solver with the exact solution of the same system, progressive
refinement's monotone unshot power, cancel and progress, and the dense solvers' size limit.

"Solver tolerance" is a theorem, not a tuned number: with residual ``r`` and ``q`` the largest
row sum of ``rho F`` (< 1), ``|B - B*| <= max |r| / (1 - q)`` (``solvers.error_bound``).
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core import lights as L
from sampling_lab.core.prepare import prepare
from sampling_lab.core.radiosity import form_factors as ff
from sampling_lab.core.radiosity.mesh import build_mesh
from sampling_lab.core.radiosity.solvers import error_bound, gauss_seidel, jacobi, southwell
from sampling_lab.core.radiosity.sources import lamp_irradiance
from sampling_lab.core.radiosity.system import RadiosityParams, solve_scene, source_term
from sampling_lab.core.sampling.warps import spherical_triangle_solid_angle
from sampling_lab.core.scene import Lights, Materials, Scene
from tests.core.radiosity_scenes import cube_room, prepared
from tests.helpers import assert_mean_within_ci

DENSE = ("jacobi", "gauss_seidel")


@pytest.mark.parametrize("solver", ["jacobi", "gauss_seidel", "progressive"])
def test_furnace_radiosity_is_emission_over_one_minus_albedo(solver):
    rho, le = 0.5, 1.0
    prep = prepared(cube_room(2.0, albedo=rho, emission=le))
    params = RadiosityParams(solver=solver, patch_size=1.5, form_factor_samples=128, seed=1,
                             tolerance=1e-6)
    sol = solve_scene(prep, params)
    mesh = sol.mesh
    F = ff.form_factor_matrix(mesh, prep.accel, 128, seed=1)
    inside = F.sum(axis=1) > 0
    E = np.pi * le
    exact = E / (1 - rho)
    # B = (I - rho F)^-1 E differs from E / (1 - rho) only through the row sums' Monte Carlo
    # error eps (tested in test_radiosity_form_factors): |B - B*| <= rho B* max|eps| / (1 - q),
    # plus the solver's own bound.
    eps = np.abs(F.sum(axis=1)[inside] - 1).max()
    q = rho * F.sum(axis=1).max()
    tol = rho * exact * eps / (1 - q) + error_bound(F, mesh.albedo, sol.stats[
        "radiosity_residual"])
    assert tol < 0.01 * exact  # the check would see a 1 % error
    assert np.abs(sol.B[inside] - exact).max() <= tol
    # The outer sides see nothing: only their own emission.
    assert np.allclose(sol.B[~inside], E)


def _point_in_polyhedron(subdivisions=1, power=100.0):
    v, f = scenes.icosphere(subdivisions, 1.0)
    mats = Materials.from_lists(["Wall"], [(0.5,) * 3], [(0, 0, 0)])
    return Scene(v, f, np.zeros(len(f), np.int32), mats,
                 L.point_light((0, 0, 0), (1, 1, 1), power, radius=0.0), None)


def test_a_point_lamp_is_shot_as_its_intensity_times_each_patchs_solid_angle():
    prep = prepare(_point_in_polyhedron())
    mesh = build_mesh(prep, 10.0)
    inner = np.arange(mesh.n_patches)[1::2]  # the icosphere faces outward
    runs = np.stack([lamp_irradiance(mesh, prep, samples=8, seed=s)[0][inner, 0]
                     for s in range(12)])
    c = mesh.patch_corners(inner)
    omega = spherical_triangle_solid_angle(c[:, 0], c[:, 1], c[:, 2], np.zeros((inner.size, 3)))
    intensity = prep.scene.lights.radiance[0, 0]
    exact = intensity * omega / mesh.area[inner]
    assert_mean_within_ci(runs, exact, what="patch irradiance")
    outer = lamp_irradiance(mesh, prep, samples=8, seed=0)[0][0::2]
    assert (outer == 0).all()


@pytest.fixture(scope="module")
def box_system():
    prep = prepare(scenes.cornell_box(8, 8, "area"))
    params = RadiosityParams(patch_size=1.0, form_factor_samples=8, seed=4, tolerance=1e-6)
    mesh = build_mesh(prep, params.patch_size)
    F = ff.form_factor_matrix(mesh, prep.accel, 8, seed=4)
    E, _ = source_term(mesh, prep, params)
    rho = mesh.albedo
    exact = np.stack([np.linalg.solve(np.eye(len(F)) - rho[:, c, None] * F, E[:, c])
                      for c in range(3)], axis=1)
    return prep, params, mesh, F, E, exact


@pytest.mark.parametrize("solver", ["jacobi", "gauss_seidel", "progressive"])
def test_every_solver_agrees_with_the_exact_solution_within_its_bound(box_system, solver):
    prep, params, mesh, F, E, exact = box_system
    rho = mesh.albedo
    if solver == "jacobi":
        sol = jacobi(F, rho, E, tol=1e-6)
    elif solver == "gauss_seidel":
        sol = gauss_seidel(F, rho, E, tol=1e-6)
    else:
        sol = southwell(lambda i: F[:, i], mesh.area, rho, E, tol=1e-6)
    bound = error_bound(F, rho, sol.residual)
    assert bound < 1e-4 * exact.max()
    assert np.abs(sol.B - exact).max() <= bound
    # A solver stopped early is outside a tighter bound: the check can fail.
    early = jacobi(F, rho, E, tol=1e-1)
    assert np.abs(early.B - exact).max() > bound


def test_gauss_seidel_needs_fewer_sweeps_than_jacobi(box_system):
    _, _, mesh, F, E, _ = box_system
    assert (gauss_seidel(F, mesh.albedo, E, tol=1e-6).iterations
            < jacobi(F, mesh.albedo, E, tol=1e-6).iterations)


def test_progressive_refinement_without_a_matrix_gives_the_dense_solution(box_system):
    prep, params, mesh, F, E, exact = box_system
    sol = solve_scene(prep, RadiosityParams(**{**params.__dict__, "solver": "progressive",
                                               "tolerance": 1e-4}))
    assert np.abs(sol.B - exact).max() <= error_bound(F, mesh.albedo,
                                                      sol.stats["radiosity_residual"])


def test_progressive_unshot_power_decreases_monotonically():
    prep = prepared(cube_room(2.0, albedo=0.8, emission=1.0))
    mesh = build_mesh(prep, 1.0)
    F = ff.form_factor_matrix(mesh, prep.accel, 8, seed=2)
    rho, area, E = mesh.albedo, mesh.area, mesh.emission
    # Shooting i hands on sum_j rho_j A_j F_ji / A_i of its unshot power: below one here, so
    # every shot must lower the total.
    assert ((rho.max(axis=1)[:, None] * area[:, None] * F).sum(axis=0) < area).all()
    sol = southwell(lambda i: F[:, i], area, rho, E, tol=1e-6)
    assert len(sol.unshot) > 10
    assert (np.diff(sol.unshot) < 0).all()


@pytest.mark.parametrize("solver", ["gauss_seidel", "progressive"])
def test_a_cancelled_solve_stops_and_progress_is_reported(solver):
    prep = prepare(scenes.cornell_box(8, 8, "mesh"))
    calls = []

    def progress(fraction, text):
        calls.append((fraction, text))

    def cancel():
        return len(calls) >= 3

    sol = solve_scene(prep, RadiosityParams(solver=solver, patch_size=0.5), progress, cancel)
    assert sol.cancelled
    assert len(calls) == 3 and all(0 <= f <= 1 and "Radiosity" in t for f, t in calls)
    assert np.isfinite(sol.B).all()


@pytest.mark.parametrize("solver", DENSE)
def test_dense_solvers_refuse_meshes_beyond_their_memory(solver):
    prep = prepare(scenes.cornell_box(8, 8, "mesh"))
    with pytest.raises(ValueError, match="Progressive or Hierarchical"):
        solve_scene(prep, RadiosityParams(solver=solver, patch_size=0.02))


# ------------------------------------------------------------------ hierarchical radiosity
@pytest.fixture(scope="module")
def quadtree_system():
    prep = prepare(scenes.cornell_box(8, 8, "area"))
    params = RadiosityParams(solver="hierarchical", patch_size=1.0, form_factor_samples=4,
                             seed=4, tolerance=1e-6)
    mesh = build_mesh(prep, params.patch_size, power_of_two=True)
    F = ff.form_factor_matrix(mesh, prep.accel, 4, seed=4)
    E, _ = source_term(mesh, prep, params)
    exact = gauss_seidel(F, mesh.albedo, E, tol=1e-10).B
    return prep, params, mesh, F, exact


def test_quadtree_children_tile_their_parent_and_leaves_are_the_patches(quadtree_system):
    from sampling_lab.core.radiosity.hierarchical import build_elements

    prep, _, mesh, _, _ = quadtree_system
    el = build_elements(prep, mesh)
    inner = el.children[:, 0] >= 0
    assert np.allclose(el.area[el.children[inner]].sum(axis=1), el.area[inner])
    leaves = el.patch_sub >= 0
    assert np.allclose(el.corners[leaves], mesh.corners[el.patch_sub[leaves]])
    assert leaves.sum() == mesh.n_patches // 2
    assert (el.parent[el.children[inner]] == np.nonzero(inner)[0][:, None]).all()


def test_hierarchical_with_epsilon_zero_is_the_dense_system(quadtree_system):
    prep, params, mesh, F, exact = quadtree_system
    sol = solve_scene(prep, RadiosityParams(**{**params.__dict__, "epsilon": 0.0}))
    assert np.abs(sol.B - exact).max() <= error_bound(F, mesh.albedo,
                                                      sol.stats["radiosity_residual"])


def test_hierarchical_error_shrinks_with_epsilon_and_links_grow(quadtree_system):
    prep, params, mesh, F, exact = quadtree_system
    errors, links = [], []
    for eps in (0.1, 0.03, 0.01):
        sol = solve_scene(prep, RadiosityParams(**{**params.__dict__, "epsilon": eps}))
        errors.append(np.sqrt(np.mean((sol.B - exact) ** 2)))
        links.append(sol.stats["radiosity_links"])
    assert errors[0] > errors[1] > errors[2]
    assert links[0] < links[1] < links[2] < (mesh.n_patches ** 2) / 4


def test_a_diverged_solve_is_refused_with_its_cause_not_rendered_as_inf():
    """Gauss-Seidel on a 2-patch system whose rho F has row sums 1.2 (sampled form factors of an
    albedo-one surface can sum past one) grows without bound: the solve is refused with a
    message naming the cause; the same system at albedo 0.5 converges and passes."""
    from sampling_lab.core.radiosity.system import _check_converged

    F = np.array([[0.0, 1.2], [1.2, 0.0]])
    E = np.ones((2, 3))
    diverged = gauss_seidel(F, np.ones((2, 3)), E, tol=1e-4, max_iterations=200)
    with pytest.raises(ValueError, match="the solve diverged: a surface reflects all"):
        _check_converged(diverged, E)
    _check_converged(gauss_seidel(F, np.full((2, 3), 0.5), E, tol=1e-4), E)
