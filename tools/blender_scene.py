"""A :class:`core.scene.Scene` rebuilt in ``bpy`` for Cycles, and Cycles renders of it.

The benchmark renders the *same* scene with our path tracer and with Cycles in the same process,
so this module is the inverse of ``addon/export/``: flat triangle and light tables in, Blender
objects out, in the units of ``docs/CONVENTIONS.md`` (emission strength is radiance, lamp energy in
Watts, camera matrix and sensor fit as Blender's).

- :func:`build_blender_scene`: one mesh object per (material, ray visibility) group, Diffuse BSDF
  (roughness 0, i.e. Lambert) and Emission materials, lamps, a camera, the world.
- :func:`configure_cycles`: Cycles settings under which Cycles is unbiased and comparable
  (no clamping, no glossy blur, no light threshold, no adaptive sampling, no denoising, fixed
  seed, fixed thread count, Blackman-Harris 1.5 filter).
- :func:`render_cycles`: one ``bpy.ops.render.render`` to a multilayer EXR, timed, read back.

``bpy`` is imported by :func:`import_bpy` only, which first points Blender's user resources at a
temporary folder (as ``tests/addon/conftest.py`` does) so a benchmark never reads or writes the
developer's own Blender configuration.
"""

from __future__ import annotations

import atexit
import contextlib
import math
import os
import shutil
import sys
import tempfile
import time

import numpy as np

from ..core.exr import read_multilayer
from ..core.scene import (
    LIGHT_DISK,
    LIGHT_POINT,
    LIGHT_RECT,
    LIGHT_SUN,
    VIS_CAMERA,
    VIS_DIFFUSE,
    VIS_GLOSSY,
    VIS_SHADOW,
    VIS_TRANSMISSION,
)

VIEW_LAYER = "ViewLayer"
_VISIBILITY_ATTRS = (("visible_camera", VIS_CAMERA), ("visible_diffuse", VIS_DIFFUSE),
                     ("visible_glossy", VIS_GLOSSY), ("visible_transmission", VIS_TRANSMISSION),
                     ("visible_shadow", VIS_SHADOW))


def import_bpy():
    """The ``bpy`` module, with Blender's user resources redirected on first import."""
    if "bpy" not in sys.modules and "BLENDER_USER_RESOURCES" not in os.environ:
        folder = tempfile.mkdtemp(prefix="sampling_lab_bench_")
        atexit.register(shutil.rmtree, folder, ignore_errors=True)
        os.environ["BLENDER_USER_RESOURCES"] = folder
    import bpy

    return bpy


def _matrix(m):
    from mathutils import Matrix

    return Matrix(np.asarray(m, np.float64).tolist())


def _frame_down(direction, position=(0.0, 0.0, 0.0)):
    """Object matrix whose local -Z is ``direction`` (how Blender lamps point)."""
    z = -np.asarray(direction, np.float64)
    z /= np.linalg.norm(z)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, np.cross(z, x), z, position
    return m


def _color_and_scale(rgb):
    """Split an RGB quantity into a colour of max 1 and its scale (Blender colour x strength)."""
    rgb = np.maximum(np.asarray(rgb, np.float64), 0.0)
    scale = float(rgb.max())
    if scale <= 0:
        return (0.0, 0.0, 0.0), 0.0
    return tuple(float(c) for c in rgb / scale), scale


