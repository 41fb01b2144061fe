"""The hard-scenes benchmark's reference (``tools/hard_scenes_reference.py``) measures its own
noise without bias and averages two renderers' references only when they agree.

Synthetic images: a known image plus Gaussian noise of known per-pixel variance in chunks of
unequal sample counts, so the true noise of every estimate is known exactly.
"""

import numpy as np

from sampling_lab.tools.common import EPS
from sampling_lab.tools.hard_scenes_reference import chunk_mean, combine, noise
from tests.helpers import assert_mean_within_ci

SHAPE = (24, 24, 3)
TRIALS = 300


def _truth(rng):
    return rng.uniform(0.05, 2.0, SHAPE)


def _chunks(rng, truth, sigma, counts, bias=1.0):
    """Independent chunk images: ``truth * bias`` plus noise of variance ``sigma^2 / n``."""
    return [truth * bias + rng.normal(size=SHAPE) * sigma / np.sqrt(n) for n in counts]


def test_chunk_variance_of_unequal_chunks_is_an_unbiased_estimate_of_the_mean_noise():
    rng = np.random.default_rng(1)
    truth = _truth(rng)
    sigma = 0.3 * truth * rng.uniform(0.5, 2.0, SHAPE)
    counts = [16, 16, 20, 11]
    true_noise = noise(sigma ** 2 / sum(counts), truth)
    estimates = [noise(chunk_mean(_chunks(rng, truth, sigma, counts), counts)[1], truth)
                 for _ in range(TRIALS)]
    # Detects a relative error of the noise estimate of about 0.5 % (4 standard errors of 0.13 %):
    # dividing by k instead of k - 1 (25 %) fails by far.
    assert_mean_within_ci(estimates, true_noise, what="noise estimated from the chunks")


def test_combined_reference_error_against_the_truth_is_its_measured_noise_and_below_either():
    rng = np.random.default_rng(2)
    truth = _truth(rng)
    sigma_a, sigma_b = 0.2 * truth, 0.4 * truth
    counts = [8] * 4
    excess, weights, floors = [], [], []
    for _ in range(TRIALS):
        a, va = chunk_mean(_chunks(rng, truth, sigma_a, counts), counts)
        b, vb = chunk_mean(_chunks(rng, truth, sigma_b, counts), counts)
        ref = combine(a, va, b, vb)
        assert ref.agree
        err = np.mean((ref.image - truth) ** 2 / (truth ** 2 + EPS))
        excess.append(err - noise(ref.variance, truth))
        weights.append(ref.weight_ours)
        floors.append(noise(ref.variance, truth))
    # The measured noise is the combined image's actual squared error (unbiased); the weights
    # are inverse noise (a has a quarter of b's variance: weight 0.8); the average is quieter
    # than the better reference alone (by the factor 0.8).
    mean_err, se = assert_mean_within_ci(excess, 0.0, what="error minus measured noise")
    assert abs(np.mean(weights) - 0.8) < 0.02
    best_alone = noise(sigma_a ** 2 / sum(counts), truth)
    assert np.mean(floors) < 0.85 * best_alone
    # Smallest error detected: about 4 standard errors of that difference, a few per cent of
    # the noise itself.
    assert 4 * se < 0.05 * np.mean(floors)


def test_references_that_disagree_by_half_a_percent_are_not_averaged():
    rng = np.random.default_rng(3)
    truth = _truth(rng)
    sigma = 0.01 * truth
    counts = [64] * 4
    a, va = chunk_mean(_chunks(rng, truth, sigma, counts), counts)
    b, vb = chunk_mean(_chunks(rng, truth, sigma, counts, bias=1.005), counts)
    ref = combine(a, va, b, vb)
    assert not ref.agree
    assert ref.weight_ours == 1.0 and np.array_equal(ref.image, a)
    assert ref.excess > 10 * ref.excess_se
