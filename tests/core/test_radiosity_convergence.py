"""Radiosity is biased, and consistent only as the mesh refines: the lecture's point in numbers.

On the diffuse Cornell box (area lamp, hidden from the camera so that its edge's antialiasing
noise does not swamp the comparison) a long path-traced render is the reference. For each
radiosity render the squared bias is estimated without the noise of either image:

    bias^2 ~ mean (I - R)^2 - mean Var[I] - mean Var[R]

(the films' per-pixel variances of their means). The test checks that this error shrinks as
the patches shrink (each step by more than z standard errors of the paired per-pixel
difference), reports the fitted rate, and shows that at a fixed mesh more samples per pixel
do not remove it: the bias stays many times the remaining noise.
"""

from __future__ import annotations

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.render import render
from tests.helpers import z_for_false_failure, plain_settings

SIZES = (1.0, 0.5, 0.25)


@pytest.fixture(scope="module")
def room():
    scene = scenes.cornell_box(16, 16, "area")
    scene.lights.visible_camera[:] = False
    ref = render(scene, plain_settings(integrator="path", spp=2048, max_bounces=16, seed=9))
    return scene, ref.combined()[..., :3].astype(np.float64), ref.variance().astype(np.float64)


def _radiosity(scene, patch_size, spp):
    r = render(scene, plain_settings(integrator="radiosity", radiosity_solver="hierarchical",
                                     radiosity_patch_size=patch_size, radiosity_samples=8,
                                     spp=spp, seed=1))
    return r.combined()[..., :3].astype(np.float64), r.variance().astype(np.float64)


def _bias2(image, var, ref, var_ref):
    """Per-pixel estimates of the squared bias ``(n,)``, normalised by the mean of ref^2."""
    d2 = ((image - ref) ** 2 - var - var_ref).reshape(-1)
    return d2 / np.mean(ref ** 2)


def test_error_against_path_tracing_shrinks_as_patches_shrink(room, record_property):
    scene, ref, var_ref = room
    per_pixel = [_bias2(*_radiosity(scene, h, 1024), ref, var_ref) for h in SIZES]
    bias2 = [float(p.mean()) for p in per_pixel]
    z = z_for_false_failure(1e-4, comparisons=len(SIZES) - 1)
    for coarse, fine in zip(per_pixel, per_pixel[1:]):
        diff = coarse - fine
        assert diff.mean() > z * diff.std(ddof=1) / np.sqrt(diff.size), bias2
    rate = np.polyfit(np.log(SIZES), np.log(bias2), 1)[0]
    record_property("radiosity_bias2_by_patch_size", dict(zip(SIZES, bias2)))
    record_property("radiosity_bias2_rate", rate)
    print(f"relative squared bias {dict(zip(SIZES, np.round(bias2, 5)))}, "
          f"fitted rate bias^2 ~ h^{rate:.2f}")
    assert rate > 0


def test_at_a_fixed_mesh_more_samples_leave_the_bias(room):
    scene, ref, var_ref = room
    few = _radiosity(scene, 1.0, 64)
    many = _radiosity(scene, 1.0, 1024)
    noise = np.mean(many[1] + var_ref) / np.mean(ref ** 2)
    bias2 = _bias2(*many, ref, var_ref)
    # The error that remains is many times what the two images' noise can explain ...
    assert bias2.mean() > 20 * noise
    # ... and sixteen times the samples did not change it beyond its standard error.
    diff = _bias2(*few, ref, var_ref) - bias2
    z = z_for_false_failure(1e-4)
    se = diff.std(ddof=1) / np.sqrt(diff.size)
    assert abs(diff.mean()) <= z * se
    # Power: had the error dropped by a quarter, this would have seen it.
    assert z * se < 0.25 * bias2.mean()


def test_adaptive_subdivision_lowers_the_error_of_its_starting_mesh(room):
    scene, ref, var_ref = room

    def run(adaptive):
        r = render(scene, plain_settings(integrator="radiosity", radiosity_patch_size=1.0,
                                         radiosity_adaptive=adaptive, radiosity_samples=8,
                                         spp=1024, seed=1))
        image = r.combined()[..., :3].astype(np.float64)
        return _bias2(image, r.variance().astype(np.float64), ref, var_ref), r.stats

    uniform, stats_u = run(0.0)
    adapted, stats_a = run(0.05)
    assert stats_a["radiosity_adaptive_rounds"] >= 1
    assert stats_a["radiosity_patch_count"] > stats_u["radiosity_patch_count"]
    diff = uniform - adapted
    z = z_for_false_failure(1e-4)
    print(f"adaptive: {stats_u['radiosity_patch_count']} -> {stats_a['radiosity_patch_count']} "
          f"patches, relative squared bias {uniform.mean():.5f} -> {adapted.mean():.5f}")
    assert diff.mean() > z * diff.std(ddof=1) / np.sqrt(diff.size)
