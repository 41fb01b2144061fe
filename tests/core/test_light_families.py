"""The light families' contract: one ray test per lamp shape, one home per emitter, tables
built by ``prepare``.

Path tracing (``hit_shapes``: radiance and NEE pdf of the lamps a ray passes) and BDPT
(``lamp_points``: the lamp vertices of camera paths) ask the same families the same question;
these tests check that they find the same rays, that the points lie on the lamps, and that every
emitter row of a batch is handed to exactly one family.
"""

import numpy as np
import pytest

from sampling_lab.core import lights as L
from sampling_lab.core.lights.sampler import LightSampler
from sampling_lab.core.lights.selection import SELECTIONS
from sampling_lab.core.prepare import prepare
from sampling_lab.core.scene import Lights
from tests.core.test_lights import make_scene


def _tilted(position, angle_x=0.6, angle_z=0.9):
    """An object matrix: rotated about x then z, local -Z turned away from straight down."""
    cx, sx, cz, sz = np.cos(angle_x), np.sin(angle_x), np.cos(angle_z), np.sin(angle_z)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = rz @ rx @ np.diag([1.0, 1.0, -1.0])
    m[:3, 3] = position
    return m


LAMPS = {
    "sphere": lambda: L.point_light((0.2, 0.1, 1.2), (1, 1, 1), 50.0, radius=0.3),
    "rectangle": lambda: L.area_light(_tilted((0.0, 0.0, 1.5)), "RECTANGLE", 0.8, 0.5,
                                      (1, 1, 1), 30.0),
    "ellipse": lambda: L.area_light(_tilted((0.1, -0.2, 1.3)), "ELLIPSE", 0.9, 0.4,
                                    (1, 1, 1), 30.0),
}


def _rays(n=50_000, seed=4):
    rng = np.random.default_rng(seed)
    o = rng.uniform(-1.5, 1.5, (n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    tmax = np.where(rng.random(n) < 0.3, rng.uniform(0.2, 2.0, n), np.inf)
    return o, d, tmax


@pytest.mark.parametrize("lamp", sorted(LAMPS))
def test_lamp_points_and_hit_shapes_find_the_same_rays(lamp):
    prep = prepare(make_scene(LAMPS[lamp]()))
    o, d, tmax = _rays()
    hit = list(prep.lights.hit_shapes(o, d, tmax, False))
    points = prep.lights.lamp_points(o, d, tmax, False)
    assert len(hit) == len(points) == 1
    rows_hit, rows_points = hit[0][0], points[0][0]
    assert rows_hit.size > 200  # the rays do meet the lamp
    np.testing.assert_array_equal(rows_hit, rows_points)


@pytest.mark.parametrize("lamp", sorted(LAMPS))
def test_lamp_points_lie_on_the_lamp_within_reach(lamp):
    prep = prepare(make_scene(LAMPS[lamp]()))
    o, d, tmax = _rays()
    (rows, index, q, normal, t), = prep.lights.lamp_points(o, d, tmax, False)
    lights = prep.scene.lights
    np.testing.assert_array_equal(index, 0)
    assert np.all((t > 0) & (t < tmax[rows]))
    np.testing.assert_allclose(q, o[rows] + t[:, None] * d[rows], atol=1e-12)
    if lamp == "sphere":
        np.testing.assert_allclose(np.linalg.norm(q - lights.position[0], axis=1),
                                   lights.radius[0], rtol=1e-9)
        np.testing.assert_allclose(normal, (q - lights.position[0]) / lights.radius[0])
        return
    # Area lights: on the emitting face, reached against its normal, inside the shape.
    assert np.all(np.einsum("ij,ij->i", d[rows], normal) < 0)
    rel = q - lights.position[0]
    ax, ay = lights.axis_x[0], lights.axis_y[0]
    x, y = rel @ ax / (ax @ ax), rel @ ay / (ay @ ay)  # orthogonal axes (no shear)
    np.testing.assert_allclose(rel @ lights.direction[0], 0.0, atol=1e-12)
    if lamp == "ellipse":
        assert np.all(x * x + y * y <= 0.25 + 1e-9)
    else:
        assert np.all((np.abs(x) <= 0.5 + 1e-9) & (np.abs(y) <= 0.5 + 1e-9))


def test_every_emitter_row_goes_to_exactly_one_family():
    lamps = Lights.concat([LAMPS["sphere"](), LAMPS["rectangle"](),
                           L.sun_light((0.2, 0.1, -1), (1, 1, 1), 3.0, angle=0.1),
                           L.point_light((0, 0, 1), (1, 1, 1), 10.0)])
    tri = (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]), np.array([[0, 1, 2]], np.int32))
    prep = prepare(make_scene(lamps, tri, emission=(2, 2, 2), world=(0.1, 0.1, 0.1)))
    ls = prep.lights
    index = np.concatenate([np.arange(ls.n_emitters), [-1], np.arange(ls.n_emitters)[::-1]])
    seen = np.zeros(index.size, int)
    names = []
    for family, rows, local in ls.families_of(index):
        seen[rows] += 1
        names.append(type(family).__name__)
    np.testing.assert_array_equal(seen, np.where(index >= 0, 1, 0))
    assert sorted(names) == sorted(["PointLights", "AreaLights", "SunLights",
                                    "EmissiveTriangles", "World"])
    np.testing.assert_array_equal(ls.is_infinite(np.arange(ls.n_emitters)),
                                  [False, False, True, False, False, True])
    np.testing.assert_array_equal(ls.delta, [False, False, False, True, False, False])


def test_prepare_builds_the_emission_over_its_light_sampler():
    prep = prepare(make_scene(LAMPS["rectangle"]()))
    assert isinstance(prep.lights, LightSampler)
    assert isinstance(prep.emission, L.Emission)
    assert prep.emission.ls is prep.lights


def test_selection_strategies_are_the_light_selection_setting():
    assert tuple(SELECTIONS) == L.LIGHT_SELECTIONS == ("power", "uniform", "tree")
    for name, cls in SELECTIONS.items():
        assert cls.name == name
