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
    "bdpt cornell area power views": "5213099b9dbd746d096d3c718793bd93c4a1c2642c7fea103e6ca15cb7f95546",
    "bdpt cornell point balance": "fcad3b14b2176d279b44810d4ae75c7bbdb827954a0f413f6aea6a7418375613",
    "bdpt glass sphere light maximum": "4bc72f560d93b51fe4516484154307a739de35c1422906d406378787b65896b8",
    "light cornell mesh": "5d0c0cabf177cf5472a5c6c70494df1e7f49dee4f1064659ae24b263184dc6f8",
    "light glass point": "e385ad0ae0bd386ec303cc180eef776c165e0b921be57589ad4645f65e2b9a22",
    "path cornell area solid angle sobol": "e1e33772f633a4b90b089d971807e5bb219d37283854080a15acef3e6ea3b7dc",
    "path cornell area defaults": "af26d0e1b52126b9dab64f4633fc7dd51d558012806f83caedea5d524bce8e83",
    "path glass sphere area power": "886a34b3251570e895e783c2d06754f1db1af2970a1456b029851cd298cb325e",
    "path cornell mesh power": "7beca62640212ea2f72906c1eec924a29dec4435527f02d9ccea6e5e647e69f2",
    "path glass sphere light alias uniform": "17487164fec9d2443f153ef77401af1a463d5663b09db89d5e63cb86f226618e",
    "path mirror point cutoff": "22fb51126f66e7c3a16b2c0a917b8456c95d0f99467ecf7d1d58f6105a555c4f",
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
