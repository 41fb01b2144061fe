"""BDPT's connection ends on plain Lambert vertices (:mod:`core.integrators.lambert_vertices`)
give the general gather's values (to the last bit from float64 columns, to float32 rounding
in a render, whose lean ends are float32), and are used only where they apply.

The unit comparison is exact (``assert_array_equal``), the renders' within 1e-5 relative: any
change of a value, a density, an MIS weight or a dropped row fails.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.integrators import connections, lambert_vertices
from sampling_lab.core.integrators.lambert_vertices import LambertVertices, all_lambert
from sampling_lab.core.integrators.subpaths import Gathered
from sampling_lab.core.materials.bsdf import IMPORTANCE, RADIANCE, KIND_DIFFUSE, BSDFParams
from sampling_lab.core.materials.frame import shading_frame, to_local
from sampling_lab.core.render import render
from tests.bdpt_probes import seen_at_connect
from tests.helpers import plain_settings


def _unit(rng, m):
    v = rng.normal(size=(m, 3))
    return v / np.linalg.norm(v, axis=1)[:, None]


@pytest.mark.parametrize("mode", [RADIANCE, IMPORTANCE])
def test_lambert_vertex_values_equal_the_general_gathers_bit_for_bit(mode):
    rng = np.random.default_rng(7)
    m = 4000
    ng = _unit(rng, m)
    frame = shading_frame(ng)
    wo, w = _unit(rng, m), _unit(rng, m)
    w[:50] = frame[0][:50]  # in the tangent plane: z exactly zero
    wo[50:100] = frame[1][50:100]
    color = rng.uniform(0.0, 1.0, (m, 3))
    params = BSDFParams(np.full(m, KIND_DIFFUSE, np.int32), color, np.ones(m), np.ones(m),
                        np.zeros((m, 3)))
    wo_l = to_local(wo, *frame)
    general = Gathered.of(False, mode, params, frame, None, wo_l, ng)
    lean = LambertVertices(color, frame[2], wo_l[:, 2], ng)
    w_l, z = general.local(w), lean.local(w)
    np.testing.assert_array_equal(z, w_l[:, 2])
    np.testing.assert_array_equal(lean.f(w, z), general.f(w, w_l))
    np.testing.assert_array_equal(lean.pdf_toward(z), general.pdf_toward(w_l))
    np.testing.assert_array_equal(lean.pdf_back(z), general.pdf_back(w_l))
    keep = np.arange(0, m, 3)
    dens, ref = lean.for_densities(keep), general.for_densities(keep)
    np.testing.assert_array_equal(dens.pdf_back(z[keep]), ref.pdf_back(w_l[keep]))
    np.testing.assert_array_equal(dens.ng, ref.ng)
    # Both sides of the surface and both lobes occur (the test is not one-sided).
    assert (lean.f(w, z).max(axis=1) > 0).mean() > 0.3 and (lean.pdf_back(z) == 0).mean() > 0.3


def _mirror_ball():
    return scenes.cornell_sphere(16, 16, ball="mirror", light="area")


def _rough_ball():
    return scenes.cornell_sphere(16, 16, ball="mirror", light="area", roughness=0.3)


def _passes(scene, monkeypatch, general):
    """Combined, variance and every strategy layer of a small BDPT render, with the lean
    gather where it applies or (``general``) the general one everywhere; and the lean
    gathers made."""
    made = []
    lean_at = LambertVertices.at

    def counted(sub, index):
        made.append(index.size)
        return lean_at(sub, index)

    with monkeypatch.context() as m:
        m.setattr(LambertVertices, "at", staticmethod(counted))
        if general:  # the connections' and the t = 1 splats' lean gathers both off
            never = lambda *args: False  # noqa: E731
            m.setattr(lambert_vertices, "all_lambert", never)
            m.setattr(connections, "all_lambert", never)
        settings = plain_settings(integrator="bdpt", spp=2, seed=3, threads=1, max_bounces=4,
                                  strategy_views=True, strategy_max_length=3)
        result = render(scene, settings)
    layers = result.layers()
    return [result.combined(), result.variance(), *[layers[n] for n in result.layer_names]], made


@pytest.mark.parametrize("make_scene", [lambda: scenes.cornell_box(16, 16, "mesh"), _mirror_ball],
                         ids=["diffuse box", "mirror ball"])
def test_bdpt_image_is_the_same_with_lambert_vertices(make_scene, monkeypatch):
    lean, made = _passes(make_scene(), monkeypatch, general=False)
    full, none = _passes(make_scene(), monkeypatch, general=True)
    assert sum(made) > 1000 and not none  # the lean gather was taken, then not
    assert len(lean) == len(full) > 2
    # The lean gather forms the values in float32 (Subpath's float32 positions, throughputs
    # and wo_z): the same to float32 rounding, here at most 2e-7 relative in Combined and
    # 6e-7 in any pass (2026-11-26); a value, density or weight off by more than 1e-5, or
    # a dropped or added connection, fails.
    for a, b in zip(lean, full):
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-7 * max(np.abs(b).max(), 1e-30))
    assert np.isfinite(lean[0]).all() and lean[0].max() > 0


@pytest.mark.parametrize("make_scene, expected", [
    (lambda: scenes.cornell_box(16, 16, "mesh"), True),
    (_mirror_ball, True),  # the delta mirror's vertices are never connected
    (_rough_ball, False),  # a rough conductor is
    (lambda: scenes.cornell_sphere(16, 16, ball="mirror", light="area", smooth=True), False),
], ids=["diffuse box", "mirror ball", "rough ball", "smooth shading"])
def test_lambert_vertices_only_where_every_connected_vertex_is_lambert(make_scene, expected):
    seen = seen_at_connect(make_scene(), lambda ctx, C, L: all_lambert(ctx.smooth, (L, C)))
    assert seen is expected
    assert lambert_vertices.all_lambert(True, ()) is False
