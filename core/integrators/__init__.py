"""Integrators: one module per estimator, each an :class:`.base.Integrator` (the contract the
render loop relies on; see :mod:`.base`).

``INTEGRATORS`` maps a name to the estimator's module (its docstring is the estimator's manual
page); :func:`integrator_class` gives the :class:`.base.Integrator` subclass a render builds.
No estimator module imports another:

- :mod:`.path`: path tracing (:class:`.path.PathTracer`);
- :mod:`.light` and :mod:`.bdpt`: light tracing and bidirectional path tracing, both
  :class:`.bidir.Bidirectional` integrators over the same subpaths (:mod:`.subpaths`), ``s = 0``
  hits (:mod:`.camera_hits`), connections (:mod:`.connections`), MIS densities
  (:mod:`.mis_densities`) and per-strategy images (:mod:`.strategy_views`);
- :mod:`.photon`: Jensen's two-pass photon mapping (:class:`.photon.PhotonMapping`, biased but
  consistent);
- :mod:`.sppm`: stochastic progressive photon mapping (:class:`.sppm.SPPM`, biased but
  consistent), over the photon stages of :mod:`core.photons`;
- :mod:`.radiosity`: finite-element radiosity (:class:`.radiosity.Radiosity`), solved once
  per render by :mod:`core.radiosity` and shown by camera rays or one final-gather bounce;
- :mod:`.mlt`: Metropolis light transport in primary sample space (:class:`.mlt.MLT`,
  consistent with its normalisation estimated), Markov chains over the path tracer's numbers;
- :mod:`.common`: stages every estimator shares (camera rays, intersection, surface
  interactions, emitters along rays, Russian roulette).
"""

from . import bdpt, light, mlt, path, photon, radiosity, sppm
from .base import Integrator

INTEGRATORS = {"path": path, "light": light, "bdpt": bdpt, "photon": photon, "sppm": sppm,
               "radiosity": radiosity, "mlt": mlt}

_CLASSES = {"path": path.PathTracer, "light": light.LightTracer, "bdpt": bdpt.BDPT,
            "photon": photon.PhotonMapping, "sppm": sppm.SPPM,
            "radiosity": radiosity.Radiosity, "mlt": mlt.MLT}


def integrator_class(name) -> type[Integrator]:
    """The :class:`.base.Integrator` subclass of the estimator called ``name``."""
    return _CLASSES[name]
