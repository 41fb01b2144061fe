"""Radiosity form factors (core/radiosity/form_factors.py) against closed forms, reciprocity and
row sums; the patch mesh's lookups.

Every tolerance is stated: agreement with a closed form within 1 %, where the test also
requires the Monte Carlo standard error to be small enough (z * se below 1 %, z for a false
failure probability of 1e-4) that a 1 % error would show. Form factors of unoccluded pairs are
unbiased estimates, so the only error is that of the stratified points on the emitting patch;
its standard error is computed as if the points were independent, which overstates the error of
stratified points (a conservative bound).
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core.radiosity import form_factors as ff
from sampling_lab.core.radiosity.mesh import build_mesh, grid_triangles, local_index
from tests.core.radiosity_scenes import (cube_room, disk, facing, polygon_scene, prepared,
                                         rectangle)
from sampling_lab.core.metrics import student_t_quantile
from tests.helpers import assert_mean_within_ci, z_for_false_failure

SAMPLES = 16


def parallel_rectangles(a, b, c):
    """Closed form: coaxial parallel a x b rectangles at distance c (Howell C-11)."""
    x, y = a / c, b / c
    return 2 / (np.pi * x * y) * (
        np.log(np.sqrt((1 + x * x) * (1 + y * y) / (1 + x * x + y * y)))
        + x * np.sqrt(1 + y * y) * np.arctan(x / np.sqrt(1 + y * y))
        + y * np.sqrt(1 + x * x) * np.arctan(y / np.sqrt(1 + x * x))
        - x * np.arctan(x) - y * np.arctan(y))


def perpendicular_rectangles(w, h, l):
    """Closed form: from a w x l rectangle to an h x l one sharing the edge l, at right angles
    (Howell C-14)."""
    W, H = w / l, h / l
    s = H * H + W * W
    log = np.log((1 + W * W) * (1 + H * H) / (1 + s)
                 * (W * W * (1 + s) / ((1 + W * W) * s)) ** (W * W)
                 * (H * H * (1 + s) / ((1 + H * H) * s)) ** (H * H))
    return (W * np.arctan(1 / W) + H * np.arctan(1 / H) - np.sqrt(s) * np.arctan(1 / np.sqrt(s))
            + log / 4) / (np.pi * W)


def coaxial_disks(r1, r2, L):
    """Closed form: between coaxial parallel disks of radii r1 (from) and r2 at distance L."""
    R1, R2 = r1 / L, r2 / L
    X = 1 + (1 + R2 * R2) / (R1 * R1)
    return 0.5 * (X - np.sqrt(X * X - 4 * (R2 / R1) ** 2))


def surface_form_factor(polygons, patch_size, samples=64):
    """F from polygon 0 to polygon 1 summed over their patches, and its standard error."""
    scene = polygon_scene(polygons)
    prep = prepared(scene)
    mesh = build_mesh(prep, patch_size)
    owner = np.repeat(np.arange(len(polygons)), [len(p) - 2 for p in polygons])
    surface = owner[mesh.sub_tri[np.arange(mesh.n_patches) // 2]]
    i = np.nonzero(surface == 0)[0]
    j = np.nonzero(surface == 1)[0]
    ii, jj = np.repeat(i, j.size), np.tile(j, i.size)
    ok = ff.facing(mesh, ii, jj, ff.plane_eps(mesh))
    F, se = ff.pair_form_factors(mesh, prep.accel, ii[ok], jj[ok], samples, seed=3)
    area = mesh.area
    total_area = area[i].sum() / 2  # both sides of every patch of surface 0
    weight = area[ii[ok]] / total_area
    return float(np.sum(weight * F)), float(np.sqrt(np.sum((weight * se) ** 2)))


def _check(value, se, exact):
    z = z_for_false_failure(1e-4)
    # The test can see a 1 % error: its Monte Carlo uncertainty is well below it.
    assert z * se < 0.01 * exact, (value, se)
    assert abs(value - exact) <= 0.01 * exact, (value, exact, se)


def test_parallel_coaxial_squares_match_the_closed_form():
    a, c = 1.0, 1.0
    low = facing(rectangle((0, 0, 0), (a, 0, 0), (0, a, 0)), (0.5, 0.5, 1))
    high = facing(rectangle((0, 0, c), (a, 0, 0), (0, a, 0)), (0.5, 0.5, 0))
    value, se = surface_form_factor([low, high], 0.25)
    _check(value, se, parallel_rectangles(a, a, c))


def test_perpendicular_rectangles_sharing_an_edge_match_the_closed_form():
    w, h, l = 1.0, 2.0, 1.5
    floor = facing(rectangle((0, 0, 0), (w, 0, 0), (0, l, 0)), (0.5, 0.5, 1))
    wall = facing(rectangle((0, 0, 0), (0, l, 0), (0, 0, h)), (1, 0.5, 0.5))
    value, se = surface_form_factor([floor, wall], 0.25)
    _check(value, se, perpendicular_rectangles(w, h, l))


def test_coaxial_disks_match_the_closed_form():
    r1, r2, L = 0.5, 0.8, 1.0
    # One patch per fan triangle (slivers from the centre to the rim).
    value, se = surface_form_factor([disk((0, 0, 0), r1, 1.0, 48), disk((0, 0, L), r2, -1.0, 48)],
                                    10.0)
    _check(value, se, coaxial_disks(r1, r2, L))


def test_the_closed_forms_themselves_check_out():
    # Tabulated values: unit squares at unit distance 0.1998; perpendicular unit squares 0.2000;
    # unit disks... and the limits (far apart -> 0).
    assert parallel_rectangles(1, 1, 1) == pytest.approx(0.19982, abs=1e-4)
    assert perpendicular_rectangles(1, 1, 1) == pytest.approx(0.20004, abs=1e-4)
    assert coaxial_disks(1, 1, 1) == pytest.approx(0.38197, abs=1e-4)


def test_point_polygon_form_factor_of_a_hemisphere_covering_square_tends_to_one():
    x, n = np.zeros((1, 3)), np.array([[0, 0, 1.0]])
    big = rectangle((-1e4, -1e4, 1.0), (2e4, 0, 0), (0, 2e4, 0))[None]
    assert ff.point_polygon_form_factor(x, n, big)[0] == pytest.approx(1.0, abs=1e-3)


def test_clipping_keeps_only_the_part_in_front_of_the_plane():
    tri = np.array([[[0, 0, -1.0], [1, 0, 1.0], [-1, 0, 1.0]]])
    poly = ff.clip_to_plane(tri, np.zeros((1, 3)), np.array([[0, 0, 1.0]]))
    assert (poly[0, :, 2] >= -1e-12).all()
    # The triangle (area 2) loses the corner below z = 0 (area 1/2): a trapezoid of area 3/2.
    area = 0.5 * np.linalg.norm(np.cross(poly[0, 1] - poly[0, 0], poly[0, 2] - poly[0, 0])) \
        + 0.5 * np.linalg.norm(np.cross(poly[0, 2] - poly[0, 0], poly[0, 3] - poly[0, 0]))
    assert area == pytest.approx(1.5)


@pytest.fixture(scope="module")
def room():
    prep = prepared(cube_room(2.0))
    mesh = build_mesh(prep, 1.5)
    return prep, mesh


REPLICATES = 40


@pytest.fixture(scope="module")
def replicates(room):
    """Form-factor matrices of the room with independent seeds: their spread is the honest
    standard error of the stratified estimate."""
    prep, mesh = room
    return np.stack([ff.form_factor_matrix(mesh, prep.accel, SAMPLES, seed=s)
                     for s in range(REPLICATES)])


def test_rows_of_a_closed_box_sum_to_one(room, replicates):
    sums = replicates.sum(axis=2)
    inside = sums[0] > 0  # the inner sides; the outer ones see nothing
    assert inside.sum() == room[1].n_patches // 2
    _, se = assert_mean_within_ci(sums[:, inside], 1.0, what="row sum")
    # Power: each row would show a 2 % leak or excess.
    q = -student_t_quantile(0.5e-4 / inside.sum(), REPLICATES - 1)
    assert (q * se < 0.02).all(), se.max()


def test_form_factors_are_reciprocal_between_the_walls_of_a_box(room, replicates):
    area = room[1].area
    flow = area[None, :, None] * replicates
    diff = flow - flow.transpose(0, 2, 1)
    pairs = np.triu(flow.mean(axis=0) > 0, 1)
    _, se = assert_mean_within_ci(diff[:, pairs], 0.0, what="A_i F_ij - A_j F_ji")
    # Power: a 5 % non-reciprocity of the larger flows between patches apart would show, and
    # 15 % between patches that share an edge or a corner (their integrand peaks there).
    q = -student_t_quantile(0.5e-4 / pairs.sum(), REPLICATES - 1)
    mean = flow.mean(axis=0)[pairs]
    big = mean > 0.1 * mean.max()
    corners = room[1].patch_corners(np.arange(room[1].n_patches))
    i, j = np.nonzero(pairs)
    gap = np.linalg.norm(corners[i][:, :, None] - corners[j][:, None], axis=3).min(axis=(1, 2))
    touching = gap < 1e-9
    target = np.where(touching, 0.15, 0.05)
    assert (q * se[big] < target[big] * mean[big]).all()


def test_a_column_is_the_same_numbers_as_the_matrix(room):
    prep, mesh = room
    F = ff.form_factor_matrix(mesh, prep.accel, SAMPLES, seed=2)
    for col in (1, 7, mesh.n_patches - 1):
        assert np.array_equal(ff.form_factor_column(mesh, prep.accel, col, SAMPLES, 2),
                              F[:, col])


def test_an_occluder_between_two_squares_blocks_their_exchange():
    low = facing(rectangle((0, 0, 0), (1, 0, 0), (0, 1, 0)), (0.5, 0.5, 1))
    high = facing(rectangle((0, 0, 2), (1, 0, 0), (0, 1, 0)), (0.5, 0.5, 0))
    blocker = rectangle((-5, -5, 1), (10, 0, 0), (0, 10, 0))
    value, _ = surface_form_factor([low, high, blocker], 0.5)
    assert value == 0.0


def test_locate_finds_the_sub_triangle_that_contains_the_hit():
    prep = prepared(polygon_scene([rectangle((0, 0, 0), (1, 0, 0), (0, 1, 0))]))
    mesh = build_mesh(prep, 0.2)
    rng = np.random.default_rng(1)
    u, v = rng.random((2, 2000))
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    prim = rng.integers(0, 2, 2000)
    patch, w = mesh.locate(prim, u, v, np.zeros(2000, bool))
    point = prep.tri_v0[prim] + u[:, None] * prep.tri_e1[prim] + v[:, None] * prep.tri_e2[prim]
    corners = mesh.patch_corners(patch)
    assert np.allclose(np.einsum("kc,kci->ki", w, corners), point)
    assert (w >= 0).all() and np.allclose(w.sum(axis=1), 1)
    assert (mesh.sub_tri[patch // 2] == prim).all()


def test_grid_numbering_matches_the_closed_form_index():
    for n in (1, 2, 5):
        grid = grid_triangles(n)
        i, j = grid.min(axis=1).T
        down = grid[:, 0, 0] > grid[:, 1, 0]
        assert np.array_equal(local_index(i, j, down, np.full(n * n, n)), np.arange(n * n))


def test_gouraud_corners_of_a_constant_field_are_that_constant(room):
    _, mesh = room
    values = np.ones((mesh.n_patches, 3)) * 2.5
    assert np.allclose(mesh.corner_values(values), 2.5)


def test_a_mesh_too_large_for_the_solver_is_refused_with_a_clear_message(room):
    prep, _ = room
    with pytest.raises(ValueError, match="raise the patch size or choose the Progressive"):
        build_mesh(prep, 0.01, max_patches=10_000)
