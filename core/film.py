"""Film: pixel filters, per-pixel accumulation of mean, variance and sample count, and splats.

Camera samples are filtered the way Cycles does it: the filter is importance-sampled, so every
camera sample lands at ``pixel centre + offset`` with the offset drawn from the (separable,
normalised) filter and carries weight one. A pixel's value is then the plain mean of its samples,
its variance the variance of that mean, and samples never spill into neighbouring pixels, which
keeps per-pixel statistics exact and threads independent.

Light-path contributions (light tracing, BDPT's t = 1) go to :meth:`Film.splat` at any film
position. A splat at film position ``x`` adds ``value * h(x - c_j)`` to every pixel ``j`` whose
filter ``h`` (the same normalised filter the camera samples are drawn from, centred on the pixel
centre ``c_j``) covers ``x``, so splatted and camera estimates of a pixel measure the same
integral. Splat sums are divided by the number of light paths traced (``splat_paths``).

Extra layers (BDPT's per-strategy images) accumulate the same way under a name: per camera
sample with :meth:`Film.add_layer`, splatted with :meth:`Film.splat_layer`.
"""

from __future__ import annotations

import os
from typing import NamedTuple

import numpy as np

from .errors import RenderRefused
from .quiet import quiet

FILTER_TABLE_SIZE = 1024
# Steps of u in the guide table of the filter's inverse CDF (PixelFilter.sample).
GUIDE = 4 * FILTER_TABLE_SIZE


def blackman_harris(x, width):
    """Cycles' Blackman-Harris window on [-width/2, width/2]. ``x : (k,)``."""
    a = 2.0 * np.pi * (x / width + 0.5)
    return 0.35875 - 0.48829 * np.cos(a) + 0.14128 * np.cos(2 * a) - 0.01168 * np.cos(3 * a)


class UnitPixels(NamedTuple):
    """The window pixels of a work unit's samples without the array: each pixel of
    ``start .. stop - 1`` ``count`` times in a row (:meth:`array`), the layout
    :func:`core.passes.render_unit` renders."""

    start: int
    stop: int
    count: int

    def array(self):
        """The pixels ``(n,)`` int64: ``np.repeat(np.arange(start, stop), count)``."""
        return np.repeat(np.arange(self.start, self.stop, dtype=np.int64), self.count)


class UnitSums(NamedTuple):
    """A work unit's camera samples summed per pixel (:func:`unit_sums`), as the worker hands
    them to the render loop: ``k / 2`` times less to send than a value per sample, and the
    loop only adds them up.

    Attributes
    ----------
    pixels : UnitPixels
        The unit's layout: pixels ``start .. stop - 1``, ``count`` samples each.
    total, total_sq : (p, 3) float64
        Per pixel, the sum of its samples' radiance and of their squares; with one sample per
        pixel ``total_sq`` is None (the square of ``total``, formed where it is added: half
        the payload).
    alpha : (p,) float64 or None
        Per pixel, the sum of the samples' transparency (None: opaque).
    """

    pixels: UnitPixels
    total: np.ndarray
    total_sq: np.ndarray
    alpha: np.ndarray


def unit_sums(unit, radiance, transparency):
    """:class:`UnitSums` of a unit's camera samples ``radiance (n, 3)`` and ``transparency
    (n,)`` (or None) laid out as ``unit`` (:class:`UnitPixels`): each pixel's consecutive
    samples added in order, to the bit the sums ``np.bincount`` forms."""
    lo, hi, k = unit
    if hi <= lo or k == 0:
        empty = np.zeros((0, 3))
        return UnitSums(unit, empty, empty, None)
    r = radiance.reshape(hi - lo, k, 3)
    if k == 1:
        total, total_sq = r[:, 0], None
    else:
        total, total_sq = r[:, 0].copy(), r[:, 0] ** 2
        for j in range(1, k):
            total += r[:, j]
            total_sq += r[:, j] ** 2
    alpha = None
    if transparency is not None:
        t = transparency.reshape(hi - lo, k)
        alpha = t[:, 0].copy()
        for j in range(1, k):
            alpha += t[:, j]
    return UnitSums(unit, total, total_sq, alpha)


