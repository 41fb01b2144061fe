"""The sampling-strategy settings inside real Blender: properties, panel, mapping to the core,
renders with every switch, and .blend files carrying them to the command line."""

import importlib
import json
import subprocess
import sys

import bpy
import numpy as np
import pytest

import scenes as S
from panels import drawn_rows
from scenes import ADDON_MODULE, ENGINE_ID

STRATEGY_PROPS = ("mis_heuristic", "mis_beta", "mis_alpha", "light_selection", "light_sampling",
                  "distribution")


@pytest.fixture(scope="module")
def engine_module(addon):
    return importlib.import_module(f"{ADDON_MODULE}.addon.engine")


@pytest.fixture(scope="module")
def core(addon):
    """The add-on's own copies of the core modules that define the strategy names."""
    names = {"mis": "core.sampling.mis", "lights": "core.lights",
             "distributions": "core.sampling.distributions", "render": "core.render",
             "samplers": "core.sampling.samplers"}
    return {k: importlib.import_module(f"{ADDON_MODULE}.{v}") for k, v in names.items()}


def _enum_items(props, name):
    return list(props.bl_rna.properties[name].enum_items)


def test_strategy_defaults_are_the_renderers_and_map_to_core(empty_scene, engine_module, core):
    props = empty_scene.sampling_lab
    assert (props.mis_heuristic, props.light_selection, props.light_sampling,
            props.distribution) == ('POWER', 'TREE', 'AREA', 'CDF')
    defaults = core["render"].RenderSettings()
    s = engine_module.render_settings(props)
    for field in ("mis_heuristic", "mis_beta", "mis_alpha", "light_selection", "light_sampling",
                  "distribution"):
        assert getattr(s, field) == pytest.approx(getattr(defaults, field)), field
    props.mis_heuristic, props.mis_beta, props.mis_alpha = 'CUTOFF', 3.5, 0.25
    props.light_selection, props.light_sampling, props.distribution = (
        'UNIFORM', 'SOLID_ANGLE', 'ALIAS')
    s = engine_module.render_settings(props)
    assert (s.mis_heuristic, s.mis_beta, s.mis_alpha) == ("cutoff", 3.5, 0.25)
    assert (s.light_selection, s.light_sampling, s.distribution) == (
        "uniform", "solid_angle", "alias")


def test_every_strategy_choice_of_the_core_is_a_documented_menu_item(empty_scene, core):
    props = empty_scene.sampling_lab
    expected = {"mis_heuristic": core["mis"].MIS_SETTINGS,
                "light_selection": core["lights"].LIGHT_SELECTIONS,
                "light_sampling": core["lights"].LIGHT_SAMPLINGS,
                "distribution": core["distributions"].DISTRIBUTION_METHODS}
    for name, core_names in expected.items():
        items = _enum_items(props, name)
        assert {i.identifier.lower() for i in items} == set(core_names), name
        for item in items:
            assert item.name and len(item.description) > 40, (name, item.identifier)
    for name in STRATEGY_PROPS:
        assert props.bl_rna.properties[name].description, name
    # The documented limits: which lights solid-angle sampling leaves alone, what 'bsdf' misses.
    sa = next(i for i in _enum_items(props, "light_sampling") if i.identifier == 'SOLID_ANGLE')
    assert "disk" in sa.description.lower() and "ellipse" in sa.description.lower()
    bsdf = next(i for i in _enum_items(props, "mis_heuristic") if i.identifier == 'BSDF')
    assert "point" in bsdf.description.lower() and "black" in bsdf.description.lower()


def test_sampler_menu_lists_every_available_sampler_with_its_label(empty_scene, core):
    samplers = core["samplers"]
    items = _enum_items(empty_scene.sampling_lab, "sampler")
    loadable = []
    for name in samplers.available():
        try:
            loadable.append((name, samplers.sampler_class(name)))
        except Exception:  # noqa: BLE001 - a sampler that cannot load is left out of the menu
            continue
    assert [i.identifier for i in items] == [n.upper() for n, _ in loadable]
    for item, (name, cls) in zip(items, loadable):
        label = getattr(cls, "label", None)
        if label:
            assert item.name == label, name
        assert item.description, name
    assert items[0].identifier == 'INDEPENDENT'


@pytest.mark.parametrize("heuristic, shown", [
    ('POWER', {"mis_beta"}), ('CUTOFF', {"mis_alpha"}), ('BALANCE', set()),
    ('MAXIMUM', set()), ('NONE', set()), ('BSDF', set()), ('LIGHT', set())])
def test_light_sampling_panel_shows_each_heuristics_parameter_only_with_it(empty_scene, heuristic,
                                                                            shown):
    panel = bpy.types.SAMPLINGLAB_RENDER_PT_light_sampling
    assert panel.bl_parent_id == "SAMPLINGLAB_RENDER_PT_sampling"
    assert panel.COMPAT_ENGINES == {ENGINE_ID}

    empty_scene.sampling_lab.mis_heuristic = heuristic
    active = drawn_rows(panel.__name__, empty_scene)
    drawn = set(active)
    assert drawn & {"mis_beta", "mis_alpha"} == shown
    assert {"mis_heuristic", "light_selection", "light_sampling", "distribution"} <= drawn
    # BSDF sampling alone never samples lights: their options are drawn inactive.
    assert active["light_selection"] == (heuristic != 'BSDF')


