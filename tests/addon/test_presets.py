"""Sampling presets: the bundled ones apply, and users can add their own (AddPresetBase)."""

import importlib
import os
from pathlib import Path

import bpy
import pytest

from scenes import ADDON_MODULE, REPO_ROOT

BUNDLED = sorted((REPO_ROOT / "presets" / "sampling_lab" / "sampling").glob("*.py"))


def test_presets_are_bundled():
    names = {p.stem for p in BUNDLED}
    assert {"Preview", "Final_Sobol", "Lecture_No_MIS"} <= names


@pytest.mark.parametrize("preset", BUNDLED, ids=[p.stem for p in BUNDLED])
def test_bundled_preset_sets_the_scene_settings(empty_scene, preset):
    settings = empty_scene.sampling_lab
    settings.samples = 3
    settings.mis_heuristic = 'BALANCE'
    result = bpy.ops.script.execute_preset(filepath=str(preset),
                                           menu_idname="SAMPLINGLAB_MT_sampling_presets")
    assert result == {'FINISHED'}
    text = preset.read_text()
    assert settings.samples != 3 and f"settings.samples = {settings.samples}" in text
    assert f"settings.mis_heuristic = '{settings.mis_heuristic}'" in text
    assert f"settings.sampler = '{settings.sampler}'" in text


def test_user_can_add_a_preset_that_restores_the_settings(empty_scene):
    settings = empty_scene.sampling_lab
    settings.samples = 77
    settings.mis_heuristic = 'CUTOFF'
    settings.mis_alpha = 0.3
    assert bpy.ops.render.sampling_lab_preset_add(name="My Test Preset") == {'FINISHED'}
    folder = Path(bpy.utils.preset_paths("sampling_lab/sampling")[0])
    written = folder / "My_Test_Preset.py"
    assert written.is_file()
    settings.samples = 5
    settings.mis_heuristic = 'POWER'
    bpy.ops.script.execute_preset(filepath=str(written),
                                  menu_idname="SAMPLINGLAB_MT_sampling_presets")
    assert settings.samples == 77 and settings.mis_heuristic == 'CUTOFF'
    assert settings.mis_alpha == pytest.approx(0.3)
    os.remove(written)


def test_added_preset_is_listed_in_the_menu_and_remove_deletes_it(empty_scene, addon):
    presets = importlib.import_module(f"{ADDON_MODULE}.addon.presets")
    shipped = {bpy.path.display_name(p.name) for p in BUNDLED}
    assert shipped <= {label for label, _ in presets.preset_files()}
    assert "Menu Test" not in dict(presets.preset_files())
    empty_scene.sampling_lab.samples = 41
    assert bpy.ops.render.sampling_lab_preset_add(name="Menu Test") == {'FINISHED'}
    listed = dict(presets.preset_files())
    user_folder = Path(bpy.utils.user_resource('SCRIPTS', path="presets/sampling_lab/sampling"))
    assert Path(listed["Menu Test"]) == user_folder / "Menu_Test.py"
    assert "settings.samples = 41" in Path(listed["Menu Test"]).read_text()
    assert shipped <= set(listed)
    # The menu's '-' button removes the active preset: the one just added.
    assert bpy.ops.render.sampling_lab_preset_add(remove_active=True) == {'FINISHED'}
    assert "Menu Test" not in dict(presets.preset_files())
    assert not (user_folder / "Menu_Test.py").exists()
