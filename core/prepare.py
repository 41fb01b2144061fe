"""Per-render derived data: Embree scenes, triangle normals and areas, the light sampler."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .accel import Accel
from .lights import LightSampler
from .scene import Scene


@dataclass
class PreparedScene:
    """A :class:`Scene` plus what every integrator derives from it once.

    Attributes
    ----------
    scene : Scene
    accel : Accel
    tri_normal : (t, 3) float64
        Unit geometric normals (right-hand rule on the vertex order; zero for degenerate ones).
    tri_area : (t,) float64
    tri_albedo : (t, 3) float64
        Diffuse albedo per triangle.
    tri_emission : (t, 3) float64
        Emitted radiance per triangle.
    lights : LightSampler
    """

    scene: Scene
    accel: Accel
    tri_normal: np.ndarray
    tri_area: np.ndarray
    tri_albedo: np.ndarray
    tri_emission: np.ndarray
    lights: LightSampler


def prepare(scene: Scene) -> PreparedScene:
    """Build the acceleration structure and light tables for ``scene``."""
    v = scene.vertices.astype(np.float64)
    tri = v[scene.triangles] if scene.n_triangles else np.zeros((0, 3, 3))
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) if len(tri) else np.zeros((0, 3))
    length = np.linalg.norm(cross, axis=1)
    normal = np.where(length[:, None] > 0, cross / np.maximum(length, 1e-300)[:, None], 0.0)
    area = 0.5 * length
    accel = Accel(scene.vertices, scene.triangles, scene.visibility)
    mats = scene.materials
    albedo = np.clip(mats.base_color[scene.material].astype(np.float64), 0.0, 1.0)
    emission = np.maximum(mats.emission[scene.material].astype(np.float64), 0.0)
    lights = LightSampler(scene, area, normal)
    return PreparedScene(scene, accel, normal, area, albedo, emission, lights)
