"""Connection ends on plain Lambert vertices under flat shading: ``f`` and both densities from
one cosine per direction, with about half the gathered columns of :class:`.subpaths.Gathered`.

Where shading is flat (no corner normals) and a vertex's BSDF is a plain two-sided Lambert row
(kind ``KIND_DIFFUSE``, none of the optional column groups), everything a connection reads
from it depends on the albedo and on the z components of directions in its frame: with
``c_o = wo_local.z``, ``c = w . fn`` (the z component :func:`core.materials.frame.to_local`
computes), and ``N = +1`` where ``c_o >= 0`` else ``-1`` (the lobe flipped to ``wo``'s side,
:func:`core.materials.families._diffuse_normal`):

- ``f |cos| = albedo max(N c, 0) / pi`` (:func:`core.materials.lambert.eval_lambert`),
- the density of sampling ``w`` from ``wo``: ``max(N c, 0) / pi``,
- the density of sampling ``wo`` from ``w``: ``max(N' c_o, 0) / pi`` with ``N'`` on ``c``'s
  side.

:func:`core.materials.bsdf.eval_bsdf` and :func:`~core.materials.bsdf.pdf_bsdf` compute the
same numbers through the whole local vectors (``N . w_l``, whose x and y terms are exact
zeros), so the values here equal theirs to the last bit, up to the sign of a zero; the frame's
two tangents, the BSDF's other columns and the densities' second gather are not needed.
:func:`gatherer` picks this form for a batch only where every vertex that may be connected
qualifies, and :class:`.subpaths.Gathered` everywhere else (tests:
``tests/core/test_lambert_vertices.py``).
"""

from __future__ import annotations

import numpy as np

from ..materials.bsdf import KIND_DIFFUSE, OPTIONAL_GROUPS
from ..materials.frame import dot
from ..sampling.warps import INV_PI, cosine_hemisphere_pdf
from ..rows import scaled
from .common import take_rows
from .subpaths import Gathered


