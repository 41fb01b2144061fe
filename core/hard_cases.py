"""Hard cases: small scenes that break renderers (no Blender needed).

Each builder returns a :class:`core.scene.Scene` at a tiny resolution; :data:`CASES` names
them, and ``docs/HARD_CASES.md`` is their table. ``tests/core/test_hard_cases.py`` renders
every case with every integrator and checks that no NaN or Inf reaches any pass, and that
each image agrees with the case's closed form where one exists (:func:`reference`). What
makes a case hard is said in its builder's docstring.

Closed forms used:

- furnace (:func:`core.scenes.furnace`): a closed surface of uniform emission ``Le`` and
  albedo ``rho`` seen from inside is ``Le (1 - rho^(B + 2)) / (1 - rho)`` with ``B`` bounces,
  whatever its shape, size or place, and whatever zero-area, NaN or duplicate triangles
  come with it;
- white world: lossless glass in a world of radiance 1 is 1 seen from outside and ``n^2``
  seen from inside (radiance mode: ``L / n^2`` is invariant, see
  :mod:`core.materials.dielectric`), up to paths longer than ``max_bounces``;
- a Lambert plane under a sun: ``rho E cos(theta) / pi``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from . import lights as L
from .scene import MAT_CONDUCTOR, MAT_DIELECTRIC, Camera, Lights, Materials, Scene
from .scenes import icosphere, look_at

# Furnace radiance and albedo of every furnace-based case.
LE, RHO = 1.0, 0.5
GLASS_IOR = 1.5
# Sun of the grazing plane: irradiance, elevation, plane albedo.
SUN_E, SUN_ELEVATION, PLANE_RHO = 3.0, np.radians(40.0), 0.6


def furnace_value(bounces, emission=LE, albedo=RHO):
    """Every pixel of a furnace rendered with ``bounces`` bounces."""
    return emission * (1 - albedo ** (bounces + 2)) / (1 - albedo)


def _furnace(radius=1.0, offset=(0.0, 0.0, 0.0), width=8, height=8, subdivisions=2,
             clip_start=1e-3):
    v, f = icosphere(subdivisions, radius)
    mats = Materials.from_lists(["Furnace"], [(RHO,) * 3], [(LE,) * 3])
    eye = np.asarray(offset, np.float64)
    cam = Camera(to_world=look_at(eye, eye + (0, 1, 0.2)), width=width, height=height,
                 lens=20.0, clip_start=clip_start, clip_end=1e3 * radius)
    return Scene(v + eye, f, np.zeros(len(f), np.int32), mats, Lights.empty(), cam)


def _extend(scene, verts, faces, material=0, messages=()):
    """``scene`` plus triangles ``faces`` over new vertices ``verts`` (material row)."""
    n = len(scene.vertices)
    faces = np.asarray(faces, np.int32).reshape(-1, 3)
    return dataclasses.replace(
        scene, vertices=np.concatenate([scene.vertices, np.asarray(verts, np.float32)]),
        triangles=np.concatenate([scene.triangles, faces + n]),
        material=np.concatenate([scene.material, np.full(len(faces), material, np.int32)]),
        visibility=None, messages=list(scene.messages) + list(messages))


def far_from_origin():
    """The furnace 10^4 units from the origin: float32 keeps 1e-3 of absolute precision
    there, as much as a ray offset of a unit-sized scene."""
    return _furnace(offset=(1e4, -1e4, 1e4))


def tiny_scale():
    """The furnace at 1e-3 scale (radius 1 mm, camera clip 1 um): fixed ray epsilons fail."""
    return _furnace(radius=1e-3, clip_start=1e-6)


def degenerate_triangles():
    """The furnace plus zero-area triangles (collinear, repeated vertices), emissive ones
    among them: an area-sampled emitter of area zero has an infinite pdf."""
    s = _furnace()
    verts = [(0.1, 0.5, 0.0), (0.2, 0.5, 0.0), (0.3, 0.5, 0.0), (0.0, 0.6, 0.1)]
    return _extend(s, verts, [(0, 1, 2), (3, 3, 3), (0, 0, 1)])


def nonfinite_vertices():
    """The furnace plus triangles with NaN and Inf vertex coordinates (they are dropped with a
    message; Embree and the bounding box would otherwise see them)."""
    s = _furnace()
    nan, inf = np.nan, np.inf
    verts = [(nan, 0.5, 0.0), (0.2, 0.5, 0.0), (0.3, 0.6, 0.0), (inf, -inf, 0.0),
             (0.1, 0.2, 0.3)]
    return _extend(s, verts, [(0, 1, 2), (3, 1, 4), (1, 2, 4)])


def coplanar_faces(width=8, height=8):
    """A Lambert plane under a sun with a coincident twin of reversed winding (z-fighting):
    a ray leaving one twin must not stop on the other, whichever normal it was offset along.
    Its radiance is :func:`grazing_plane_value`."""
    v, f = _plane(0.5)
    mats = Materials.from_lists(["Plane"], [(PLANE_RHO,) * 3], [(0, 0, 0)])
    sun = L.sun_light(sun_direction(), (1, 1, 1), SUN_E)
    cam = Camera(to_world=look_at((0, -0.2, 0.8), (0, 0, 0)), width=width, height=height,
                 lens=50.0, clip_start=1e-3, clip_end=100.0)
    return Scene(v, np.concatenate([f, f[:, ::-1]]), np.zeros(4, np.int32), mats, sun, cam)


def bad_normals(kind="inverted"):
    """The furnace with smooth-shading corner normals that point inward (``'inverted'``) or
    have zero length (``'zero'``)."""
    s = _furnace()
    v = s.vertices.astype(np.float64)
    n = v[s.triangles] / np.linalg.norm(v[s.triangles], axis=2, keepdims=True)
    n = -n if kind == "inverted" else np.zeros_like(n)
    return dataclasses.replace(s, corner_normals=n)


def degenerate_lights():
    """The furnace plus lamps that emit nothing: an area light of zero size, a 0 W point light,
    a sun of strength 0 and a 0 W sphere light."""
    s = _furnace()
    m = np.eye(4)
    m[:3, 3] = (0.0, 0.3, 0.0)
    lamps = Lights.concat([
        L.area_light(m, "SQUARE", 0.0, 0.0, (1, 1, 1), 100.0, name="Zero Area"),
        L.area_light(m, "RECTANGLE", 0.3, 0.0, (1, 1, 1), 100.0, name="Zero Height"),
        L.point_light((0.0, -0.3, 0.0), (1, 1, 1), 0.0, name="Zero Power"),
        L.point_light((0.2, 0.0, 0.1), (1, 1, 1), 0.0, radius=0.05, name="Zero Sphere"),
        L.sun_light((0, 0, -1), (1, 1, 1), 0.0, name="Zero Sun"),
    ])
    return dataclasses.replace(s, lights=lamps)


def emissive_100k():
    """A closed cube furnace of 101,568 emissive triangles (a 92 x 92 grid of quads per
    face): light selection, the light tree and light paths over 100 k emitters."""
    n = 92
    g = np.linspace(-1.0, 1.0, n + 1)
    a, b = np.meshgrid(g, g, indexing="ij")
    grid = np.stack([a.ravel(), b.ravel()], axis=1)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    quads = np.stack([i, i + n + 1, i + n + 2, i + 1], axis=-1).reshape(-1, 4)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    verts, faces = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            p = np.insert(grid, axis, sign, axis=1)
            faces.append(tris + sum(len(x) for x in verts))
            verts.append(p)
    s = _furnace()
    return dataclasses.replace(s, vertices=np.concatenate(verts),
                               triangles=np.concatenate(faces),
                               material=np.zeros(sum(len(f) for f in faces), np.int32),
                               visibility=None)


def _plane(half, z=0.0):
    v = np.array([(-half, -half, z), (half, -half, z), (half, half, z), (-half, half, z)])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def sun_direction():
    """Where the grazing plane's sun light travels (down, from the -y side)."""
    e = SUN_ELEVATION
    return np.array([0.0, np.cos(e), -np.sin(e)])


