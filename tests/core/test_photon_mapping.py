"""Photon mapping (core/integrators/photon.py): renders a point light seen through a mirror
(the caustic map), every lookup setting it shows changes the image, the stats say which
settings were used, and cancel answers while the maps are built."""

from __future__ import annotations

import numpy as np

from sampling_lab.core import render, scenes
from tests.helpers import plain_settings
from tests.core.test_sppm import mirror_reference


def _settings(**kw):
    base = dict(integrator="photon", threads=2, filter_type="box", filter_width=1.0)
    base.update(kw)
    return plain_settings(**base)


def test_photon_mapping_reproduces_the_mirror_image_of_a_point_light():
    """The light a mirror reflects from a point light onto a diffuse floor (closed form: the
    light's mirror image) comes from the caustic map. Fixed radius 0.02 m: the bias allowance
    is 2 r = 4 % of the reflected energy (the floor's share within r of its edges, where the
    lookup disk leaves the floor), the smallest error this test detects; measured +0.5 % and
    -1.2 % for seeds 1 and 2."""
    scene = scenes.mirror_point_light(48, 48)
    direct, reflected, _ = mirror_reference(scene)
    result = render.render(scene, _settings(spp=4, photons=300_000, max_bounces=1, seed=1,
                                            photon_lookup="radius", photon_radius=0.02))
    got = result.film.mean()[..., 0].sum() - direct.sum()
    print(f"reflected energy: closed form {reflected.sum():.3f}, photon mapping {got:.3f}")
    assert abs(got / reflected.sum() - 1) < 2 * 0.02
    assert result.stats["photons_emitted"] == 300_000 and result.stats["photons_stored"] > 0
    assert "biased" in result.stats["estimator_bias"]


def test_every_lookup_setting_shown_changes_the_render():
    scene = scenes.cornell_sphere(16, 16, ball="glass")

    def image(**kw):
        return render.render(scene, _settings(spp=1, photons=20_000, seed=2, **kw)).combined()

    base = image()
    for kw in (dict(photon_kernel="cone"), dict(photon_kernel="epanechnikov"),
               dict(photon_k=10), dict(gather_rays=0), dict(gather_rays=2),
               dict(photon_lookup="radius", photon_radius=0.05),
               dict(photon_surface_test=False)):
        other = image(**kw)
        assert np.isfinite(other).all() and not np.array_equal(base, other), kw
    fixed = image(photon_lookup="radius", photon_radius=0.05)
    assert not np.array_equal(fixed, image(photon_lookup="radius", photon_radius=0.1))


def test_stats_say_which_photon_settings_were_used():
    knn = render.used_settings(_settings(photon_lookup="knn"))
    assert knn["photon_k"] == 50 and knn["photon_radius"] == "n/a"
    assert knn["sppm_alpha"] == "n/a" and knn["mis_heuristic"] == "n/a"
    fixed = render.used_settings(_settings(photon_lookup="radius", photon_radius=0.1))
    assert fixed["photon_radius"] == 0.1 and fixed["photon_k"] == "n/a"
    sppm = render.used_settings(_settings(integrator="sppm"))
    assert sppm["sppm_alpha"] == 0.7 and sppm["photon_kernel"] == "n/a"
    assert sppm["sppm_radius"] == "adaptive" and sppm["photon_surface_test"] is True
    # Footprint radii replace the automatic initial radius only.
    assert render.used_settings(_settings(integrator="sppm", photon_radius=0.1))[
        "sppm_radius"] == "n/a"
    assert knn["sppm_radius"] == "n/a" and knn["photon_surface_test"] is True
    path = render.used_settings(_settings(integrator="path"))
    assert all(path[k] == "n/a" for k in ("photons", "photon_radius", "gather_rays"))


def test_cancel_answers_while_the_photon_maps_are_built():
    polls = []

    def cancel():
        polls.append(1)
        return True

    result = render.render(scenes.cornell_box(8, 8), _settings(spp=4, photons=300_000),
                           cancel=cancel)
    assert result.cancelled and result.stats["spp"] == 0 and len(polls) == 1
    assert result.stats["photons_emitted"] == 0


def test_photon_renders_say_that_soft_falloff_lamps_emit_photons_as_spheres():
    import dataclasses

    from sampling_lab.core import lights

    scene = dataclasses.replace(scenes.cornell_box(8, 8, "point"), lights=lights.point_light(
        (0, 0, 1.7), (1, 1, 1), 60.0, radius=0.05, soft_falloff=True))
    for integrator in ("photon", "sppm"):
        result = render.render(scene, _settings(integrator=integrator, spp=1, photons=1000))
        assert result.messages == [f"{integrator}: Soft Falloff of Point is rendered as a "
                                   f"plain sphere light"]
