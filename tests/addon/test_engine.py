"""The render engine inside real Blender: passes, EXR output, errors, UI, packaging."""

import importlib
import math
import os
import subprocess
import sys
from pathlib import Path

import addon_utils
import bpy
import numpy as np
import pytest

import scenes
from scenes import ADDON_MODULE, ENGINE_ID, REPO_ROOT, registered_engines

BLENDER_EXT = (Path(bpy.utils.system_resource('SCRIPTS')) / "addons_core" / "bl_pkg" / "cli"
               / "blender_ext.py")


@pytest.fixture(scope="module")
def engine_module(addon):
    return importlib.import_module(f"{ADDON_MODULE}.addon.engine")


# --------------------------------------------------------------------------- rendering


def test_tiny_render_fills_every_pass_with_finite_values(empty_scene, tmp_path):
    scenes.cornell_box_mesh_light(empty_scene, resolution=(32, 24))
    scenes.set_sampling_lab(empty_scene, samples=4)
    passes = scenes.render_to_exr(empty_scene, tmp_path / "tiny.exr")
    assert set(passes) == {"Combined", "Variance", "Sample Count"}
    combined, variance, count = passes["Combined"], passes["Variance"], passes["Sample Count"]
    assert combined.shape == (24, 32, 4)
    assert variance.shape == (24, 32, 3)
    assert count.shape == (24, 32, 1)
    for image in (combined, variance, count):
        assert np.isfinite(image).all()
    assert combined[..., :3].min() >= 0 and combined[..., :3].mean() > 0.01
    np.testing.assert_array_equal(combined[..., 3], 1.0)
    assert variance.min() >= 0 and variance.max() > 0
    np.testing.assert_array_equal(count, 4.0)


def test_multilayer_exr_channel_names(empty_scene, tmp_path):
    import OpenEXR

    scenes.cornell_box_point_light(empty_scene, resolution=(8, 8))
    scenes.set_sampling_lab(empty_scene, samples=1)
    path = tmp_path / "names.exr"
    scenes.render_to_exr(empty_scene, path)
    with OpenEXR.File(str(path), separate_channels=True) as f:
        names = {name for part in f.parts for name in part.channels}
    layer = empty_scene.view_layers[0].name
    for expected in ("Combined.R", "Combined.G", "Combined.B", "Combined.A",
                     "Variance.R", "Variance.G", "Variance.B", "Sample Count.X"):
        assert f"{layer}.{expected}" in names


def test_render_result_row_zero_is_the_bottom_row(empty_scene, tmp_path):
    # An emitter filling the lower half of the view and nothing above the horizon.
    glow = scenes.emission_material("Glow", (1.0, 1.0, 1.0), 1.0)
    scenes.add_quad(empty_scene, "Ground", [(-50, 5, -50), (50, 5, -50), (50, 5, -0.01),
                                            (-50, 5, -0.01)], glow)
    scenes.set_world(empty_scene, (0, 0, 0), 0.0)
    scenes.add_camera(empty_scene, (0, 0, 0), (math.radians(90), 0, 0))
    scenes.set_resolution(empty_scene, 16, 16)
    scenes.set_sampling_lab(empty_scene, samples=2, filter_type='BOX', filter_width=1.0)
    rgb = scenes.render_to_exr(empty_scene, tmp_path / "rows.exr")["Combined"][..., :3]
    np.testing.assert_allclose(rgb[:7], 1.0, rtol=1e-5)
    np.testing.assert_allclose(rgb[9:], 0.0)


def test_camera_rays_that_escape_see_the_world_radiance(empty_scene, tmp_path):
    scenes.set_world(empty_scene, (0.2, 0.4, 0.6), 2.0)
    scenes.add_camera(empty_scene, (0, 0, 5), (0, 0, 0))
    scenes.set_resolution(empty_scene, 8, 8)
    scenes.set_sampling_lab(empty_scene, samples=2)
    passes = scenes.render_to_exr(empty_scene, tmp_path / "world.exr")
    np.testing.assert_allclose(passes["Combined"][..., :3], np.broadcast_to([0.4, 0.8, 1.2],
                                                                           (8, 8, 3)), rtol=1e-6)
    np.testing.assert_array_equal(passes["Variance"], 0.0)


