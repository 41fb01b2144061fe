"""Render passes: which ones the engine writes, and copying core images into Blender results."""

import numpy as np

# (name, channels, channel ids, type) as RenderEngine.register_pass takes them.
PASSES = (
    ("Combined", 4, "RGBA", 'COLOR'),
    ("Variance", 3, "RGB", 'COLOR'),
    ("Sample Count", 1, "X", 'VALUE'),
)


def register_passes(engine, scene, view_layer):
    """Declare every pass of :data:`PASSES` for ``view_layer`` (``update_render_passes``)."""
    for name, channels, chan_id, pass_type in PASSES:
        engine.register_pass(scene, view_layer, name, channels, chan_id, pass_type)


def pass_images(result):
    """Core images of a :class:`core.render.RenderResult` by pass name.

    Returns
    -------
    dict of str -> (h, w, c) float32
        Row 0 is the bottom row, as Blender stores render results.
    """
    return {
        "Combined": result.combined(),
        "Variance": result.variance(),
        "Sample Count": result.sample_count()[..., None],
    }


def write_passes(layer, images, window=None):
    """Copy ``images`` into the passes of a ``RenderLayer`` that exist there.

    Parameters
    ----------
    layer : bpy.types.RenderLayer
        ``result.layers[0]`` of ``RenderEngine.begin_result``.
    images : dict of str -> (h, w, c) array
    window : tuple of slice or None
        ``(rows, columns)`` of the images that the layer covers (render region); all if None.
    """
    for render_pass in layer.passes:
        image = images.get(render_pass.name)
        if image is None:
            continue
        if window is not None:
            image = image[window]
        if image.shape[-1] != render_pass.channels:
            continue
        # foreach_set with a contiguous float32 buffer is a memcpy; assigning rect is not.
        render_pass.rect.foreach_set(np.ascontiguousarray(image, np.float32).ravel())
