"""The light-vertex splats' cheaper steps (issue 12, eighth round) give the very bytes of the
formulas they replaced: the camera projection (``camera.project``, no isfinite tests and no
stack), the filter density of the taps (``PixelFilter.pdf_1d``, the cell index clipped by
``np.take``) and the taps of a film (``Film.splat_taps``). The previous formulas are written
out here; inputs include NaN, infinities, points behind the camera or at the pinhole, offsets
outside the filter's support and on its grid points, and a render region's window."""

import numpy as np
import pytest

from sampling_lab.core.camera import project, view_extent
from sampling_lab.core.film import Film, PixelFilter
from tests.core.test_camera import make_camera


def _project_before(cam, p, margin=0.0, window=None):
    """``project`` as it was (main at 4096fcf)."""
    half_x, half_y, sx, sy = view_extent(cam)
    m = np.asarray(cam.to_world, np.float64)
    rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0, keepdims=True)
    local = np.einsum("ij,jk->ik", p - m[:3, 3], rot)
    depth = -local[:, 2]
    dist = np.sqrt(np.einsum("ij,ij->i", local, local))
    with np.errstate(divide="ignore", invalid="ignore"):
        tx, ty, cos_theta = local[:, 0] / depth, local[:, 1] / depth, depth / dist
    fx = ((tx - sx) / (2.0 * half_x) + 0.5) * cam.width
    fy = ((ty - sy) / (2.0 * half_y) + 0.5) * cam.height
    film_xy = np.stack([fx, fy], axis=-1)
    x0, y0, x1, y1 = window if window is not None else (0, 0, cam.width, cam.height)
    visible = ((depth > 0) & (depth >= cam.clip_start) & (depth <= cam.clip_end)
               & (fx >= x0 - margin) & (fx < x1 + margin) & (fy >= y0 - margin)
               & (fy < y1 + margin) & np.isfinite(fx) & np.isfinite(fy))
    return (np.where(np.isfinite(film_xy), film_xy, -1.0), visible,
            np.where(visible, cos_theta, 0.0), dist)


def _pdf_1d_before(f, x):
    half, step = 0.5 * f.support, f.grid[1] - f.grid[0]
    i = np.clip(np.floor((x + half) / step).astype(np.int64), 0, f.grid.size - 2)
    return np.where(np.abs(x) < half, np.take(f.cell_density, i), 0.0)


def _hard_points(cam, n=4000, seed=3):
    """Points around the camera: in view, beside it, behind it, at the pinhole, far away."""
    rng = np.random.default_rng(seed)
    m = np.asarray(cam.to_world, np.float64)
    local = rng.normal(size=(n, 3)) * rng.choice([0.01, 1.0, 100.0, 1e12], size=(n, 1))
    local[: n // 2, 2] = -np.abs(local[: n // 2, 2])  # half in front (view along -z)
    p = local @ m[:3, :3].T + m[:3, 3]
    p[:4] = m[:3, 3]  # the pinhole itself: distance and depth zero
    p[4:8, 0] = np.inf
    p[8:12, 1] = np.nan
    return p


@pytest.mark.parametrize("window", [None, (3, 2, 40, 21)])
def test_project_gives_the_previous_bytes_for_hidden_and_nonfinite_points(window):
    cam = make_camera()
    p = _hard_points(cam)
    with np.errstate(all="ignore"):
        new, old = project(cam, p, 1.5, window), _project_before(cam, p, 1.5, window)
    assert old[1].any() and not old[1].all()  # some points seen, some not
    for a, b in zip(new, old):
        assert a.dtype == b.dtype and a.shape == b.shape
        assert a.tobytes() == b.tobytes()


@pytest.mark.parametrize("kind,width", [("BLACKMAN_HARRIS", 1.5), ("BLACKMAN_HARRIS", 0.7),
                                        ("GAUSSIAN", 2.0)])
def test_pdf_1d_gives_the_previous_bytes_inside_outside_and_on_grid_points(kind, width):
    f = PixelFilter(kind, width)
    rng = np.random.default_rng(1)
    half = 0.5 * f.support
    x = np.concatenate([rng.uniform(-2 * half, 2 * half, 20000), f.grid, -f.grid,
                        [half, -half, np.nextafter(half, 0), np.nextafter(-half, 0), 0.0, -0.0,
                         np.inf, -np.inf, np.nan, 1e300, -1e300]])
    with np.errstate(invalid="ignore"):
        assert f.pdf_1d(x).tobytes() == _pdf_1d_before(f, x).tobytes()


def _splat_taps_before(film, film_xy, value, f):
    """``Film.splat_taps`` as it was (main at 4096fcf), for finite splats."""
    film_xy = film_xy - (film.x0, film.y0)
    n, k = film.n_pixels, value.shape[0]

    def axis(x, size, stride):
        p = np.floor(x).astype(np.int64)[None, :] + f.reach()[:, None]
        inside = (p >= 0) & (p < size)
        w = _pdf_1d_before(f, x[None, :] - (p + 0.5))
        return np.where(inside, p * stride, n), np.where(inside, w, 0.0)

    px, wx = axis(film_xy[:, 0], film.width, 1)
    py, wy = axis(film_xy[:, 1], film.height, film.width)
    pixel = np.minimum(py[None, :, :] + px[:, None, :], n).reshape(-1)
    w = (wx[:, None, :] * wy[None, :, :]).reshape(-1, k)
    weighted = np.empty((3, w.size))
    for c in range(3):
        np.multiply(w, value[:, c], out=weighted[c].reshape(w.shape))
    return pixel, weighted.T


@pytest.mark.parametrize("x0,y0", [(0, 0), (5, 3)])
def test_splat_taps_give_the_previous_bytes(x0, y0):
    film, f = Film(23, 17, x0, y0), PixelFilter("BLACKMAN_HARRIS", 1.5)
    rng = np.random.default_rng(7)
    xy = rng.uniform(-3, 40, (3000, 2))
    xy[:20] = np.floor(xy[:20])  # on pixel corners
    value = rng.exponential(size=(3000, 3))
    pixel, weighted = film.splat_taps(xy, value, f)
    pixel_0, weighted_0 = _splat_taps_before(film, xy, value, f)
    assert (pixel_0 == film.n_pixels).any() and (pixel_0 < film.n_pixels).any()
    assert pixel.tobytes() == pixel_0.tobytes()
    assert weighted.shape == weighted_0.shape
    assert np.ascontiguousarray(weighted).tobytes() == np.ascontiguousarray(weighted_0).tobytes()
