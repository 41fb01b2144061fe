"""Sample streams: where every random number of a path comes from.

An integrator asks a :class:`SampleStream` for ``next_1d()`` / ``next_2d()`` and never calls a
random generator itself. A stream is a deterministic function of (pixel, sample index, dimension,
seed), so a render is reproducible bit for bit, independent of threads and batch sizes, and a
sampler (stratified, low-discrepancy, blue noise) or Metropolis (primary sample space) can supply
the numbers without the integrator changing.

All paths of a batch consume dimensions in lockstep, so the dimension counter is one integer for
the whole batch; terminated paths leave with :meth:`SampleStream.compact`.
"""

from __future__ import annotations

import copy

import numpy as np

from ..quiet import quiet

_M1 = np.uint32(0x7FEB352D)
_M2 = np.uint32(0x846CA68B)


def hash_u32(x):
    """Chris Wellons' ``lowbias32`` integer hash on uint32 arrays (wrapping arithmetic)."""
    x = np.asarray(x, np.uint32)
    if x.ndim == 0:
        # NumPy warns about wrapping only for scalars; arrays wrap silently.
        with quiet("over"):
            x = x ^ (x >> np.uint32(16))
            x = x * _M1
            x = x ^ (x >> np.uint32(15))
            x = x * _M2
            return x ^ (x >> np.uint32(16))
    # One copy and one scratch array, then in place: this runs several times per sample slot.
    x = x.copy()
    t = np.empty_like(x)
    for shift, multiplier in ((16, _M1), (15, _M2)):
        np.right_shift(x, np.uint32(shift), out=t)
        x ^= t
        x *= multiplier
    np.right_shift(x, np.uint32(16), out=t)
    x ^= t
    return x


def u32_to_unit_float(x):
    """Map uint32 to doubles in [0, 1) using the top 24 bits (exactly representable)."""
    return (np.asarray(x, np.uint32) >> np.uint32(8)).astype(np.float64) * (1.0 / (1 << 24))


class Aborted(Exception):
    """Raised by :meth:`SampleStream.skip_to` once the stream's ``abort()`` says so: the render
    that owns the stream was cancelled, and the work unit's unfinished paths are dropped."""


class SampleStream:
    """Base class: a batch of sample vectors, one per (pixel, sample index).

    Parameters
    ----------
    pixel : (n,) int64
        Pixel index ``y * width + x``.
    sample_index : (n,) int64
        Index of the sample within its pixel.
    seed : int
    """

    # Set by the render loop to a callable that says whether the render was cancelled; checked
    # where every integrator starts a bounce or a vertex (:meth:`skip_to`).
    abort = None

    def __init__(self, pixel, sample_index, seed):
        self.pixel = np.asarray(pixel, np.int64)
        self.sample_index = np.asarray(sample_index, np.int64)
        self.seed = int(seed)
        self.dimension = 0

    def __len__(self):
        return self.pixel.shape[0]

    def compact(self, keep):
        """Keep the paths ``keep`` (index array or boolean mask)."""
        self.pixel = self.pixel[keep]
        self.sample_index = self.sample_index[keep]
        self._compact_state(keep)

    def _compact_state(self, keep):
        """Subclasses compact their own per-path arrays here."""

    def skip_to(self, dimension):
        """Jump to ``dimension`` (integrators start each bounce at a fixed dimension). Raises
        :class:`Aborted` if ``abort()`` says the render was cancelled: so a work unit stops
        within one bounce of a cancel instead of running to its end."""
        self.check_abort()
        self.dimension = int(dimension)

    def check_abort(self):
        """Raise :class:`Aborted` if ``abort()`` says the render was cancelled (integrators
        call it between long stages that draw no numbers, such as BDPT's connections)."""
        if self.abort is not None and self.abort():
            raise Aborted

    def next_1d(self):
        """``(n,)`` float64 in [0, 1)."""
        u = self.sample(self.dimension, 1)[:, 0]
        self.dimension += 1
        return u

    def next_2d(self):
        """``(n, 2)`` float64 in [0, 1)^2 (one 2-D sample: samplers stratify the pair jointly)."""
        u = self.sample(self.dimension, 2)
        self.dimension += 2
        return u

    def next_slots(self, sizes):
        """The draws of consecutive calls in one: size 1 is ``next_1d()``, 2 is ``next_2d()``,
        0 skips one dimension (as :func:`core.integrators.common.next_1d_if` when the number is
        not needed) and gives None. Returns one entry per size, the same values as the calls
        one by one (a 2-D value may be a transposed view). Streams that draw several slots
        more cheaply together override :meth:`_draw_slots`."""
        slots, d = [], self.dimension
        for size in sizes:
            if size:
                slots.append((d, size))
            d += max(size, 1)
        values = iter(self._draw_slots(slots))
        self.dimension = d
        return [next(values) if size else None for size in sizes]

    def slots_of_rows(self, rows, dimensions, sizes):
        """For the paths ``rows (m,)`` of this stream, each from its own ``dimensions (m,)``,
        the draws of ``next_slots(sizes)`` (sizes 1 or 2): one ``(m,)`` or ``(m, 2)`` array
        per size, row ``i`` as a copy of the stream compacted to path ``rows[i]`` and skipped
        to ``dimensions[i]`` would draw it. The stream itself is not advanced. Here one such
        copy per distinct dimension; streams that draw rows of mixed dimensions together
        override it (:class:`.samplers.sobol.SobolStream`)."""
        self.check_abort()
        out = [np.empty((rows.size,) + ((size,) if size == 2 else ())) for size in sizes]
        for d in np.unique(dimensions).tolist():
            at = np.nonzero(dimensions == d)[0]
            part = copy.copy(self)
            part.compact(rows[at])
            part.dimension = int(d)
            for o, value in zip(out, part.next_slots(sizes)):
                o[at] = value
        return out

    def _draw_slots(self, slots):
        """Values of the slots ``(dimension, size)``, in order: one ``next_1d`` / ``next_2d``
        each."""
        out = []
        for dimension, size in slots:
            self.dimension = dimension
            out.append(self.next_1d() if size == 1 else self.next_2d())
        return out

    def sample(self, dimension, count):
        """Sample values of dimensions ``dimension .. dimension + count - 1``: ``(n, count)``."""
        raise NotImplementedError
