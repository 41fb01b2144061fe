"""The integrator contract (core/integrators/base.py): every registered estimator is an
:class:`Integrator` that declares its work-unit size, its layers and whether it splats, returns a
:class:`BatchOutput` for a work unit, and no estimator module imports another."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from sampling_lab.core import integrators, scenes
from sampling_lab.core.film import PixelFilter
from sampling_lab.core.integrators import INTEGRATORS, integrator_class
from sampling_lab.core.integrators.base import BatchOutput, Counters, Integrator
from sampling_lab.core.integrators.common import strategy_pass_names
from sampling_lab.core.prepare import prepare

from sampling_lab.core.sampling.samplers import make_sampler
from tests.helpers import plain_settings

PACKAGE = Path(integrators.__file__).parent


@pytest.fixture(scope="module")
def prep():
    return prepare(scenes.cornell_box(6, 4, "area"))


@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_every_registered_integrator_declares_units_layers_and_splats(name, prep):
    cls = integrator_class(name)
    assert issubclass(cls, Integrator) and cls.__module__ == INTEGRATORS[name].__name__
    assert isinstance(cls.unit_paths, int) and cls.unit_paths > 0
    assert isinstance(cls.splats, bool) and isinstance(cls.strategy_views, bool)
    plain = cls(prep, plain_settings(integrator=name))
    assert plain.layers == ()
    views = cls(prep, plain_settings(integrator=name, strategy_views=True, strategy_max_length=2))
    assert list(views.layers) == (strategy_pass_names(2) if cls.strategy_views else [])


@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_a_work_unit_gives_a_batch_output_with_splats_only_where_declared(name, prep):
    settings = plain_settings(integrator=name, max_bounces=2, strategy_views=True,
                              strategy_max_length=2)
    integrator = integrator_class(name)(prep, settings)
    if integrator.whole_passes:
        _check_whole_pass(integrator)
        return
    pixels = np.repeat(np.arange(24), 2)
    stream = make_sampler("independent", seed=1).stream(pixels, np.tile([0, 1], 24))
    counters = Counters()
    out = integrator.render_samples(stream, PixelFilter(), counters)
    assert isinstance(out, BatchOutput)
    assert out.radiance.shape == (48, 3) and np.isfinite(out.radiance).all()
    assert counters.camera_samples == 48 and counters.rays > 0
    assert (out.splats is not None) == integrator.splats
    assert (out.light_paths > 0) == integrator.splats
    assert set(out.camera_layers) | set(out.splat_layers) <= set(integrator.layers)
    for values in out.camera_layers.values():
        assert values.shape == (48, 3)


def _check_whole_pass(integrator):
    """An integrator that renders whole passes (SPPM) returns one finite, non-negative value
    per film pixel from ``render_pass``, counts its camera samples and rays, and gives None
    when ``map_chunks`` reports a cancel."""
    counters = Counters()
    sampler = make_sampler("independent", seed=1)
    frame_pixels = np.arange(24, dtype=np.int64)
    image = integrator.render_pass(0, frame_pixels, sampler, PixelFilter(), counters,
                                   lambda fn, items: [fn(item) for item in items])
    assert image.shape == (24, 3) and np.isfinite(image).all() and (image >= 0).all()
    assert counters.camera_samples == 24 and counters.rays > 0
    assert integrator.render_pass(1, frame_pixels, sampler, PixelFilter(), counters,
                                  lambda fn, items: None) is None


def _imported_modules(path):
    """Modules of this package that ``path`` imports (relative imports resolved)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            if node.module:
                names.add(node.module.split(".")[0])
            else:
                names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module and (
                ".core.integrators." in f".{node.module}."):
            names.add(node.module.rsplit(".", 1)[-1])
    return names


def test_no_integrator_module_imports_another():
    estimators = set(INTEGRATORS)
    for path in sorted(PACKAGE.glob("*.py")):
        if path.stem == "__init__":
            continue
        imported = _imported_modules(path) & estimators
        assert not imported - {path.stem}, f"{path.name} imports {sorted(imported)}"
