"""Cancel (Esc in Blender, Ctrl-C on the command line) through the core's ``cancel`` hook, for
every integrator: the render stops, says it was cancelled and keeps the samples it finished.

No wall-clock time is asserted: a render that ignored the cancel would finish its samples
(``0 < spp < SPP`` fails), and the latency itself is measured by ``python -m sampling_lab bench-limits`` (docs/LIMITS.md).
"""

from __future__ import annotations


import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.film import PixelFilter
from sampling_lab.core.integrators import INTEGRATORS, integrator_class
from sampling_lab.core.integrators.base import Counters
from sampling_lab.core.prepare import prepare
from sampling_lab.core.render import render
from sampling_lab.core.sampling.samplers import make_sampler
from sampling_lab.core.sampling.stream import Aborted
from tests.helpers import plain_settings

SPP = 100_000  # far more than a test renders: only cancel stops it


def _settings(integrator):
    return plain_settings(integrator=integrator, spp=SPP, photons=2000, threads=2,
                          radiosity_patch_size=1.0, radiosity_samples=1)


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_cancel_after_a_pass_keeps_the_finished_samples(integrator):
    scene = scenes.cornell_box(16, 12, "point")
    asked = []

    def on_update(result):
        if not asked:
            asked.append(True)

    result = render(scene, _settings(integrator), cancel=lambda: bool(asked),
                    on_update=on_update)
    assert result.cancelled
    done = result.stats["spp"]
    assert 0 < done < SPP
    count = result.sample_count()
    # Every pixel holds the finished passes (units in flight when cancel came are kept too).
    assert count.min() >= done and np.isfinite(result.combined()).all()
    rgb = result.combined()[..., :3]
    assert rgb.max() > 0


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_cancel_at_once_renders_no_pass(integrator):
    """Cancel already set when the render starts: no pass completes (the units in flight stop
    at their next bounce, photon mapping and SPPM drop their pass, radiosity stops inside its
    solve) and the image is finite."""
    scene = scenes.cornell_box(64, 48, "point")
    result = render(scene, _settings(integrator), cancel=lambda: True)
    assert result.cancelled
    assert result.stats["spp"] == 0
    assert np.isfinite(result.combined()).all()


@pytest.mark.parametrize("integrator", ["path", "light", "bdpt", "radiosity"])
def test_a_work_unit_stops_at_its_first_bounce_once_aborted(integrator):
    """The render loop's cancel reaches work units in flight: every integrator that renders
    units starts each bounce (or subpath vertex) with ``skip_to``, which raises ``Aborted``
    once the stream's ``abort()`` says so (radiosity's final gather; its other displays trace
    one camera ray per sample and no bounce)."""
    scene = scenes.cornell_box(8, 8, "point")
    settings = _settings(integrator)
    settings.radiosity_display = "final_gather"
    prep = prepare(scene)
    integrator_obj = integrator_class(integrator)(prep, settings)
    integrator_obj.prepare_render()
    pixels = np.repeat(np.arange(64), 4)
    stream = make_sampler("independent", seed=1).stream(pixels, np.tile(np.arange(4), 64))
    asked = []

    def abort():
        asked.append(1)
        return True

    stream.abort = abort
    with pytest.raises(Aborted):
        integrator_obj.render_samples(stream, PixelFilter("box", 1.0), Counters())
    assert len(asked) == 1


def test_sppm_image_does_not_depend_on_the_lookup_chunk(monkeypatch):
    """SPPM's photon lookups run in tasks of ``QUERY_CHUNK`` visible points, so that cancel is
    polled between small tasks; how the points are cut changes only the order of each pixel's
    sum of photon contributions, so the image agrees to rounding with one task per thread.
    The smallest difference this detects: a relative 1e-12 of the brightest pixel (a point
    counted twice or lost changes its pixel by a whole photon's share)."""
    from sampling_lab.core.integrators import sppm

    scene = scenes.cornell_box(24, 18, "point")
    settings = plain_settings(integrator="sppm", spp=2, photons=4000, threads=2)
    images = []
    for chunk in (1 << 30, 37):
        monkeypatch.setattr(sppm, "QUERY_CHUNK", chunk)
        images.append(render(scene, settings).combined()[..., :3])
    whole, cut = images
    assert whole.max() > 0
    np.testing.assert_allclose(cut, whole, rtol=0, atol=1e-12 * whole.max())


