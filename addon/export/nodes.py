"""Reading shader node trees: links through reroutes and muted nodes, the active output, and
constant socket values (reporting whatever drives them that the exporter cannot translate)."""

from __future__ import annotations

import bpy
import numpy as np

_BLENDER_5 = bpy.app.version >= (5, 0, 0)

# The colour input of each BSDF node that an Image Texture may drive (the base colour).
TEXTURED_SOCKETS = {
    'ShaderNodeBsdfPrincipled': "Base Color",
    'ShaderNodeBsdfDiffuse': "Color",
    'ShaderNodeBsdfGlossy': "Color",
    'ShaderNodeBsdfAnisotropic': "Color",
    'ShaderNodeBsdfGlass': "Color",
    'ShaderNodeBsdfRefraction': "Color",
}


# The roughness input of each BSDF node that an Image Texture may drive (its luminance).
ROUGHNESS_SOCKETS = {
    'ShaderNodeBsdfPrincipled': "Roughness",
    'ShaderNodeBsdfGlossy': "Roughness",
    'ShaderNodeBsdfAnisotropic': "Roughness",
    'ShaderNodeBsdfGlass': "Roughness",
}


# Scalar inputs an Image Texture may drive (its luminance), read by textures.scalar_texture.
SCALAR_TEXTURE_SOCKETS = {
    'ShaderNodeBsdfPrincipled': ("Metallic", "Alpha", "Specular IOR Level", "Coat Weight"),
}


def uses_nodes(id_data):
    """Whether a material or world shades with its node tree."""
    # Blender 5 always shades with nodes and deprecates `use_nodes`.
    return _BLENDER_5 or bool(getattr(id_data, "use_nodes", False))


def node_name(node):
    """The name the user sees on a node: its label, else its name."""
    return node.label or node.name


def follow_link(socket):
    """The node and output socket feeding ``socket``, through reroutes and muted nodes.

    Returns ``None`` when nothing valid is connected (the socket's own value then applies).
    """
    for _ in range(256):  # bounded: node trees may be cyclic when invalid
        if not socket.is_linked:
            return None
        link = socket.links[0]
        if not link.is_valid or getattr(link, "is_muted", False):
            return None
        node = link.from_node
        if node.bl_idname == 'NodeReroute':
            socket = node.inputs[0]
            continue
        if node.mute:
            # A muted node passes its first matching input through, or outputs nothing.
            passed = [lk.from_socket for lk in node.internal_links
                      if lk.to_socket == link.from_socket]
            if not passed:
                return None
            socket = passed[0]
            continue
        return node, link.from_socket
    return None


def active_output(tree, idname):
    """The active output node of type ``idname`` that Cycles would use, or None."""
    outputs = [n for n in tree.nodes
               if n.bl_idname == idname and not n.mute
               and getattr(n, "target", 'ALL') in {'ALL', 'CYCLES'}]
    for node in outputs:
        if getattr(node, "is_active_output", False):
            return node
    return outputs[0] if outputs else None


class NodeReader:
    """Reads constant socket values, reporting anything that drives them."""

    def __init__(self, owner, messages):
        self.owner = owner  # "Material 'Name'" or "World 'Name'"
        self.messages = messages

    def color(self, node, name, default=(0.0, 0.0, 0.0)):
        socket = node.inputs.get(name)
        if socket is None:
            return np.asarray(default, np.float64)
        return np.asarray(self._value(node, socket, 3), np.float64)

    def value(self, node, name, default=0.0):
        socket = node.inputs.get(name)
        if socket is None:
            return float(default)
        return float(self._value(node, socket, 1))

    def _value(self, node, socket, size):
        source = follow_link(socket)
        if source is not None:
            src_node, out = source
            # Constant nodes are exact; anything else (textures, math) is approximated.
            if src_node.bl_idname in {'ShaderNodeRGB', 'ShaderNodeValue'}:
                return as_size(out.default_value, size)
            textured = socket.name in (TEXTURED_SOCKETS.get(node.bl_idname),
                                       ROUGHNESS_SOCKETS.get(node.bl_idname),
                                       *SCALAR_TEXTURE_SOCKETS.get(node.bl_idname, ()))
            if textured and src_node.bl_idname == 'ShaderNodeTexImage':
                # Read by textures.surface_texture, which reports what it cannot translate.
                return as_size(socket.default_value, size)
            self.messages.add(
                f"{self.owner}: input '{socket.name}' of node '{node_name(node)}' is driven "
                f"by node '{node_name(src_node)}', which is not supported yet; using the "
                f"input's own value")
        return as_size(socket.default_value, size)

    def ignored_if_linked(self, node, name, what):
        socket = node.inputs.get(name)
        if socket is not None and follow_link(socket) is not None:
            self.messages.add(f"{self.owner}: {what} of node '{node_name(node)}' is not "
                              f"supported yet; ignored")


def as_size(value, size):
    """A socket value as a scalar (``size`` 1) or a ``size``-tuple (a scalar repeated)."""
    try:
        seq = tuple(value)
    except TypeError:
        seq = (float(value),)
    if size == 1:
        return seq[0]
    if len(seq) == 1:
        return seq * size
    return seq[:size]


def as_color(value):
    """``(3,) float64`` RGB of a colour socket value."""
    return np.asarray(as_size(value, 3), np.float64)