class PixelFilter:
    """A separable pixel filter sampled through its tabulated CDF (as Cycles' filter table).

    Parameters
    ----------
    kind : str
        ``'BOX'`` or ``'BLACKMAN_HARRIS'``.
    width : float
        Blender's filter width in pixels. Cycles doubles it for Blackman-Harris, so the default
        1.5 covers 3 pixels.
    """

    def __init__(self, kind="BLACKMAN_HARRIS", width=1.5):
        kind = kind.upper()
        if kind not in ("BOX", "BLACKMAN_HARRIS", "GAUSSIAN"):
            raise ValueError(f"unknown pixel filter {kind!r}")
        self.kind = kind
        self.width = float(width)
        self.support = self.width * (2.0 if kind == "BLACKMAN_HARRIS" else 1.0)
        if kind == "BOX" or self.support <= 0:
            self.inverse_cdf = None
            return
        # Tabulate the 1-D CDF on a fine grid (trapezoid rule) and invert it exactly by linear
        # interpolation: the offsets then follow the piecewise-linear CDF everywhere, tails included.
        x = np.linspace(-0.5 * self.support, 0.5 * self.support, 4 * FILTER_TABLE_SIZE + 1)
        f = np.maximum(blackman_harris(x, self.support), 0.0)
        cdf = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]))])
        self.cdf = cdf / cdf[-1]
        self.grid = x
        self.inverse_cdf = True
        # np.interp's binary search costs more than the rest of camera ray generation: a guide
        # table (the CDF cell where each of GUIDE equal steps of u starts) and one step find
        # the same cell wherever a step of u spans at most one cell; the flat tails of the
        # CDF go to np.interp. The formula is np.interp's, so the offsets agree to the bit.
        self.slope = np.append((x[1:] - x[:-1]) / (self.cdf[1:] - self.cdf[:-1]), 0.0)
        start = np.searchsorted(self.cdf, np.arange(GUIDE + 1) / GUIDE, side="right") - 1
        self.guide = np.minimum(start[:-1], self.cdf.size - 2)
        self.guide_hard = start[1:] - self.guide > 1
        # pdf_1d's density per grid cell, computed once (the same quotients it took per call).
        self.cell_density = (self.cdf[1:] - self.cdf[:-1]) / (x[1] - x[0])

    def sample(self, u):
        """Filter offsets in pixels for ``u : (n, 2)``: ``(n, 2)``, each sample weight one."""
        if self.inverse_cdf is None:
            return (u - 0.5) * self.support
        cdf = self.cdf
        step = np.minimum((u * GUIDE).astype(np.intp), GUIDE - 1)
        j = self.guide[step]
        j += cdf[j + 1] <= u
        x = self.slope[j] * (u - cdf[j]) + self.grid[j]
        hard = self.guide_hard[step]
        if hard.any():
            x[hard] = np.interp(u[hard], cdf, self.grid)
        return x

    def pdf_1d(self, x):
        """Density ``(k,)`` with which :meth:`sample` draws the 1-D offset ``x (k,)`` (pixels).

        The 2-D density of an offset ``(x, y)`` is ``pdf_1d(x) * pdf_1d(y)``; it integrates to
        one, and it is the filter weight a splat at that offset gives the pixel.
        """
        x = np.asarray(x, np.float64)
        half = 0.5 * self.support
        if self.inverse_cdf is None:
            return np.where(np.abs(x) < half, 1.0 / max(self.support, 1e-300), 0.0)
        # The derivative of the piecewise-linear CDF: constant between grid points.
        step = self.grid[1] - self.grid[0]
        # The cell index clipped to the table by np.take itself (mode="clip", the table has
        # grid.size - 1 cells); truncation instead of np.floor differs only below zero, where
        # both clip to cell 0.
        i = ((x + half) / step).astype(np.int64)
        return np.where(np.abs(x) < half, self.cell_density.take(i, mode="clip"), 0.0)

    def taps(self):
        """Pixel offsets ``(m,)`` int a splat must visit: every pixel whose filter can cover a
        film position lies within ``floor(x) + taps`` along each axis."""
        reach = int(np.ceil(0.5 * self.support + 0.5))
        return np.arange(-reach, reach + 1)

    def reach(self):
        """The offsets of :meth:`taps` whose pixel the filter can cover from some position in
        pixel ``floor(x)``: from a position ``f`` in ``[0, 1)`` of its pixel, pixel
        ``floor(x) + d``'s centre is ``|f - d - 1/2|`` away, which comes as close as
        ``max(|d| - 1/2, 0)``, and the filter covers distances below half its support
        (Blackman-Harris of width 1.5: offsets -1, 0, 1 of -2..2)."""
        taps = self.taps()
        return taps[np.abs(taps) - 0.5 < 0.5 * self.support]


