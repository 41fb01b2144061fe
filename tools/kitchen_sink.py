"""The kitchen-sink scene: most of what users put in a scene, at once, built with the data API.

Mesh light (an emissive quad), a sphere lamp (point of radius 0.3) and an area lamp; a world
lit by an equirectangular HDR image written to ``folder`` and read back by an Environment Texture; a
floor of textured Principled BSDF (base colour and roughness Image Textures) under a Coat; a
smooth-shaded Principled sphere whose Normal input is a Normal Map node (tangent space) on an
image; smooth glass and rough glass (0.3) spheres; a "leaf" that mixes a Principled BSDF with a
Transparent BSDF; a mirror; a rough Principled metal. Every node keeps Blender's defaults
beyond the inputs set here (so the rough ones are Multiscatter GGX). Used by
``tests/addon/test_cycles_kitchen_sink.py``; a benchmark may render the same scene.
"""

from __future__ import annotations

import math

import numpy as np

from .blender_scene import import_bpy
from .bpy_scenes import (
    add_camera,
    add_light,
    add_quad,
    emission_material,
    float_image,
    set_environment_world,
    set_resolution,
    shader_material,
)

bpy = import_bpy()

# The principled inputs of each material made here (everything else at Blender's defaults).
METAL = {"Base Color": (0.9, 0.6, 0.5, 1.0), "Metallic": 1.0, "Roughness": 0.5}
LEAF = {"Base Color": (0.2, 0.5, 0.1, 1.0), "Roughness": 0.8}
BUMPY = {"Base Color": (0.6, 0.3, 0.6, 1.0), "Roughness": 0.4}
FLOOR_COAT = {"Coat Weight": 0.6, "Coat Roughness": 0.1}
LEAF_TRANSPARENCY = 0.5  # the Mix Shader's factor toward the Transparent BSDF


def principled_material(name, inputs):
    """A Principled BSDF material (as Blender creates it) with ``inputs`` set; returns
    ``(material, principled_node)``."""
    mat = shader_material(name, "ShaderNodeBsdfPrincipled")
    node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    return mat, node


def image_node(mat, image):
    """An Image Texture node of ``image`` in ``mat``'s tree."""
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    return tex


def data_image(name, rgb):
    """A float image of Non-Color data from ``rgb (h, w, 3)``. The colour space is set before
    the pixels: changing it afterwards regenerates a generated image's pixels (black)."""
    rgb = np.asarray(rgb, np.float32)
    h, w = rgb.shape[:2]
    image = bpy.data.images.new(name, w, h, alpha=True, float_buffer=True)
    image.colorspace_settings.name = 'Non-Color'
    rgba = np.concatenate([rgb, np.ones((h, w, 1), np.float32)], axis=2)
    image.pixels.foreach_set(rgba.reshape(-1))
    image.update()
    return image


def checker(n, colors):
    """``(n, n, 3)`` float32 cells cycling through ``colors`` (row 0 at the bottom)."""
    colors = np.asarray(colors, np.float32)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    return colors[(i + 2 * j) % len(colors)]


def bump_normals(n=16, slope=0.3):
    """``(n, n, 3)`` tangent-space normal map (encoded ``0.5 n + 0.5``) of gentle ripples."""
    x = (np.arange(n) + 0.5) / n
    tx = slope * np.sin(2 * np.pi * 2 * x)[None, :].repeat(n, 0)
    ty = slope * np.cos(2 * np.pi * 3 * x)[:, None].repeat(n, 1)
    normal = np.stack([-tx, -ty, np.ones_like(tx)], axis=-1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    return (0.5 * normal + 0.5).astype(np.float32)


def write_hdr(path, rgb):
    """Write ``rgb (h, w, 3)`` (row 0 at the bottom) as an uncompressed Radiance HDR file
    (RGBE: an 8-bit mantissa per channel and a shared exponent)."""
    rgb = np.maximum(np.asarray(rgb, np.float64)[::-1], 0.0)
    h, w = rgb.shape[:2]
    peak = rgb.max(axis=-1)
    mantissa, exponent = np.frexp(peak)
    scale = np.where(peak > 1e-32, mantissa * 256.0 / np.maximum(peak, 1e-300), 0.0)
    rgbe = np.empty((h, w, 4), np.uint8)
    rgbe[..., :3] = np.clip(rgb * scale[..., None], 0, 255).astype(np.uint8)
    rgbe[..., 3] = np.where(peak > 1e-32, exponent + 128, 0)
    header = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n".encode()
    with open(path, "wb") as f:
        f.write(header + rgbe.tobytes())


def sky_hdr(folder, width=32, height=16):
    """Write a small equirectangular sky (a warm sun-ish patch over a blue gradient, a dark
    ground) as a Radiance HDR file in ``folder`` and load it (as linear Rec.709, as users'
    HDRIs load); returns the image."""
    path = str(folder / "kitchen_sink_sky.hdr")
    v = (np.arange(height) + 0.5) / height
    u = (np.arange(width) + 0.5) / width
    rgb = np.empty((height, width, 3), np.float32)
    rgb[:] = np.where(v[:, None] > 0.5, 1.0, 0.25)[..., None] * np.array([0.5, 0.65, 0.9])
    rgb *= (0.6 + 0.8 * v)[:, None, None]
    sun = (np.abs(u - 0.3)[None, :] < 0.1) & (np.abs(v - 0.75)[:, None] < 0.15)
    rgb[sun] = (1.8, 1.5, 1.2)
    write_hdr(path, rgb)
    return bpy.data.images.load(path)


def uv_sphere(scene, name, center, radius, material, smooth=False, segments=24, rings=12):
    """A UV sphere with a UV map (Blender's own sphere UVs), flat or smooth shaded."""
    import bmesh

    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    # calc_uvs fills the UV layer that exists (a new sphere in Blender has "UVMap").
    bm.loops.layers.uv.new("UVMap")
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=radius,
                              calc_uvs=True)
    bm.to_mesh(mesh)
    bm.free()
    mesh.polygons.foreach_set("use_smooth", [smooth] * len(mesh.polygons))
    mesh.materials.append(material)
    mesh.update()
    ob = bpy.data.objects.new(name, mesh)
    ob.location = center
    scene.collection.objects.link(ob)
    return ob


