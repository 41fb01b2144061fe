"""Light tracing's speed paths (issue 12, fifth round) against the general code they replace.

- Light tracing walks a work unit in one chunk (``LightTracer.chunk_paths = None``), where the
  bidirectional driver cuts batches into chunks of ``bidir.CHUNK`` paths, and its units hold
  64 k paths (16 k before). Property: the camera samples' image is the same bit for bit, and
  the splats are the same set of (position, value) pairs bit for bit; only the order in which
  a pixel's splats are summed differs, so a whole render agrees with one in the former units
  and chunks to rounding.
- The pixel filter's density (``PixelFilter.pdf_1d``, the weight of every splat tap) reads a
  per-cell table made once. Property: it equals the slope of the tabulated CDF, bit for bit.

Smallest error detected: any difference at all in the compared arrays (equality), and a
relative difference of 1e-12 in a pixel's float64 splat sums.
"""

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.film import PixelFilter
from sampling_lab.core.integrators import bidir
from sampling_lab.core.integrators.base import Counters
from sampling_lab.core.integrators.light import LightTracer
from sampling_lab.core.prepare import prepare
from sampling_lab.core.render import RenderSettings, render
from sampling_lab.core.sampling.samplers import make_sampler
from tests.helpers import plain_settings


class _Chunked(LightTracer):
    """Light tracing in the driver's chunks of ``bidir.CHUNK`` paths (the general code)."""

    chunk_paths = bidir.CHUNK


def _unit(cls, scene, settings, n):
    integ = cls(prepare(scene, settings.light_selection), settings)
    sampler = make_sampler(settings.sampler, seed=settings.seed, spp=settings.spp,
                           width=scene.camera.width)
    pixels = np.arange(n) % (scene.camera.width * scene.camera.height)
    stream = sampler.stream(pixels, pixels // 4096)
    counters = Counters()
    return integ.render_samples(stream, PixelFilter(), counters), counters


def _sorted_splats(splats):
    rows = np.concatenate([splats.xy, splats.value], axis=1)
    return rows[np.lexsort(rows.T[::-1])]


@pytest.mark.parametrize("sampler,selection", [("sobol", "tree"), ("independent", "power")])
def test_one_chunk_makes_the_chunked_splats(sampler, selection):
    scene = scenes.cornell_box(64, 64, "mesh")
    settings = RenderSettings(integrator="light", spp=5, seed=4, sampler=sampler,
                              light_selection=selection)
    n = 2 * bidir.CHUNK + 1000  # three chunks for the general code
    whole, c_whole = _unit(LightTracer, scene, settings, n)
    chunked, c_chunked = _unit(_Chunked, scene, settings, n)
    assert np.array_equal(whole.radiance, chunked.radiance)
    assert whole.light_paths == chunked.light_paths == n
    assert len(whole.splats.xy) > n // 2  # enough splats for the comparison to mean something
    assert np.array_equal(_sorted_splats(whole.splats), _sorted_splats(chunked.splats))
    assert c_whole.rays == c_chunked.rays


def test_render_in_whole_units_agrees_with_the_former_units_and_chunks(monkeypatch):
    scene = scenes.cornell_box(64, 64, "mesh")
    settings = plain_settings(integrator="light", spp=8, seed=2, threads=2)
    whole = render(scene, settings)  # one unit of 32 k paths, one chunk
    monkeypatch.setattr(LightTracer, "chunk_paths", bidir.CHUNK)
    monkeypatch.setattr(LightTracer, "unit_paths", 1 << 14)
    chunked = render(scene, settings)  # two units of 16 k paths, two chunks each
    a, b = whole.film, chunked.film
    assert np.array_equal(a.sum, b.sum) and np.array_equal(a.count, b.count)
    assert a.splat_paths == b.splat_paths and b.splat_sum.mean() > 0
    # The float64 sums of the splats, in another order (measured: up to 2e-15 relative).
    for name in ("splat_sum", "splat_sum_sq"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-12, atol=0)


@pytest.mark.parametrize("kind,width", [("BLACKMAN_HARRIS", 1.5), ("GAUSSIAN", 1.5),
                                        ("BLACKMAN_HARRIS", 0.7)])
def test_filter_density_is_the_cdf_slope(kind, width):
    pf = PixelFilter(kind, width)
    x = np.random.default_rng(1).uniform(-0.6 * pf.support, 0.6 * pf.support, 20000)
    half, step = 0.5 * pf.support, pf.grid[1] - pf.grid[0]
    i = np.clip(np.floor((x + half) / step).astype(np.int64), 0, pf.grid.size - 2)
    slope = np.where(np.abs(x) < half, (pf.cdf[i + 1] - pf.cdf[i]) / step, 0.0)
    assert np.array_equal(pf.pdf_1d(x), slope)
