"""Alpha from an Image Texture (core/alpha.py): a sheet whose opacity is a 2 x 2 checker over a
floor lit by a sun straight above, against closed forms per checker cell.

The sheet (z = 0.5) is a mixture of a diffuse of albedo ``RHO_SHEET`` (opaque side) and a
white Transparent BSDF (clear side), laid out for opacity 0.5 as the exporter does, with an
opacity texture of one value per quadrant (Closest lookups). The floor (z = 0) has albedo
``RHO_FLOOR``. With direct light only, a pixel over a quadrant of opacity ``a`` sees
``a RHO_SHEET E / pi`` from the sheet and, through it with probability ``1 - a``, the floor lit
through the same quadrant (the camera and the sun's rays cross the sheet in the same quadrant,
both lie on lines through the quadrant's floor point and the z axis's side of it):
``(1 - a)^2 RHO_FLOOR E / pi``.

Checked for path tracing (and its shadow rays alone, the sheet hidden from the camera), light
tracing and BDPT (the floor through the sheet: their passes through it are not subpath
vertices, and their connections cross it), and photon mapping on the sheet alone (its
shadow rays stop at transparent surfaces, so the floor lit by a delta sun through the sheet is
out of its reach, as the render reports); the component choice by chi-square.
"""

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.integrators.shadows import shadow_transmittance
from sampling_lab.core.lights import sun_light
from sampling_lab.core.materials.bsdf import KIND_DIELECTRIC
from sampling_lab.core.prepare import prepare
from sampling_lab.core.render import render
from sampling_lab.core.scene import (MAT_CONDUCTOR, MAT_DIELECTRIC, MAT_LAYERED, VIS_ALL,
                                     VIS_CAMERA, Camera, Lights, Materials, Scene)
from tests.helpers import assert_mean_within_ci, chi_square_counts, plain_settings

RHO_FLOOR, RHO_SHEET, SUN = 0.5, 0.8, 3.0
# Opacity per quadrant, as the texture's rows (v) and columns (u): (-x -y), (+x -y) / (-x +y),
# (+x +y).
OPACITY = np.array([[0.0, 0.3], [0.75, 1.0]], np.float32)
SIZE = 32


def _quad(z, half):
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def alpha_sheet_scene(opacity=OPACITY, invert=False, textured=True, sheet_visibility=VIS_ALL,
                      channels=1, floor=True):
    """Floor (row 0; hidden from every ray without ``floor``), sheet (row 1: components 2 =
    diffuse, 3 = transparent, clear side), a sun straight down, a narrow camera straight
    above."""
    fv, ff = _quad(0.0, 1.0)
    sv, sf = _quad(0.5, 1.5)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    corner_uvs = np.zeros((4, 3, 2), np.float32)
    corner_uvs[2:] = uv[sf]
    pixels = (1.0 - opacity) if invert else opacity
    texture = np.repeat(pixels[..., None], channels, axis=2).astype(np.float32)
    mats = Materials.from_lists(
        ["floor", "sheet", "sheet diffuse", "sheet clear"],
        [(RHO_FLOOR,) * 3, (1,) * 3, (RHO_SHEET,) * 3, (1,) * 3], np.zeros((4, 3)),
        kinds=[0, 0, 0, KIND_DIELECTRIC], roughness=[0.5, 0.5, 0.5, 0.0],
        ior=[1.5, 1.5, 1.5, 1.0], mix_rows=[[0, 0], [2, 3], [2, 2], [3, 3]],
        mix_weights=[[1, 0], [0.5, 0.5], [1, 0], [1, 0]],
        alpha_texture=[-1, 0 if textured else -1, -1, -1], alpha_invert=[False, invert, False,
                                                                          False],
        alpha_clear=[False, False, False, True])
    camera = Camera(to_world=scenes.look_at((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0)), width=SIZE,
                    height=SIZE, lens=200.0, sensor_width=36.0, clip_start=0.1, clip_end=100.0)
    return Scene(np.concatenate([fv, sv]).astype(np.float32),
                 np.concatenate([ff, sf + 4]).astype(np.int32), np.array([0, 0, 1, 1]), mats,
                 sun_light((0, 0, -1), (1, 1, 1), SUN), camera, textures=[texture],
                 texture_interpolation=["Closest"], corner_uvs=corner_uvs,
                 visibility=np.array([VIS_ALL * floor] * 2 + [sheet_visibility] * 2))


