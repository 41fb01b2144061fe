"""The image agreement checkers catch wrong images, and detect what they say they detect.

Every agreement test of the suite rests on three checkers in :mod:`tests.helpers`:
:func:`assert_images_agree` (our render with its variance pass against replicates of another
renderer, as for Cycles), :func:`assert_two_images_agree` (two renders with variance passes) and
:func:`assert_replicates_agree` (replicate renders on both sides, for splatted light paths).
Here each is fed real path-traced images of the Cornell box that are right, and the same images
made wrong the ways a renderer goes wrong: scaled by 1.02, 1.05 and 1.10, one 8 x 8 block 5 %
too bright, a missing bounce, an image shifted by two pixels. The right ones must pass and every
wrong one must fail, at sample counts where the checker reports that it detects a 2 % image-mean
error and a 5 % block error with 99 % probability.

The power figure itself is checked on synthetic data with known noise: a shift of exactly the
reported detectable size is caught in at least ~99 % of trials, and no shift in at most
``p_false`` of them.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core.render import render
from sampling_lab.core.scenes import cornell_box
from tests.helpers import (
    DETECT,
    POWER,
    assert_images_agree,
    assert_replicates_agree,
    assert_two_images_agree,
    plain_settings,
)

RES = 16
BOUNCES = 3
SPP = 2048          # our image (A) and the second render (B) of assert_two_images_agree
REPLICATES = 8      # B of assert_images_agree: REPLICATES renders of SPP // 4
RUNS = 16           # replicates a side for assert_replicates_agree, RUN_SPP each
RUN_SPP = 256


def _scene():
    """The Cornell box with its area light hidden from the camera, as Blender 5 makes lights:
    the lamp's few antialiased edge pixels would otherwise hold nearly all the variance."""
    scene = cornell_box(RES, RES, "area")
    scene.lights.visible_camera[:] = False
    return scene


def _render(spp, seed, bounces=BOUNCES):
    res = render(_scene(), plain_settings(spp=spp, seed=seed, max_bounces=bounces))
    return res.combined()[..., :3].astype(np.float64), res.variance().astype(np.float64)


