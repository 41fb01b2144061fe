"""The shading frames of subpath vertices under flat shading: made once per triangle and
gathered per hit, instead of built per hit (the walk) or stored per vertex (the subpath
tables). Under flat shading without anisotropic tangents a vertex's frame is a row-wise
function of its triangle's geometric normal, so the values are the same."""

from __future__ import annotations

from ..materials.frame import shading_frame
from .common import take_rows


def triangle_frames(prep):
    """Per triangle, the tangents ``(s, t)`` (two ``(T, 3)`` arrays) of the shading frame
    :func:`.frame.shading_frame` makes around its geometric normal: what the walk's frames
    are under flat shading without anisotropic tangents, gathered per hit instead of made
    per hit (the same values: the frame is a row-wise function of the normal). None under
    smooth shading or with tangents, where the frame depends on the hit point."""
    scene = prep.scene
    if scene.corner_normals is not None or scene.aniso_tangents is not None:
        return None
    fs, ft, _ = shading_frame(prep.tri_normal)
    return fs, ft


def gather_frames(sub, column, ng):
    """The shading frames ``(fs, ft, fn)`` of some vertices of ``sub`` (a
    :class:`.subpaths.Subpath`): ``column(name)`` gathers a stored column for them, ``ng``
    is their gathered geometric normal (the frames' normal under flat shading). The same
    values as gathering ``fs, ft, fn`` themselves."""
    if sub.tri_frames is not None:  # not stored: each vertex's triangle's frame
        prim = column("prim")
        fs, ft = (take_rows(a, prim) for a in sub.tri_frames)
    else:
        fs, ft = column("fs"), column("ft")
    return fs, ft, ng if sub.flat_frames else column("fn")
