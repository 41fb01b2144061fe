"""Blender depsgraph -> :class:`core.scene.Scene`.

Everything is read from the evaluated (render) depsgraph: meshes with their modifiers, every
instance (collection instances, particles, geometry nodes) through
``depsgraph.object_instances``, lights, the world and the camera. Mesh data is copied with
``foreach_get`` into NumPy arrays and moved to world space with one matrix product per object;
there is no Python loop over vertices or triangles.

The exporter maps what a scene uses onto the small closed set of core materials and lights, and
says once per render, in :attr:`core.scene.Scene.messages`, what it approximated or ignored.
Unit conversion of lights is left to :mod:`core.lights`; this module only reads Blender's values.
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from typing import NamedTuple

import bpy
import numpy as np

from ...core import lights as core_lights
from ...core.scene import (
    VIS_CAMERA,
    VIS_DIFFUSE,
    VIS_GLOSSY,
    VIS_SHADOW,
    VIS_TRANSMISSION,
    MAT_CONDUCTOR,
    MAT_DIELECTRIC,
    MAT_DIFFUSE,
    MAT_LAYERED,
    TEXTURE_EXTENSIONS,
    TEXTURE_INTERPOLATIONS,
    Camera,
    Lights,
    Materials,
    Scene,
)

NO_CAMERA_MESSAGE = (
    "Sampling Lab: the scene has no camera. Add a camera object and set it as the scene "
    "camera (Scene Properties > Camera)"
)

# Cycles shades surfaces without a material as a 0.8 grey diffuse.
DEFAULT_SURFACE_NAME = "Default Surface"
DEFAULT_SURFACE_COLOR = (0.8, 0.8, 0.8)

# Object types Blender can turn into a triangle mesh.
MESH_TYPES = {'MESH', 'CURVE', 'SURFACE', 'FONT', 'META'}
# Object types that neither emit nor occlude anything.
SKIPPED_TYPES = {'CAMERA', 'EMPTY', 'ARMATURE', 'LATTICE', 'SPEAKER', 'LIGHT_PROBE'}

_BLENDER_5 = bpy.app.version >= (5, 0, 0)


class ExportError(Exception):
    """A scene that cannot be rendered; the message is meant for the user."""


class Messages:
    """What the exporter approximated or ignored: each message once, in order."""

    def __init__(self):
        self._seen = set()
        self.items = []

    def add(self, text):
        if text not in self._seen:
            self._seen.add(text)
            self.items.append(text)


# --------------------------------------------------------------------------- node trees


def _uses_nodes(id_data):
    # Blender 5 always shades with nodes and deprecates `use_nodes`.
    return _BLENDER_5 or bool(getattr(id_data, "use_nodes", False))


def _node_name(node):
    return node.label or node.name


def _follow_link(socket):
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


def _active_output(tree, idname):
    """The active output node of type ``idname`` that Cycles would use, or None."""
    outputs = [n for n in tree.nodes
               if n.bl_idname == idname and not n.mute
               and getattr(n, "target", 'ALL') in {'ALL', 'CYCLES'}]
    for node in outputs:
        if getattr(node, "is_active_output", False):
            return node
    return outputs[0] if outputs else None


class _NodeReader:
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
        source = _follow_link(socket)
        if source is not None:
            src_node, out = source
            # Constant nodes are exact; anything else (textures, math) is approximated.
            if src_node.bl_idname in {'ShaderNodeRGB', 'ShaderNodeValue'}:
                return _as_size(out.default_value, size)
            if _TEXTURED_SOCKETS.get(node.bl_idname) == socket.name \
                    and src_node.bl_idname == 'ShaderNodeTexImage':
                # Read by _surface_texture, which reports what it cannot translate.
                return _as_size(socket.default_value, size)
            self.messages.add(
                f"{self.owner}: input '{socket.name}' of node '{_node_name(node)}' is driven "
                f"by node '{_node_name(src_node)}', which is not supported yet; using the "
                f"input's own value")
        return _as_size(socket.default_value, size)

    def ignored_if_linked(self, node, name, what):
        socket = node.inputs.get(name)
        if socket is not None and _follow_link(socket) is not None:
            self.messages.add(f"{self.owner}: {what} of node '{_node_name(node)}' is not "
                              f"supported yet; ignored")


def _as_size(value, size):
    try:
        seq = tuple(value)
    except TypeError:
        seq = (float(value),)
    if size == 1:
        return seq[0]
    if len(seq) == 1:
        return seq * size
    return seq[:size]


# Principled BSDF inputs whose non-zero value adds a lobe the core materials do not have.
_PRINCIPLED_LOBES = (
    ("Coat Weight", "coat"),
    ("Sheen Weight", "sheen"),
    ("Subsurface Weight", "subsurface"),
)


class Surface(NamedTuple):
    """One row of :class:`core.scene.Materials`, as translated from a Blender material."""

    kind: int = MAT_DIFFUSE
    base_color: np.ndarray = np.array(DEFAULT_SURFACE_COLOR)
    emission: np.ndarray = np.zeros(3)
    roughness: float = 0.5
    ior: float = 1.5
    metallic: float = 0.0
    transmission: float = 0.0
    specular_ior_level: float = 0.5
    specular_tint: np.ndarray = np.ones(3)
    texture: np.ndarray = None  # (h, w, 3) float32 base colour image, see _surface_texture
    texture_mode: tuple = ("Linear", "REPEAT")  # the image node's interpolation, extension
    # A mixture: ((weight, Surface), ...) of plain surfaces (see mix_surfaces); this row's own
    # BSDF fields are then unused, its emission is the mixture's.
    components: tuple = ()


# Most components a mixture keeps (the largest weights, renormalised; reported beyond).
MAX_COMPONENTS = 8


def _diffuse(color, emission=None):
    return Surface(MAT_DIFFUSE, np.asarray(color, np.float64),
                   np.zeros(3) if emission is None else emission)


_BLACK = Surface(MAT_DIFFUSE, np.zeros(3), np.zeros(3))


def material_surface(material, messages):
    """Core material (kind, colours, roughness, IOR, ...) and emitted radiance of a material.

    Parameters
    ----------
    material : bpy.types.Material or None
    messages : Messages

    Returns
    -------
    Surface
        ``emission`` is radiance, emitted from both faces.
    """
    if material is None:
        return _diffuse(DEFAULT_SURFACE_COLOR)
    owner = f"Material '{material.name}'"
    if not _uses_nodes(material) or material.node_tree is None:
        return _diffuse(material.diffuse_color[:3])
    tree = material.node_tree
    output = _active_output(tree, 'ShaderNodeOutputMaterial')
    if output is None:
        # Cycles renders a material without an output as black.
        return _BLACK
    for name in ("Volume", "Displacement"):
        socket = output.inputs.get(name)
        if socket is not None and _follow_link(socket) is not None:
            messages.add(f"{owner}: {name.lower()} is not supported yet; ignored")
    return _shader_surface(_follow_link(output.inputs["Surface"]), owner, messages)


# The colour input of each BSDF node that an Image Texture may drive (the base colour).
_TEXTURED_SOCKETS = {
    'ShaderNodeBsdfPrincipled': "Base Color",
    'ShaderNodeBsdfDiffuse': "Color",
    'ShaderNodeBsdfGlossy': "Color",
    'ShaderNodeBsdfAnisotropic': "Color",
    'ShaderNodeBsdfGlass': "Color",
    'ShaderNodeBsdfRefraction': "Color",
}


def _surface_texture(node, owner, messages):
    """``(pixels, (interpolation, extension))`` of the Image Texture driving the base colour
    of BSDF node ``node``, or None (unsupported ones reported)."""
    name = _TEXTURED_SOCKETS.get(node.bl_idname)
    socket = node.inputs.get(name) if name else None
    link = _follow_link(socket) if socket is not None else None
    if link is None or link[0].bl_idname != 'ShaderNodeTexImage':
        return None
    return _image_texture_pixels(link[0], link[1], owner, messages)


def _image_texture_pixels(node, out, owner, messages):
    """``(pixels, (interpolation, extension))`` of an Image Texture node: RGB ``(h, w, 3)``
    float32 and the lookup modes, or None (reported).

    What the core's lookup models: the Color output, flat projection of the active UV map
    (Vector unlinked, or from a UV Map node of the default map or a Texture Coordinate's UV),
    Linear or Closest interpolation (Cubic and Smart are reported and rendered as Linear),
    every extension (Repeat, Extend, Clip, Mirror); anything else falls back to the socket's
    own colour.
    """
    name = _node_name(node)
    fallback = "; using the input's own colour"
    image = node.image
    if image is None:
        messages.add(f"{owner}: image texture '{name}' has no image{fallback}")
        return None
    if out.identifier != "Color":
        messages.add(f"{owner}: the {out.name} output of image texture '{name}' is not "
                     f"supported yet{fallback}")
        return None
    if getattr(node, "projection", 'FLAT') != 'FLAT':
        messages.add(f"{owner}: {node.projection.lower()} projection of image texture '{name}' "
                     f"is not supported yet{fallback}")
        return None
    vector = node.inputs.get("Vector")
    coords = _follow_link(vector) if vector is not None else None
    if coords is not None:
        src, socket = coords
        default_uv = ((src.bl_idname == 'ShaderNodeUVMap' and not src.uv_map
                       and not getattr(src, "from_instancer", False))
                      or (src.bl_idname == 'ShaderNodeTexCoord' and socket.identifier == "UV"
                          and not getattr(src, "from_instancer", False)))
        if not default_uv:
            messages.add(f"{owner}: the Vector input of image texture '{name}' (node "
                         f"'{_node_name(src)}') is not supported yet{fallback}")
            return None
    if not _image_usable(node, image, "image texture", name, owner, fallback, messages,
                         TEXTURE_INTERPOLATIONS):
        return None
    extension = getattr(node, "extension", 'REPEAT')
    if extension not in TEXTURE_EXTENSIONS:
        messages.add(f"{owner}: {extension.lower()} extension of image texture '{name}' is "
                     f"not supported yet{fallback}")
        return None
    interpolation = getattr(node, "interpolation", 'Linear')
    if interpolation not in TEXTURE_INTERPOLATIONS:
        interpolation = 'Linear'
    return _image_rgb(image, owner, messages), (interpolation, extension)


def _image_usable(node, image, what, name, owner, fallback, messages,
                  interpolations=("Linear",)):
    """Whether ``image`` of texture node ``node`` has pixels (else reported with ``fallback``);
    reports interpolations not in ``interpolations``, which are rendered as Linear."""
    w, h = (int(x) for x in image.size)
    if w <= 0 or h <= 0 or int(image.channels) <= 0:
        messages.add(f"{owner}: image '{image.name}' of {what} '{name}' has no "
                     f"pixels{fallback}")
        return False
    interpolation = getattr(node, "interpolation", 'Linear')
    if interpolation not in interpolations:
        messages.add(f"{owner}: {interpolation} interpolation of {what} '{name}' is "
                     f"not supported yet; rendered with Linear")
    return True


def _distribution_note(node, read, owner, what="GGX"):
    """Report a rough microfacet node whose distribution is not single-scattering GGX."""
    distribution = getattr(node, "distribution", 'GGX')
    if distribution not in {'GGX', 'SHARP'} and read.value(node, "Roughness") > 0:
        read.messages.add(f"{owner}: {distribution} distribution of node '{_node_name(node)}' "
                          f"is not supported yet; rendered as {what}")


def _shader_surface(source, owner, messages, depth=0):
    """Translate the shader node feeding a Surface socket (``source = (node, socket)``)."""
    if source is None:
        return _BLACK
    node, _ = source
    read = _NodeReader(owner, messages)
    kind = node.bl_idname
    if kind == 'ShaderNodeMixShader' and depth < 16:
        # Cycles weighs input 1 by 1 - Fac and input 2 by Fac (nested mixes multiply).
        fac = min(max(read.value(node, "Fac", 0.5), 0.0), 1.0)
        parts = [(1.0 - fac, _shader_surface(_follow_link(node.inputs[1]), owner, messages,
                                             depth + 1)),
                 (fac, _shader_surface(_follow_link(node.inputs[2]), owner, messages,
                                       depth + 1))]
        return mix_surfaces(parts, owner, messages)
    texture = _surface_texture(node, owner, messages)
    if kind == 'ShaderNodeBsdfPrincipled':
        read.ignored_if_linked(node, "Normal", "the normal input")
        return _principled_surface(node, read, owner, texture)
    surface = _node_surface(node, read, owner, messages)
    if texture is not None:
        surface = surface._replace(texture=texture[0], texture_mode=texture[1])
    return surface


def _node_surface(node, read, owner, messages):
    """Translate one shader node other than a Mix Shader or a Principled BSDF."""
    kind = node.bl_idname
    name = _node_name(node)
    if kind not in {'ShaderNodeMixShader', 'ShaderNodeEmission'}:
        read.ignored_if_linked(node, "Normal", "the normal input")

    if kind == 'ShaderNodeBsdfDiffuse':
        if read.value(node, "Roughness") > 0:
            messages.add(f"{owner}: Oren-Nayar roughness of node '{name}' is not "
                         f"supported yet; rendered as Lambertian")
        return _diffuse(read.color(node, "Color"))

    if kind == 'ShaderNodeEmission':
        emission = read.color(node, "Color") * read.value(node, "Strength")
        return Surface(MAT_DIFFUSE, np.zeros(3), emission)

    if kind in {'ShaderNodeBsdfGlossy', 'ShaderNodeBsdfAnisotropic'}:
        _distribution_note(node, read, owner)
        if read.value(node, "Anisotropy") != 0:
            messages.add(f"{owner}: anisotropy of node '{name}' is not supported yet; "
                         f"rendered isotropic")
        return Surface(MAT_CONDUCTOR, read.color(node, "Color", (1.0, 1.0, 1.0)), np.zeros(3),
                       roughness=read.value(node, "Roughness", 0.5))

    if kind in {'ShaderNodeBsdfGlass', 'ShaderNodeBsdfRefraction'}:
        _distribution_note(node, read, owner)
        if kind == 'ShaderNodeBsdfRefraction':
            messages.add(f"{owner}: node '{name}' (refraction only) is not supported yet; "
                         f"rendered as glass (with Fresnel reflection)")
        color = read.color(node, "Color", (1.0, 1.0, 1.0))
        return Surface(MAT_DIELECTRIC, color, np.zeros(3),
                       roughness=read.value(node, "Roughness", 0.0),
                       ior=read.value(node, "IOR", 1.5), transmission=1.0, specular_tint=color)

    if kind == 'ShaderNodeBsdfTransparent':
        _transparent_note(owner, messages, f"node '{name}'")
        return _transparent(read.color(node, "Color", (1.0, 1.0, 1.0)))

    messages.add(f"{owner}: node '{name}' is not supported yet; rendered as diffuse")
    if node.inputs.get("Color") is not None and node.inputs["Color"].type == 'RGBA':
        return _diffuse(read.color(node, "Color"))
    return _diffuse(DEFAULT_SURFACE_COLOR)


def _transparent(color):
    """Transparent BSDF: a smooth dielectric of IOR 1 (straight through, tinted by ``color``)."""
    color = np.asarray(color, np.float64)
    return Surface(MAT_DIELECTRIC, color, np.zeros(3), roughness=0.0, ior=1.0,
                   transmission=1.0, specular_tint=color)


def _transparent_note(owner, messages, what):
    messages.add(f"{owner}: {what} is rendered as a pass-through (glass of IOR 1) that still "
                 f"blocks shadow rays and counts as a transmission bounce")


def _surface_key(surface):
    """What makes two plain surfaces the same BSDF (to merge equal mixture components)."""
    return (surface.kind, tuple(np.round(surface.base_color, 9)), surface.roughness,
            surface.ior, surface.specular_ior_level, tuple(np.round(surface.specular_tint, 9)),
            id(surface.texture), surface.texture_mode)


def mix_surfaces(parts, owner, messages):
    """The mixture of ``parts = [(weight, Surface), ...]`` (weights summing to 1).

    Nested mixtures are flattened (their weights multiply); emission is the weighted sum;
    components of zero weight are dropped and equal ones merged. A mixture of untextured
    diffuse surfaces is the diffuse surface of the blended colour (Lambert is linear in its
    albedo); a mixture left with one component is that component.
    """
    flat = []
    emission = np.zeros(3)
    for weight, surface in parts:
        emission = emission + weight * np.asarray(surface.emission, np.float64)
        inner = surface.components or ((1.0, surface),)
        for w, component in inner:
            if weight * w > 0:
                flat.append((weight * w, component._replace(emission=np.zeros(3),
                                                            components=())))
    merged = {}
    for w, component in flat:
        key = _surface_key(component)
        w0, _ = merged.get(key, (0.0, component))
        merged[key] = (w0 + w, component)
    flat = sorted(merged.values(), key=lambda wc: -wc[0])
    if not flat:
        return _BLACK._replace(emission=emission)
    if all(c.kind == MAT_DIFFUSE and c.texture is None for _, c in flat):
        color = sum(w * np.asarray(c.base_color, np.float64) for w, c in flat)
        return _diffuse(color / sum(w for w, _ in flat), emission)
    if len(flat) == 1:
        return flat[0][1]._replace(emission=emission)
    if len(flat) > MAX_COMPONENTS:
        messages.add(f"{owner}: mixtures of more than {MAX_COMPONENTS} BSDFs are not "
                     f"supported yet; the {MAX_COMPONENTS} largest are kept")
        flat = flat[:MAX_COMPONENTS]
    total = sum(w for w, _ in flat)
    components = tuple((w / total, c) for w, c in flat)
    main = components[0][1]
    return main._replace(emission=emission, texture=None, components=components)


def _principled_surface(node, read, owner, texture=None):
    """Principled BSDF -> a mixture of conductor (metallic), dielectric (transmission), coat
    over diffuse and, for Alpha < 1, a transparent pass-through.

    Weights as Cycles' Principled: transparent ``1 - a``, then of the rest ``a``: metal ``m``,
    glass ``(1 - m) t`` and the opaque dielectric ``(1 - m)(1 - t)``; emission is scaled by
    ``a`` too. ``texture`` (pixels, modes) drives the base colour of every component but the
    transparent one.
    """
    messages = read.messages
    name = _node_name(node)
    base = read.color(node, "Base Color", DEFAULT_SURFACE_COLOR)
    emission = read.color(node, "Emission Color") * read.value(node, "Emission Strength")
    metallic = min(max(read.value(node, "Metallic"), 0.0), 1.0)
    transmission = min(max(read.value(node, "Transmission Weight"), 0.0), 1.0)
    roughness = min(max(read.value(node, "Roughness", 0.5), 0.0), 1.0)
    ior = read.value(node, "IOR", 1.5)
    level = min(max(read.value(node, "Specular IOR Level", 0.5), 0.0), 1.0)
    tint = read.color(node, "Specular Tint", (1.0, 1.0, 1.0))
    lobes = [label for socket, label in _PRINCIPLED_LOBES if read.value(node, socket) > 0]
    if lobes:
        messages.add(f"{owner}: {', '.join(lobes)} of node '{name}' "
                     f"{'is' if len(lobes) == 1 else 'are'} not supported yet; ignored")
    alpha = min(max(read.value(node, "Alpha", 1.0), 0.0), 1.0)
    if read.value(node, "Anisotropic") != 0:
        messages.add(f"{owner}: anisotropy of node '{name}' is not supported yet; "
                     f"rendered isotropic")
    distribution = getattr(node, "distribution", 'GGX')
    if distribution != 'GGX' and roughness > 0:
        messages.add(f"{owner}: {distribution} distribution of node '{name}' is not "
                     f"supported yet; rendered as GGX")

    weights = {MAT_CONDUCTOR: metallic, MAT_DIELECTRIC: (1 - metallic) * transmission,
               MAT_LAYERED: (1 - metallic) * (1 - transmission)}
    if metallic > 0 and np.any(tint != 1.0):
        messages.add(f"{owner}: metallic specular tint (F82) of node '{name}' is not "
                     f"supported yet; ignored")
    if weights[MAT_DIELECTRIC] > 0 and level != 0.5:
        messages.add(f"{owner}: specular IOR level of transmissive node '{name}' is not "
                     f"supported yet; ignored")
    pixels, mode = texture if texture is not None else (None, ("Linear", "REPEAT"))
    parts = [(w, Surface(kind, base, np.zeros(3), roughness, ior,
                         float(kind == MAT_CONDUCTOR), float(kind == MAT_DIELECTRIC), level,
                         tint, pixels, mode))
             for kind, w in weights.items() if w > 0]
    parts = [(alpha * w, surface) for w, surface in parts]
    if alpha < 1.0:
        _transparent_note(owner, messages, f"alpha of node '{name}'")
        parts.append((1.0 - alpha, _transparent((1.0, 1.0, 1.0))))
    surface = mix_surfaces(parts, owner, messages)
    return surface._replace(emission=alpha * emission, metallic=metallic,
                            transmission=transmission)


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
    if not _uses_nodes(world) or world.node_tree is None:
        return np.asarray(world.color[:3], np.float64), None
    output = _active_output(world.node_tree, 'ShaderNodeOutputWorld')
    if output is None:
        return np.zeros(3), None
    socket = output.inputs.get("Volume")
    if socket is not None and _follow_link(socket) is not None:
        messages.add(f"{owner}: volume is not supported yet; ignored")
    source = _follow_link(output.inputs["Surface"])
    if source is None:
        return np.zeros(3), None
    node, _ = source
    read = _NodeReader(owner, messages)
    if node.bl_idname in {'ShaderNodeBackground', 'ShaderNodeEmission'}:
        strength = read.value(node, "Strength")
        color_source = _follow_link(node.inputs["Color"])
        if color_source is not None and color_source[0].bl_idname == 'ShaderNodeTexEnvironment':
            pixels = _environment_pixels(color_source[0], owner, messages)
            if pixels is not None:
                return np.zeros(3), (pixels * np.float32(strength)).astype(np.float32)
            return _as_color(node.inputs["Color"].default_value) * strength, None
        return read.color(node, "Color") * strength, None
    messages.add(f"{owner}: node '{_node_name(node)}' is not supported yet; rendered black")
    return np.zeros(3), None


def _as_color(value):
    return np.asarray(_as_size(value, 3), np.float64)


# Colour spaces whose float values are scene-linear Rec.709 (Blender's working space) already.
_LINEAR_COLORSPACES = {'Linear Rec.709', 'Linear', 'Non-Color'}


def _environment_pixels(node, owner, messages):
    """RGB ``(h, w, 3)`` float32 of an Environment Texture node's image, or None (reported).

    Only what Cycles computes without a Mapping: equirectangular projection, nothing linked to
    the Vector input. Images in a linear Rec.709 colour space are used as they are; 8-bit sRGB
    images are decoded with the sRGB transfer function; other colour spaces are used as stored
    (reported once). Interpolation other than Linear (Cycles' default) is reported.
    """
    name = _node_name(node)
    fallback = "; using the Background colour"
    if node.image is None:
        messages.add(f"{owner}: environment texture '{name}' has no image{fallback}")
        return None
    if getattr(node, "projection", 'EQUIRECTANGULAR') != 'EQUIRECTANGULAR':
        messages.add(f"{owner}: {node.projection.lower().replace('_', ' ')} projection of "
                     f"environment texture '{name}' is not supported yet{fallback}")
        return None
    vector = node.inputs.get("Vector")
    if vector is not None and _follow_link(vector) is not None:
        messages.add(f"{owner}: the Vector input of environment texture '{name}' (a mapping) "
                     f"is not supported yet{fallback}")
        return None
    image = node.image
    if not _image_usable(node, image, "environment texture", name, owner, fallback, messages):
        return None
    return _image_rgb(image, owner, messages)


def _image_rgb(image, owner, messages):
    """Linear RGB ``(h, w, 3)`` float32 of an image (row 0 at the bottom), read with
    ``foreach_get``: linear colour spaces as they are, 8-bit sRGB decoded, others reported."""
    w, h = (int(x) for x in image.size)
    channels = int(image.channels)
    buf = np.empty(w * h * channels, np.float32)
    image.pixels.foreach_get(buf)
    buf = buf.reshape(h, w, channels)
    rgb = buf[..., :3] if channels >= 3 else np.repeat(buf[..., :1], 3, axis=2)
    rgb = np.ascontiguousarray(rgb)
    space = image.colorspace_settings.name
    if not image.is_float and space == 'sRGB':
        # 8-bit sRGB pixels are stored encoded; Cycles decodes them to linear.
        rgb = np.where(rgb <= 0.04045, rgb / 12.92,
                       ((np.maximum(rgb, 0.04045) + 0.055) / 1.055) ** 2.4).astype(np.float32)
    elif space not in _LINEAR_COLORSPACES:
        messages.add(f"{owner}: colour space '{space}' of image '{image.name}' is not "
                     f"converted yet; its values are used as linear Rec.709")
    return rgb


class MaterialTable:
    """Rows of :class:`core.scene.Materials`: one per distinct Blender material used, plus the
    component rows of the mixtures among them (after their mixture row)."""

    def __init__(self, messages):
        self.messages = messages
        self._rows = {}
        self.names = []
        self.surfaces = []
        self.mixes = []  # per row: ((component row, weight), ...)

    def row(self, material):
        """Row index of ``material`` (None: Cycles' default surface), adding it if new."""
        key = material.original.as_pointer() if material is not None else 0
        index = self._rows.get(key)
        if index is None:
            surface = material_surface(material, self.messages)
            name = material.name if material is not None else DEFAULT_SURFACE_NAME
            index = self._add(name, surface)
            self._rows[key] = index
            if surface.components:
                self.mixes[index] = tuple(
                    (self._add(f"{name} [{i}]", component), weight)
                    for i, (weight, component) in enumerate(surface.components))
        return index

    def _add(self, name, surface):
        index = len(self.names)
        self.names.append(name)
        self.surfaces.append(surface._replace(
            base_color=np.clip(surface.base_color, 0.0, 1.0),
            emission=np.maximum(surface.emission, 0.0),
            specular_tint=np.clip(surface.specular_tint, 0.0, 1.0)))
        self.mixes.append(((index, 1.0),))
        return index

    def build(self):
        if not self.names:
            return Materials.from_lists([], np.zeros((0, 3)), np.zeros((0, 3)))
        col = {field: [getattr(s, field) for s in self.surfaces] for field in Surface._fields}
        width = max(len(mix) for mix in self.mixes)
        mix_rows = np.zeros((len(self.names), width), np.int32)
        mix_weights = np.zeros((len(self.names), width), np.float32)
        for index, mix in enumerate(self.mixes):
            rows, weights = zip(*mix)
            mix_rows[index] = rows[0]  # padding: the first component, of weight 0
            mix_rows[index, :len(rows)] = rows
            mix_weights[index, :len(rows)] = np.asarray(weights) / np.sum(weights)
        return Materials.from_lists(
            self.names, col["base_color"], col["emission"], kinds=col["kind"],
            roughness=col["roughness"], ior=col["ior"], metallic=col["metallic"],
            transmission=col["transmission"], specular_ior_level=col["specular_ior_level"],
            specular_tint=col["specular_tint"], texture=self._texture_index()[0],
            mix_rows=mix_rows, mix_weights=mix_weights)

    def _texture_index(self):
        """``(m,) int32`` index into the distinct textures per row (-1 for untextured rows),
        and those textures as ``[(pixels, (interpolation, extension)), ...]``."""
        index, distinct, found = [], [], {}
        for s in self.surfaces:
            if s.texture is None:
                index.append(-1)
                continue
            key = (id(s.texture), s.texture_mode)
            if key not in found:
                found[key] = len(distinct)
                distinct.append((s.texture, s.texture_mode))
            index.append(found[key])
        return np.asarray(index, np.int32), distinct

    @property
    def textures(self):
        """Distinct base colour images in order of first use (``Scene.textures``)."""
        return [pixels for pixels, _ in self._texture_index()[1]]

    @property
    def texture_modes(self):
        """``(interpolations, extensions)`` of :attr:`textures` (``Scene.texture_*``)."""
        modes = [mode for _, mode in self._texture_index()[1]]
        return [m[0] for m in modes], [m[1] for m in modes]

    def texture_rows(self):
        """``(m,) int32`` index into :attr:`textures` per row, -1 for untextured rows."""
        return self._texture_index()[0]

    def textured(self, rows):
        """Whether any of the material rows ``rows`` (or their components) has a texture."""
        return any(self.surfaces[c].texture is not None
                   for r in np.unique(rows) for c, _ in self.mixes[int(r)])


# --------------------------------------------------------------------------- meshes


def _visibility_bits(ob):
    bits = 0
    for attr, bit in (("visible_camera", VIS_CAMERA), ("visible_diffuse", VIS_DIFFUSE),
                      ("visible_glossy", VIS_GLOSSY), ("visible_transmission", VIS_TRANSMISSION),
                      ("visible_shadow", VIS_SHADOW)):
        if getattr(ob, attr, True):
            bits |= bit
    return bits


@contextmanager
def evaluated_mesh(ob):
    """The evaluated mesh of ``ob`` (modifiers applied), or None; freed when the block ends.

    Every per-mesh array (positions, corner normals, corner UVs) is read from this one
    evaluation, so a mesh is never evaluated twice.
    """
    try:
        mesh = ob.to_mesh()
    except RuntimeError:
        mesh = None
    try:
        yield mesh
    finally:
        if mesh is not None:
            ob.to_mesh_clear()


def mesh_arrays(mesh):
    """Local-space triangles of an evaluated mesh.

    Returns
    -------
    vertices : (v, 3) float32
    triangles : (t, 3) int32
    slot : (t,) int32
        Material slot index per triangle.

    or None when the mesh has no triangles.
    """
    n_tris = len(mesh.loop_triangles)
    n_verts = len(mesh.vertices)
    if n_tris == 0 or n_verts == 0:
        return None
    verts = np.empty(n_verts * 3, np.float32)
    position = mesh.attributes.get("position")
    if position is not None and position.data_type == 'FLOAT_VECTOR':
        position.data.foreach_get("vector", verts)
    else:
        mesh.vertices.foreach_get("co", verts)
    tris = np.empty(n_tris * 3, np.int32)
    mesh.loop_triangles.foreach_get("vertices", tris)
    slot = np.zeros(n_tris, np.int32)
    mat_attr = mesh.attributes.get("material_index")
    if mat_attr is not None and mat_attr.domain == 'FACE' and mat_attr.data_type == 'INT':
        face_mat = np.empty(len(mesh.polygons), np.int32)
        mat_attr.data.foreach_get("value", face_mat)
        tri_face = np.empty(n_tris, np.int32)
        mesh.loop_triangle_polygons.foreach_get("value", tri_face)
        slot = face_mat[tri_face]
    return verts.reshape(-1, 3), tris.reshape(-1, 3), slot


def mesh_corner_normals(mesh):
    """Object-space shading normals at the corners of an evaluated mesh's loop triangles.

    Blender 4.1+ ``Mesh.corner_normals`` (smooth faces, sharp edges, custom normals), gathered by
    ``loop_triangles`` loops. Returns a ``(t, 3, 3)`` float32 array, or None when the mesh is
    flat-shaded throughout (``normals_domain == 'FACE'``: the geometric normal is the shading
    normal) or the Blender version has no corner normals.
    """
    n_tris = len(mesh.loop_triangles)
    if n_tris == 0 or not hasattr(mesh, "corner_normals"):
        return None
    if getattr(mesh, "normals_domain", 'CORNER') == 'FACE':
        return None
    normals = np.empty(len(mesh.corner_normals) * 3, np.float32)
    mesh.corner_normals.foreach_get("vector", normals)
    loops = np.empty(n_tris * 3, np.int32)
    mesh.loop_triangles.foreach_get("loops", loops)
    return normals.reshape(-1, 3)[loops].reshape(n_tris, 3, 3)


def _normals_to_world(normals, matrix):
    """Object-space normals ``(..., 3)`` to world space (inverse transpose), unit length."""
    m = np.asarray(matrix, np.float64)[:3, :3]
    try:
        inv_t = np.linalg.inv(m).T
    except np.linalg.LinAlgError:
        inv_t = m
    n = normals.astype(np.float64) @ inv_t.T
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    return (n / np.where(length > 0, length, 1.0)).astype(np.float32)


def _concat_corner_normals(chunks, vertices, triangles):
    """One ``(t, 3, 3)`` corner-normal table for the scene, or None if every mesh is flat.

    ``chunks`` holds one entry per exported object (world-space normals or None); flat objects
    get their face normals at every corner.
    """
    if all(c is None for c, _ in chunks):
        return None
    tri = vertices.astype(np.float64)[triangles]
    face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).astype(np.float32)
    out = np.repeat(face[:, None, :], 3, axis=1)
    start = 0
    for c, count in chunks:
        if c is not None:
            out[start:start + count] = c
        start += count
    return out


def mesh_corner_uvs(mesh, name, messages):
    """``(t, 3, 2) float32`` active-UV-map coordinates at the corners of an evaluated mesh's
    loop triangles (the order of :func:`mesh_arrays`), or None without triangles."""
    n_tris = len(mesh.loop_triangles)
    if n_tris == 0:
        return None
    layer = mesh.uv_layers.active
    if layer is None:
        messages.add(f"Object '{name}': no UV map for its image textures; they are "
                     f"looked up at (0, 0)")
        return np.zeros((n_tris, 3, 2), np.float32)
    loops = np.empty(n_tris * 3, np.int32)
    mesh.loop_triangles.foreach_get("loops", loops)
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    layer.uv.foreach_get("vector", uv)
    return uv.reshape(-1, 2)[loops].reshape(n_tris, 3, 2)


def _instance_uvs(tri_mat, materials, uvs):
    """Corner UVs of one instance when its materials use textures, else None."""
    if not materials.textured(tri_mat):
        return None
    return uvs if uvs is not None and uvs.shape[0] == tri_mat.shape[0] else None


def _concat_uvs(uv_chunks, tri_counts):
    """``Scene.corner_uvs``: the instances' UVs (zero where untextured), or None if none."""
    if all(c is None for c in uv_chunks):
        return None
    return np.concatenate([np.zeros((n, 3, 2), np.float32) if c is None else c
                           for c, n in zip(uv_chunks, tri_counts)])


def _to_world(verts, matrix):
    m = np.asarray(matrix, np.float64)
    return (verts.astype(np.float64) @ m[:3, :3].T + m[:3, 3]).astype(np.float32)


# --------------------------------------------------------------------------- lights


def _light_rows(ob, matrix, messages):
    """Single-row :class:`core.scene.Lights` for a light object (empty list if it emits nothing)."""
    light = ob.data
    owner = f"Light '{ob.name}'"
    m = np.asarray(matrix, np.float64)
    color = np.asarray(light.color[:3], np.float64)
    if getattr(light, "use_temperature", False):
        color = color * np.asarray(light.temperature_color[:3], np.float64)
    energy = float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))
    visible_camera = bool(getattr(ob, "visible_camera", True))
    name = ob.name

    if not getattr(light, "normalize", True):
        messages.add(f"{owner}: 'Normalize' off is not supported yet; rendered normalized")
    if getattr(light, "use_nodes", False) and light.node_tree is not None:
        messages.add(f"{owner}: light nodes are not supported yet; ignored")
    hidden = [label for attr, label in (("visible_diffuse", "diffuse"),
                                        ("visible_glossy", "glossy"),
                                        ("visible_transmission", "transmission"))
              if not getattr(ob, attr, True)]
    if hidden:
        messages.add(f"{owner}: ray visibility ({', '.join(hidden)} off) is not supported for "
                     f"lights yet; ignored")
    if not getattr(light, "use_shadow", True):
        messages.add(f"{owner}: lights without shadows are not supported yet; shadows cast")

    # The light shines down its local -Z axis.
    down = -m[:3, 2]
    # Blender 4.1+ point and spot lights have Soft Falloff, on by default.
    soft = bool(getattr(light, "use_soft_falloff", False))
    if light.type == 'POINT':
        return core_lights.point_light(m[:3, 3], color, energy, light.shadow_soft_size, name,
                                       visible_camera, soft_falloff=soft)
    if light.type == 'SPOT':
        return core_lights.point_light(m[:3, 3], color, energy, light.shadow_soft_size, name,
                                       visible_camera, spot_direction=down,
                                       spot_size=light.spot_size, spot_blend=light.spot_blend,
                                       soft_falloff=soft)
    if light.type == 'SUN':
        return core_lights.sun_light(down, color, energy, light.angle, name, visible_camera)
    if light.type == 'AREA':
        if getattr(light, "spread", math.pi) < math.pi - 1e-6:
            messages.add(f"{owner}: area light spread is not supported yet; rendered with "
                         f"180 degrees")
        return core_lights.area_light(m, light.shape, light.size, light.size_y, color, energy,
                                      name, visible_camera)
    messages.add(f"{owner}: light type '{light.type}' is not supported; ignored")
    return None


