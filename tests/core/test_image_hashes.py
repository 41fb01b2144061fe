"""Refactoring guard: the same seed gives the same image, bit for bit, as the code that the
pinned hashes were computed with.

Reshaping lights, MIS, the integrator contract or the render loop must not change what any
integrator computes. Each case renders a small scene with a fixed seed and compares the SHA-256
of every pass (Combined, Variance, Sample Count and BDPT's strategy views) with the value pinned
in :data:`PINNED`. The cases cover every integrator, area / point / mesh / sphere lights,
glass and mirror caustics, several MIS heuristics, light selection, solid-angle sampling and a
low-discrepancy sampler.

A pinned hash is a property of this code on this kind of machine (Embree's SIMD width and
NumPy's BLAS can change the last bits of a float on another CPU): if a case fails on a machine
where nothing in ``core`` changed, re-pin it there with ``python tests/core/test_image_hashes.py``
and say so in the commit. A behaviour change on purpose re-pins the affected cases the same way.
"""

import hashlib
import sys

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.render import render
from tests.helpers import plain_settings

CASES = {
    "path cornell mesh power": (lambda: scenes.cornell_box(24, 24, "mesh"),
                                dict(integrator="path", spp=4)),
    "path cornell area solid angle sobol": (
        lambda: scenes.cornell_box(24, 24, "area"),
        dict(integrator="path", spp=4, sampler="sobol", light_sampling="solid_angle",
             mis_heuristic="balance")),
    "path glass sphere light alias uniform": (
        lambda: scenes.cornell_sphere(24, 24, ball="glass", light="sphere"),
        dict(integrator="path", spp=4, distribution="alias", light_selection="uniform")),
    "path mirror point cutoff": (
        lambda: scenes.cornell_sphere(24, 24, ball="mirror", light="point"),
        dict(integrator="path", spp=4, mis_heuristic="cutoff", mis_alpha=0.2)),
    "path cornell area defaults": (lambda: scenes.cornell_box(24, 24, "area"),
                                   dict(integrator="path", spp=4, sampler="sobol",
                                        light_selection="tree")),
    "path glass sphere area power": (
        lambda: scenes.cornell_sphere(24, 24, ball="glass", light="area"),
        dict(integrator="path", spp=4)),
    "light cornell mesh": (lambda: scenes.cornell_box(24, 24, "mesh"),
                           dict(integrator="light", spp=4)),
    "light glass point": (lambda: scenes.cornell_sphere(24, 24, ball="glass", light="point"),
                          dict(integrator="light", spp=4)),
    "bdpt cornell area power views": (
        lambda: scenes.cornell_box(24, 24, "area"),
        dict(integrator="bdpt", spp=2, strategy_views=True, strategy_max_length=3)),
    "bdpt glass sphere light maximum": (
        lambda: scenes.cornell_sphere(24, 24, ball="glass", light="sphere"),
        dict(integrator="bdpt", spp=2, mis_heuristic="maximum")),
    "bdpt cornell point balance": (lambda: scenes.cornell_box(24, 24, "point"),
                                   dict(integrator="bdpt", spp=2, mis_heuristic="balance")),
}

PINNED = {
    "bdpt cornell area power views": "c07ac4a84e738a6310926166ecc4d5da17b17a3740bd069945a8bd2557d913d2",
    "bdpt cornell point balance": "de3ac35df3f06b1b8de48f007712a540d807145b34e9da139dd77a0428e2c622",
    "bdpt glass sphere light maximum": "c6e80f22c1e5c5f8041dda0af155a9d0a5cd450e014678365c59cdc8523c8937",
    "light cornell mesh": "7bdaea47c1f03443b6f9af5768dcaa445d18319d73d2956d00545c7a0e8c811e",
    "light glass point": "09d2d760f0d0d821c8a18a6ccf1ee74489c24dbe5337e607e4ef7d20412af4f7",
    "path cornell area solid angle sobol": "4a0ec16d62462b01061f0eedc2790fa8c616a93abf72503513359101fae77d9e",
    "path cornell area defaults": "12f764085359552a006c79170b66f288a3c02077211ab909e482964bed71ae28",
    "path glass sphere area power": "c19de56b52a0ff9003db71baa7e75ea3a3b79b0fbac13c8bc82316b43f0cdf34",
    "path cornell mesh power": "28ddadd4083e439330cc890943f66f690ecda232bfa7047a6539ae5acafc904a",
    "path glass sphere light alias uniform": "fe9e4b21693b54cf4095cb31684de3286d80781ce76edde504ea29b4ab637402",
    "path mirror point cutoff": "fd5daec1b1c48774cab389d1f7a317153394bc4f81c4ae7ee00019167aa694c5",
}


def image_hash(name):
    """SHA-256 over every pass of case ``name``'s render, in a fixed order."""
    make_scene, kw = CASES[name]
    result = render(make_scene(), plain_settings(seed=3, max_bounces=5, threads=2, **kw))
    digest = hashlib.sha256()
    layers = result.layers()
    for image in [result.combined(), result.variance(), result.sample_count(),
                  *[layers[n] for n in result.layer_names]]:
        digest.update(np.ascontiguousarray(image, np.float32).tobytes())
    stats = result.stats
    digest.update(np.asarray([stats["spp"], stats["samples"]], np.int64).tobytes())
    return digest.hexdigest()


@pytest.mark.parametrize("name", sorted(CASES))
def test_same_seed_gives_the_pinned_image(name):
    assert image_hash(name) == PINNED[name], (
        f"{name}: the image changed; see this module's docstring")


if __name__ == "__main__":
    for case in sorted(CASES) if len(sys.argv) < 2 else sys.argv[1:]:
        print(f'    "{case}": "{image_hash(case)}",')