class SplatSums(NamedTuple):
    """One batch's splat taps summed per film pixel (:func:`tap_sums`).

    Attributes
    ----------
    sum, sum_sq : (n, 3) float64
        Per-pixel sums of the weighted taps and of their squares.
    """

    sum: np.ndarray
    sum_sq: np.ndarray


def tap_sums(pixel, weighted, n):
    """Per-pixel sums of taps ``pixel (m,)``, ``weighted (m, 3)`` over a film of ``n`` pixels
    (pixel ``n``, the taps outside the film, dropped): the very sums
    :meth:`Film.add_splat_taps` adds, so adding them gives the same film bit for bit."""
    return _summed(pixel, None, weighted, n)


def _summed(pixel, w, channels, n):
    """:class:`SplatSums` of taps at pixels ``pixel (m,)`` over a film of ``n`` pixels (pixel
    ``n`` dropped), whose values are :func:`_weighted`'s of ``w`` and ``channels``, formed
    channel by channel in one buffer (for the channel's sums, then its squares) instead of
    the ``(m, 3)`` table."""
    buf = np.empty(pixel.size)
    total, total_sq = np.empty((n, 3)), np.empty((n, 3))
    for c in range(3):
        if w is None:
            np.copyto(buf, channels[:, c])
        else:
            np.multiply(w, channels[c], out=buf.reshape(w.shape))
        total[:, c] = _film_bins(pixel, buf, n)
        total_sq[:, c] = _film_bins(pixel, np.square(buf, out=buf), n)
    return SplatSums(total, total_sq)


def _film_bins(pixel, weights, n):
    """Sums ``(n,)`` of ``weights (m,)`` per film pixel ``pixel (m,)``; pixel ``n`` (the taps
    outside the film, :meth:`Film.splat_taps`) is dropped."""
    return np.bincount(pixel, weights, minlength=n + 1)[:n]


