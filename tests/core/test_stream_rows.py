"""``SampleStream.slots_of_rows`` (issue 12, eighth round): the numbers of many paths, each
from its own dimension, in one call, as BDPT's ``s = 1`` emitter points draw them for the
connectible camera vertices of every depth at once.

Properties: for every row, the values equal those of a copy of the stream compacted to that
path and skipped to that dimension (the definition), for the generic implementation (one copy
per distinct dimension) and for the row-wise overrides of the Sobol stream (also when the rows
are cut into batches) and of the independent stream; the stream itself is not advanced. Smallest error detected: any changed bit
of any value (byte equality).
"""

import copy

import numpy as np
import pytest

from sampling_lab.core.sampling.samplers import make_sampler
from sampling_lab.core.sampling.samplers import independent, sobol


def _stream(name, n=3000):
    rng = np.random.default_rng(3)
    return make_sampler(name, seed=4, spp=16, width=64).stream(rng.integers(0, 4096, n),
                                                              rng.integers(0, 16, n))


def _rows(n, m=2500):
    rng = np.random.default_rng(m)
    level = np.sort(rng.integers(0, 6, m))  # depth-major, as BDPT lists its vertices
    return rng.integers(0, n, m), 7 + 9 * level


def _definition(stream, rows, dims, sizes):
    out = [[] for _ in sizes]
    for r, d in zip(rows.tolist(), dims.tolist()):
        part = copy.copy(stream)
        part.compact(np.array([r]))
        part.skip_to(d)
        for o, value in zip(out, part.next_slots(sizes)):
            o.append(value[0])
    return [np.array(o) for o in out]


def _same(a, b):
    return all(x.shape == y.shape and np.ascontiguousarray(x).tobytes()
               == np.ascontiguousarray(y).tobytes() for x, y in zip(a, b))


@pytest.mark.parametrize("name", ["sobol", "independent", "halton"])
def test_rows_of_mixed_dimensions_draw_what_a_compacted_copy_draws(name):
    stream = _stream(name)
    rows, dims = _rows(len(stream), m=300)
    got = stream.slots_of_rows(rows, dims, (1, 2))
    assert stream.dimension == 0
    assert _same(got, _definition(stream, rows, dims, (1, 2)))


@pytest.mark.parametrize("sizes", [(1, 2), (2,), (2, 1, 1)])
def test_sobol_rows_equal_the_generic_copies_also_in_batches(monkeypatch, sizes):
    stream = _stream("sobol")
    rows, dims = _rows(len(stream))
    generic = super(sobol.SobolStream, stream).slots_of_rows(rows, dims, sizes)
    assert _same(stream.slots_of_rows(rows, dims, sizes), generic)
    monkeypatch.setattr(sobol, "BATCH_PATHS", 700)  # batches of rows, the last one partial
    assert _same(stream.slots_of_rows(rows, dims, sizes), generic)


@pytest.mark.parametrize("sizes", [(1, 2), (2,), (2, 1, 1)])
def test_independent_rows_equal_the_generic_copies(sizes):
    stream = _stream("independent")
    rows, dims = _rows(len(stream))
    generic = super(independent.IndependentStream, stream).slots_of_rows(rows, dims, sizes)
    assert _same(stream.slots_of_rows(rows, dims, sizes), generic)
    assert stream.dimension == 0
