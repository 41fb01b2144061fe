"""The fast paths of light tracing and BDPT (issue 12) against the general code they skip.

- BDPT's subpath tables carry only the optional BSDF column groups (coat, sheen, anisotropy,
  bump) that the stored vertices use, so a diffuse scene pays for none. Property: the same
  image, bit for bit, as tables that carry every group in every batch (the general layout
  before), on a scene that uses three of them on different materials, and to float32 rounding
  (:func:`_same_to_float32`) on a scene without any group, whose lean tables let the Lambert
  connection ends compute in float32; and the tables hold exactly the groups the scene's
  materials use.
- In a scene of plain diffuse materials (``PreparedScene.lambert_only``) the connections
  gather no glossy parameters (alpha, IOR, tint) of their vertices. Property: the same image
  as the general gather, bit for bit for light tracing, to float32 rounding for BDPT (whose
  lean ends are float32).
- Light tracing connects its vertices to the pinhole with the occlusion query alone when no
  material is transparent. Property: the same image, bit for bit, as the transmittance walk
  (:func:`core.integrators.shadows.shadow_transmittance`) that a scene with transparent
  materials takes.

- BDPT's ``t = 1`` strategies splat the light vertices of every depth in one batch
  (:func:`core.integrators.connections.connect_cameras`). Property: the same image and
  strategy views, bit for bit, as one batch per depth (``connect_camera`` for ``s = 2, 3,
  ...``), on plain diffuse vertices, on coated / sheen / anisotropic ones, under smooth
  shading and through a transparent leaf; and where depths mix plain-Lambert and general
  gathers, the per-depth fallback is taken and equals the loop.

Smallest error detected: any difference at all (the passes are compared for equality).
"""

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.film import PixelFilter
from sampling_lab.core.integrators import bidir, connections, subpaths
from sampling_lab.core.integrators.base import Counters
from sampling_lab.core.integrators.bdpt import BDPT
from sampling_lab.core.prepare import prepare
from sampling_lab.core.render import render
from sampling_lab.core.sampling.samplers import make_sampler
from sampling_lab.tools.transparent import transparent_scene
from tests.bdpt_probes import bdpt_images, layered_cornell, seen_at_connect
from tests.helpers import plain_settings


def _diffuse_scene():
    return scenes.cornell_box(16, 16, "mesh")


def _layered_scene():
    return layered_cornell(16)


def _passes(scene):
    return bdpt_images(scene, spp=2, seed=3, max_bounces=4)


def _with_every_group(monkeypatch):
    """Subpath tables as before: every optional group present (neutral) in every batch."""
    empty, reset = subpaths._empty_params, subpaths.Subpath.reset

    def reset_keeping_every_group(self):
        out = reset(self)
        out._set_table(out.all_params.with_all_groups())
        return out

    monkeypatch.setattr(subpaths, "_empty_params", lambda n: empty(n).with_all_groups())
    monkeypatch.setattr(subpaths.Subpath, "reset", reset_keeping_every_group)


def _same_to_float32(a, b):
    """BDPT's float32 Lambert connection ends against float64 ones: within 1e-5 relative
    (measured at most 6e-7 in any pass, 2026-11-26); a changed value, density or weight, or a
    dropped connection, is off by more."""
    np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-7 * max(np.abs(b).max(), 1e-30))


@pytest.mark.parametrize("make_scene, exact", [(_diffuse_scene, False), (_layered_scene, True)],
                         ids=["diffuse", "coat sheen aniso"])
def test_bdpt_image_is_the_same_with_only_the_groups_the_scene_uses(make_scene, exact,
                                                                    monkeypatch):
    lean = _passes(make_scene())
    with monkeypatch.context() as m:
        _with_every_group(m)
        full = _passes(make_scene())
    assert len(lean) == len(full) > 2
    for a, b in zip(lean, full):
        (np.testing.assert_array_equal if exact else _same_to_float32)(a, b)
    assert np.isfinite(lean[0]).all() and lean[0].max() > 0


@pytest.mark.parametrize("make_scene, expected", [(_diffuse_scene, set()),
                                                  (_layered_scene, {"coat", "sheen", "aniso"})],
                         ids=["diffuse", "coat sheen aniso"])
def test_subpath_tables_hold_the_groups_the_materials_use(make_scene, expected):
    seen = seen_at_connect(make_scene(), lambda ctx, C, L: {
        g for g in ("coat", "sheen", "aniso", "bump")
        if C.all_params.has(g) or L.all_params.has(g)})
    assert seen == expected


@pytest.mark.parametrize("make_scene", [_diffuse_scene, _layered_scene],
                         ids=["diffuse", "coat sheen aniso"])
def test_light_tracing_image_is_the_same_without_the_transmittance_walk(make_scene):
    scene = make_scene()
    settings = plain_settings(integrator="light", spp=2, seed=3, threads=1, max_bounces=4)
    first = render(scene, settings)
    prep = first.prepared
    assert prep.material_transparency is None  # the fast path was taken
    # Every material opaque, but through the general walk (zero transparency, not None).
    prep.material_transparency = np.zeros((len(scene.materials.kind), 3))
    general = render(scene, settings, prepared=prep)
    np.testing.assert_array_equal(first.combined(), general.combined())
    np.testing.assert_array_equal(first.variance(), general.variance())
    # The walk also traces a closest-hit ray per blocked connection, to find the blocker opaque.
    assert first.stats["rays"] < general.stats["rays"]
    assert np.isfinite(first.combined()).all() and first.combined().max() > 0