def uv_quad(scene, name, corners, material, repeat=1.0):
    """A quad whose UVs span ``[0, repeat]^2`` along its first and last edges."""
    ob = add_quad(scene, name, corners, material)
    layer = ob.data.uv_layers.new(name="UVMap")
    uv = np.array([0, 0, 1, 0, 1, 1, 0, 1], np.float32) * repeat
    layer.uv.foreach_set("vector", uv)
    ob.data.update()
    return ob


def floor_material():
    """Principled floor: checker base colour and a Non-Color roughness checker, under a
    Coat."""
    mat, node = principled_material("Floor", FLOOR_COAT)
    tree = mat.node_tree
    color = image_node(mat, float_image("FloorColor", checker(
        8, [(0.5, 0.4, 0.3), (0.15, 0.2, 0.25), (0.4, 0.12, 0.1)])))
    rough = image_node(mat, data_image("FloorRoughness", checker(4, [(0.2,) * 3, (0.7,) * 3])))
    tree.links.new(color.outputs["Color"], node.inputs["Base Color"])
    tree.links.new(rough.outputs["Color"], node.inputs["Roughness"])
    return mat


def bumpy_material():
    """Principled sphere whose Normal is a tangent-space Normal Map node on an image."""
    mat, node = principled_material("Bumpy", BUMPY)
    tree = mat.node_tree
    tex = image_node(mat, data_image("Ripples", bump_normals()))
    normal_map = tree.nodes.new("ShaderNodeNormalMap")
    tree.links.new(tex.outputs["Color"], normal_map.inputs["Color"])
    tree.links.new(normal_map.outputs["Normal"], node.inputs["Normal"])
    return mat


def leaf_material():
    """A Mix Shader of a green Principled BSDF and a Transparent BSDF."""
    mat, node = principled_material("Leaf", LEAF)
    tree = mat.node_tree
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    clear = tree.nodes.new("ShaderNodeBsdfTransparent")
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = LEAF_TRANSPARENCY
    tree.links.new(node.outputs[0], mix.inputs[1])
    tree.links.new(clear.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    return mat


def kitchen_sink(scene, folder, resolution=(48, 32)):
    """Build the kitchen-sink scene into ``scene`` (normally empty); the sky EXR is written to
    ``folder``. Returns a dict of the objects made, by role."""
    objects = {"floor": uv_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0),
                                                 (-3, 3, 0)], floor_material(), repeat=3.0)}
    glass = shader_material("Glass", "ShaderNodeBsdfGlass")
    rough_glass = shader_material("RoughGlass", "ShaderNodeBsdfGlass")
    rough_glass.node_tree.nodes["Glass BSDF"].inputs["Roughness"].default_value = 0.3
    mirror = shader_material("Mirror", "ShaderNodeBsdfGlossy", color=(0.9, 0.9, 0.9))
    mirror.node_tree.nodes["Glossy BSDF"].inputs["Roughness"].default_value = 0.0
    spheres = {"bumpy": ((-1.0, 0.3, 0.35), bumpy_material(), True),
               "glass": ((-0.25, -0.3, 0.3), glass, False),
               "rough_glass": ((0.45, -0.2, 0.3), rough_glass, False),
               "metal": ((1.1, 0.4, 0.4), principled_material("Metal", METAL)[0], False)}
    for role, (center, mat, smooth) in spheres.items():
        objects[role] = uv_sphere(scene, role.title(), center, center[2], mat, smooth)
    objects["mirror"] = add_quad(scene, "Mirror", [(-1.6, 1.3, 0), (0.4, 1.6, 0),
                                                   (0.4, 1.6, 1.4), (-1.6, 1.3, 1.4)], mirror)
    objects["leaf"] = uv_quad(scene, "Leaf", [(0.5, -0.3, 1.3), (1.5, -0.3, 1.3),
                                              (1.5, 0.7, 1.5), (0.5, 0.7, 1.5)], leaf_material())
    objects["mesh_light"] = add_quad(scene, "Panel", [(-1.5, -0.5, 2.2), (-1.5, 0.3, 2.2),
                                                      (-0.7, 0.3, 2.4), (-0.7, -0.5, 2.4)],
                                     emission_material("Panel", (1.0, 0.9, 0.8), 2.0))
    objects["sphere_lamp"] = add_light(scene, 'POINT', "Bulb", (0.2, -1.0, 2.0), energy=25.0,
                                       color=(1.0, 0.8, 0.6), shadow_soft_size=0.3)
    objects["area_lamp"] = add_light(scene, 'AREA', "Softbox", (1.2, 0.2, 2.6), energy=40.0,
                                     shape='SQUARE', size=1.5)
    set_environment_world(scene, sky_hdr(folder), strength=1.0)
    objects["camera"] = add_camera(scene, (0.0, -4.2, 1.6), (math.radians(74.0), 0.0, 0.0),
                                   lens=35.0)
    set_resolution(scene, *resolution)
    return objects
