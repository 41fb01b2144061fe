"""Discrete and piecewise-constant distributions over arrays.

Each has ``sample(u) -> (index, pmf, u_remapped)``: ``u`` is uniform in [0, 1), ``index`` the
chosen bin, ``pmf`` its probability (for a continuous distribution, the bin's probability; the
density is ``pmf * n`` on [0, 1)), and ``u_remapped`` the position of ``u`` inside the bin, again
uniform in [0, 1), so one random number can drive a choice and then a continuous sample.

Two ways to make a discrete choice, selectable wherever the renderer makes one
(``method='cdf' | 'alias'``, see :func:`make_distribution`):

- ``'cdf'``: :class:`PiecewiseConstant1D`, inversion of the cumulative distribution by binary
  search. O(n) build, O(log n) per sample; it maps ``u`` monotonically onto the bins, so
  stratified or low-discrepancy ``u`` stay stratified over the bins.
- ``'alias'``: :class:`AliasTable` (Walker 1977, Vose 1991). O(n) build, O(1) per sample
  (one column, one comparison); the map from ``u`` to bins is not monotone, so it scrambles
  the stratification of ``u`` across bins.

:class:`Segmented1D` holds many small distributions back to back (the conditional rows of a 2-D
distribution, the triangles of each emissive material) and samples each query from its own
segment, with the same two methods; :class:`PiecewiseConstant2D` is a marginal over rows times
a :class:`Segmented1D` of conditional rows.
"""

from __future__ import annotations

import numpy as np

from ..quiet import quiet

DISTRIBUTION_METHODS = ("cdf", "alias")

_ONE_MINUS = np.nextafter(1.0, 0.0)
KEY_DTYPE = np.longdouble


def _clean_weights(func):
    """Non-negative float64 weights ``(n,)``; NaN and infinity count as zero."""
    func = np.abs(np.asarray(func, np.float64)).reshape(-1)
    return np.where(np.isfinite(func), func, 0.0)


def search_right(values, lo, hi, x):
    """First index ``i`` in ``[lo, hi)`` with ``values[i] > x``, else ``hi``: a batched bisection.

    Each query searches its own sorted range of one flat array, so ragged families of sorted
    arrays (per-row CDFs, per-segment running sums) are searched in one vectorized call.

    Parameters
    ----------
    values : (N,) float
        Non-decreasing inside every queried range.
    lo, hi : (q,) int64
        Half-open index range of each query (``lo <= hi``).
    x : (q,) float
        Query values.

    Returns
    -------
    (q,) int64
    """
    lo = np.asarray(lo, np.int64).copy()
    hi = np.asarray(hi, np.int64).copy()
    x = np.asarray(x)
    if lo.size == 0:
        return lo
    last = max(values.shape[0] - 1, 0)
    # Bisection halves every range per step, so the longest range bounds the step count.
    for _ in range(int(np.max(hi - lo, initial=0)).bit_length() + 1):
        active = lo < hi
        if not active.any():
            break
        mid = (lo + hi) >> 1
        right = active & (values[np.minimum(mid, last)] <= x)
        lo = np.where(right, mid + 1, lo)
        hi = np.where(active & ~right, mid, hi)
    return lo


def _segment_ids(offsets):
    """Segment of every element for segment ``offsets (r + 1,)``: ``(N,)`` int64."""
    lengths = np.diff(offsets)
    return np.repeat(np.arange(lengths.size, dtype=np.int64), lengths)


def _segment_pmf(func, offsets):
    """Per-segment normalised weights; segments without mass become uniform. ``(N,)``."""
    seg = _segment_ids(offsets)
    lengths = np.diff(offsets)
    total = np.add.reduceat(func, offsets[:-1]) if func.size else np.zeros(0)
    empty = ~(np.isfinite(total) & (total > 0))
    func = np.where(empty[seg], 1.0, func)
    total = np.where(empty, lengths.astype(np.float64), total)
    return func / total[seg], func


