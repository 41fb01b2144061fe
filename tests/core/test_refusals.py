"""What the core refuses on purpose raises ``core.errors.RenderRefused`` (a ``ValueError``
with a message for the user), and nothing else does: Blender and the command line show a
refusal as one line and any other exception as a failure with its traceback.
"""

from __future__ import annotations

import dataclasses

import pytest

from sampling_lab.core import scenes
from sampling_lab.core.errors import RenderRefused
from sampling_lab.core.film import check_film_memory
from sampling_lab.core.render import RenderSettings, render


def _scene(**camera):
    scene = scenes.cornell_box(8, 6, "point")
    for name, value in camera.items():
        setattr(scene.camera, name, value)
    return scene


REFUSED = {
    "no samples, no time limit": (_scene, dict(spp=0, time_limit=0.0), "sample count"),
    "an option out of range": (_scene, dict(photon_k=0), "photon_k"),
    "a region outside the frame": (_scene, dict(region=(0, 0, 9, 6)), "render region"),
    "photons over their memory cap": (
        _scene, dict(integrator="sppm", photons=1 << 26, photon_memory=1.0), "photon storage"),
    "Hammersley without a sample count": (
        _scene, dict(sampler="hammersley", spp=0, time_limit=0.5), "Hammersley"),
    "radiosity patches over the solver's limit": (
        _scene, dict(integrator="radiosity", radiosity_solver="gauss_seidel",
                     radiosity_patch_size=0.001), "patches"),
}


@pytest.mark.parametrize("case", list(REFUSED))
def test_deliberate_refusals_raise_render_refused(case):
    make, settings, words = REFUSED[case]
    with pytest.raises(RenderRefused, match=words):
        render(make(), RenderSettings(**{"spp": 1, **settings}))


def test_a_film_larger_than_memory_is_refused_unless_its_region_is_small():
    with pytest.raises(RenderRefused, match="needs about"):
        check_film_memory(65536, 65536)
    check_film_memory(65536, 65536, region=(0, 0, 8, 8))


def test_a_bug_half_way_is_an_error_with_a_traceback_and_a_refusal_is_not(monkeypatch):
    from sampling_lab.core.integrators import path

    def failing(error):
        def render_samples(self, *args):
            raise error
        return render_samples

    scene = _scene()
    for error, has_traceback in ((ValueError("shapes not aligned"), True),
                                 (RenderRefused("refused"), False)):
        monkeypatch.setattr(path.PathTracer, "render_samples", failing(error))
        result = render(scene, RenderSettings(spp=1, threads=1))
        assert result.error.endswith(str(error))
        assert (result.traceback is not None) == has_traceback
        if has_traceback:
            assert "render_samples" in result.traceback
