"""Small BDPT renders the bidirectional tests share: a Cornell box whose walls and ball use
the optional BSDF groups, every image of a render with strategy views, and what BDPT's
connection stage sees of one batch of subpaths."""

from __future__ import annotations

import numpy as np

from sampling_lab.core import scenes
from sampling_lab.core.film import PixelFilter
from sampling_lab.core.integrators.base import Counters
from sampling_lab.core.integrators.bdpt import BDPT
from sampling_lab.core.prepare import prepare
from sampling_lab.core.render import render
from sampling_lab.core.sampling.samplers import make_sampler
from tests.helpers import plain_settings


def layered_cornell(size):
    """The ``size x size`` Cornell box with a rough anisotropic metal ball, a coated white and
    a sheened red wall: three optional groups, on different rows of every subpath."""
    scene = scenes.cornell_sphere(size, size, ball="mirror", light="area", roughness=0.3)
    mats = scene.materials
    mats.coat_weight[0] = 0.5
    mats.sheen_weight[1] = 0.8
    mats.aniso_scale[3] = 2.0
    return scene


def bdpt_images(scene, spp, seed, max_bounces, **kw):
    """Combined, variance and every strategy layer (paths of up to 3 segments) of a
    one-thread BDPT render (``kw``: further settings)."""
    settings = plain_settings(integrator="bdpt", spp=spp, seed=seed, threads=1,
                              max_bounces=max_bounces, strategy_views=True,
                              strategy_max_length=3, **kw)
    result = render(scene, settings)
    layers = result.layers()
    return [result.combined(), result.variance(), *[layers[n] for n in result.layer_names]]


def seen_at_connect(scene, look):
    """``look(ctx, C, L)`` of BDPT's connection stage for one batch: the first 256 pixels of
    ``scene`` at one sample each (independent sampler, 4 bounces)."""
    seen = []

    class Probe(BDPT):
        def connect(self, ctx, stream, C, L, out):
            seen.append(look(ctx, C, L))

    settings = plain_settings(integrator="bdpt", spp=1, max_bounces=4)
    integ = Probe(prepare(scene), settings)
    sampler = make_sampler("independent", seed=1, spp=1, width=scene.camera.width)
    integ.render_samples(sampler.stream(np.arange(256), np.zeros(256, np.int64)),
                         PixelFilter(settings.filter_type, settings.filter_width), Counters())
    return seen[-1]
