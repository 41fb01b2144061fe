"""Render passes: which ones the engine writes, and copying core images into Blender results.

Besides :data:`PASSES`, Bidirectional renders with Strategy Views on get two RGB passes per
strategy ``(s, t)`` (:func:`core.integrators.common.strategy_pass_names`), named as core's
``RenderResult.layers()`` names them, so every layer lands in the pass of the same name.
"""

import numpy as np

# (name, channels, channel ids, type) as RenderEngine.register_pass takes them.
PASSES = (
    ("Combined", 4, "RGBA", 'COLOR'),
    ("Variance", 3, "RGB", 'COLOR'),
    ("Sample Count", 1, "X", 'VALUE'),
)


# Integrators (property identifiers) that write per-strategy images.
STRATEGY_VIEW_INTEGRATORS = {'BDPT'}


def strategy_passes(settings):
    """Names of the per-strategy passes the scene's ``SamplingLabSettings`` ask for.

    Returns
    -------
    list of str
        :func:`core.integrators.common.strategy_pass_names` of ``strategy_max_length`` when
        ``use_strategy_views`` is on and the integrator writes views (Bidirectional), else [].
    """
    if settings is None or not settings.use_strategy_views:
        return []
    if settings.integrator not in STRATEGY_VIEW_INTEGRATORS:
        return []
    from ..core.integrators.common import strategy_pass_names

    return strategy_pass_names(settings.strategy_max_length)


# The radiosity integrator's optional pass showing its patches (core.integrators.radiosity).
RADIOSITY_PATCHES_PASS = "Radiosity Patches"


def radiosity_passes(settings):
    """``["Radiosity Patches"]`` when the scene's settings render radiosity with the patches
    pass on, else []."""
    if settings is None or settings.integrator != 'RADIOSITY':
        return []
    return [RADIOSITY_PATCHES_PASS] if settings.use_radiosity_patches else []


def register_passes(engine, scene, view_layer):
    """Declare every pass of :data:`PASSES`, and the strategy views and radiosity patches the
    scene asks for, for ``view_layer`` (``update_render_passes``)."""
    for name, channels, chan_id, pass_type in PASSES:
        engine.register_pass(scene, view_layer, name, channels, chan_id, pass_type)
    settings = getattr(scene, "sampling_lab", None)
    for name in strategy_passes(settings) + radiosity_passes(settings):
        engine.register_pass(scene, view_layer, name, 3, "RGB", 'COLOR')


def pass_images(result):
    """Core images of a :class:`core.render.RenderResult` by pass name.

    Returns
    -------
    dict of str -> (h, w, c) float32
        Combined, Variance, Sample Count and every extra layer of ``result.layers()`` (BDPT's
        strategy views); row 0 is the bottom row, as Blender stores render results.
    """
    images = {
        "Combined": result.combined(),
        "Variance": result.variance(),
        "Sample Count": result.sample_count()[..., None],
    }
    for name, image in result.layers().items():
        images.setdefault(name, image)
    return images


def write_passes(layer, images):
    """Copy ``images`` into the passes of a ``RenderLayer`` that exist there.

    Parameters
    ----------
    layer : bpy.types.RenderLayer
        ``result.layers[0]`` of ``RenderEngine.begin_result``.
    images : dict of str -> (h, w, c) array
        Of the layer's size (a render region renders only the region: ``core.film.Film``).
    """
    for render_pass in layer.passes:
        image = images.get(render_pass.name)
        if image is None:
            continue
        if image.shape[-1] != render_pass.channels:
            continue
        # foreach_set with a contiguous float32 buffer is a memcpy; assigning rect is not.
        render_pass.rect.foreach_set(np.ascontiguousarray(image, np.float32).ravel())
