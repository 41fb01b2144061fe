"""Normal Map node (tangent space): the shading normal perturbed by an image, as Cycles does.

Cycles' ``svm_node_normal_map`` (``kernel/svm/tex_coord.h``; behaviour matched, the code is
ours) decodes the colour ``c`` of the map as ``m = 2 c - 1`` and builds the perturbed normal in
the frame of the *interpolated, unnormalised* per-corner tangent ``T`` (MikkTSpace, from the
active UV map), the interpolated bitangent sign ``s`` and the interpolated, unnormalised
smooth normal ``n`` (the geometric normal on flat faces)::

    B = s (n x T),    N = normalize(m_x T + m_y B + m_z n)

with the node's Strength ``k`` applied to the decoded colour first, in tangent space (Blender
4.0 and later, checked in the 5.0 source; 3.x blended the world normals linearly)::

    m_x <- k m_x,    m_y <- k m_y,    m_z <- 1 + (m_z - 1) clamp(k, 0, 1)

so that ``k = 0`` gives the unperturbed ``n`` and ``k = 1`` the map; a zero or non-finite
result keeps the unmapped shading normal ``ns``.
Everything is in world space here: the exporter moves tangents to world space with the
object's matrix, which is what Cycles' object-space construction gives for rotations, uniform
scales and translations (not under a non-uniform scale, where Cycles' normal transform and our
vector transform of the tangent differ).
"""

from __future__ import annotations

import numpy as np

from .textures import material_texture_values


def hit_tangents(corner_tangents, prim, u, v):
    """Interpolated tangent and bitangent sign at barycentrics ``u, v (k,)`` of ``prim (k,)``.

    Parameters
    ----------
    corner_tangents : (t, 3, 4) float32
        Per-corner world-space tangent (xyz) and bitangent sign (w).

    Returns
    -------
    tangent : (k, 3) float64
        Barycentric blend of the corner tangents, not normalised (as Cycles).
    sign : (k,) float64
        Blend of the corner signs (+-1 on a triangle that is not mirrored in UV).
    """
    c = corner_tangents[prim].astype(np.float64)
    u = np.asarray(u, np.float64)[:, None]
    v = np.asarray(v, np.float64)[:, None]
    t = (1.0 - u - v) * c[:, 0] + u * c[:, 1] + v * c[:, 2]
    return t[:, :3], t[:, 3]


def _normalize(x):
    """Rows of ``x (k, 3)`` scaled to unit length, and whether each was non-zero."""
    length = np.linalg.norm(x, axis=1)
    good = length > 1e-12
    return x / np.where(good, length, 1.0)[:, None], good


def tangent_space_normals(color, tangent, sign, normal, strength=None):
    """Cycles' tangent-space decoding: ``normalize(m_x T + m_y s (n x T) + m_z n)``.

    Parameters
    ----------
    color : (k, 3) float64
        Normal map colours (Non-Color data), ``m = 2 color - 1``.
    tangent : (k, 3) float64
        Interpolated tangents ``T`` (not normalised).
    sign : (k,) float64
        Interpolated bitangent signs ``s``.
    normal : (k, 3) float64
        Interpolated smooth normals ``n`` (not normalised), or the geometric normal.
    strength : (k,) float64, optional
        The node's Strength ``k``, applied to ``m`` as :func:`apply_strength` (None: 1).

    Returns
    -------
    N : (k, 3) float64
        Unit normals; zero rows where the combination vanishes.
    """
    m = 2.0 * np.asarray(color, np.float64) - 1.0
    if strength is not None:
        m = apply_strength(m, strength)
    bitangent = sign[:, None] * np.cross(normal, tangent)
    n = m[:, :1] * tangent + m[:, 1:2] * bitangent + m[:, 2:] * normal
    n, good = _normalize(n)
    return n * good[:, None]


def apply_strength(m, strength):
    """Blender 4.0+'s Strength ``k (k,)`` of a tangent-space map on decoded colours ``m (k, 3)``:
    ``(k m_x, k m_y, 1 + (m_z - 1) clamp(k, 0, 1))`` (Cycles' ``svm_node_normal_map``)."""
    k = np.asarray(strength, np.float64)
    out = np.array(m, np.float64)
    out[:, 0] *= k
    out[:, 1] *= k
    out[:, 2] = 1.0 + (out[:, 2] - 1.0) * np.clip(k, 0.0, 1.0)
    return out


def normal_mapped(scene, prim, u, v, normal, ns):
    """Shading normals of hits ``prim, u, v (k,)`` with their materials' normal maps applied.

    Parameters
    ----------
    scene : core.scene.Scene
        ``materials.normal_texture`` names the map of each row (-1: none) and
        ``materials.normal_strength`` its Strength; ``corner_tangents`` the frames.
    normal : (k, 3) float64
        Interpolated smooth normals, not normalised, on the front side of the geometric
        normal (Cycles' ``n`` above).
    ns : (k, 3) float64
        The unit shading normals without the map (``normalize(normal)``).

    Returns
    -------
    (k, 3) float64
        ``ns`` with the rows of normal-mapped materials replaced (``ns`` itself when the scene
        has no normal maps).
    """
    tangents = getattr(scene, "corner_tangents", None)
    if tangents is None or prim.size == 0:
        return ns
    material = scene.material[prim]
    rows, color = material_texture_values(scene, scene.materials.normal_texture, material,
                                          prim, u, v)
    if rows.size == 0:
        return ns
    tangent, sign = hit_tangents(tangents, prim[rows], u[rows], v[rows])
    mapped = tangent_space_normals(color, tangent, sign, normal[rows],
                                   scene.materials.normal_strength[material[rows]])
    good = np.all(np.isfinite(mapped), axis=1) & (np.linalg.norm(mapped, axis=1) > 0.5)
    out = ns.copy()
    out[rows] = np.where(good[:, None], mapped, ns[rows])
    return out
