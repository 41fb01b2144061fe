"""Render settings of Sampling Lab, stored on the scene as ``scene.sampling_lab``.

The ``description=`` strings are the user documentation: Blender shows them as tooltips.
"""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty
from bpy.types import PropertyGroup

# (identifier, UI name, description); the identifier lower-cased is core's name for it.
INTEGRATOR_ITEMS = (
    ('PATH', "Path Tracing",
     "Unidirectional path tracing with next-event estimation and multiple importance sampling. "
     "Unbiased and consistent; the reference estimator the others are compared with"),
    ('LIGHT', "Light Tracing",
     "Particles traced from the lights, each vertex connected to the camera and splatted onto "
     "the film. Unbiased; good for caustics seen directly (light through glass or off a mirror "
     "onto a diffuse surface), but it cannot find paths the camera sees through a specular "
     "surface (mirrors and glass in view render black). No MIS: one strategy per path"),
    ('BDPT', "Bidirectional",
     "Bidirectional path tracing: a camera subpath and a light subpath, joined by every "
     "connection strategy (s light vertices, t camera vertices) and combined by multiple "
     "importance sampling with the Light Sampling panel's MIS heuristic. Unbiased; robust for caustics and "
     "indirectly lit scenes, where one strategy's noise is another's strength"),
)

# Samplers the UI offers when a sampler class carries no label or description of its own.
_SAMPLER_FALLBACK = {
    "independent": (
        "Independent",
        "Independent uniform random numbers for every sample and dimension (plain Monte Carlo). "
        "Error falls as 1/sqrt(samples); the baseline other samplers are measured against"),
}


def sampler_items():
    """EnumProperty items for every sampler ``core.sampling.samplers.available()`` lists.

    Each item is ``(NAME, label, description)`` from the sampler class's ``label`` and
    ``description`` (falling back to a known text, the first line of the class or module
    docstring, then the name). A sampler module that fails to import is left out, so one broken
    sampler cannot stop the add-on from registering.
    """
    import importlib

    from ..core.sampling.samplers import available, sampler_class

    items = []
    for name in available():
        try:
            cls = sampler_class(name)
        except Exception:  # noqa: BLE001 - a sampler being written must not break the add-on
            continue
        fallback_label, fallback_desc = _SAMPLER_FALLBACK.get(name, (None, None))
        label = getattr(cls, "label", None) or fallback_label or name.replace("_", " ").title()
        doc = cls.__doc__ or importlib.import_module(cls.__module__).__doc__ or ""
        description = (getattr(cls, "description", None) or fallback_desc
                       or doc.strip().split("\n")[0].strip() or f"{label} sampler")
        items.append((name.upper(), str(label), str(description).strip().rstrip(".")))
    if not any(item[0] == "INDEPENDENT" for item in items):
        label, description = _SAMPLER_FALLBACK["independent"]
        items.insert(0, ("INDEPENDENT", label, description))
    return tuple(items)


SAMPLER_ITEMS = sampler_items()

MIS_ITEMS = (
    ('POWER', "Power Heuristic",
     "Multiple importance sampling of light and BSDF samples with weights p^beta / sum p^beta "
     "(Veach). Unbiased; beta = 2 is the usual choice, cutting noise from both small lights "
     "and broad reflections"),
    ('BALANCE', "Balance Heuristic",
     "MIS with weights proportional to each strategy's density (the power heuristic with "
     "beta = 1). Unbiased; provably close to the best weights, a little noisier than power"),
    ('MAXIMUM', "Maximum Heuristic",
     "MIS where the strategy with the larger density takes the whole sample. Unbiased; "
     "the limit of the power heuristic for large beta"),
    ('CUTOFF', "Cutoff Heuristic",
     "MIS where strategies whose density is below alpha times the largest get weight zero "
     "and the rest share by the balance heuristic. Unbiased"),
    ('NONE', "None (Average)",
     "Both strategies with constant weight 1/2: the unweighted average of light sampling and "
     "BSDF sampling. Unbiased, but without MIS's variance reduction: each strategy's noisy "
     "cases are only halved"),
    ('BSDF', "BSDF Sampling Only",
     "No light sampling: direct light only where a BSDF-sampled ray happens to hit an emitter "
     "(weight one). Unbiased for area, mesh, sphere and sun-disk lights, but point, spot and "
     "sharp sun lights can never be hit and render black: a teaching baseline"),
    ('LIGHT', "Light Sampling Only",
     "Next-event estimation only (weight one); emitters found by rays after a bounce are "
     "dropped where light sampling could have picked them. Unbiased; emitters seen directly "
     "by the camera still show. Noisy for glossy surfaces and huge lights"),
)