@pytest.mark.parametrize("switches", [
    dict(mis_heuristic='BALANCE', light_selection='UNIFORM', light_sampling='SOLID_ANGLE',
         distribution='ALIAS'),
    dict(mis_heuristic='LIGHT', light_sampling='SOLID_ANGLE'),
    dict(mis_heuristic='BSDF'),
], ids=["balance-uniform-solidangle-alias", "light-solidangle", "bsdf"])
def test_renders_with_strategy_switches_agree_with_the_defaults(empty_scene, tmp_path, switches,
                                                                capfd):
    S.cornell_box(empty_scene, "area", (24, 24))
    S.set_sampling_lab(empty_scene, samples=256, seed=3, max_bounces=3)
    ref = S.render_to_exr(empty_scene, tmp_path / "ref.exr")
    for name, value in switches.items():
        setattr(empty_scene.sampling_lab, name, value)
    empty_scene.sampling_lab.seed = 4
    capfd.readouterr()
    out = S.render_to_exr(empty_scene, tmp_path / "switch.exr")
    log = capfd.readouterr().out
    for img in (out["Combined"], out["Variance"]):
        assert np.isfinite(img).all()
    from tests.helpers import assert_two_images_agree

    # Detects (image mean, worst 8x8 block) with 99 % power, measured: balance/uniform/solid
    # angle/alias 3.8 % / 14 %, light only 3.8 % / 14 %, BSDF only 25 % / 96 % (24 x 24 at 256
    # spp: this test checks that the switches reach the render; tests/core/test_strategies.py
    # holds the agreement of each setting).
    detect = (0.28, 1.1) if switches.get("mis_heuristic") == 'BSDF' else (0.045, 0.17)
    assert_two_images_agree(out["Combined"][..., :3], out["Variance"], ref["Combined"][..., :3],
                            ref["Variance"], detect=detect, what=str(switches))
    method = switches.get("distribution", "CDF").lower()
    assert f"by {method}, " in log, log[-2000:]
    if switches.get("mis_heuristic") != 'BSDF':
        assert f"emitters by {switches.get('light_sampling', 'AREA').lower()}, " in log


def test_blend_file_strategy_settings_reach_the_command_line(empty_scene, tmp_path):
    S.cornell_box(empty_scene, "mesh", (16, 12))
    S.set_sampling_lab(empty_scene, samples=3, seed=5, max_bounces=3)
    props = empty_scene.sampling_lab
    props.mis_heuristic, props.mis_beta = 'POWER', 3.0
    props.light_selection, props.light_sampling, props.distribution = (
        'UNIFORM', 'SOLID_ANGLE', 'ALIAS')
    engine = S.render_to_exr(empty_scene, tmp_path / "engine.exr")
    blend = tmp_path / "strategies.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    run = subprocess.run([sys.executable, "-m", "sampling_lab", "render", str(blend), "-o",
                          str(tmp_path / "cli.exr"), "--json", "--quiet"],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    stats = json.loads(run.stdout.strip().splitlines()[-1])
    assert (stats["mis_heuristic"], stats["mis_beta"], stats["light_selection"],
            stats["light_sampling"], stats["distribution"]) == (
        "power", 3.0, "uniform", "solid_angle", "alias")
    from sampling_lab.core.exr import read_multilayer

    cli = read_multilayer(tmp_path / "cli.exr")
    np.testing.assert_array_equal(cli["Combined"], engine["Combined"])


def test_mis_parameters_set_in_blender_reach_the_weights(empty_scene, tmp_path):
    # The limits of the parameters are other heuristics (tests/core/test_mis_parameters.py):
    # same seed, same weights, the same image bit for bit. A Beta or Alpha that did not reach
    # the renderer would break an equality.
    S.cornell_box(empty_scene, "mesh", (16, 12))
    S.set_sampling_lab(empty_scene, samples=2, seed=7, max_bounces=3)
    props = empty_scene.sampling_lab

    def image(heuristic, **values):
        props.mis_heuristic = heuristic
        for name, value in values.items():
            setattr(props, name, value)
        return S.render_to_exr(empty_scene, tmp_path / f"{heuristic}.exr")["Combined"]

    balance, maximum = image('BALANCE'), image('MAXIMUM')
    np.testing.assert_array_equal(image('POWER', mis_beta=1.0), balance)
    assert np.any(image('POWER', mis_beta=3.0) != balance)
    np.testing.assert_array_equal(image('CUTOFF', mis_alpha=0.0), balance)
    np.testing.assert_array_equal(image('CUTOFF', mis_alpha=1.0), maximum)


@pytest.mark.parametrize("mode, threads", [('FIXED', 1), ('FIXED', 3), ('AUTO', None)])
def test_blenders_thread_setting_sets_the_render_threads(empty_scene, engine_module, mode,
                                                         threads):
    import os

    render = empty_scene.render
    render.threads_mode = mode
    if threads is not None:
        render.threads = threads
    expected = threads if mode == 'FIXED' else os.cpu_count()
    assert engine_module.render_settings(empty_scene.sampling_lab).threads == expected


def test_render_stats_report_the_threads_used(empty_scene, tmp_path, capfd):
    S.cornell_box(empty_scene, "mesh", (8, 8))
    S.set_sampling_lab(empty_scene, samples=1)
    empty_scene.render.threads_mode, empty_scene.render.threads = 'FIXED', 3
    capfd.readouterr()
    S.render_to_exr(empty_scene, tmp_path / "processes.exr")  # the default: processes
    assert "on 3 worker processes" in capfd.readouterr().out
    empty_scene.sampling_lab.workers = 'THREADS'
    S.render_to_exr(empty_scene, tmp_path / "threads.exr")
    assert "on 3 threads" in capfd.readouterr().out
