"""Light endpoints' fast paths (issue 12, eighth round) against the general code they replace.

- ``Segmented1D.pick`` (an element and its probability, no remapped number) returns what
  :meth:`Segmented1D.sample` returns, for one segment (its start, length and base are numbers,
  not gathers) and for several, both methods, at the CDF's boundaries and past zero-mass
  elements.
- Power selection of a scene whose only lights are one emissive mesh skips the lamp and world
  masks: property, the emitter rows and probabilities are those of the two distributions'
  ``sample`` (the general formula), bit for bit; so is a scene with a lamp and a mesh (the
  general branch, now through ``pick``).
- Emissive triangles' light-path origins are formed axis by axis from 1-D gathers
  (``EmissiveTriangles._points_of``) and, where every row chose a triangle, as whole arrays:
  property, the points equal ``v0 + b1 e1 + b2 e2`` of the gathered corners and the normals and densities
  the row-scatter formulas, bit for bit, for all rows and for a subset of rows. Their
  cosine directions, written as whole arrays where every row chose a triangle, equal the
  scattered rows of the same draw, and light paths' directions, radiance and densities from
  ``Emission.sample_directions`` (which skips its selections where every density is positive)
  equal the selections' values.
- Area lamps' light-path origins and directions: whole arrays where every row chose an area
  lamp, and each lamp's tangent frame made once (``AreaLights.le_s``, ``le_t``) instead of per
  sample; property, the points, normals, densities and directions equal the per-row formulas
  bit for bit, with one lamp (whole arrays) and with an area lamp beside a point lamp (rows).

Smallest error detected: any difference at all (byte equality of the compared arrays).
"""

import dataclasses

import numpy as np
import pytest

from sampling_lab.core import lights as L
from sampling_lab.core import scenes
from sampling_lab.core.lights.base import LeDirections, LeOrigins
from sampling_lab.core.prepare import prepare
from sampling_lab.core.sampling import warps
from sampling_lab.core.scene import Lights
from sampling_lab.core.sampling.distributions import Segmented1D


def _same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def _numbers(n, seed=0):
    u = np.random.default_rng(seed).random(n)
    u[:6] = [0.0, 0.25, 0.5, 0.75, 1.0 - 2.0**-53, 0.5 - 2.0**-54]
    return u


@pytest.mark.parametrize("method", ["cdf", "alias"])
@pytest.mark.parametrize("func, offsets", [
    ([1.0, 1.0], [0, 2]),                      # one quad light: two equal triangles
    ([3.0], [0, 1]),                           # one triangle
    ([1.0, 0.0, 2.0, 0.0, 1.0], [0, 5]),       # zero-mass elements inside the segment
    ([1.0, 2.0, 0.0, 4.0, 1.0], [0, 2, 5]),    # several segments (the general search)
])
def test_pick_returns_the_element_and_probability_of_sample(method, func, offsets):
    dist = Segmented1D(np.array(func), np.array(offsets), method)
    u = _numbers(5000)
    segment = np.arange(u.size) % (len(offsets) - 1)
    index, pmf, _ = dist.sample(segment, u)
    got_index, got_pmf = dist.pick(segment, u)
    assert _same(got_index, index) and _same(got_pmf, pmf)


def _with_lamp(scene):
    lamp = L.point_light((0.3, 0.2, 1.5), (1, 1, 1), 30.0, radius=0.0, name="Lamp")
    return dataclasses.replace(scene, lights=Lights.concat([scene.lights, lamp]))


def _reference_choose(sel, u):
    """Light paths' emitter choice by the distributions' ``sample`` (the general formula)."""
    k = sel.n_lamps
    light, pmf, u_next = sel.light_dist.sample(u)
    index = light.copy()
    m = np.nonzero((light >= k) & (light < k + sel.n_groups))[0]
    e, pmf_tri, _ = sel.triangle_dist.sample(light[m] - k, u_next[m])
    index[m] = k + e
    pmf[m] = pmf[m] * pmf_tri
    return index, pmf


@pytest.mark.parametrize("lamp", [False, True])
@pytest.mark.parametrize("n", [100, 5000])
def test_light_path_emitter_choice_equals_the_general_formula(lamp, n):
    scene = scenes.cornell_box(16, 16, light="mesh")
    sampler = prepare(_with_lamp(scene) if lamp else scene, "power").emission.ls
    u = _numbers(n, seed=n)
    index, pmf = sampler.choose(u)
    ref_index, ref_pmf = _reference_choose(sampler.path_selector, u)
    assert _same(index, ref_index) and _same(pmf, ref_pmf)
    lamps = sampler.path_selector.n_lamps
    assert (lamps > 0) == lamp and (index < lamps).any() == lamp


