"""The world -> the background radiance: a constant colour or an environment map."""

from __future__ import annotations

import numpy as np

from .nodes import NodeReader, active_output, as_color, follow_link, node_name, uses_nodes
from .textures import environment_pixels


def world_radiance(world, messages):
    """Background radiance of a world: a constant (Background Color x Strength) or a map.

    A Background (or Emission) node whose Color is linked to an Environment Texture node with
    an image (equirectangular projection, nothing linked to its Vector) gives an environment
    map: the image's RGB x Strength, rows bottom first as Blender stores them (see
    :attr:`core.scene.Scene.world_map`). Anything else linked to the Color is reported once
    and replaced by the socket's own colour.

    Returns
    -------
    color : (3,) float64
        Constant radiance (zero when a map is returned).
    world_map : (h, w, 3) float32 or None
    """
    if world is None:
        return np.zeros(3), None
    owner = f"World '{world.name}'"
    if not uses_nodes(world) or world.node_tree is None:
        return np.asarray(world.color[:3], np.float64), None
    output = active_output(world.node_tree, 'ShaderNodeOutputWorld')
    if output is None:
        return np.zeros(3), None
    socket = output.inputs.get("Volume")
    if socket is not None and follow_link(socket) is not None:
        messages.add(f"{owner}: volume is not supported yet; ignored")
    source = follow_link(output.inputs["Surface"])
    if source is None:
        return np.zeros(3), None
    node, _ = source
    read = NodeReader(owner, messages)
    if node.bl_idname in {'ShaderNodeBackground', 'ShaderNodeEmission'}:
        strength = read.value(node, "Strength")
        color_source = follow_link(node.inputs["Color"])
        if color_source is not None and color_source[0].bl_idname == 'ShaderNodeTexEnvironment':
            pixels = environment_pixels(color_source[0], owner, messages)
            if pixels is not None:
                return np.zeros(3), (pixels * np.float32(strength)).astype(np.float32)
            return as_color(node.inputs["Color"].default_value) * strength, None
        return read.color(node, "Color") * strength, None
    messages.add(f"{owner}: node '{node_name(node)}' is not supported yet; rendered black")
    return np.zeros(3), None