def test_sun_scene_renders(empty_scene, tmp_path):
    scenes.plane_under_sun(empty_scene, resolution=(16, 16))
    scenes.set_sampling_lab(empty_scene, samples=2)
    rgb = scenes.render_to_exr(empty_scene, tmp_path / "sun.exr")["Combined"][..., :3]
    assert np.isfinite(rgb).all() and rgb.mean() > 0


def _engine_class():
    return next(c for c in bpy.types.RenderEngine.__subclasses__()
                if getattr(c, "bl_idname", None) == ENGINE_ID)


class _FakeClock:
    """Stands in for the ``time`` module of the add-on's ``core.render``: its clock moves only
    when the test moves it, so the time limit runs out at a chosen point on any machine."""

    def __init__(self):
        self.now = 0.0

    def perf_counter(self):
        return self.now


def test_time_limit_stops_early_and_keeps_samples(empty_scene, tmp_path, monkeypatch):
    scenes.cornell_box_area_light(empty_scene, resolution=(8, 8))
    limit, polls_before_limit, backstop = 10.0, 3, 50
    scenes.set_sampling_lab(empty_scene, samples=1 << 24, time_limit=limit)
    clock = _FakeClock()
    monkeypatch.setattr(importlib.import_module(f"{ADDON_MODULE}.core.passes"), "time", clock)
    polls = []

    def cancel_requested(self):
        # Polled after every work unit (and once more when the render stops, to tell a cancel
        # from a time limit): the clock reaches the limit at the third poll. The backstop only
        # ends a render whose time limit is broken.
        polls.append(1)
        if len(polls) == polls_before_limit:
            clock.now = limit
        return len(polls) > backstop

    monkeypatch.setattr(_engine_class(), "cancel_requested", cancel_requested)
    passes = scenes.render_to_exr(empty_scene, tmp_path / "limit.exr")
    assert len(polls) <= polls_before_limit + 1, (
        f"{len(polls)} polls: the render went on after its time limit")
    count = passes["Sample Count"]
    assert 1 <= count.min() and count.max() < 1 << 24
    assert np.isfinite(passes["Combined"]).all()


def test_progressive_updates_show_the_image_so_far(empty_scene, tmp_path, engine_module,
                                                   monkeypatch):
    scenes.cornell_box_point_light(empty_scene, resolution=(8, 8))
    scenes.set_sampling_lab(empty_scene, samples=256)
    monkeypatch.setattr(engine_module, "UPDATE_INTERVAL", 0.0)
    passes_module = engine_module.passes
    write_passes = passes_module.write_passes
    counts = []

    def recording_write_passes(layer, images):
        counts.append(float(images["Sample Count"].mean()))
        write_passes(layer, images)

    monkeypatch.setattr(passes_module, "write_passes", recording_write_passes)
    passes = scenes.render_to_exr(empty_scene, tmp_path / "progressive.exr")
    # Several partial images, each with more samples, then the final one.
    assert len(counts) >= 3
    assert counts == sorted(counts) and 0 < counts[0] < 256 and counts[-1] == 256
    np.testing.assert_array_equal(passes["Sample Count"], 256)


def test_cancelled_render_keeps_the_samples_taken(empty_scene, tmp_path, monkeypatch):
    scenes.cornell_box_point_light(empty_scene, resolution=(64, 64))
    # The time limit only bounds the test if cancelling were broken.
    scenes.set_sampling_lab(empty_scene, samples=1 << 20, time_limit=20.0)
    units = []  # Esc once two work units have reported their progress

    def update_progress(self, fraction):
        units.append(fraction)

    monkeypatch.setattr(_engine_class(), "update_progress", update_progress, raising=False)
    monkeypatch.setattr(_engine_class(), "cancel_requested", lambda self: len(units) >= 2)
    passes = scenes.render_to_exr(empty_scene, tmp_path / "cancel.exr")
    count = passes["Sample Count"]
    assert count.max() >= 1 and count.max() < 1 << 20
    assert np.isfinite(passes["Combined"]).all()
    lit = count[..., 0] > 0
    assert passes["Combined"][lit][:, :3].mean() > 0