@pytest.mark.parametrize("polls_before_cancel", [0, 6, 7])
def test_cancel_while_preparing_stops_between_stages(polls_before_cancel, monkeypatch):
    """Cancel is polled while a scene of more than ``TABLE_CHUNK`` triangles is prepared
    (a 10 M triangle scene took 16 s): after leaving out non-finite triangles, after
    recentring, after each chunk of the triangle tables (5 here), after Embree's BVH and
    after the light tables. A render cancelled there returns at that poll, without samples,
    with an empty film; the BVH is built only when cancel comes after the tables."""
    from sampling_lab.core import prepare as prepare_module
    from sampling_lab.core.hard_cases import many_triangles

    scene = many_triangles(300_000, 8, 6)
    chunks = -(-scene.n_triangles // prepare_module.TABLE_CHUNK)
    assert chunks == 5
    built = []

    class CountingAccel(prepare_module.Accel):
        """Counts the builds; its BVH build does not poll (its polls are timed, every
        ``POLL_S``: tests/core/test_bvh_cancel.py checks them)."""

        def build(self, cancel=None):
            built.append(1)
            super().build(None)

    monkeypatch.setattr(prepare_module, "Accel", CountingAccel)
    polls = []

    def cancel():
        polls.append(1)
        return len(polls) > polls_before_cancel

    result = render(scene, _settings("path"), cancel=cancel)
    assert result.cancelled and result.stats["spp"] == 0
    assert len(polls) == polls_before_cancel + 1  # stopped at the first poll that said so
    assert len(built) == (polls_before_cancel >= 2 + chunks)
    assert result.sample_count().max() == 0 and np.isfinite(result.combined()).all()


def test_a_small_scene_is_prepared_without_polling_cancel():
    polls = []
    result = render(scenes.cornell_box(16, 12, "point"), _settings("path"),
                    cancel=lambda: polls.append(1) or True)
    # Preparing finished (its result is kept); the first poll was the render loop's.
    assert result.cancelled and result.prepared is not None


def test_triangle_tables_do_not_depend_on_the_chunk_size():
    """The tables are computed in chunks so that cancel is polled between them; each row
    depends on its triangle alone, so any chunking gives the same bits (a row computed twice,
    skipped or shifted would not)."""
    from sampling_lab.core.hard_cases import many_triangles
    from sampling_lab.core.prepare import triangle_tables

    scene = many_triangles(5000)
    polls = []
    whole = triangle_tables(scene, chunk=1 << 30)
    cut = triangle_tables(scene, poll=lambda: polls.append(1), chunk=777)
    assert len(polls) == -(-scene.n_triangles // 777)
    for a, b in zip(whole, cut):
        assert np.array_equal(a, b)
    assert whole[4].sum() > 0


@pytest.mark.parametrize("lookup", ["knn", "radius"])
def test_photon_mapping_image_does_not_depend_on_the_lookup_step(lookup, monkeypatch):
    """Photon mapping's density estimates run in steps with a cancel poll before each
    (``LOOKUP_PAIRS // k`` points for k-nearest, ``QUERY_CHUNK`` for a fixed radius). Each
    point's estimate is its own: k-nearest gives the same bits with any step; a fixed radius's
    pairs come in another order, so its sums agree to rounding (1e-12 of the brightest pixel;
    a point counted twice or lost changes its pixel by a whole photon's share)."""
    from sampling_lab.core.photons import estimate

    scene = scenes.cornell_box(24, 18, "point")
    settings = plain_settings(integrator="photon", spp=1, photons=4000, threads=2,
                              photon_lookup=lookup, photon_k=20, photon_radius=0.1)
    images = []
    for pairs, chunk in ((1 << 40, 1 << 30), (20 * 7, 37)):
        monkeypatch.setattr(estimate, "LOOKUP_PAIRS", pairs)
        monkeypatch.setattr(estimate, "QUERY_CHUNK", chunk)
        images.append(render(scene, settings).combined()[..., :3])
    whole, cut = images
    assert whole.max() > 0
    if lookup == "knn":
        assert np.array_equal(cut, whole)
    else:
        np.testing.assert_allclose(cut, whole, rtol=0, atol=1e-12 * whole.max())
