"""Sampling strategies of the path tracer: every MIS setting, light-selection rule, area-light
sampling and discrete-sampling method is unbiased, and they agree with each other.

- MIS weights: for every setting the light-sampling and BSDF-sampling weights of the same path
  sum to one (the condition for an unbiased combination, Veach eq. 9.3).
- Closed forms: the furnace (``Le (1 - rho^(B+2)) / (1 - rho)``) and a light at the centre of a
  diffuse sphere (a point light, and a small sphere light that BSDF rays can hit, so that MIS
  matters) for every MIS setting with both light-selection rules; BSDF sampling alone renders
  the delta point light black, by definition.
- Agreement: on the Cornell box (area light, and mesh light for the emissive-triangle paths) every
  setting agrees with the power heuristic, block mean by block mean, within the confidence
  interval of the difference of two independent renders.
- Selection: uniform selection gives every light the same probability, the triangles of an
  emission material in proportion to their power; CDF and alias tables give the same
  probabilities; the render reports the tables' build and sampling times.

Tolerances: confidence intervals at p_false = 1e-4 per test (tests/helpers.py), chi-square at
alpha = 1e-3.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from sampling_lab.core import lights as L
from sampling_lab.core import scenes
from sampling_lab.core.prepare import prepare
from sampling_lab.core.render import render
from sampling_lab.core.sampling.mis import MIS_SETTINGS, bsdf_weight, light_weight
from tests.core.test_light_sampling import P_WORLD, _classify, _mixed_scene
from tests.helpers import (
    assert_mean_within_ci,
    assert_samples_agree,
    assert_two_images_agree,
    chi_square_test,
    plain_settings,
)

EPS = np.finfo(np.float64).eps
# Every MIS setting, with non-default parameters where it has them.
SETTINGS = ([(h, {}) for h in MIS_SETTINGS]
            + [("power", {"mis_beta": 1.5}), ("power", {"mis_beta": 4.0}),
               ("cutoff", {"mis_alpha": 0.3})])
SETTING_IDS = [h + "".join(f"-{k[4:]}{v:g}" for k, v in kw.items()) for h, kw in SETTINGS]
# The light sampler's switches, in two opposite combinations.
LIGHT_CONFIGS = {
    "power-area-cdf": dict(light_selection="power", light_sampling="area", distribution="cdf"),
    "uniform-solidangle-alias": dict(light_selection="uniform", light_sampling="solid_angle",
                                     distribution="alias"),
}


def pixel_means(result):
    return result.combined()[..., 0].ravel().astype(np.float64)


# --------------------------------------------------------------------------------------------
# MIS weights
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("setting, kw", SETTINGS, ids=SETTING_IDS)
def test_light_and_bsdf_weights_of_every_setting_sum_to_one_per_path(setting, kw):
    rng = np.random.default_rng(0)
    n = 20_000
    # Densities of sampled directions: light pdfs (selection included) and BSDF pdfs over a
    # wide range, plus exact ties.
    pdf_l = 10.0 ** rng.uniform(-6, 6, n)
    pdf_b = np.where(rng.random(n) < 0.1, pdf_l, 10.0 ** rng.uniform(-6, 6, n))
    beta, alpha = kw.get("mis_beta", 2.0), kw.get("mis_alpha", 0.1)
    w_l = light_weight(pdf_l, pdf_b, setting, beta, alpha)
    w_b = bsdf_weight(pdf_b, pdf_l, setting, beta, alpha)
    assert np.all((w_l >= 0) & (w_l <= 1) & (w_b >= 0) & (w_b <= 1))
    np.testing.assert_allclose(w_l + w_b, 1.0, rtol=0, atol=4 * EPS)
    # A BSDF ray that finds an emitter NEE cannot sample keeps all of it.
    np.testing.assert_array_equal(bsdf_weight(pdf_b, np.zeros(n), setting, beta, alpha), 1.0)
    # A light sample the BSDF cannot produce keeps all of it, except with BSDF sampling only.
    expected = 0.0 if setting == "bsdf" else 1.0
    np.testing.assert_array_equal(light_weight(pdf_l, np.zeros(n), setting, beta, alpha),
                                  expected)


def test_none_is_the_unweighted_average_and_single_strategies_are_all_or_nothing():
    a, b = np.array([1e-3, 1.0, 7.0]), np.array([5.0, 1.0, 1e-2])
    np.testing.assert_array_equal(light_weight(a, b, "none"), 0.5)
    np.testing.assert_array_equal(light_weight(a, b, "light"), 1.0)
    np.testing.assert_array_equal(bsdf_weight(b, a, "light"), 0.0)
    np.testing.assert_array_equal(light_weight(a, b, "bsdf"), 0.0)
    np.testing.assert_array_equal(bsdf_weight(b, a, "bsdf"), 1.0)


# --------------------------------------------------------------------------------------------
# Closed forms
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("config", list(LIGHT_CONFIGS))
@pytest.mark.parametrize("setting, kw", SETTINGS, ids=SETTING_IDS)
def test_every_setting_is_unbiased_in_the_furnace(setting, kw, config):
    rho, bounces = 0.5, 4
    scene = scenes.furnace(emission=1.0, albedo=rho, width=24, height=24)
    res = render(scene, plain_settings(spp=32, max_bounces=bounces, seed=11,
                                       mis_heuristic=setting, **kw, **LIGHT_CONFIGS[config]))
    assert_mean_within_ci(pixel_means(res), (1 - rho ** (bounces + 2)) / (1 - rho),
                          what=f"furnace {setting} {config}")


def _sphere_bracket(scene, power, rho, bounces):
    """Bounds of the closed form for a light at the centre of the icosphere (see test_path)."""
    tri = scene.vertices.astype(np.float64)[scene.triangles]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    r_min = float(np.abs(np.einsum("ij,ij->i", normal, tri[:, 0])).min())
    series = (1 - rho ** (bounces + 1)) / (1 - rho)
    hi = rho * power / (4 * np.pi) / (np.pi * r_min**2) * series
    lo = rho * power / (4 * np.pi) / np.pi * series
    return lo, hi


@pytest.mark.parametrize("config", list(LIGHT_CONFIGS))
@pytest.mark.parametrize("setting, kw", SETTINGS, ids=SETTING_IDS)
def test_every_setting_is_unbiased_for_a_sphere_light_in_a_sphere(setting, kw, config):
    """A small sphere light (BSDF rays hit it, so MIS weights matter) lights the walls as the
    point light of the same power does: every emitted photon reaches the enclosure, and the
    light does not block the light reflected across the sphere (Cycles' convention)."""
    rho, power, bounces = 0.5, 100.0, 4
    scene = scenes.point_in_sphere(power=power, albedo=rho, subdivisions=4, width=16, height=16)
    # The camera sits inside the sphere light, which would fill the view: hide it from the camera.
    scene.lights = L.point_light((0, 0, 0), (1, 1, 1), power, radius=0.15, visible_camera=False)
    res = render(scene, plain_settings(spp=48, max_bounces=bounces, seed=5,
                                       mis_heuristic=setting, **kw, **LIGHT_CONFIGS[config]))
    lo, hi = _sphere_bracket(scene, power, rho, bounces)
    assert_mean_within_ci(pixel_means(res), 0.5 * (hi + lo), atol=0.5 * (hi - lo),
                          what=f"sphere light {setting} {config}")


@pytest.mark.parametrize("config", list(LIGHT_CONFIGS))
@pytest.mark.parametrize("setting", [s for s in MIS_SETTINGS if s != "bsdf"])
def test_every_setting_but_bsdf_only_is_unbiased_for_a_point_light_in_a_sphere(setting, config):
    rho, power, bounces = 0.5, 100.0, 4
    scene = scenes.point_in_sphere(power=power, albedo=rho, subdivisions=4, width=16, height=16)
    res = render(scene, plain_settings(spp=32, max_bounces=bounces, seed=3,
                                       mis_heuristic=setting, **LIGHT_CONFIGS[config]))
    lo, hi = _sphere_bracket(scene, power, rho, bounces)
    assert_mean_within_ci(pixel_means(res), 0.5 * (hi + lo), atol=0.5 * (hi - lo),
                          what=f"point light {setting} {config}")


def test_bsdf_only_renders_a_delta_point_light_black_but_converges_for_an_area_light():
    point = render(scenes.cornell_box(16, 16, light="point"),
                   plain_settings(spp=8, mis_heuristic="bsdf"))
    # The point light of the scene has radius 0.05 in cornell_box: make it a true delta light.
    scene = scenes.cornell_box(16, 16, light="point")
    scene.lights = L.point_light((0, 0, 1.7), (1, 1, 1), 60.0, radius=0.0)
    delta = render(scene, plain_settings(spp=8, mis_heuristic="bsdf"))
    assert np.all(delta.combined()[..., :3] == 0.0), "BSDF sampling found a delta light"
    assert point.combined()[..., :3].mean() > 0, "a sphere light can be hit by BSDF rays"
    # The same point light with light sampling is lit: black is the strategy, not the scene.
    lit = render(scene, plain_settings(spp=2, mis_heuristic="power")).combined()[..., :3]
    assert lit.mean() > 0

    area = scenes.cornell_box(24, 24, light="area")
    a = render(area, plain_settings(spp=256, seed=1, max_bounces=3, mis_heuristic="bsdf"))
    b = render(area, plain_settings(spp=64, seed=2, max_bounces=3, mis_heuristic="power"))
    # Detects 21 % image-mean and 62 % block errors (99 % power): BSDF sampling alone is noisy.
    assert_two_images_agree(a.combined()[..., :3], a.variance(), b.combined()[..., :3],
                            b.variance(), detect=(0.24, 0.72),
                            what="bsdf only vs power, area light")


# --------------------------------------------------------------------------------------------
# Agreement on the Cornell box
# --------------------------------------------------------------------------------------------

RES = 24
SPP = 512


def _cornell(light, **kw):
    """The Cornell box; an area lamp is hidden from the camera (as Blender 5 makes lights):
    seen, its few antialiased edge pixels hold most of the image's variance and blind the
    comparison (it detected only 14 % image-mean errors) without testing any of the settings."""
    scene = scenes.cornell_box(RES, RES, light=light, **kw)
    scene.lights.visible_camera[:] = False
    return scene


@pytest.fixture(scope="module")
def cornell_reference():
    """Power heuristic, power selection, area sampling, CDF: the renderer's defaults."""
    out = {}
    for light in ("area", "mesh"):
        res = render(_cornell(light),
                     plain_settings(spp=3 * SPP, seed=1000, max_bounces=3))
        out[light] = (res.combined()[..., :3], res.variance())
    return out


AGREEMENT = ([pytest.param("area", dict(mis_heuristic=h, **kw), id=f"area-{i}")
              for (h, kw), i in zip(SETTINGS, SETTING_IDS)]
             + [pytest.param(light, dict(cfg), id=f"{light}-{name}")
                for light in ("area", "mesh") for name, cfg in LIGHT_CONFIGS.items()]
             + [pytest.param("mesh", dict(mis_heuristic=h, light_sampling="solid_angle"),
                             id=f"mesh-solidangle-{h}") for h in ("balance", "bsdf", "light")])


@pytest.mark.parametrize("light, overrides", AGREEMENT)
def test_settings_agree_with_the_power_heuristic_on_the_cornell_box(cornell_reference, light,
                                                                    overrides):
    spp = 4 * SPP if overrides.get("mis_heuristic") == "bsdf" else SPP
    res = render(_cornell(light),
                 plain_settings(spp=spp, seed=7, max_bounces=3, **overrides))
    ref, ref_var = cornell_reference[light]
    # Measured (99 % power, image mean / worst 8x8 block): area light 1.7 % / 5.2 %; mesh light
    # (seen by the camera) 7.1 % / 9.7 %; 7.2 % / 22 % without MIS or with BSDF sampling only.
    if overrides.get("mis_heuristic") in ("none", "bsdf"):
        detect = (0.085, 0.25)
    else:
        detect = (0.02, 0.06) if light == "area" else (0.085, 0.12)
    assert_two_images_agree(res.combined()[..., :3], res.variance(), ref, ref_var,
                            detect=detect, what=f"{light} {overrides}")


def test_agreement_check_rejects_a_five_percent_brighter_light(cornell_reference):
    """At the sample counts above the area-light check detects a 1.7 % image-mean error with
    99 % power: a lamp 5 % too bright (a wrong MIS weight or pdf misweights all direct light
    alike) is far outside its intervals."""
    scene = _cornell("area", light_power=42.0)
    res = render(scene, plain_settings(spp=SPP, seed=7, max_bounces=3))
    ref, ref_var = cornell_reference["area"]
    with pytest.raises(AssertionError, match="outside the interval"):
        assert_two_images_agree(res.combined()[..., :3], res.variance(), ref, ref_var,
                                detect=(0.02, 0.06))


# --------------------------------------------------------------------------------------------
# Light selection and discrete sampling
# --------------------------------------------------------------------------------------------


def _nee(prep, n, seed):
    rng = np.random.default_rng(seed)
    p = np.broadcast_to(P_WORLD - prep.shift, (n, 3)).astype(np.float64)
    return prep.lights.sample(p, rng.random(n), rng.random((n, 2)))


@pytest.mark.parametrize("method", ["cdf", "alias"])
def test_uniform_selection_chooses_every_light_equally(method):
    scene, hues, names, delta = _mixed_scene()
    prep = prepare(scene, light_selection="uniform", distribution=method)
    ls = prep.lights
    # 7 lamps, 2 emission materials (one triangle each) and the world: 10 lights.
    np.testing.assert_allclose(ls.select_prob, 0.1, rtol=1e-12)
    n = 200_000
    wi, dist, radiance, pdf, is_delta, _ = _nee(prep, n, 21)
    which, miss = _classify(radiance, hues)
    assert miss.max() < 1e-6
    chi_square_test(which, ls.select_prob, what=f"uniform selection ({method})")
    np.testing.assert_allclose(pdf[is_delta], 0.1, rtol=1e-12)


def test_uniform_selection_picks_triangles_of_a_material_by_power():
    # Two emission materials: one of three triangles of different areas, one of a single one.
    tris = np.array([[0, 0, 1], [1, 0, 1], [0, 1, 1],
                     [2, 0, 1], [4, 0, 1], [2, 2, 1],
                     [5, 0, 1], [5.5, 0, 1], [5, 0.5, 1],
                     [-2, 0, 1], [-1, 0, 1], [-2, 1, 1]], np.float64)
    faces = np.arange(12).reshape(4, 3)
    from tests.core.test_light_sampling import make_scene

    scene = make_scene(tris=(tris, faces), emissions=[(1.0, 1.0, 1.0), (5.0, 5.0, 5.0)],
                       tri_material=[0, 0, 0, 1])
    for method in ("cdf", "alias"):
        prep = prepare(scene, light_selection="uniform", distribution=method)
        ls = prep.lights
        area = prep.tri_area[:3]
        expected = np.zeros(ls.n_emitters)
        expected[ls.tri_emitter[:3]] = 0.5 * area / area.sum()
        expected[ls.tri_emitter[3]] = 0.5
        np.testing.assert_allclose(ls.select_prob, expected, rtol=1e-12)
        index, pmf = ls.choose(np.random.default_rng(3).random(100_000))
        np.testing.assert_allclose(pmf, ls.select_prob[index], rtol=1e-15)
        chi_square_test(index, expected, what=f"triangles by power ({method})")


def test_power_selection_is_the_same_for_cdf_and_alias_tables():
    scene, *_ = _mixed_scene()
    a = prepare(scene, distribution="cdf").lights
    b = prepare(scene, distribution="alias").lights
    np.testing.assert_allclose(a.select_prob, b.select_prob, rtol=1e-12)
    assert abs(a.select_prob.sum() - 1) < 1e-12


@pytest.mark.parametrize("selection, method", [("uniform", "cdf"), ("power", "alias"),
                                               ("uniform", "alias")])
def test_nee_irradiance_does_not_depend_on_the_selection_rule_or_table(selection, method):
    """Every emitter of the mixed scene at once: the irradiance estimate of any selection rule
    and table agrees with power selection by CDF (independent samples)."""
    scene, *_ = _mixed_scene()
    n = 400_000

    def irradiance(prep, seed):
        wi, dist, li, pdf, delta, _ = _nee(prep, n, seed)
        cos = np.maximum(wi[:, 2], 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(pdf[:, None] > 0, li * (cos / pdf)[:, None], 0.0)

    ref = irradiance(prepare(scene), 30)
    other = irradiance(prepare(scene, light_selection=selection, distribution=method,
                               light_sampling="solid_angle"), 31)
    assert_samples_agree(other, ref, what=f"irradiance {selection} {method}")


def test_render_stats_report_the_tables_build_and_sampling_time():
    scene = scenes.cornell_box(16, 16)
    for method in ("cdf", "alias"):
        res = render(scene, plain_settings(spp=4, distribution=method))
        s = res.stats
        assert s["distribution"] == method
        assert s["distribution_build_s"] > 0 and s["distribution_sample_s"] > 0
        # One light choice per NEE vertex, a second draw for the mesh light's triangle.
        assert s["distribution_samples"] >= s["samples"]
        assert s["distribution_ns_per_sample"] > 0
        assert (s["mis_heuristic"], s["light_selection"], s["light_sampling"]) == (
            "power", "power", "area")
    res = render(scene, plain_settings(spp=2, mis_heuristic="bsdf"))
    assert res.stats["distribution_samples"] == 0  # no light sampling, no draws


def test_progress_text_names_the_table_and_its_times():
    texts = []
    render(scenes.cornell_box(16, 16), plain_settings(spp=2, distribution="alias"),
           progress=lambda f, t: texts.append(t))
    assert "lights by alias table: build" in texts[-1] and "sampling" in texts[-1]


@pytest.mark.parametrize("field, value", [
    ("mis_heuristic", "veach"), ("mis_beta", 0.0), ("mis_beta", float("nan")),
    ("mis_alpha", 1.5), ("mis_alpha", -0.1), ("light_selection", "random"),
    ("light_sampling", "volume"), ("distribution", "inversion")])
def test_render_rejects_unknown_strategies_with_a_clear_message(field, value):
    with pytest.raises(ValueError, match=field.split("_")[-1]):
        render(scenes.cornell_box(8, 8), plain_settings(spp=1, **{field: value}))


@pytest.mark.parametrize("config", list(LIGHT_CONFIGS))
def test_zero_size_lights_and_a_light_on_a_surface_leave_no_nan(config):
    """Hard cases for the light switches: area lights of zero size (never hit, never chosen
    by power), a rectangle lying on the floor (receivers in its plane: zero solid angle)."""
    from sampling_lab.core.scene import Lights

    scene = scenes.cornell_box(16, 16, light="area")
    on_floor = np.eye(4)
    on_floor[:3, 3] = (0.2, 0.1, 0.0)
    flat = np.eye(4)
    flat[:3, 3] = (0.0, 0.0, 1.9)
    scene.lights = Lights.concat([
        scene.lights,
        L.area_light(flat, "RECTANGLE", 0.0, 0.5, (1, 1, 1), 10.0),
        L.area_light(flat, "DISK", 0.0, 0.0, (1, 1, 1), 10.0),
        L.area_light(on_floor, "SQUARE", 0.3, 0.3, (1, 1, 1), 10.0),
    ])
    for setting in ("power", "light", "bsdf"):
        res = render(scene, plain_settings(spp=4, mis_heuristic=setting, **LIGHT_CONFIGS[config]))
        for img in (res.combined(), res.variance()):
            assert np.isfinite(img).all()
        assert res.combined()[..., :3].min() >= 0 and res.combined()[..., :3].mean() > 0


# --------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------

CLI_DRIVER = """
import contextlib, io, json, sys
from sampling_lab.cli import main
results = {}
for name, argv in json.loads(sys.argv[1]).items():
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except BaseException as exc:
            code = f"raised {exc!r}"
    results[name] = [code, out.getvalue(), err.getvalue()]
print(json.dumps(results))
"""


@pytest.fixture(scope="module")
def cli_results(tmp_path_factory):
    """Runs ``cli.main`` in a helper process."""
    tmp = tmp_path_factory.mktemp("cli_strategies")
    base = ["render", "cornell", "--spp", "2", "--resolution", "16x16", "-o", f"{tmp}/a.exr"]
    cases = {
        "ok": base + ["--json", "--quiet", "--mis", "cutoff", "--mis-alpha", "0.25",
                      "--mis-beta", "3", "--light-selection", "uniform",
                      "--light-sampling", "solid_angle", "--distribution", "alias"],
        "bdpt solid angle": base + ["--json", "--quiet", "--integrator", "bdpt",
                                    "--light-sampling", "solid_angle"],
        "bad mis": base + ["--mis", "veach"],
        "bad beta": base + ["--mis-beta", "0"],
        "bad beta text": base + ["--mis-beta", "two"],
        "bad alpha": base + ["--mis-alpha", "1.5"],
        "bad selection": base + ["--light-selection", "random"],
        "bad sampling": base + ["--light-sampling", "volume"],
        "bad distribution": base + ["--distribution", "inversion"],
    }
    r = subprocess.run([sys.executable, "-c", CLI_DRIVER, json.dumps(cases)], cwd=tmp,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.splitlines()[-1])


def test_cli_strategy_flags_reach_the_renderer_and_its_json(cli_results):
    code, out, err = cli_results["ok"]
    assert code == 0, err
    stats = json.loads(out.strip().splitlines()[-1])
    # The cutoff heuristic has no beta: the stats say so and a note tells the user.
    assert (stats["mis_heuristic"], stats["mis_alpha"], stats["mis_beta"]) == (
        "cutoff", 0.25, "n/a")
    assert "note: --mis-beta 3.0 does not apply to path with --mis cutoff" in err
    assert (stats["light_selection"], stats["light_sampling"], stats["distribution"]) == (
        "uniform", "solid_angle", "alias")
    for key in ("distribution_build_s", "distribution_sample_s"):
        assert isinstance(stats[key], float) and stats[key] > 0, key


def test_cli_says_when_a_strategy_flag_does_not_apply_and_the_stats_report_what_was_used(
        cli_results):
    code, out, err = cli_results["bdpt solid angle"]
    assert code == 0, err
    stats = json.loads(out.strip().splitlines()[-1])
    assert stats["light_sampling"] == "area"
    assert "note: --light-sampling solid_angle does not apply to bdpt" in err
    assert "it uses area" in err


@pytest.mark.parametrize("case", ["bad mis", "bad beta", "bad beta text", "bad alpha",
                                  "bad selection", "bad sampling", "bad distribution"])
def test_cli_bad_strategy_values_exit_2_with_one_line(cli_results, case):
    code, out, err = cli_results[case]
    assert code == 2, err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("sampling_lab: error:"), err
    assert out == ""


@pytest.mark.parametrize("integrator, heuristic, expected", [
    ("path", "power", dict(mis_heuristic="power", mis_beta=3.0, mis_alpha="n/a",
                           light_selection="uniform", light_sampling="solid_angle")),
    ("path", "cutoff", dict(mis_beta="n/a", mis_alpha=0.25)),
    ("path", "bsdf", dict(mis_beta="n/a", mis_alpha="n/a", light_selection="n/a",
                          light_sampling="n/a", distribution="alias")),
    ("bdpt", "power", dict(mis_beta=3.0, light_selection="uniform", light_sampling="area")),
    ("light", "power", dict(mis_heuristic="n/a", mis_beta="n/a", light_sampling="area")),
])
def test_render_stats_report_the_strategy_settings_each_integrator_used(integrator, heuristic,
                                                                        expected):
    settings = plain_settings(integrator=integrator, spp=1, mis_heuristic=heuristic,
                              mis_beta=3.0, mis_alpha=0.25, light_selection="uniform",
                              light_sampling="solid_angle", distribution="alias")
    stats = render(scenes.cornell_box(8, 8), settings).stats
    assert {k: stats[k] for k in expected} == expected


@pytest.mark.parametrize("integrator", ["light", "bdpt"])
def test_solid_angle_setting_leaves_light_tracing_and_bdpt_images_unchanged(integrator):
    # They start light paths on emitters sampled by area: the setting is greyed out for them.
    images = [render(scenes.cornell_box(12, 12), plain_settings(
        integrator=integrator, spp=2, seed=4, light_sampling=s)).combined()
        for s in ("area", "solid_angle")]
    np.testing.assert_array_equal(images[0], images[1])
