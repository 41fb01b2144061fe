"""Row scatters of NumPy arrays faster than fancy-index assignment (same values)."""

from __future__ import annotations

import numpy as np


def put_rows(dst, rows, src):
    """``dst[rows] = src`` for a C-contiguous ``dst (n,)`` or ``(n, c)``; ``src (k,)`` or
    ``(k, c)`` (or a scalar). Rows of ``(n, c)`` arrays are scattered as single ``c``-element
    items (``np.put`` on a byte-row view): about 3 x faster than ``dst[rows] = src``, which
    scatters element by element; the stored values are the same."""
    if dst.ndim == 1:
        dst[rows] = src
        return
    item = np.dtype((np.void, dst.strides[0]))
    shape = (rows.size,) + dst.shape[1:]
    src = np.ascontiguousarray(src if np.shape(src) == shape else np.broadcast_to(src, shape),
                               dst.dtype)
    np.put(dst.view(item).reshape(-1), rows, src.view(item).reshape(-1))


# Rows at which :func:`combine_rows` goes column by column: a (k, 1) x (k, 3) broadcast costs
# about four times the plain operations at 16k rows (NumPy 1.26, this machine's x86), and
# column-wise calls cost more than it saves below a few thousand rows.
COLUMNWISE_ROWS = 2048


def combine_rows(terms, base=None):
    """``base + a_1[:, None] * v_1 + a_2[:, None] * v_2 + ...`` for weights ``a_i (k,)``
    and rows ``v_i (k, c)`` (``base (k, c)`` or None), added left to right as written.

    The same values as that expression (each product rounded, then added in that order);
    float64 batches of :data:`COLUMNWISE_ROWS` rows or more are computed column by column,
    each operation one long loop instead of ``k`` loops of ``c`` elements."""
    arrays = [x for term in terms for x in term] + ([] if base is None else [base])
    (a0, v0), k = terms[0], terms[0][0].shape[0]
    if k < COLUMNWISE_ROWS or any(x.dtype != np.float64 for x in arrays):
        out = a0[:, None] * v0 if base is None else base + a0[:, None] * v0
        for a, v in terms[1:]:
            out = out + a[:, None] * v
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
