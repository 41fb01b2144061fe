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
    "bdpt cornell area power views": "bd26156cba63f4c3a4ff154b73d30c5944298c2f8fabbba140c5c92bf8b1cbce",
    "bdpt cornell point balance": "9996a9328e5d914941bc2f713fec076adb39c2c6f66e7fec1568ac7d0bad712d",
    "bdpt glass sphere light maximum": "16ef55e7b142d14bfd3ea07930bafe419c8060c6c354bf4d55eac9102a077574",
    "light cornell mesh": "0416524d5d617547675f7a457652dfb288c209e5524438ce86e65dce3e65da16",
    "light glass point": "e04c5c1e77519051193fa255574b217465e05ee0e6c22da61dcd2ca6a112a973",
    "path cornell area solid angle sobol": "02be7a38affd970c515226ec5e0d27269b4d26f28b414d422fbdc2f73aca2aac",
    "path cornell area defaults": "3b723c18e28e638b702a110480cbfd5d4a32a8993cdc7b3452c541f6459f7042",
    "path glass sphere area power": "163b4861599c11b1f41c2dc0f52138bc5ea038f9c3cc5677a9e67a2bb2ab4e06",
    "path cornell mesh power": "7f3418122c34f1381dbf8210505e07616f10f27e0948c85f2109ad5b0400762d",
    "path glass sphere light alias uniform": "68d24b3a6280a2bab4ffc49604316878dacb276f461a2559d607c10533eda80e",
    "path mirror point cutoff": "54c8355d09a83f2e55e90d2be8f0e42cc25ff01c4157eccef3ba0b7ef59bc5ec",
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
