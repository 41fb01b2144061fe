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
    "bdpt cornell area power views": "b783e6d8d33ba87a085756761f6371ee54c6651e546f0a9b8dcf8ae83ddfdcfe",
    "bdpt cornell point balance": "c14a376d6405969258ff0fe61d392018271d5a34b9dd49249749998dbcc2a621",
    "bdpt glass sphere light maximum": "4c3aba75e66caefbbc7469f0dd16d616402c03957ac9ca553d0a3f6213690cc9",
    "light cornell mesh": "336841007cc43b73ad8543a1581b6fbd453d26f1c124e658be4646100f15a83e",
    "light glass point": "4dce5ed3dcd1d0a5021284b0e9a9bc7346021ee9f3a9715316dcc3088dc913fd",
    "path cornell area solid angle sobol": "1f8724ec64ddb022426641a4abb5a283ab1ac11eb4ac546da930a60fed1020f2",
    "path cornell area defaults": "16cc4bba1560a479394f2845b9f9bc89c8bf1a6e71ea0350ab0f41fc876c5941",
    "path glass sphere area power": "56b95e41c3debbfe2a6316cef117e8eaa63579c0afcf748032d19516c3e602b6",
    "path cornell mesh power": "ccc104eb8778757a5b1fa5b2eb1759b3a9682cae9899cd8fce4660db98ec7a08",
    "path glass sphere light alias uniform": "f3df55af663f530a7d9e048f312f1a376aeb689ea68c11e382061a905a4ec61a",
    "path mirror point cutoff": "f03fad457978abd7f66f895bcbf19323dda6d82ca39f5338e3f19dab1ae69d6d",
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
