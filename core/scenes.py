"""Built-in procedural scenes for demos, tests and benchmarks (no Blender needed).

- :func:`cornell_box`: the Lambertian Cornell box with a ceiling mesh light (or a point or
  area light), Z up, camera looking down +Y, as one would model it in Blender.
- :func:`furnace`: a closed sphere of emission ``Le`` and albedo ``rho`` seen from inside; every
  pixel converges to ``Le (1 - rho^(B + 2)) / (1 - rho)`` for ``B`` bounces.
- :func:`point_in_sphere`: a point light at the centre of a closed diffuse sphere.
- :func:`cornell_sphere`: the Cornell box's walls around a glass or mirror ball under a small
  light: the caustic and the "light seen in a mirror" cases of light transport.
- :func:`many_lights`: the box lit by 1,024 small emissive quads of varied power, where light
  selection decides the noise (the light tree's benchmark).
- :func:`mirror_point_light`: a point light between a diffuse floor and a mirror, seen by a
  pinhole that does not see the mirror; its closed form (:func:`mirror_floor_radiance`,
  :func:`mirror_point_light_reference`): the light's mirror image. With ``glass=True``
  (``point_mirror_glass``) a glass ball on the floor adds a refracted caustic, part of it seen
  through the ball.
"""

from __future__ import annotations

import numpy as np

from . import lights as L
from .scene import (MAT_CONDUCTOR, MAT_DIELECTRIC, MAT_LAYERED, VIS_ALL, VIS_CAMERA, Camera,
                    Lights, Materials, Scene)

WHITE = (0.725, 0.71, 0.68)
RED = (0.63, 0.065, 0.05)
GREEN = (0.14, 0.45, 0.091)


def look_at(eye, target, up=(0.0, 0.0, 1.0)):
    """Camera ``to_world`` (4, 4) at ``eye`` looking at ``target`` (local -Z forward, +Y up)."""
    eye = np.asarray(eye, np.float64)
    f = np.asarray(target, np.float64) - eye
    f /= np.linalg.norm(f)
    x = np.cross(f, up)
    x /= np.linalg.norm(x)
    y = np.cross(x, f)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, -f, eye
    return m


def _quad(p0, p1, p2, p3):
    """Two triangles of the quad p0-p1-p2-p3 (counter-clockwise seen from the normal side)."""
    return np.array([p0, p1, p2, p3], np.float64), np.array([[0, 1, 2], [0, 2, 3]])


def _box(center, size, angle_z):
    """Closed axis-aligned box of ``size`` rotated about Z: (8, 3) vertices, (12, 3) faces."""
    hx, hy, hz = 0.5 * np.asarray(size, np.float64)
    c, s = np.cos(angle_z), np.sin(angle_z)
    corners = np.array([[x, y, z] for z in (-hz, hz) for y in (-hy, hy) for x in (-hx, hx)])
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    v = corners @ rot.T + np.asarray(center)
    faces = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                      [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]])
    return v, faces


class _Builder:
    def __init__(self):
        self.v, self.f, self.m = [], [], []
        self.count = 0

    def add(self, verts, faces, mat):
        self.v.append(np.asarray(verts, np.float64))
        self.f.append(np.asarray(faces) + self.count)
        self.m.append(np.full(len(faces), mat, np.int32))
        self.count += len(verts)

    def arrays(self):
        return np.concatenate(self.v), np.concatenate(self.f), np.concatenate(self.m)


def cornell_box(width=256, height=256, light="mesh", light_power=None):
    """The Cornell box, 2 x 2 x 2 units, floor at z = 0, open toward the camera at y = -1.

    Parameters
    ----------
    width, height : int
        Resolution.
    light : str
        ``'mesh'`` (an emissive quad under the ceiling, radiance 12), ``'point'`` (a 60 W point
        light of radius 0.05 near the ceiling) or ``'area'`` (a 40 W square area light, 0.5 m).
    """
    b = _cornell_walls()
    z1 = 2.0
    b.add(*_box((0.33, 0.3, 0.6), (0.6, 0.6, 1.2), np.radians(-17)), 0)       # tall box
    b.add(*_box((-0.35, -0.3, 0.3), (0.6, 0.6, 0.6), np.radians(17)), 0)      # short box
    names = ["White", "Red", "Green"]
    colors = [WHITE, RED, GREEN]
    emissions = [(0, 0, 0)] * 3
    lights = Lights.empty()
    if light == "mesh":
        h = 0.25
        b.add(*_quad((-h, -h, z1 - 1e-3), (h, -h, z1 - 1e-3), (h, h, z1 - 1e-3),
                     (-h, h, z1 - 1e-3)), 3)
        names.append("Light")
        colors.append((0, 0, 0))
        emissions.append((12.0, 12.0, 12.0) if light_power is None else light_power)
    elif light == "point":
        lights = L.point_light((0, 0, 1.7), (1, 1, 1), light_power or 60.0, radius=0.05,
                               name="Point")
    elif light == "area":
        m = np.eye(4)
        m[:3, 3] = (0, 0, z1 - 1e-3)
        lights = L.area_light(m, "SQUARE", 0.5, 0.5, (1, 1, 1), light_power or 40.0, name="Area")
    else:
        raise ValueError(f"unknown Cornell box light {light!r}")
    v, f, m = b.arrays()
    return Scene(v, f, m, Materials.from_lists(names, colors, emissions), lights,
                 _cornell_camera(width, height))