def quadrant_pixels(image, margin=3):
    """Pixels of each quadrant ``(2, 2, n)`` (rows: -y, +y; columns: -x, +x), leaving out
    ``margin`` pixels on each side of the axes (the pixel filter blends across them)."""
    h = SIZE // 2
    lo, hi = slice(0, h - margin), slice(h + margin, SIZE)
    # Image row 0 is the bottom (-y); the camera's +Y is world +y, its right is +x.
    return np.array([[image[r, c].reshape(-1) for c in (lo, hi)] for r in (lo, hi)])


def seen_through_sheet(opacity):
    """Closed form of the pixel over a quadrant of opacity ``opacity`` (direct light only)."""
    return (opacity * RHO_SHEET + (1 - opacity) ** 2 * RHO_FLOOR) * SUN / np.pi


def assert_quadrants(image, expected, what, rtol=1e-12):
    """Each quadrant's pixel mean within its confidence interval of ``expected (2, 2)``
    (``rtol``: the float32 film's rounding where the pixels have no noise)."""
    cells = quadrant_pixels(image)
    for i in range(2):
        for j in range(2):
            assert_mean_within_ci(cells[i, j], expected[i, j], comparisons=4, rtol=rtol,
                                  what=f"{what}, quadrant {i, j}")


def test_alpha_texture_chooses_components_by_the_opacity_at_the_hit():
    prep = prepare(alpha_sheet_scene())
    n = 40_000
    rng = np.random.default_rng(3)
    for i, j in np.ndindex(2, 2):
        uv = (np.array([j, i]) + 0.1 + 0.8 * rng.random((n, 2))) / 2
        # The sheet's first triangle has UVs (0, 0), (1, 0), (1, 1): barycentrics from uv.
        u, v = uv[:, 0] - uv[:, 1], uv[:, 1]
        lower = u >= 0
        prim = np.where(lower, 2, 3)
        u, v = np.where(lower, u, uv[:, 0]), np.where(lower, v, uv[:, 1] - uv[:, 0])
        u_lobe = rng.random(n)
        material, u_out = prep.choose_material(prim, u_lobe, u, v)
        a = float(OPACITY[i, j])
        expect = np.array([a, 1 - a]) * n
        counts = np.array([(material == 2).sum(), (material == 3).sum()])
        assert np.all(counts[expect == 0] == 0)
        keep = expect > 0
        chi_square_counts(counts[keep], expect[keep], what=f"components at opacity {a}")
        sel = u_out[material == (2 if a > 0 else 3)]
        chi_square_counts(np.histogram(sel, bins=10, range=(0, 1))[0],
                          np.full(10, sel.size / 10), what="remapped lobe number")


def test_shadow_rays_keep_one_minus_the_opacity_of_the_cell_they_cross():
    prep = prepare(alpha_sheet_scene())
    rng = np.random.default_rng(4)
    xy = rng.uniform(-0.9, 0.9, (2000, 2))
    origins = np.column_stack([xy, np.full(2000, 0.01)]) - prep.shift
    directions = np.tile([0.0, 0.0, 1.0], (2000, 1))
    transmit = shadow_transmittance(prep, origins, directions, np.full(2000, np.inf), 4)
    a = OPACITY[(xy[:, 1] > 0).astype(int), (xy[:, 0] > 0).astype(int)]
    np.testing.assert_allclose(transmit, np.repeat((1 - a)[:, None], 3, axis=1), atol=1e-12)


