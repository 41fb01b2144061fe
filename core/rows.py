"""Row operations on NumPy arrays, faster than NumPy's plain forms and with the same values:
row scatters (:func:`put_rows`) and row-wise arithmetic on ``(k, c)`` vectors done one component
at a time (:func:`combine_rows`, :func:`divide_rows`, :func:`scaled`, :func:`norms`,
:func:`dots`).

NumPy broadcasts a ``(k, 3)`` array against a ``(k, 1)`` column through an inner loop of three
elements per row: on 8,192 rows ``v * s[:, None]`` took 22 us against 9 us here and 4 us for
``v * v``, and ``np.linalg.norm(v, axis=1)`` (a reduction over a short axis) 103 us against
18 us here (NumPy 1.26, 2026-11-26). A division gains little either way (``v / s[:, None]``
25 us, 24 per component; :func:`divide_rows` goes by columns only on large batches). The
functions do the same IEEE operations per element, component by component into one output, so
their results are the same to the last bit: ``norms`` forms ``(x * x + y * y) + z * z`` as ``np.linalg.norm``'s
reduction over three elements does (``tests/core/test_row_arithmetic.py``). On arrays of a few
hundred rows the broadcast's one call costs no more than three.
"""

from __future__ import annotations

import numpy as np


def put_rows(dst, rows, src):
    """``dst[rows] = src`` for ``dst (n,)`` or ``(n, c)``; ``src (k,)`` or ``(k, c)`` (or a
    scalar). Rows of C-contiguous ``(n, c)`` arrays are scattered as single ``c``-element
    items (``np.put`` on a byte-row view): about 3 x faster than ``dst[rows] = src``, which
    scatters element by element; the stored values are the same."""
    if dst.ndim == 1 or not dst.flags.c_contiguous:
        dst[rows] = src
        return
    item = np.dtype((np.void, dst.strides[0]))
    shape = (rows.size,) + dst.shape[1:]
    src = np.ascontiguousarray(src if np.shape(src) == shape else np.broadcast_to(src, shape),
                               dst.dtype)
    dst.view(item).reshape(-1).put(rows, src.view(item).reshape(-1))


# Rows at which :func:`combine_rows` goes column by column: a (k, 1) x (k, 3) broadcast costs
# about four times the plain operations at 16k rows (NumPy 1.26, this machine's x86), and
# column-wise calls cost more than it saves below a few thousand rows.
COLUMNWISE_ROWS = 2048
# ... and up to which it does: above it the inputs of a combination no longer fit in the core's
# cache together, and each column pass streams every input again. On an Intel Xeon VM (2 MB L2,
# 2026-11-26) two terms and a base took 8.2 ns per row column by column against 11.3 broadcast at
# 8 k rows, the same at 16 k, and 18.1 against 13.5 at 32 k.
COLUMNWISE_MAX_ROWS = 16384


def combine_rows(terms, base=None):
    """``base + a_1[:, None] * v_1 + a_2[:, None] * v_2 + ...`` for weights ``a_i (k,)``
    and rows ``v_i (k, c)`` (``base (k, c)`` or None), added left to right as written.

    The same values as that expression (each product rounded, then added in that order);
    float64 batches of :data:`COLUMNWISE_ROWS` to :data:`COLUMNWISE_MAX_ROWS` rows are
    computed column by column, each operation one long loop instead of ``k`` loops of ``c``
    elements; larger ones add each product in place (``x + y`` is ``y + x`` in IEEE
    arithmetic, so the values are the same)."""
    arrays = [x for term in terms for x in term] + ([] if base is None else [base])
    (a0, v0), k = terms[0], terms[0][0].shape[0]
    if k < COLUMNWISE_ROWS or any(x.dtype != np.float64 for x in arrays):
        out = a0[:, None] * v0 if base is None else base + a0[:, None] * v0
        for a, v in terms[1:]:
            out = out + a[:, None] * v
        return out
    if k > COLUMNWISE_MAX_ROWS:
        out = a0[:, None] * v0
        if base is not None:
            out += base
        for a, v in terms[1:]:
            out += a[:, None] * v
        return out
    out = np.empty(v0.shape)
    for c in range(v0.shape[1]):
        column = out[:, c]
        np.multiply(a0, v0[:, c], out=column)
        if base is not None:
            np.add(base[:, c], column, out=column)
        for a, v in terms[1:]:
            column += a * v[:, c]
    return out


