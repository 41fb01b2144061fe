"""Embree acceleration: closest-hit and any-hit queries on ray batches, and robust ray offsets.

All triangles of a scene go into one Embree triangle mesh, so Embree's primitive id is the row of
the scene's triangle tables. Object ray visibility (Cycles' camera / diffuse / shadow ... switches)
is honoured by building one extra Embree scene per visibility class that some object opts out of;
a scene where everything is visible to everything builds just one.

:meth:`Accel.build` builds them (``core.prepare`` calls it, polling cancel), through
:mod:`core.embree_commit` so that a cancel can stop the BVH build; a scene not built yet is
built at its first query.

embreex has no ``tnear``: rays leave a surface from an origin pushed off it along the geometric
normal by :func:`offset_origin`, by an amount proportional to the float32 precision of the
triangle's coordinates, so that no scale and no distance from the origin gives self-intersection.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from .embree_commit import build_scene
from .scene import VIS_ALL, VIS_CAMERA, VIS_DIFFUSE, VIS_GLOSSY, VIS_SHADOW, VIS_TRANSMISSION
from .rows import at_least_tiny, dots, scaled

RAY_CLASSES = (VIS_CAMERA, VIS_DIFFUSE, VIS_GLOSSY, VIS_TRANSMISSION, VIS_SHADOW)

# Offsets are this many float32 ulps of the triangle's largest coordinate.
OFFSET_ULPS = 64.0
FLOAT32_EPS = float(np.finfo(np.float32).eps)


def max_abs_component(v):
    """Largest absolute coordinate of each row of ``v (n, 3)``, without a slow axis reduction."""
    a = np.abs(v)
    return np.maximum(np.maximum(a[:, 0], a[:, 1]), a[:, 2])


def as_float32(v):
    """``v (n, 3)`` as the C-contiguous float32 array that Embree reads (no copy if it is one)."""
    return np.ascontiguousarray(v, np.float32)


def ray_lengths(tmax, n):
    """Embree's ``tfar (n,)`` for ``tmax`` (``(n,)`` or a scalar): float32, capped at 3e38 (inf
    is not a valid tfar).

    One pass into a fresh float32 array: the same values as capping in float64 and then
    converting, without the float64 temporary.
    """
    return np.minimum(tmax, 3e38, out=np.empty(n, np.float32), casting="same_kind")


@dataclass
class Hits:
    """Closest hits of a ray batch.

    Attributes
    ----------
    prim : (n,) int32
        Triangle index, -1 for a miss.
    t : (n,) float64
        Hit distance along the (unit) direction; inf for a miss.
    u, v : (n,) float64
        Barycentrics of the hit (weights of vertices 1 and 2).
    """

    prim: np.ndarray
    t: np.ndarray
    u: np.ndarray
    v: np.ndarray

    @property
    def hit(self):
        return self.prim >= 0


class Accel:
    """Embree scenes over a :class:`core.scene.Scene`'s triangles.

    Parameters
    ----------
    vertices : (v, 3) float32
    triangles : (t, 3) int32
    visibility : (t,) int32
        ``VIS_*`` bits per triangle.
    """

    def __init__(self, vertices, triangles, visibility=None):
        self.vertices = np.ascontiguousarray(vertices, np.float32)
        self.triangles = np.ascontiguousarray(triangles, np.int32)
        t = self.triangles.shape[0]
        self.visibility = (np.full(t, VIS_ALL, np.int32) if visibility is None
                           else np.asarray(visibility, np.int32))
        # Largest coordinate of each vertex, then of each triangle's three (float32 values:
        # the same as over a (t, 3, 3) float64 gather, without its memory and time).
        vertex_scale = max_abs_component(self.vertices).astype(np.float64)
        self.tri_scale = (vertex_scale[self.triangles].max(axis=1) if t and len(vertex_scale)
                          else np.zeros(t))
        # The push off each triangle (offset_origin), computed once per scene.
        self.tri_offset = OFFSET_ULPS * FLOAT32_EPS * np.maximum(self.tri_scale, 1e-30)
        self.tri_offset32 = self.tri_offset.astype(np.float32)  # for float32 points
        self._scenes = {}
        self._by_mask = {}  # ray mask -> _scene_for(mask), once looked up
        self._building = threading.Lock()
        self.builds = {}
        self.rays_traced = 0

    def _key(self, mask):
        visible = (self.visibility & mask) != 0
        return (VIS_ALL if visible.all() else mask), visible

    def build(self, cancel=None):
        """Build the Embree scene of every ray-visibility class now (one when every object is
        visible to every ray), polling ``cancel()`` (raises
        ``core.sampling.stream.Aborted`` once it says so)."""
        for mask in (VIS_ALL,) + RAY_CLASSES:
            self._scene_for(mask, cancel)

    def _scene_for(self, mask, cancel=None):
        """Embree scene of the triangles visible to rays of class ``mask`` (a ``VIS_*`` bit),
        built at its first use (under a lock: the build releases the GIL). Each mask's answer
        is kept: finding its key tests every triangle's visibility against the mask (about
        12 us a call on the bench box, several per bounce for closest hits and shadow rays)."""
        found = self._by_mask.get(mask)
        if found is not None:
            return found
        key, visible = self._key(mask)
        if key not in self._scenes:
            with self._building:
                if key not in self._scenes:
                    rows = visible.nonzero()[0]
                    mine = self.triangles if key == VIS_ALL else self.triangles[rows]
                    scene, report = build_scene(self.vertices, mine, cancel)
                    self.builds[key] = report
                    self._scenes[key] = (scene, None if key == VIS_ALL
                                         else rows.astype(np.int32), rows.size > 0)
        found = self._by_mask[mask] = self._scenes[key]
        return found

    @property
    def visible_to_all(self):
        """Whether every triangle is visible to every ray class (then one Embree scene answers
        every query, whatever the rays' classes)."""
        cached = self.__dict__.get("_visible_to_all")
        if cached is None:
            cached = self._visible_to_all = bool(np.all(self.visibility == VIS_ALL))
        return cached
    def build_stats(self):
        """How the Embree scenes were built, for a render's stats: ``bvh_build`` (``'ctypes'``,
        cancellable, or ``'embreex: <why not>'``), ``bvh_build_s`` and ``bvh_scenes``."""
        reports = list(self.builds.values())
        methods = sorted({r.method + (f": {r.reason}" if r.reason else "") for r in reports})
        return {"bvh_build": ", ".join(methods) or "none",
                "bvh_build_s": sum(r.seconds for r in reports), "bvh_scenes": len(reports)}

    def intersect(self, origins, directions, tmax=None, mask=VIS_ALL):
        """Closest hits of rays ``origins (n, 3)``, unit ``directions (n, 3)``, up to ``tmax (n,)``."""
        n = origins.shape[0]
        self.rays_traced += n
        scene, rows, any_tris = self._scene_for(mask)
        if n == 0 or not any_tris:
            return Hits(np.full(n, -1, np.int32), np.full(n, np.inf), np.zeros(n), np.zeros(n))
        out = scene.run(as_float32(origins), as_float32(directions),
                        dists=None if tmax is None else ray_lengths(tmax, n), output=1)
        prim = out["primID"].astype(np.int32, copy=False)
        miss = prim < 0
        if rows is not None:
            prim = rows[np.maximum(prim, 0)]
            prim[miss] = -1
        t = out["tfar"].astype(np.float64)
        t[miss] = np.inf
        return Hits(prim, t, out["u"].astype(np.float64), out["v"].astype(np.float64))

    def occluded(self, origins, directions, tmax, mask=VIS_ALL):
        """Whether anything blocks ``origins (n, 3)`` along ``directions (n, 3)`` before ``tmax``."""
        n = origins.shape[0]
        self.rays_traced += n
        scene, _, any_tris = self._scene_for(mask)
        if n == 0 or not any_tris:
            return np.zeros(n, bool)
        res = scene.run(as_float32(origins), as_float32(directions), dists=ray_lengths(tmax, n),
                        query="OCCLUDED")
        return res != -1

    def shadow_rays(self, p, ng, prim, wi, dist, light_normal):
        """Shadow rays from surface points toward sampled light points, both ends pushed off.

        Parameters
        ----------
        p, ng : (n, 3) float64 or float32
            Receiving points and their unit geometric normals on triangles ``prim (n,)``.
        wi : (n, 3) float64 or float32
            Unit directions toward the light samples at distances ``dist (n,)`` (inf for
            directions to the sun or the world).
        light_normal : (n, 3) float64 or float32, or None
            Normal at the light sample (zero for points and directions; None: zero, the
            pinhole's, and the push along it skipped).

        Returns
        -------
        origins, directions : (n, 3) float64, or float32 where every input is
        tmax : (n,)
            The segment stops short of the light sample by the same float32 margin as the
            origin, so an emitting triangle never shadows its own sample.

        Mixed float32 and float64 inputs are all taken in float64 (operations on mixed types
        cost about 1.5 x those on either); all-float32 ones (BDPT's float32 connection ends)
        in float32, as Embree traces them: 64-ulp offsets are far above float32 rounding.
        """
        dtype = np.result_type(p, ng, wi, dist, *(() if light_normal is None else (light_normal,)))
        if dtype != np.float32:
            p, ng, wi, dist = (np.asarray(a, np.float64) for a in (p, ng, wi, dist))
            if light_normal is not None:
                light_normal = np.asarray(light_normal, np.float64)
        origins = self.offset_origin(p, ng, prim, wi)
        finite = np.isfinite(dist)
        every_finite = finite.all()  # points on lamps and emitters (no sun, no world)
        # Row scalings one component at a time (.rows: the same values, faster).
        q = scaled(wi, dist if every_finite else np.where(finite, dist, 0.0))
        q += p
        scale = np.maximum(max_abs_component(q), max_abs_component(p))
        eps = OFFSET_ULPS * FLOAT32_EPS * np.maximum(scale, 1e-30)
        if light_normal is not None:  # (a zero normal adds zeros)
            toward = np.sign(dots(light_normal, origins - q))
            q += scaled(light_normal, toward * eps)
        seg = np.subtract(q, origins, out=q)
        length = np.sqrt(dots(seg, seg))
        ok = finite & (length > 0)
        directions = np.divide(seg, at_least_tiny(length)[:, None], out=seg)
        if ok.all():
            # Every segment has a length (so every distance is finite): no choice per row.
            tmax = np.subtract(length, eps, out=length)
            return origins, directions, np.maximum(tmax, 0.0, out=tmax)
        directions[~ok] = wi[~ok]
        tmax = np.where(finite, np.where(ok, length - eps, 0.0), np.inf)
        return origins, directions, np.maximum(tmax, 0.0)

    def offset_origin(self, p, ng, prim, w, cos=None):
        """Push points ``p (n, 3)`` off triangles ``prim (n,)`` to the side of ``w (n, 3)``.

        The push is ``OFFSET_ULPS`` float32 ulps of the triangle's largest coordinate, along its
        unit geometric normal ``ng (n, 3)``. ``cos (n,)``: ``rows.dots(ng, w)`` where the
        caller has it already (the random walks keep it for the next vertex).
        """
        side = np.sign(dots(ng, w) if cos is None else cos)
        side[side == 0] = 1.0
        # float32 normals and directions: float32 offsets (a float64 product would make the
        # rest mixed-type, and slower).
        offsets = self.tri_offset32 if side.dtype == np.float32 else self.tri_offset
        out = scaled(ng, side * offsets[prim])
        out += p
        return out
