"""Image Texture and Environment Texture nodes -> linear RGB pixel arrays.

Pixels are copied with ``foreach_get``, row 0 at the bottom as Blender stores them. Only what
the core's lookups model is translated; anything else is reported, and the caller falls back to
the socket's own colour.
"""

from __future__ import annotations

import numpy as np

from ...core.scene import TEXTURE_EXTENSIONS, TEXTURE_INTERPOLATIONS
from .nodes import ROUGHNESS_SOCKETS, TEXTURED_SOCKETS, follow_link, node_name

# Colour spaces whose float values are scene-linear Rec.709 (Blender's working space) already.
_LINEAR_COLORSPACES = {'Linear Rec.709', 'Linear', 'Non-Color'}


def surface_texture(node, owner, messages):
    """``(pixels, (interpolation, extension))`` of the Image Texture driving the base colour
    of BSDF node ``node``, or None (unsupported ones reported)."""
    name = TEXTURED_SOCKETS.get(node.bl_idname)
    socket = node.inputs.get(name) if name else None
    link = follow_link(socket) if socket is not None else None
    if link is None or link[0].bl_idname != 'ShaderNodeTexImage':
        return None
    return _image_texture_pixels(link[0], link[1], owner, messages)


def roughness_texture(node, owner, messages):
    """``(pixels, (interpolation, extension))`` of the Image Texture driving the Roughness of
    BSDF node ``node`` (its luminance is the roughness; the image's colour space is honoured
    as for colours, so Non-Color data is used as stored), or None (unsupported ones
    reported)."""
    name = ROUGHNESS_SOCKETS.get(node.bl_idname)
    socket = node.inputs.get(name) if name else None
    link = follow_link(socket) if socket is not None else None
    if link is None or link[0].bl_idname != 'ShaderNodeTexImage':
        return None
    return _image_texture_pixels(link[0], link[1], owner, messages)


def scalar_texture(node, name, owner, messages, alpha_output=False):
    """``(pixels, (interpolation, extension))`` of the Image Texture driving the scalar input
    ``name`` of ``node`` (one of ``nodes.SCALAR_TEXTURE_SOCKETS``; its luminance is the value,
    the image's colour space honoured as for colours), or None (unsupported ones reported).
    With ``alpha_output`` the node's Alpha output may drive it too (pixels ``(h, w, 1)``, see
    :func:`image_alpha`)."""
    socket = node.inputs.get(name)
    link = follow_link(socket) if socket is not None else None
    if link is None or link[0].bl_idname != 'ShaderNodeTexImage':
        return None
    return _image_texture_pixels(link[0], link[1], owner, messages, alpha_output)


def _image_texture_pixels(node, out, owner, messages, alpha_output=False):
    """``(pixels, (interpolation, extension))`` of an Image Texture node: RGB ``(h, w, 3)``
    float32 (with ``alpha_output`` and its Alpha output: the alpha ``(h, w, 1)``) and the
    lookup modes, or None (reported).

    What the core's lookup models: the Color output (and the Alpha output where a socket takes
    it), flat projection of the active UV map
    (Vector unlinked, or from a UV Map node of the default map or a Texture Coordinate's UV),
    Linear or Closest interpolation (Cubic and Smart are reported and rendered as Linear),
    every extension (Repeat, Extend, Clip, Mirror); anything else falls back to the socket's
    own colour.
    """
    name = node_name(node)
    fallback = "; using the input's own colour"
    image = node.image
    if image is None:
        messages.add(f"{owner}: image texture '{name}' has no image{fallback}")
        return None
    if out.identifier != "Color" and not (alpha_output and out.identifier == "Alpha"):
        messages.add(f"{owner}: the {out.name} output of image texture '{name}' is not "
                     f"supported yet{fallback}")
        return None
    if getattr(node, "projection", 'FLAT') != 'FLAT':
        messages.add(f"{owner}: {node.projection.lower()} projection of image texture '{name}' "
                     f"is not supported yet{fallback}")
        return None
    if not _default_uv_vector(node, owner, fallback, messages):
        return None
    if not _has_pixels(image, "image texture", name, owner, fallback, messages):
        return None
    interpolation = _interpolation(node, "image texture", name, owner, messages,
                                   TEXTURE_INTERPOLATIONS)
    extension = getattr(node, "extension", 'REPEAT')
    if extension not in TEXTURE_EXTENSIONS:
        messages.add(f"{owner}: {extension.lower()} extension of image texture '{name}' is "
                     f"not supported yet{fallback}")
        return None
    if out.identifier == "Alpha":
        return image_alpha(image)[..., None], (interpolation, extension)
    if interpolation == 'Linear':
        _note_unassociated_blend(node, image, owner, messages)
    return _image_rgb(image, owner, messages, node), (interpolation, extension)


