"""Light objects -> rows of :class:`core.scene.Lights`.

Only Blender's values are read here (colour, energy, exposure, size, shape, angles); their
conversion to radiant quantities is :mod:`core.lights`'.
"""

from __future__ import annotations

import math

import numpy as np

from ...core import lights as core_lights


def light_row(ob, matrix, messages):
    """Single-row :class:`core.scene.Lights` for a light object placed by ``matrix (4, 4)``,
    or None for a light type the core does not have (reported)."""
    light = ob.data
    owner = f"Light '{ob.name}'"
    m = np.asarray(matrix, np.float64)
    color = np.asarray(light.color[:3], np.float64)
    if getattr(light, "use_temperature", False):
        color = color * np.asarray(light.temperature_color[:3], np.float64)
    energy = float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))
    visible_camera = bool(getattr(ob, "visible_camera", True))
    name = ob.name
    _report_unsupported(ob, light, owner, messages)

    # The light shines down its local -Z axis.
    down = -m[:3, 2]
    # Blender 4.1+ point and spot lights have Soft Falloff, on by default.
    soft = bool(getattr(light, "use_soft_falloff", False))
    if light.type == 'POINT':
        return core_lights.point_light(m[:3, 3], color, energy, light.shadow_soft_size, name,
                                       visible_camera, soft_falloff=soft)
    if light.type == 'SPOT':
        return core_lights.point_light(m[:3, 3], color, energy, light.shadow_soft_size, name,
                                       visible_camera, spot_direction=down,
                                       spot_size=light.spot_size, spot_blend=light.spot_blend,
                                       soft_falloff=soft)
    if light.type == 'SUN':
        return core_lights.sun_light(down, color, energy, light.angle, name, visible_camera)
    if light.type == 'AREA':
        if getattr(light, "spread", math.pi) < math.pi - 1e-6:
            messages.add(f"{owner}: area light spread is not supported yet; rendered with "
                         f"180 degrees")
        return core_lights.area_light(m, light.shape, light.size, light.size_y, color, energy,
                                      name, visible_camera)
    messages.add(f"{owner}: light type '{light.type}' is not supported; ignored")
    return None


def _report_unsupported(ob, light, owner, messages):
    """Report the settings of light object ``ob`` that every light type ignores."""
    if not getattr(light, "normalize", True):
        messages.add(f"{owner}: 'Normalize' off is not supported yet; rendered normalized")
    if getattr(light, "use_nodes", False) and light.node_tree is not None:
        messages.add(f"{owner}: light nodes are not supported yet; ignored")
    hidden = [label for attr, label in (("visible_diffuse", "diffuse"),
                                        ("visible_glossy", "glossy"),
                                        ("visible_transmission", "transmission"))
              if not getattr(ob, attr, True)]
    if hidden:
        messages.add(f"{owner}: ray visibility ({', '.join(hidden)} off) is not supported for "
                     f"lights yet; ignored")
    if not getattr(light, "use_shadow", True):
        messages.add(f"{owner}: lights without shadows are not supported yet; shadows cast")
