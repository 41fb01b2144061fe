"""Where BDPT's error lies: each strategy's share of the image's variance, weighted as relMSE,
and the per-render distribution of the error.

``python -m sampling_lab bdpt-error`` calls :func:`run`. It renders a scene (a ``bench-scenes``
scene, which needs ``bpy``, or a built-in one) ``renders`` times with BDPT, Strategy Views on and
independent seeds, all with the same sample count, and measures from the spread between the
renders (never from a per-pixel sample variance, so any sampler, Sobol included, is fine):

- *total*: the expected relMSE of one render, ``mean over pixels and RGB of w Var[x]`` with
  ``w = 1 / (ref^2 + EPS)`` (``ref``: the mean of the renders), ``Var`` unbiased over renders;
  times ``spp`` it is the error per sample, which does not depend on the machine's load.
- per strategy ``(s, t)`` (its MIS-weighted view ``v``): *variance share* ``mean w Var[v] /
  total`` (its error were it alone; these need not sum to one, strategies of one pixel are
  correlated) and *covariance share* ``mean w Cov[v, x] / total``, which do sum to one over all
  strategies because the weighted views add up to the image; what they leave is light the views
  do not cover (paths longer than ``max_length``).
- per render: ``relMSE x spp`` against the mean of the renders, scaled by ``n / (n - 1)`` so
  that its mean is the total (median, mean, max); and for the worst render the share of its
  error in its worst pixel and, by the same covariance split, the strategies that put it there.

Figures only, never asserted (``docs/CONVENTIONS.md``, "Tests").
"""

from __future__ import annotations

import os
import time
from dataclasses import replace

import numpy as np

from ..core.integrators.bounces import uniform_limits
from ..core.integrators.common import strategies
from ..core.options import DEFAULTS
from ..core.render import RenderSettings, render
from ..core.scenes import BUILTIN
from .common import EPS, write_csv


def load_scene(name, size, bench=False):
    """``bench-scenes`` scene ``name`` (``tools.hard_scenes.SCENES``, built in ``bpy``) if
    ``bench``, else the built-in scene (``core.scenes.BUILTIN``); the two sets share names
    (``mirror_ball``, ``cornell``) but not scenes."""
    if not bench:
        if name not in BUILTIN:
            raise ValueError(f"unknown built-in scene {name!r}: {', '.join(sorted(BUILTIN))}")
        return BUILTIN[name](*size)
    from .hard_scenes import SCENES, build_scene

    if name not in SCENES:
        raise ValueError(f"unknown bench-scenes scene {name!r}: {', '.join(SCENES)}")
    return build_scene(name, size)[1]


def render_views(scene, settings, renders, seed, progress=print):
    """``renders`` independent renders (seeds ``seed, seed + 1, ...``): the images ``(n, h, w,
    3)`` float64, the weighted views by strategy ``{(s, t): (n, h, w, 3) float32}`` and the
    seconds they took."""
    images, views, prepared, t0 = [], {}, None, time.perf_counter()
    pairs = strategies(settings.strategy_max_length)
    for i in range(renders):
        res = render(scene, replace(settings, seed=seed + i),
                     prepared=prepared)
        prepared = res.prepared
        images.append(res.film.mean()[..., :3])
        for s, t in pairs:
            img = res.film.layer_mean(f"Strategy s{s} t{t} weighted")[..., :3]
            views.setdefault((s, t), []).append(img.astype(np.float32))
        if progress:
            progress(f"render {i + 1}/{renders}: {time.perf_counter() - t0:.1f} s")
    return (np.stack(images), {k: np.stack(v) for k, v in views.items()},
            time.perf_counter() - t0)


def shares(images, views):
    """The error's split by strategy and by render (see the module's docstring).

    Parameters
    ----------
    images : (n, h, w, 3) float
        ``n >= 2`` independent renders of equal sample count.
    views : dict of (s, t) -> (n, h, w, 3) float
        Each strategy's MIS-weighted view in the same renders.

    Returns
    -------
    dict
        ``total`` (expected relMSE of one render), ``strategies``: list of ``(s, t,
        variance share, covariance share)`` by falling variance share, ``covered`` (sum of the
        covariance shares), ``per_render`` ``(n,)`` relMSE of each render, ``worst`` (index of
        the worst render), ``worst_pixel`` ``(y, x)``, ``worst_pixel_share`` (of that render's
        error) and ``worst_pixel_strategies``: ``(s, t, share)`` of that pixel's squared error,
        largest first.
    """
    x = np.asarray(images, dtype=np.float64)
    n = x.shape[0]
    ref = x.mean(axis=0)
    w = 1.0 / (ref * ref + EPS)
    dx = x - ref
    total = float(np.mean(w * (dx * dx).sum(axis=0) / (n - 1)))
    rows = []
    for (s, t), v in views.items():
        dv = np.asarray(v, dtype=np.float64) - np.asarray(v, dtype=np.float64).mean(axis=0)
        var = float(np.mean(w * (dv * dv).sum(axis=0) / (n - 1)))
        cov = float(np.mean(w * (dv * dx).sum(axis=0) / (n - 1)))
        rows.append((s, t, var / total, cov / total))
    rows.sort(key=lambda r: -r[2])
    per_pixel = (w * dx * dx).mean(axis=-1)                       # (n, h, w)
    per_render = per_pixel.mean(axis=(1, 2)) * n / (n - 1)
    worst = int(np.argmax(per_render))
    y, xp = np.unravel_index(int(np.argmax(per_pixel[worst])), per_pixel.shape[1:])
    return dict(total=total, strategies=rows, covered=sum(r[3] for r in rows),
                per_render=per_render, worst=worst, worst_pixel=(int(y), int(xp)),
                worst_pixel_share=float(per_pixel[worst, y, xp] / per_pixel[worst].sum()),
                worst_pixel_strategies=_pixel_split(views, dx, worst, y, xp))