def _local_running_sum(x, offsets, seg, dtype=np.longdouble):
    """Inclusive running sum of ``x`` restarted at every segment.

    The running sums of all segments come from one cumulative sum minus each segment's starting
    value, by default in ``np.longdouble`` (80-bit on x86) so that subtracting a large prefix
    does not cost the small segments their precision.
    """
    run = np.cumsum(x.astype(dtype))
    start = np.concatenate([np.zeros(1, dtype), run])[offsets[:-1]]
    return run - start[seg]


def _heavy_bins(scaled, offsets, seg):
    """Bins at or above one column (``scaled >= 1``), at least one per segment: rounding can
    leave a segment with every bin at ``1 - eps``, whose largest bin is then promoted."""
    n = scaled.size
    heavy = scaled >= 1.0
    has_heavy = np.logical_or.reduceat(heavy, offsets[:-1])
    if not has_heavy.all():
        seg_max = np.maximum.reduceat(scaled, offsets[:-1])
        first_max = np.minimum.reduceat(np.where(scaled == seg_max[seg], np.arange(n), n),
                                        offsets[:-1])
        heavy[first_max[~has_heavy]] = True
    return heavy


def _alias_light_bins(prob, alias, scaled, deficit, deficit_end, surplus_key, seg, hv, lt,
                      h_first, h_last):
    """Fill ``prob`` and ``alias`` of the light bins ``lt`` (see :func:`build_alias_segments`)."""
    # Light bins keep their own mass and alias the heavy bin whose surplus holds their start.
    if lt.size:
        s = seg[lt]
        start = deficit_end[lt] - deficit[lt]
        j = np.searchsorted(surplus_key[hv], start, side="right")
        prob[lt] = scaled[lt]
        alias[lt] = hv[np.clip(j, h_first[s], h_last[s])]


def _top_up_heavy_bins(prob, alias, deficit, deficit_end, surplus_key, seg, hv, lt, h_last,
                       l_stop):
    """Fill ``prob`` and ``alias`` of the heavy bins ``hv`` (see :func:`build_alias_segments`)."""
    # Heavy bins (but each segment's last) lack the overshoot of the light bin straddling the
    # end of their surplus; the next heavy bin supplies it.
    pos = np.arange(hv.size)
    inner = pos != h_last[seg[hv]]
    hi_, pos = hv[inner], pos[inner]
    if hi_.size and lt.size:
        s = seg[hi_]
        end = surplus_key[hi_]
        i = np.searchsorted(deficit_end[lt], end, side="right")
        found = i < l_stop[s]
        li = lt[np.minimum(i, lt.size - 1)]
        straddles = found & (deficit_end[li] - deficit[li] < end)
        overshoot = np.where(straddles, (deficit_end[li] - end).astype(np.float64), 0.0)
        prob[hi_] = 1.0 - overshoot
    if hi_.size:
        alias[hi_] = hv[pos + 1]


