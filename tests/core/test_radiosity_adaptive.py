"""Adaptive subdivision (core/radiosity/adaptive.py): split meshes keep the surface and find every
hit's patch; a uniform solution is not split. (That splitting lowers the error against path
tracing is in test_radiosity_convergence.py.)"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.prepare import prepare
from sampling_lab.core.radiosity import adaptive
from sampling_lab.core.radiosity.mesh import build_mesh
from sampling_lab.core.radiosity.system import RadiosityParams, solve_scene
from tests.core.radiosity_scenes import cube_room, prepared


@pytest.fixture(scope="module")
def box():
    prep = prepare(scenes.cornell_box(8, 8, "area"))
    return prep, build_mesh(prep, 0.8)


def test_split_meshes_cover_the_same_surface_and_locate_every_hit(box):
    prep, mesh = box
    first = np.arange(0, mesh.sub_area.shape[0], 3)
    twice = adaptive.split(mesh, first)
    second = np.arange(1, twice.sub_area.shape[0], 4)
    thrice = adaptive.split(twice, second)
    rng = np.random.default_rng(3)
    k = 4000
    prim = rng.integers(0, prep.scene.n_triangles, k)
    u, v = rng.random((2, k))
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    point = prep.tri_v0[prim] + u[:, None] * prep.tri_e1[prim] + v[:, None] * prep.tri_e2[prim]
    for m in (twice, thrice):
        assert m.sub_area.sum() == pytest.approx(mesh.sub_area.sum())
        patch, w = m.locate(prim, u, v, rng.random(k) < 0.5)
        assert np.allclose(np.einsum("kc,kci->ki", w, m.patch_corners(patch)), point)
        assert (w >= 0).all() and (m.sub_tri[patch // 2] == prim).all()
    # Each split sub-triangle becomes four: three more, six more patches.
    assert twice.n_patches == mesh.n_patches + 6 * first.size
    assert thrice.n_patches == twice.n_patches + 6 * second.size


def test_a_uniform_solution_is_not_split():
    prep = prepared(cube_room(2.0, albedo=0.5, emission=1.0))
    sol = solve_scene(prep, RadiosityParams(patch_size=1.5, form_factor_samples=16,
                                            adaptive=0.05))
    assert sol.stats["radiosity_adaptive_rounds"] == 0


def test_steep_radiosity_is_split_and_flat_radiosity_is_not(box):
    prep, mesh = box
    B = np.ones((mesh.n_patches, 3))
    steep = np.nonzero(mesh.sub_tri == 0)[0][:2]  # two patches of the floor made bright
    B[2 * steep] = 5.0
    grad = adaptive.gradients(mesh, B)
    split = np.nonzero(grad > 0.05)[0]
    assert set(steep) <= set(split)
    assert split.size < mesh.sub_area.shape[0] // 4