def _note_unassociated_blend(node, image, owner, messages):
    """Report a Linear lookup of colour whose Alpha output is used, in an image whose alpha
    varies: Cycles blends the premultiplied colour between texels and divides by the blended
    alpha, we blend the colour itself (the texels agree, the blend between them differs)."""
    if not (_associates_alpha(image) and node.outputs["Alpha"].is_linked):
        return
    alpha = image_alpha(image)
    if alpha.min() < alpha.max():
        messages.add(f"{owner}: the colour of image '{image.name}' (with alpha) is blended "
                     f"between texels without premultiplying it by alpha, as Cycles does; "
                     f"texels agree, the blend between texels of different alpha differs")


def _default_uv_vector(node, owner, fallback, messages):
    """Whether the Vector input of Image Texture ``node`` is the active UV map: unlinked, a UV
    Map node of the default map, or a Texture Coordinate's UV (else reported)."""
    vector = node.inputs.get("Vector")
    coords = follow_link(vector) if vector is not None else None
    if coords is None:
        return True
    src, socket = coords
    default_uv = ((src.bl_idname == 'ShaderNodeUVMap' and not src.uv_map
                   and not getattr(src, "from_instancer", False))
                  or (src.bl_idname == 'ShaderNodeTexCoord' and socket.identifier == "UV"
                      and not getattr(src, "from_instancer", False)))
    if not default_uv:
        messages.add(f"{owner}: the Vector input of image texture '{node_name(node)}' (node "
                     f"'{node_name(src)}') is not supported yet{fallback}")
    return default_uv


def environment_pixels(node, owner, messages):
    """RGB ``(h, w, 3)`` float32 of an Environment Texture node's image, or None (reported).

    Only what Cycles computes without a Mapping: equirectangular projection, nothing linked to
    the Vector input. Images in a linear Rec.709 colour space are used as they are; 8-bit sRGB
    images are decoded with the sRGB transfer function; other colour spaces are used as stored
    (reported once). Interpolation other than Linear (Cycles' default) is reported.
    """
    name = node_name(node)
    fallback = "; using the Background colour"
    if node.image is None:
        messages.add(f"{owner}: environment texture '{name}' has no image{fallback}")
        return None
    if getattr(node, "projection", 'EQUIRECTANGULAR') != 'EQUIRECTANGULAR':
        messages.add(f"{owner}: {node.projection.lower().replace('_', ' ')} projection of "
                     f"environment texture '{name}' is not supported yet{fallback}")
        return None
    vector = node.inputs.get("Vector")
    if vector is not None and follow_link(vector) is not None:
        messages.add(f"{owner}: the Vector input of environment texture '{name}' (a mapping) "
                     f"is not supported yet{fallback}")
        return None
    image = node.image
    if not _has_pixels(image, "environment texture", name, owner, fallback, messages):
        return None
    _interpolation(node, "environment texture", name, owner, messages)
    return _image_rgb(image, owner, messages)


def _has_pixels(image, what, name, owner, fallback, messages):
    """Whether ``image`` of texture node ``name`` has pixels (else reported with
    ``fallback``)."""
    w, h = (int(x) for x in image.size)
    if w <= 0 or h <= 0 or int(image.channels) <= 0:
        messages.add(f"{owner}: image '{image.name}' of {what} '{name}' has no "
                     f"pixels{fallback}")
        return False
    return True


def _interpolation(node, what, name, owner, messages, supported=("Linear",)):
    """The interpolation the core uses for texture node ``node``: its own when ``supported``,
    else Linear (reported)."""
    interpolation = getattr(node, "interpolation", 'Linear')
    if interpolation in supported:
        return interpolation
    messages.add(f"{owner}: {interpolation} interpolation of {what} '{name}' is "
                 f"not supported yet; rendered with Linear")
    return 'Linear'


def _read_pixels(image):
    """The pixels of ``image`` as ``(h, w, channels)`` float32 (row 0 at the bottom); a pixel
    with a non-finite channel is zero in all, as Cycles loads float images."""
    w, h = (int(x) for x in image.size)
    channels = int(image.channels)
    buf = np.empty(w * h * channels, np.float32)
    image.pixels.foreach_get(buf)
    buf = buf.reshape(h, w, channels)
    buf[~np.isfinite(buf).all(axis=2)] = 0.0
    return buf