class Film:
    """Accumulation buffers for a ``width`` x ``height`` image (row 0 at the bottom).

    A film may be a window of a larger frame (a render region): its pixel ``(0, 0)`` is the
    frame's pixel ``(x0, y0)``. Camera samples are added by window pixel index; splats come at
    frame positions and only the taps that fall inside the window are kept.

    Parameters
    ----------
    width, height : int
        Size of the window (the whole image when it is the frame).
    x0, y0 : int
        Frame pixel of the window's lower-left pixel.

    Attributes
    ----------
    sum, sum_sq : (h * w, 3) float64
        Per-pixel sums of camera-sample radiance and of its square.
    count : (h * w,) int64
        Camera samples per pixel.
    splat_sum, splat_sum_sq : (h * w, 3) float64
        Sums of light-path contributions (already divided by nothing).
    splat_paths : int
        Light paths traced so far (the splat estimator's denominator).
    """

    def __init__(self, width, height, x0=0, y0=0):
        self.width = int(width)
        self.height = int(height)
        self.x0 = int(x0)
        self.y0 = int(y0)
        n = self.width * self.height
        self.sum = np.zeros((n, 3))
        self.sum_sq = np.zeros((n, 3))
        self.count = np.zeros(n, np.int64)
        self.splat_sum = np.zeros((n, 3))
        self.splat_sum_sq = np.zeros((n, 3))
        self.splat_paths = 0
        # Extra layers: name -> [camera-sample sum (n, 3), splat sum (n, 3)].
        self.layers = {}
        # Sum of the camera samples' transparency (a transparent film), None while opaque.
        self.transparency = None

    @property
    def n_pixels(self):
        return self.width * self.height

    def add_samples(self, pixel, radiance, transparency=None):
        """Accumulate camera samples ``radiance (k, 3)`` into their pixels ``pixel (k,)``;
        ``transparency (k,)``: what of each reached a transparent film's background (None:
        nothing). A work unit's samples come summed per pixel instead
        (:meth:`add_unit_sums`)."""
        if pixel.size == 0:
            return
        # Over the span of pixels the batch touches (a work unit's own pixels), not the whole
        # film: the same sums in the same order, without seven film-sized arrays per batch.
        lo, hi = int(pixel.min()), int(pixel.max()) + 1
        local, span = pixel - lo, hi - lo
        if transparency is not None:
            if self.transparency is None:
                self.transparency = np.zeros(self.n_pixels)
            self.transparency[lo:hi] += np.bincount(local, transparency, minlength=span)
        for c in range(3):
            self.sum[lo:hi, c] += np.bincount(local, radiance[:, c], minlength=span)
            self.sum_sq[lo:hi, c] += np.bincount(local, radiance[:, c] ** 2, minlength=span)
        self.count[lo:hi] += np.bincount(local, minlength=span)

    def add_unit_sums(self, sums):
        """Add a work unit's :class:`UnitSums` (its samples summed per pixel by
        :func:`unit_sums`): the same film sums as :meth:`add_samples` of the samples."""
        lo, hi, k = sums.pixels
        if hi <= lo or k == 0:
            return
        self.sum[lo:hi] += sums.total
        self.sum_sq[lo:hi] += sums.total ** 2 if sums.total_sq is None else sums.total_sq
        self.count[lo:hi] += k
        if sums.alpha is not None:
            if self.transparency is None:
                self.transparency = np.zeros(self.n_pixels)
            self.transparency[lo:hi] += sums.alpha

    def splat(self, film_xy, value, pixel_filter=None):
        """Add light-path contributions ``value (k, 3)`` at film positions ``film_xy (k, 2)``.

        With ``pixel_filter`` (a :class:`PixelFilter`) each contribution is spread over the
        pixels whose filter covers its position, weighted by the filter's normalised density;
        without, it goes to the pixel that contains it (a 1-pixel box). Positions are in frame
        pixels (see the class docstring); non-finite values and taps outside the window are
        dropped. Call :meth:`add_splat_paths` once per batch with the number of light paths
        that batch traced.
        """
        self.add_splat_taps(*self.splat_taps(film_xy, value, pixel_filter))

    def unit_splats(self, film_xy, value, pixel_filter):
        """What a work unit hands the render loop for its splats (as :meth:`splat`'s): their
        taps (:meth:`splat_taps`), or their per-pixel :class:`SplatSums` when the film has
        fewer than two thirds as many pixels as there are taps (two ``(n, 3)`` tables are then
        smaller than the taps, and the render loop, which :meth:`add_splat_sums` them, has two
        array additions to do instead of six bincounts). The sums are made from the filter
        weights and the values without the ``(m, 3)`` table of weighted taps. Reads nothing
        the film accumulates."""
        pixel, w, channels = self._tap_weights(film_xy, value, pixel_filter)
        if 3 * self.n_pixels >= 2 * len(pixel):
            return pixel, _weighted(w, channels)
        return _summed(pixel, w, channels, self.n_pixels)

    def add_splat_sums(self, sums):
        """Add a :class:`SplatSums` (:meth:`unit_splats`): the same sums, in the same
        order, as :meth:`add_splat_taps` of its taps."""
        self.splat_sum += sums.sum
        self.splat_sum_sq += sums.sum_sq

    def add_splat_taps(self, pixel, weighted):
        """Add the taps :meth:`splat_taps` made: ``pixel (m,)``, ``weighted (m, 3)``."""
        n = self.n_pixels
        for c in range(3):
            self.splat_sum[:, c] += _film_bins(pixel, weighted[:, c], n)
            self.splat_sum_sq[:, c] += _film_bins(pixel, weighted[:, c] ** 2, n)

    def splat_taps(self, film_xy, value, pixel_filter):
        """Pixels ``(m,)`` and filter-weighted values ``(m, 3)`` of a batch of splats (see
        :meth:`splat`); pixel ``n`` (the film's pixel count) holds the filter's taps outside
        the film, which :meth:`add_splat_taps` drops. Reads nothing the film accumulates, so
        a worker thread may make them while the render loop adds other units' taps."""
        pixel, w, channels = self._tap_weights(film_xy, value, pixel_filter)
        return pixel, _weighted(w, channels)

    def _tap_weights(self, film_xy, value, pixel_filter):
        """The taps of splats (:meth:`splat_taps`) before their values are weighted: pixels
        ``(T * k,)``, filter weights ``(T, k)`` for the ``T`` pairs of taps of each of the
        ``k`` finite splats, and their values ``(3, k)`` channel by channel; without
        ``pixel_filter`` (a 1-pixel box) the weights are None and the values ``(k, 3)``."""
        film_xy = np.asarray(film_xy, np.float64).reshape(-1, 2)
        value = np.asarray(value, np.float64).reshape(-1, 3)
        # Column by column: an .all(axis=1) over three columns is about ten times slower.
        fv, fx = np.isfinite(value), np.isfinite(film_xy)
        ok = fv[:, 0] & fv[:, 1] & fv[:, 2] & fx[:, 0] & fx[:, 1]
        if not ok.all():
            keep = ok.nonzero()[0]
            film_xy, value = film_xy.take(keep, axis=0), value.take(keep, axis=0)
        if self.x0 or self.y0:  # a render region's window (x - 0 is x, bit for bit)
            film_xy = film_xy - (self.x0, self.y0)
        if pixel_filter is None:
            x = np.floor(film_xy[:, 0]).astype(np.int64)
            y = np.floor(film_xy[:, 1]).astype(np.int64)
            inside = (x >= 0) & (x < self.width) & (y >= 0) & (y < self.height)
            return (y * self.width + x)[inside], None, value[inside]
        n, k = self.n_pixels, value.shape[0]
        px, wx = _axis_taps(film_xy[:, 0], pixel_filter, self.width, 1, n)
        py, wy = _axis_taps(film_xy[:, 1], pixel_filter, self.height, self.width, n)
        # Every pair of taps at once, (Tx, Ty, k): the order in which the pixels' sums add
        # them (pair by pair, then splat by splat). Taps outside the film go to pixel n,
        # which the sums drop; taps of weight zero add zeros, which change no sum.
        pixel = np.add(py[None, :, :], px[:, None, :])
        pixel = np.minimum(pixel, n, out=pixel).reshape(-1)
        w = (wx[:, None, :] * wy[None, :, :]).reshape(wx.shape[0] * wy.shape[0], k)
        return pixel, w, value.T.copy()  # contiguous channels for the broadcasts

    def add_splat_paths(self, k):
        self.splat_paths += int(k)

    def _layer(self, name):
        if name not in self.layers:
            self.layers[name] = [np.zeros((self.n_pixels, 3)), np.zeros((self.n_pixels, 3))]
        return self.layers[name]

    def add_layer(self, name, pixel, value):
        """Accumulate per-camera-sample values ``value (k, 3)`` of layer ``name`` (created on
        first use) into pixels ``pixel (k,)``; divided by the pixels' camera sample counts."""
        acc = self._layer(name)[0]
        for c in range(3):
            acc[:, c] += np.bincount(pixel, value[:, c], minlength=self.n_pixels)

    def splat_layer(self, name, film_xy, value, pixel_filter=None):
        """Splat ``value (k, 3)`` at ``film_xy (k, 2)`` into layer ``name`` (as :meth:`splat`)."""
        pixel, weighted = self.splat_taps(film_xy, value, pixel_filter)
        acc, n = self._layer(name)[1], self.n_pixels
        for c in range(3):
            acc[:, c] += _film_bins(pixel, weighted[:, c], n)

    def layer_mean(self, name):
        """Estimate ``(h, w, 3)`` float64 of layer ``name`` (zeros if nothing was added)."""
        camera, splats = self._layer(name)
        img = camera / np.maximum(self.count, 1)[:, None]
        if self.splat_paths:
            img = img + splats / self.splat_paths
        return img.reshape(self.height, self.width, 3)

    def mean(self):
        """Pixel estimates ``(h, w, 3)`` float64: camera mean plus splats per light path."""
        with quiet("invalid", "divide"):
            img = np.where(self.count[:, None] > 0, self.sum / np.maximum(self.count, 1)[:, None], 0.0)
        if self.splat_paths:
            img = img + self.splat_sum / self.splat_paths
        return img.reshape(self.height, self.width, 3)

    def variance(self):
        """Variance of each pixel estimate ``(h, w, 3)``: sample variance / sample count."""
        n = self.count[:, None].astype(np.float64)
        with quiet("invalid", "divide"):
            mean = self.sum / np.maximum(n, 1)
            s2 = (self.sum_sq - n * mean * mean) / np.maximum(n - 1, 1)
            var = np.where(n > 1, np.maximum(s2, 0.0) / np.maximum(n, 1), 0.0)
            if self.splat_paths > 1:
                m = self.splat_paths
                sm = self.splat_sum / m
                var = var + np.maximum(self.splat_sum_sq / m - sm * sm, 0.0) / (m - 1)
        return var.reshape(self.height, self.width, 3)

    def sample_count(self):
        """Camera samples per pixel ``(h, w)`` float32."""
        return self.count.reshape(self.height, self.width).astype(np.float32)

    def alpha(self):
        """Alpha ``(h, w)`` float64: one minus the pixels' mean transparency (one everywhere
        on an opaque film, Blender's default), in [0, 1]."""
        if self.transparency is None:
            return np.ones((self.height, self.width))
        clear = self.transparency / np.maximum(self.count, 1)
        return np.clip(1.0 - clear, 0.0, 1.0).reshape(self.height, self.width)

    def combined(self):
        """RGBA ``(h, w, 4)`` float32; RGB as Cycles writes it on a transparent film (the
        world seen by camera rays left out, not divided by alpha)."""
        rgba = np.ones((self.height, self.width, 4), np.float32)
        rgba[..., :3] = to_float32(self.mean())
        rgba[..., 3] = self.alpha()
        return rgba