def divide_rows(v, d):
    """``v / d[:, None]`` for rows ``v (k, c)`` and divisors ``d (k,)``: the same values,
    column by column on large float64 batches (as :func:`combine_rows`)."""
    if d.shape[0] < COLUMNWISE_ROWS or v.dtype != np.float64 or d.dtype != np.float64:
        return v / d[:, None]
    out = np.empty(v.shape)
    for c in range(v.shape[1]):
        np.divide(v[:, c], d, out=out[:, c])
    return out


def norms(v):
    """``np.linalg.norm(v, axis=1)`` of ``v (k, 3)``: ``(k,)``, the same values."""
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    out = x * x
    out += y * y
    out += z * z
    return np.sqrt(out, out=out)


# The smallest value divided by, per dtype (:func:`at_least_tiny`): float32 rows would round
# float64's 1e-300 to zero.
_TINY = {np.dtype(np.float64): 1e-300, np.dtype(np.float32): float(np.finfo(np.float32).tiny)}


def at_least_tiny(x):
    """``x`` (float64 or float32) with values below its dtype's smallest divisor (1e-300;
    float32's smallest normal number) raised to it: no division by zero."""
    return np.maximum(x, _TINY[x.dtype])


# Rows from which :func:`dots` goes column by column: below, its five calls cost more than
# einsum's one.
DOTS_COLUMNWISE_ROWS = 512


def dots(a, b, out=None):
    """``np.einsum("ij,ij->i", a, b)`` of rows ``a, b (k, 3)``: ``(k,)``, the same values.

    einsum's loop for this product costs about twice the three column products on the row
    counts of a batch (16,384 rows: 58.7 against 29.3 us; 4,096: 15.1 against 8.5; float32,
    32,768 rows: 110.6 against 48.1; NumPy 1.26, Intel Xeon VM, 2026-11-26). It adds the three
    products as ``(x + z) + y`` in float64 and as ``(x + y) + z`` in float32 (measured: every
    row of random inputs of any size, rows contiguous or strided), and so does this: the same
    bits. Other layouts (Fortran-ordered, mixed types, not three columns) and small batches go
    to einsum itself. ``out``: a ``(k,)`` array of the rows' type (or a column view) to write
    them into."""
    if (a.shape[0] < DOTS_COLUMNWISE_ROWS or a.ndim != 2 or a.shape[1] != 3
            or a.shape != b.shape or a.dtype != b.dtype
            or a.dtype not in _DOT_ORDER or a.strides[1] != a.itemsize
            or b.strides[1] != b.itemsize):
        return np.einsum("ij,ij->i", a, b, out=out)
    first, second, third = _DOT_ORDER[a.dtype]
    out = np.multiply(a[:, first], b[:, first], out=out)
    out += a[:, second] * b[:, second]
    out += a[:, third] * b[:, third]
    return out


# The order in which einsum adds a row's three products, by type (see dots).
_DOT_ORDER = {np.dtype(np.float64): (0, 2, 1), np.dtype(np.float32): (0, 1, 2)}


def scaled(v, s, out=None):
    """``v * s[:, None]`` of ``v (k, 3)`` and ``s (k,)``: ``(k, 3)``, the same values
    (``out``: where to write them, may be ``v``)."""
    if out is None:
        out = np.empty(v.shape, v.dtype if v.dtype == s.dtype else np.result_type(v, s))
    for i in range(3):
        np.multiply(v[:, i], s, out=out[:, i])
    return out

