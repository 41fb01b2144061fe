"""Sampling presets: a menu of bundled and user presets, and the operator that adds one.

Bundled presets live in the repository's ``presets/sampling_lab/sampling/`` (each a small Python
file that sets ``scene.sampling_lab``); presets the user adds go to Blender's user preset folder
``presets/sampling_lab/sampling/``, as Cycles' and every other ``AddPresetBase`` preset does.
"""

from pathlib import Path

import bpy
from bl_operators.presets import AddPresetBase
from bpy.types import Menu, Operator

PRESET_SUBDIR = "sampling_lab/sampling"
BUNDLED_DIR = Path(__file__).resolve().parent.parent / "presets" / PRESET_SUBDIR

# Every setting a preset stores (the Sampling, Light Sampling, Strategy Views and Light Paths
# panels). Bundled presets may leave some out: those keep their current values.
PRESET_VALUES = [f"settings.{name}" for name in (
    "integrator", "sampler", "samples", "time_limit", "max_bounces", "use_russian_roulette",
    "rr_min_bounces", "mis_heuristic", "mis_beta", "mis_alpha", "light_selection",
    "light_sampling", "distribution", "use_strategy_views", "strategy_max_length")]


def preset_paths():
    """Folders holding sampling presets: the bundled ones first, then the user's."""
    paths = [str(BUNDLED_DIR)] if BUNDLED_DIR.is_dir() else []
    return paths + [p for p in bpy.utils.preset_paths(PRESET_SUBDIR) if p not in paths]


class SAMPLINGLAB_MT_sampling_presets(Menu):
    """Bundled and user sampling presets."""

    bl_label = "Sampling Presets"
    preset_subdir = PRESET_SUBDIR
    preset_operator = "script.execute_preset"

    def draw(self, context):
        self.path_menu(preset_paths(), self.preset_operator,
                       props_default={"menu_idname": self.bl_idname},
                       filter_ext=lambda ext: ext.lower() == ".py")


class SAMPLINGLAB_OT_sampling_preset_add(AddPresetBase, Operator):
    """Add or remove a Sampling Lab sampling preset"""

    bl_idname = "render.sampling_lab_preset_add"
    bl_label = "Add Sampling Preset"
    preset_menu = "SAMPLINGLAB_MT_sampling_presets"
    preset_defines = ["settings = bpy.context.scene.sampling_lab"]
    preset_values = PRESET_VALUES
    preset_subdir = PRESET_SUBDIR


classes = (SAMPLINGLAB_MT_sampling_presets, SAMPLINGLAB_OT_sampling_preset_add)


def draw_preset_row(layout):
    """The preset menu with add and remove buttons, as at the top of Cycles' old panels."""
    row = layout.row(align=True)
    row.menu(SAMPLINGLAB_MT_sampling_presets.__name__, text=SAMPLINGLAB_MT_sampling_presets.bl_label)
    row.operator(SAMPLINGLAB_OT_sampling_preset_add.bl_idname, text="", icon='ADD')
    row.operator(SAMPLINGLAB_OT_sampling_preset_add.bl_idname, text="",
                 icon='REMOVE').remove_active = True


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