def _weighted(w, channels):
    """The weighted taps ``(T * k, 3)`` of :meth:`Film._tap_weights`' weights ``w (T, k)`` and
    values ``channels (3, k)`` (without weights, the values ``(k, 3)`` themselves)."""
    if w is None:
        return channels
    # Channel by channel into a (3, m) table, returned as its (m, 3) transpose: each
    # channel's column is contiguous for add_splat_taps' bincounts.
    weighted = np.empty((3, w.size))
    for c in range(3):
        np.multiply(w, channels[c], out=weighted[c].reshape(w.shape))
    return weighted.T


def _axis_taps(x, pixel_filter, size, stride, outside):
    """One axis of splats at film coordinates ``x (k,)``: per tap of the filter that can
    reach a splat (:meth:`PixelFilter.reach`), the pixel coordinate times ``stride`` (or
    ``outside`` where the pixel is outside ``[0, size)``) and the filter weight there (zero
    outside): two ``(T, k)`` arrays."""
    p = np.floor(x).astype(np.int64)[None, :] + pixel_filter.reach()[:, None]
    inside = (p >= 0) & (p < size)
    w = pixel_filter.pdf_1d(x[None, :] - (p + 0.5))
    if stride != 1:
        p *= stride
    return np.where(inside, p, outside), np.where(inside, w, 0.0)