def grazing_camera(width=8, height=8):
    """A Lambert plane 2 km wide under a sun, seen by a camera 1 cm above it looking 0.5
    degrees below the horizon: rays meet the plane at near-zero cosines, far away."""
    v, f = _plane(1e3)
    mats = Materials.from_lists(["Plane"], [(PLANE_RHO,) * 3], [(0, 0, 0)])
    sun = L.sun_light(sun_direction(), (1, 1, 1), SUN_E)
    eye = np.array([0.0, 0.0, 0.01])
    target = eye + (0.0, 1.0, -np.tan(np.radians(0.5)))
    cam = Camera(to_world=look_at(eye, target), width=width, height=height, lens=400.0,
                 clip_start=1e-3, clip_end=1e4)
    return Scene(v, f, np.zeros(2, np.int32), mats, sun, cam)


def grazing_plane_value():
    """Radiance of the grazing plane (one bounce: nothing else in the scene)."""
    return PLANE_RHO * SUN_E * np.sin(SUN_ELEVATION) / np.pi


def disco_sun(width=8, height=8):
    """A mirror-faceted ball (flat facets, perfect conductor) on a grey floor under a sun of
    0.05 degrees and 1000 W/m^2 : the sun's reflections are tiny, very bright spots."""
    v, f = icosphere(2, 0.5)
    fv, ff = _plane(3.0)
    verts = np.concatenate([fv, v + (0, 0, 0.6)])
    faces = np.concatenate([ff, f + 4])
    mats = Materials.from_lists(["Floor", "Facets"], [(0.5,) * 3, (1.0,) * 3],
                                [(0, 0, 0)] * 2, kinds=[0, MAT_CONDUCTOR],
                                roughness=np.array([0.5, 0.0], np.float32))
    sun = L.sun_light((0.3, 0.2, -1.0), (1, 1, 1), 1000.0, angle=np.radians(0.05))
    cam = Camera(to_world=look_at((0, -3.0, 1.5), (0, 0, 0.5)), width=width, height=height,
                 clip_start=0.1, clip_end=100.0)
    material = np.concatenate([np.zeros(2, np.int32), np.ones(len(f), np.int32)])
    return Scene(verts, faces, material, mats, sun, cam, world_color=np.full(3, 0.05))