def _cornell_walls():
    """Floor, ceiling, back (white, row 0), left (red, row 1) and right (green, row 2) walls."""
    b = _Builder()
    y0, y1, x0, x1, z0, z1 = -1.0, 1.0, -1.0, 1.0, 0.0, 2.0
    b.add(*_quad((x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0)), 0)  # floor
    b.add(*_quad((x0, y0, z1), (x0, y1, z1), (x1, y1, z1), (x1, y0, z1)), 0)  # ceiling
    b.add(*_quad((x0, y1, z0), (x1, y1, z0), (x1, y1, z1), (x0, y1, z1)), 0)  # back
    b.add(*_quad((x0, y0, z0), (x0, y1, z0), (x0, y1, z1), (x0, y0, z1)), 1)  # left, red
    b.add(*_quad((x1, y0, z0), (x1, y0, z1), (x1, y1, z1), (x1, y1, z0)), 2)  # right, green
    return b


def _cornell_camera(width, height):
    return Camera(to_world=look_at((0, -3.9, 1.0), (0, 0, 1.0)), width=width, height=height,
                  lens=50.0, sensor_width=36.0, clip_start=0.1, clip_end=100.0)


def cornell_sphere(width=256, height=256, ball="glass", light="point", light_radius=0.02,
                   light_power=60.0, subdivisions=4, roughness=0.0, smooth=False):
    """The Cornell box's walls around a smooth ball of radius 0.45 resting above the floor.

    Parameters
    ----------
    ball : str
        ``'glass'`` (clear dielectric, IOR 1.5: it focuses the light into a caustic on the
        floor), ``'mirror'`` (a white conductor: the light is seen in it) or ``'coat'`` (a
        dielectric coat over a diffuse base).
    roughness : float
        The ball's roughness (0: smooth, delta BSDFs).
    smooth : bool
        Smooth shading: the ball's corner normals are the sphere's normals.
    light : str
        ``'point'`` (a delta point light at (0, 0, 1.75): path tracing cannot find it through
        the ball), ``'sphere'`` (a sphere light of ``light_radius``: found rarely, so noisy) or
        ``'area'`` (a square area light of side ``4 * light_radius`` under the ceiling).
    """
    b = _cornell_walls()
    v, f = icosphere(subdivisions, 0.45)
    n_walls = sum(len(faces) for faces in b.f)
    b.add(v + np.array([0.0, 0.0, 0.75]), f, 3)
    kind = {"glass": MAT_DIELECTRIC, "mirror": MAT_CONDUCTOR, "coat": MAT_LAYERED}.get(ball)
    if kind is None:
        raise ValueError(f"unknown ball {ball!r}")
    names = ["White", "Red", "Green", "Ball"]
    colors = [WHITE, RED, GREEN, (0.8, 0.3, 0.2) if ball == "coat" else (1.0, 1.0, 1.0)]
    mats = Materials.from_lists(names, colors, [(0, 0, 0)] * 4, kinds=[0, 0, 0, kind],
                                roughness=np.array([0.5, 0.5, 0.5, roughness], np.float32),
                                ior=np.full(4, 1.5, np.float32))
    position = (0.0, 0.0, 1.75)
    if light == "point":
        lights = L.point_light(position, (1, 1, 1), light_power, radius=0.0)
    elif light == "sphere":
        lights = L.point_light(position, (1, 1, 1), light_power, radius=light_radius)
    elif light == "area":
        m = np.eye(4)
        m[:3, 3] = (0.0, 0.0, 2.0 - 1e-3)
        lights = L.area_light(m, "SQUARE", 4 * light_radius, 4 * light_radius, (1, 1, 1),
                              light_power)
    else:
        raise ValueError(f"unknown light {light!r}")
    verts, faces, m = b.arrays()
    corner = None
    if smooth:
        # Flat walls keep their face normal; the ball's corners get the sphere's normals.
        tri = verts[faces]
        face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        face_n /= np.maximum(np.linalg.norm(face_n, axis=1, keepdims=True), 1e-300)
        corner = np.repeat(face_n[:, None, :], 3, axis=1)
        corner[n_walls:] = v[f]
    return Scene(verts, faces, m, mats, lights, _cornell_camera(width, height),
                 corner_normals=corner)


