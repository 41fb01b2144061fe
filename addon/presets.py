"""Sampling presets: a menu of bundled and user presets, and the operator that adds one.

Bundled presets live in the repository's ``presets/sampling_lab/sampling/`` (each a small Python
file that sets ``scene.sampling_lab``); presets the user adds go to Blender's user preset folder
``presets/sampling_lab/sampling/``, as Cycles' and every other ``AddPresetBase`` preset does.
"""

import re
from pathlib import Path

import bpy
from bl_operators.presets import AddPresetBase
from bpy.types import Menu, Operator

PRESET_SUBDIR = "sampling_lab/sampling"
BUNDLED_DIR = Path(__file__).resolve().parent.parent / "presets" / PRESET_SUBDIR

# Every setting a preset stores (the Sampling, Light Sampling, Strategy Views and Light Paths
# panels). Bundled presets may leave some out: those keep their current values.
PRESET_VALUES = [f"settings.{name}" for name in (
    "integrator", "sampler", "samples", "time_limit", "max_bounces", "diffuse_bounces",
    "glossy_bounces", "transmission_bounces", "transparent_max_bounces", "use_russian_roulette",
    "rr_min_bounces", "rr_survival", "connection_roulette", "mis_heuristic", "mis_beta", "mis_alpha",
    "light_selection", "light_sampling", "light_points", "distribution", "use_strategy_views",
    "strategy_max_length")]


def preset_paths():
    """Folders holding sampling presets: the bundled ones first, then the user's."""
    paths = [str(BUNDLED_DIR)] if BUNDLED_DIR.is_dir() else []
    return paths + [p for p in bpy.utils.preset_paths(PRESET_SUBDIR) if p not in paths]


def preset_files():
    """What the Sampling presets menu lists, in its order: ``[(label, path), ...]``.

    Every ``.py`` file of :func:`preset_paths` (bundled and user presets together), in the
    natural order and with the labels of Blender's own preset menus (``Menu.path_menu``).
    """
    files = [(name, str(Path(folder) / name)) for folder in preset_paths()
             for name in sorted(p.name for p in Path(folder).iterdir())
             if name.lower().endswith(".py") and not name.startswith(".")]
    files.sort(key=lambda item: tuple(int(t) if t.isdigit() else t
                                      for t in re.split(r"(\d+)", item[0].lower())))
    return [(bpy.path.display_name(name), path) for name, path in files]


class SAMPLINGLAB_MT_sampling_presets(Menu):
    """Bundled and user sampling presets."""

    bl_label = "Sampling Presets"
    preset_subdir = PRESET_SUBDIR
    preset_operator = "script.execute_preset"

    def draw(self, context):
        col = self.layout.column(align=True)
        for label, path in preset_files():
            props = col.operator(self.preset_operator, text=label, translate=False)
            props.filepath = path
            props.menu_idname = self.bl_idname


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