def _glass_mats():
    return Materials.from_lists(["Glass"], [(1.0,) * 3], [(0, 0, 0)], kinds=[MAT_DIELECTRIC],
                                roughness=np.zeros(1, np.float32),
                                ior=np.full(1, GLASS_IOR, np.float32))


def glass_block_tir(width=8, height=8):
    """A smooth glass block (IOR 1.5) in a white world, seen through two faces at once so that
    many rays are totally reflected inside it."""
    v = np.array([[x, y, z] for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)])
    faces = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                      [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]])
    cam = Camera(to_world=look_at((1.6, -1.9, 1.2), (0, 0, 0)), width=width, height=height,
                 lens=60.0, clip_start=0.01, clip_end=100.0)
    return Scene(v, faces, np.zeros(12, np.int32), _glass_mats(), Lights.empty(), cam,
                 world_color=np.ones(3))


def camera_in_glass(width=8, height=8):
    """The camera at the centre of a smooth glass ball (IOR 1.5) in a white world."""
    v, f = icosphere(2, 1.0)
    cam = Camera(to_world=look_at((0, 0, 0), (0, 1, 0.2)), width=width, height=height,
                 lens=20.0, clip_start=1e-3, clip_end=100.0)
    return Scene(v, f, np.zeros(len(f), np.int32), _glass_mats(), Lights.empty(), cam,
                 world_color=np.ones(3))


