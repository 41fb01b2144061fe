"""Scenes built with Blender's data API, shared by the Cycles agreement tests and the benchmarks.

Every scene builder works on the given (normally empty) ``bpy`` scene, adds a camera and sets it
as the scene camera, and returns a dict of the objects it made by role. ``tests/addon/scenes.py``
re-exports everything here for the tests; :mod:`.hard_scenes` renders the same scenes with our
integrators and with Cycles.

Scene units follow ``docs/CONVENTIONS.md``: Cornell box walls span x, y in [-1, 1] and z in
[0, 2], open toward -y where the camera stands; materials are Lambertian (Diffuse BSDF) unless
named otherwise; lights are given in Blender's units (W, W/m^2, Emission strength = radiance).
"""

from __future__ import annotations

import math

import numpy as np

from .blender_scene import import_bpy

bpy = import_bpy()

_BLENDER_5 = bpy.app.version >= (5, 0, 0)

RED = (0.63, 0.065, 0.05)
GREEN = (0.14, 0.45, 0.091)
WHITE = (0.725, 0.71, 0.68)


# --------------------------------------------------------------------------- building blocks


def _new_node_tree_material(name):
    mat = bpy.data.materials.new(name)
    if not _BLENDER_5:
        mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    out.is_active_output = True
    return mat, out


def diffuse_material(name, color, roughness=0.0):
    """A material made of a single Diffuse BSDF node."""
    mat, out = _new_node_tree_material(name)
    node = mat.node_tree.nodes.new("ShaderNodeBsdfDiffuse")
    node.inputs["Color"].default_value = (*color, 1.0)
    node.inputs["Roughness"].default_value = roughness
    mat.node_tree.links.new(node.outputs["BSDF"], out.inputs["Surface"])
    mat.diffuse_color = (*color, 1.0)
    return mat


def emission_material(name, color, strength):
    """A material made of a single Emission node (radiance = color x strength, both faces)."""
    mat, out = _new_node_tree_material(name)
    node = mat.node_tree.nodes.new("ShaderNodeEmission")
    node.inputs["Color"].default_value = (*color, 1.0)
    node.inputs["Strength"].default_value = strength
    mat.node_tree.links.new(node.outputs["Emission"], out.inputs["Surface"])
    return mat


def shader_material(name, node_type, color=None):
    """A material made of one shader node of ``node_type`` (e.g. ``'ShaderNodeBsdfGlass'``)."""
    mat, out = _new_node_tree_material(name)
    node = mat.node_tree.nodes.new(node_type)
    if color is not None and "Color" in node.inputs:
        node.inputs["Color"].default_value = (*color, 1.0)
    mat.node_tree.links.new(node.outputs[0], out.inputs["Surface"])
    return mat


def glossy_material(name, color, roughness, distribution='GGX'):
    """A Glossy BSDF material (single-scattering GGX unless ``distribution`` says otherwise;
    Blender's own default is Multiscatter GGX)."""
    mat, out = _new_node_tree_material(name)
    node = mat.node_tree.nodes.new("ShaderNodeBsdfGlossy")
    node.distribution = distribution
    node.inputs["Color"].default_value = (*color, 1.0)
    node.inputs["Roughness"].default_value = roughness
    mat.node_tree.links.new(node.outputs["BSDF"], out.inputs["Surface"])
    return mat


def glass_material(name, color=(1.0, 1.0, 1.0), ior=1.5, roughness=0.0, distribution='GGX'):
    """A Glass BSDF material."""
    mat, out = _new_node_tree_material(name)
    node = mat.node_tree.nodes.new("ShaderNodeBsdfGlass")
    node.distribution = distribution
    node.inputs["Color"].default_value = (*color, 1.0)
    node.inputs["IOR"].default_value = ior
    node.inputs["Roughness"].default_value = roughness
    mat.node_tree.links.new(node.outputs["BSDF"], out.inputs["Surface"])
    return mat


def set_world(scene, color, strength=1.0, name="World"):
    """Give ``scene`` a world whose Background node has ``color`` x ``strength``."""
    world = bpy.data.worlds.new(name)
    if not _BLENDER_5:
        world.use_nodes = True
    nodes = world.node_tree.nodes
    nodes.clear()
    bg = nodes.new("ShaderNodeBackground")
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength
    out = nodes.new("ShaderNodeOutputWorld")
    out.is_active_output = True
    world.node_tree.links.new(bg.outputs["Background"], out.inputs["Surface"])
    scene.world = world
    return world


