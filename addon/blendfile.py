"""Open a ``.blend`` with the ``bpy`` module and export it, as ``blender -b file -f N`` would."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile

# First bytes of a .blend: plain, zstd-compressed (Blender 3+) or gzip-compressed (older).
_BLEND_MAGIC = (b"BLENDER", b"\x28\xb5\x2f\xfd", b"\x1f\x8b")


def is_blend_file(path):
    """Whether ``path`` starts like a .blend file (checked before handing it to Blender)."""
    with open(path, "rb") as f:
        head = f.read(7)
    return head.startswith(_BLEND_MAGIC)


def load_blend(path, frame=None, resolution=None):
    """Export the active scene of the ``.blend`` at ``path`` with its Sampling Lab settings.

    Parameters
    ----------
    frame : int or None
        Frame to render (default: the file's current frame).
    resolution : (int, int) or None
        Override of the file's resolution (the percentage is then 100 %).

    Returns
    -------
    scene : core.scene.Scene
    settings : core.render.RenderSettings
    """
    import bpy

    from . import properties
    from .engine import render_settings
    from .export import ExportError, export_scene

    # The file stores the add-on's settings as ID properties; registering the property group
    # (if the add-on is not enabled in this Blender) reads them back with their defaults.
    if not hasattr(bpy.types.Scene, "sampling_lab"):
        properties.register()
    # Blender's C code logs "Read blend: ..." and the like on the process's stdout and stderr;
    # the command line's output is its own lines only (a failure raises with its cause).
    with _quiet_fds():
        bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    bl_scene = bpy.context.scene
    if frame is not None:
        bl_scene.frame_start = bl_scene.frame_end = frame
        bl_scene.frame_set(frame)
    if resolution is not None:
        bl_scene.render.resolution_x, bl_scene.render.resolution_y = resolution
        bl_scene.render.resolution_percentage = 100
    # Reading images logs Blender's own errors too ("imb_load_openexr: Unable to open"); the
    # exporter says what it could not read in its messages, which the command line prints.
    with _quiet_fds():
        depsgraph = bpy.context.evaluated_depsgraph_get()
        try:
            scene = export_scene(depsgraph)
        except ExportError as exc:
            raise ValueError(str(exc)) from None
    return scene, render_settings(bl_scene.sampling_lab)


@contextlib.contextmanager
def fds_into(file):
    """Python's streams and file descriptors 1 and 2 (C code included) into the open binary
    ``file`` meanwhile."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    os.dup2(file.fileno(), 1)
    os.dup2(file.fileno(), 2)
    try:
        yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        os.close(saved[0])
        os.close(saved[1])


@contextlib.contextmanager
def _quiet_fds():
    """Discard what is written to file descriptors 1 and 2 (C code included) meanwhile."""
    with tempfile.TemporaryFile() as sink, fds_into(sink):
        yield