@pytest.mark.parametrize("lamp", [False, True])
@pytest.mark.parametrize("n", [100, 5000])
def test_triangle_origins_equal_the_row_gather_formulas(lamp, n):
    scene = scenes.cornell_box(16, 16, light="mesh")
    ls = prepare(_with_lamp(scene) if lamp else scene, "power").emission.ls
    tris = ls.triangles
    rng = np.random.default_rng(n)
    u, u_sel = rng.random((n, 2)), rng.random(n)
    index, pmf = ls.choose(u_sel)
    m = np.nonzero(index >= ls.path_selector.n_lamps)[0]
    e = index[m] - ls.path_selector.n_lamps
    out = LeOrigins.empty(n)
    tris.sample_le_origin(m, e, u, pmf, out)
    ref_p = np.zeros((n, 3))
    _, b1, b2 = warps.uniform_triangle_barycentrics(u[m])
    ref_p[m] = tris.emit_v0[e] + b1[:, None] * tris.emit_e1[e] + b2[:, None] * tris.emit_e2[e]
    ref_normal = np.zeros((n, 3))
    ref_normal[m] = tris.emit_normal[e]
    ref_pdf = np.zeros(n)
    ref_pdf[m] = pmf[m] / tris.emit_area[e]
    assert (m.size < n) == lamp
    assert _same(out.p, ref_p) and _same(out.normal, ref_normal) and _same(out.pdf, ref_pdf)


def _directions(n):
    w = np.zeros((n, 3))
    w[:, 2] = 1.0
    return LeDirections(np.zeros((n, 3)), w, np.zeros(n), np.ones(n))


@pytest.mark.parametrize("n", [100, 5000])
def test_triangle_directions_as_whole_arrays_equal_the_scattered_rows(n):
    em = prepare(scenes.cornell_box(16, 16, light="mesh"), "power").emission
    rng = np.random.default_rng(n)
    pts = em.sample_points(rng.random(n), rng.random((n, 2)))
    u = rng.random((n, 2))
    tris, m, e = em.ls.triangles, np.arange(n), pts.index - em.ls.path_selector.n_lamps
    whole, scattered = _directions(n), _directions(n + 1)  # one spare row: the scatter path
    tris.sample_le_direction(m, e, pts, u, whole)
    tris.sample_le_direction(m, e, pts, u, scattered)
    for name in ("w", "pdf", "cos_l"):
        assert _same(getattr(whole, name), getattr(scattered, name)[:n])
    origin, w, pdf, cos_l, le = em.sample_directions(pts, u)
    assert (pdf > 0).all() and _same(w, whole.w) and _same(cos_l, whole.cos_l)
    assert _same(pdf, np.where(pdf > 0, whole.pdf, 0.0))
    ref_le = em.radiance(pts.index, origin, pts.normal, w, None)
    assert _same(le, np.where((pdf > 0)[:, None], ref_le, 0.0))


@pytest.mark.parametrize("lamp", [False, True])
def test_area_lamp_origins_and_directions_equal_the_per_row_formulas(lamp):
    scene = scenes.cornell_box(16, 16, light="area")
    em = prepare(_with_lamp(scene) if lamp else scene, "power").emission
    area = next(f for f in em.ls.families if hasattr(f, "le_s"))
    n = 3000
    rng = np.random.default_rng(7)
    u_sel, u_pos, u_dir = rng.random(n), rng.random((n, 2)), rng.random((n, 2))
    pts = em.sample_points(u_sel, u_pos)
    origin, w, pdf, cos_l, le = em.sample_directions(pts, u_dir)
    m = np.nonzero(~pts.delta_light)[0]  # the area lamp's rows (the point lamp is a delta)
    assert (m.size < n) == lamp and m.size > 0
    li = pts.index[m]
    q, size, _ = area._points(li, u_pos[m])
    normal = area.lights.direction[li]
    assert _same(pts.p[m], q) and _same(pts.normal[m], normal)
    pmf = em.ls.choose(u_sel)[1][m]
    assert _same(pts.pdf_origin[m], np.where(size > 0, pmf / np.maximum(size, 1e-300), 0.0))
    uu = u_dir[m].copy()
    uu[:, 0] = np.minimum(uu[:, 0], 1 - 1e-16)
    local = warps.sample_cosine_hemisphere(uu)
    ref_w = warps.to_world(local, *warps.frame_from_normal(normal), normal)
    assert _same(w[m], ref_w) and _same(cos_l[m], local[:, 2])
    assert _same(pdf[m], warps.cosine_hemisphere_pdf(local[:, 2]))


def test_li_samples_keep_fresh_whole_arrays_and_copy_views_and_partial_rows():
    # Property: put() stores what a row scatter would, and keeps a whole fresh array as the
    # field itself only where no one else can see it (a read-only broadcast is copied).
    from sampling_lab.core.lights.base import LiSamples

    n = 5
    every, some = np.arange(n), np.array([1, 3])
    out = LiSamples.empty(n)
    fresh = np.random.default_rng(0).random((n, 3))
    out.put("wi", every, fresh)
    assert out.wi is fresh
    view = np.broadcast_to(np.array([1.0, 2.0, 3.0]), (n, 3))
    out.put("radiance", every, view)
    assert out.radiance is not view and out.radiance.flags.writeable
    np.testing.assert_array_equal(out.radiance, view)
    out.put("pdf", some, np.array([7.0, 8.0]))
    np.testing.assert_array_equal(out.pdf, [0.0, 7.0, 0.0, 8.0, 0.0])
    out.put("dist", every, np.ones(n, np.float32))  # another type: converted into the field
    assert out.dist.dtype == np.float64 and np.all(out.dist == 1.0)