def _associates_alpha(image):
    """Whether Cycles associates the image's colour with its alpha (Cycles'
    ``image_associate_alpha``): not for Non-Color data, Channel Packed or no alpha."""
    return (int(image.channels) == 4 and image.colorspace_settings.name != 'Non-Color'
            and getattr(image, "alpha_mode", 'STRAIGHT') not in ('CHANNEL_PACKED', 'NONE'))


def image_alpha(image):
    """The Alpha output of an Image Texture of ``image`` per texel: ``(h, w)`` float32, as
    Cycles loads it (the alpha channel as stored, in no colour space; 1 for images without
    one and for Alpha mode None)."""
    w, h = (int(x) for x in image.size)
    if int(image.channels) < 4 or getattr(image, "alpha_mode", 'STRAIGHT') == 'NONE':
        return np.ones((h, w), np.float32)
    return np.ascontiguousarray(_read_pixels(image)[..., 3])


def _associated_rgb(rgb, buf, image, node):
    """The colour Cycles' Image Texture ``node`` gives per texel, before decoding (see
    :func:`_image_rgb`): with its Alpha output unused, an 8-bit image's colour premultiplied
    by alpha (a float image's pixels are premultiplied already); with it used, a float
    image's colour divided by alpha where it is neither 0 nor 1 (Cycles'
    ``NODE_IMAGE_ALPHA_UNASSOCIATE``)."""
    if node is None or not _associates_alpha(image):
        return rgb
    alpha = buf[..., 3:4]
    if not node.outputs["Alpha"].is_linked:
        return rgb if image.is_float else (rgb * alpha).astype(np.float32)
    if not image.is_float:
        return rgb
    keep = (alpha == 0.0) | (alpha == 1.0)
    return np.where(keep, rgb, rgb / np.where(keep, 1.0, alpha)).astype(np.float32)


def _image_rgb(image, owner, messages, node=None):
    """Linear RGB ``(h, w, 3)`` float32 of an image (row 0 at the bottom), read with
    ``foreach_get``: float images and 8-bit linear colour spaces as they are, 8-bit sRGB
    decoded, others reported; for an Image Texture ``node``, associated with alpha as Cycles
    does (:func:`_associated_rgb`)."""
    buf = _read_pixels(image)
    channels = buf.shape[2]
    rgb = buf[..., :3] if channels >= 3 else np.repeat(buf[..., :1], 3, axis=2)
    rgb = np.ascontiguousarray(_associated_rgb(rgb, buf, image, node))
    space = image.colorspace_settings.name
    if image.is_float:
        # Blender converts a float image to scene-linear Rec.709 as it loads it, whatever its
        # colour space (e.g. the 'sRGB' it tags EXR files it wrote with); Cycles' texels are
        # the same, but from a non-linear space it interpolates before converting.
        if space not in _LINEAR_COLORSPACES and not space.startswith("Linear"):
            messages.add(f"{owner}: float image '{image.name}' in colour space '{space}' is "
                         f"interpolated after conversion to linear (Cycles converts after "
                         f"interpolating; the texels agree, the blend between them differs)")
        return rgb
    if space == 'sRGB':
        # 8-bit sRGB pixels are stored encoded; Cycles decodes them to linear.
        rgb = np.where(rgb <= 0.04045, rgb / 12.92,
                       ((np.maximum(rgb, 0.04045) + 0.055) / 1.055) ** 2.4).astype(np.float32)
    elif space not in _LINEAR_COLORSPACES:
        messages.add(f"{owner}: colour space '{space}' of image '{image.name}' is not "
                     f"converted yet; its values are used as linear Rec.709")
    return rgb


def own_principled_texture(node, name, owner, messages, depth, alpha_output=False):
    """:func:`scalar_texture` of input ``name`` of a material's own Principled ``node`` (at
    mix ``depth`` 0), whose mixture is re-weighted per hit; one inside a Mix Shader is reported
    and its socket's value used (None)."""
    found = scalar_texture(node, name, owner, messages, alpha_output=alpha_output)
    if found is not None and depth > 0:
        messages.add(f"{owner}: the {name.lower()} texture of node '{node_name(node)}' inside "
                     f"a mix is not supported yet; using the input's own value")
        return None
    return found
