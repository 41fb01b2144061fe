"""Light tracing, BDPT and BDPT's strategy views inside real Blender and on the command line:
menu items, properties and their mapping to the core, the render passes Blender is told about,
the images written into them, and the EXR layers of engine and CLI renders.
"""

import importlib
import json
import subprocess
import sys

import bpy
import numpy as np
import pytest

import scenes as S
from panels import drawn_rows
from scenes import ADDON_MODULE

BASE_OUTPUTS = ["Image", "Alpha", "Variance", "Sample Count"]


@pytest.fixture(scope="module")
def mods(addon):
    """The add-on's own modules (and its copies of the core's)."""
    names = {"engine": "addon.engine", "passes": "addon.passes", "render": "core.render",
             "film": "core.film", "common": "core.integrators.common",
             "integrators": "core.integrators"}
    return {k: importlib.import_module(f"{ADDON_MODULE}.{v}") for k, v in names.items()}


def _render_layer_outputs(scene):
    """Enabled outputs of a new compositor Render Layers node: the passes the engine declared
    in ``update_render_passes`` for the scene's settings."""
    tree = bpy.data.node_groups.new("Inspect", "CompositorNodeTree")
    try:
        node = tree.nodes.new("CompositorNodeRLayers")
        node.scene = scene
        return [o.name for o in node.outputs if o.enabled]
    finally:
        bpy.data.node_groups.remove(tree)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "sampling_lab", "render", *args],
                          capture_output=True, text=True, timeout=600)


# --------------------------------------------------------------------------- properties


def test_integrator_menu_offers_light_tracing_and_bidirectional_with_documentation(empty_scene,
                                                                                    mods):
    items = {i.identifier: i for i in
             empty_scene.sampling_lab.bl_rna.properties["integrator"].enum_items}
    # The Monte Carlo estimators first; the others (photon mapping, radiosity) follow them.
    assert list(items)[:3] == ['PATH', 'LIGHT', 'BDPT']
    # The photon estimators are biased, and their menu entries say so.
    for name in ('PHOTON', 'SPPM'):
        assert "biased but consistent" in items[name].description.lower()
    assert (items['LIGHT'].name, items['BDPT'].name) == ("Light Tracing", "Bidirectional")
    light, bdpt = items['LIGHT'].description.lower(), items['BDPT'].description.lower()
    assert "caustic" in light and "specular" in light and "no mis" in light
    assert "(s" in bdpt and "multiple importance sampling" in bdpt
    # Every estimator the core has is in the menu.
    assert set(mods["integrators"].INTEGRATORS) <= {k.lower() for k in items}


@pytest.mark.parametrize("item", ['PATH', 'LIGHT', 'BDPT', 'PHOTON', 'SPPM'])
def test_integrator_menu_item_maps_to_a_core_integrator_module(empty_scene, mods, item):
    empty_scene.sampling_lab.integrator = item
    name = mods["engine"].render_settings(empty_scene.sampling_lab).integrator
    assert name == item.lower()
    module = mods["integrators"].INTEGRATORS[name]
    assert module.__name__ == f"{ADDON_MODULE}.core.integrators.{name}"
    # What core.render builds once per render and calls for every work unit.
    cls = mods["integrators"].integrator_class(name)
    assert issubclass(cls, importlib.import_module(
        f"{ADDON_MODULE}.core.integrators.base").Integrator)
    assert cls.__module__ == module.__name__


def test_strategy_view_properties_default_to_the_core_and_map_to_render_settings(empty_scene,
                                                                                  mods):
    props = empty_scene.sampling_lab
    rna = props.bl_rna.properties
    defaults = mods["render"].RenderSettings()
    assert props.use_strategy_views is False and defaults.strategy_views is False
    assert props.strategy_max_length == defaults.strategy_max_length == 3
    assert (rna["strategy_max_length"].hard_min, rna["strategy_max_length"].hard_max) == (1, 8)
    assert rna["use_strategy_views"].name == "Strategy Views"
    assert rna["strategy_max_length"].name == "Max Path Length"
    assert "(s, t)" in rna["use_strategy_views"].description
    assert "segments" in rna["strategy_max_length"].description

    s = mods["engine"].render_settings(props)
    assert (s.integrator, s.strategy_views, s.strategy_max_length) == ("path", False, 3)
    props.integrator, props.use_strategy_views, props.strategy_max_length = 'BDPT', True, 5
    s = mods["engine"].render_settings(props)
    assert (s.integrator, s.strategy_views, s.strategy_max_length) == ("bdpt", True, 5)
    props.integrator = 'LIGHT'
    assert mods["engine"].render_settings(props).integrator == "light"


# --------------------------------------------------------------------------- UI


