"""Hard cases (``core/hard_cases.py``, table in ``docs/HARD_CASES.md``): every case renders with
every integrator without NaN or Inf in any pass, and agrees with its closed form where one
exists.

Agreement is checked on independent replicates (renders with different seeds; light-path
splats make a render's pixels dependent, so per-pixel variances would not do): each replicate
gives one number, the mean over the checked pixels of ``image - reference``, and their mean
must be zero within a Student-t interval of false-failure probability 1e-4. Each check also
computes the smallest relative error it detects with 99 % power and fails if that is above
``DETECT`` (the figure is printed), so a change that made it blind fails too.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from sampling_lab.core import hard_cases as H
from sampling_lab.core.camera import generate_rays
from sampling_lab.core.integrators import INTEGRATORS
from sampling_lab.core.metrics import normal_quantile, student_t_quantile
from sampling_lab.core.render import render
from sampling_lab.core.scenes import mirror_point_light_reference
from tests.helpers import plain_settings

# Smallest relative error every agreement check must detect with 99 % power.
DETECT = 0.04
P_FALSE = 1e-4
REPLICATES = 16
BOUNCES = 4  # furnace cases: few bounces keep them fast; the closed form counts them


@functools.lru_cache(maxsize=None)
def _scene(case):
    return H.CASES[case]()


def _settings(scene, integrator, **kw):
    """Small, independent-sampler settings; radiosity with one patch per triangle, one
    form-factor sample and the Jacobi solver (the albedo-1 mirrors of two cases, diffuse to
    radiosity, make systems without a solution: every solver runs its 1,000 sweeps, and
    Jacobi's are the cheapest); Metropolis with 4,096 bootstrap paths (not 100,000)."""
    if scene.n_triangles:
        v = scene.vertices[np.isfinite(scene.vertices).all(axis=1)].astype(np.float64)
        size = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    else:
        size = 1.0
    base = dict(integrator=integrator, spp=4, photons=2000, threads=1,
                radiosity_patch_size=max(size, 1e-6), radiosity_samples=1,
                radiosity_solver="jacobi", mlt_bootstrap=4096)
    return plain_settings(**{**base, **kw})


def _passes(result):
    return {"Combined": result.combined(), "Variance": result.variance(),
            "Sample Count": result.sample_count(), **result.layers()}


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
@pytest.mark.parametrize("case", list(H.CASES))
def test_hard_case_renders_finite_non_negative_passes(case, integrator):
    scene = _scene(case)
    settings = _settings(scene, integrator)
    if case == "emissive_100k" and integrator == "radiosity":
        # Its matrix solvers hold 8,192 patches: refused before any work, naming the fix.
        with pytest.raises(ValueError, match="patches, more than"):
            render(scene, settings)
        return
    result = render(scene, settings)
    assert result.stats["spp"] == settings.spp
    for name, image in _passes(result).items():
        assert np.isfinite(image).all(), f"{case}/{integrator}: NaN or Inf in {name}"
        assert image.min() >= 0, f"{case}/{integrator}: negative values in {name}"
    if case == "nonfinite_vertices":
        assert any("2 triangle(s) with NaN or infinite" in m for m in result.messages)
    if case == "empty_scene":
        assert result.combined()[..., :3].max() == 0
        assert any(m.startswith("the scene has no geometry") for m in result.messages)


def test_triangles_with_nonfinite_vertices_are_dropped_and_the_rest_kept():
    from sampling_lab.core.prepare import prepare

    scene = _scene("nonfinite_vertices")
    prep = prepare(scene)
    assert prep.scene.n_triangles == scene.n_triangles - 2
    assert np.isfinite(prep.scene.vertices).all()
    assert prep.notes == ["2 triangle(s) with NaN or infinite vertex coordinates were left out"]


def test_zero_area_lights_have_zero_power():
    lights = _scene("degenerate_lights").lights
    assert np.all(lights.power == 0.0) and np.all(lights.radiance == 0.0)


# ---------------------------------------------------------------------------------------------
# Agreement with closed forms
# ---------------------------------------------------------------------------------------------


# Samples per pixel of agreement checks: light tracing spreads its paths over the scene.
AGREEMENT_SPP = {"path": 16, "light": 64, "bdpt": 16}


def _replicates(scene, reference, mask, integrator, **kw):
    """``(REPLICATES,)`` means over ``mask`` of ``image - reference`` (grey references)."""
    kw.setdefault("spp", AGREEMENT_SPP[integrator])
    out, prepared = [], None
    for seed in range(REPLICATES):
        # The seed does not change the prepared scene (Persistent Data): built once.
        result = render(scene, _settings(scene, integrator, seed=seed, **kw), prepared=prepared)
        prepared = result.prepared
        out.append((result.combined()[..., :3] - reference[..., None])[mask].mean())
    return np.array(out)


def assert_replicates_agree(diffs, expected_mean, what):
    """Mean of ``diffs`` is zero within a Student-t interval; and the check detects an error of
    ``DETECT * expected_mean`` with 99 % power (printed: the smallest error it detects)."""
    n = len(diffs)
    se = diffs.std(ddof=1) / np.sqrt(n)
    q = -student_t_quantile(0.5 * P_FALSE, n - 1)
    smallest = (q - normal_quantile(0.01)) * se / expected_mean
    print(f"{what}: mean diff {diffs.mean():.4g} +- {se:.3g}; detects {100 * smallest:.2f} %")
    # 1e-6: float32 rounding of estimators that are exact on every sample (a sun on a plane).
    assert abs(diffs.mean()) <= q * se + 1e-6 * expected_mean, (
        f"{what}: image - reference = {diffs.mean():.4g}, {abs(diffs.mean()) / se:.1f} standard "
        f"errors (interval {q:.2f})")
    assert smallest <= DETECT, f"{what}: detects only {100 * smallest:.1f} % errors"


FURNACE_CASES = ["far_from_origin", "tiny_scale", "degenerate_triangles", "degenerate_lights",
                 "nonfinite_vertices", "inverted_normals", "zero_length_normals",
                 "emissive_100k"]


@pytest.mark.parametrize("integrator", ["path", "light", "bdpt"])
@pytest.mark.parametrize("case", FURNACE_CASES)
def test_furnace_cases_match_the_closed_form(case, integrator):
    scene = _scene(case)
    cam = scene.camera
    expected = H.furnace_value(BOUNCES)
    ref = np.full((cam.height, cam.width), expected)
    diffs = _replicates(scene, ref, np.ones_like(ref, bool), integrator, max_bounces=BOUNCES)
    assert_replicates_agree(diffs, expected, f"{case}/{integrator}")


def _plane_reference(scene, supersample=8):
    """Pixels (box filter) of a plane of :func:`core.hard_cases.grazing_plane_value` under a
    black sky: ``(reference (h, w), full (h, w) bool)``, ``full`` where every sub-ray hits."""
    cam, k = scene.camera, supersample
    ys, xs = np.mgrid[0:cam.height * k, 0:cam.width * k]
    xy = np.stack([(xs.ravel() + 0.5) / k, (ys.ravel() + 0.5) / k], axis=1)
    o, d, _ = generate_rays(cam, xy)
    half = np.abs(scene.vertices[:, 0]).max()
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -o[:, 2] / d[:, 2]
    p = o + np.where(t > 0, t, 0.0)[:, None] * d
    hit = ((t > 0) & (np.abs(p[:, :2]) <= half).all(axis=1)).astype(np.float64)
    frac = hit.reshape(cam.height, k, cam.width, k).mean(axis=(1, 3))
    return frac * H.grazing_plane_value(), frac == 1.0


@pytest.mark.parametrize("case,integrator", [
    ("grazing_camera", "path"), ("grazing_camera", "bdpt"),
    ("coplanar_faces", "path"), ("coplanar_faces", "light"), ("coplanar_faces", "bdpt")])
def test_sunlit_planes_match_the_closed_form(case, integrator):
    """Light tracing is left out of the grazing view: unbiased, but its light paths land on a
    2 km plane of which the camera sees a sliver."""
    scene = _scene(case)
    ref, full = _plane_reference(scene)
    assert full.sum() >= 16
    diffs = _replicates(scene, ref, full, integrator, filter_type="box", filter_width=1.0,
                        max_bounces=1, spp=4 * AGREEMENT_SPP[integrator])
    assert_replicates_agree(diffs, H.grazing_plane_value(), f"{case}/{integrator}")


@pytest.mark.parametrize("case,value", [("glass_block_tir", 1.0),
                                        ("camera_in_glass", H.GLASS_IOR ** 2)])
@pytest.mark.parametrize("integrator", ["path", "bdpt"])
def test_glass_in_a_white_world_matches_the_closed_form(case, value, integrator):
    """Lossless glass in a world of radiance 1: 1 from outside, n^2 from inside (radiance mode);
    64 bounces leave out only paths longer than that (Fresnel reflection is 4 % head-on)."""
    scene = _scene(case)
    cam = scene.camera
    ref = np.full((cam.height, cam.width), value)
    diffs = _replicates(scene, ref, np.ones_like(ref, bool), integrator, max_bounces=64)
    assert_replicates_agree(diffs, value, f"{case}/{integrator}")


@pytest.mark.parametrize("integrator", ["path", "light", "bdpt"])
def test_point_light_in_a_mirror_matches_the_closed_form(integrator):
    """The floor's direct light (every estimator) plus the light's mirror image (light paths
    only: path tracing cannot find a point light through a mirror)."""
    scene = H.point_mirror(16, 16)
    # Pixels that see only mirror-lit floor: the supersampled reference is accurate to 1e-4
    # there (a pixel that the floor's edge crosses would need far more sub-rays).
    direct, reflected, mask = mirror_point_light_reference(scene, supersample=32)
    ref = direct + (reflected if integrator != "path" else 0.0)
    diffs = _replicates(scene, ref, mask, integrator, filter_type="box", filter_width=1.0,
                        max_bounces=1)
    assert_replicates_agree(diffs, ref[mask].mean(), f"point_mirror/{integrator}")


@pytest.mark.parametrize("integrator", ["path", "light", "bdpt", "photon", "sppm"])
def test_a_light_inside_a_closed_mirror_is_never_seen(integrator):
    """No path from this point light to the camera has a non-delta vertex: exactly black."""
    result = render(_scene("light_in_mirror_sphere"),
                    _settings(_scene("light_in_mirror_sphere"), integrator))
    assert result.combined()[..., :3].max() == 0.0


@functools.lru_cache(maxsize=1)
def _ten_million():
    """The 10 M triangle plane and its prepared scene (built once for every integrator)."""
    scene = H.many_triangles(10_000_000)
    return scene, render(scene, _settings(scene, "path", spp=1)).prepared


@pytest.mark.slow
@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_ten_million_triangles_render_and_match_the_sunlit_plane(integrator):
    """10 M triangles (peak RSS: ``bench-limits``). The sunlit plane's closed form, exact on
    every camera sample for path tracing (checked to float32 rounding); finite for the others
    (BDPT's light-tracing strategy makes it noisy); radiosity refuses so many patches before
    any work."""
    scene, prepared = _ten_million()
    settings = _settings(scene, integrator, filter_type="box", filter_width=1.0, max_bounces=1)
    if integrator == "radiosity":
        with pytest.raises(ValueError, match="patches, more than"):
            render(scene, settings, prepared=prepared)
        return
    result = render(scene, settings, prepared=prepared)
    for name, image in _passes(result).items():
        assert np.isfinite(image).all(), name
    if integrator == "path":
        rgb = result.combined()[..., :3]
        np.testing.assert_allclose(rgb, H.grazing_plane_value(), rtol=1e-5)


@pytest.mark.parametrize("integrator", ["light", "bdpt"])
def test_light_paths_do_not_depend_on_the_scene_scale(integrator):
    """The same furnace at 1 m and 1 mm, the same seed: the same image. Russian roulette on
    light paths once looked at their absolute throughput (Watts): at 1 mm it killed nearly
    every path after the third bounce and weighted the survivors by hundreds, and the
    estimate read 1.5 % low (4.6 standard errors in the closed-form test)."""
    settings = _settings(_scene("tiny_scale"), integrator, spp=16, max_bounces=BOUNCES)
    images = [render(s, settings).combined()[..., :3]
              for s in (H._furnace(), _scene("tiny_scale"))]
    np.testing.assert_allclose(images[1], images[0], rtol=1e-4)
