"""Mesh-like objects -> the scene's world-space triangles, with per-triangle material rows and
ray visibility, corner shading normals, corner UVs and the corner tangents of anisotropic
materials (:mod:`.anisotropy`).

Every array is copied with ``foreach_get`` and moved to world space with one matrix product per
instance; there is no Python loop over vertices or triangles. :class:`Geometry` gathers the
instances and evaluates each object's mesh once, however often it is instanced.
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np

from ...core.scene import (
    VIS_CAMERA,
    VIS_DIFFUSE,
    VIS_GLOSSY,
    VIS_SHADOW,
    VIS_TRANSMISSION,
)
from .anisotropy import AXES, object_tangents, texture_space
from .anisotropy import tangents_to_world as aniso_tangents_to_world
from .normal_maps import concat_tangents, mesh_corner_tangents, tangents_to_world

# Object types Blender can turn into a triangle mesh.
MESH_TYPES = {'MESH', 'CURVE', 'SURFACE', 'FONT', 'META'}


class Geometry:
    """The scene's triangles, gathered one object instance at a time.

    Parameters
    ----------
    materials : MaterialTable
        Numbers the materials of the objects' slots.
    messages : Messages
    """

    def __init__(self, materials, messages):
        self.materials = materials
        self.messages = messages
        # Evaluated geometry shared by instances, keyed by (object, data) pointers: positions,
        # material rows, corner normals (None when flat) and corner UVs (None when untextured);
        # None for an object without triangles.
        self._shared = {}
        self._vertices, self._triangles, self._material, self._visibility = [], [], [], []
        # Per instance: corner UVs, and world corner normals with the triangle count.
        self._uvs, self._normals = [], []
        # Per instance: world anisotropy tangents (None when isotropic) with the triangle count.
        self._aniso_tangents = []
        self._tangents = []  # per instance: world UV tangents, or None without normal maps
        self._n_verts = 0

    def add(self, ob, matrix):
        """Add one instance of the mesh-like object ``ob`` placed by ``matrix (4, 4)``."""
        if getattr(ob, "is_holdout", False):
            self.messages.add(f"Object '{ob.name}': holdout is not supported yet; rendered as a "
                              f"regular object")
        if getattr(ob, "is_shadow_catcher", False):
            self.messages.add(f"Object '{ob.name}': shadow catcher is not supported yet; "
                              f"rendered as a regular object")
        key = (ob.as_pointer(), ob.data.as_pointer() if ob.data is not None else 0)
        if key not in self._shared:
            self._shared[key] = self._evaluate(ob)
        if self._shared[key] is None:
            return
        verts, tris, tri_mat, corner, uvs, aniso, tangents = self._shared[key]
        self._vertices.append(_to_world(verts, matrix))
        self._triangles.append(tris + self._n_verts)
        self._material.append(tri_mat)
        self._visibility.append(np.full(tris.shape[0], _visibility_bits(ob), np.int32))
        self._uvs.append(_instance_uvs(tri_mat, self.materials, uvs))
        self._tangents.append(None if tangents is None else tangents_to_world(tangents, matrix))
        self._n_verts += verts.shape[0]
        self._normals.append((None if corner is None else _normals_to_world(corner, matrix),
                              tris.shape[0]))
        self._aniso_tangents.append(
            (None if aniso is None else aniso_tangents_to_world(aniso, matrix), tris.shape[0]))

    def _evaluate(self, ob):
        """``(vertices, triangles, material rows, corner normals, corner UVs, anisotropy
        tangents, corner UV tangents)`` of the evaluated mesh of ``ob`` in object space, or
        None when it has no triangles."""
        with evaluated_mesh(ob) as mesh:
            arrays = None if mesh is None else mesh_arrays(mesh)
            if arrays is None:
                return None
            verts, tris, slot = arrays
            tri_mat = self._triangle_materials(ob, slot)
            uvs = (mesh_corner_uvs(mesh, ob.name, self.messages)
                   if self.materials.textured(tri_mat) else None)
            axes = self.materials.tangent_axes(tri_mat)
            tangents = (mesh_corner_tangents(mesh, ob.name, self.messages)
                        if self.materials.normal_mapped(tri_mat) else None)
            uv_tangents = tangents
            if uv_tangents is None and np.any(axes == AXES['UV']):
                uv_tangents = mesh_corner_tangents(
                    mesh, ob.name, self.messages, "its UV Map tangent nodes",
                    "the radial tangent about Z is used")
            aniso = (object_tangents(verts, tris, axes, texture_space(mesh, verts), uv_tangents)
                     if axes.any() else None)
            corner = mesh_corner_normals(mesh)
            return verts, tris, tri_mat, corner, uvs, aniso, tangents

    def _triangle_materials(self, ob, slot):
        """``(t,) int32`` material rows of triangles with material slot indices ``slot``."""
        slots = [self.materials.row(s.material) for s in ob.material_slots]
        if not slots:
            slots = [self.materials.row(None)]
        # Blender clamps out-of-range material indices to the last slot.
        table = np.asarray(slots, np.int32)
        return table[np.clip(slot, 0, len(slots) - 1)]

    def arrays(self):
        """The triangle fields of :class:`core.scene.Scene`: ``vertices``, ``triangles``,
        ``material``, ``visibility``, ``corner_uvs``, ``corner_normals`` and
        ``aniso_tangents`` and ``corner_tangents``."""
        if self._vertices:
            vertices = np.concatenate(self._vertices)
            triangles = np.concatenate(self._triangles)
            material = np.concatenate(self._material)
            visibility = np.concatenate(self._visibility)
        else:
            vertices = np.zeros((0, 3), np.float32)
            triangles = np.zeros((0, 3), np.int32)
            material = np.zeros(0, np.int32)
            visibility = np.zeros(0, np.int32)
        return dict(
            vertices=vertices,
            triangles=triangles,
            material=material,
            visibility=visibility,
            corner_uvs=_concat_uvs(self._uvs, [t.shape[0] for t in self._triangles]),
            corner_normals=_concat_corner_normals(self._normals, vertices, triangles),
            aniso_tangents=_concat_aniso_tangents(self._aniso_tangents),
            corner_tangents=concat_tangents(self._tangents,
                                            [t.shape[0] for t in self._triangles]),
        )


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
    return _fill_rows(np.repeat(face[:, None, :], 3, axis=1), chunks)


def _concat_aniso_tangents(chunks):
    """One ``(t, 3, 3)`` corner-tangent table (zero for isotropic objects), or None."""
    if all(c is None for c, _ in chunks):
        return None
    return _fill_rows(np.zeros((sum(count for _, count in chunks), 3, 3), np.float32), chunks)


def _fill_rows(out, chunks):
    """``out`` with each ``(rows, count)`` chunk of ``chunks`` written over its own run of
    ``count`` rows, in order (None chunks keep ``out``'s rows)."""
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
    """Object-space ``verts (n, 3)`` to world space ``(n, 3)`` float32; NaN or infinite
    vertices stay non-finite without a warning (preparing the scene drops their triangles and
    says so)."""
    m = np.asarray(matrix, np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        return (verts.astype(np.float64) @ m[:3, :3].T + m[:3, 3]).astype(np.float32)
