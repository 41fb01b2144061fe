"""The Sobol stream's fused draw (issue 12, sixth round) gives exactly the values of its
definition: per padded slot, Owen(Sobol_c(shuffle(i))) with keys hashed from (pixel, slot,
seed). Exact equality: any changed bit of any value fails."""

import numpy as np
import pytest

from sampling_lab.core.sampling import lowdiscrepancy as ld
from sampling_lab.core.sampling.samplers.sobol import SobolSampler
from sampling_lab.core.sampling.stream import hash_u32


def _reference(pixel, index, seed, dimension, count):
    """The values of ``sample(dimension, count)`` from the building blocks, slot by slot."""
    key = ld.path_keys(pixel, seed, 0x510E527F)
    out = np.empty((pixel.size, count))
    for d in range(0, count, 2):
        slot = ld.slot_keys(key, dimension + d)
        shuffled = ld.shuffle_index(index.astype(np.uint32), ld.sub_key(slot, 0))
        for c in range(min(2, count - d)):
            point = ld.reverse_bits(ld.sobol_reversed(c, shuffled))
            out[:, d + c] = ld.unit_from_u32(ld.owen_scramble(point, ld.sub_key(slot, 1 + c)))
    return out


@pytest.mark.parametrize("count", [1, 2, 3, 5])
def test_sobol_stream_sample_equals_the_slot_definition_bit_for_bit(count):
    rng = np.random.default_rng(12)
    pixel = rng.integers(0, 2**33, 3000)  # high 32 bits count too
    index = rng.integers(0, 2**20, 3000)
    stream = SobolSampler(seed=7).stream(pixel, index)
    for dimension in (0, 9):
        np.testing.assert_array_equal(stream.sample(dimension, count),
                                      _reference(pixel, index, 7, dimension, count))


def test_sobol_stream_after_compaction_equals_a_stream_of_the_kept_paths():
    rng = np.random.default_rng(5)
    pixel, index = rng.integers(0, 9216, 2000), rng.integers(0, 64, 2000)
    stream = SobolSampler(seed=1).stream(pixel, index)
    keep = rng.random(2000) < 0.4
    stream.compact(keep)
    np.testing.assert_array_equal(stream.sample(4, 2), _reference(pixel[keep], index[keep],
                                                                  1, 4, 2))


def test_hash_u32_of_arrays_equals_the_scalar_form():
    """The in-place array form of lowbias32 against its scalar branch, element by element."""
    x = np.random.default_rng(0).integers(0, 2**32, 200).astype(np.uint32)
    x[:3] = (0, 1, 0xFFFFFFFF)
    want = np.array([hash_u32(np.uint32(v)) for v in x], np.uint32)
    np.testing.assert_array_equal(hash_u32(x), want)
    np.testing.assert_array_equal(hash_u32(x.reshape(20, 10)), want.reshape(20, 10))


def test_sub_keys_rows_equal_sub_key_and_unit_into_equals_unit_from_u32():
    key = np.random.default_rng(1).integers(0, 2**32, 500).astype(np.uint32)
    rows = ld.sub_keys(key, 3)
    for s in range(3):
        np.testing.assert_array_equal(rows[s], ld.sub_key(key, s))
    out = np.empty((500, 3))
    ld.unit_from_u32_into(rows.copy(), out.T)
    np.testing.assert_array_equal(out, ld.unit_from_u32(rows).T)


@pytest.mark.parametrize("sampler", ["sobol", "independent", "stratified"])
def test_next_slots_equals_the_calls_one_by_one(sampler):
    """A bounce's draws in one call (the path tracer's 1, 2, 1, 2, 1 with skipped dimensions)
    give exactly the values of next_1d / next_2d / a skipped dimension, and the same final
    dimension."""
    from sampling_lab.core.sampling.samplers import make_sampler
    rng = np.random.default_rng(4)
    pixel, index = rng.integers(0, 9216, 1500), rng.integers(0, 64, 1500)
    make = make_sampler(sampler, seed=3, spp=64, width=96)
    for sizes in [(1, 2, 1, 2, 1), (1, 2, 0, 2, 0), (2,), (1,), (0, 0), (2, 2, 1)]:
        one, many = make.stream(pixel, index), make.stream(pixel, index)
        one.skip_to(9)
        many.skip_to(9)
        want = []
        for size in sizes:
            if size == 0:
                one.skip_to(one.dimension + 1)
            want.append(None if size == 0 else one.next_1d() if size == 1 else one.next_2d())
        got = many.next_slots(sizes)
        assert many.dimension == one.dimension
        for w, g in zip(want, got):
            if w is None:
                assert g is None
            else:
                np.testing.assert_array_equal(g, w)
