"""Adaptive subdivision: split the patches where the solved radiosity changes fast, and solve
again.

After a solve, every patch's *gradient* is the largest difference between its own radiosity
(luminance) and its Gouraud corners (the means of the patches around each corner), relative to
the brightest patch. Sub-triangles whose either side exceeds ``threshold`` are split at their
edge midpoints into four (corner 0, 1, 2 and middle children, each with the parent's
orientation), and the system is solved again on the new mesh (:func:`.system.solve_scene`
does at most :data:`ROUNDS` rounds). The split patches form a quadtree below each grid
sub-triangle, which :meth:`.mesh.PatchMesh.locate` descends.

Where split patches meet unsplit ones the corners do not match (T-vertices): Gouraud display
is continuous only within each level. Radiosity stays biased, with the bias concentrated
where it was largest now smaller.
"""

from __future__ import annotations

import numpy as np

from .mesh import PatchMesh, _gouraud_table

ROUNDS = 2
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def gradients(mesh, B):
    """``(m,)`` relative radiosity gradient of every sub-triangle (the larger of its sides)."""
    lum = B @ LUMINANCE
    corners = mesh.corner_values(lum[:, None])[..., 0]
    grad = np.abs(corners - lum[:, None]).max(axis=1)
    return grad.reshape(-1, 2).max(axis=1) / max(float(lum.max()), 1e-300)


def split(mesh, subs):
    """A new :class:`PatchMesh` with sub-triangles ``subs`` of ``mesh`` split into four."""
    subs = np.unique(np.asarray(subs, np.int64))
    m = mesh.sub_area.shape[0]
    keep = np.ones(m, bool)
    keep[subs] = False
    kept = np.nonzero(keep)[0]
    c = mesh.corners[subs]
    m01, m12, m02 = (0.5 * (c[:, 0] + c[:, 1]), 0.5 * (c[:, 1] + c[:, 2]),
                     0.5 * (c[:, 0] + c[:, 2]))
    kids = np.stack([np.stack([c[:, 0], m01, m02], 1), np.stack([m01, c[:, 1], m12], 1),
                     np.stack([m02, m12, c[:, 2]], 1), np.stack([m12, m02, m01], 1)], axis=1)
    corners = np.concatenate([mesh.corners[kept], kids.reshape(-1, 3, 3)])
    parent = np.concatenate([kept, np.repeat(subs, 4)])
    area = np.concatenate([mesh.sub_area[kept], np.repeat(mesh.sub_area[subs] / 4, 4)])
    patches = np.stack([2 * parent, 2 * parent + 1], axis=1).reshape(-1)
    out = PatchMesh(corners, area, mesh.sub_normal[parent], mesh.sub_tri[parent],
                    mesh.segments, mesh.first, mesh.albedo[patches], mesh.emission[patches])
    _tree(mesh, out, kept, subs)
    _gouraud_table(out)
    return out


def _tree(old, new, kept, subs):
    """The quadtree of ``new``: ``old``'s (or one leaf node per grid sub-triangle) with the
    leaves of ``subs`` given four children each; leaf numbers follow ``new``'s order."""
    m = old.sub_area.shape[0]
    if old.node_children is None:
        children = np.full((m, 4), -1, np.int64)
        leaf = np.arange(m, dtype=np.int64)
        base = np.arange(m, dtype=np.int64)
    else:
        children, leaf, base = old.node_children, old.node_leaf, old.base_node
    node_of = np.full(m, -1, np.int64)
    is_leaf = leaf >= 0
    node_of[leaf[is_leaf]] = np.nonzero(is_leaf)[0]
    k = children.shape[0]
    new_nodes = k + np.arange(4 * subs.size).reshape(-1, 4)
    children = np.concatenate([children, np.full((4 * subs.size, 4), -1, np.int64)])
    children[node_of[subs]] = new_nodes
    renumber = np.full(m, -1, np.int64)
    renumber[kept] = np.arange(kept.size)
    leaf = np.concatenate([np.where(leaf >= 0, renumber[np.maximum(leaf, 0)], -1),
                           kept.size + np.arange(4 * subs.size)])
    leaf[node_of[subs]] = -1
    new.node_children, new.node_leaf, new.base_node = children, leaf, base


def refine(mesh, B, threshold, max_patches):
    """The mesh split where :func:`gradients` exceed ``threshold`` (None if nothing is, or if
    the split would pass ``max_patches``)."""
    grad = gradients(mesh, B)
    subs = np.nonzero(grad > threshold)[0]
    if subs.size == 0 or mesh.n_patches + 6 * subs.size > max_patches:
        return None
    return split(mesh, subs)