def build_alias_segments(func, offsets):
    """Alias tables of many distributions at once (Vose's pairing, vectorized by prefix sums).

    Vose's algorithm pairs each under-full column (scaled weight ``s < 1``, a *light* bin) with an
    over-full *heavy* bin that tops it up. Sweeping both lists in index order (Hübschle-Schneider
    and Sanders 2019) makes the pairing a pure function of two running sums: laid end to end,
    the heavy bins' surpluses ``s - 1`` and the light bins' deficits ``1 - s`` cover the same
    interval; a light bin is aliased to the heavy bin whose surplus holds the start of its
    deficit, and a heavy bin whose surplus runs out inside some light bin's deficit becomes
    under-full by the overshoot, which the next heavy bin fills. Two sorted searches find all of
    it without a Python loop. Every comparison is made between the same two running sums, so
    each bin's mass is reproduced exactly up to the rounding of those sums (kept in extended
    precision).

    Parameters
    ----------
    func : (N,) float
        Non-negative weights of all segments back to back.
    offsets : (r + 1,) int
        Segment boundaries: segment ``j`` is ``func[offsets[j]:offsets[j + 1]]`` (non-empty).
        A segment without mass gets the uniform distribution.

    Returns
    -------
    prob : (N,) float64
        Probability of keeping the column's own bin.
    alias : (N,) int64
        Global index of the bin that takes the rest of the column (inside the same segment).
    pmf : (N,) float64
        Each bin's probability within its segment.
    """
    func = _clean_weights(func)
    offsets = np.asarray(offsets, np.int64)
    n = func.size
    seg = _segment_ids(offsets)
    lengths = np.diff(offsets)
    pmf, _ = _segment_pmf(func, offsets)
    scaled = pmf * lengths[seg]
    heavy = _heavy_bins(scaled, offsets, seg)
    light = ~heavy
    deficit = np.where(light, 1.0 - scaled, 0.0)
    surplus = np.where(heavy, np.maximum(scaled - 1.0, 0.0), 0.0)

    # One globally sorted key per stream: the deficits' running sum over all segments, and each
    # segment's surplus running sum placed at the same segment start (clamped to the segment's
    # end so that the keys stay sorted across segments despite rounding).
    deficit_end = np.cumsum(deficit.astype(KEY_DTYPE))
    seg_start = np.concatenate([np.zeros(1, KEY_DTYPE), deficit_end])[offsets[:-1]]
    seg_end = deficit_end[offsets[1:] - 1]
    surplus_key = np.minimum(seg_start[seg] + _local_running_sum(surplus, offsets, seg, KEY_DTYPE),
                             seg_end[seg])

    prob = np.ones(n)
    alias = np.arange(n, dtype=np.int64)
    hv = np.flatnonzero(heavy)
    lt = np.flatnonzero(light)
    h_first = np.searchsorted(hv, offsets[:-1])
    h_last = np.searchsorted(hv, offsets[1:]) - 1
    l_stop = np.searchsorted(lt, offsets[1:])

    _alias_light_bins(prob, alias, scaled, deficit, deficit_end, surplus_key, seg, hv, lt,
                      h_first, h_last)
    _top_up_heavy_bins(prob, alias, deficit, deficit_end, surplus_key, seg, hv, lt, h_last,
                       l_stop)
    return np.clip(prob, 0.0, 1.0), alias, pmf


class PiecewiseConstant1D:
    """Inverse-CDF sampling by binary search: O(n) build, O(log n) per sample.

    Parameters
    ----------
    func : (n,) float
        Non-negative weights. All zero gives the uniform distribution.
    """

    method = "cdf"

    def __init__(self, func):
        func = np.abs(np.asarray(func, np.float64)).reshape(-1)
        if func.size == 0:
            raise ValueError("PiecewiseConstant1D needs at least one bin")
        running = np.cumsum(func)
        total = running[-1]
        if not np.isfinite(total) or total <= 0:
            func = np.ones_like(func)
            running = np.cumsum(func)
            total = running[-1]
        self.func = func
        self.integral = total / func.size
        self.pmf_table = func / total
        # Normalise the running sum itself rather than summing normalised pmfs: a cumulative sum
        # of non-negative terms is monotone, and total / total is exactly 1, so the CDF is
        # non-decreasing and every bin after the last non-zero one ends at exactly 1.0. (Forcing
        # cdf[-1] = 1 after summing pmfs could overshoot 1 mid-table, or leave a sliver below 1
        # that mapped u to a trailing zero-weight bin with pmf 0.)
        self.cdf = np.concatenate([[0.0], running / total])

    def __len__(self):
        return self.func.size

    def sample(self, u):
        """Choose bins. ``u : (k,)`` -> ``index (k,) int64, pmf (k,), u_remapped (k,)``."""
        u = np.asarray(u, np.float64)
        if self.func.size == 1:
            # One bin (a scene with one light): nothing to search, and u keeps its value (the
            # remap below is (u - 0) / 1).
            return (np.zeros(u.shape, np.int64), np.full(u.shape, self.pmf_table[0]),
                    np.clip(u, 0.0, _ONE_MINUS))
        # side="right" puts a u equal to a run of equal CDF values (zero-mass bins) in the last
        # bin of the run, which is the next bin with mass: empty bins are never chosen.
        index = np.searchsorted(self.cdf, u, side="right") - 1
        index = np.clip(index, 0, self.func.size - 1)
        pmf = self.pmf_table[index]
        lo = self.cdf[index]
        # Remap by the bin's width in the CDF actually searched, so u_remapped spans [0, 1).
        width = self.cdf[index + 1] - lo
        with quiet("divide", "invalid"):
            u_remapped = np.where(width > 0, (u - lo) / width, 0.0)
        return index, pmf, np.clip(u_remapped, 0.0, _ONE_MINUS)

    def pmf(self, index):
        """Probability of choosing ``index (k,)``."""
        return self.pmf_table[index]


