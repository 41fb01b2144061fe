"""Warps: samples follow their pdfs, pdfs integrate to one, inverses invert, frames are frames."""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core.sampling import warps as W
from tests.helpers import (
    chi_square_2d,
    chi_square_directions,
    chi_square_test,
    chi_square_uniform_square,
    integrate_density_2d,
    integrate_solid_angle,
)

N = 200_000
CONE_COS = [-0.7, 0.0, 0.5, 0.95, 0.9999]


def _cone_pdf(cos_max):
    """Solid-angle density of the cone warp as a function of direction (zero outside)."""
    return lambda w: np.where(w[:, 2] >= cos_max, W.uniform_cone_pdf(cos_max), 0.0)


def _disk_polar(p):
    """Disk points -> (r^2, phi): area density q(p) becomes q / 2 per d(r^2) d(phi)."""
    phi = np.arctan2(p[:, 1], p[:, 0])
    return np.stack([np.sum(p * p, axis=1), np.where(phi < 0, phi + 2 * np.pi, phi)], axis=-1)


def _disk_from_polar(q):
    r = np.sqrt(q[:, 0])
    return np.stack([r * np.cos(q[:, 1]), r * np.sin(q[:, 1])], axis=-1)


def _subtriangle_index(b, k):
    """Index of the sub-triangle holding barycentrics ``b (n, 3)`` in the k x k subdivision.

    The triangle (b1, b2 >= 0, b1 + b2 <= 1) splits into k^2 congruent sub-triangles of equal
    area: in grid cell (i, j) with i + j <= k - 1 a lower one, and an upper one if i + j <= k - 2.
    """
    x, y = b[:, 1] * k, b[:, 2] * k
    i = np.clip(np.floor(x).astype(np.int64), 0, k - 1)
    j = np.clip(np.floor(y).astype(np.int64), 0, k - 1)
    upper = (x - i) + (y - j) >= 1.0
    # Rounding can put a point of the last diagonal in a missing upper cell: keep it in the lower.
    upper &= i + j <= k - 2
    inside = i + j <= k - 1
    j = np.where(inside, j, k - 1 - i)
    cell = i * k + j
    return 2 * cell + upper.astype(np.int64)


def _subtriangle_probs(k):
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    lower = (i + j <= k - 1).astype(np.float64)
    upper = (i + j <= k - 2).astype(np.float64)
    return np.stack([lower, upper], axis=-1).reshape(-1) / (k * k)


# --------------------------------------------------------------------------------------------
# Samples follow their pdfs (chi-square)
# --------------------------------------------------------------------------------------------


def test_cosine_hemisphere_samples_match_pdf():
    chi_square_directions(W.sample_cosine_hemisphere, lambda w: W.cosine_hemisphere_pdf(w[:, 2]),
                          n=N, res=(20, 40), seed=1, what="cosine hemisphere")


def test_uniform_sphere_samples_match_pdf():
    chi_square_directions(W.sample_uniform_sphere, lambda w: W.uniform_sphere_pdf(len(w)),
                          n=N, res=(20, 40), seed=2, what="uniform sphere")


@pytest.mark.parametrize("cos_max", CONE_COS)
def test_uniform_cone_samples_match_pdf(cos_max):
    # Bins over the cone's own zone resolve even the narrowest cone.
    chi_square_directions(lambda u: W.sample_uniform_cone(u, cos_max), _cone_pdf(cos_max),
                          n=N, res=(16, 32), z_range=(cos_max, 1.0), seed=3,
                          what=f"cone cos_max={cos_max}")


def test_uniform_cone_samples_stay_in_cone_on_whole_sphere_bins():
    cos_max = 0.3
    chi_square_directions(lambda u: W.sample_uniform_cone(u, cos_max), _cone_pdf(cos_max),
                          n=N, res=(20, 24), seed=4, what="cone on sphere")


def test_uniform_cone_accepts_per_sample_cos_max():
    rng = np.random.default_rng(5)
    u = rng.random((1000, 2))
    cos_max = rng.uniform(-1, 1, 1000)
    batch = W.sample_uniform_cone(u, cos_max)
    picks = range(0, 1000, 97)
    one_by_one = np.stack([W.sample_uniform_cone(u[i:i + 1], cos_max[i])[0] for i in picks])
    np.testing.assert_allclose(batch[::97], one_by_one, rtol=0, atol=1e-15)
    assert np.all(batch[:, 2] >= cos_max - 1e-12)
    np.testing.assert_allclose(W.uniform_cone_pdf(cos_max), 1 / (2 * np.pi * (1 - cos_max)))


