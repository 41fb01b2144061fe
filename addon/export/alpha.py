"""Textured alpha: an Image Texture into a Principled BSDF's Alpha, or into the Fac of a Mix
Shader with a Transparent BSDF on one side.

Either becomes a mixture laid out for opacity :data:`LAYOUT` whose components on the
transparent side are marked ``alpha_clear``; the core re-weights them at every hit from the
texture (:mod:`core.alpha`). Only a material's own node is translated so (not one inside a Mix
Shader); others are reported and use the socket's value.
"""

from __future__ import annotations

import numpy as np

from .nodes import follow_link, node_name
from .textures import own_principled_texture, scalar_texture

LAYOUT = 0.5
"""The opacity a textured-alpha mixture is laid out for (both sides exist)."""


def principled_alpha_texture(node, owner, messages, depth):
    """``(pixels, mode)`` of an Image Texture (its Color or Alpha output) into the Alpha of
    Principled ``node``, or None."""
    return own_principled_texture(node, "Alpha", owner, messages, depth, alpha_output=True)


def mix_fac_texture(node, owner, messages, depth):
    """``(pixels, mode, clear_input)`` of an Image Texture into the Fac of Mix Shader ``node``
    with a Transparent BSDF on exactly one side (``clear_input`` 1 or 2), or None (then the
    Fac is read as any other input: reported if linked)."""
    link = follow_link(node.inputs[0])
    if depth > 0 or link is None or link[0].bl_idname != 'ShaderNodeTexImage':
        return None
    sides = [follow_link(node.inputs[i]) for i in (1, 2)]
    clear = [s is not None and s[0].bl_idname == 'ShaderNodeBsdfTransparent' for s in sides]
    if clear.count(True) != 1:
        return None
    texture = scalar_texture(node, node.inputs[0].name, owner, messages, alpha_output=True)
    # Not translatable (reported): the Fac's own value.
    return (texture or (None, None)) + (clear.index(True) + 1,)


def mean_opacity(pixels, invert=False):
    """The mean opacity of an alpha texture (its luminance or value, clipped to [0, 1]): what
    scales emission, which the core keeps per material, not per hit."""
    values = pixels.reshape(-1, pixels.shape[-1]).astype(np.float64)
    lum = values.mean(axis=1) if values.shape[1] == 1 else values @ [0.2126, 0.7152, 0.0722]
    mean = float(np.clip(lum, 0.0, 1.0).mean())
    return 1.0 - mean if invert else mean


def emission_note(owner, node, messages):
    """Report that the emission of a textured-alpha node is scaled by its mean opacity."""
    messages.add(f"{owner}: the emission of node '{node_name(node)}' is scaled by the mean of "
                 f"its alpha texture, not per hit")
