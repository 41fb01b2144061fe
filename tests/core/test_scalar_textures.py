"""Specular IOR Level and Coat Weight from Image Textures (core/scalar_textures.py): the BSDF
at a hit is the one of a constant input of the looked-up value."""

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.lights import sun_light
from sampling_lab.core.prepare import prepare
from sampling_lab.core.render import render
from sampling_lab.core.scene import MAT_LAYERED, Camera, Materials, Scene
from tests.helpers import plain_settings

LEVEL, COAT = 0.85, 0.35


def coated_plane(level=0.5, coat=0.0, level_texture=None, coat_texture=None):
    """A plastic (layered) plane of Specular IOR Level ``level`` and Coat Weight ``coat``, or
    of constant textures of the given values (the coat laid out at weight 1 as the exporter
    does), under a tilted sun, seen from above."""
    textures, columns = [], {}
    for name, value in (("specular_level_texture", level_texture),
                        ("coat_weight_texture", coat_texture)):
        if value is not None:
            columns[name] = [len(textures)]
            textures.append(np.full((2, 2, 3), value, np.float32))
    if coat_texture is not None:
        coat = 1.0
    mats = Materials.from_lists(["P"], [(0.6, 0.3, 0.2)], [(0, 0, 0)], kinds=[MAT_LAYERED],
                                roughness=[0.3], specular_ior_level=[level], coat_weight=[coat],
                                coat_roughness=[0.1], **columns)
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    camera = Camera(to_world=scenes.look_at((0, -1.0, 2.5), (0, 0, 0), up=(0, 0, 1)),
                    width=16, height=16, lens=50.0)
    return Scene(v, np.array([[0, 1, 2], [0, 2, 3]]), [0, 0], mats,
                 sun_light((0.3, 0.5, -1.0), (1, 1, 1), 3.0), camera, textures=textures,
                 corner_uvs=np.zeros((2, 3, 2)) if textures else None)


@pytest.mark.parametrize("case", ["level", "coat"])
def test_textured_input_gives_the_bsdf_of_the_constant_input(case):
    const = dict(level=LEVEL) if case == "level" else dict(coat=COAT)
    textured = (dict(level_texture=LEVEL) if case == "level" else dict(coat_texture=COAT))
    n = 64
    prim = np.zeros(n, np.int64)
    u_lobe = np.linspace(0, 1, n, endpoint=False)
    bary = np.full(n, 0.25)
    a, _, _ = prepare(coated_plane(**const)).choose_bsdf(prim, u_lobe, bary, bary)
    b, _, _ = prepare(coated_plane(**textured)).choose_bsdf(prim, u_lobe, bary, bary)
    np.testing.assert_allclose(b.eta, a.eta, rtol=1e-6)
    if case == "coat":
        np.testing.assert_allclose(b.coat_weight, a.coat_weight, rtol=1e-6)


@pytest.mark.parametrize("case", ["level", "coat"])
def test_textured_input_renders_as_the_constant_input_and_not_as_its_layout(case):
    const = dict(level=LEVEL) if case == "level" else dict(coat=COAT)
    textured = (dict(level_texture=LEVEL) if case == "level" else dict(coat_texture=COAT))
    settings = plain_settings(spp=8, max_bounces=1, seed=3)
    a = render(coated_plane(**const), settings).combined()
    b = render(coated_plane(**textured), settings).combined()
    # The same lobe choices and directions from the same numbers: equal up to rounding.
    np.testing.assert_allclose(b, a, rtol=1e-5, atol=1e-7)
    # The texture ignored (the row's own value: level 0.5, or the coat laid out at weight 1)
    # changes the image.
    layout = dict(level=0.5) if case == "level" else dict(coat=1.0)
    c = render(coated_plane(**layout), settings).combined()
    assert np.abs(c - a).max() > 1e-3