@pytest.fixture(scope="module")
def renders():
    """Right images of one scene, and the same scene one bounce short."""
    a, var_a = _render(SPP, 1)
    b, var_b = _render(SPP, 2)
    reps = np.stack([_render(SPP // 4, 100 + i)[0] for i in range(REPLICATES)])
    short, var_short = _render(SPP, 3, bounces=BOUNCES - 1)
    runs_a = np.stack([_render(RUN_SPP, 1000 + i)[0] for i in range(RUNS)])
    runs_b = np.stack([_render(RUN_SPP, 2000 + i)[0] for i in range(RUNS)])
    runs_short = np.stack([_render(RUN_SPP, 3000 + i, BOUNCES - 1)[0] for i in range(RUNS)])
    return dict(a=a, var_a=var_a, b=b, var_b=var_b, reps=reps, short=short,
                var_short=var_short, runs_a=runs_a, runs_b=runs_b, runs_short=runs_short)


def _scaled_block(img, found_block_of, factor=1.05):
    """``img`` with its hardest-to-check 8 x 8 block scaled (the block whose detectable error
    is largest is the one a weak check would miss)."""
    y, x = found_block_of
    out = img.copy()
    out[..., 8 * y:8 * y + 8, 8 * x:8 * x + 8, :] *= factor
    return out


def _dimmest_block(img):
    """Index of the block with the smallest mean: its relative noise is the largest."""
    means = img.reshape(RES // 8, 8, RES // 8, 8, 3).mean(axis=(1, 3)).sum(-1)
    return np.unravel_index(np.argmin(means), means.shape)


def _wrong_images(img):
    """Name -> wrong version of a (..., h, w, 3) image (a stack of replicates keeps its axis)."""
    return {
        "x1.02": img * 1.02,
        "x1.05": img * 1.05,
        "x1.10": img * 1.10,
        "one block x1.05": _scaled_block(img, _dimmest_block(img.reshape(-1, RES, RES, 3)[0])),
        "shifted 2 px": np.roll(img, 2, axis=-2),
    }


# -------------------------------------------------------------------------- assert_images_agree
def test_images_checker_passes_right_images_at_its_stated_power(renders):
    found = assert_images_agree(renders["a"], renders["var_a"], renders["reps"], what="right")
    assert found.detectable.image_mean <= DETECT[0] and found.detectable.block <= DETECT[1]


@pytest.mark.parametrize("wrong", ["x1.02", "x1.05", "x1.10", "one block x1.05",
                                   "shifted 2 px", "missing bounce"])
def test_images_checker_rejects_a_wrong_image(renders, wrong):
    img = renders["short"] if wrong == "missing bounce" else _wrong_images(renders["a"])[wrong]
    var = renders["var_short"] if wrong == "missing bounce" else renders["var_a"]
    with pytest.raises(AssertionError, match="differ|outside"):
        assert_images_agree(img, var, renders["reps"], what=wrong)


def test_images_checker_fails_a_test_too_small_to_see_the_errors_it_asks_for(renders):
    """Four replicates of a 16 x 16 image cannot see a 5 % block error: the check says so
    instead of passing a blind test."""
    with pytest.raises(AssertionError, match="too few samples"):
        assert_images_agree(renders["a"], renders["var_a"] * 400, renders["reps"][:4])


# --------------------------------------------------------------------- assert_two_images_agree
def test_two_images_checker_passes_right_images_at_its_stated_power(renders):
    found = assert_two_images_agree(renders["a"], renders["var_a"], renders["b"],
                                    renders["var_b"], what="right")
    assert found.detectable.image_mean <= DETECT[0] and found.detectable.block <= DETECT[1]


@pytest.mark.parametrize("wrong", ["x1.02", "x1.05", "x1.10", "one block x1.05",
                                   "shifted 2 px", "missing bounce"])
def test_two_images_checker_rejects_a_wrong_image(renders, wrong):
    img = renders["short"] if wrong == "missing bounce" else _wrong_images(renders["a"])[wrong]
    var = renders["var_short"] if wrong == "missing bounce" else renders["var_a"]
    with pytest.raises(AssertionError, match="outside the interval"):
        assert_two_images_agree(img, var, renders["b"], renders["var_b"], what=wrong)


# --------------------------------------------------------------------- assert_replicates_agree
def test_replicates_checker_passes_right_images_at_its_stated_power(renders):
    found = assert_replicates_agree(renders["runs_a"], renders["runs_b"], what="right")
    assert found.detectable.image_mean <= DETECT[0] and found.detectable.block <= DETECT[1]


@pytest.mark.parametrize("wrong", ["x1.02", "x1.05", "x1.10", "one block x1.05",
                                   "shifted 2 px", "missing bounce"])
def test_replicates_checker_rejects_wrong_images(renders, wrong):
    if wrong == "missing bounce":
        imgs = renders["runs_short"]
    else:
        imgs = _wrong_images(renders["runs_a"])[wrong]
    with pytest.raises(AssertionError, match="differ beyond"):
        assert_replicates_agree(imgs, renders["runs_b"], what=wrong)


def test_replicates_checker_with_four_runs_a_side_admits_it_is_blind():
    """The audit's case: 4 replicates a side leave 3 degrees of freedom and an interval ~50
    standard errors wide, so an image 1.5 times too bright passes the comparison itself; the
    power check then refuses to certify anything with so few replicates."""
    rng = np.random.default_rng(3)
    a = 1.0 + 0.4 * rng.normal(size=(4, 16, 16, 3))
    b = 1.0 + 0.4 * rng.normal(size=(4, 16, 16, 3))
    assert_replicates_agree(a * 1.5, b, detect=None)
    with pytest.raises(AssertionError, match="too few samples"):
        assert_replicates_agree(a * 1.5, b)


# ------------------------------------------------------------------ the power figure is right
def _fraction_flagged(check, trials, rng):
    flagged = 0
    for _ in range(trials):
        try:
            check(rng)
        except AssertionError:
            flagged += 1
    return flagged / trials


@pytest.mark.parametrize("checker", ["two_images", "replicates"])
def test_reported_detectable_error_is_caught_with_the_stated_power(checker):
    """Synthetic images with known Gaussian noise: a whole-image scale error of exactly the
    reported image-mean figure is flagged in >= 99 % of trials (checked within a binomial
    interval), and right images in at most the false-alarm rate."""
    h = w = 16
    truth = np.linspace(0.5, 1.5, h * w * 3).reshape(h, w, 3)
    sigma = 0.02

    if checker == "two_images":
        var = np.full((h, w, 3), sigma**2)

        def check(scale, rng, detect=None):
            a = truth * scale + sigma * rng.normal(size=truth.shape)
            b = truth + sigma * rng.normal(size=truth.shape)
            return assert_two_images_agree(a, var, b, var, detect=detect, what="synthetic")
    else:
        def check(scale, rng, detect=None):
            a = truth * scale + sigma * rng.normal(size=(16,) + truth.shape)
            b = truth + sigma * rng.normal(size=(16,) + truth.shape)
            return assert_replicates_agree(a, b, detect=detect, what="synthetic")

    rng = np.random.default_rng(11)
    found = check(1.0, rng).detectable.image_mean
    trials = 300
    caught = _fraction_flagged(lambda r: check(1.0 + found, r), trials, rng)
    # Binomial: with a true rate of POWER, 300 trials fall 4 standard errors short of it with
    # probability ~3e-5.
    assert caught >= POWER - 4.0 * np.sqrt(POWER * (1 - POWER) / trials), (
        f"{checker}: a {found:.2%} error caught in only {caught:.1%} of trials")
    false_alarms = _fraction_flagged(lambda r: check(1.0, r), trials, rng)
    assert false_alarms <= 0.01, f"{checker}: {false_alarms:.1%} of right images flagged"
