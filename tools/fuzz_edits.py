"""Ways to break a Blender scene through the data API, for the fuzz harness (:mod:`.fuzz`).

Each edit is ``edit(scene, objs, value, folder)``: ``objs`` is what
:func:`.bpy_scenes.cornell_box` returns (``camera``, ``light``, ``walls``, ``blocks``), ``value``
one of :data:`.fuzz_cases.EDITS`'s values, ``folder`` the case's folder with the broken files of
``fuzz_child.make_fixtures``. An edit Blender refuses raises (TypeError, ValueError, ...) and the
child logs it as skipped.
"""

from __future__ import annotations

import os
import random

import bpy

from .bpy_scenes import glass_material, set_environment_world, set_world


def _lamp(objs):
    lamp = objs["light"]
    if lamp.type != "LIGHT":
        raise TypeError("the light is an emissive mesh, not a lamp")
    return lamp.data


def _white():
    return bpy.data.materials["White"].node_tree


def _output(tree):
    return next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")


def _set_inputs(tree, name, value):
    found = [n.inputs[name] for n in tree.nodes if name in n.inputs]
    if not found:
        raise KeyError(f"no node with an input {name!r}")
    for socket in found:
        socket.default_value = value


def _emission_tree():
    for mat in bpy.data.materials:
        if mat.node_tree and any(n.bl_idname == "ShaderNodeEmission" for n in mat.node_tree.nodes):
            return mat.node_tree
    raise KeyError("no emission material")


def light_energy(scene, objs, v, folder):
    if objs["light"].type == "LIGHT":
        _lamp(objs).energy = v
    else:
        _set_inputs(_emission_tree(), "Strength", v)


def light_size(scene, objs, v, folder):
    lamp = _lamp(objs)
    if lamp.type == "AREA":
        lamp.size = v
    lamp.shadow_soft_size = v


def light_color(scene, objs, v, folder):
    if objs["light"].type == "LIGHT":
        _lamp(objs).color = (v, v, v)
    else:
        _set_inputs(_emission_tree(), "Color", (v, v, v, 1.0))


def spot_size(scene, objs, v, folder):
    lamp = _lamp(objs)
    lamp.type = "SPOT"
    objs["light"].data.spot_size = v


def sun_angle(scene, objs, v, folder):
    lamp = _lamp(objs)
    lamp.type = "SUN"
    objs["light"].data.angle = v


def emission_strength(scene, objs, v, folder):
    _set_inputs(_emission_tree(), "Strength", v)


def _camera_attr(attr):
    def edit(scene, objs, v, folder):
        setattr(objs["camera"].data, attr, v)
    edit.__name__ = f"camera_{attr}"
    return edit


def camera_ortho_scale(scene, objs, v, folder):
    objs["camera"].data.type = "ORTHO"
    objs["camera"].data.ortho_scale = v


def object_scale(scene, objs, v, folder):
    (objs["blocks"] or objs["walls"])[0].scale = (v, v, v)


def object_location(scene, objs, v, folder):
    (objs["blocks"] or objs["walls"])[0].location.x = v


def roughness(scene, objs, v, folder):
    _set_inputs(_white(), "Roughness", v)


def ior(scene, objs, v, folder):
    glass = glass_material("Glass", ior=v)
    for obj in objs["blocks"] or objs["walls"][:1]:
        obj.data.materials[0] = glass


def base_color(scene, objs, v, folder):
    _set_inputs(_white(), "Color", (v, v, v, 1.0))


def world_strength(scene, objs, v, folder):
    set_world(scene, (0.2, 0.2, 0.2), v)


def remove_output_node(scene, objs, v, folder):
    tree = _white()
    tree.nodes.remove(_output(tree))


def unlink_surface(scene, objs, v, folder):
    tree = _white()
    for link in list(_output(tree).inputs["Surface"].links):
        tree.links.remove(link)


def cyclic_nodes(scene, objs, v, folder):
    tree = _white()
    a, b = tree.nodes.new("ShaderNodeMixShader"), tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(a.outputs[0], b.inputs[1])
    tree.links.new(b.outputs[0], a.inputs[1])
    tree.links.new(a.outputs[0], _output(tree).inputs["Surface"])


def unknown_node(scene, objs, v, folder):
    tree = _white()
    node = tree.nodes.new(v)
    tree.links.new(node.outputs[0], _output(tree).inputs["Surface"])


def node_group(scene, objs, v, folder):
    tree = _white()
    node = tree.nodes.new("ShaderNodeGroup")
    if v != "none":
        group = bpy.data.node_groups.new("Broken Group", "ShaderNodeTree")
        if v != "empty":
            group.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
            inner = group.nodes.new("ShaderNodeBsdfPrincipled")
            if v == "shader":
                out = group.nodes.new("NodeGroupOutput")
                group.links.new(inner.outputs[0], out.inputs[0])
        node.node_tree = group
    if node.outputs:
        tree.links.new(node.outputs[0], _output(tree).inputs["Surface"])


def _image(kind, folder):
    if kind == "none":
        return None
    image = bpy.data.images.new(f"Broken {kind}", 4, 4, float_buffer=True)
    image.source = "FILE"
    image.filepath = (os.path.join(folder, "truncated.exr") if kind == "truncated"
                      else os.path.join(folder, "no_such_image.exr"))
    return image


