"""Bump Map Correction (Cycles' shadowing of diffuse lobes on normal-mapped surfaces): the
closed form on a plane under a sun, the BSDF's sampled weights against its evaluation, and
light paths against camera paths."""

import dataclasses

import numpy as np
import pytest

from sampling_lab.core import lights as L
from sampling_lab.core.materials import bump_correction as bc
from sampling_lab.core.materials.bsdf import (IMPORTANCE, KIND_CONDUCTOR, KIND_DIFFUSE,
                                              KIND_LAYERED, RADIANCE, eval_bsdf, make_params,
                                              pdf_bsdf, sample_bsdf)
from sampling_lab.core.render import render
from sampling_lab.core.scene import Camera, Materials, Scene
from tests.core.test_normal_maps import with_normal_map
from tests.helpers import plain_settings

ALBEDO, IRRADIANCE = 0.8, 3.0


def tilt_color(tilt_deg):
    """The Normal Map colour of a normal tilted by ``tilt_deg`` toward tangent +X."""
    t = np.radians(tilt_deg)
    return tuple(0.5 * (np.array([np.sin(t), 0.0, np.cos(t)]) + 1.0))


def sun_plane(toward_sun, color, correction=True):
    """A diffuse plane z = 0 with a constant normal map under a sun, seen from above."""
    v = np.array([(-9, -9, 0), (9, -9, 0), (9, 9, 0), (-9, 9, 0)], np.float32)
    mats = Materials.from_lists(["White"], [(ALBEDO,) * 3], [(0, 0, 0)],
                                bump_correction=[correction])
    to_world = np.eye(4)
    to_world[2, 3] = 1.0
    cam = Camera(to_world, 8, 8, type="ORTHO", ortho_scale=1.0)
    toward_sun = np.asarray(toward_sun, np.float64) / np.linalg.norm(toward_sun)
    scene = Scene(v, [(0, 1, 2), (0, 2, 3)], [0, 0], mats,
                  L.sun_light(-toward_sun, (1, 1, 1), IRRADIANCE), cam)
    return with_normal_map(scene, [0], color), toward_sun


def cycles_shadowing(cos_d, cos_i):
    """Conty Estevez et al.'s term written out: GGX G1 at alpha^2 = tan^2(d) / 8."""
    alpha2 = min((1.0 / cos_d ** 2 - 1.0) / 8.0, 1.0)
    return 2.0 / (1.0 + np.sqrt(1.0 + alpha2 * (1.0 / cos_i ** 2 - 1.0)))


@pytest.mark.parametrize("tilt,sun_elevation", [(50.0, 23.8), (50.0, 45.0), (20.0, 10.0),
                                                (70.0, 60.0)])
def test_tilted_map_under_a_sun_is_darkened_by_the_shadowing_term(tilt, sun_elevation):
    e = np.radians(sun_elevation)
    toward_sun = (np.cos(e), 0.0, np.sin(e))  # in the tilt's plane, on its side
    scene, w = sun_plane(toward_sun, tilt_color(tilt))
    img = render(scene, plain_settings(spp=4, max_bounces=1, seed=3)).combined()[..., :3]
    t = np.radians(tilt)
    n = np.array([np.sin(t), 0.0, np.cos(t)])
    g = cycles_shadowing(np.cos(t), w[2])
    # A delta sun on a Lambertian plane: every sample is exactly rho E (n . l) G / pi, so the
    # image is that constant; at these angles G is 0.77-0.98 (a missing or misplaced term
    # is 2-23 % off, far beyond the 1e-4 rounding).
    expect = ALBEDO * IRRADIANCE * (n @ w) * g / np.pi
    assert g < 0.99
    np.testing.assert_allclose(img, expect, rtol=1e-4)
    off, _ = sun_plane(toward_sun, tilt_color(tilt), correction=False)
    plain = render(off, plain_settings(spp=4, max_bounces=1, seed=3)).combined()[..., :3]
    np.testing.assert_allclose(plain, expect / g, rtol=1e-4)


