"""BDPT's subpath tables between batches (issue 12, sixth round: the walks).

A worker thread reuses its subpath tables from one chunk to the next; ``Subpath.recycle``
clears the columns that decide which vertices exist (``valid``, ``connectible``, ``delta``,
the reverse densities; the transparent pass counts where a walk stored some) but leaves the
columns that the walk writes whole at every vertex it makes (position, normals, frame,
directions, throughput, forward density, edge, triangle, BSDF table) at vertices ``1..D-1`` as
the last chunk left them. In a flat-shaded scene ``fn`` is ``ng`` (and without anisotropic
tangents ``fs`` and ``ft`` are never stored, but gathered from each triangle's frame); in a
Lambert-only one the glossy BSDF columns are never stored.

Property: no reader looks at those stale or unstored entries. Each recycle here fills them
with NaN (triangles with -1, and the BSDF kinds with an unknown code, which every BSDF call
refuses); the BDPT
passes (combined, variance and the strategy layers) must equal, bit for bit, those of the
plain recycle, over several chunks per thread, on a diffuse scene, a smooth-shaded rough
coated ball (the smooth-only columns) and a scene with coat, sheen and anisotropy groups.

Smallest error detected: any read of a stale entry that reaches the film (a NaN or an error
where there was a number), and any other difference at all.
"""

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.integrators import subpaths
from tests.bdpt_probes import bdpt_images, layered_cornell


def _diffuse():
    return scenes.cornell_box(24, 24, "mesh")


def _smooth_coat():
    # A rough (connectible) smooth-shaded ball: its vertices read the smooth-only columns.
    return scenes.cornell_sphere(24, 24, ball="coat", light="area", roughness=0.3, smooth=True)


def _layered():
    return layered_cornell(24)


def _transparent():
    # Light subpaths pass the sheet straight through: their pass counts are stored.
    from sampling_lab.tools.transparent import transparent_scene

    return transparent_scene("sheet_between_light_and_floor", size=24)


def _passes(scene, **kw):
    # 24 x 24 x 64 = 36,864 paths: three chunks on the one thread (two recycles per side).
    return bdpt_images(scene, spp=64, seed=5, max_bounces=5, **kw)


def _poisoning(monkeypatch, calls):
    recycle = subpaths.Subpath.recycle

    def recycle_then_poison(self):
        out = recycle(self)
        calls.append(1)
        # Pass counts are cleared where a walk stored some, and never stored elsewhere.
        assert not out.passed.any() and not out.passes_stored
        for name in subpaths._STORED:
            column = getattr(out, name)[1:]
            column.fill(np.nan if column.dtype.kind == "f" else -1)  # prim: no triangle
        n, table = out.valid.shape[1], out.all_params
        table.kind[n:] = -1
        for column in (table.color, table.alpha, table.eta, table.tint):
            column[n:] = np.nan
        return out

    monkeypatch.setattr(subpaths.Subpath, "recycle", recycle_then_poison)


@pytest.mark.parametrize("make_scene", [_diffuse, _smooth_coat, _layered, _transparent],
                         ids=["diffuse", "smooth coat", "coat sheen aniso", "transparent sheet"])
def test_bdpt_never_reads_the_entries_a_recycle_leaves(make_scene, monkeypatch):
    plain = _passes(make_scene())
    calls = []
    with monkeypatch.context() as m:
        _poisoning(m, calls)
        poisoned = _passes(make_scene())
    assert len(calls) >= 4  # both sides' tables were reused (and poisoned) at least twice
    assert len(plain) == len(poisoned) > 2
    for a, b in zip(plain, poisoned):
        np.testing.assert_array_equal(a, b)
    assert np.isfinite(plain[0]).all() and plain[0].max() > 0


def test_to_area_converts_finite_edges_and_leaves_infinite_ones_unchanged():
    """``to_area`` (solid angle -> area density): ``pdf |cos| / d^2`` where the edge is
    finite, the solid-angle density itself toward infinite endpoints; a batch of finite
    edges only (its fast path) gives the same values, bit for bit, as the same rows mixed
    with infinite ones."""
    from sampling_lab.core.integrators.subpaths import to_area

    rng = np.random.default_rng(5)
    pdf, cos = rng.uniform(0.1, 2.0, 64), rng.uniform(-1.0, 1.0, 64)
    dist = rng.uniform(0.01, 5.0, 64)
    finite = to_area(pdf, cos, dist)
    np.testing.assert_allclose(finite, pdf * np.abs(cos) / dist ** 2, rtol=1e-15)
    mixed_dist = dist.copy()
    mixed_dist[::3] = np.inf
    mixed = to_area(pdf, cos, mixed_dist)
    np.testing.assert_array_equal(mixed[1::3], finite[1::3])
    np.testing.assert_array_equal(mixed[::3], pdf[::3])


def test_bdpt_per_strategy_weights_never_read_the_entries_a_recycle_leaves(monkeypatch):
    """As above for the heuristics weighed strategy by strategy (``maximum``: every stored
    density of the path read by :mod:`.mis_densities`, not by the running sums)."""
    plain = _passes(_diffuse(), mis_heuristic="maximum")
    calls = []
    with monkeypatch.context() as m:
        _poisoning(m, calls)
        poisoned = _passes(_diffuse(), mis_heuristic="maximum")
    assert len(calls) >= 4
    for a, b in zip(plain, poisoned):
        np.testing.assert_array_equal(a, b)
    assert np.isfinite(plain[0]).all() and plain[0].max() > 0


def _resetting_whole(monkeypatch, calls):
    recycle = subpaths.Subpath.recycle

    def recycle_then_reset_whole(self):
        # What Subpath.reset adds to a recycle: every stored column and the BSDF table back
        # to Subpath.empty's values, vertex 0 included.
        out = recycle(self)
        calls.append(1)
        out.passed.fill(0)
        for name, value in subpaths._STORED.items():
            getattr(out, name).fill(value)
        for column, value in subpaths._table_base(out.all_params):
            column.fill(value)
        return out

    monkeypatch.setattr(subpaths.Subpath, "recycle", recycle_then_reset_whole)


@pytest.mark.parametrize("make_scene", [_diffuse, _smooth_coat, _layered, _transparent],
                         ids=["diffuse", "smooth coat", "coat sheen aniso", "transparent sheet"])
def test_bdpt_with_recycled_tables_equals_bdpt_with_tables_reset_whole(make_scene,
                                                                       monkeypatch):
    """``recycle`` resets of vertex 0 only what the walk writes there (``pdf_rev``): the
    setups write their columns of vertex 0 whole every batch and nothing else writes there.
    The passes equal, bit for bit, those of tables reset whole (as :meth:`Subpath.empty`
    makes them) before every batch."""
    plain = _passes(make_scene())
    calls = []
    with monkeypatch.context() as m:
        _resetting_whole(m, calls)
        whole = _passes(make_scene())
    assert len(calls) >= 4
    assert len(plain) == len(whole) > 2
    for a, b in zip(plain, whole):
        np.testing.assert_array_equal(a, b)
