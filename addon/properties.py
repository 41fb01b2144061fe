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
)

SAMPLER_ITEMS = (
    ('INDEPENDENT', "Independent",
     "Independent uniform random numbers for every sample and dimension (plain Monte Carlo). "
     "Error falls as 1/sqrt(samples); the baseline other samplers are measured against"),
)

FILTER_ITEMS = (
    ('BOX', "Box",
     "Box filter: every sample counts only for the pixel it falls in"),
    ('BLACKMAN_HARRIS', "Blackman-Harris",
     "Blackman-Harris window, as Cycles' default pixel filter (importance sampled, so every "
     "camera sample has weight one). Cycles doubles the width for this filter: a width of "
     "1.5 pixels gives a 3 pixel wide footprint"),
)


class SamplingLabSettings(PropertyGroup):
    """Per-scene render settings of the Sampling Lab engine."""

    integrator: EnumProperty(
        name="Integrator",
        description="Light transport estimator: which Monte Carlo estimator of the rendering "
                    "equation computes each pixel",
        items=INTEGRATOR_ITEMS,
        default='PATH',
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
    seed: IntProperty(
        name="Seed",
        description="Seed of the sample streams. The same seed, samples and scene give the same "
                    "image; change it to get an independent render of the same scene "
                    "(e.g. to measure variance)",
        default=0, min=0,
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