@pytest.mark.parametrize("invert,channels", [(False, 1), (True, 3)])
def test_floor_shadow_under_an_alpha_textured_sheet_is_one_minus_its_opacity(invert, channels):
    # The sheet hidden from the camera: the floor alone, lit through it (no noise: a delta
    # sun, a diffuse floor, deterministic shadow rays). A Mix Shader whose
    # second input is the Transparent BSDF stores 1 - opacity (invert); a colour image's
    # luminance is the value.
    scene = alpha_sheet_scene(invert=invert, channels=channels,
                              sheet_visibility=VIS_ALL & ~VIS_CAMERA)
    res = render(scene, plain_settings(spp=16, max_bounces=0, transparent_max_bounces=4,
                                       seed=7))
    assert_quadrants(res.combined()[..., 0], (1 - OPACITY) * RHO_FLOOR * SUN / np.pi,
                     "floor shadow", rtol=1e-5)


def test_alpha_textured_sheet_seen_over_the_floor_matches_the_closed_form():
    # Measured half-widths 1.8 % (a = 0.3) and 2.0 % (a = 0.75); exact at a = 0 and 1. The
    # texture ignored is 5 %, 8 %, 17 % and 34 % off (next test).
    res = render(alpha_sheet_scene(), plain_settings(spp=64, max_bounces=0,
                                                     transparent_max_bounces=4, seed=9))
    assert_quadrants(res.combined()[..., 0], seen_through_sheet(OPACITY), "path tracing")


def test_the_closed_form_check_fails_when_the_texture_is_ignored():
    # The same sheet at its layout opacity 0.5 everywhere: three of four quadrants are off by
    # 20 % or more of the closed form, far outside the intervals.
    res = render(alpha_sheet_scene(textured=False),
                 plain_settings(spp=64, max_bounces=0, transparent_max_bounces=4, seed=9))
    with pytest.raises(AssertionError):
        assert_quadrants(res.combined()[..., 0], seen_through_sheet(OPACITY), "ignored")


def replicate_quadrant_means(scene, integrator, spp, max_bounces, runs=8):
    """``(runs, 2, 2)`` quadrant means of independent renders (light paths splat across
    pixels, so a pixel's variance is no error estimate: replicates are)."""
    return np.array([quadrant_pixels(render(scene, plain_settings(
        integrator=integrator, spp=spp, max_bounces=max_bounces, transparent_max_bounces=4,
        seed=31 + 1000 * i)).combined()[..., 0]).mean(axis=2) for i in range(runs)])


def test_light_tracing_sees_the_floor_through_the_alpha_texture():
    # Light paths pass the sheet where they sample its clear side, the camera connections
    # through it keep 1 - a (a pass counts toward the Transparent limit only). Measured
    # interval half-widths (Student t, 15 dof, 4 quadrants) 17-19 % of the closed forms: this
    # checks light tracing's use of the per-hit opacity for gross errors only (a connection
    # ignoring the sheet's 1 - a is off by 25-100 %); the path-tracing test below is the
    # precise one.
    means = replicate_quadrant_means(alpha_sheet_scene(), "light", 32, 1, runs=16)
    expected = seen_through_sheet(OPACITY)
    for i, j in np.ndindex(2, 2):
        assert_mean_within_ci(means[:, i, j], expected[i, j], comparisons=4,
                              what=f"light tracing, quadrant {i, j}")