class LambertVertices:
    """Plain Lambert vertices of a subpath for the rows of one connection (the part of the
    :class:`.subpaths.Gathered` interface the connections use).

    Attributes
    ----------
    color : (m, 3) float32 or float64, or None
        Albedo (None once only densities are needed).
    fn : (m, 3) float32 or float64, or None
        The frame's normal (the geometric normal, flat shading).
    wo_z : (m,) float32 or float64
        The incoming direction's z in the frame.
    ng : (m, 3) float32 or float64
        Geometric normal.

    Gathered by :meth:`at` from a subpath whose walks store no normals or colours
    (:attr:`.subpaths.Subpath.by_triangle`, the usual case) they are float32, and so is
    everything formed from them and float32 directions; the values are the general gather's
    to float32 rounding. Given float64 columns they are float64 and equal its values bit for
    bit (``tests/core/test_lambert_vertices.py``).
    """

    __slots__ = ("color", "fn", "wo_z", "ng")

    def __init__(self, color, fn, wo_z, ng):
        self.color, self.fn, self.wo_z, self.ng = color, fn, wo_z, ng

    @staticmethod
    def at(sub, index):
        """Vertices ``index (m,)`` of ``sub`` as rows of :meth:`.subpaths.Subpath.flat`."""
        # The stored ng (and colour, where given) is the triangle's: gathered through prim
        # (4 bytes a row from the large table, then rows of the triangles' table) instead of
        # 24 bytes a row, from the float32 copies of those tables: with the float32 positions,
        # throughputs and wo_z of Subpath, the connection's values are formed in float32.
        prim = None if sub.tri_normals is None else sub.prim.reshape(-1).take(index)
        ng = (take_rows(sub.flat("ng"), index) if prim is None
              else take_rows(sub.tri_normals32, prim))
        color = (take_rows(sub.all_params.color, index) if prim is None or sub.tri_colors is None
                 else take_rows(sub.tri_colors32, prim))
        # The z column read as elements 3 i + 2 of the contiguous table (np.take of the
        # strided column would copy it whole; fancy indexing of two axes is slower), or
        # where the walks store it alone, from its own table.
        wo_z = (sub.wo_z.reshape(-1).take(index) if sub.by_triangle
                else sub.wo_local.reshape(-1).take(index * 3 + 2))
        return LambertVertices(color,
                               ng if sub.flat_frames else take_rows(sub.flat("fn"), index),
                               wo_z, ng)

    def for_densities(self, idx):
        """The rows ``idx`` for :meth:`pdf_toward`, :meth:`pdf_back` and ``ng`` only."""
        return LambertVertices(None, None, self.wo_z[idx], take_rows(self.ng, idx))

    def local(self, w):
        """``(m,)``: the z components of world directions ``w (m, 3)`` in the frames (all that
        the other methods read of a local direction)."""
        return dot(w, self.fn)

    def cos_ng(self, w, w_l, rows):
        """``ng . w`` ``(k,)`` at the rows ``rows (k,)`` of world directions ``w (m, 3)``
        whose :meth:`local` is ``w_l``: read from ``w_l`` where the frame's normal is ``ng``
        (flat shading: the same dot product)."""
        if self.fn is self.ng:
            return w_l[rows]
        return dot(take_rows(self.ng, rows), take_rows(w, rows))

    def _lobe_side(self, cos):
        """``N`` for cosines ``cos (m,)``: ``+1`` where ``cos >= 0`` (either zero), else ``-1``.
        A copy of the sign (with ``-0 + 0 = +0``) instead of a select on ``cos >= 0``: the
        same values at a sixth of the cost where the signs are mixed (a select's branches
        mispredict on them)."""
        one = np.ones((), cos.dtype)  # float32 cosines stay float32
        return np.copysign(one, cos + np.zeros((), cos.dtype))

    def f(self, w, w_l):
        """``f |cos|`` ``(m, 3)`` toward ``w_l`` (from :meth:`local`; ``w`` unused)."""
        cos = self._lobe_side(self.wo_z) * w_l
        return scaled(self.color, np.maximum(cos, 0.0) * INV_PI)

    def values(self, w, w_l):
        """:meth:`f`, :meth:`pdf_toward` and :meth:`pdf_back` of ``w_l`` in one call (``f``
        is the albedo times the density toward ``w_l``: the same expression, formed once)."""
        toward = self.pdf_toward(w_l)
        return scaled(self.color, toward), toward, self.pdf_back(w_l)

    def pdf_toward(self, w_l):
        """Solid-angle density ``(m,)`` of sampling ``w_l`` given the incoming direction."""
        return cosine_hemisphere_pdf(self._lobe_side(self.wo_z) * w_l)

    def pdf_back(self, w_l):
        """Solid-angle density ``(m,)`` of sampling the incoming direction given ``w_l``."""
        return cosine_hemisphere_pdf(self._lobe_side(w_l) * self.wo_z)


def all_lambert(smooth, subs, j=None):
    """Whether every vertex of the subpaths ``subs`` that a connection may use (valid and
    connectible; at depth ``j`` only, if given) is a plain Lambert row under flat shading."""
    if smooth:
        return False
    for sub in subs:
        table = sub.all_params
        if any(table.has(group) for group in OPTIONAL_GROUPS):
            return False
        if sub.lambert:  # every material is plain diffuse: no kind to look at
            continue
        kind, valid, connectible = table.kind.reshape(sub.valid.shape), sub.valid, sub.connectible
        if j is not None:
            kind, valid, connectible = kind[j], valid[j], connectible[j]
        if np.any((kind != KIND_DIFFUSE) & valid & connectible):
            return False
    return True


def gatherer(ctx, *subs):
    """``gather(sub, index, mode)``: the connection ends ``index`` of ``sub`` as
    :class:`LambertVertices` where :func:`all_lambert` holds for ``subs``, else as
    :meth:`.subpaths.Gathered.at` (``mode``: radiance or importance)."""
    if all_lambert(ctx.smooth, subs):
        return lambda sub, index, mode: LambertVertices.at(sub, index)
    return lambda sub, index, mode: Gathered.at(ctx, sub, index, mode)
