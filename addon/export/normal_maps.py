"""Normal Map and Bump nodes into a BSDF's Normal input -> a normal-map image and Strength, and
a height image with Distance and Strength, per material (:mod:`core.normal_maps` and
:mod:`core.bump` perturb the shading normal), and the UV tangents of meshes.

Modelled: a Normal Map node in Tangent Space on the active UV map, its Color from an Image
Texture (Non-Color data as stored; another colour space is decoded as Cycles does) or a
constant colour, its Strength; a Bump node whose Height is an Image Texture (its luminance),
with Strength, Distance, Invert, and a Normal Map (as above) or nothing in its own Normal.
Anything else linked to a Normal input is reported and ignored.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...core.scene import MAT_DIELECTRIC, MAT_DIFFUSE, MAT_LAYERED
from .nodes import NodeReader, follow_link, node_name
from .textures import _image_texture_pixels

# The colour a Normal Map node decodes to the unperturbed normal.
FLAT_COLOR = (0.5, 0.5, 1.0)


class NormalMap(NamedTuple):
    """What a material's Normal input gets: the map's pixels, lookup modes and Strength."""

    pixels: np.ndarray  # (h, w, 3) float32, row 0 at v = 0
    mode: tuple  # (interpolation, extension) of the image node
    strength: float


class Bump(NamedTuple):
    """A Bump node: its height image's pixels and lookup modes, Distance (negated by Invert)
    and Strength."""

    pixels: np.ndarray
    mode: tuple
    distance: float
    strength: float


def normal_input(node, owner, messages):
    """``(NormalMap or None, Bump or None)`` feeding the Normal input of BSDF ``node`` (None
    for what is not linked or is reported as not supported)."""
    socket = node.inputs.get("Normal")
    link = follow_link(socket) if socket is not None else None
    if link is None:
        return None, None
    src = link[0]
    if src.bl_idname == 'ShaderNodeBump':
        return normal_map_input(src, owner, messages), _bump(src, owner, messages)
    return normal_map_input(node, owner, messages), None


def _bump(src, owner, messages):
    """The :class:`Bump` of Bump node ``src``, or None (no height image; reported)."""
    height = src.inputs.get("Height")
    link = follow_link(height) if height is not None else None
    if link is None:
        return None  # a constant height: no bump
    if link[0].bl_idname != 'ShaderNodeTexImage':
        messages.add(f"{owner}: the height of bump node '{node_name(src)}' (node "
                     f"'{node_name(link[0])}') is not supported yet; ignored")
        return None
    pixels = _image_texture_pixels(link[0], link[1], owner, messages)
    if pixels is None:
        return None
    read = NodeReader(owner, messages)
    distance = read.value(src, "Distance", 1.0) * (-1.0 if getattr(src, "invert", False) else 1.0)
    return Bump(pixels[0], pixels[1], distance, read.value(src, "Strength", 1.0))


def normal_map_input(node, owner, messages):
    """The :class:`NormalMap` feeding the Normal input of ``node`` (a BSDF or a Bump node), or
    None (nothing linked, or reported as not supported)."""
    socket = node.inputs.get("Normal")
    link = follow_link(socket) if socket is not None else None
    if link is None:
        return None
    src = link[0]
    ignored = f"{owner}: the normal input of node '{node_name(node)}'"
    if src.bl_idname != 'ShaderNodeNormalMap':
        messages.add(f"{ignored} (node '{node_name(src)}') is not supported yet; ignored")
        return None
    space = getattr(src, "space", 'TANGENT')
    if space != 'TANGENT':
        messages.add(f"{ignored}: {space.lower().replace('_', ' ')} space of normal map "
                     f"'{node_name(src)}' is not supported yet; ignored")
        return None
    if getattr(src, "uv_map", ""):
        messages.add(f"{owner}: UV map '{src.uv_map}' of normal map '{node_name(src)}' is not "
                     f"supported yet; the active UV map is used")
    read = NodeReader(owner, messages)
    strength = read.value(src, "Strength", 1.0)
    color = _map_color(src, owner, messages, read)
    if color is None:
        return None
    return NormalMap(color[0], color[1], strength)


def _map_color(src, owner, messages, read):
    """``(pixels, mode)`` of the Color input of Normal Map node ``src``: an Image Texture's
    pixels, or a one-texel image of a constant colour; None for the flat colour or what is
    not supported (reported)."""
    color = src.inputs.get("Color")
    link = follow_link(color) if color is not None else None
    if link is not None and link[0].bl_idname == 'ShaderNodeTexImage':
        return _image_texture_pixels(link[0], link[1], owner, messages)
    value = read.color(src, "Color", FLAT_COLOR)
    if np.allclose(value, FLAT_COLOR):
        return None
    return np.asarray(value, np.float32).reshape(1, 1, 3), ("Closest", 'REPEAT')


def mixed_normal_input(parts, owner, messages):
    """The ``normal_map`` and ``bump`` :class:`Surface` fields of a mixture of ``parts =
    [(weight, Surface), ...]``: the core applies one per material, that of the heaviest part
    with one; reported when the parts differ (the transparent pass-through, which no normal
    changes, does not count)."""
    inputs = [(w, (s.normal_map, s.bump)) for w, s in parts if w > 0 and not _pass_through(s)]
    if not inputs:
        return {"normal_map": None, "bump": None}
    chosen = max(inputs, key=lambda wm: (wm[1] != (None, None), wm[0]))[1]
    if any(m[0] is not chosen[0] or m[1] is not chosen[1] for _, m in inputs):
        messages.add(f"{owner}: the shaders of a mix have different normal inputs; all are "
                     f"rendered with one of them")
    return {"normal_map": chosen[0], "bump": chosen[1]}


def bump_map_correction(material, surface):
    """Whether Cycles' Bump Map Correction (a material setting, on by default) applies to
    ``surface``: the setting is on and a normal map or bump perturbs the normal
    (:mod:`core.materials.bump_correction` shadows the diffuse lobes then)."""
    if surface.normal_map is None and surface.bump is None:
        return False
    return bool(getattr(getattr(material, "cycles", None), "use_bump_map_correction", False))


def _pass_through(surface):
    """Whether ``surface`` is a Transparent BSDF (an IOR 1 smooth dielectric)."""
    return (surface.kind == MAT_DIELECTRIC and surface.ior == 1.0 and surface.roughness == 0.0
            and not surface.components)


def mesh_corner_tangents(mesh, name, messages, user="its normal maps",
                         fallback="they are ignored"):
    """``(t, 3, 4) float32`` MikkTSpace tangents (xyz, object space) and bitangent signs (w)
    of the active UV map at the corners of an evaluated mesh's loop triangles, or None
    (reported, naming ``user`` and what is done instead, ``fallback``) without a UV map or
    where Blender cannot compute them."""
    n_tris = len(mesh.loop_triangles)
    layer = mesh.uv_layers.active
    if n_tris == 0 or layer is None:
        if n_tris:
            messages.add(f"Object '{name}': no UV map for {user}; {fallback}")
        return None
    try:
        mesh.calc_tangents(uvmap=layer.name)
    except RuntimeError as err:
        messages.add(f"Object '{name}': tangents for {user} could not be computed "
                     f"({str(err).strip()}); {fallback}")
        return None
    n_loops = len(mesh.loops)
    tangent = np.empty(n_loops * 3, np.float32)
    sign = np.empty(n_loops, np.float32)
    mesh.loops.foreach_get("tangent", tangent)
    mesh.loops.foreach_get("bitangent_sign", sign)
    loops = np.empty(n_tris * 3, np.int32)
    mesh.loop_triangles.foreach_get("loops", loops)
    out = np.concatenate([tangent.reshape(-1, 3), sign[:, None]], axis=1)
    return out[loops].reshape(n_tris, 3, 4)


def tangents_to_world(tangents, matrix):
    """Object-space corner tangents ``(t, 3, 4)`` to world space: the tangent as a vector (unit
    length), the sign flipped by a mirroring matrix (so that ``s (n x T)`` stays the
    transformed bitangent)."""
    m = np.asarray(matrix, np.float64)[:3, :3]
    t = tangents[..., :3].astype(np.float64) @ m.T
    length = np.linalg.norm(t, axis=-1, keepdims=True)
    t = t / np.where(length > 0, length, 1.0)
    sign = tangents[..., 3:] * (-1.0 if np.linalg.det(m) < 0 else 1.0)
    return np.concatenate([t, sign], axis=-1).astype(np.float32)


def concat_tangents(chunks, tri_counts):
    """``Scene.corner_tangents``: the instances' world tangents (zero where a mesh has no
    normal map), or None when none has."""
    if all(c is None for c in chunks):
        return None
    return np.concatenate([np.zeros((n, 3, 4), np.float32) if c is None else c
                           for c, n in zip(chunks, tri_counts)])