class AliasTable:
    """Walker/Vose alias method: O(n) build, O(1) per sample.

    The table is built by :func:`build_alias_segments` (vectorized; about 50 ms per million
    bins) and reproduces the pmf exactly up to rounding: bin ``i``'s probability is
    ``(prob[i] + sum of (1 - prob[j]) over columns j aliased to i) / n``.

    Parameters
    ----------
    func : (n,) float
        Non-negative weights. All zero gives the uniform distribution.
    """

    method = "alias"

    def __init__(self, func):
        func = np.abs(np.asarray(func, np.float64)).reshape(-1)
        n = func.size
        if n == 0:
            raise ValueError("AliasTable needs at least one bin")
        self.prob, self.alias, self.pmf_table = build_alias_segments(func, np.array([0, n]))

    def __len__(self):
        return self.prob.size

    def sample(self, u):
        """Choose bins. ``u : (k,)`` -> ``index (k,) int64, pmf (k,), u_remapped (k,)``."""
        u = np.asarray(u, np.float64)
        n = self.prob.size
        x = u * n
        column = np.minimum(x.astype(np.int64), n - 1)
        index, u_remapped = _alias_pick(self.prob, self.alias, column, x - column)
        return index, self.pmf_table[index], u_remapped

    def pmf(self, index):
        """Probability of choosing ``index (k,)``."""
        return self.pmf_table[index]


def _alias_pick(prob, alias, column, up):
    """Keep ``column`` or take its alias; ``up`` in [0, 1) is the position inside the column."""
    p = prob[column]
    keep = up < p
    index = np.where(keep, column, alias[column])
    with quiet("divide", "invalid"):
        u_remapped = np.where(keep, up / p, (up - p) / (1.0 - p))
    return index, np.clip(np.nan_to_num(u_remapped), 0.0, _ONE_MINUS)


def make_distribution(weights, method="cdf"):
    """A discrete distribution over ``weights (n,)`` by ``method`` in ``DISTRIBUTION_METHODS``.

    Returns
    -------
    PiecewiseConstant1D or AliasTable
    """
    if method == "cdf":
        return PiecewiseConstant1D(weights)
    if method == "alias":
        return AliasTable(weights)
    raise ValueError(f"unknown distribution method {method!r}; choose from "
                     f"{', '.join(DISTRIBUTION_METHODS)}")


