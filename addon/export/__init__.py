"""Blender depsgraph -> :class:`core.scene.Scene`.

Everything is read from the evaluated (render) depsgraph: meshes with their modifiers, every
instance (collection instances, particles, geometry nodes) through
``depsgraph.object_instances``, lights, the world and the camera. Mesh data is copied with
``foreach_get`` into NumPy arrays and moved to world space with one matrix product per object;
there is no Python loop over vertices or triangles.

The exporter maps what a scene uses onto the small closed set of core materials and lights, and
says once per render, in :attr:`core.scene.Scene.messages`, what it approximated or ignored.
Unit conversion of lights is left to :mod:`core.lights`; this package only reads Blender's
values. :func:`export_scene` walks the depsgraph and hands each part to its module:

- :mod:`.camera`: the render camera;
- :mod:`.meshes`: triangles, material rows, visibility, corner normals and UVs per instance;
- :mod:`.materials`: shader nodes -> core materials and mixtures (:mod:`.alpha`: textured
  alpha); :mod:`.material_table`: the material table;
- :mod:`.textures`: Image and Environment Texture pixels;
- :mod:`.nodes`: reading node trees (links, active outputs, constant socket values);
- :mod:`.lights`: light objects -> core light rows;
- :mod:`.world`: the background colour or environment map;
- :mod:`.messages`: the notes an export collects and :class:`ExportError`.
"""

from __future__ import annotations

import numpy as np

from ...core.scene import Lights, Scene
from .camera import NO_CAMERA_MESSAGE, export_camera, render_camera
from .lights import light_row
from .material_table import MaterialTable
from .materials import (
    DEFAULT_SURFACE_COLOR,
    DEFAULT_SURFACE_NAME,
    MAX_COMPONENTS,
    Surface,
    material_surface,
    mix_surfaces,
)
from .meshes import (
    MESH_TYPES,
    Geometry,
    evaluated_mesh,
    mesh_arrays,
    mesh_corner_normals,
    mesh_corner_uvs,
)
from .messages import ExportError, Messages
from .world import world_radiance

__all__ = [
    "DEFAULT_SURFACE_COLOR", "DEFAULT_SURFACE_NAME", "MAX_COMPONENTS", "MESH_TYPES",
    "NO_CAMERA_MESSAGE", "SKIPPED_TYPES", "ExportError", "MaterialTable", "Messages", "Surface",
    "evaluated_mesh", "export_camera", "export_scene", "material_surface", "mesh_arrays",
    "mesh_corner_normals", "mesh_corner_uvs", "mix_surfaces", "world_radiance",
]

# Object types that neither emit nor occlude anything.
SKIPPED_TYPES = {'CAMERA', 'EMPTY', 'ARMATURE', 'LATTICE', 'SPEAKER', 'LIGHT_PROBE'}


def export_scene(depsgraph, camera_object=None, camera=None):
    """Translate an evaluated depsgraph into a :class:`core.scene.Scene`.

    Parameters
    ----------
    depsgraph : bpy.types.Depsgraph
        The render depsgraph (``RenderEngine.render``'s argument) or
        ``bpy.context.evaluated_depsgraph_get()``.
    camera_object : bpy.types.Object or None
        Camera to render from; defaults to the scene camera (pass
        ``RenderEngine.camera_override`` here).
    camera : core.scene.Camera or None
        A camera to use as it is instead of a camera object (the rendered viewport's free
        view, which needs no camera object in the scene); ``camera_object`` is then ignored.

    Returns
    -------
    core.scene.Scene
        World-space triangles, materials, lights, world color, camera, and the messages about
        what was approximated or ignored.

    Raises
    ------
    ExportError
        The scene has no camera (and ``camera`` is None).
    """
    scene = depsgraph.scene
    messages = Messages()
    if camera is None:
        camera = export_camera(scene, render_camera(depsgraph, camera_object), messages)
    _report_render_settings(scene, messages)
    materials = MaterialTable(messages)
    geometry = Geometry(materials, messages)
    light_rows = []
    for inst in depsgraph.object_instances:
        ob = inst.object
        if not (inst.is_instance or inst.show_self) or ob.type in SKIPPED_TYPES:
            continue
        matrix = np.array(inst.matrix_world, np.float64)
        if ob.type == 'LIGHT':
            row = light_row(ob, matrix, messages)
            if row is not None:
                light_rows.append(row)
        elif ob.type in MESH_TYPES:
            geometry.add(ob, matrix)
        else:
            messages.add(f"Object '{ob.name}': {ob.type.lower()} objects are not supported "
                         f"yet; ignored")
    world_color, world_map = world_radiance(scene.world, messages)
    return Scene(
        **geometry.arrays(),
        materials=materials.build(),
        lights=Lights.concat(light_rows),
        camera=camera,
        world_color=world_color,
        world_map=world_map,
        messages=messages.items,
        textures=materials.textures,
        texture_interpolation=materials.texture_modes[0],
        texture_extension=materials.texture_modes[1],
        film_transparent=bool(scene.render.film_transparent),
    )


def _report_render_settings(scene, messages):
    """Report the render settings of the scene that the renderer ignores."""
    render = scene.render
    if render.use_motion_blur:
        messages.add("Motion blur is not supported yet; rendered without")
    cycles = getattr(scene, "cycles", None)
    if render.film_transparent and getattr(cycles, "film_transparent_glass", False):
        messages.add("Film > Transparent Glass is not supported yet; glass in front of the "
                     "background is opaque in the alpha channel")
