"""Render regions: only the region's pixels are traced, and they are the full frame's pixels.

Camera samples are indexed by frame pixel, so a region of a path-traced image is bit-identical
to the same window of the full-frame render with the same seed. Light tracing and BDPT trace one
light path per region camera sample and keep the splats that reach the region, so their region
is a different (noisier) but unbiased estimate: it is compared with the full frame's window by
independent replicates (:func:`tests.helpers.assert_replicates_agree`), since light paths make
neighbouring pixels correlated.
"""

import numpy as np
import pytest

from sampling_lab.core.film import Film, PixelFilter
from sampling_lab.core.render import render
from sampling_lab.core.scenes import cornell_box
from tests.helpers import assert_replicates_agree, plain_settings

# (x0, y0, x1, y1) in frame pixels, y from the bottom: an odd window of a 24 x 20 frame.
REGION = (5, 3, 17, 15)


def _window(image, region=REGION):
    x0, y0, x1, y1 = region
    return image[y0:y1, x0:x1]


@pytest.mark.parametrize("sampler", ["independent", "sobol", "poisson_disk"])
def test_region_pixels_are_bit_identical_to_the_full_frame(sampler):
    scene = cornell_box(24, 20, "area")
    full = render(scene, plain_settings(sampler=sampler, spp=6, seed=5))
    part = render(scene, plain_settings(sampler=sampler, spp=6, seed=5, region=REGION))
    assert part.combined().shape == (12, 12, 4)
    np.testing.assert_array_equal(part.combined(), _window(full.combined()))
    np.testing.assert_array_equal(part.variance(), _window(full.variance()))
    np.testing.assert_array_equal(part.sample_count(), _window(full.sample_count()))
    assert part.combined()[..., :3].mean() > 0


@pytest.mark.parametrize("integrator", ["path", "light", "bdpt"])
def test_region_traces_only_its_pixels_samples(integrator):
    """The region's cost is its share: camera samples (and, for light tracing and BDPT, light
    paths) are the region's pixels times the samples per pixel."""
    scene = cornell_box(24, 20, "area")
    spp = 2
    full = render(scene, plain_settings(integrator=integrator, spp=spp, seed=1))
    part = render(scene, plain_settings(integrator=integrator, spp=spp, seed=1, region=REGION))
    assert full.stats["samples"] == 24 * 20 * spp
    assert part.stats["samples"] == 12 * 12 * spp
    assert part.film.splat_paths == (12 * 12 * spp if integrator != "path" else 0)
    assert part.stats["spp"] == spp
    np.testing.assert_array_equal(part.sample_count(), spp)
    assert part.stats["rays"] < full.stats["rays"]


@pytest.mark.parametrize("integrator,spp,detect", [
    # Detects 5.7 % image-mean and 7.1 % 8x8-block errors (99 % power).
    ("light", 32, (0.06, 0.075)),
    # Detects 2.9 % image-mean and 5.0 % 8x8-block errors (99 % power).
    ("bdpt", 12, (0.04, 0.06)),
])
def test_light_path_regions_agree_with_the_full_frame(integrator, spp, detect):
    """Splats from the region's light paths, divided by their number (and BDPT's MIS over the
    region's camera density), estimate the full frame's pixels without bias."""
    scene = cornell_box(24, 24, "area")
    region = (4, 8, 20, 16)
    runs = 24
    full = np.array([_window(render(scene, plain_settings(
        integrator=integrator, spp=spp, seed=100 + i, threads=1)).film.mean(), region)
        for i in range(runs)])
    part = np.array([render(scene, plain_settings(
        integrator=integrator, spp=spp, seed=500 + i, threads=1, region=region)).film.mean()
        for i in range(runs)])
    assert part.shape == full.shape == (runs, 8, 16, 3)
    found = assert_replicates_agree(part, full, detect=detect,
                                    what=f"{integrator}: region vs full frame")
    print(f"{integrator}: region / full frame = {np.round(found.ratio, 4)}")


def test_film_window_keeps_the_splats_that_reach_its_pixels():
    """A window of a frame receives exactly the filtered splats the frame's pixels there get;
    positions outside the window (beyond the filter's reach) are dropped."""
    rng = np.random.default_rng(3)
    xy = rng.uniform(-1.0, 11.0, (4000, 2))
    value = rng.uniform(0.0, 1.0, (4000, 3))
    pixel_filter = PixelFilter("BLACKMAN_HARRIS", 1.5)
    frame = Film(10, 10)
    window = Film(4, 3, x0=2, y0=5)
    frame.splat(xy, value, pixel_filter)
    window.splat(xy, value, pixel_filter)
    expected = frame.splat_sum.reshape(10, 10, 3)[5:8, 2:6]
    np.testing.assert_allclose(window.splat_sum.reshape(3, 4, 3), expected, rtol=1e-12)
    assert expected.min() > 0
    # Without a filter a splat lands in the window pixel that contains it, or nowhere.
    box = Film(4, 3, x0=2, y0=5)
    box.splat([[2.5, 5.5], [5.9, 7.9], [1.9, 5.5], [6.0, 6.0]], np.ones((4, 3)))
    np.testing.assert_array_equal(box.splat_sum[:, 0], np.eye(12)[0] + np.eye(12)[11])


@pytest.mark.parametrize("region", [(0, 0, 25, 20), (5, 5, 5, 9), (-1, 0, 4, 4)])
def test_region_outside_the_frame_is_a_clear_error(region):
    with pytest.raises(ValueError, match="render region"):
        render(cornell_box(24, 20), plain_settings(spp=1, region=region))