def _material(bpy, name, base_color, emission):
    """Diffuse BSDF (roughness 0 = Lambert), Emission, or both added, as a new material."""
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree  # Blender 5 materials always have a node tree
    nodes, links = tree.nodes, tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    shaders = []
    if np.max(base_color) > 0 or np.max(emission) <= 0:
        diffuse = nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (*[float(c) for c in base_color], 1.0)
        diffuse.inputs["Roughness"].default_value = 0.0
        shaders.append(diffuse)
    if np.max(emission) > 0:
        # Cycles' emission strength is the emitted radiance of a mesh, from both faces.
        color, strength = _color_and_scale(emission)
        emit = nodes.new("ShaderNodeEmission")
        emit.inputs["Color"].default_value = (*color, 1.0)
        emit.inputs["Strength"].default_value = strength
        shaders.append(emit)
    if len(shaders) == 2:
        add = nodes.new("ShaderNodeAddShader")
        links.new(shaders[0].outputs[0], add.inputs[0])
        links.new(shaders[1].outputs[0], add.inputs[1])
        links.new(add.outputs[0], out.inputs["Surface"])
    else:
        links.new(shaders[0].outputs[0], out.inputs["Surface"])
    return mat


def _mesh_object(bpy, name, vertices, triangles, material):
    """A mesh object of ``triangles (t, 3)`` over the vertices they use, built with foreach_set."""
    used, local = np.unique(triangles.ravel(), return_inverse=True)
    verts = np.ascontiguousarray(vertices[used], np.float32)
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(verts.shape[0])
    mesh.vertices.foreach_set("co", verts.ravel())
    t = triangles.shape[0]
    mesh.loops.add(3 * t)
    mesh.loops.foreach_set("vertex_index", local.astype(np.int32))
    mesh.polygons.add(t)
    mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * t, 3, dtype=np.int32))
    # Flat faces: the core shades with geometric normals (new meshes are smooth since 4.1).
    mesh.polygons.foreach_set("use_smooth", np.zeros(t, bool))
    mesh.update()
    mesh.materials.append(material)
    return bpy.data.objects.new(name, mesh)


def _lamp(bpy, lights, i):
    """Light object of row ``i`` of a :class:`core.scene.Lights` table, back in Blender's Watts."""
    kind = int(lights.kind[i])
    name = lights.names[i] if i < len(lights.names) else f"Light{i}"
    radiance = np.asarray(lights.radiance[i], np.float64)
    if kind == LIGHT_POINT:
        r = float(lights.radius[i])
        # Delta point: intensity S / (4 pi); sphere: radiance S / (4 pi^2 r^2).
        power = radiance * (4 * math.pi**2 * r * r if r > 0 else 4 * math.pi)
        cos_half = float(lights.spot_cos_half[i])
        spot = cos_half > -1.0
        data = bpy.data.lights.new(name, "SPOT" if spot else "POINT")
        data.shadow_soft_size = r
        if spot:
            data.spot_size = 2.0 * math.acos(min(max(cos_half, -1.0), 1.0))
            smooth = float(lights.spot_smooth[i])
            data.spot_blend = (0.0 if not np.isfinite(smooth)
                               else min(1.0, 1.0 / (smooth * (1.0 - cos_half))))
        matrix = _frame_down(lights.direction[i], lights.position[i])
    elif kind == LIGHT_SUN:
        a = float(lights.angle[i])
        # Delta sun: irradiance S; disk of angle a: radiance S / (pi sin^2(a/2)).
        power = radiance * (math.pi * math.sin(0.5 * a) ** 2 if a > 0 else 1.0)
        data = bpy.data.lights.new(name, "SUN")
        data.angle = a
        matrix = _frame_down(lights.direction[i])
    elif kind in (LIGHT_RECT, LIGHT_DISK):
        ax, ay = np.asarray(lights.axis_x[i]), np.asarray(lights.axis_y[i])
        sx, sy = float(np.linalg.norm(ax)), float(np.linalg.norm(ay))
        area = sx * sy * (math.pi / 4 if kind == LIGHT_DISK else 1.0)
        # Area light: radiance S / (pi A), one-sided toward local -Z.
        power = radiance * math.pi * area
        data = bpy.data.lights.new(name, "AREA")
        square = abs(sx - sy) <= 1e-9 * max(sx, sy)
        if kind == LIGHT_DISK:
            data.shape = "DISK" if square else "ELLIPSE"
        else:
            data.shape = "SQUARE" if square else "RECTANGLE"
        data.size, data.size_y = sx, sy
        x, y = ax / sx, ay / sy
        matrix = np.eye(4)
        matrix[:3, 0], matrix[:3, 1], matrix[:3, 2] = x, y, np.cross(x, y)
        matrix[:3, 3] = lights.position[i]
    else:
        raise ValueError(f"light {name!r}: unknown kind {kind}")
    color, energy = _color_and_scale(power)
    data.color = color
    data.energy = energy
    ob = bpy.data.objects.new(name, data)
    ob.matrix_world = _matrix(matrix)
    ob.visible_camera = bool(lights.visible_camera[i])
    return ob