def test_shadowing_term_limits():
    n = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.6, 0.0, 0.8], [0.0, 0.0, 0.0]])
    w = np.array([[0.0, 0.6, 0.8], [0.6, 0.0, 0.8], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    # Unperturbed normal: 1; light along the smooth normal: 1; light in the smooth tangent
    # plane: 0; no correction (zero row): 1.
    np.testing.assert_allclose(bc.shadowing(n, w), [1.0, 1.0, 0.0, 1.0])


DETECTS_LIGHT = (0.05, 0.18)
DETECTS_BDPT = (0.04, 0.14)
SHEENED_METAL = "sheened metal"  # a conductor under a sheen: only the sheen is corrected


def bumped_params(kind):
    tilt = np.radians(40.0)
    if kind == SHEENED_METAL:
        params = make_params(np.array([KIND_CONDUCTOR]), (0.7, 0.5, 0.3), roughness=0.4, k=1,
                             sheen_weight=1.0, sheen_roughness=0.5)
    else:
        params = make_params(np.array([kind]), (0.7, 0.5, 0.3), roughness=0.4, k=1)
    # The smooth normal seen from the frame of the mapped one (tilted 40 degrees about Y).
    return dataclasses.replace(params, bump_normal=np.array([[-np.sin(tilt), 0.0,
                                                               np.cos(tilt)]]))


@pytest.mark.parametrize("kind", [KIND_DIFFUSE, KIND_LAYERED, SHEENED_METAL])
@pytest.mark.parametrize("mode", [RADIANCE, IMPORTANCE])
def test_sampled_weights_are_eval_over_pdf(kind, mode):
    rng = np.random.default_rng(4)
    k = 4096
    params = bumped_params(kind)
    params = params.take(np.zeros(k, np.int64))
    wo = np.tile([[0.5, 0.2, np.sqrt(1 - 0.29)]], (k, 1))
    smp = sample_bsdf(params, wo, rng.random(k), rng.random((k, 2)), mode)
    ok = (smp.pdf > 0) & ~smp.delta
    f = eval_bsdf(params.take(ok), wo[ok], smp.wi[ok], mode)
    np.testing.assert_allclose(smp.weight[ok], f / pdf_bsdf(params.take(ok), wo[ok],
                                                            smp.wi[ok])[:, None], rtol=1e-9)
    plain = eval_bsdf(dataclasses.replace(params.take(ok), bump_normal=None), wo[ok],
                      smp.wi[ok], mode)
    assert np.all(f <= plain + 1e-12) and np.any(f < 0.9 * plain)  # the term acted


@pytest.mark.parametrize("kind", [KIND_DIFFUSE, KIND_LAYERED, SHEENED_METAL])
def test_importance_mode_is_the_adjoint(kind):
    rng = np.random.default_rng(5)
    k = 256
    params = bumped_params(kind).take(np.zeros(k, np.int64))
    a, b = (v / np.linalg.norm(v, axis=1, keepdims=True)
            for v in (rng.normal(size=(k, 3)) + [0, 0, 2], rng.normal(size=(k, 3)) + [0, 0, 2]))
    a[:, 2], b[:, 2] = np.abs(a[:, 2]), np.abs(b[:, 2])
    # f_rad(wo=a, wi=b) / |cos b| == f_imp(wo=b, wi=a) / |cos a|: the same BSDF read from
    # the light's side (the shadowing on the light-side direction b in both).
    rad = eval_bsdf(params, a, b, RADIANCE) / b[:, 2:]
    imp = eval_bsdf(params, b, a, IMPORTANCE) / a[:, 2:]
    np.testing.assert_allclose(rad, imp, rtol=1e-9, atol=1e-12)


def tilted_box(size=24, tilt=40.0, correction=True):
    """A Cornell box (``size`` pixels square, area light) whose every surface has a normal map
    tilted ``tilt`` degrees, with Bump Map Correction (``correction``)."""
    from sampling_lab.core.scenes import cornell_box

    box = cornell_box(size, size, "area")
    rows = np.arange(len(box.materials.kind))
    box = with_normal_map(box, rows, tilt_color(tilt))
    return dataclasses.replace(box, materials=dataclasses.replace(
        box.materials, bump_correction=np.full(len(rows), correction)))


def rough_metal_box(size=16, roughness=0.45, correction=True):
    """:func:`tilted_box` at 55 degrees with every surface a conductor of ``roughness``: with
    Bump Map Correction the camera side bends the glossy normal wherever the view's
    reflection about the mapped normal would fall below the surface."""
    from sampling_lab.core.scene import MAT_CONDUCTOR

    box = tilted_box(size, 55.0, correction)
    m = len(box.materials.kind)
    return dataclasses.replace(box, materials=dataclasses.replace(
        box.materials, kind=np.full(m, MAT_CONDUCTOR, np.int32),
        roughness=np.full(m, roughness, np.float32)))


def lamp_mask(pt):
    """Pixels of the lamp seen by the camera, grown by one: most of the variance, drawn by
    camera rays alike in every integrator."""
    lamp = pt.mean(0).sum(-1) > 5.0
    lamp[:-1] |= lamp[1:]
    lamp[1:] |= lamp[:-1]
    lamp[:, :-1] |= lamp[:, 1:]
    lamp[:, 1:] |= lamp[:, :-1]
    return lamp


def test_light_tracing_and_bdpt_agree_with_path_tracing_with_the_correction():
    """A Cornell box whose every surface has a normal map tilted 40 degrees, corrected: the
    camera side shades in the mapped normal's frame by Cycles' rule where the view falls below
    it, light paths use the exact adjoint of that BSDF (:mod:`core.integrators.adjoint_normals`)
    and apply the term to the light-side direction, so the three estimate one image. Earlier
    rules each failed this check: choosing the normal by the light's direction made 4 of 30
    blocks 16-24 % brighter in light tracing; the adjoint of the facet fallback (while the
    path tracer already kept the mapped normal) made 4 of 30 blocks 4-16 % brighter
    (measured)."""
    from tests.core.test_bdpt import _replicates
    from tests.helpers import assert_replicates_agree

    box = tilted_box()
    rows = np.arange(len(box.materials.kind))
    kw = dict(max_bounces=3)
    pt = _replicates(box, "path", 24, 8, **kw)
    off = dataclasses.replace(box, materials=dataclasses.replace(
        box.materials, bump_correction=np.zeros(len(rows), bool)))
    print("uncorrected / corrected image mean:",
          _replicates(off, "path", 4, 8, **kw).mean() / pt.mean())
    # The lamp seen by the camera (and a pixel around it) holds most of the variance and is
    # drawn by camera rays alike in all three: left out, the check is five times sharper.
    lamp = lamp_mask(pt)
    # Smallest (image mean, block) errors detected with 99 % power, measured: light
    # tracing DETECTS_LIGHT, BDPT DETECTS_BDPT (the checker asserts them).
    for integrator, detect in (("light", DETECTS_LIGHT), ("bdpt", DETECTS_BDPT)):
        imgs = _replicates(box, integrator, 24, 4 if integrator == "bdpt" else 8, seed0=5, **kw)
        found = assert_replicates_agree(imgs, pt, mask=~lamp, detect=detect,
                                        what=f"{integrator} vs path (corrected normal maps)")
        print(f"{integrator}/path: image mean ratio {np.round(found.ratio, 4)}")


# The light side's weights f / mixture are heavy-tailed here (the bent lobe lies between the
# two proposal frames), so light tracing needs many replicates for a sharp interval.
DETECTS_BENT_LIGHT = (0.15, 0.40)
DETECTS_BENT_BDPT = (0.10, 0.30)


def test_light_paths_use_the_bent_glossy_normal_of_the_camera_side():
    """Rough conductors (roughness 0.45) under 55-degree maps with Bump Map Correction: the
    camera side bends each glossy normal for the direction toward the camera (Cycles'
    ``ensure_valid_specular_reflection``), so the BSDF depends on that direction; light
    tracing and BDPT evaluate that BSDF exactly and sample a mixture whose pdf they use.
    Before, light paths shaded around the unbent normal: light tracing was 27-37 % darker than
    path tracing per channel, 21 of 30 blocks beyond their intervals (measured)."""
    from tests.core.test_bdpt import _replicates
    from tests.helpers import assert_replicates_agree

    box = rough_metal_box()
    kw = dict(max_bounces=3)
    pt = _replicates(box, "path", 16, 16, **kw)
    lamp = lamp_mask(pt)
    # Smallest (image mean, block) errors detected with 99 % power, measured 11 % / 30 %
    # (light tracing) and 9 % / 16 % (BDPT); the checker asserts DETECTS_BENT_*.
    for integrator, runs, spp, detect in (("light", 128, 16, DETECTS_BENT_LIGHT),
                                          ("bdpt", 16, 8, DETECTS_BENT_BDPT)):
        imgs = _replicates(box, integrator, runs, spp, seed0=5, **kw)
        found = assert_replicates_agree(imgs, pt, mask=~lamp, detect=detect,
                                        what=f"{integrator} vs path (bent glossy normals)")
        print(f"{integrator}/path: image mean ratio {np.round(found.ratio, 4)}")


BENT_MIRROR_NOTE = "light paths do not sample the bent mirror normal"


def test_bent_smooth_mirrors_are_reported_by_name_for_light_paths():
    """Smooth (roughness 0) mirrors have no exact adjoint sample of the bent normal: renders
    with light paths say so, naming the materials; the path tracer, rough lobes and mapped
    materials without the correction (no bending) say nothing."""
    def notes(box, integrator):
        res = render(box, plain_settings(integrator=integrator, spp=1, max_bounces=1))
        return [m for m in res.messages if BENT_MIRROR_NOTE in m]

    mirror = rough_metal_box(8, roughness=0.0)
    found = notes(mirror, "light")
    assert len(found) == 1 and all(name in found[0] for name in mirror.materials.names)
    assert notes(mirror, "bdpt")
    assert not notes(mirror, "path")
    assert not notes(rough_metal_box(8), "light")
    assert not notes(rough_metal_box(8, roughness=0.0, correction=False), "light")
