"""The default settings, chosen by measurement (``docs/GAP.md``), and Russian roulette through
glass.

The defaults are the Sobol sampler and light-tree selection. Sobol points make a pixel's
samples correlated, so its variance is no longer an error estimate: the defaults are compared
with the plain settings (independent sampler, power selection) by independent replicates, as
light-path renders are. Russian roulette divides out the ``1 / etap^2`` of refractions before
it decides (pbrt-v4's ``etaScale``); any survival probability keeps the estimate unbiased, and
the tests check that both rules (pbrt's throughput, Cycles' square root, the default) do.
"""

import numpy as np

from sampling_lab.core import scenes
from sampling_lab.core.integrators.common import russian_roulette
from sampling_lab.core.options import DEFAULTS
from sampling_lab.core.render import RenderSettings, render
from tests.helpers import (assert_replicates_agree, assert_two_images_agree, plain_settings,
                           uniform_bounces)


def test_the_defaults_are_sobol_and_the_light_tree():
    assert (DEFAULTS["sampler"], DEFAULTS["light_selection"]) == ("sobol", "tree")
    assert (RenderSettings().sampler, RenderSettings().light_selection) == ("sobol", "tree")


def test_the_default_settings_estimate_the_same_image_as_the_plain_ones():
    """24 replicates a side of the 24 x 24 Cornell box (area light), 32 spp: the printed line
    says the smallest image-mean and 8 x 8 block errors the comparison detects (6.3 % and
    8.6 % with 99 % power when written)."""
    scene = scenes.cornell_box(24, 24, "area")
    runs = 24
    # Same bounce limits on both sides: this compares the sampler and the light selection.
    default = np.array([render(scene, RenderSettings(spp=32, seed=100 + i, threads=1,
                                                     **uniform_bounces({})))
                        .film.mean() for i in range(runs)])
    plain = np.array([render(scene, plain_settings(spp=32, seed=500 + i, threads=1))
                      .film.mean() for i in range(runs)])
    found = assert_replicates_agree(default, plain, detect=(0.07, 0.10),
                                    what="defaults vs plain")
    print(found)


def test_roulette_looks_past_the_radiance_scaling_of_refraction():
    """A path inside glass (beta = 1 / 1.5^2, eta_scale = 1.5^2) always survives; without the
    scale it would survive with probability 0.44 (pbrt's survival rule)."""
    settings = plain_settings(rr_min_bounces=0, rr_survival="throughput")
    beta = np.full((4, 3), 1 / 2.25)
    u = np.array([0.1, 0.5, 0.9, 0.99])
    alive, out = russian_roulette(beta, np.ones(4, bool), u, settings, 1, np.full(4, 2.25))
    assert alive.all() and np.allclose(out, beta)
    alive, out = russian_roulette(beta, np.ones(4, bool), u, settings, 1)
    assert alive.tolist() == [True, False, False, False]
    assert np.allclose(out[0], 1.0)


def test_roulette_through_glass_keeps_the_caustic_unbiased():
    """Roulette from the first bounce against none, looking through a glass ball at a room lit
    by a point light: the two images agree within their confidence intervals (per-pixel
    variances of the independent sampler). Detects a 6.8 % image-mean and a 16 % 8 x 8 block
    error with 99 % power (when written)."""
    scene = scenes.cornell_sphere(16, 16, "glass", "point")
    kw = dict(spp=256, max_bounces=12, threads=2)
    with_rr = render(scene, plain_settings(seed=1, rr_min_bounces=0, **kw))
    without = render(scene, plain_settings(seed=2, use_russian_roulette=False, **kw))
    found = assert_two_images_agree(with_rr.film.mean(), with_rr.variance(),
                                    without.film.mean(), without.variance(),
                                    detect=(0.08, 0.20), what="roulette vs none")
    print(found)


def test_square_root_survival_is_the_square_root_of_the_throughput():
    """``rr_survival='square_root'`` (Cycles' rule): a path of throughput 0.25 survives with
    probability 0.5 and carries twice its throughput; ``'throughput'`` keeps it with 0.25."""
    beta = np.full((2, 3), 0.25)
    u = np.array([0.4, 0.6])
    alive, out = russian_roulette(beta, np.ones(2, bool), u,
                                  plain_settings(rr_min_bounces=0, rr_survival="square_root"), 0)
    assert alive.tolist() == [True, False] and np.allclose(out[0], 0.5)
    alive, out = russian_roulette(beta, np.ones(2, bool), u,
                                  plain_settings(rr_min_bounces=0, rr_survival="throughput"), 0)
    assert alive.tolist() == [False, False]


def test_square_root_roulette_from_the_first_bounce_estimates_the_image_without_roulette():
    """Square-root roulette (Cycles' rule) from the first bounce against no roulette, looking
    through a glass ball at a room lit by a point light: the two images agree within their
    confidence intervals (per-pixel variances of the independent sampler). Detects a 6.6 %
    image-mean and a 15 % 8 x 8 block error with 99 % power (when written)."""
    scene = scenes.cornell_sphere(16, 16, "glass", "point")
    kw = dict(spp=256, max_bounces=12, threads=2)
    with_rr = render(scene, plain_settings(seed=1, rr_min_bounces=0, rr_survival="square_root",
                                           **kw))
    without = render(scene, plain_settings(seed=2, use_russian_roulette=False, **kw))
    found = assert_two_images_agree(with_rr.film.mean(), with_rr.variance(),
                                    without.film.mean(), without.variance(),
                                    detect=(0.08, 0.20), what="square-root roulette vs none")
    print(found)