@pytest.mark.parametrize("integrator", ['PATH', 'LIGHT', 'BDPT'])
def test_strategy_views_panel_is_active_only_for_bidirectional(empty_scene, integrator):
    panel = bpy.types.SAMPLINGLAB_RENDER_PT_strategy_views
    assert panel.bl_parent_id == "SAMPLINGLAB_RENDER_PT_sampling"
    settings = empty_scene.sampling_lab
    settings.integrator, settings.use_strategy_views = integrator, True
    name = panel.__name__
    assert drawn_rows(name, empty_scene, header=True) == {
        "use_strategy_views": integrator == 'BDPT'}
    assert drawn_rows(name, empty_scene) == {"strategy_max_length": integrator == 'BDPT'}
    settings.use_strategy_views = False
    assert drawn_rows(name, empty_scene) == {"strategy_max_length": False}


@pytest.mark.parametrize("integrator", ['PATH', 'LIGHT', 'BDPT'])
def test_mis_options_are_active_for_path_and_bidirectional_not_light_tracing(empty_scene,
                                                                              integrator):
    settings = empty_scene.sampling_lab
    settings.integrator, settings.mis_heuristic = integrator, 'POWER'
    active = drawn_rows("SAMPLINGLAB_RENDER_PT_light_sampling", empty_scene)
    assert active["mis_heuristic"] == active["mis_beta"] == (integrator != 'LIGHT')
    assert active["light_selection"] and active["distribution"]
    # Light and BDPT paths start on emitters sampled by area: only the path tracer samples
    # them by solid angle.
    assert active["light_sampling"] == (integrator == 'PATH')


# --------------------------------------------------------------------------- passes


@pytest.mark.parametrize("integrator, views", [
    ('BDPT', True), ('BDPT', False), ('PATH', True), ('LIGHT', True)])
def test_strategy_passes_are_registered_only_for_bidirectional_with_views_on(empty_scene, mods,
                                                                             integrator, views):
    settings = empty_scene.sampling_lab
    settings.integrator, settings.use_strategy_views, settings.strategy_max_length = (
        integrator, views, 2)
    expected = BASE_OUTPUTS + (mods["common"].strategy_pass_names(2)
                               if integrator == 'BDPT' and views else [])
    assert _render_layer_outputs(empty_scene) == expected


def test_strategy_passes_follow_max_path_length(empty_scene, mods):
    settings = empty_scene.sampling_lab
    settings.integrator, settings.use_strategy_views = 'BDPT', True
    for k in (1, 4):
        settings.strategy_max_length = k
        names = mods["common"].strategy_pass_names(k)
        assert _render_layer_outputs(empty_scene) == BASE_OUTPUTS + names
        assert len(names) == 2 * len(mods["common"].strategies(k))


def test_changing_strategy_settings_updates_the_compositor_render_layers_node(empty_scene,
                                                                             mods):
    tree = bpy.data.node_groups.new("Compositor", "CompositorNodeTree")
    empty_scene.compositing_node_group = tree
    node = tree.nodes.new("CompositorNodeRLayers")
    node.scene = empty_scene

    def outputs():
        return [o.name for o in node.outputs if o.enabled]

    settings = empty_scene.sampling_lab
    assert outputs() == BASE_OUTPUTS
    settings.integrator, settings.use_strategy_views = 'BDPT', True
    assert outputs() == BASE_OUTPUTS + mods["common"].strategy_pass_names(3)
    settings.strategy_max_length = 1
    assert outputs() == BASE_OUTPUTS + mods["common"].strategy_pass_names(1)
    settings.integrator = 'PATH'
    assert outputs() == BASE_OUTPUTS


def test_pass_images_include_every_result_layer(mods):
    film = mods["film"].Film(4, 3)
    pixels = np.arange(12)
    rng = np.random.default_rng(1)
    film.add_samples(pixels, rng.random((12, 3)))
    names = mods["common"].strategy_pass_names(1)
    for i, name in enumerate(names):
        film.add_layer(name, pixels, np.full((12, 3), i + 0.5))
    result = mods["render"].RenderResult(film, layer_names=names)
    images = mods["passes"].pass_images(result)
    assert list(images) == ["Combined", "Variance", "Sample Count"] + names
    for i, name in enumerate(names):
        assert images[name].shape == (3, 4, 3) and images[name].dtype == np.float32
        np.testing.assert_array_equal(images[name], i + 0.5)
    np.testing.assert_array_equal(images["Combined"], film.combined())
    # Without layers only the three standard passes.
    plain = mods["render"].RenderResult(film)
    assert list(mods["passes"].pass_images(plain)) == ["Combined", "Variance", "Sample Count"]


