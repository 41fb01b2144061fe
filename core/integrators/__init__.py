"""Integrators: one module per estimator. ``INTEGRATORS`` maps names to modules."""

from . import bdpt, light, path

INTEGRATORS = {"path": path, "light": light, "bdpt": bdpt}