FLOAT32_MAX = float(np.finfo(np.float32).max)


def to_float32(image):
    """``image`` as float32 with finite float64 values beyond float32's range clipped to its
    largest value: a sum that is finite in float64 must not become Inf in an output image."""
    return np.clip(image, -FLOAT32_MAX, FLOAT32_MAX).astype(np.float32)


# Bytes per pixel of the film (five (n, 3) float64 sums and an int64 count), and as much again
# for the images a render hands back.
FILM_BYTES_PER_PIXEL = 2 * (5 * 3 * 8 + 8)


def physical_memory():
    """Bytes of physical memory, or None where the platform does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return None


def check_film_memory(width, height, region=None, memory=None):
    """Refuse (:class:`core.errors.RenderRefused`) an image whose film would take more than half of the machine's
    ``memory`` (default: :func:`physical_memory`), before anything is allocated: a huge
    resolution then says so instead of failing deep inside NumPy or exhausting the machine."""
    n = (region[2] - region[0]) * (region[3] - region[1]) if region else width * height
    memory = physical_memory() if memory is None else memory
    need = n * FILM_BYTES_PER_PIXEL
    if memory and need > memory / 2:
        raise RenderRefused(f"a {width} x {height} image needs about {need / 2 ** 30:.0f} GB for "
                         f"its film, more than half of the {memory / 2 ** 30:.0f} GB of memory "
                         f"here: lower the resolution or render a region")
