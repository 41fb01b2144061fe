"""A work unit's splat taps summed per pixel (core.film.tap_sums, Film.compact_splat_taps) add
to the film the very sums that adding the taps does, bit for bit."""

import numpy as np

from sampling_lab.core.film import Film, PixelFilter, SplatSums, tap_sums
from sampling_lab.core.worker_child import FilmWindow


def _taps(film, m, seed=5):
    """Taps as Film.splat_taps makes them, some outside the film (pixel n)."""
    rng = np.random.default_rng(seed)
    xy = rng.random((m, 2)) * (film.width + 4, film.height + 4) - 2
    value = rng.exponential(size=(m, 3)) * rng.choice([0.0, 1.0, 1e-3], size=(m, 1))
    return film.splat_taps(xy, value, PixelFilter("BLACKMAN_HARRIS", 1.5))


def test_added_tap_sums_equal_added_taps_bit_for_bit():
    by_taps, by_sums = Film(9, 7), Film(9, 7)
    for seed in range(3):  # several units: the film's running sums, not only the first
        pixel, weighted = _taps(by_taps, 400, seed)
        assert (pixel == by_taps.n_pixels).any()  # taps outside the film were dropped
        by_taps.add_splat_taps(pixel, weighted)
        by_sums.add_splat_sums(tap_sums(pixel, weighted, by_sums.n_pixels))
    assert np.any(by_taps.splat_sum > 0)
    np.testing.assert_array_equal(by_sums.splat_sum, by_taps.splat_sum)
    np.testing.assert_array_equal(by_sums.splat_sum_sq, by_taps.splat_sum_sq)


def test_compact_splat_taps_sums_only_when_smaller():
    small, large = FilmWindow(0, 0, 4, 4), FilmWindow(0, 0, 64, 64)
    pixel, weighted = _taps(Film(4, 4), 40)
    assert len(pixel) * 2 > 3 * small.n_pixels
    sums = small.compact_splat_taps(pixel, weighted)
    assert isinstance(sums, SplatSums) and sums.sum.shape == (small.n_pixels, 3)
    kept = large.compact_splat_taps(pixel, weighted)
    assert not isinstance(kept, SplatSums) and kept[0] is pixel and kept[1] is weighted
