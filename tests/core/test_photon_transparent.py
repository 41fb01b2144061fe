"""Photon mapping and SPPM through transparent surfaces (core/photons/passes.py): photons, camera
paths to visible points and final-gather rays pass a Transparent BSDF, a Principled Alpha or an
alpha-textured leaf straight through (not a bounce, no photon stored there), and the visible
points' shadow rays cross such surfaces with their transmittance.

Scenes: :func:`sampling_lab.tools.transparent.transparent_scene` (16 x 16), the four cases that
``test_transparent_bidir.py`` renders with light tracing and BDPT. Both estimators are biased:
they are held to the path tracer's image within confidence intervals plus the radius' bias
allowance on the image mean, as the Cornell-box consistency checks
(``test_photon_consistency.py``).
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core import render
from sampling_lab.core.integrators.base import Counters
from sampling_lab.core.photons.tracing import trace_photons
from sampling_lab.core.prepare import prepare
from sampling_lab.core.sampling.samplers import make_sampler
from sampling_lab.tools.transparent import CASES, RHO_FLOOR, SUN, transparent_scene
from tests.core.test_photon_consistency import _bias_allowance, _settings
from tests.helpers import assert_images_agree

# Per estimator: its settings (radius 0.02 m for SPPM, 0.03 m for photon mapping, as the
# Cornell-box checks), seeds, and the relative image-mean and 8 x 8 block errors its comparison
# detects with 99 % power on every case (asserted by the checker; the image-mean figure includes
# the bias allowance 2 r). Measured, cases (a)-(d): SPPM 5.2 / 4.4 %, 7.4 / 9.0 %, 7.0 / 11.2 %,
# 5.3 / 3.2 %; photon mapping 7.2 / 4.4 %, 9.4 / 9.2 %, 9.0 / 11.2 %, 7.3 / 3.2 %.
ESTIMATORS = {
    "sppm": (dict(integrator="sppm", spp=32, photons=5000, photon_radius=0.02), 8,
             (0.08, 0.12)),
    "photon": (dict(integrator="photon", spp=32, photons=100_000, photon_lookup="radius",
                    photon_radius=0.03, gather_rays=1), 8, (0.10, 0.12)),
}


@pytest.fixture(scope="module")
def path_images():
    """Path-traced reference (512 spp) of each case, with its variance."""
    return {case: render.render(transparent_scene(case), _settings(integrator="path", spp=512))
            for case in CASES}


@pytest.mark.parametrize("integrator", sorted(ESTIMATORS))
@pytest.mark.parametrize("case", CASES)
def test_photon_estimators_agree_with_path_tracing_through_transparent_surfaces(
        case, integrator, path_images):
    # The old way (a pass a transmission bounce, shadow rays blocked: photons carried the
    # light the shadow rays lost) fails (b) with both estimators (3 of 12 block means outside
    # their intervals, the worst 6.7 % bright) and passed (a), (c) and (d) (measured); it fails
    # the closed-form test below. In (a) and (d) no photon is read (the light reaches the
    # floor only directly; its reflection escapes through the sheet): both estimators render
    # next-event estimation at visible points behind passes there, the same image.
    kw, seeds, detect = ESTIMATORS[integrator]
    scene, path = transparent_scene(case), path_images[case]
    reps = np.array([render.render(scene, _settings(seed=seed, **kw)).film.mean()
                     for seed in range(seeds)])
    assert np.isfinite(reps).all() and (reps >= 0).all()
    agreement = assert_images_agree(path.film.mean(), path.film.variance(), reps, block=8,
                                    mean_rtol=_bias_allowance(kw["photon_radius"]),
                                    detect=detect, what=f"{case}: {integrator} vs path")
    print(f"image-mean ratio path / {integrator}: {agreement.ratio}")


@pytest.mark.parametrize("integrator", sorted(ESTIMATORS))
@pytest.mark.parametrize("limit,lit", [(2, True), (1, False), (0, False)])
def test_photon_estimators_light_a_floor_through_the_sheet_the_sun_and_the_camera_look_through(
        integrator, limit, lit):
    # A sun straight down through a Transparent BSDF sheet of colour 0.6 onto the floor, seen
    # through the same sheet, direct light only (Max Bounces 0: no photon is read, the image is
    # next-event estimation at the visible points): every pixel is rho / pi E 0.6^2 exactly
    # (the sun is a delta light, the sheet passes every ray; colours are float32: rtol 1e-6),
    # so any error beyond 1e-6 is detected. With
    # a Transparent limit of 1 the camera path passes the sheet and its shadow ray may not
    # (as in the path tracer), with 0 the camera path ends at it: black. Before (a pass a
    # specular bounce, shadow rays blocked) the image was black at every limit.
    scene = transparent_scene("sheet_before_camera", light="sun")
    kw, _, _ = ESTIMATORS[integrator]
    img = render.render(scene, _settings(**{**kw, "spp": 2}, max_bounces=0,
                                         transparent_max_bounces=limit)).film.mean()
    closed = RHO_FLOOR / np.pi * SUN * 0.6 ** 2
    np.testing.assert_allclose(img, closed if lit else 0.0, rtol=1e-6, atol=1e-12)
    path = render.render(scene, _settings(integrator="path", spp=2, max_bounces=0,
                                          transparent_max_bounces=limit)).film.mean()
    np.testing.assert_allclose(path, closed if lit else 0.0, rtol=1e-6, atol=1e-12)


def test_photons_pass_a_transparent_sheet_without_a_bounce():
    # The sheet between the light and the floor passes every photon (colour 0.6): every photon
    # is stored on the floor (none on the sheet), its first hit there is hit 1 (no bounce),
    # not caustic, with 0.6 times the power it leaves the light with (the same photons traced
    # with the sheet at colour one, a limit of 8 passes). Before, the floor's first photons
    # were hit 2 and caustic (a pass was a specular bounce).
    prep = prepare(transparent_scene("sheet_between_light_and_floor"))
    floor_z = _floor_z(prep)
    n = 20_000

    def trace(limit, color=None):
        if color is not None:
            prep.material_bsdf.color[3] = color
        stream = make_sampler("independent", seed=5).stream(np.arange(n), np.zeros(n, np.int64))
        return trace_photons(prep, stream, 2, Counters(), transparent=limit)

    photons = trace(8)
    first = photons.hit == 1
    assert first.sum() > 0.5 * n
    assert not photons.caustic.any()
    np.testing.assert_allclose(photons.p[:, 2], floor_z, atol=1e-4)
    clear = trace(8, color=1.0)
    np.testing.assert_allclose(photons.power[first], 0.6 * clear.power[clear.hit == 1],
                               rtol=1e-6)
    # With a Transparent limit of 0 every photon ends at the sheet: none is stored.
    assert len(trace(0)) == 0


def _floor_z(prep):
    """The floor's height in the prepared (re-centred) frame: its first vertex's."""
    return float(prep.scene.vertices[0, 2])


@pytest.mark.parametrize("integrator", sorted(ESTIMATORS))
def test_photon_estimators_through_passes_give_the_same_image_for_one_or_two_threads(integrator):
    # The passes' component choices draw from each path's own stream dimensions.
    kw, _, _ = ESTIMATORS[integrator]
    scene = transparent_scene("leaf")
    imgs = [render.render(scene, _settings(**{**kw, "spp": 2}, seed=4, threads=t,
                                           sampler="sobol")).film.mean() for t in (1, 2)]
    assert imgs[0].max() > 0
    np.testing.assert_allclose(imgs[0], imgs[1], rtol=1e-9, atol=1e-12)


def test_photon_estimators_use_the_transparent_limit_and_report_nothing_about_passes():
    for integrator, (kw, _, _) in ESTIMATORS.items():
        res = render.render(transparent_scene("leaf"), _settings(**{**kw, "spp": 1}))
        assert not [m for m in res.messages if "transparent" in m.lower()], res.messages
        used = render.used_settings(_settings(transparent_max_bounces=3, **kw))
        assert used["transparent_max_bounces"] == 3
