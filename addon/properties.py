"""Render settings of Sampling Lab, stored on the scene as ``scene.sampling_lab``.

The render options (names, menus, defaults, ranges and the ``description=`` strings Blender
shows as tooltips, the user documentation) come from :data:`core.options.OPTIONS`, which the
command line and the core's validation read too; this module adds only how Blender presents
them. ``viewport_samples`` and ``use_animated_seed`` are the add-on's own (no core setting).
"""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty
from bpy.types import PropertyGroup

from ..core.options import OPTIONS, identifier, menu_value


def enum_items(option):
    """``EnumProperty`` items ``(IDENTIFIER, label, description)`` of a menu option."""
    return tuple((c.identifier, c.label, c.description) for c in option.choices)


def _property(name, **ui):
    """The property of render option ``name`` (``core.options.OPTIONS``): its label, tooltip,
    default, items or range come from the registry; ``ui`` adds presentation (soft limits,
    precision, subtype, update) and may narrow the range, never widen it."""
    o = OPTIONS[name]
    common = dict(name=o.label, description=o.description, **ui)
    if o.choices:
        return EnumProperty(items=enum_items(o), default=identifier(o.default), **common)
    if o.kind is bool:
        return BoolProperty(default=o.default, **common)
    limits = {k: v for k, v in (("min", o.minimum), ("max", o.maximum)) if v is not None}
    cls = IntProperty if o.kind is int else FloatProperty
    return cls(default=o.default, **{**limits, **common})


def core_values(props):
    """The render options of ``props`` (a ``SamplingLabSettings``) as core values, by
    ``RenderSettings`` field: menu identifiers lower-cased, numbers and switches converted.
    Options without a property here (``threads``: Blender's own setting) are left out."""
    out = {}
    for name, o in OPTIONS.items():
        if not hasattr(props, o.prop_name):
            continue
        value = getattr(props, o.prop_name)
        out[name] = menu_value(value) if o.choices else o.kind(value)
    return out


def _update_render_passes(self, context):
    """Let Blender ask the engine for its passes again (compositor sockets, render result),
    as Cycles does when a pass setting changes."""
    view_layer = getattr(context, "view_layer", None)
    if view_layer is not None:
        view_layer.update_render_passes()


class SamplingLabSettings(PropertyGroup):
    """Per-scene render settings of the Sampling Lab engine."""

    integrator: _property("integrator", update=_update_render_passes)
    sampler: _property("sampler")
    # Blender renders a sample count; the time-only render (0 samples) is the CLI's --time.
    samples: _property("spp", min=1, soft_max=4096)
    time_limit: _property("time_limit", soft_max=3600.0, step=100, precision=1,
                          subtype='TIME_ABSOLUTE', unit='TIME_ABSOLUTE')
    viewport_samples: IntProperty(
        name="Viewport Samples",
        description="Samples per pixel of the rendered 3D viewport, which refines its image "
                    "pass by pass until it has this many. Zero means no limit (render until the "
                    "view or the scene changes)",
        default=1024, min=0, max=1 << 24, soft_max=4096,
    )
    seed: _property("seed")
    use_animated_seed: BoolProperty(
        name="Animate Seed",
        description="Use a different seed on each frame (Seed plus the frame number, as Cycles' "
                    "Animate Seed), so the noise of an animation changes from frame to frame "
                    "instead of staying fixed on the screen",
        default=False,
    )
    max_bounces: _property("max_bounces", soft_max=64)
    diffuse_bounces: _property("diffuse_bounces", soft_max=64)
    glossy_bounces: _property("glossy_bounces", soft_max=64)
    transmission_bounces: _property("transmission_bounces", soft_max=64)
    transparent_max_bounces: _property("transparent_max_bounces", soft_max=64)
    use_russian_roulette: _property("use_russian_roulette")
    rr_min_bounces: _property("rr_min_bounces", soft_max=64)
    rr_survival: _property("rr_survival")
    connection_roulette: _property("connection_roulette", soft_max=1.0, precision=2)
    light_points: _property("light_points")
    mis_heuristic: _property("mis_heuristic")
    mis_beta: _property("mis_beta", soft_min=0.5, soft_max=8.0, precision=2)
    mis_alpha: _property("mis_alpha", precision=3, subtype='FACTOR')
    light_selection: _property("light_selection")
    light_sampling: _property("light_sampling")
    distribution: _property("distribution")
    use_strategy_views: _property("strategy_views", update=_update_render_passes)
    strategy_max_length: _property("strategy_max_length", update=_update_render_passes)
    photons: _property("photons", soft_min=1000, soft_max=10_000_000)
    photon_radius: _property("photon_radius", soft_max=1.0, precision=4, subtype='DISTANCE',
                             unit='LENGTH')
    sppm_alpha: _property("sppm_alpha", precision=2, subtype='FACTOR')
    photon_memory: _property("photon_memory", soft_max=16384.0, precision=0)
    photon_lookup: _property("photon_lookup")
    photon_k: _property("photon_k", soft_max=500)
    photon_kernel: _property("photon_kernel")
    use_photon_surface_test: _property("photon_surface_test")
    sppm_radius: _property("sppm_radius")
    use_sppm_coverage: _property("sppm_coverage")
    gather_rays: _property("gather_rays", soft_max=64)
    radiosity_solver: _property("radiosity_solver")
    radiosity_patch_size: _property("radiosity_patch_size", soft_min=0.01, soft_max=2.0,
                                    precision=3, subtype='DISTANCE', unit='LENGTH')
    radiosity_samples: _property("radiosity_samples", soft_max=64)
    radiosity_adaptive: _property("radiosity_adaptive", soft_max=0.5, precision=3,
                                  subtype='FACTOR')
    radiosity_display: _property("radiosity_display")
    use_radiosity_patches: _property("radiosity_patches", update=_update_render_passes)
    mlt_large_step: _property("mlt_large_step", precision=2, subtype='FACTOR')
    mlt_bootstrap: _property("mlt_bootstrap", soft_min=1000, soft_max=10_000_000)
    mlt_chains: _property("mlt_chains", soft_min=64, soft_max=65536)
    filter_type: _property("filter_type")
    filter_width: _property("filter_width", soft_max=5.0, precision=2, subtype='PIXEL')
    # Final renders only: the viewport always renders on threads (addon/viewport.py).
    workers: _property("workers")


classes = (SamplingLabSettings,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.sampling_lab = bpy.props.PointerProperty(
        type=SamplingLabSettings,
        name="Sampling Lab",
        description="Render settings of the Sampling Lab engine",
    )


def unregister():
    del bpy.types.Scene.sampling_lab
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
