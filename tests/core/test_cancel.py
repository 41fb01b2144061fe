"""Cancel (Esc in Blender, Ctrl-C on the command line) through the core's ``cancel`` hook, for
every integrator: the render stops, says it was cancelled and keeps the samples it finished.

No wall-clock time is asserted but a bound only a hang would break (:data:`HANG_S`); the
latency itself is measured by ``python -m sampling_lab bench-limits`` (docs/LIMITS.md).
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from sampling_lab.core import scenes
from sampling_lab.core.integrators import INTEGRATORS
from sampling_lab.core.render import render
from tests.helpers import plain_settings

HANG_S = 60.0
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
            asked.append(time.perf_counter())

    result = render(scene, _settings(integrator), cancel=lambda: bool(asked),
                    on_update=on_update)
    waited = time.perf_counter() - asked[0]
    assert result.cancelled
    assert waited < HANG_S
    done = result.stats["spp"]
    assert 0 < done < SPP
    count = result.sample_count()
    # Every pixel holds the finished passes (units in flight when cancel came are kept too).
    assert count.min() >= done and np.isfinite(result.combined()).all()
    rgb = result.combined()[..., :3]
    assert rgb.max() > 0


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_cancel_at_once_keeps_only_the_work_under_way(integrator):
    """Cancel already set when the render starts (a pass here is several work units): the
    units in flight are finished and kept, no pass completes; photon mapping and SPPM drop
    their unfinished pass, radiosity stops inside its solve; the image is finite."""
    scene = scenes.cornell_box(64, 48, "point")
    t0 = time.perf_counter()
    result = render(scene, _settings(integrator), cancel=lambda: True)
    assert time.perf_counter() - t0 < HANG_S
    assert result.cancelled
    assert result.stats["spp"] == 0
    kept = result.sample_count().sum()
    if integrator in ("path", "light", "bdpt"):
        assert 0 < kept < scene.camera.width * scene.camera.height * 64
    else:
        assert kept == 0
    assert np.isfinite(result.combined()).all()