def _camera(bpy, cam):
    data = bpy.data.cameras.new("Camera")
    data.type = cam.type
    data.lens = cam.lens
    data.sensor_width = cam.sensor_width
    data.sensor_height = cam.sensor_height
    data.sensor_fit = cam.sensor_fit
    data.shift_x, data.shift_y = cam.shift_x, cam.shift_y
    data.clip_start, data.clip_end = cam.clip_start, cam.clip_end
    data.ortho_scale = cam.ortho_scale
    ob = bpy.data.objects.new("Camera", data)
    ob.matrix_world = _matrix(cam.to_world)
    return ob


def _world(bpy, color_rgb):
    world = bpy.data.worlds.new("World")
    background = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    color, strength = _color_and_scale(color_rgb)
    background.inputs["Color"].default_value = (*color, 1.0)
    background.inputs["Strength"].default_value = strength
    return world


def build_blender_scene(core_scene, name="Sampling Lab Bench"):
    """Build ``core_scene`` as a new ``bpy`` scene (objects, materials, lamps, camera, world).

    Parameters
    ----------
    core_scene : core.scene.Scene
        Only diffuse materials (the core's closed set today) and emission are translated.
    name : str
        Name of the new scene (Blender may append a suffix if it is taken).

    Returns
    -------
    bpy.types.Scene
        Render engine Cycles, resolution 100 %, no compositor or sequencer.
    """
    bpy = import_bpy()
    scene = bpy.data.scenes.new(name)
    coll = scene.collection
    mats = core_scene.materials
    blender_mats = [_material(bpy, mats.names[m] if m < len(mats.names) else f"Material{m}",
                              mats.base_color[m], mats.emission[m])
                    for m in range(mats.base_color.shape[0])]
    # One object per (material, visibility) group: visibility is per object in Blender.
    groups = np.stack([core_scene.material, core_scene.visibility], axis=1)
    for mat, vis in np.unique(groups, axis=0):
        rows = np.nonzero((core_scene.material == mat) & (core_scene.visibility == vis))[0]
        ob = _mesh_object(bpy, blender_mats[mat].name, core_scene.vertices,
                          core_scene.triangles[rows], blender_mats[mat])
        for attr, bit in _VISIBILITY_ATTRS:
            setattr(ob, attr, bool(vis & bit))
        coll.objects.link(ob)
    for i in range(len(core_scene.lights)):
        coll.objects.link(_lamp(bpy, core_scene.lights, i))
    cam = core_scene.camera
    cam_ob = _camera(bpy, cam)
    coll.objects.link(cam_ob)
    scene.camera = cam_ob
    scene.world = _world(bpy, core_scene.world_color)

    render = scene.render
    render.engine = "CYCLES"
    render.resolution_x, render.resolution_y = cam.width, cam.height
    render.resolution_percentage = 100
    render.pixel_aspect_x, render.pixel_aspect_y = cam.pixel_aspect_x, cam.pixel_aspect_y
    render.film_transparent = False
    render.use_compositing = False
    render.use_sequencer = False
    scene.view_layers[0].name = VIEW_LAYER
    # EXR pixels are scene-linear whatever the view transform; Standard keeps previews honest.
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    return scene