LIGHT_SELECTION_ITEMS = (
    ('POWER', "Power",
     "Choose the light to sample in proportion to its estimated emitted power. Unbiased; "
     "best when brighter lights contribute more"),
    ('UNIFORM', "Uniform",
     "Choose every light with the same probability: each lamp, each emission material (all "
     "triangles sharing it count as one light, and a triangle inside it is chosen in "
     "proportion to area times radiance) and the world. Unbiased; lights that emit nothing "
     "are skipped"),
)

LIGHT_SAMPLING_ITEMS = (
    ('AREA', "Area",
     "Sample points uniformly over the surface of area lights and emissive triangles. "
     "Unbiased; noisy close to large lights, whose near parts are undersampled"),
    ('SOLID_ANGLE', "Solid Angle",
     "Sample directions uniformly over the solid angle that an emitter subtends: spherical "
     "triangles (Arvo) for emissive triangles, spherical rectangles (Urena et al.) for square "
     "and rectangular area lights. Unbiased; much less noise near large lights. Disk and "
     "ellipse lights, and emitters seen under a tiny or near-hemispherical solid angle, stay "
     "area-sampled"),
)

DISTRIBUTION_ITEMS = (
    ('CDF', "CDF Inversion",
     "Discrete choices (which light, which emissive triangle, which component of a mixed "
     "material) by binary search in a "
     "cumulative distribution: O(log n) per sample, preserves the stratification of the "
     "sampler's numbers"),
    ('ALIAS', "Alias Table",
     "Discrete choices by Walker's alias method (Vose's construction): O(1) per sample after "
     "an O(n) build, but scrambles the stratification of the sampler's numbers"),
)

FILTER_ITEMS = (
    ('BOX', "Box",
     "Box filter: every sample counts only for the pixel it falls in"),
    ('BLACKMAN_HARRIS', "Blackman-Harris",
     "Blackman-Harris window, as Cycles' default pixel filter (importance sampled, so every "
     "camera sample has weight one). Cycles doubles the width for this filter: a width of "
     "1.5 pixels gives a 3 pixel wide footprint"),
)


def _update_render_passes(self, context):
    """Let Blender ask the engine for its passes again (compositor sockets, render result),
    as Cycles does when a pass setting changes."""
    view_layer = getattr(context, "view_layer", None)
    if view_layer is not None:
        view_layer.update_render_passes()