def test_concentric_disk_samples_match_area_pdf():
    rng = np.random.default_rng(6)
    p = W.sample_uniform_disk_concentric(rng.random((N, 2)))
    assert np.all(np.sum(p * p, axis=1) <= 1 + 1e-12)
    # d(area) = r dr dphi = d(r^2) dphi / 2: density per d(r^2) dphi is pdf / 2.
    chi_square_2d(_disk_polar(p), lambda q: 0.5 * W.uniform_disk_pdf(_disk_from_polar(q)),
                  ((0.0, 1.0), (0.0, 2 * np.pi)), res=(16, 32), what="concentric disk")


@pytest.mark.parametrize("k", [1, 2, 8])
def test_uniform_triangle_barycentrics_are_uniform_over_sub_triangles(k):
    rng = np.random.default_rng(7 + k)
    b = W.sample_uniform_triangle(rng.random((N, 2)))
    assert np.all(b >= -1e-15) and np.allclose(b.sum(axis=1), 1.0, atol=1e-15)
    chi_square_test(_subtriangle_index(b, k), _subtriangle_probs(k), what=f"triangle k={k}")


def test_uniform_triangle_barycentrics_are_the_select_on_each_side_of_the_diagonal_to_the_bit():
    # The maxima give the very values of the select on u0 < u1 they replaced (Heitz's map).
    rng = np.random.default_rng(11)
    u = rng.random((20000, 2))
    u[:50, 1] = u[:50, 0]  # on the diagonal
    u[50:60] = 0.0
    u[60:70, 0] = 0.0
    u[70:80, 1] = 0.0
    u[80:90] = np.nextafter(1.0, 0.0)
    u0, u1 = u[:, 0], u[:, 1]
    lower = u0 < u1
    b0 = np.where(lower, u0 * 0.5, u0 - u1 * 0.5)
    b1 = np.where(lower, u1 - u0 * 0.5, u1 * 0.5)
    got = W.uniform_triangle_barycentrics(u)
    for a, b in zip(got, (b0, b1, 1.0 - b0 - b1)):
        assert a.tobytes() == b.tobytes()


def test_direction_chi_square_rejects_a_mismatched_pdf():
    # Cosine-weighted samples against the uniform-hemisphere pdf: the checker must object.
    with pytest.raises(AssertionError, match="chi-square"):
        chi_square_directions(W.sample_cosine_hemisphere,
                              lambda w: np.where(w[:, 2] >= 0, 0.5 / np.pi, 0.0),
                              n=N, res=(20, 40), seed=1)
    # A 10 % tilt of the sphere's density is found too.
    with pytest.raises(AssertionError, match="chi-square"):
        chi_square_directions(W.sample_uniform_sphere,
                              lambda w: (1 + 0.1 * w[:, 2]) / (4 * np.pi),
                              n=N, res=(20, 40), seed=2)


def test_direction_chi_square_rejects_samples_outside_the_support():
    with pytest.raises(AssertionError, match="probability zero"):
        chi_square_directions(W.sample_uniform_sphere, _cone_pdf(-0.5), n=10_000, seed=3)


def test_direction_chi_square_rejects_a_wrongly_normalised_pdf():
    with pytest.raises(AssertionError, match="integrates to"):
        chi_square_directions(W.sample_cosine_hemisphere,
                              lambda w: 1.02 * W.cosine_hemisphere_pdf(w[:, 2]), n=10_000)


# --------------------------------------------------------------------------------------------
# Pdfs integrate to one
# --------------------------------------------------------------------------------------------


def test_cosine_hemisphere_pdf_integrates_to_one_over_the_sphere():
    total = integrate_solid_angle(lambda w: W.cosine_hemisphere_pdf(w[:, 2]), res=(512, 64))
    assert total == pytest.approx(1.0, abs=1e-9)


def test_uniform_sphere_pdf_integrates_to_one():
    total = integrate_solid_angle(lambda w: W.uniform_sphere_pdf(len(w)), res=(64, 64))
    assert total == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("cos_max", CONE_COS + [-1.0])
def test_uniform_cone_pdf_integrates_to_one_over_its_cone(cos_max):
    total = integrate_solid_angle(_cone_pdf(cos_max), z_range=(cos_max, 1.0), res=(64, 64))
    assert total == pytest.approx(1.0, abs=1e-9)


def test_uniform_cone_of_full_sphere_is_the_uniform_sphere():
    u = np.random.default_rng(8).random((1000, 2))
    np.testing.assert_allclose(W.sample_uniform_cone(u, -1.0), W.sample_uniform_sphere(u),
                               atol=1e-15)
    assert W.uniform_cone_pdf(-1.0) == pytest.approx(W.uniform_sphere_pdf(1)[0], rel=1e-15)
    assert W.uniform_cone_pdf(0.0) == pytest.approx(1 / (2 * np.pi), rel=1e-15)