def icosphere(subdivisions=3, radius=1.0, inward=False):
    """Unit icosphere scaled to ``radius``: ``(v, 3)`` vertices, ``(f, 3)`` faces."""
    t = (1 + 5**0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t),
         (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    v = np.array(v, np.float64)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    f = np.array(f, np.int64)
    for _ in range(subdivisions):
        # Split every edge at its midpoint (shared edges get one vertex) and re-project.
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        uniq, inv = np.unique(edges, axis=0, return_inverse=True)
        mid = v[uniq[:, 0]] + v[uniq[:, 1]]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        base = v.shape[0]
        v = np.concatenate([v, mid])
        nf = f.shape[0]
        a, b_, c = (inv[:nf] + base, inv[nf:2 * nf] + base, inv[2 * nf:] + base)
        f = np.concatenate([np.stack([f[:, 0], a, c], 1), np.stack([f[:, 1], b_, a], 1),
                            np.stack([f[:, 2], c, b_], 1), np.stack([a, b_, c], 1)])
    if inward:
        f = f[:, ::-1]
    return v * radius, f


def _inside_camera(width, height):
    return Camera(to_world=look_at((0, 0, 0), (0, 1, 0.2)), width=width, height=height,
                  lens=20.0, clip_start=1e-3, clip_end=100.0)


def furnace(emission=1.0, albedo=0.5, radius=1.0, subdivisions=2, width=16, height=16):
    """Closed sphere of uniform emission and albedo, camera at its centre."""
    v, f = icosphere(subdivisions, radius)
    mats = Materials.from_lists(["Furnace"], [(albedo,) * 3], [(emission,) * 3])
    return Scene(v, f, np.zeros(len(f), np.int32), mats, Lights.empty(),
                 _inside_camera(width, height))


def point_in_sphere(power=100.0, albedo=0.5, radius=1.0, subdivisions=5, width=16, height=16):
    """A delta point light of ``power`` W at the centre of a closed diffuse sphere."""
    v, f = icosphere(subdivisions, radius)
    mats = Materials.from_lists(["Wall"], [(albedo,) * 3], [(0, 0, 0)])
    lights = L.point_light((0, 0, 0), (1, 1, 1), power, radius=0.0)
    return Scene(v, f, np.zeros(len(f), np.int32), mats, lights, _inside_camera(width, height))


BUILTIN = {
    "cornell": lambda w, h: cornell_box(w, h, "mesh"),
    "cornell_point": lambda w, h: cornell_box(w, h, "point"),
    "cornell_area": lambda w, h: cornell_box(w, h, "area"),
    "furnace": lambda w, h: furnace(width=w, height=h),
    "point_in_sphere": lambda w, h: point_in_sphere(width=w, height=h),
    "glass_caustic": lambda w, h: cornell_sphere(w, h, "glass", "sphere"),
    "mirror_ball": lambda w, h: cornell_sphere(w, h, "mirror", "area", light_radius=0.05),
    "many_lights": lambda w, h: many_lights(w, h),
}


def many_lights(width=64, height=64, n=1024, size=0.04, seed=7):
    """The Cornell box's white room lit by ``n`` small emissive quads of varied power.

    The quads (``size`` x ``size``, random orientation, two-sided) hover 10 to 30 cm in front of
    the floor, the ceiling and the three walls; each uses one of 8 emission materials whose
    radiances are log-uniform over 0.5 to 50, so power selection keeps sending samples to
    bright quads across the room while a receiving point is lit mostly by the quads near it:
    the case a light tree is for.

    Parameters
    ----------
    width, height : int
        Resolution.
    n : int
        Number of emissive quads (each two triangles).
    size : float
        Edge length of a quad.
    seed : int
        Seed of the quads' placement, orientation and material.
    """
    b = _cornell_walls()
    rng = np.random.default_rng(seed)
    # Each quad hovers 10 to 30 cm in front of the floor, the ceiling or one of the three walls.
    wall = rng.integers(0, 5, n)
    inward = np.array([[0, 0, 1], [0, 0, -1], [0, -1, 0], [1, 0, 0], [-1, 0, 0]], np.float64)
    plane = np.array([[0, 0, 0], [0, 0, 2], [0, 1, 0], [-1, 0, 1], [1, 0, 1]], np.float64)
    spread = rng.uniform(-0.95, 0.95, (n, 3))
    centre = (np.where(inward[wall] != 0, plane[wall], spread * (1, 1, 0) + (0, 0, 1)
                       + spread * (0, 0, 0.95))
              + inward[wall] * rng.uniform(0.1, 0.3, (n, 1)))
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    helper = np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t1 = np.cross(normal, helper)
    t1 *= 0.5 * size / np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(normal, t1)
    corners = np.stack([centre - t1 - t2, centre + t1 - t2, centre + t1 + t2,
                        centre - t1 + t2], axis=1).reshape(-1, 3)
    faces = (4 * np.arange(n)[:, None, None] + np.array([[0, 1, 2], [0, 2, 3]])).reshape(-1, 3)
    n_mat = 8
    strength = np.geomspace(0.5, 50.0, n_mat)
    mat = np.repeat(3 + rng.integers(0, n_mat, n), 2)
    v, f, m = b.arrays()
    v = np.concatenate([v, corners])
    f = np.concatenate([f, faces + b.count])
    m = np.concatenate([m, mat.astype(np.int32)])
    names = ["White", "Red", "Green"] + [f"Light {i}" for i in range(n_mat)]
    colors = [WHITE, RED, GREEN] + [(0, 0, 0)] * n_mat
    emissions = [(0, 0, 0)] * 3 + [(s, s, s) for s in strength]
    # The quads do not show to the camera: the image is the light they cast, not a sky of
    # sub-pixel emitters whose pixel coverage alone would dominate every pixel's variance.
    visibility = np.full(f.shape[0], VIS_ALL, np.int32)
    visibility[-faces.shape[0]:] = VIS_ALL & ~VIS_CAMERA
    return Scene(v, f, m, Materials.from_lists(names, colors, emissions), Lights.empty(),
                 _cornell_camera(width, height), visibility=visibility)


def mirror_point_light(width=64, height=64, power=100.0, albedo=0.5, light_z=1.0, mirror_z=1.5,
                       mirror_half=0.5, glass=False, view="floor"):
    """A point light between a diffuse floor and a perfect mirror facing it, seen by a pinhole
    that does not see the mirror: the floor receives the light directly and as reflected by
    the mirror, from the light's mirror image at ``z = 2 mirror_z - light_z``
    (:func:`mirror_floor_radiance` gives both in closed form).

    Parameters
    ----------
    power : float
        The point light's power in W (intensity ``power / (4 pi)`` W/sr), radius 0.
    albedo : float
        The floor's grey diffuse albedo (floor: the square ``[-1, 1]^2`` at ``z = 0``).
    light_z, mirror_z : float
        Heights of the light and of the mirror (a square of half side ``mirror_half``,
        centred above the light, reflecting on both faces).
    glass : bool
        Add a smooth glass ball (IOR 1.5, radius 0.3) on the floor beside the light's foot:
        a refracted caustic besides the reflected light (no closed form then).
    view : str
        ``'floor'``: the camera looks down at the floor and does not see the mirror;
        ``'mirror'``: it looks up at the mirror and sees the floor *in* it (the reflected light
        then reaches the camera through the mirror twice, ``L S D S E``: neither path tracing
        nor BDPT can find it; 2 bounces hold it).
    """
    b = _Builder()
    b.add(*_quad((-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)), 0)
    h = mirror_half
    b.add(*_quad((-h, -h, mirror_z), (-h, h, mirror_z), (h, h, mirror_z), (h, -h, mirror_z)), 1)
    names, colors, kinds = ["Floor", "Mirror"], [(albedo,) * 3, (1.0, 1.0, 1.0)], [0, MAT_CONDUCTOR]
    if glass:
        v, f = icosphere(4, 0.3)
        b.add(v + np.array([0.45, 0.2, 0.3]), f, 2)
        names.append("Glass")
        colors.append((1.0, 1.0, 1.0))
        kinds.append(MAT_DIELECTRIC)
    k = len(names)
    mats = Materials.from_lists(names, colors, [(0, 0, 0)] * k, kinds=kinds,
                                roughness=np.array([0.5, 0.0, 0.0][:k], np.float32),
                                ior=np.full(k, 1.5, np.float32))
    lights = L.point_light((0.0, 0.0, light_z), (1, 1, 1), power, radius=0.0)
    eye, target = ((0, -3.0, 1.0), (0, 0, 0)) if view == "floor" else ((0, -0.6, 0.3),
                                                                        (0, 0.1, mirror_z))
    camera = Camera(to_world=look_at(eye, target), width=width, height=height,
                    lens=50.0, sensor_width=36.0, clip_start=0.1, clip_end=100.0)
    v, f, m = b.arrays()
    return Scene(v, f, m, mats, lights, camera)


def mirror_floor_radiance(points, power=100.0, albedo=0.5, light_z=1.0, mirror_z=1.5,
                          mirror_half=0.5):
    """Closed-form radiance of floor points ``points (n, 3)`` of :func:`mirror_point_light`:
    ``(direct, reflected)``, each ``(n,)``: ``albedo / pi * I cos / d^2`` from the light and
    from its mirror image (where the line from the image crosses the mirror's square)."""
    p = np.asarray(points, np.float64)
    intensity = power / (4 * np.pi)

    def from_source(z):
        d = np.array([0.0, 0.0, z]) - p
        dist2 = np.einsum("ij,ij->i", d, d)
        return albedo / np.pi * intensity * (d[:, 2] / np.sqrt(dist2)) / dist2

    image_z = 2 * mirror_z - light_z
    t = mirror_z / image_z  # where the segment floor -> image crosses the mirror plane
    cross = p[:, :2] * (1 - t)
    inside = (np.abs(cross) <= mirror_half).all(axis=1)
    return from_source(light_z), np.where(inside, from_source(image_z), 0.0)


def mirror_point_light_reference(scene, supersample=8, **kw):
    """Closed-form pixels of a :func:`mirror_point_light` image with a box filter of one pixel:
    the mean of :func:`mirror_floor_radiance` over ``supersample^2`` camera rays per pixel,
    each followed through the mirror if it meets it first. Exact with ``max_bounces = 1``
    (``view='floor'``) or 2 (``view='mirror'``): no light bounces back from the floor then.

    Parameters
    ----------
    scene : Scene
        Made by :func:`mirror_point_light` with the keywords ``kw`` (``power``, ``albedo``,
        ``light_z``, ``mirror_z``, ``mirror_half``).

    Returns
    -------
    direct, reflected : (h, w) float64
        Radiance from the light and from its mirror image (grey: every channel alike).
    lit : (h, w) bool
        Pixels that see only floor lit by the mirror.
    """
    from .camera import generate_rays

    cam, k = scene.camera, int(supersample)
    ys, xs = np.mgrid[0:cam.height * k, 0:cam.width * k]
    xy = np.stack([(xs.ravel() + 0.5) / k, (ys.ravel() + 0.5) / k], axis=1)
    o, d, _ = generate_rays(cam, xy)
    floor, p = _floor_hits(o, d, kw.get("mirror_z", 1.5), kw.get("mirror_half", 0.5))
    direct, reflected = mirror_floor_radiance(np.where(floor[:, None], p, 0.0), **kw)

    def pixels(v):
        return v.reshape(cam.height, k, cam.width, k).mean(axis=(1, 3))

    lit = (reflected * floor > 0).reshape(cam.height, k, cam.width, k).all(axis=(1, 3))
    return pixels(direct * floor), pixels(reflected * floor), lit


def _floor_hits(o, d, mirror_z, mirror_half):
    """Where rays ``o + t d`` meet the floor square, after reflecting off the mirror's square
    if they meet it first: ``(hit (n,) bool, point (n, 3))``."""
    o, d = o.astype(np.float64).copy(), d.astype(np.float64).copy()
    with np.errstate(divide="ignore", invalid="ignore"):
        t_m = (mirror_z - o[:, 2]) / d[:, 2]
        t_f = -o[:, 2] / d[:, 2]
    pm = o + np.where(np.isfinite(t_m), t_m, 0.0)[:, None] * d
    on_mirror = ((t_m > 0) & (np.abs(pm[:, :2]) <= mirror_half).all(axis=1)
                 & ~((t_f > 0) & (t_f < t_m)))
    o[on_mirror] = pm[on_mirror]
    d[on_mirror, 2] *= -1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -o[:, 2] / d[:, 2]
    p = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d
    return (t > 0) & (np.abs(p[:, :2]) <= 1).all(axis=1), p


# Point lights through a mirror and through glass onto a diffuse floor (photon mapping's cases).
BUILTIN.update({
    "point_mirror": lambda w, h: mirror_point_light(w, h),
    "point_glass": lambda w, h: cornell_sphere(w, h, "glass", "point"),
    "point_mirror_seen": lambda w, h: mirror_point_light(w, h, view="mirror"),
    "point_mirror_glass": lambda w, h: mirror_point_light(w, h, glass=True),
})
