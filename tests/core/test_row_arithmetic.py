"""core.rows (norms, scaled, dots): the component-wise row arithmetic gives NumPy's broadcast results bit for bit
(so the connections and shadow rays that use it render the same images)."""

import numpy as np

from sampling_lab.core.rows import DOTS_COLUMNWISE_ROWS, dots, norms, scaled


def _rows(rng, n=20000):
    """Row vectors over many magnitudes, with zeros, subnormals, infinities and NaN."""
    v = rng.standard_normal((n, 3)) * np.exp(rng.uniform(-300, 300, (n, 1)))
    v[:10] = 0.0
    v[10:20, 1] = 5e-324
    v[20, 0], v[21, 2], v[22, 1] = np.inf, -np.inf, np.nan
    return v


def test_norms_equal_linalg_norm_bit_for_bit():
    v = _rows(np.random.default_rng(1))
    with np.errstate(over="ignore", invalid="ignore"):
        np.testing.assert_array_equal(norms(v), np.linalg.norm(v, axis=1))


def test_scaled_equals_broadcast_product_bit_for_bit():
    rng = np.random.default_rng(2)
    v = _rows(rng)
    s = rng.standard_normal(v.shape[0]) * np.exp(rng.uniform(-300, 300, v.shape[0]))
    s[:5] = 0.0
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        want = v * s[:, None]
        np.testing.assert_array_equal(scaled(v, s), want)
        out = v.copy()
        assert scaled(out, s, out=out) is out
        np.testing.assert_array_equal(out, want)


def test_scaled_keeps_float32_rows_float32_with_float32_scales():
    v = np.ones((4, 3), np.float32)
    assert scaled(v, np.full(4, 2.0, np.float32)).dtype == np.float32


def test_dots_equal_einsum_bit_for_bit():
    # Rows contiguous and strided, batches below and above the column-wise threshold, with
    # magnitudes over 600 orders (rounding differs if the products are added in another
    # order), zeros, subnormals, infinities and NaN; and into a column of a table (out=).
    rng = np.random.default_rng(3)
    for n in (1, 7, DOTS_COLUMNWISE_ROWS - 1, DOTS_COLUMNWISE_ROWS, 20000):
        a, b = _rows(rng, max(n, 30))[:n], _rows(rng, max(n, 30))[:n]
        wide = np.zeros((2 * n, 4))
        wide[::2, :3] = a
        with np.errstate(over="ignore", invalid="ignore", under="ignore"):
            want = np.einsum("ij,ij->i", a, b)
            np.testing.assert_array_equal(dots(a, b), want)
            np.testing.assert_array_equal(dots(wide[::2, :3], b), want)
            table = np.zeros((n, 3))
            assert dots(a, b, out=table[:, 2]).base is table
            np.testing.assert_array_equal(table[:, 2], want)
    # float32 rows (einsum adds them in another order), a Fortran-ordered operand and mixed
    # types (einsum itself).
    f = np.asfortranarray(_rows(rng, 5000))
    g = _rows(rng, 5000)
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        np.testing.assert_array_equal(dots(f, g), np.einsum("ij,ij->i", f, g))
        h = (rng.standard_normal((5000, 3)) * np.exp(rng.uniform(-20, 20, (5000, 1))))
        h, k = h.astype(np.float32), (rng.standard_normal((5000, 3)) * 1e3).astype(np.float32)
        assert dots(h, k).dtype == np.float32
        np.testing.assert_array_equal(dots(h, k), np.einsum("ij,ij->i", h, k))
        np.testing.assert_array_equal(dots(h, g), np.einsum("ij,ij->i", h, g))