def test_uniform_disk_pdf_integrates_to_one_over_the_disk():
    mass = integrate_density_2d(lambda q: 0.5 * W.uniform_disk_pdf(_disk_from_polar(q)),
                                ((0.0, 1.0), (0.0, 2 * np.pi)), (32, 32))
    assert mass.sum() == pytest.approx(1.0, abs=1e-12)


def test_uniform_triangle_pdf_integrates_to_one_over_the_triangle():
    # Map the unit square onto the triangle (the warp itself) and integrate pdf * |Jacobian|:
    # the Heitz map has a constant area Jacobian, so any point rule is exact up to rounding.
    p = np.array([[0.3, -1.0, 2.0], [4.0, 0.5, 1.0], [-1.0, 2.0, 0.0]])
    area = 0.5 * np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]))
    m = 64
    g = (np.arange(m) + 0.5) / m
    # Shift u1 by a quarter cell so no finite difference straddles the map's fold at u0 = u1.
    u = np.stack(np.meshgrid(g, g + 0.25 / m, indexing="ij"), axis=-1).reshape(-1, 2)
    h = 1e-6
    tri = W.sample_uniform_triangle
    b = tri(u)
    db_du0 = (tri(u + [h, 0]) - tri(u - [h, 0])) / (2 * h)
    db_du1 = (tri(u + [0, h]) - tri(u - [0, h])) / (2 * h)
    # Barycentric derivatives -> world-space tangents -> area element |dP/du0 x dP/du1|.
    jac = np.linalg.norm(np.cross(db_du0 @ p, db_du1 @ p), axis=1)
    assert np.all(b >= 0)
    total = np.sum(W.uniform_triangle_pdf(area) * jac) / (m * m)
    assert total == pytest.approx(1.0, abs=1e-6)


# --------------------------------------------------------------------------------------------
# Inverses: sample -> invert recovers u, and invert maps uniform points to uniform u
# --------------------------------------------------------------------------------------------


def _round_trip_u():
    rng = np.random.default_rng(9)
    edges = np.array([1e-9, 0.25, 0.5, 0.75, 1 - 1e-9])
    grid = np.stack(np.meshgrid(edges, edges, indexing="ij"), axis=-1).reshape(-1, 2)
    return np.concatenate([rng.random((20_000, 2)), grid])


# Warps through the concentric map, which is computed in float32: disk points within 1.5e-7
# of the exact map. A u off the samplers' 24-bit grid is rounded to float32 (6e-8 in the
# radius), which a cosine-weighted direction's z amplifies near the horizon (7e-6 at worst).
FLOAT32_WARPS = ("disk", "cosine_hemisphere")
FLOAT32_ATOL = 1e-5

ROUND_TRIPS = {
    "disk": (W.sample_uniform_disk_concentric, W.invert_uniform_disk_concentric),
    "cosine_hemisphere": (W.sample_cosine_hemisphere, W.invert_cosine_hemisphere_sample),
    "sphere": (W.sample_uniform_sphere, W.invert_uniform_sphere_sample),
    "cone_0.5": (lambda u: W.sample_uniform_cone(u, 0.5),
                 lambda w: W.invert_uniform_cone_sample(w, 0.5)),
    "cone_0.9999": (lambda u: W.sample_uniform_cone(u, 0.9999),
                    lambda w: W.invert_uniform_cone_sample(w, 0.9999)),
    "triangle": (W.sample_uniform_triangle, W.invert_uniform_triangle_sample),
}


@pytest.mark.parametrize("name", list(ROUND_TRIPS))
def test_sample_then_invert_recovers_u(name):
    sample, invert = ROUND_TRIPS[name]
    u = _round_trip_u()
    back = invert(sample(u))
    # The cone's 1 - cos_max amplifies rounding by 1 / (1 - cos_max); the concentric map
    # (disk, cosine hemisphere) runs in float32 (warps._concentric).
    atol = {"cone_0.9999": 1e-8, **dict.fromkeys(FLOAT32_WARPS, FLOAT32_ATOL)}.get(name, 1e-11)
    np.testing.assert_allclose(back, u, rtol=0, atol=atol, err_msg=name)