@pytest.mark.parametrize("integrator", ["light", "bdpt"])
def test_lambert_gathers_give_the_same_image_as_the_general_gather(integrator):
    scene = _diffuse_scene()
    settings = plain_settings(integrator=integrator, spp=2, seed=3, threads=1, max_bounces=4)
    lean = render(scene, settings)
    prep = lean.prepared
    assert prep.lambert_only
    prep.lambert_only = False  # gather every parameter column
    general = render(scene, settings, prepared=prep)
    same = np.testing.assert_array_equal if integrator == "light" else _same_to_float32
    same(lean.combined(), general.combined())
    same(lean.variance(), general.variance())
    assert lean.combined().max() > 0


def test_bdpt_batch_is_the_same_in_chunks_of_any_size():
    """BDPT's work units and chunks grow with a shallow depth (``bdpt._unit_paths``): each
    sample's contributions do not depend on the chunk it is rendered in (its random numbers,
    subpaths, connections and weights are its own), only the order of the splats does."""
    scene = _layered_scene()
    settings = plain_settings(integrator="bdpt", spp=1, max_bounces=4, strategy_views=True,
                              strategy_max_length=3)
    integ = BDPT(prepare(scene), settings)
    assert integ.unit_paths == integ.chunk_paths == 1 << 14  # shallow: the larger units
    sampler = make_sampler("independent", seed=2, spp=2, width=16)
    pixel_filter = PixelFilter(settings.filter_type, settings.filter_width)
    outs = []
    for chunk in (512, 100):
        integ.chunk_paths = chunk
        stream = sampler.stream(np.tile(np.arange(256), 2), np.repeat(np.arange(2), 256))
        outs.append(integ.render_samples(stream, pixel_filter, Counters()))

    def splats(s):
        rows = np.column_stack([s.xy, s.value])
        return rows[np.lexsort(rows.T[::-1])]

    one, many = outs
    np.testing.assert_array_equal(one.radiance, many.radiance)
    np.testing.assert_array_equal(splats(one.splats), splats(many.splats))
    assert one.camera_layers.keys() == many.camera_layers.keys()
    assert one.splat_layers.keys() == many.splat_layers.keys() and len(one.camera_layers) > 2
    for name in one.camera_layers:
        np.testing.assert_array_equal(one.camera_layers[name], many.camera_layers[name])
    for name in one.splat_layers:
        np.testing.assert_array_equal(splats(one.splat_layers[name]),
                                      splats(many.splat_layers[name]))
    assert one.radiance.max() > 0 and len(one.splats.xy) > 100


def _depth_by_depth(ctx, L, out):
    """``t = 1`` as before connect_cameras: one connect_camera call per light depth."""
    for s in range(2, L.valid.shape[0] + 1):
        if not L.valid[s - 1].any():
            break
        connections.connect_camera(ctx, L, s, out)


@pytest.mark.parametrize("make_scene", [
    _diffuse_scene, _layered_scene,
    lambda: scenes.cornell_sphere(16, 16, ball="mirror", light="area", roughness=0.3,
                                  smooth=True),
    lambda: transparent_scene("leaf")], ids=["diffuse", "coat sheen aniso", "smooth rough",
                                             "transparent leaf"])
def test_bdpt_splats_every_light_depth_at_once_as_depth_by_depth(make_scene, monkeypatch):
    calls = []
    one_depth = connections.connect_camera
    with monkeypatch.context() as m:
        m.setattr(connections, "connect_camera", lambda *a: calls.append(a) or one_depth(*a))
        fused = _passes(make_scene())
    assert not calls  # every depth in one batch (not the per-depth fallback)
    with monkeypatch.context() as m:
        m.setattr(bidir, "connect_cameras", _depth_by_depth)
        loop = _passes(make_scene())
    assert len(fused) == len(loop) > 2
    for a, b in zip(fused, loop):
        np.testing.assert_array_equal(a, b)
    assert np.isfinite(fused[0]).all() and fused[0].max() > 0


def test_bdpt_splats_depth_by_depth_where_depths_gather_differently(monkeypatch):
    """Where some light depths are all plain Lambert and others are not (gathered by
    different code), connect_cameras falls back to one connect_camera per depth: the
    fallback is taken, and the image equals the per-depth loop's."""
    real = connections.all_lambert

    def mixed(smooth, subs, j=None):  # odd depths Lambert, even depths general
        return real(smooth, subs, j) and (j is None or j % 2 == 1)

    calls = []
    one_depth = connections.connect_camera
    with monkeypatch.context() as m:
        m.setattr(connections, "all_lambert", mixed)
        m.setattr(connections, "connect_camera", lambda *a: calls.append(a) or one_depth(*a))
        fused = _passes(_diffuse_scene())
    assert calls  # the fallback ran
    with monkeypatch.context() as m:
        m.setattr(connections, "all_lambert", mixed)
        m.setattr(bidir, "connect_cameras", _depth_by_depth)
        loop = _passes(_diffuse_scene())
    for a, b in zip(fused, loop):
        np.testing.assert_array_equal(a, b)
    assert fused[0].max() > 0