# --------------------------------------------------------------------------- camera


def export_camera(scene, camera_object, messages):
    """:class:`core.scene.Camera` of ``camera_object`` at the scene's render resolution."""
    render = scene.render
    cam = camera_object.data
    width = render.resolution_x * render.resolution_percentage // 100
    height = render.resolution_y * render.resolution_percentage // 100
    cam_type = cam.type
    if cam_type not in {'PERSP', 'ORTHO'}:
        messages.add(f"Camera '{camera_object.name}': {cam_type} cameras are not supported yet; "
                     f"rendered as perspective")
        cam_type = 'PERSP'
    if getattr(cam, "dof", None) is not None and cam.dof.use_dof:
        messages.add(f"Camera '{camera_object.name}': depth of field is not supported yet; "
                     f"rendered with a pinhole camera")
    m = np.array(camera_object.matrix_world, np.float64)
    # Object scale must not scale the view: keep only rotation and translation.
    norms = np.linalg.norm(m[:3, :3], axis=0)
    m[:3, :3] /= np.where(norms > 0, norms, 1.0)
    return Camera(
        to_world=m,
        width=int(width),
        height=int(height),
        type=cam_type,
        lens=float(cam.lens),
        sensor_width=float(cam.sensor_width),
        sensor_height=float(cam.sensor_height),
        sensor_fit=cam.sensor_fit,
        shift_x=float(cam.shift_x),
        shift_y=float(cam.shift_y),
        clip_start=float(cam.clip_start),
        clip_end=float(cam.clip_end),
        ortho_scale=float(cam.ortho_scale),
        pixel_aspect_x=float(render.pixel_aspect_x),
        pixel_aspect_y=float(render.pixel_aspect_y),
    )