def _image_edit(kind):
    def edit(scene, objs, v, folder):
        image = _image(kind, folder)
        if v == "world":
            set_environment_world(scene, image)
            return
        tree = _white()
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        shader = next(n for n in tree.nodes if "Color" in n.inputs)
        tree.links.new(tex.outputs["Color"], shader.inputs["Color"])
    edit.__name__ = f"{kind}_image"
    return edit


def empty_material_slot(scene, objs, v, folder):
    objs["walls"][0].data.materials[0] = None


def no_world(scene, objs, v, folder):
    scene.world = None


def no_camera(scene, objs, v, folder):
    scene.camera = None


def no_lights(scene, objs, v, folder):
    bpy.data.objects.remove(objs["light"])


def samples(scene, objs, v, folder):
    scene.sampling_lab.samples = v
    if v > 1:  # a huge count needs a time limit to end
        scene.sampling_lab.time_limit = 0.3


def time_limit(scene, objs, v, folder):
    scene.sampling_lab.time_limit = v


def resolution(scene, objs, v, folder):
    scene.render.resolution_x, scene.render.resolution_y = v
    scene.render.resolution_percentage = 100


def nan_vertex(scene, objs, v, folder):
    mesh = (objs["blocks"] or objs["walls"])[0].data
    mesh.vertices[0].co = (v, v, v)


def empty_mesh(scene, objs, v, folder):
    mesh = bpy.data.meshes.new("Broken Mesh")
    if v == "one_point":
        mesh.from_pydata([(0.0, 0.0, 1.0)], [], [])
    elif v == "collapsed":
        mesh.from_pydata([(0.0, 0.0, 1.0)] * 4, [], [(0, 1, 2), (0, 2, 3)])
    obj = bpy.data.objects.new("Broken Mesh", mesh)
    scene.collection.objects.link(obj)


def camera_type(scene, objs, v, folder):
    objs["camera"].data.type = v


def render_region(scene, objs, v, folder):
    r = scene.render
    r.use_border = True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = v


def frame(scene, objs, v, folder):
    scene.frame_set(v)


def mix_fac(scene, objs, v, folder):
    tree = _white()
    shader = next(n for n in tree.nodes if n.bl_idname != "ShaderNodeOutputMaterial")
    mix = tree.nodes.new("ShaderNodeMixShader")
    glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
    mix.inputs["Fac"].default_value = v
    tree.links.new(shader.outputs[0], mix.inputs[1])
    tree.links.new(glossy.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], _output(tree).inputs["Surface"])


def volume_output(scene, objs, v, folder):
    tree = _white()
    volume = tree.nodes.new("ShaderNodeVolumePrincipled")
    tree.links.new(volume.outputs[0], _output(tree).inputs["Volume"])


def sampler(scene, objs, v, folder):
    scene.sampling_lab.sampler = v.upper()


def threads(scene, objs, v, folder):
    scene.render.threads_mode = "FIXED"
    scene.render.threads = v


def _setting(name):
    def edit(scene, objs, v, folder):
        setattr(scene.sampling_lab, name, v)
    edit.__name__ = name
    return edit


EDITS = {
    "light_energy": light_energy,
    "light_size": light_size,
    "light_color": light_color,
    "spot_size": spot_size,
    "sun_angle": sun_angle,
    "emission_strength": emission_strength,
    "camera_lens": _camera_attr("lens"),
    "camera_clip_start": _camera_attr("clip_start"),
    "camera_clip_end": _camera_attr("clip_end"),
    "camera_sensor": _camera_attr("sensor_width"),
    "camera_ortho_scale": camera_ortho_scale,
    "camera_shift": _camera_attr("shift_x"),
    "object_scale": object_scale,
    "object_location": object_location,
    "roughness": roughness,
    "ior": ior,
    "base_color": base_color,
    "world_strength": world_strength,
    "remove_output_node": remove_output_node,
    "unlink_surface": unlink_surface,
    "cyclic_nodes": cyclic_nodes,
    "unknown_node": unknown_node,
    "node_group": node_group,
    "missing_image": _image_edit("missing"),
    "truncated_exr": _image_edit("truncated"),
    "image_without_file": _image_edit("none"),
    "empty_material_slot": empty_material_slot,
    "no_world": no_world,
    "no_camera": no_camera,
    "no_lights": no_lights,
    "samples": samples,
    "time_limit": time_limit,
    "resolution": resolution,
    "nan_vertex": nan_vertex,
    "empty_mesh": empty_mesh,
    "camera_type": camera_type,
    "render_region": render_region,
    "frame": frame,
    "mix_fac": mix_fac,
    "volume_output": volume_output,
    "sampler": sampler,
    "threads": threads,
    "photon_memory": _setting("photon_memory"),
    "radiosity_patch_size": _setting("radiosity_patch_size"),
}


def apply_damage(path, damage):
    """Damage the saved ``.blend`` at ``path``: cut it in half, overwrite its middle with random
    bytes, empty it, or leave only its magic word."""
    if damage is None:
        return
    size = os.path.getsize(path)
    with open(path, "r+b") as f:
        if damage == "truncate":
            f.truncate(size // 2)
        elif damage == "garble":
            rng = random.Random(size)
            f.seek(size // 4)
            f.write(bytes(rng.randrange(256) for _ in range(min(size // 2, 65536))))
        elif damage == "empty":
            f.truncate(0)
        elif damage == "magic_only":
            f.truncate(0)
            f.write(b"BLENDER")