def set_environment_world(scene, image, strength=1.0, name="World"):
    """Give ``scene`` a world: Environment Texture (``image``) -> Background -> World Output.

    Returns
    -------
    world, env_node, background_node
    """
    world = set_world(scene, (0.0, 0.0, 0.0), strength, name)
    nodes = world.node_tree.nodes
    bg = next(n for n in nodes if n.bl_idname == "ShaderNodeBackground")
    env = nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    world.node_tree.links.new(env.outputs["Color"], bg.inputs["Color"])
    return world, env, bg


def float_image(name, rgb):
    """A float image from ``rgb (h, w, 3)`` (row 0 is the bottom row, as Blender stores it)."""
    rgb = np.asarray(rgb, np.float32)
    h, w = rgb.shape[:2]
    image = bpy.data.images.new(name, w, h, alpha=True, float_buffer=True)
    rgba = np.concatenate([rgb, np.ones((h, w, 1), np.float32)], axis=2)
    image.pixels.foreach_set(np.ascontiguousarray(rgba).reshape(-1))
    image.update()
    return image


def add_mesh(scene, name, vertices, faces, material=None, location=(0.0, 0.0, 0.0)):
    """Link a new mesh object built from ``vertices (v, 3)`` and ``faces`` (index lists)."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(map(float, v)) for v in vertices], [], [tuple(f) for f in faces])
    return _link_mesh(scene, name, mesh, material, location)


def _link_mesh(scene, name, mesh, material, location):
    """Give ``mesh`` its material and link it to ``scene`` as object ``name`` at ``location``."""
    mesh.update()
    if material is not None:
        mesh.materials.append(material)
    ob = bpy.data.objects.new(name, mesh)
    ob.location = location
    scene.collection.objects.link(ob)
    return ob


def add_uv_sphere(scene, name, center, radius, material=None, segments=32, rings=16):
    """A closed, flat-shaded UV sphere (see :func:`cornell_smooth_sphere` for smooth shading)."""
    import bmesh

    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=radius)
    bm.to_mesh(mesh)
    bm.free()
    mesh.polygons.foreach_set("use_smooth", [False] * len(mesh.polygons))
    return _link_mesh(scene, name, mesh, material, center)


def add_quad(scene, name, corners, material=None):
    """A single quad from four corners in order."""
    return add_mesh(scene, name, corners, [(0, 1, 2, 3)], material)


def add_block(scene, name, center, size, rotation_z=0.0, material=None):
    """A closed axis-aligned box of ``size (3,)`` resting at ``center``, turned about z."""
    sx, sy, sz = (0.5 * s for s in size)
    v = np.array([(x, y, z) for z in (-sz, sz) for y in (-sy, sy) for x in (-sx, sx)])
    faces = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    ob = add_mesh(scene, name, v, faces, material, location=center)
    ob.rotation_euler = (0.0, 0.0, rotation_z)
    return ob


def add_camera(scene, location, rotation_euler, lens=50.0, name="Camera"):
    """Link a perspective camera and make it the scene camera."""
    cam = bpy.data.cameras.new(name)
    cam.lens = lens
    ob = bpy.data.objects.new(name, cam)
    ob.location = location
    ob.rotation_euler = rotation_euler
    scene.collection.objects.link(ob)
    scene.camera = ob
    return ob


def add_light(scene, light_type, name, location=(0.0, 0.0, 0.0), rotation_euler=(0.0, 0.0, 0.0),
              energy=10.0, color=(1.0, 1.0, 1.0), **props):
    """Link a light object; ``props`` are set on the light data (e.g. ``shadow_soft_size``)."""
    light = bpy.data.lights.new(name, light_type)
    light.energy = energy
    light.color = color
    for key, value in props.items():
        setattr(light, key, value)
    ob = bpy.data.objects.new(name, light)
    ob.location = location
    ob.rotation_euler = rotation_euler
    scene.collection.objects.link(ob)
    return ob


def set_resolution(scene, width, height, percentage=100):
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = percentage
    scene.render.pixel_aspect_x = 1.0
    scene.render.pixel_aspect_y = 1.0


# --------------------------------------------------------------------------- scenes


def cornell_box(scene, light="mesh", resolution=(32, 32), light_color=(1.0, 1.0, 1.0),
                blocks=True, light_size=0.5):
    """A Lambertian Cornell box with one light, a camera and a black world.

    Parameters
    ----------
    scene : bpy.types.Scene
    light : str
        ``'mesh'``: an emissive quad under the ceiling (Emission shader, strength 10);
        ``'point'``: a 100 W point light of radius 0 at (0, 0, 1.8);
        ``'area'``: a ``light_size`` square area light of 50 W under the ceiling, facing down.
    resolution : (int, int)
    light_color : (3,) float
    blocks : bool
        Whether to add the two white blocks.
    light_size : float
        Side of the area light (m).

    Returns
    -------
    dict
        ``camera``, ``light``, ``walls`` (list), ``blocks`` (list) objects.
    """
    white = diffuse_material("White", WHITE)
    red = diffuse_material("Red", RED)
    green = diffuse_material("Green", GREEN)
    walls = [
        add_quad(scene, "Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], white),
        add_quad(scene, "Ceiling", [(-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)], white),
        add_quad(scene, "Back", [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)], white),
        add_quad(scene, "Left", [(-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)], red),
        add_quad(scene, "Right", [(1, -1, 0), (1, -1, 2), (1, 1, 2), (1, 1, 0)], green),
    ]
    blocks = [
        add_block(scene, "ShortBlock", (0.33, -0.3, 0.3), (0.6, 0.6, 0.6), math.radians(-17), white),
        add_block(scene, "TallBlock", (-0.33, 0.35, 0.6), (0.6, 0.6, 1.2), math.radians(17), white),
    ] if blocks else []
    if light == "mesh":
        emit = emission_material("Light", light_color, 10.0)
        h = 0.25
        lamp = add_quad(scene, "Lamp", [(-h, -h, 1.98), (h, -h, 1.98), (h, h, 1.98), (-h, h, 1.98)],
                        emit)
    elif light == "point":
        lamp = add_light(scene, 'POINT', "Lamp", (0.0, 0.0, 1.8), energy=100.0, color=light_color,
                         shadow_soft_size=0.0)
    elif light == "area":
        lamp = add_light(scene, 'AREA', "Lamp", (0.0, 0.0, 1.98), energy=50.0, color=light_color,
                         shape='SQUARE', size=light_size)
    else:
        raise ValueError(f"unknown light {light!r}")
    set_world(scene, (0.0, 0.0, 0.0), 0.0)
    camera = add_camera(scene, (0.0, -3.9, 1.0), (math.radians(90), 0.0, 0.0), lens=38.0)
    set_resolution(scene, *resolution)
    return {"camera": camera, "light": lamp, "walls": walls, "blocks": blocks}


def cornell_box_mesh_light(scene, resolution=(32, 32)):
    """:func:`cornell_box` lit by an emissive mesh (Emission shader)."""
    return cornell_box(scene, "mesh", resolution)


def cornell_box_point_light(scene, resolution=(32, 32)):
    """:func:`cornell_box` lit by a 100 W point light of radius 0."""
    return cornell_box(scene, "point", resolution)


def cornell_box_area_light(scene, resolution=(32, 32)):
    """:func:`cornell_box` lit by a 50 W square area light."""
    return cornell_box(scene, "area", resolution)


def plane_under_sun(scene, resolution=(32, 32), strength=3.0, angle_deg=0.526,
                    world_color=(0.05, 0.07, 0.1)):
    """A 4 x 4 m grey diffuse plane at z = 0 under a sun tilted 30 degrees, with a dim world.

    Returns
    -------
    dict
        ``camera``, ``sun``, ``plane`` objects.
    """
    grey = diffuse_material("Grey", (0.5, 0.5, 0.5))
    plane = add_quad(scene, "Plane", [(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], grey)
    sun = add_light(scene, 'SUN', "Sun", (0.0, 0.0, 5.0), (math.radians(30), 0.0, 0.0),
                    energy=strength, angle=math.radians(angle_deg))
    set_world(scene, world_color, 1.0)
    camera = add_camera(scene, (0.0, -3.0, 2.0), (math.radians(60), 0.0, 0.0), lens=35.0)
    set_resolution(scene, *resolution)
    return {"camera": camera, "sun": sun, "plane": plane}


def cornell_sphere(scene, material, resolution=(32, 32), light_size=0.3,
                   center=(0.0, -0.1, 0.45), radius=0.45):
    """The Cornell box without blocks, a ``light_size`` 50 W area light, and one flat-shaded
    UV sphere of ``material`` (a mirror ball, a glass sphere)."""
    objects = cornell_box(scene, "area", resolution, blocks=False, light_size=light_size)
    objects["sphere"] = add_uv_sphere(scene, "Sphere", center, radius, material)
    return objects


def cornell_smooth_sphere(scene, material, resolution=(32, 32), light_size=0.3,
                          center=(0.0, -0.1, 0.45), radius=0.45, segments=16, rings=8):
    """:func:`cornell_sphere` with a coarse smooth-shaded UV sphere (Shade Smooth): shading
    normals differ visibly from the facets, so the corner-normal export and the geometric-side
    rule are both exercised."""
    objects = cornell_box(scene, "area", resolution, blocks=False, light_size=light_size)
    ob = add_uv_sphere(scene, "Sphere", center, radius, material, segments, rings)
    ob.data.polygons.foreach_set("use_smooth", [True] * len(ob.data.polygons))
    ob.data.update()
    objects["sphere"] = ob
    return objects


def glossy_plates(scene, resolution=(32, 32), roughness=(0.1, 0.3, 0.6)):
    """Three Glossy BSDF (GGX) plates over a grey diffuse floor, under a small (0.1 m, 10 W)
    and a large (1 m, 50 W) square area light whose reflections the camera sees, black world."""
    grey = diffuse_material("Grey", (0.4, 0.4, 0.4))
    floor = add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], grey)
    plates = []
    for i, (x, r) in enumerate(zip((-0.7, 0.0, 0.7), roughness)):
        mat = glossy_material(f"Glossy{i}", (0.9, 0.8, 0.6), r)
        h = 0.3
        plates.append(add_quad(scene, f"Plate{i}", [(x - h, -h, 0.01), (x + h, -h, 0.01),
                                                    (x + h, h, 0.01), (x - h, h, 0.01)], mat))
    small = add_light(scene, 'AREA', "SmallLamp", (-0.6, 1.1, 1.5), energy=10.0,
                      shape='SQUARE', size=0.1)
    large = add_light(scene, 'AREA', "LargeLamp", (0.6, 1.1, 1.5), energy=50.0,
                      shape='SQUARE', size=1.0)
    set_world(scene, (0.0, 0.0, 0.0), 0.0)
    camera = add_camera(scene, (0.0, -2.5, 1.5), (math.radians(61), 0.0, 0.0), lens=35.0)
    set_resolution(scene, *resolution)
    return {"camera": camera, "floor": floor, "plates": plates, "lights": [small, large]}


# Size of the environment map of :func:`environment_scene`.
SKY_W, SKY_H = 64, 32


def sky_pixels():
    """``(32, 64, 3)`` radiance: a gradient in u (red) and v (green), dark below the horizon,
    and a 3 x 2 pixel spot ten times brighter (row 0 is the bottom, the nadir)."""
    u = (np.arange(SKY_W) + 0.5) / SKY_W
    v = (np.arange(SKY_H) + 0.5) / SKY_H
    r = 0.2 + 1.2 * u[None, :] * np.ones((SKY_H, 1))
    g = 0.1 + 1.0 * v[:, None] * np.ones((1, SKY_W))
    b = np.full((SKY_H, SKY_W), 0.4)
    rgb = np.stack([r, g, b], axis=-1)
    rgb[v < 0.5] *= 0.3
    rgb[19:21, 20:23] = (12.0, 10.0, 6.0)   # above the horizon, toward +Y+X
    return rgb.astype(np.float32)


def environment_scene(scene, resolution=(64, 64), strength=1.5):
    """A grey diffuse plane and a white flat-shaded UV sphere under an Environment Texture
    world (:func:`sky_pixels` x ``strength``); the camera sees the sky in the upper part.

    Returns
    -------
    world, env_node, background_node
    """
    image = float_image("Sky", sky_pixels())
    world, env, bg = set_environment_world(scene, image, strength)
    grey = diffuse_material("Grey", (0.5, 0.5, 0.5))
    white = diffuse_material("White", (0.8, 0.8, 0.8))
    add_quad(scene, "Plane", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], grey)
    add_uv_sphere(scene, "Sphere", (0.3, 0.4, 0.6), 0.6, white)
    # Looking toward +Y and 10 degrees down: the upper part of the image is sky.
    add_camera(scene, (0.0, -4.0, 1.4), (math.radians(80), 0.0, 0.0), lens=24.0)
    set_resolution(scene, *resolution)
    return world, env, bg
