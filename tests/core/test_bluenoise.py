"""Blue-noise samplers (Poisson disk, Lloyd, CVT) and their shared machinery.

Statistical checks compare a measured mean with a bound through its confidence interval over
independent realizations (different set seeds), with the false-failure probability stated in
each test; every such check is shown to reject white noise, so it can fail. The tables are
generated into a fresh cache folder for this module (no test depends on an existing cache).
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from sampling_lab.core.metrics import student_t_quantile
from sampling_lab.core.sampling.lab import low_frequency_power, periodogram, star_discrepancy
from sampling_lab.core.sampling.samplers import bluenoise, cvt, lloyd, make_sampler, poisson_disk
from tests.helpers import z_for_false_failure

KINDS = ["poisson_disk", "lloyd", "cvt"]
GENERATORS = {"poisson_disk": poisson_disk.generate, "lloyd": lloyd.generate, "cvt": cvt.generate}


@pytest.fixture(autouse=True, scope="module")
def fresh_cache(tmp_path_factory):
    """Generate every table afresh into a temporary cache (and leave the memo clean after)."""
    old = os.environ.get("SAMPLING_LAB_CACHE")
    os.environ["SAMPLING_LAB_CACHE"] = str(tmp_path_factory.mktemp("bluenoise_cache"))
    bluenoise.clear_memo()
    yield
    bluenoise.clear_memo()
    if old is None:
        del os.environ["SAMPLING_LAB_CACHE"]
    else:
        os.environ["SAMPLING_LAB_CACHE"] = old


def brute_torus_distances(p):
    """All pairwise toroidal distances by the nine periodic images (no wrapping arithmetic)."""
    shifts = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)], float)
    d = p[:, None, None, :] - p[None, :, None, :] + shifts[None, None, :, :]
    return np.sqrt((d ** 2).sum(-1)).min(-1)


def one_sided_upper(values, p_false):
    """Upper confidence bound of the mean of independent ``values`` (Student t)."""
    v = np.asarray(values, float)
    return v.mean() - student_t_quantile(p_false, v.size - 1) * v.std(ddof=1) / math.sqrt(v.size)


# --------------------------------------------------------------------------------------------
# Torus geometry and helpers
# --------------------------------------------------------------------------------------------


def test_torus_distance_wraps_around_the_edges():
    a = np.array([[0.01, 0.5], [0.02, 0.98], [0.3, 0.3]])
    b = np.array([[0.99, 0.5], [0.98, 0.01], [0.7, 0.7]])
    np.testing.assert_allclose(np.sqrt(bluenoise.torus_distance2(a, b)),
                               [0.02, math.hypot(0.04, 0.03), math.hypot(0.4, 0.4)], atol=1e-12)
    rng = np.random.default_rng(0)
    p = rng.random((40, 2))
    d = brute_torus_distances(p)
    np.fill_diagonal(d, np.inf)
    assert bluenoise.min_torus_distance(p) == pytest.approx(d.min(), abs=1e-12)


@pytest.mark.parametrize("n", [1, 5, 9, 50, 300])
def test_nearest_site_matches_brute_force(n):
    rng = np.random.default_rng(n)
    # Clustered sites leave big voids: the grid's certification must fall back to brute force.
    sites = np.concatenate([rng.random((n - n // 2, 2)), 0.1 * rng.random((n // 2, 2))])
    q = rng.random((4000, 2))
    idx, d2 = bluenoise.nearest_site(q, sites)
    full = bluenoise.torus_distance2(q[:, None, :], sites[None, :, :])
    np.testing.assert_array_equal(idx, full.argmin(axis=1))
    np.testing.assert_allclose(d2, full.min(axis=1), rtol=1e-12)


def test_hilbert_index_is_a_continuous_bijection():
    order = 4
    x, y = np.meshgrid(np.arange(16), np.arange(16))
    d = cvt.hilbert_index(x.ravel(), y.ravel(), order)
    np.testing.assert_array_equal(np.sort(d), np.arange(256))
    path = np.stack([x.ravel(), y.ravel()], 1)[np.argsort(d)]
    assert np.all(np.abs(np.diff(path, axis=0)).sum(axis=1) == 1), "consecutive cells not adjacent"


def test_set_size_uses_spp_then_complete_cycles():
    assert bluenoise.set_size(None, 256, 1024) == 256
    assert bluenoise.set_size(0, 256, 1024) == 256
    assert bluenoise.set_size(100, 256, 1024) == 100
    assert bluenoise.set_size(1024, 256, 1024) == 1024
    assert bluenoise.set_size(2000, 256, 1024) == 1000  # two complete cycles of 1000
    assert bluenoise.set_size(5000, 256, 1024) == 1000  # five of 1000


# --------------------------------------------------------------------------------------------
# The point sets
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 16, 100, 1024])
def test_poisson_disk_points_are_at_least_the_radius_apart(n):
    pts, info = poisson_disk.generate(n, seed=3)
    assert pts.shape == (n, 2) and pts.min() >= 0 and pts.max() < 1
    if n > 1:
        d = brute_torus_distances(pts)
        np.fill_diagonal(d, np.inf)
        assert d.min() >= info["radius"]
    if n >= 16:
        # The radius is chosen for n: in the blue-noise range of Lagae and Dutre.
        assert 0.6 <= info["rho"] <= 1.0
        assert info["radius"] == pytest.approx(info["rho"] * poisson_disk.hex_distance(n))


@pytest.mark.parametrize("kind", KINDS)
def test_blue_noise_sets_have_less_low_frequency_power_than_white_noise(kind):
    """Radially averaged periodogram below the white-noise level 1 in every ring of the band.

    White noise has E[P(k)] = 1 for k != 0. Each ring's mean over R = 6 independent sets (set
    seeds) gets a one-sided t bound, Bonferroni over the rings (false failure <= 1e-3); the same
    bound computed for white-noise sets must not come out below 1, which shows the check can fail.
    """
    n, r, band = 256, 6, 8  # rings |k| = 1 .. sqrt(n) / 2
    rings = np.rint(np.hypot(*np.meshgrid(np.arange(-band, band + 1), np.arange(-band, band + 1))))

    def ring_means(sets):
        p = periodogram(sets, band)
        return np.stack([p[:, rings == k].mean(axis=1) for k in range(1, band + 1)], 1)

    blue = ring_means(np.stack([GENERATORS[kind](n, seed=s)[0] for s in range(r)]))
    white = ring_means(np.random.default_rng(5).random((r, n, 2)))
    p_ring = 1e-3 / band
    upper = [one_sided_upper(blue[:, k], p_ring) for k in range(band)]
    assert max(upper) < 1.0, f"{kind}: ring bounds {np.round(upper, 3)}"
    assert np.mean(low_frequency_power(periodogram(np.stack(
        [GENERATORS[kind](n, seed=s)[0] for s in range(2)]), band), n)) < 0.2
    white_band = white.mean(axis=1)
    assert one_sided_upper(white_band, 1e-3) > 1.0, "the bound would not reject white noise"


@pytest.mark.parametrize("kind", KINDS)
def test_blue_noise_sets_are_more_uniform_than_random_points(kind):
    """Star discrepancy below that of independent points, by more than the difference's CI.

    10 sets (independent seeds) against 60 sets of independent points; Welch's difference with
    a t quantile on 9 degrees of freedom (the smaller sample's, conservative), one-sided, false
    failure 1e-3.
    """
    n, r, r_white = 256, 10, 60
    blue = np.array([star_discrepancy(GENERATORS[kind](n, seed=10 + s)[0]) for s in range(r)])
    rng = np.random.default_rng(11)
    white = np.array([star_discrepancy(rng.random((n, 2))) for _ in range(r_white)])
    se = math.sqrt(blue.var(ddof=1) / r + white.var(ddof=1) / r_white)
    t = -student_t_quantile(1e-3, r - 1)
    assert white.mean() - blue.mean() > t * se, (kind, blue.mean(), white.mean(), se)


def test_lloyd_moves_sites_to_centroids():
    """After relaxation the sites sit close to their Voronoi centroids (residual step small)."""
    pts, info = lloyd.generate(256, seed=0)
    assert info["last_move"] < 0.1  # in units of the mean spacing (jittered probes' noise)
    probes = np.random.default_rng(1).random((200_000, 2))
    idx, _ = bluenoise.nearest_site(probes, pts)
    delta = bluenoise.torus_delta(probes, pts[idx])
    step = np.stack([np.bincount(idx, delta[:, k], minlength=256) for k in (0, 1)], 1)
    step /= np.bincount(idx, minlength=256)[:, None]
    random_sites = np.random.default_rng(2).random((256, 2))
    idx_r, _ = bluenoise.nearest_site(probes, random_sites)
    delta_r = bluenoise.torus_delta(probes, random_sites[idx_r])
    step_r = np.stack([np.bincount(idx_r, delta_r[:, k], minlength=256) for k in (0, 1)], 1)
    step_r /= np.maximum(np.bincount(idx_r, minlength=256), 1)[:, None]
    assert np.sqrt((step ** 2).sum(1).mean()) < 0.25 * np.sqrt((step_r ** 2).sum(1).mean())


def test_cvt_reaches_a_stable_capacity_constrained_set():
    pts, info = cvt.generate(256, seed=0)
    assert info["stable"] == 1.0 and info["swaps"] == 0.0
    assert pts.shape == (256, 2) and pts.min() >= 0 and pts.max() < 1
    # Equal capacities: the discrete cells have equal area, so their nearest-site areas are
    # close to 1/N (a CVT of equal cells); random sites' areas vary like a Poisson-Voronoi's.
    probes = np.random.default_rng(3).random((400_000, 2))
    area = np.bincount(bluenoise.nearest_site(probes, pts)[0], minlength=256) / probes.shape[0]
    area_r = np.bincount(bluenoise.nearest_site(probes, np.random.default_rng(4).random(
        (256, 2)))[0], minlength=256) / probes.shape[0]
    assert np.std(area * 256) < 0.25 * np.std(area_r * 256)


# --------------------------------------------------------------------------------------------
# Masks
# --------------------------------------------------------------------------------------------


def low_band_ratio(img, band=8):
    """Mean periodogram of an image over 0 < |k| <= band, relative to its mean over k != 0."""
    img = np.asarray(img, float) - np.mean(img)
    f = np.abs(np.fft.fft2(img)) ** 2
    k = np.fft.fftfreq(img.shape[0]) * img.shape[0]
    r = np.hypot(k[:, None], k[None, :])
    return f[(r > 0) & (r <= band)].mean() / f[r > 0].mean()


def test_void_and_cluster_mask_is_a_blue_stratified_ranking():
    m = bluenoise.mask()
    np.testing.assert_allclose(np.sort(m.ravel()), (np.arange(4096) + 0.5) / 4096)
    assert low_band_ratio(m) < 0.05
    # White noise: the ratio of two averages of ~100 independent exponential powers, 1 +- 0.15.
    shuffled = np.random.default_rng(0).permutation(m.ravel()).reshape(64, 64)
    assert low_band_ratio(shuffled) > 0.5


def test_vector_mask_pairs_are_blue_and_components_stay_stratified():
    m1, m2 = bluenoise.mask(), bluenoise.mask2()
    for c in (0, 1):
        np.testing.assert_allclose(np.sort(m2[..., c].ravel()), np.sort(m1.ravel()))
        assert low_band_ratio(np.sin(2 * np.pi * m2[..., c])) < 0.1
    rot = np.random.default_rng(1).random((4, 2))
    prod = [low_band_ratio(np.sin(2 * np.pi * ((m2[..., 0] + a) % 1))
                           * np.cos(2 * np.pi * ((m2[..., 1] + b) % 1))) for a, b in rot]
    # Two placements of the 1-D mask are blue per component but not as pairs.
    naive = np.stack([m1, np.roll(m1, (29, 37), (0, 1))], -1)
    prod_naive = [low_band_ratio(np.sin(2 * np.pi * ((naive[..., 0] + a) % 1))
                                 * np.cos(2 * np.pi * ((naive[..., 1] + b) % 1))) for a, b in rot]
    assert max(prod) < 0.3 < 0.7 < min(prod_naive)


# --------------------------------------------------------------------------------------------
# Streams
# --------------------------------------------------------------------------------------------


def rotation_of(values, points):
    """The offset o with frac(points + o) == values as sets, or None."""
    for k in range(points.shape[0]):
        o = values[0] - points[k]
        moved = bluenoise.wrap(points + o)
        a = moved[np.lexsort(moved.T[::-1])]
        b = values[np.lexsort(values.T[::-1])]
        if np.allclose(bluenoise.torus_delta(a, b), 0, atol=1e-9):
            return o
    return None


@pytest.mark.parametrize("kind", KINDS)
def test_each_pixel_sees_the_whole_set_under_a_rotation(kind):
    n = 64
    sampler = make_sampler(kind, seed=4, spp=n)
    pts = sampler.points
    offsets = []
    for pixel in (0, 1, 777):
        s = sampler.stream(np.full(n, pixel), np.arange(n))
        for dim in (0, 2, 7):
            o = rotation_of(s.sample(dim, 2), pts)
            assert o is not None, f"{kind}: pixel {pixel} dimension {dim} is not the set rotated"
            offsets.append(o)
        # 1-D requests: the first coordinate of the set, rotated.
        x = np.sort(s.sample(4, 1)[:, 0])
        o = (x[0] - pts[:, 0]) % 1.0
        assert any(np.allclose(np.sort((pts[:, 0] + c) % 1.0), x, atol=1e-9) for c in o)
    # Different pixels and dimensions are rotated differently.
    offsets = np.array(offsets) % 1.0
    assert len(np.unique(np.round(offsets, 9), axis=0)) == len(offsets)


@pytest.mark.parametrize("kind", KINDS)
def test_sample_indices_beyond_n_are_new_rotations_of_the_set(kind):
    sampler = make_sampler(kind, seed=2, spp=None)  # time-limited render: N = default
    n = sampler.n_points
    assert n == sampler.default_points == 256
    s = sampler.stream(np.full(3 * n, 42), np.arange(3 * n))
    u = s.sample(0, 2)
    offs = [rotation_of(u[c * n:(c + 1) * n], sampler.points) for c in range(3)]
    assert all(o is not None for o in offs)
    d = bluenoise.torus_delta(offs[1], offs[0])
    assert np.abs(d).max() > 1e-3, "cycle 1 repeats cycle 0"


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("spp,n", [(16, 16), (16, 40), (None, 64)])
def test_pixel_estimates_are_unbiased(kind, spp, n):
    """Mean of many pixel estimates of a smooth integral within its CI (false failure 1e-4
    over the 9 cases). Pixels are negatively correlated through the mask, which only makes the
    independent-pixel interval conservative."""
    sampler = make_sampler(kind, seed=9, spp=spp)
    pixels = 4096
    s = sampler.stream(np.repeat(np.arange(pixels), n), np.tile(np.arange(n), pixels))
    u = s.sample(3, 2)
    v = s.sample(5, 1)[:, 0]
    f = (np.sin(2 * np.pi * u[:, 0]) + 1.0) * u[:, 1] ** 2 + v  # integral 1/3 + 1/2
    est = f.reshape(pixels, n).mean(axis=1)
    z = z_for_false_failure(1e-4, 9)
    assert abs(est.mean() - 5 / 6) <= z * est.std(ddof=1) / math.sqrt(pixels)


@pytest.mark.parametrize("kind", KINDS)
def test_screen_space_error_is_blue_noise(kind):
    """Neighbouring pixels get well-spread offsets: the error image of a smooth integrand has
    little low-frequency power. The independent sampler's (white) ratio is 1 +- 0.15 on the
    ~100 independent frequencies of the band; the blue samplers must be below 0.5."""
    w = 64
    f = lambda u: np.sin(2 * np.pi * u[:, 0]) * np.cos(2 * np.pi * u[:, 1])  # noqa: E731
    for n in (1, 4):
        for name, width in ((kind, w), ("independent", None)):
            sampler = make_sampler(name, seed=1, spp=n)
            if width:
                sampler.width = width
            s = sampler.stream(np.repeat(np.arange(w * w), n), np.tile(np.arange(n), w * w))
            err = f(s.sample(0, 2)).reshape(w * w, n).mean(axis=1).reshape(w, w)
            ratio = low_band_ratio(err)
            if name == kind:
                assert ratio < 0.5, f"{kind} n={n}: low-band ratio {ratio:.3f}"
            else:
                assert ratio > 0.6, f"independent n={n}: low-band ratio {ratio:.3f}"


def test_width_argument_and_attribute_agree():
    a = make_sampler("cvt", seed=0, spp=4)
    a.width = 100
    b = cvt.CVTSampler(seed=0, spp=4, width=100)
    pix, smp = np.repeat(np.arange(300), 4), np.tile(np.arange(4), 300)
    np.testing.assert_array_equal(a.stream(pix, smp).sample(0, 2), b.stream(pix, smp).sample(0, 2))
    c = make_sampler("cvt", seed=0, spp=4)
    assert not np.array_equal(c.stream(pix, smp).sample(0, 2), a.stream(pix, smp).sample(0, 2))


def test_too_many_points_are_refused():
    with pytest.raises(ValueError, match="supported"):
        cvt.CVTSampler.point_set(cvt.CVTSampler.max_points + 1)


# --------------------------------------------------------------------------------------------
# Cache
# --------------------------------------------------------------------------------------------


def test_sets_are_cached_on_disk_and_regenerated_when_damaged(tmp_path, monkeypatch):
    monkeypatch.setenv("SAMPLING_LAB_CACHE", str(tmp_path))
    bluenoise.clear_memo()
    calls = []
    real = poisson_disk.generate

    def counting(n, seed=0):
        calls.append(n)
        return real(n, seed)

    monkeypatch.setattr(poisson_disk, "generate", counting)
    first = poisson_disk.PoissonDiskSampler.point_set(50)[0].copy()
    path = tmp_path / "bluenoise" / f"poisson_disk_n50_s0_v{poisson_disk.PoissonDiskSampler.version}.npz"
    assert path.is_file() and calls == [50]
    # A new session reads the file instead of generating.
    bluenoise.clear_memo()
    np.testing.assert_array_equal(poisson_disk.PoissonDiskSampler.point_set(50)[0], first)
    assert calls == [50]
    # A damaged file is regenerated (same generator, same seed: same set).
    path.write_bytes(b"not an npz file")
    bluenoise.clear_memo()
    np.testing.assert_array_equal(poisson_disk.PoissonDiskSampler.point_set(50)[0], first)
    assert calls == [50, 50]
    bluenoise.clear_memo()


def test_unwritable_cache_only_costs_regeneration(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache folder should be")
    monkeypatch.setenv("SAMPLING_LAB_CACHE", str(blocker))
    bluenoise.clear_memo()
    pts, _ = lloyd.LloydSampler.point_set(20)
    assert pts.shape == (20, 2)
    bluenoise.clear_memo()