class Segmented1D:
    """Many discrete distributions stored back to back; each query samples its own segment.

    Parameters
    ----------
    func : (N,) float
        Non-negative weights of all segments, concatenated.
    offsets : (r + 1,) int
        Segment ``j`` is ``func[offsets[j]:offsets[j + 1]]``; every segment must be non-empty.
        A segment without mass gets the uniform distribution.
    method : str
        ``'cdf'`` (per-segment CDF, batched bisection) or ``'alias'`` (per-segment alias
        tables, one column lookup).

    Attributes
    ----------
    pmf_table : (N,) float64
        Probability of each element within its segment.
    """

    def __init__(self, func, offsets, method="cdf"):
        if method not in DISTRIBUTION_METHODS:
            raise ValueError(f"unknown distribution method {method!r}; choose from "
                             f"{', '.join(DISTRIBUTION_METHODS)}")
        func = _clean_weights(func)
        offsets = np.asarray(offsets, np.int64).reshape(-1)
        if offsets.size < 2 or offsets[0] != 0 or offsets[-1] != func.size \
                or np.any(np.diff(offsets) <= 0):
            raise ValueError("Segmented1D needs non-empty segments covering all weights")
        self.method = method
        self.offsets = offsets
        self.lengths = np.diff(offsets)
        if method == "alias":
            self.prob, self.alias, self.pmf_table = build_alias_segments(func, offsets)
        else:
            self.pmf_table, func = _segment_pmf(func, offsets)
            seg = _segment_ids(offsets)
            running = _local_running_sum(func, offsets, seg)
            total = running[offsets[1:] - 1]
            # One leading zero per segment: segment j's CDF is cdf[offsets[j] + j : ... + len + 1];
            # running / total of the segment's own last element is exactly 1.
            cdf = np.empty(func.size + offsets.size - 1)
            starts = offsets[:-1] + np.arange(offsets.size - 1)
            cdf[starts] = 0.0
            body = np.ones(cdf.size, bool)
            body[starts] = False
            cdf[body] = (running / total[seg]).astype(np.float64)
            self.cdf = cdf
            self.cdf_start = starts

    def __len__(self):
        return self.pmf_table.size

    @property
    def n_segments(self):
        return self.lengths.size

    def sample(self, segment, u):
        """Choose an element of each query's segment.

        Parameters
        ----------
        segment : (k,) int
            Segment of each query.
        u : (k,) float
            Uniform in [0, 1).

        Returns
        -------
        index : (k,) int64
            Global index of the chosen element, in
            ``[offsets[segment], offsets[segment + 1])``.
        pmf : (k,) float64
            Its probability within the segment.
        u_remapped : (k,) float64
            Position of ``u`` inside the chosen element, uniform in [0, 1).
        """
        segment = np.asarray(segment, np.int64)
        u = np.asarray(u, np.float64)
        length = self.lengths[segment]
        base = self.offsets[segment]
        if self.method == "alias":
            x = u * length
            column = base + np.minimum(x.astype(np.int64), length - 1)
            index, u_remapped = _alias_pick(self.prob, self.alias, column, x - (column - base))
            return index, self.pmf_table[index], u_remapped
        start = self.cdf_start[segment]
        # As in PiecewiseConstant1D: the last CDF entry <= u, so zero-mass elements are skipped.
        local = self._search(start, length, u) - start - 1
        local = np.clip(local, 0, length - 1)
        lo = self.cdf[start + local]
        width = self.cdf[start + local + 1] - lo
        with quiet("divide", "invalid"):
            u_remapped = np.where(width > 0, (u - lo) / width, 0.0)
        index = base + local
        return index, self.pmf_table[index], np.clip(u_remapped, 0.0, _ONE_MINUS)

    def pick(self, segment, u):
        """``index, pmf`` of :meth:`sample` without the remapped number (the same values),
        for callers that discard it (light selection's triangle draw). With one ``'cdf'``
        segment (one emissive mesh) its start, length and base are numbers, not gathers."""
        if self.method == "alias" or self.lengths.size > 1:
            index, pmf, _ = self.sample(segment, u)
            return index, pmf
        u = np.asarray(u, np.float64)
        length = int(self.lengths[0])
        local = np.searchsorted(self.cdf, u, side="right") - 1
        if length > 1:
            np.clip(local, 0, length - 1, out=local)
        else:
            local = np.zeros(u.shape, np.int64)
        return local, self.pmf_table.take(local)

    def pmf(self, index):
        """Probability of global element ``index (k,)`` within its segment."""
        return self.pmf_table[index]

    def _search(self, start, length, u):
        """:func:`search_right` of ``u (k,)`` in the CDFs of its segments (``start``,
        ``length``: theirs). With one segment (one emissive mesh, one image row) NumPy's own
        binary search finds the same index (the first CDF entry above ``u``, else the end)
        in one call instead of a Python loop of bisection steps."""
        if self.lengths.size == 1:
            return np.searchsorted(self.cdf, u, side="right")
        return search_right(self.cdf, start, start + length + 1, u)


