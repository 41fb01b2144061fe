"""Row helpers (core/rows.py) give the values of the NumPy expressions they replace, bit for
bit: ``combine_rows`` (weighted sums of (k, c) rows) and ``divide_rows`` (rows over per-row
divisors), column by column on large float64 batches (combinations of very large ones in place), and ``put_rows`` (row scatters).

Smallest error detected: any difference at all (arrays are compared for equality), on batches
below and above the column-wise threshold, with a base and without, and in float32.
"""

import numpy as np
import pytest

from sampling_lab.core.rows import (COLUMNWISE_MAX_ROWS, COLUMNWISE_ROWS, combine_rows, divide_rows,
                                    put_rows)


@pytest.mark.parametrize("k", [0, 7, COLUMNWISE_ROWS - 1, COLUMNWISE_ROWS, 3 * COLUMNWISE_ROWS,
                               COLUMNWISE_MAX_ROWS + 1])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_combine_rows_is_the_broadcast_expression_bit_for_bit(k, dtype):
    rng = np.random.default_rng(k)
    a, b, c = (rng.normal(size=k).astype(dtype) * 1e3 for _ in range(3))
    u, v, w, base = (rng.normal(size=(k, 3)).astype(dtype) for _ in range(4))
    np.testing.assert_array_equal(combine_rows(((a, u),)), a[:, None] * u)
    np.testing.assert_array_equal(combine_rows(((a, u), (b, v), (c, w))),
                                  a[:, None] * u + b[:, None] * v + c[:, None] * w)
    got = combine_rows(((a, u), (b, v)), base=base)
    np.testing.assert_array_equal(got, base + a[:, None] * u + b[:, None] * v)
    assert got.dtype == (base + a[:, None] * u).dtype and got.shape == (k, 3)


@pytest.mark.parametrize("k", [0, 5, COLUMNWISE_ROWS, 2 * COLUMNWISE_ROWS + 1])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_divide_rows_is_the_broadcast_division_bit_for_bit(k, dtype):
    rng = np.random.default_rng(k + 1)
    v = rng.normal(size=(k, 3)).astype(dtype)
    d = rng.uniform(1e-3, 10.0, k).astype(dtype)
    got = divide_rows(v, d)
    np.testing.assert_array_equal(got, v / d[:, None])
    assert got.dtype == (v / d[:, None]).dtype


@pytest.mark.parametrize("k", [2 * COLUMNWISE_ROWS, COLUMNWISE_MAX_ROWS + 1])
def test_combine_rows_keeps_nonfinite_values_where_the_expression_has_them(k):
    a = np.ones(k)
    a[:3] = (np.inf, np.nan, 0.0)
    u = np.ones((k, 3))
    u[2] = np.inf  # 0 * inf
    with np.errstate(invalid="ignore"):
        expected = 1.0 + a[:, None] * u
        got = combine_rows(((a, u),), base=np.ones((k, 3)))
    np.testing.assert_array_equal(got, expected)


def test_put_rows_scatters_as_fancy_assignment():
    rng = np.random.default_rng(1)
    dst, ref = np.zeros((50, 3)), np.zeros((50, 3))
    rows = rng.choice(50, 20, replace=False)
    src = rng.normal(size=(20, 3))
    put_rows(dst, rows, src)
    ref[rows] = src
    np.testing.assert_array_equal(dst, ref)