def light_in_mirror_sphere(width=8, height=8):
    """A point light and the camera inside a closed perfect mirror: light never leaves and
    never meets a surface that is not a delta BSDF, so no estimator can see it (the image is
    black); every path runs to ``max_bounces``."""
    v, f = icosphere(2, 1.0)
    mats = Materials.from_lists(["Mirror"], [(1.0,) * 3], [(0, 0, 0)], kinds=[MAT_CONDUCTOR],
                                roughness=np.zeros(1, np.float32))
    lamp = L.point_light((0.2, 0.1, 0.3), (1, 1, 1), 100.0)
    cam = Camera(to_world=look_at((0, 0, 0), (0, 1, 0.2)), width=width, height=height,
                 lens=20.0, clip_start=1e-3, clip_end=100.0)
    return Scene(v, f, np.zeros(len(f), np.int32), mats, lamp, cam)


def point_mirror(width=8, height=8):
    """A point light between a Lambert floor and a perfect mirror (:func:`core.scenes.
    mirror_point_light`): the reflected light is a delta chain only light paths find."""
    from .scenes import mirror_point_light
    return mirror_point_light(width, height)


def empty_scene(width=8, height=8):
    """No geometry, no lamps, a black world."""
    cam = Camera(to_world=look_at((0, -3, 1), (0, 0, 1)), width=width, height=height)
    z = np.zeros(0, np.int32)
    return Scene(np.zeros((0, 3)), np.zeros((0, 3)), z, Materials.from_lists([], [], []),
                 Lights.empty(), cam)


def many_triangles(n_triangles=10_000_000, width=8, height=8):
    """A Lambert plane cut into ``n_triangles`` triangles (a square grid), under a sun:
    memory of the tables and of Embree's BVH. Its radiance is :func:`grazing_plane_value`."""
    n = int(np.ceil(np.sqrt(n_triangles / 2)))
    g = np.linspace(-1.0, 1.0, n + 1, dtype=np.float32)
    verts = np.zeros(((n + 1) ** 2, 3), np.float32)
    verts[:, 0] = np.repeat(g, n + 1)
    verts[:, 1] = np.tile(g, n + 1)
    i = (np.arange(n, dtype=np.int32)[:, None] * (n + 1)
         + np.arange(n, dtype=np.int32)[None, :]).ravel()
    faces = np.empty((2 * n * n, 3), np.int32)
    faces[0::2] = np.stack([i, i + n + 1, i + n + 2], axis=1)
    faces[1::2] = np.stack([i, i + n + 2, i + 1], axis=1)
    mats = Materials.from_lists(["Plane"], [(PLANE_RHO,) * 3], [(0, 0, 0)])
    sun = L.sun_light(sun_direction(), (1, 1, 1), SUN_E)
    cam = Camera(to_world=look_at((0, -0.5, 1.0), (0, 0, 0)), width=width, height=height,
                 lens=50.0, clip_start=1e-3, clip_end=100.0)
    return Scene(verts, faces, np.zeros(len(faces), np.int32), mats, sun, cam)


CASES = {
    "disco_sun": disco_sun,
    "point_mirror": point_mirror,
    "glass_block_tir": glass_block_tir,
    "grazing_camera": grazing_camera,
    "far_from_origin": far_from_origin,
    "tiny_scale": tiny_scale,
    "degenerate_triangles": degenerate_triangles,
    "degenerate_lights": degenerate_lights,
    "nonfinite_vertices": nonfinite_vertices,
    "inverted_normals": lambda: bad_normals("inverted"),
    "zero_length_normals": lambda: bad_normals("zero"),
    "coplanar_faces": coplanar_faces,
    "emissive_100k": emissive_100k,
    "empty_scene": empty_scene,
    "camera_in_glass": camera_in_glass,
    "light_in_mirror_sphere": light_in_mirror_sphere,
}
"""Hard cases by name (each a builder with no required argument). The 10 M triangle plane
(:func:`many_triangles`) is left out: it is the slow tier's and the limits tool's."""