def test_same_seed_same_image(empty_scene, tmp_path):
    scenes.cornell_box_point_light(empty_scene, resolution=(8, 8))
    scenes.set_sampling_lab(empty_scene, samples=2, seed=7)
    a = scenes.render_to_exr(empty_scene, tmp_path / "a.exr")["Combined"]
    b = scenes.render_to_exr(empty_scene, tmp_path / "b.exr")["Combined"]
    empty_scene.sampling_lab.seed = 8
    c = scenes.render_to_exr(empty_scene, tmp_path / "c.exr")["Combined"]
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_unsupported_material_warns_but_renders(empty_scene, tmp_path, capfd):
    scenes.cornell_box_mesh_light(empty_scene, resolution=(8, 8))
    toon = scenes.shader_material("Toon", "ShaderNodeBsdfToon")
    bpy.data.objects["TallBlock"].data.materials[0] = toon
    scenes.set_sampling_lab(empty_scene, samples=1)
    capfd.readouterr()
    passes = scenes.render_to_exr(empty_scene, tmp_path / "toon.exr")
    # The engine reports it with RenderEngine.report({'WARNING'}, ...), which Blender prints
    # (in background mode) with its level; an INFO or ERROR report would read otherwise.
    captured = capfd.readouterr()
    log = captured.out + captured.err
    assert ("Warning: Sampling Lab: Material 'Toon': node 'Toon BSDF' is not supported yet"
            in log), log
    assert np.isfinite(passes["Combined"]).all()
    np.testing.assert_array_equal(passes["Sample Count"], 1.0)
    assert passes["Combined"][..., :3].mean() > 0  # a lit image, not an empty result


def test_approximations_are_reported_once_per_render(empty_scene, tmp_path, capfd):
    scenes.cornell_box_mesh_light(empty_scene, resolution=(8, 8))
    toon = scenes.shader_material("Toon", "ShaderNodeBsdfToon")
    for name in ("TallBlock", "ShortBlock"):
        bpy.data.objects[name].data.materials[0] = toon
    scenes.set_sampling_lab(empty_scene, samples=1)
    capfd.readouterr()
    scenes.render_to_exr(empty_scene, tmp_path / "once.exr")
    out = capfd.readouterr().out
    assert out.count("Material 'Toon': node 'Toon BSDF' is not supported yet") == 1, out


def test_every_view_layer_gets_its_passes(empty_scene, tmp_path):
    scenes.cornell_box_point_light(empty_scene, resolution=(8, 8))
    empty_scene.view_layers.new("Second")
    scenes.set_sampling_lab(empty_scene, samples=1)
    passes = scenes.render_to_exr(empty_scene, tmp_path / "layers.exr")
    first = empty_scene.view_layers[0].name
    for layer in (first, "Second"):
        for name in ("Combined", "Variance", "Sample Count"):
            assert f"{layer}.{name}" in passes
    np.testing.assert_array_equal(passes["Second.Sample Count"], 1.0)


# --------------------------------------------------------------------------- errors