def _pixel_split(views, dx, i, y, x):
    """Each strategy's share ``(s, t, share)`` of render ``i``'s squared error at pixel
    ``(y, x)``: its view's deviation from its mean dotted with the pixel's deviation (shares sum
    to what the views cover), largest first."""
    d = dx[i, y, x]
    norm = float(d @ d)
    out = []
    for (s, t), v in views.items():
        dv = v[i, y, x].astype(np.float64) - v[:, y, x].astype(np.float64).mean(axis=0)
        out.append((s, t, float(dv @ d) / norm if norm > 0 else 0.0))
    return sorted(out, key=lambda r: -r[2])


def run(scene="mirror_ball", size=(96, 96), spp=16, renders=32, max_length=8, max_bounces=8,
        sampler=DEFAULTS["sampler"], seed=1000, threads=2, top=12, output=None,
        progress=print, bench=True):
    """Render, split the error, print the table and, with ``output`` (a folder), write
    ``bdpt_error_<scene>.csv`` (one row per strategy, then one per render) there; returns
    :func:`shares`' dict with the settings (``scene``, ``spp``, ``renders``, ``seconds``).
    ``bench``: ``scene`` names a ``bench-scenes`` scene (:func:`load_scene`)."""
    if renders < 2:
        raise ValueError("bdpt-error needs at least two renders to measure a variance")
    settings = RenderSettings(integrator="bdpt", spp=spp, sampler=sampler, threads=threads,
                              strategy_views=True, strategy_max_length=max_length,
                              **uniform_limits(max_bounces))
    images, views, seconds = render_views(load_scene(scene, size, bench), settings, renders,
                                          seed, progress)
    out = shares(images, views)
    out.update(scene=("bench-scenes " if bench else "built-in ") + scene, spp=spp, renders=renders, seconds=seconds, size=size,
               sampler=sampler, max_length=max_length, max_bounces=max_bounces)
    print_report(out, top)
    if output is not None:
        os.makedirs(output, exist_ok=True)
        path = os.path.join(output, f"bdpt_error_{scene}.csv")
        write_csv(path, _csv_rows(out))
        print(f"wrote {path}")
    return out


def _csv_rows(out):
    """The strategies' shares, then each render's relMSE x spp, as CSV rows."""
    rows = [dict(kind="strategy", s=s, t=t, variance_share=var, covariance_share=cov)
            for s, t, var, cov in out["strategies"]]
    rows += [dict(kind="render", seed_offset=i, relmse_x_spp=float(e * out["spp"]))
             for i, e in enumerate(out["per_render"])]
    return rows


def print_report(out, top=12):
    """The figures of :func:`run` as text."""
    spp, per = out["spp"], out["per_render"] * out["spp"]
    print(f"\nBDPT on {out['scene']} {out['size'][0]}x{out['size'][1]}: {out['renders']} "
          f"renders of {spp} spp ({out['sampler']}, {out['max_bounces']} bounces, views up to "
          f"{out['max_length']} segments), {out['seconds']:.1f} s")
    print(f"relMSE of one render {out['total']:.3e}; x spp {out['total'] * spp:.3f}")
    print(f"per render relMSE x spp: median {np.median(per):.3f}, mean {per.mean():.3f}, "
          f"max {per.max():.3f}")
    print(f"{'strategy':<10} {'variance share':>15} {'covariance share':>17}")
    for s, t, var, cov in out["strategies"][:top]:
        print(f"s{s} t{t:<6} {var:15.1%} {cov:17.1%}")
    rest = out["strategies"][top:]
    print(f"{len(rest)} others: variance {sum(r[2] for r in rest):.1%}, covariance "
          f"{sum(r[3] for r in rest):.1%}; all: variance "
          f"{sum(r[2] for r in out['strategies']):.1%}, covariance {out['covered']:.1%} "
          f"(the rest, {1 - out['covered']:.1%}: paths longer than the views)")
    y, x = out["worst_pixel"]
    split = ", ".join(f"s{s} t{t} {share:.0%}" for s, t, share in
                      out["worst_pixel_strategies"][:3])
    print(f"worst render {out['worst']} (relMSE x spp {per[out['worst']]:.3f}): pixel "
          f"(y {y}, x {x}) holds {out['worst_pixel_share']:.0%} of its error; there: {split}")
