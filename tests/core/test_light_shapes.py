"""Ray tests of the area lamp's shape (``core.lights.shapes``): the in-plane coordinates of a
sheared lamp, and which rays its hit test (the MIS of BSDF rays that find the lamp) accepts."""

import numpy as np
import pytest

from sampling_lab.core.lights.shapes import dual_basis, ray_parallelogram

AXIS_X = np.array([0.8, 0.1, -0.2])
AXIS_Y = np.array([0.5, 0.6, 0.3])  # sheared: not orthogonal to AXIS_X, another length


def test_dual_basis_gives_in_plane_coordinates():
    rng = np.random.default_rng(3)
    xy = rng.uniform(-2, 2, (1000, 2))
    p = xy[:, :1] * AXIS_X + xy[:, 1:] * AXIS_Y
    dx, dy = dual_basis(AXIS_X, AXIS_Y)
    np.testing.assert_allclose(p @ dx, xy[:, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(p @ dy, xy[:, 1], rtol=0, atol=1e-12)


def test_dual_basis_of_parallel_or_zero_axes_is_none():
    assert dual_basis(AXIS_X, 2 * AXIS_X) is None
    assert dual_basis(np.zeros(3), AXIS_Y) is None


@pytest.mark.parametrize("disk", [False, True])
def test_ray_parallelogram_hits_exactly_the_points_inside_a_sheared_lamp(disk):
    # Rays from below aimed at known in-plane coordinates; points within 1e-6 of the border
    # are left out (either answer is right there). Projecting on the axes instead of the dual
    # basis misclassifies 27 % (rectangle) and 31 % (disk) of these rays.
    rng = np.random.default_rng(4)
    n = 4000
    position = np.array([0.3, -0.2, 1.5])
    normal = np.cross(AXIS_X, AXIS_Y)
    normal /= np.linalg.norm(normal)
    xy = rng.uniform(-0.75, 0.75, (n, 2))
    inside = (xy ** 2).sum(axis=1) <= 0.25 if disk else np.all(np.abs(xy) <= 0.5, axis=1)
    border = (np.abs(np.sqrt((xy ** 2).sum(axis=1)) - 0.5) if disk
              else np.abs(np.abs(xy) - 0.5).min(axis=1))
    keep = border > 1e-6
    xy, inside = xy[keep], inside[keep]
    target = position + xy[:, :1] * AXIS_X + xy[:, 1:] * AXIS_Y
    origin = target + normal * rng.uniform(1.0, 3.0, (xy.shape[0], 1)) \
        + rng.normal(0, 0.1, (xy.shape[0], 3))
    d = target - origin
    dist = np.linalg.norm(d, axis=1)
    d /= dist[:, None]
    rows, t, _, q = ray_parallelogram(origin, d, position, normal, AXIS_X, AXIS_Y,
                                      np.full(xy.shape[0], np.inf), disk)
    assert inside.any() and not inside.all()
    np.testing.assert_array_equal(rows, np.nonzero(inside)[0])
    np.testing.assert_allclose(q, target[rows], atol=1e-9)
    np.testing.assert_allclose(t[rows], dist[rows], rtol=1e-12)


def test_dot_vector_is_the_row_dot_product_with_one_vector_from_either_end():
    from sampling_lab.core.lights.shapes import dot_vector

    rng = np.random.default_rng(4)
    a, v, origin = rng.normal(size=(1000, 3)) * 1e3, rng.normal(size=3), rng.normal(size=3)
    np.testing.assert_allclose(dot_vector(a, v), np.einsum("ij,j->i", a, v), rtol=1e-12)
    np.testing.assert_allclose(dot_vector(a, v, origin), np.einsum("ij,j->i", origin - a, v),
                               rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(dot_vector(a, v, origin, negate=False),
                               np.einsum("ij,j->i", a - origin, v), rtol=1e-12, atol=1e-9)
