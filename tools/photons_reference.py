"""Complete references for point-light caustics: BDPT plus the light BDPT cannot sample.

With a point light and a pinhole (both delta), a path can be sampled by BDPT (or path or light
tracing) only if it has an edge between two non-delta vertices, starts ``L D`` (next-event
estimation) or ends ``D E`` (light tracing's splat). The paths ``L S+ (D S+)* D S+ E`` have
none: light that reached a diffuse surface through mirrors or smooth glass, seen through them
again (``L S D S E``), e.g. the caustic seen through the glass ball. A long BDPT render is
therefore an incomplete reference there, and so is any comparison against it.

:func:`complete_reference` builds a reference with every path: a long BDPT render (unbiased,
everything but those paths) plus a long SPPM render of exactly those paths
(:class:`ReferenceSPPM`: visible points reached through at least one specular bounce, photons
flagged ``unconnectable`` by :func:`core.photons.tracing.trace_photons`). The two sets of paths
are disjoint and together are every path, so the sum is complete; its only bias is SPPM's on
the missing paths (a blur that shrinks with the radius), which :func:`complete_reference`
measures by rendering the missing part with two initial radii. The same SPPM run also gives
the full SPPM image, which :func:`reference_check` compares with the reference per pixel group
(seen directly, seen through specular surfaces): a reference that lacks light (BDPT alone) is
caught on the second group, tested in ``tests/core/test_photon_reference.py``.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..core.film import PixelFilter
from ..core.integrators.base import Counters
from ..core.integrators.bounces import uniform_limits
from ..core.integrators.sppm import SPPM
from ..core.photons.tracing import sppm_auto_radius
from ..core.prepare import prepare
from ..core.render import RenderSettings, render
from ..core.sampling.samplers import make_sampler

# Independent sampler and light selection by power: per-pixel variances are then honest.
PLAIN = dict(sampler="independent", light_selection="power", filter_type="box",
             filter_width=1.0)


class ReferenceSPPM(SPPM):
    """SPPM that also tallies, with the same radii, the light of the paths BDPT cannot sample
    (``L S+ (D S+)* D S+ E`` with a point light and a pinhole): photons flagged
    ``unconnectable`` found by visible points reached through a specular bounce or more.
    :meth:`image` is SPPM's image, :meth:`missing_image` that part of it; both are means of
    per-pass estimates, kept in ``per_pass`` (float32, ``(passes, n_pixels, 3)`` each) so that
    the standard error of any sum of pixels can be read from their spread (pixels share
    photons, so their variances do not add)."""

    def _start(self, n_pixels):
        super()._start(n_pixels)
        self.state["tau_missing"] = np.zeros((n_pixels, 3))
        self.per_pass = {"image": [], "missing": []}

    def _gather(self, points, photons, tree):
        """``(phi (k, 6), m (k,))``: SPPM's flux, then the missing paths' flux."""
        i, j, _, live, radii = self._pairs(points, photons, tree)
        phi, m, _ = self._flux(points, photons, i, j)
        sel = (points.bounces[i] > 0) & photons.unconnectable[j]
        missing, _, _ = self._flux(points, photons, i[sel], j[sel])
        both = np.concatenate([phi, missing], axis=1)
        if self.coverage:
            both[live] /= self._coverage(points.take(live), radii[live])[:, None]
        return both * np.tile(points.beta, 2), m, None

    def _add_pass_estimate(self, direct, rows, phi):
        super()._add_pass_estimate(direct, rows, phi[:, :3])
        r = self.state["r"][rows]
        for name, flux, first in (("image", phi[:, :3], direct), ("missing", phi[:, 3:], None)):
            x = np.zeros_like(direct) if first is None else first.copy()
            with np.errstate(invalid="ignore", divide="ignore"):
                found = flux / (float(self.photons) * np.pi * r * r)[:, None]
            found[~np.isfinite(found).all(axis=1)] = 0.0
            x[rows] += found
            self.per_pass[name].append(x.astype(np.float32))

    def _update(self, pixels, phi, m, sub=None):
        s = self.state
        hit = m > 0
        px = pixels[hit]
        r_old = s["r"][px].copy()
        super()._update(pixels, phi[:, :3], m)
        scale = (s["r"][px] / r_old) ** 2
        s["tau_missing"][px] = (s["tau_missing"][px] + phi[hit, 3:]) * scale[:, None]

    def missing_image(self):
        """``(n_pixels, 3)``: the light of the paths BDPT cannot sample."""
        s = self.state
        emitted = float(self.photons) * max(s["passes"], 1)
        with np.errstate(invalid="ignore", divide="ignore"):
            img = s["tau_missing"] / (emitted * np.pi * s["r"] ** 2)[:, None]
        img[~np.isfinite(img).all(axis=1)] = 0.0
        return img


def sppm_reference(scene, bounces, seconds, seed, threads=2, photon_radius=0.0, passes=None,
                   photons=None):
    """Render ``scene`` (every light a delta light, seen through a pinhole) with
    :class:`ReferenceSPPM` for ``seconds`` (whole passes; at most ``passes``). Returns a dict of ``(h, w, 3)`` arrays ``image`` and ``missing``, their
    per-pass estimates ``image_passes`` and ``missing_passes`` (``(passes, h, w, 3)``) and the
    figures ``passes``, ``radius0``, ``radius_mean`` (final) and ``seconds``."""
    extra = {"photons": int(photons)} if photons else {}
    # One initial radius for every pixel (the reference bounds its bias with two of them).
    extra["sppm_radius"] = "scene"
    settings = RenderSettings(integrator="sppm", spp=0, time_limit=seconds, seed=seed,
                              threads=threads, photon_radius=photon_radius,
                              **uniform_limits(bounces), **PLAIN, **extra)
    prep = prepare(scene, settings.light_selection)
    if not (prep.lights.n_emitters and prep.lights.delta.all()):
        raise ValueError("the missing part is the light BDPT cannot sample only when every "
                         "light is a delta light (a point of radius 0 or a sun of angle 0)")
    cam = scene.camera
    n = cam.width * cam.height
    integ = ReferenceSPPM(prep, settings)
    sampler = make_sampler(settings.sampler, seed=seed, width=cam.width)
    pixel_filter, counters = PixelFilter("box", 1.0), Counters()
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=threads) as pool:
        k = 0
        while (passes is None or k < passes) and (k == 0 or time.perf_counter() - t0 < seconds):
            integ.render_pass(k, np.arange(n, dtype=np.int64), sampler, pixel_filter,
                              counters, lambda fn, items: list(pool.map(fn, items)))
            k += 1
    shape = (cam.height, cam.width, 3)
    return dict(image=integ.image().reshape(shape), missing=integ.missing_image().reshape(shape),
                **{f"{name}_passes": np.stack(v).reshape((-1,) + shape)
                   for name, v in integ.per_pass.items()},
                passes=k, radius0=integ.radius0, seconds=time.perf_counter() - t0,
                radius_mean=float(np.nanmean(integ.state["r"])))


def bdpt_reference(scene, bounces, seconds, seed=999, threads=2, spp=0):
    """``(image, variance)``, each ``(h, w, 3)``: BDPT for ``seconds`` (or ``spp`` samples)."""
    res = render(scene, RenderSettings(integrator="bdpt", spp=spp, time_limit=seconds,
                                       seed=seed, threads=threads, **uniform_limits(bounces),
                                       **PLAIN))
    return res.film.mean(), res.film.variance(), res.stats["spp"]


def complete_reference(scene, bounces, bdpt_seconds, sppm_seconds, threads=2, log=print,
                       photons=None):
    """The complete reference of a point-light scene (see the module docstring): a dict with
    ``image`` (``(h, w, 3)``: BDPT plus the missing paths) with its noise (``variance``, BDPT's
    per pixel, and ``passes``, the missing part's per-pass estimates: :func:`group_se`), the
    parts (``bdpt``, ``missing``, ``missing_half``: the missing paths with half the initial
    radius), the full SPPM image ``sppm`` with ``sppm_passes`` for :func:`reference_check`,
    and the figures ``bias`` (relative difference of the missing light between the two radii,
    over the whole image) and ``notes``. ``photons``: SPPM's photons per pass (None: the
    default)."""
    bdpt, var_bdpt, spp = bdpt_reference(scene, bounces, bdpt_seconds, threads=threads)
    log(f"reference: BDPT {spp} spp in {bdpt_seconds:g} s")
    r0 = sppm_auto_radius(prepare(scene))
    a = sppm_reference(scene, bounces, sppm_seconds, seed=998, threads=threads, photons=photons)
    b = sppm_reference(scene, bounces, sppm_seconds, seed=997, threads=threads,
                       photon_radius=0.5 * r0, photons=photons)
    total = a["missing"].sum()
    bias = float((a["missing"].sum() - b["missing"].sum()) / total) if total > 0 else 0.0
    notes = (f"BDPT {spp} spp ({bdpt_seconds:g} s) + SPPM of the paths BDPT cannot sample "
             f"({a['passes']} passes, radius {a['radius0']:.3g} -> {a['radius_mean']:.3g}; "
             f"with half the initial radius {b['passes']} passes, -> {b['radius_mean']:.3g}): "
             f"the missing light is {total / max(bdpt.sum(), 1e-30):.2%} of BDPT's, and its "
             f"two radii differ by {bias:+.2%}")
    log(f"reference: {notes}")
    return dict(image=bdpt + a["missing"], variance=var_bdpt, passes=a["missing_passes"],
                bdpt=bdpt, missing=a["missing"], missing_half=b["missing"], sppm=a["image"],
                sppm_passes=a["image_passes"], bias=bias, notes=notes)


def group_se(mask, variance=None, passes=None):
    """Standard error of an image's sum over the pixels ``mask (h, w)``: from per-pixel
    variances of independent pixels (``variance``, BDPT's film) plus from the spread of the
    sums of per-pass estimates (``passes``, ``(k, h, w, 3)``: SPPM's pixels share photons)."""
    v = 0.0
    if variance is not None:
        v += float(variance[mask].sum())
    if passes is not None and len(passes) > 1:
        sums = passes[:, mask].astype(np.float64).sum(axis=(1, 2))
        v += float(sums.var(ddof=1) / sums.size)
    return float(np.sqrt(v))


def reference_check(ref, check, groups, se_ref, se_check, z=4.0, allowance=0.02):
    """Compare a reference with an independent estimate of every path (e.g. a long SPPM
    render, or a closed form) over pixel groups ``{name: (h, w) bool mask}``: the sums over
    each group must differ by at most ``z`` combined standard errors (``se_ref`` and
    ``se_check``: ``{name: standard error of the group's sum}``, :func:`group_se`) plus
    ``allowance`` times the check's sum (the check's or the reference's known bias, e.g.
    SPPM's blur). Returns ``{name: (relative difference, ok)}``: a reference that lacks light
    fails the group where it lacks it."""
    out = {}
    for name, mask in groups.items():
        a, b = float(ref[mask].sum()), float(check[mask].sum())
        se = np.hypot(se_ref.get(name, 0.0), se_check.get(name, 0.0))
        ok = abs(a - b) <= z * se + allowance * abs(b)
        out[name] = ((a - b) / b if b else 0.0, bool(ok))
    return out