def test_non_camera_scene_camera_is_a_render_error(empty_scene):
    scenes.add_quad(empty_scene, "Q", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    empty = bpy.data.objects.new("Empty", None)
    empty_scene.collection.objects.link(empty)
    empty_scene.camera = empty
    scenes.set_resolution(empty_scene, 8, 8)
    with pytest.raises(RuntimeError, match="Sampling Lab: the scene camera 'Empty'"):
        bpy.ops.render.render()


def test_missing_embreex_is_reported_by_name(empty_scene, engine_module, monkeypatch):
    scenes.cornell_box_point_light(empty_scene, resolution=(8, 8))
    monkeypatch.setattr(engine_module, "REQUIRED_MODULES", ("embreex_not_installed",))
    with pytest.raises(RuntimeError, match="embreex_not_installed"):
        bpy.ops.render.render()


def test_a_render_failing_half_way_keeps_its_samples_and_says_so(empty_scene, tmp_path,
                                                                 monkeypatch, capfd):
    scenes.cornell_box_point_light(empty_scene, resolution=(160, 120))
    scenes.set_sampling_lab(empty_scene, samples=4)
    # Threads: the patch below exists in this process only, not in worker processes.
    empty_scene.sampling_lab.workers = 'THREADS'
    path = importlib.import_module(f"{ADDON_MODULE}.core.integrators.path")
    original = path.PathTracer.render_samples
    # One 64 k-path unit per batch: the frame's 76,800 paths are then two units.
    monkeypatch.setattr(path.PathTracer, "batch_units", 1)

    def render_samples(self, stream, *args):
        # Every unit but the first (pixel 0, sample 0) breaks. Chosen by what the unit holds,
        # not by call order: two workers may start their units in either order.
        if stream.pixel.min() > 0 or stream.sample_index.min() > 0:
            raise RuntimeError("unit broke")
        return original(self, stream, *args)

    monkeypatch.setattr(path.PathTracer, "render_samples", render_samples)
    # The render goes on to write its file, with a warning that says what failed.
    passes = scenes.render_to_exr(empty_scene, tmp_path / "failed.exr")
    # The file holds the first unit's samples (half the frame's), finite.
    assert passes["Sample Count"].sum() == 160 * 120 * 4 / 2
    assert np.isfinite(passes["Combined"]).all()
    assert passes["Combined"][..., :3].mean() > 0
    assert "render failed part-way: RuntimeError: unit broke" in capfd.readouterr().out


def test_unexpected_exception_becomes_an_error_report(empty_scene, export, monkeypatch):
    scenes.cornell_box_point_light(empty_scene, resolution=(8, 8))

    def broken(depsgraph, camera_object=None):
        raise ZeroDivisionError("synthetic failure")

    monkeypatch.setattr(export, "export_scene", broken)
    with pytest.raises(RuntimeError, match="render failed: ZeroDivisionError: synthetic"):
        bpy.ops.render.render()


def test_a_refused_setting_is_one_error_report_without_a_traceback(empty_scene, capfd):
    """Core's refusals (here photons that need more than the Photon Memory cap) reach Blender
    as one ERROR report naming the cause, not as the catch-all with a traceback."""
    scenes.cornell_box_point_light(empty_scene, resolution=(8, 8))
    props = empty_scene.sampling_lab
    props.integrator, props.photons, props.photon_memory = 'SPPM', 1 << 26, 1.0
    capfd.readouterr()
    with pytest.raises(RuntimeError, match="Sampling Lab: photon storage") as err:
        bpy.ops.render.render()
    assert "render failed" not in str(err.value)
    assert "Traceback" not in capfd.readouterr().err


def test_a_huge_resolution_is_refused_before_blender_allocates_it(empty_scene):
    scenes.cornell_box_point_light(empty_scene, resolution=(8, 8))
    scenes.set_resolution(empty_scene, 65536, 65536)
    with pytest.raises(RuntimeError, match="a 65536 x 65536 image needs about"):
        bpy.ops.render.render()


def test_a_small_cropped_region_of_a_huge_frame_is_not_refused(empty_scene, tmp_path):
    """The film-memory check counts the pixels Blender allocates: a cropped Render Region's
    (8 x 8 of a 65536 x 65536 frame, whose full film the check above refuses)."""
    scenes.cornell_box_point_light(empty_scene, resolution=(8, 8))
    scenes.set_sampling_lab(empty_scene, samples=1)
    scenes.set_resolution(empty_scene, 65536, 65536)
    render = empty_scene.render
    render.use_border, render.use_crop_to_border = True, True
    render.border_min_x, render.border_min_y = 0.5, 0.5
    render.border_max_x = render.border_max_y = 0.5 + 8 / 65536
    passes = scenes.render_to_exr(empty_scene, tmp_path / "region.exr")
    assert passes["Combined"].shape[:2] == (8, 8)
    assert np.isfinite(passes["Combined"]).all()


def test_a_bug_is_reported_as_a_failure_with_its_traceback(empty_scene, monkeypatch, capfd):
    """A ValueError that is not a refusal (a NumPy error inside the core) is a render failure
    with its traceback in the console, not a one-line refusal."""
    scenes.cornell_box_point_light(empty_scene, resolution=(8, 8))
    core_render = importlib.import_module(f"{ADDON_MODULE}.core.render")

    def broken_prepare(*args, **kw):
        raise ValueError("operands could not be broadcast together")

    monkeypatch.setattr(core_render, "prepare", broken_prepare)
    capfd.readouterr()
    with pytest.raises(RuntimeError, match="render failed: ValueError: operands") as err:
        bpy.ops.render.render()
    assert "traceback in the console" in str(err.value)
    assert "Traceback" in capfd.readouterr().err


def test_a_bug_half_way_keeps_the_samples_and_prints_its_traceback(empty_scene, tmp_path,
                                                                    monkeypatch, capfd):
    scenes.cornell_box_point_light(empty_scene, resolution=(160, 120))
    scenes.set_sampling_lab(empty_scene, samples=4)
    # One worker thread: the second call is the second unit, after the first has finished.
    empty_scene.render.threads_mode, empty_scene.render.threads = 'FIXED', 1
    path = importlib.import_module(f"{ADDON_MODULE}.core.integrators.path")
    original, calls = path.PathTracer.render_samples, []
    monkeypatch.setattr(path.PathTracer, "batch_units", 1)  # two 64 k-path units

    def render_samples(self, *args):  # the second work unit meets a NumPy-style ValueError
        calls.append(1)
        if len(calls) == 2:
            raise ValueError("shapes (3,) and (4,) not aligned")
        return original(self, *args)

    monkeypatch.setattr(path.PathTracer, "render_samples", render_samples)
    passes = scenes.render_to_exr(empty_scene, tmp_path / "failed.exr")
    assert passes["Sample Count"].sum() == 160 * 120 * 4 / 2
    out = capfd.readouterr()
    assert "render failed part-way: ValueError: shapes" in out.out
    assert "Traceback" in out.err and "render_samples" in out.err


# --------------------------------------------------------------------------- settings and UI


def test_settings_defaults_and_mapping_to_core(empty_scene, engine_module):
    props = empty_scene.sampling_lab
    assert (props.integrator, props.sampler, props.light_selection) == ('PATH', 'SOBOL', 'TREE')
    assert (props.filter_type, props.filter_width) == ('BLACKMAN_HARRIS', pytest.approx(1.5))
    assert props.use_russian_roulette and props.time_limit == 0.0
    props.samples, props.seed, props.max_bounces, props.rr_min_bounces = 32, 5, 4, 2
    props.time_limit, props.filter_type, props.filter_width = 2.5, 'BOX', 1.0
    s = engine_module.render_settings(props)
    assert (s.integrator, s.sampler, s.spp, s.seed) == ("path", "sobol", 32, 5)
    assert (s.max_bounces, s.rr_min_bounces, s.use_russian_roulette) == (4, 2, True)
    assert (s.time_limit, s.filter_type, s.filter_width) == (2.5, "box", 1.0)
    for prop in props.bl_rna.properties:
        if prop.identifier not in {"rna_type", "name"}:
            assert prop.description, f"{prop.identifier} has no description"


def test_engine_and_panels_are_registered(addon):
    engine = next(c for c in bpy.types.RenderEngine.__subclasses__()
                  if getattr(c, "bl_idname", None) == ENGINE_ID)
    assert engine.bl_label == "Sampling Lab"
    assert engine.bl_use_postprocess and not engine.bl_use_preview
    for name in ("SAMPLINGLAB_RENDER_PT_sampling", "SAMPLINGLAB_RENDER_PT_light_paths",
                 "SAMPLINGLAB_RENDER_PT_film"):
        panel = getattr(bpy.types, name)
        assert panel.COMPAT_ENGINES == {ENGINE_ID} and panel.bl_context == 'render'
    # Blender's own output, format, color management and view layer panels show for the engine.
    for name in ("RENDER_PT_format", "RENDER_PT_output", "RENDER_PT_frame_range",
                 "RENDER_PT_color_management", "VIEWLAYER_PT_layer", "DATA_PT_lens",
                 "DATA_PT_EEVEE_light", "EEVEE_MATERIAL_PT_surface", "EEVEE_WORLD_PT_surface"):
        assert ENGINE_ID in getattr(bpy.types, name).COMPAT_ENGINES, name
    # ...but not the panels of features it does not render.
    assert ENGINE_ID not in bpy.types.RENDER_PT_freestyle.COMPAT_ENGINES


class _LayoutRecorder:
    """Stands in for a UILayout: records ``prop`` calls, accepts everything else."""

    def __init__(self, calls):
        self._calls = calls

    def prop(self, data, name, **_):
        self._calls.append((data, name))

    def __getattr__(self, name):
        return lambda *args, **kwargs: _LayoutRecorder(self._calls)

    def __setattr__(self, name, value):
        object.__setattr__(self, name, value)


def test_panels_draw_existing_properties(empty_scene):
    class Context:
        scene = empty_scene
        engine = ENGINE_ID
        object = bpy.data.objects.new("Probe", bpy.data.meshes.new("Probe"))

    for name in ("SAMPLINGLAB_RENDER_PT_sampling", "SAMPLINGLAB_RENDER_PT_light_paths",
                 "SAMPLINGLAB_RENDER_PT_film", "SAMPLINGLAB_OBJECT_PT_ray_visibility"):
        panel = getattr(bpy.types, name)
        assert panel.poll(Context)
        calls = []
        holder = type("Panel", (), {"layout": _LayoutRecorder(calls)})()
        panel.draw(holder, Context)
        assert calls, name
        for data, prop in calls:
            assert prop in data.bl_rna.properties, f"{name} draws a missing property {prop!r}"


def test_disable_removes_everything_and_enable_restores_it(addon):
    addon_utils.disable(ADDON_MODULE, default_set=True)
    try:
        assert not hasattr(bpy.types.Scene, "sampling_lab")
        assert ENGINE_ID not in bpy.types.RENDER_PT_format.COMPAT_ENGINES
        assert not hasattr(bpy.types, "SAMPLINGLAB_RENDER_PT_sampling")
    finally:
        assert addon_utils.enable(ADDON_MODULE, default_set=True) is not None
    assert ENGINE_ID in registered_engines()
    assert ENGINE_ID in bpy.types.RENDER_PT_format.COMPAT_ENGINES
    assert hasattr(bpy.types.Scene, "sampling_lab")


# --------------------------------------------------------------------------- packaging


def test_manifest_passes_blenders_validator():
    assert BLENDER_EXT.is_file(), BLENDER_EXT
    proc = subprocess.run([sys.executable, str(BLENDER_EXT), "validate", str(REPO_ROOT)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Success" in proc.stdout


def test_package_imports_without_bpy(tmp_path):
    # `sampling_lab` is the repository root (as pip install -e maps it).
    (tmp_path / "sampling_lab").symlink_to(REPO_ROOT, target_is_directory=True)
    code = ("import sys, sampling_lab, sampling_lab.core.scene, sampling_lab.core.render; "
            "assert 'bpy' not in sys.modules, 'bpy imported'; print('ok')")
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr


def test_extension_archive_holds_the_addon_and_nothing_else(tmp_path):
    import zipfile

    archive = tmp_path / "sampling_lab.zip"
    proc = subprocess.run([sys.executable, str(BLENDER_EXT), "build", "--source-dir",
                           str(REPO_ROOT), "--output-filepath", str(archive)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    names = zipfile.ZipFile(archive).namelist()
    for required in ("blender_manifest.toml", "__init__.py", "addon/engine.py",
                     "addon/export/__init__.py", "core/scene.py", "core/render.py"):
        assert required in names
    for name in names:
        assert not name.startswith((".venv/", ".git/", "tests/", "bench/", "tools/", "docs/",
                                    "out/")), name
        assert "__pycache__" not in name and not name.endswith(".pyc"), name


RELOAD_SCRIPT = """
import os, sys, importlib, tempfile
os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp()
import bpy, addon_utils
repo = tempfile.mkdtemp()
os.symlink(sys.argv[1], os.path.join(repo, "sampling_lab"))
bpy.context.preferences.extensions.repos.new(name="dev", module="dev", custom_directory=repo,
                                             source='USER')
name = "bl_ext.dev.sampling_lab"
assert addon_utils.enable(name, default_set=True)
old = sys.modules[name + ".addon.engine"]
# What Blender's Reload Scripts does: unregister, reload the package module, register.
addon_utils.disable(name)
importlib.reload(sys.modules[name])
assert addon_utils.enable(name)
new = sys.modules[name + ".addon.engine"]
engines = [c for c in bpy.types.RenderEngine.__subclasses__()
           if getattr(c, "bl_idname", "") == "SAMPLING_LAB"]
print(new is not old, any(c is new.SAMPLINGLAB_RenderEngine for c in engines))
"""


def test_reloading_the_package_reimports_its_submodules():
    proc = subprocess.run([sys.executable, "-c", RELOAD_SCRIPT, str(REPO_ROOT)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split()[-2:] == ["True", "True"], proc.stdout + proc.stderr


def test_stats_line_names_the_biased_estimators_figures(engine_module):
    """Photon mapping and radiosity add their figures, and the word biased, to the stats line;
    the unbiased integrators add nothing."""
    photon = engine_module.estimator_text(
        {"estimator_bias": "biased, consistent", "photons_emitted": 2_500_000,
         "photons_per_s": 1.5e6, "photon_memory_peak_mb": 12.0})
    assert photon == ", biased, consistent: 2.50 M photons (1.50 M/s, peak 12.0 MB)"
    radiosity = engine_module.estimator_text(
        {"radiosity_patch_count": 992, "radiosity_solver": "gauss_seidel",
         "radiosity_iterations": 14, "radiosity_residual": 1e-4})
    assert radiosity.startswith(", biased (radiosity): 992 patches, gauss_seidel in 14")
    assert engine_module.estimator_text({"spp": 4}) == ""
