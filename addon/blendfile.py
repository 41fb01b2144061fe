"""Open a ``.blend`` with the ``bpy`` module and export it, as ``blender -b file -f N`` would."""

from __future__ import annotations

from ..core.render import RenderSettings

# The add-on's scene properties (``scene.sampling_lab``) and the RenderSettings field of each.
_SETTING_NAMES = {"samples": "spp", "time_limit": "time_limit", "seed": "seed",
                  "max_bounces": "max_bounces", "use_russian_roulette": "use_russian_roulette",
                  "rr_min_bounces": "rr_min_bounces", "filter_width": "filter_width"}


# First bytes of a .blend: plain, zstd-compressed (Blender 3+) or gzip-compressed (older).
_BLEND_MAGIC = (b"BLENDER", b"\x28\xb5\x2f\xfd", b"\x1f\x8b")


def is_blend_file(path):
    """Whether ``path`` starts like a .blend file (checked before handing it to Blender)."""
    with open(path, "rb") as f:
        head = f.read(7)
    return head.startswith(_BLEND_MAGIC)


def settings_from_scene(bl_scene) -> RenderSettings:
    """RenderSettings from the file's Sampling Lab settings (stored even without the add-on)."""
    settings = RenderSettings()
    group = bl_scene.get("sampling_lab")
    if group is None:
        return settings
    for prop, field in _SETTING_NAMES.items():
        if prop in group:
            setattr(settings, field, type(getattr(settings, field))(group[prop]))
    return settings


def load_blend(path, frame=None, resolution=None):
    """Export the active scene of the ``.blend`` at ``path``.

    Parameters
    ----------
    frame : int or None
        Frame to render (default: the file's current frame).
    resolution : (int, int) or None
        Override of the file's resolution (the percentage is then 100 %).

    Returns
    -------
    scene : core.scene.Scene
    settings : RenderSettings
    """
    import bpy

    from .export import export_scene

    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    bl_scene = bpy.context.scene
    if frame is not None:
        bl_scene.frame_start = bl_scene.frame_end = frame
        bl_scene.frame_set(frame)
    if resolution is not None:
        bl_scene.render.resolution_x, bl_scene.render.resolution_y = resolution
        bl_scene.render.resolution_percentage = 100
    depsgraph = bpy.context.evaluated_depsgraph_get()
    scene = export_scene(depsgraph)
    return scene, settings_from_scene(bl_scene)