class SamplingLabSettings(PropertyGroup):
    """Per-scene render settings of the Sampling Lab engine."""

    integrator: EnumProperty(
        name="Integrator",
        description="Light transport estimator: which Monte Carlo estimator of the rendering "
                    "equation computes each pixel",
        items=INTEGRATOR_ITEMS,
        default='PATH',
        update=_update_render_passes,
    )
    sampler: EnumProperty(
        name="Sampler",
        description="How the random numbers of each pixel sample are generated: independent, "
                    "stratified, low-discrepancy or blue-noise sequences trade the same work "
                    "for a different error",
        items=SAMPLER_ITEMS,
        default='INDEPENDENT',
    )
    samples: IntProperty(
        name="Samples",
        description="Number of samples per pixel. The render stops after this many, or "
                    "earlier when the time limit runs out",
        default=16, min=1, max=1 << 24, soft_max=4096,
    )
    time_limit: FloatProperty(
        name="Time Limit",
        description="Stop rendering after this many seconds, keeping the samples taken so far. "
                    "Zero means no limit (render all samples)",
        default=0.0, min=0.0, soft_max=3600.0, step=100, precision=1,
        subtype='TIME_ABSOLUTE', unit='TIME_ABSOLUTE',
    )
    viewport_samples: IntProperty(
        name="Viewport Samples",
        description="Samples per pixel of the rendered 3D viewport, which refines its image "
                    "pass by pass until it has this many. Zero means no limit (render until the "
                    "view or the scene changes)",
        default=1024, min=0, max=1 << 24, soft_max=4096,
    )
    seed: IntProperty(
        name="Seed",
        description="Seed of the sample streams. The same seed, samples and scene give the same "
                    "image; change it to get an independent render of the same scene "
                    "(e.g. to measure variance)",
        default=0, min=0,
    )
    use_animated_seed: BoolProperty(
        name="Animate Seed",
        description="Use a different seed on each frame (Seed plus the frame number, as Cycles' "
                    "Animate Seed), so the noise of an animation changes from frame to frame "
                    "instead of staying fixed on the screen",
        default=False,
    )
    max_bounces: IntProperty(
        name="Max Bounces",
        description="Maximum number of surface interactions of a path. Cutting paths short "
                    "loses the light they would have carried (a bias toward darker images)",
        default=8, min=0, max=1024, soft_max=64,
    )
    use_russian_roulette: BoolProperty(
        name="Russian Roulette",
        description="Terminate low-throughput paths at random and reweight the survivors. "
                    "Unbiased: it trades a little variance for a lot less work on long paths",
        default=True,
    )
    rr_min_bounces: IntProperty(
        name="Min Bounces",
        description="Number of bounces every path survives before Russian roulette may "
                    "terminate it",
        default=3, min=0, max=1024, soft_max=64,
    )
    mis_heuristic: EnumProperty(
        name="MIS",
        description="How light sampling (next-event estimation) and BSDF sampling are "
                    "combined for direct light: a multiple importance sampling heuristic, "
                    "their plain average, or one strategy alone. Bidirectional weights all its "
                    "connection strategies with the same heuristic. Light tracing has no MIS",
        items=MIS_ITEMS,
        default='POWER',
    )
    mis_beta: FloatProperty(
        name="Beta",
        description="Exponent of the power heuristic: 1 is the balance heuristic, 2 the usual "
                    "choice, large values approach the maximum heuristic",
        default=2.0, min=0.01, max=100.0, soft_min=0.5, soft_max=8.0, precision=2,
    )
    mis_alpha: FloatProperty(
        name="Alpha",
        description="Cutoff of the cutoff heuristic: a strategy whose density is below alpha "
                    "times the largest one gets weight zero (0 is the balance heuristic, "
                    "1 the maximum heuristic)",
        default=0.1, min=0.0, max=1.0, precision=3, subtype='FACTOR',
    )
    light_selection: EnumProperty(
        name="Light Selection",
        description="How next-event estimation chooses which light to sample",
        items=LIGHT_SELECTION_ITEMS,
        default='POWER',
    )
    light_sampling: EnumProperty(
        name="Area Lights",
        description="Path Tracing only: how next-event estimation samples a point on an "
                    "area light or emissive triangle, uniformly by area or uniformly over the "
                    "solid angle it covers. Light Tracing and Bidirectional start their light "
                    "paths on emitters sampled by area",
        items=LIGHT_SAMPLING_ITEMS,
        default='AREA',
    )
    distribution: EnumProperty(
        name="Discrete Sampling",
        description="Data structure for discrete choices (lights, emissive triangles, mixed "
                    "materials' components): CDF "
                    "inversion or an alias table. Its build and sampling times are shown in "
                    "the render stats",
        items=DISTRIBUTION_ITEMS,
        default='CDF',
    )
    use_strategy_views: BoolProperty(
        name="Strategy Views",
        description="Bidirectional only: write two render passes per BDPT strategy (s, t) with "
                    "s light and t camera vertices, for paths up to Max Path Length: the "
                    "strategy's own estimate (as if it were the only one) and its MIS-weighted "
                    "share of the image (the weighted shares of one path length add up to that length's "
                    "part of Combined)",
        default=False,
        update=_update_render_passes,
    )
    strategy_max_length: IntProperty(
        name="Max Path Length",
        description="Longest path, in segments, that gets strategy views: 1 is emitters seen "
                    "directly, 2 direct light, 3 one indirect bounce, and so on. A path of k "
                    "segments has k + 1 strategies, so the number of passes grows "
                    "quadratically",
        default=3, min=1, max=8,
        update=_update_render_passes,
    )
    filter_type: EnumProperty(
        name="Pixel Filter",
        description="Pixel reconstruction filter: how camera samples spread over pixels",
        items=FILTER_ITEMS,
        default='BLACKMAN_HARRIS',
    )
    filter_width: FloatProperty(
        name="Width",
        description="Pixel filter width in pixels (as Cycles' filter width)",
        default=1.5, min=0.01, max=10.0, soft_max=5.0, precision=2,
        subtype='PIXEL',
    )


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
