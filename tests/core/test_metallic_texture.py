"""Metallic from an Image Texture: a Principled mixture re-weighted at every hit."""

import numpy as np
import pytest

from sampling_lab.core.prepare import prepare
from sampling_lab.core.scene import (MAT_CONDUCTOR, MAT_DIELECTRIC, MAT_LAYERED, Lights,
                                     Materials, Scene)
from tests.helpers import chi_square_counts


def principled_mixture(metal_value, alpha=0.8):
    """Row 0: a Principled laid out for Metallic 0.5 (metal, dielectric, transparent rows 1-3)
    whose Metallic is a constant texture of ``metal_value``; one triangle."""
    w = [0.5 * alpha, 0.5 * alpha, 1.0 - alpha]
    mats = Materials.from_lists(
        ["P", "P metal", "P dielectric", "P transparent"], [(0.8, 0.5, 0.3)] * 4, [(0, 0, 0)] * 4,
        kinds=[MAT_LAYERED, MAT_CONDUCTOR, MAT_LAYERED, MAT_DIELECTRIC],
        ior=[1.5, 1.5, 1.5, 1.0], roughness=[0.5, 0.5, 0.5, 0.0], metallic=[0.5, 1, 0, 0],
        mix_rows=[[1, 2, 3], [1, 1, 1], [2, 2, 2], [3, 3, 3]],
        mix_weights=[w, [1, 0, 0], [1, 0, 0], [1, 0, 0]],
        metallic_texture=[0, -1, -1, -1])
    texture = np.full((2, 2, 3), metal_value, np.float32)
    return Scene([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)], [0], mats, Lights.empty(),
                 None, textures=[texture], corner_uvs=np.zeros((1, 3, 2)))


@pytest.mark.parametrize("metal", [0.0, 0.3, 1.0])
def test_metallic_texture_chooses_components_by_their_reweighted_weights(metal):
    prep = prepare(principled_mixture(metal))
    n = 200_000
    rng = np.random.default_rng(4)
    u_lobe = rng.random(n)
    prim = np.zeros(n, np.int64)
    bary = rng.random((n, 2)) * 0.5
    material, u_out = prep.choose_material(prim, u_lobe, bary[:, 0], bary[:, 1])
    expect = np.array([0.8 * metal, 0.8 * (1 - metal), 0.2]) * n
    counts = np.bincount(material, minlength=4)[1:]
    assert np.all(counts[expect == 0] == 0)
    keep = expect > 0
    chi_square_counts(counts[keep], expect[keep], what=f"components at metallic {metal}")
    # The remapped lobe number is uniform again within each component.
    for row in np.nonzero(keep)[0] + 1:
        sel = u_out[material == row]
        chi_square_counts(np.histogram(sel, bins=10, range=(0, 1))[0],
                          np.full(10, sel.size / 10), what=f"remapped u of row {row}")


def test_untextured_choice_is_unchanged():
    scene = principled_mixture(0.3)
    scene.materials.metallic_texture[:] = -1
    prep = prepare(scene)
    u_lobe = np.random.default_rng(5).random(1000)
    prim = np.zeros(1000, np.int64)
    a = prep.choose_material(prim, u_lobe)
    b = prep.choose_material(prim, u_lobe, np.zeros(1000), np.zeros(1000))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