def configure_cycles(scene, spp, seed=0, threads=2, max_bounces=8, time_limit=0.0):
    """Set Cycles up so that it is unbiased and comparable with our path tracer.

    Parameters
    ----------
    scene : bpy.types.Scene
    spp : int
        ``scene.cycles.samples`` (the cap when ``time_limit`` is set).
    seed : int
    threads : int
        ``render.threads`` with ``threads_mode = 'FIXED'``.
    max_bounces : int
        Total bounces and every per-kind bounce limit.
    time_limit : float
        Cycles' own render time limit in seconds (synchronisation excluded); 0 disables it.
    """
    c = scene.cycles
    c.device = "CPU"
    c.samples = int(spp)
    c.time_limit = float(time_limit)
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.light_sampling_threshold = 0.0
    c.max_bounces = max_bounces
    c.diffuse_bounces = max_bounces
    c.glossy_bounces = max_bounces
    c.transmission_bounces = max_bounces
    c.volume_bounces = max_bounces
    c.transparent_max_bounces = max_bounces
    c.min_light_bounces = 0
    c.min_transparent_bounces = 0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.pixel_filter_type = "BLACKMAN_HARRIS"
    c.filter_width = 1.5
    c.seed = int(seed)
    c.use_animated_seed = False
    c.use_guiding = False
    c.film_exposure = 1.0
    render = scene.render
    render.threads_mode = "FIXED"
    render.threads = int(threads)
    fmt = render.image_settings
    if hasattr(fmt, "media_type"):  # Blender 5: multilayer EXR is a media type of its own
        fmt.media_type = "MULTI_LAYER_IMAGE"
    fmt.file_format = "OPEN_EXR_MULTILAYER"
    fmt.color_depth = "32"
    fmt.exr_codec = "ZIP"


def render_cycles(scene, path, quiet=True):
    """Render ``scene`` with ``bpy.ops.render.render(write_still=True)`` to the EXR ``path``.

    Parameters
    ----------
    scene : bpy.types.Scene
    path : str
        Output file (overwritten).
    quiet : bool
        Swallow Blender's per-sample log lines (shown if the render raises).

    Returns
    -------
    seconds : float
        Wall-clock time of the render call (synchronisation, BVH, kernels, path tracing, EXR
        writing).
    passes : dict of str -> (h, w, c) float32
        Passes of the written EXR (:func:`core.exr.read_multilayer`), row 0 at the bottom.
    cycles_times : dict
        Cycles' own figures from the EXR metadata, in seconds: ``render_time`` (path tracing),
        ``synchronization_time``, ``total_time`` (NaN where absent).
    """
    bpy = import_bpy()
    scene.render.filepath = path
    scene.render.use_file_extension = False
    with _captured_output(quiet):
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=True, scene=scene.name)
        seconds = time.perf_counter() - t0
    return seconds, read_multilayer(path), _cycles_times(path)


@contextlib.contextmanager
def _captured_output(enabled):
    """Send file descriptors 1 and 2 (Blender's C-level logging) to a temporary file."""
    if not enabled:
        yield
        return
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    with tempfile.TemporaryFile() as log:
        os.dup2(log.fileno(), 1)
        os.dup2(log.fileno(), 2)
        try:
            yield
        except BaseException:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            log.seek(0)
            sys.stderr.write(log.read().decode(errors="replace")[-4000:])
            raise
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])


def _cycles_times(path):
    """``cycles.<layer>.*_time`` metadata of a Cycles EXR, as seconds."""
    import OpenEXR

    header = OpenEXR.File(path, header_only=True).header()
    out = {}
    for key in ("render_time", "synchronization_time", "total_time"):
        text = header.get(f"cycles.{VIEW_LAYER}.{key}")
        out[key] = _clock_seconds(text) if isinstance(text, str) else float("nan")
    return out


def _clock_seconds(text):
    """Blender's ``[hh:]mm:ss.cc`` time stamps as seconds."""
    seconds = 0.0
    for field in text.strip().split(":"):
        seconds = 60.0 * seconds + float(field)
    return seconds