# --------------------------------------------------------------------------- scene


def export_scene(depsgraph, camera_object=None):
    """Translate an evaluated depsgraph into a :class:`core.scene.Scene`.

    Parameters
    ----------
    depsgraph : bpy.types.Depsgraph
        The render depsgraph (``RenderEngine.render``'s argument) or
        ``bpy.context.evaluated_depsgraph_get()``.
    camera_object : bpy.types.Object or None
        Camera to render from; defaults to the scene camera (pass
        ``RenderEngine.camera_override`` here).

    Returns
    -------
    core.scene.Scene
        World-space triangles, materials, lights, world color, camera, and the messages about
        what was approximated or ignored.

    Raises
    ------
    ExportError
        The scene has no camera.
    """
    scene = depsgraph.scene
    messages = Messages()
    camera_object = camera_object or scene.camera
    if camera_object is None:
        raise ExportError(NO_CAMERA_MESSAGE)
    camera_object = camera_object.evaluated_get(depsgraph)
    if camera_object.type != 'CAMERA':
        raise ExportError(f"Sampling Lab: the scene camera '{camera_object.name}' is not a "
                          f"camera object")
    camera = export_camera(scene, camera_object, messages)

    render = scene.render
    if render.use_motion_blur:
        messages.add("Motion blur is not supported yet; rendered without")
    if render.film_transparent:
        messages.add("Transparent film is not supported yet; the background is rendered opaque")

    materials = MaterialTable(messages)
    vert_chunks, tri_chunks, mat_chunks, vis_chunks = [], [], [], []
    n_verts = 0
    light_rows = []
    # Evaluated geometry shared by instances, keyed by (object, data) pointers: positions,
    # material rows, corner normals (None when flat) and corner UVs (None when untextured).
    cache = {}
    # Per exported instance: corner UVs, and world corner normals with the triangle count.
    uv_chunks, normal_chunks = [], []

    for inst in depsgraph.object_instances:
        ob = inst.object
        if not (inst.is_instance or inst.show_self):
            continue
        ob_type = ob.type
        if ob_type in SKIPPED_TYPES:
            continue
        matrix = np.array(inst.matrix_world, np.float64)
        if ob_type == 'LIGHT':
            row = _light_rows(ob, matrix, messages)
            if row is not None:
                light_rows.append(row)
            continue
        if ob_type not in MESH_TYPES:
            messages.add(f"Object '{ob.name}': {ob_type.lower()} objects are not supported yet; "
                         f"ignored")
            continue
        if getattr(ob, "is_holdout", False):
            messages.add(f"Object '{ob.name}': holdout is not supported yet; rendered as a "
                         f"regular object")
        if getattr(ob, "is_shadow_catcher", False):
            messages.add(f"Object '{ob.name}': shadow catcher is not supported yet; rendered as "
                         f"a regular object")

        key = (ob.as_pointer(), ob.data.as_pointer() if ob.data is not None else 0)
        entry = cache.get(key)
        if entry is None:
            entry = False
            with evaluated_mesh(ob) as mesh:
                arrays = None if mesh is None else mesh_arrays(mesh)
                if arrays is not None:
                    verts, tris, slot = arrays
                    slots = [materials.row(s.material) for s in ob.material_slots]
                    if not slots:
                        slots = [materials.row(None)]
                    # Blender clamps out-of-range material indices to the last slot.
                    table = np.asarray(slots, np.int32)
                    tri_mat = table[np.clip(slot, 0, len(slots) - 1)]
                    uvs = (mesh_corner_uvs(mesh, ob.name, messages)
                           if materials.textured(tri_mat) else None)
                    entry = (verts, tris, tri_mat, mesh_corner_normals(mesh), uvs)
            cache[key] = entry
        if entry is False:
            continue
        verts, tris, tri_mat, corner, uvs = entry
        vert_chunks.append(_to_world(verts, matrix))
        tri_chunks.append(tris + n_verts)
        mat_chunks.append(tri_mat)
        vis_chunks.append(np.full(tris.shape[0], _visibility_bits(ob), np.int32))
        uv_chunks.append(_instance_uvs(tri_mat, materials, uvs))
        n_verts += verts.shape[0]
        normal_chunks.append((None if corner is None else _normals_to_world(corner, matrix),
                              tris.shape[0]))

    if vert_chunks:
        vertices = np.concatenate(vert_chunks)
        triangles = np.concatenate(tri_chunks)
        material = np.concatenate(mat_chunks)
        visibility = np.concatenate(vis_chunks)
    else:
        vertices = np.zeros((0, 3), np.float32)
        triangles = np.zeros((0, 3), np.int32)
        material = np.zeros(0, np.int32)
        visibility = np.zeros(0, np.int32)

    world_color, world_map = world_radiance(scene.world, messages)
    return Scene(
        vertices=vertices,
        triangles=triangles,
        material=material,
        materials=materials.build(),
        lights=Lights.concat(light_rows),
        camera=camera,
        world_color=world_color,
        world_map=world_map,
        visibility=visibility,
        messages=messages.items,
        textures=materials.textures,
        texture_interpolation=materials.texture_modes[0],
        texture_extension=materials.texture_modes[1],
        corner_uvs=_concat_uvs(uv_chunks, [t.shape[0] for t in tri_chunks]),
        corner_normals=_concat_corner_normals(normal_chunks, vertices, triangles),
    )
