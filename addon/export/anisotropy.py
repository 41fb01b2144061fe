"""Anisotropic reflection: the Principled BSDF's Anisotropic, Anisotropic Rotation and the
Glossy BSDF's Anisotropy, Rotation, and the tangents they need.

Materials get :class:`.materials.Surface` fields ``aniso_scale`` (``alpha_x = alpha k``,
``alpha_y = alpha / k``, :mod:`core.materials.anisotropic`), ``aniso_rotation`` (turns) and
``tangent_axis``. Meshes using such materials get per-corner tangents
(:attr:`core.scene.Scene.aniso_tangents`): Cycles connects an unlinked Tangent input to the
Geometry node's Tangent (``ShaderGraph::default_inputs``, ``primitive_tangent``), the radial
tangent ``(-(g_y - 1/2), g_x - 1/2, 0)`` about Z of the generated coordinates ``g`` (the
object's texture space), moved to the world by the object's normal matrix and projected on the
shading normal's plane at the hit; a Tangent node in Radial mode is the same about its X, Y or
Z axis (``svm_node_tangent``). Generated coordinates are read from the evaluated mesh (Cycles
takes them before deforming modifiers). A Tangent node in UV Map mode gives the MikkTSpace
tangents of the active UV map (:func:`.normal_maps.mesh_corner_tangents`, as Cycles'
``svm_node_tangent`` reads its tangent attribute), moved by the same normal matrix; another
UV map than the active one is reported, and a mesh without a UV map falls back to the radial
Z tangent.
"""

from __future__ import annotations

import numpy as np

from ...core.materials.anisotropic import glossy_scale, principled_scale
from .nodes import follow_link, node_name

# Axis codes of corner tangents: 0 for isotropic triangles.
# 'UV': the UV map's tangents (a Tangent node in UV Map mode).
AXES = {None: 0, 'X': 1, 'Y': 2, 'Z': 3, 'UV': 4}


def tangent_axis(node, owner, messages):
    """Axis ``'X'``, ``'Y'`` or ``'Z'`` of the radial tangent feeding ``node``'s Tangent, or
    ``'UV'`` for a Tangent node in UV Map mode."""
    socket = node.inputs.get("Tangent")
    source = None if socket is None else follow_link(socket)
    if source is None:
        return 'Z'
    tangent = source[0]
    if tangent.bl_idname == 'ShaderNodeTangent':
        if tangent.direction_type == 'RADIAL':
            return tangent.axis
        if getattr(tangent, "uv_map", ""):
            messages.add(f"{owner}: UV map '{tangent.uv_map}' of tangent node "
                         f"'{node_name(tangent)}' is not supported yet; the active UV map is "
                         f"used")
        return 'UV'
    messages.add(f"{owner}: the tangent of node '{node_name(node)}' from node "
                 f"'{node_name(tangent)}' is not supported yet; approximated by the radial "
                 f"tangent about Z")
    return 'Z'


def principled_anisotropy(node, read, owner):
    """:class:`.materials.Surface` fields of the Principled BSDF's anisotropy (empty when
    isotropic), for its metallic lobe and specular layer (its transmission is isotropic, as in
    Cycles)."""
    amount = min(max(read.value(node, "Anisotropic"), 0.0), 1.0)
    if amount <= 0:
        return {}
    return {"aniso_scale": float(principled_scale(amount)),
            "aniso_rotation": read.value(node, "Anisotropic Rotation"),
            "tangent_axis": tangent_axis(node, owner, read.messages)}


def glossy_anisotropy(node, read, owner):
    """:class:`.materials.Surface` fields of a Glossy BSDF's Anisotropy (empty when Cycles
    renders it isotropic: ``|anisotropy| <= 1e-4``)."""
    amount = read.value(node, "Anisotropy")
    if abs(amount) <= 1e-4:
        return {}
    return {"aniso_scale": float(glossy_scale(amount)),
            "aniso_rotation": read.value(node, "Rotation"),
            "tangent_axis": tangent_axis(node, owner, read.messages)}


def texture_space(mesh, verts):
    """``(centre, size)`` of the mesh's texture space (Blender's auto texture space: the
    bounding box), which maps positions to generated coordinates ``(co - centre) / (2 size)
    + 1/2``."""
    centre = np.asarray(getattr(mesh, "texspace_location", (0.0, 0.0, 0.0)), np.float64)
    size = np.asarray(getattr(mesh, "texspace_size", (1.0, 1.0, 1.0)), np.float64)
    if getattr(mesh, "use_auto_texspace", True) and len(verts):
        lo, hi = verts.min(axis=0), verts.max(axis=0)
        centre, size = 0.5 * (lo + hi), 0.5 * (hi - lo)
    return centre, np.where(np.abs(size) > 1e-12, size, 1.0)


def radial_tangents(verts, tris, axis_codes, space):
    """Object-space radial tangents ``(t, 3, 3)`` at the corners of ``tris``, about the axis of
    each triangle's code (:data:`AXES`; zero for code 0)."""
    centre, size = space
    g = (np.asarray(verts, np.float64) - centre) / (2.0 * size)   # generated - 1/2
    zero = np.zeros(len(g))
    per_axis = {1: np.stack([zero, -g[:, 2], g[:, 1]], 1),
                2: np.stack([-g[:, 2], zero, g[:, 0]], 1),
                3: np.stack([-g[:, 1], g[:, 0], zero], 1)}
    out = np.zeros((len(tris), 3, 3), np.float64)
    for code, radial in per_axis.items():
        rows = np.flatnonzero(axis_codes == code)
        out[rows] = radial[tris[rows]]
    return out


def object_tangents(verts, tris, axis_codes, space, uv_tangents):
    """Object-space corner tangents ``(t, 3, 3)``: radial (:func:`radial_tangents`), and the
    UV map's ``uv_tangents (t, 3, 4)`` (xyz used) on triangles of code ``AXES['UV']``; those
    take the radial Z tangent when ``uv_tangents`` is None (no UV map, reported)."""
    codes = np.asarray(axis_codes)
    uv = codes == AXES['UV']
    if uv_tangents is None:
        codes = np.where(uv, AXES['Z'], codes)
    out = radial_tangents(verts, tris, codes, space)
    if uv_tangents is not None and uv.any():
        out[uv] = uv_tangents[uv, :, :3]
    return out


def tangents_to_world(tangents, matrix):
    """``tangents (t, 3, 3)`` moved by the normal matrix of ``matrix (4, 4)`` (the inverse
    transpose, as Cycles' ``object_normal_transform``), float32."""
    m = np.asarray(matrix, np.float64)[:3, :3]
    try:
        normal_matrix = np.linalg.inv(m).T
    except np.linalg.LinAlgError:
        normal_matrix = np.zeros((3, 3))
    return (tangents.reshape(-1, 3) @ normal_matrix.T).reshape(-1, 3, 3).astype(np.float32)