def test_bdpt_sees_the_floor_through_the_alpha_texture():
    # Passes through the sheet are not vertices of BDPT's subpaths, and its connections cross
    # the sheet keeping 1 - a (core/integrators/transparent_passes.py): each quadrant is the
    # closed form, the sheet's share a of its diffuse plus the floor lit and seen through it.
    # (Connections that stop at the sheet leave the floor dark: 5-100 % off.) Measured
    # interval half-widths (Student t, 7 dof, 4 quadrants): 0.3-3 % of the closed forms.
    means = replicate_quadrant_means(alpha_sheet_scene(), "bdpt", 8, 0, runs=8)
    expected = seen_through_sheet(OPACITY)
    for i, j in np.ndindex(2, 2):
        assert_mean_within_ci(means[:, i, j], expected[i, j], comparisons=4, rtol=1e-5,
                              what=f"BDPT, quadrant {i, j}")


def test_metallic_and_alpha_textures_multiply_their_factors():
    # A Principled laid out for Metallic 0.5 and Alpha 0.5 (metal, dielectric, transparent):
    # with textures of m = 0.3 and a = 0.6 the components weigh a m, a (1 - m), 1 - a.
    m, a = 0.3, 0.6
    mats = Materials.from_lists(
        ["P", "metal", "dielectric", "clear"], [(0.8, 0.5, 0.3)] * 4, np.zeros((4, 3)),
        kinds=[MAT_LAYERED, MAT_CONDUCTOR, MAT_LAYERED, MAT_DIELECTRIC],
        ior=[1.5, 1.5, 1.5, 1.0], roughness=[0.5, 0.5, 0.5, 0.0], metallic=[0.5, 1, 0, 0],
        mix_rows=[[1, 2, 3], [1, 1, 1], [2, 2, 2], [3, 3, 3]],
        mix_weights=[[0.25, 0.25, 0.5], [1, 0, 0], [1, 0, 0], [1, 0, 0]],
        metallic_texture=[0, -1, -1, -1], alpha_texture=[1, -1, -1, -1],
        alpha_clear=[False, False, False, True])
    scene = Scene([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)], [0], mats, Lights.empty(),
                  None, textures=[np.full((2, 2, 3), m, np.float32),
                                  np.full((2, 2, 1), a, np.float32)],
                  corner_uvs=np.zeros((1, 3, 2)))
    prep = prepare(scene)
    n = 100_000
    rng = np.random.default_rng(6)
    material, _ = prep.choose_material(np.zeros(n, np.int64), rng.random(n),
                                       np.zeros(n), np.zeros(n))
    chi_square_counts(np.bincount(material, minlength=4)[1:],
                      np.array([a * m, a * (1 - m), 1 - a]) * n, what="components")


def test_non_finite_alpha_texels_are_transparent_and_never_reach_the_film():
    opacity = np.array([[np.nan, np.inf], [-np.inf, 0.5]], np.float32)
    res = render(alpha_sheet_scene(opacity=opacity), plain_settings(
        spp=8, max_bounces=0, transparent_max_bounces=4, seed=2))
    image = res.combined()
    assert np.isfinite(image).all()
    # The core reads NaN as 0 (transparent) and clips infinities (the exporter zeroes
    # non-finite pixels first, as Cycles loads them).
    expected = seen_through_sheet(np.array([[0.0, 1.0], [0.0, 0.5]]))
    assert_quadrants(image[..., 0], expected, "non-finite texels", rtol=1e-5)


def test_photon_mapping_shows_each_quadrant_of_the_sheet_with_its_opacity():
    # No floor (photon mapping's light paths and shadow rays stop at transparent surfaces, as
    # the render reports), the sheet lit directly by the sun; the only noise is each
    # camera sample's choice of side, independent per pixel (the image's Variance pass is not
    # estimated for photon mapping, so the interval comes from the quadrant's pixels).
    # Measured half-widths 9 % (a = 0.3) and 3 % (a = 0.75); the texture ignored is 33-67 %
    # off.
    res = render(alpha_sheet_scene(floor=False), plain_settings(
        integrator="photon", spp=32, max_bounces=2, transparent_max_bounces=4, seed=9))
    assert_quadrants(res.combined()[..., 0], OPACITY * RHO_SHEET * SUN / np.pi,
                     "photon mapping", rtol=1e-5)
