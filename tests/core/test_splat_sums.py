"""A work unit's splat taps summed per pixel (core.film.tap_sums, Film.unit_splats) add to the
film the very sums that adding the taps does, bit for bit."""

import numpy as np
import pytest

from sampling_lab.core.film import Film, PixelFilter, SplatSums, tap_sums
from sampling_lab.core.worker_child import FilmWindow


def _splats(film, m, seed=5):
    """Splats ``(xy (m, 2), value (m, 3))``, some beyond the film's edges and some not finite."""
    rng = np.random.default_rng(seed)
    xy = rng.random((m, 2)) * (film.width + 4, film.height + 4) - 2 + (film.x0, film.y0)
    value = rng.exponential(size=(m, 3)) * rng.choice([0.0, 1.0, 1e-3], size=(m, 1))
    value[:3, 1] = (np.nan, np.inf, -np.inf)
    return xy, value


def _taps(film, m, seed=5, pixel_filter=PixelFilter("BLACKMAN_HARRIS", 1.5)):
    """Taps as Film.splat_taps makes them, some outside the film (pixel n)."""
    return film.splat_taps(*_splats(film, m, seed), pixel_filter)


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


@pytest.mark.parametrize("pixel_filter", [PixelFilter("BLACKMAN_HARRIS", 1.5), None])
@pytest.mark.parametrize("x0,y0", [(0, 0), (3, 2)])
def test_unit_splats_sum_the_taps_to_the_bit(pixel_filter, x0, y0):
    film = FilmWindow(x0, y0, 5, 4)
    xy, value = _splats(film, 300)
    sums = film.unit_splats(xy, value, pixel_filter)
    assert isinstance(sums, SplatSums)
    expected = tap_sums(*film.splat_taps(xy, value, pixel_filter), film.n_pixels)
    assert np.any(expected.sum > 0)
    assert sums.sum.tobytes() == expected.sum.tobytes()
    assert sums.sum_sq.tobytes() == expected.sum_sq.tobytes()


def test_unit_splats_sum_only_when_smaller():
    small, large = FilmWindow(0, 0, 4, 4), FilmWindow(0, 0, 64, 64)
    xy, value = _splats(small, 40)
    pixel_filter = PixelFilter("BLACKMAN_HARRIS", 1.5)
    assert len(small.splat_taps(xy, value, pixel_filter)[0]) * 2 > 3 * small.n_pixels
    sums = small.unit_splats(xy, value, pixel_filter)
    assert isinstance(sums, SplatSums) and sums.sum.shape == (small.n_pixels, 3)
    kept = large.unit_splats(xy, value, pixel_filter)
    assert not isinstance(kept, SplatSums)
    for a, b in zip(kept, large.splat_taps(xy, value, pixel_filter)):
        assert a.tobytes() == b.tobytes()