def _independent_uniform_points(name, rng, n):
    """Uniform points of each domain, drawn by a method unrelated to the warp under test."""
    if name == "disk":
        p = rng.uniform(-1, 1, (2 * n, 2))
        return p[np.sum(p * p, axis=1) < 1][:n]
    if name == "cosine_hemisphere":
        # Cosine-weighted by the polar method: r = sqrt(u1), phi = 2 pi u2, lifted to the sphere.
        u = rng.random((n, 2))
        r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
        return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - r * r)], axis=-1)
    if name.startswith(("sphere", "cone")):
        cos_max = -1.0 if name == "sphere" else float(name.split("_")[1])
        w = rng.normal(size=(n * 5, 3))
        w /= np.linalg.norm(w, axis=1, keepdims=True)
        if cos_max > 0.9:
            # Rejection would be wasteful for a narrow cone: uniform in z, uniform in phi.
            z = rng.uniform(cos_max, 1, n)
            phi = rng.uniform(0, 2 * np.pi, n)
            s = np.sqrt(1 - z * z)
            return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=-1)
        return w[w[:, 2] > cos_max][:n]
    if name == "triangle":
        # Sorted uniforms: the spacings of two uniform points are uniform barycentrics.
        s = np.sort(rng.random((n, 2)), axis=1)
        return np.stack([s[:, 0], s[:, 1] - s[:, 0], 1 - s[:, 1]], axis=-1)
    raise KeyError(name)


@pytest.mark.parametrize("name", list(ROUND_TRIPS))
def test_invert_maps_uniform_domain_points_to_uniform_u(name):
    sample, invert = ROUND_TRIPS[name]
    rng = np.random.default_rng(10)
    pts = _independent_uniform_points(name, rng, 100_000)
    u = invert(pts)
    assert np.all((u >= -1e-12) & (u <= 1 + 1e-12)), name
    chi_square_uniform_square(np.clip(u, 0.0, 1.0), res=(16, 16), what=f"invert {name}")
    # And the warp takes them back to where they came from.
    atol = FLOAT32_ATOL if name in FLOAT32_WARPS else 1e-8
    np.testing.assert_allclose(sample(u), pts, rtol=0, atol=atol, err_msg=name)


# --------------------------------------------------------------------------------------------
# Frames
# --------------------------------------------------------------------------------------------


def _hard_normals():
    rng = np.random.default_rng(11)
    g = rng.normal(size=(5000, 3))
    tiny = [1e-300, 1e-17, 1e-12, 1e-8, 1e-4]
    special = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0],
               [1, 1, 0], [0, 1e-9, -1], [1e-9, 0, -1], [0.0, 0.0, -1.0 + 1e-16]]
    special += [[t, t, 1] for t in tiny] + [[t, -t, -1] for t in tiny]
    special += [[t, 0, -1] for t in tiny] + [[0, t, -1] for t in tiny]
    special += [[1, 0, t] for t in tiny] + [[1, 0, -t] for t in tiny] + [[1, 0, -0.0]]
    n = np.concatenate([g, np.array(special, np.float64)])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def test_frame_from_normal_is_orthonormal_and_right_handed():
    n = _hard_normals()
    s, t = W.frame_from_normal(n)
    dot = lambda a, b: np.sum(a * b, axis=1)  # noqa: E731
    for name, value, want in [("|s|", dot(s, s), 1), ("|t|", dot(t, t), 1), ("s.t", dot(s, t), 0),
                              ("s.n", dot(s, n), 0), ("t.n", dot(t, n), 0)]:
        np.testing.assert_allclose(value, want, rtol=0, atol=1e-12, err_msg=name)
    np.testing.assert_allclose(np.cross(s, t), n, rtol=0, atol=1e-12, err_msg="s x t = n")
    assert np.all(np.isfinite(s)) and np.all(np.isfinite(t))


def test_to_world_maps_local_z_to_the_normal_and_keeps_lengths_and_cosines():
    n = _hard_normals()
    s, t = W.frame_from_normal(n)
    local = W.sample_cosine_hemisphere(np.random.default_rng(12).random((len(n), 2)))
    world = W.to_world(local, s, t, n)
    np.testing.assert_allclose(np.linalg.norm(world, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.sum(world * n, axis=1), local[:, 2], atol=1e-12)
    np.testing.assert_allclose(W.to_world(np.tile([0.0, 0.0, 1.0], (len(n), 1)), s, t, n), n,
                               atol=1e-15)


def test_to_world_around_is_to_world_in_the_frame_of_the_normal():
    n = _hard_normals()
    local = W.sample_cosine_hemisphere(np.random.default_rng(13).random((len(n), 2)))
    local = np.concatenate([local, -local[:100]])  # also below the surface (transmission)
    n = np.concatenate([n, n[:100]])
    s, t = W.frame_from_normal(n)
    world = W.to_world_around(local, n)
    np.testing.assert_allclose(world, W.to_world(local, s, t, n), rtol=0, atol=4e-16)
    assert np.all(np.isfinite(world))