def test_path_tracing_with_views_on_writes_only_the_standard_passes(empty_scene, tmp_path):
    S.cornell_box_mesh_light(empty_scene, resolution=(8, 6))
    S.set_sampling_lab(empty_scene, samples=1, max_bounces=2)
    empty_scene.sampling_lab.use_strategy_views = True
    passes = S.render_to_exr(empty_scene, tmp_path / "path.exr")
    assert set(passes) == {"Combined", "Variance", "Sample Count"}


def test_bidirectional_strategy_views_fill_render_passes_and_blender_exr(empty_scene, mods,
                                                                         tmp_path):
    S.cornell_box_mesh_light(empty_scene, resolution=(12, 8))
    S.set_sampling_lab(empty_scene, samples=2, max_bounces=3)
    settings = empty_scene.sampling_lab
    settings.integrator, settings.use_strategy_views, settings.strategy_max_length = (
        'BDPT', True, 2)
    passes = S.render_to_exr(empty_scene, tmp_path / "bdpt.exr")
    names = mods["common"].strategy_pass_names(2)
    assert set(passes) == {"Combined", "Variance", "Sample Count", *names}
    for name in names:
        assert passes[name].shape == (8, 12, 3), name
        assert np.isfinite(passes[name]).all() and passes[name].min() >= 0, name
    weighted = sum(passes[n] for n in names if n.endswith("weighted"))
    assert weighted.max() > 0, "every strategy view is black"


# --------------------------------------------------------------------------- command line


def test_cli_strategy_flags_reach_render_settings(tmp_path):
    out = tmp_path / "path.exr"
    run = _cli("cornell", "-o", str(out), "--resolution", "8x6", "--spp", "1",
               "--strategy-views", "--strategy-max-length", "2", "--json", "--quiet")
    assert run.returncode == 0, run.stderr
    stats = json.loads(run.stdout.strip().splitlines()[-1])
    # --json lists every layer the EXR holds: here no strategy views beside the three passes.
    assert (stats["strategy_views"], stats["strategy_max_length"], stats["layers"]) == (
        True, 2, ["Combined", "Variance", "Sample Count"])
    assert "writes no strategy views" in run.stderr
    from sampling_lab.core.exr import read_multilayer

    assert set(read_multilayer(out)) == {"Combined", "Variance", "Sample Count"}


@pytest.mark.parametrize("value", ["0", "9", "two"])
def test_cli_strategy_max_length_out_of_range_exits_2_with_one_line(tmp_path, value):
    run = _cli("cornell", "-o", str(tmp_path / "a.exr"), "--strategy-max-length", value)
    assert run.returncode == 2
    lines = run.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("sampling_lab: error:"), run.stderr
    # The registry's message: the option and its range.
    assert "strategy_max_length" in lines[0] and "in [1, 8]" in lines[0]
    assert not (tmp_path / "a.exr").exists()


def test_blend_file_strategy_views_reach_the_command_line(empty_scene, tmp_path):
    S.cornell_box_mesh_light(empty_scene, resolution=(8, 6))
    S.set_sampling_lab(empty_scene, samples=1, max_bounces=2)
    settings = empty_scene.sampling_lab
    settings.use_strategy_views, settings.strategy_max_length = True, 4
    blend = tmp_path / "views.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    run = _cli(str(blend), "-o", str(tmp_path / "o.exr"), "--json", "--quiet")
    assert run.returncode == 0, run.stderr
    stats = json.loads(run.stdout.strip().splitlines()[-1])
    assert (stats["strategy_views"], stats["strategy_max_length"]) == (True, 4)
    # A flag overrides the file.
    run = _cli(str(blend), "-o", str(tmp_path / "o.exr"), "--strategy-max-length", "1",
               "--json", "--quiet")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout.strip().splitlines()[-1])["strategy_max_length"] == 1


@pytest.mark.parametrize("integrator", ["light", "bdpt"])
def test_cli_renders_with_the_new_integrators(tmp_path, mods, integrator):
    out = tmp_path / f"{integrator}.exr"
    run = _cli("cornell", "-o", str(out), "--integrator", integrator, "--resolution", "8x6",
               "--spp", "2", "--strategy-views", "--strategy-max-length", "2", "--json",
               "--quiet")
    assert run.returncode == 0, run.stderr
    stats = json.loads(run.stdout.strip().splitlines()[-1])
    assert stats["integrator"] == integrator
    from sampling_lab.core.exr import read_multilayer

    passes = read_multilayer(out)
    names = mods["common"].strategy_pass_names(2) if integrator == "bdpt" else []
    assert stats["layers"] == ["Combined", "Variance", "Sample Count", *names]
    assert set(passes) == set(stats["layers"])
    for name in names:
        assert passes[name].shape == (6, 8, 3) and np.isfinite(passes[name]).all(), name