class PiecewiseConstant2D:
    """A piecewise-constant density on [0, 1)^2: a marginal over rows, a conditional per row.

    Cell ``(row, col)`` of ``func`` covers
    ``[col / nu, (col + 1) / nu) x [row / nv, (row + 1) / nv)`` with density proportional to ``func[row, col]`` (pbrt's layout: ``u[:, 1]`` picks the row
    through the marginal, ``u[:, 0]`` the column through that row's conditional).

    Parameters
    ----------
    func : (nv, nu) float
        Non-negative weights. All zero gives the uniform density; a row of zeros is never chosen.
    method : str
        ``'cdf'`` or ``'alias'`` for both the marginal and the conditionals (see module doc).

    Attributes
    ----------
    pmf_table : (nv, nu) float64
        Probability of every cell (sums to one).
    integral : float
        Mean of ``func`` (its integral over the unit square).
    """

    def __init__(self, func, method="cdf"):
        func = np.asarray(func, np.float64)
        if func.ndim != 2 or func.size == 0:
            raise ValueError("PiecewiseConstant2D needs a non-empty (nv, nu) array")
        func = np.where(np.isfinite(func), np.abs(func), 0.0)
        nv, nu = func.shape
        self.nu, self.nv = nu, nv
        self.method = method
        self.integral = float(func.mean())
        self.marginal = make_distribution(func.sum(axis=1), method)
        self.conditional = Segmented1D(func.reshape(-1), np.arange(nv + 1) * nu, method)
        self.pmf_table = (self.marginal.pmf_table[:, None]
                          * self.conditional.pmf_table.reshape(nv, nu))

    def __len__(self):
        return self.nu * self.nv

    def sample(self, u):
        """Choose cells.

        Parameters
        ----------
        u : (k, 2) float
            Uniform in [0, 1)^2.

        Returns
        -------
        index : (k,) int64
            Flat cell index ``row * nu + col``.
        pmf : (k,) float64
            Probability of the cell.
        u_remapped : (k, 2) float64
            Position inside the cell (column direction, row direction), uniform in [0, 1)^2.
        """
        u = np.asarray(u, np.float64).reshape(-1, 2)
        row, pmf_row, u1 = self.marginal.sample(u[:, 1])
        index, pmf_col, u0 = self.conditional.sample(row, u[:, 0])
        return index, pmf_row * pmf_col, np.stack([u0, u1], axis=-1)

    def sample_continuous(self, u):
        """Points with density :meth:`pdf`: ``u (k, 2)`` -> ``points (k, 2), pdf (k,)``."""
        index, pmf, ur = self.sample(u)
        row, col = np.divmod(index, self.nu)
        points = np.stack([(col + ur[:, 0]) / self.nu, (row + ur[:, 1]) / self.nv], axis=-1)
        return np.minimum(points, _ONE_MINUS), pmf * (self.nu * self.nv)

    def pdf(self, points):
        """Density ``(k,)`` on [0, 1)^2 at ``points (k, 2)`` (x along columns, y along rows)."""
        points = np.asarray(points, np.float64).reshape(-1, 2)
        col = np.clip((points[:, 0] * self.nu).astype(np.int64), 0, self.nu - 1)
        row = np.clip((points[:, 1] * self.nv).astype(np.int64), 0, self.nv - 1)
        return self.pmf_table[row, col] * (self.nu * self.nv)

    def pmf(self, index):
        """Probability of flat cell ``index (k,)``."""
        return self.pmf_table.reshape(-1)[index]
