"""Integrators: one module per estimator. ``INTEGRATORS`` maps names to modules."""

from . import path

INTEGRATORS = {"path": path}
