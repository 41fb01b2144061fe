"""Lights in Cycles' units: one module per light family, their selection, and the samplers.

Constructors (:func:`point_light`, :func:`sun_light`, :func:`area_light`) turn Blender's light
settings (S = color x energy, in W or W/m^2) into the radiometric quantities of
:class:`core.scene.Lights`:

- point / spot of radius 0: intensity S / (4 pi) W/sr (spot: times its smoothstep cone falloff,
  not renormalised); radius r > 0: a sphere of radiance S / (4 pi^2 r^2);
- sun: irradiance S W/m^2; with angular diameter a > 0, a disk of radiance S / (pi sin^2(a/2));
- area: radiance S / (pi A), one-sided toward the light's local -Z (A x pi/4 for disk, ellipse).

Modules:

- :mod:`.base`: the :class:`~.base.LightFamily` contract every family implements
  (``sample_li``, ``pdf_li``, ``intersect``, ``sample_le_*``, ``pdf_le_*``, ``le``) and the
  batches they fill;
- :mod:`.point` (point, spot, sphere), :mod:`.area` (rectangle, disk, ellipse), :mod:`.sun`,
  :mod:`.environment` (constant world and environment map), :mod:`.triangles` (emissive
  triangles): the families;
- :mod:`.shapes`: the ray tests against lamp shapes (sphere, facing disk, parallelogram);
- :mod:`.selection`: how an emitter is chosen (power, uniform, light tree) and :mod:`.tree`,
  the light tree (bounds, importance, traversal, exact pmf);
- :mod:`.sampler`: :class:`LightSampler`, every emitter of a scene in one table, for
  next-event estimation and for rays that find emitters;
- :mod:`.emission`: :class:`Emission`, how light paths leave the emitters.

Area and sphere lights are not occluders: as in Cycles, they emit toward rays that pass through
them and never block light.
"""

from .area import area_light
from .base import LUMINANCE
from .emission import Emission, EmitterPoints
from .environment import (environment_importance, environment_lookup, equirect_direction,
                          equirect_uv)
from .point import point_light, spot_attenuation
from .sampler import LIGHT_SAMPLINGS, LIGHT_SELECTIONS, LightSampler
from .sun import sun_light

__all__ = [
    "LIGHT_SAMPLINGS", "LIGHT_SELECTIONS", "LUMINANCE", "Emission", "EmitterPoints",
    "LightSampler", "area_light", "environment_importance", "environment_lookup",
    "equirect_direction", "equirect_uv", "point_light", "spot_attenuation", "sun_light",
]
