"""Integrators: one module per estimator, each an :class:`.base.Integrator` (the contract the
render loop relies on; see :mod:`.base`).

``INTEGRATORS`` maps a name to the estimator's module (its docstring is the estimator's manual
page); :func:`integrator_class` gives the :class:`.base.Integrator` subclass a render builds.
Shared stages are in :mod:`.common`; no estimator module imports another.
"""

from . import bdpt, light, path
from .base import Integrator

INTEGRATORS = {"path": path, "light": light, "bdpt": bdpt}

_CLASSES = {"path": path.PathTracer, "light": light.LightTracer, "bdpt": bdpt.BDPT}


def integrator_class(name) -> type[Integrator]:
    """The :class:`.base.Integrator` subclass of the estimator called ``name``."""
    return _CLASSES[name]
