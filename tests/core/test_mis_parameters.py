"""The MIS heuristics' parameters reach the weights: ``mis_beta`` and ``mis_alpha`` change the
image, and their limits are the heuristics they are documented to become.

Every heuristic is unbiased, so an unbiasedness test cannot see a parameter that is ignored.
These tests use the limits instead: the power heuristic with beta = 1 *is* the balance
heuristic, the cutoff heuristic with alpha = 0 is the balance heuristic and with alpha = 1 the
maximum heuristic. MIS weights do not change which paths are traced, so with the same seed the
images of two settings with the same weights are bit-identical, and a parameter that were
ignored (or read from the wrong field) would break one of the equalities below: with beta and
alpha replaced by the constants 2 and 0.1 in ``core.sampling.mis``, four of the path tracer's
five tests fail.
"""

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.render import render
from tests.helpers import plain_settings

INTEGRATORS = ("path", "bdpt")


def _image(integrator, heuristic, **kw):
    # Inside an emitting sphere both next-event estimation (or BDPT's connections) and
    # BSDF-sampled rays find the emitter at every vertex, and their densities are often of the
    # same order: the heuristics' weights differ at most samples. (Under the Cornell box's
    # small ceiling light the density ratios are mostly below 0.1, where cutoff and maximum
    # agree.)
    scene = scenes.furnace(width=24, height=24)
    settings = plain_settings(integrator=integrator, spp=4, seed=11, max_bounces=3,
                              mis_heuristic=heuristic, **kw)
    return render(scene, settings).combined()[..., :3]


@pytest.fixture(scope="module", params=INTEGRATORS)
def images(request):
    integrator = request.param
    return {
        "balance": _image(integrator, "balance"),
        "maximum": _image(integrator, "maximum"),
        "power 1": _image(integrator, "power", mis_beta=1.0),
        "power 2": _image(integrator, "power", mis_beta=2.0),
        "power 4": _image(integrator, "power", mis_beta=4.0),
        "cutoff 0": _image(integrator, "cutoff", mis_alpha=0.0),
        "cutoff 0.3": _image(integrator, "cutoff", mis_alpha=0.3),
        "cutoff 1": _image(integrator, "cutoff", mis_alpha=1.0),
    }


def _differs(a, b):
    """Whether two same-seed images differ in a visible share of their pixels."""
    return np.mean(np.any(a != b, axis=-1)) > 0.05


def test_power_heuristic_with_beta_one_is_the_balance_heuristic(images):
    np.testing.assert_array_equal(images["power 1"], images["balance"])


def test_mis_beta_changes_the_image(images):
    assert _differs(images["power 2"], images["balance"])
    assert _differs(images["power 4"], images["power 2"])


def test_larger_beta_moves_the_weights_toward_the_maximum_heuristic(images):
    # For each sample, w_beta = r^beta / sum r'^beta tends to the maximum heuristic's 0 or 1.
    gap = {b: np.abs(images[f"power {b}"] - images["maximum"]).sum() for b in (1, 2, 4)}
    assert gap[1] > gap[2] > gap[4]


def test_cutoff_heuristic_is_balance_at_alpha_zero_and_maximum_at_alpha_one(images):
    np.testing.assert_array_equal(images["cutoff 0"], images["balance"])
    np.testing.assert_array_equal(images["cutoff 1"], images["maximum"])


def test_mis_alpha_between_the_limits_is_neither(images):
    assert _differs(images["cutoff 0.3"], images["balance"])  # 18 % of pixels (path)
    assert _differs(images["cutoff 0.3"], images["maximum"])
