"""Small scenes of polygons for the radiosity tests (no camera needed to solve)."""

from __future__ import annotations

import numpy as np

from sampling_lab.core.prepare import prepare
from sampling_lab.core.scene import Lights, Materials, Scene


def polygon_scene(polygons, albedo=0.5, emission=0.0, lights=None):
    """A scene of convex planar ``polygons`` (each ``(v, 3)``, counter-clockwise seen from
    its front), fanned into triangles; one material."""
    verts, faces = [], []
    for poly in polygons:
        poly = np.asarray(poly, np.float64)
        base = sum(len(v) for v in verts)
        verts.append(poly)
        faces += [(base, base + k, base + k + 1) for k in range(1, len(poly) - 1)]
    mats = Materials.from_lists(["Wall"], [(albedo,) * 3], [(emission,) * 3])
    return Scene(np.concatenate(verts), np.array(faces), np.zeros(len(faces), np.int32), mats,
                 Lights.empty() if lights is None else lights, None)


def rectangle(origin, ex, ey):
    """Corners of the parallelogram ``origin + [0, 1] ex + [0, 1] ey`` (front: ex x ey)."""
    o, ex, ey = (np.asarray(a, np.float64) for a in (origin, ex, ey))
    return np.array([o, o + ex, o + ex + ey, o + ey])


def disk(center, radius, normal_z=1.0, sides=64):
    """A regular polygon of the disk's area (so its form factors match the disk's to second
    order), in the plane z = center[2], facing +z (``normal_z`` 1) or -z (-1)."""
    angle = 2 * np.pi * np.arange(sides) / sides * normal_z
    r = radius * np.sqrt(2 * np.pi / (sides * np.sin(2 * np.pi / sides)))
    c = np.asarray(center, np.float64)
    return c + np.stack([r * np.cos(angle), r * np.sin(angle), np.zeros(sides)], axis=1)


def facing(poly, point):
    """``poly`` with its vertex order reversed if its front does not face ``point``."""
    n = np.cross(poly[1] - poly[0], poly[2] - poly[0])
    return poly if np.dot(n, np.asarray(point) - poly[0]) > 0 else poly[::-1]


def cube_faces(size=2.0):
    """The six faces of a cube of side ``size`` centred on the origin, facing inward."""
    h = size / 2
    faces = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u, v = np.eye(3)[(axis + 1) % 3] * size, np.eye(3)[(axis + 2) % 3] * size
            origin = -h * np.ones(3)
            origin[axis] = sign * h
            faces.append(facing(rectangle(origin, u, v), np.zeros(3)))
    return faces


def cube_room(size=2.0, albedo=0.5, emission=0.0):
    """A closed cube of side ``size`` centred on the origin, faces toward the inside."""
    return polygon_scene(cube_faces(size), albedo, emission)


def prepared(scene):
    return prepare(scene)
