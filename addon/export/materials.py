"""Blender materials -> rows of :class:`core.scene.Materials`.

A material's surface shader becomes a :class:`Surface`: one of the core's closed set of BSDFs
(diffuse, conductor, dielectric, layered coat over diffuse) or a mixture of them. The Principled
BSDF becomes the mixture Cycles' Principled weighs; Mix Shaders are flattened into mixtures;
the other BSDF nodes map one to one; anything else is reported and rendered as diffuse.
:class:`.material_table.MaterialTable` numbers the materials a scene uses and lays out their
rows.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...core.scene import (
    MAT_CONDUCTOR,
    MAT_DIELECTRIC,
    MAT_DIFFUSE,
    MAT_LAYERED,
)
from .alpha import (LAYOUT, emission_note, mean_opacity, mix_fac_texture,
                    principled_alpha_texture)
from .anisotropy import glossy_anisotropy, principled_anisotropy
from .nodes import NodeReader, active_output, follow_link, node_name, uses_nodes
from .normal_maps import bump_map_correction, mixed_normal_input, normal_input
from .textures import own_principled_texture, roughness_texture, scalar_texture, surface_texture

# Cycles shades surfaces without a material as a 0.8 grey diffuse.
DEFAULT_SURFACE_NAME = "Default Surface"
DEFAULT_SURFACE_COLOR = (0.8, 0.8, 0.8)

# Most components a mixture keeps (the largest weights, renormalised; reported beyond).
MAX_COMPONENTS = 8


class Surface(NamedTuple):
    """One row of :class:`core.scene.Materials`, as translated from a Blender material."""

    kind: int = MAT_DIFFUSE
    base_color: np.ndarray = np.array(DEFAULT_SURFACE_COLOR)
    emission: np.ndarray = np.zeros(3)
    roughness: float = 0.5
    ior: float = 1.5
    metallic: float = 0.0
    transmission: float = 0.0
    specular_ior_level: float = 0.5
    specular_tint: np.ndarray = np.ones(3)
    multiscatter: bool = False  # Multiscatter GGX (on conductor and layered rows, see Materials)
    texture: np.ndarray = None  # (h, w, 3) float32 base colour image, see surface_texture
    texture_mode: tuple = ("Linear", "REPEAT")  # the image node's interpolation, extension
    # A mixture: ((weight, Surface), ...) of plain surfaces (see mix_surfaces); this row's own
    # BSDF fields are then unused, its emission is the mixture's.
    components: tuple = ()
    # Principled Coat over this surface (core.materials.coat); weight 0: none.
    coat_weight: float = 0.0
    coat_roughness: float = 0.03
    coat_ior: float = 1.5
    coat_tint: np.ndarray = np.ones(3)
    # (h, w, 3) float32 image whose luminance is the roughness (None: the roughness field).
    roughness_texture: np.ndarray = None
    roughness_texture_mode: tuple = ("Linear", "REPEAT")
    # Microfiber sheen over this surface and its coat (core.materials.sheen); weight 0: none.
    sheen_weight: float = 0.0
    sheen_roughness: float = 0.5
    sheen_tint: np.ndarray = np.ones(3)
    # Anisotropic GGX of a conductor (core.materials.anisotropic; addon.export.anisotropy):
    # alpha_x = alpha k, alpha_y = alpha / k, the tangent turned by the rotation (turns) and
    # taken radial about this axis of the object ('X', 'Y', 'Z'; None: isotropic).
    aniso_scale: float = 1.0
    aniso_rotation: float = 0.0
    tangent_axis: str = None
    # The Normal Map feeding the Normal input (normal_maps.NormalMap), or None; a mixture
    # row's applies to all its components.
    normal_map: tuple = None
    bump: tuple = None  # the Bump node (normal_maps.Bump) after the normal map, or None
    # (pixels, mode) of a Principled's Metallic texture (its mixture laid out for metallic
    # 0.5, see core.metallic), or None.
    metallic_texture: tuple = None
    # Cycles' Bump Map Correction on this row's diffuse lobes (core.materials.bump_correction).
    bump_correction: bool = False
    # The coat follows the Normal input's normal (Coat Normal linked to it); else the smooth one.
    coat_mapped: bool = False
    # (pixels, mode, invert) of a textured alpha (its mixture laid out for opacity 0.5, see
    # core.alpha and .alpha), or None; alpha_clear marks the components on its clear side.
    alpha_texture: tuple = None
    alpha_clear: bool = False
    # (pixels, mode) whose luminance is this row's Specular IOR Level or Coat Weight per hit
    # (core.scalar_textures), or None.
    specular_level_texture: tuple = None
    coat_weight_texture: tuple = None


def _diffuse(color, emission=None):
    return Surface(MAT_DIFFUSE, np.asarray(color, np.float64),
                   np.zeros(3) if emission is None else emission)


_BLACK = Surface(MAT_DIFFUSE, np.zeros(3), np.zeros(3))


def material_surface(material, messages):
    """Core material (kind, colours, roughness, IOR, ...) and emitted radiance of a material.

    Parameters
    ----------
    material : bpy.types.Material or None
    messages : Messages

    Returns
    -------
    Surface
        ``emission`` is radiance, emitted from both faces.
    """
    if material is None:
        return _diffuse(DEFAULT_SURFACE_COLOR)
    owner = f"Material '{material.name}'"
    if not uses_nodes(material) or material.node_tree is None:
        return _diffuse(material.diffuse_color[:3])
    tree = material.node_tree
    output = active_output(tree, 'ShaderNodeOutputMaterial')
    if output is None:
        # Cycles renders a material without an output as black.
        return _BLACK
    for name in ("Volume", "Displacement"):
        socket = output.inputs.get(name)
        if socket is not None and follow_link(socket) is not None:
            messages.add(f"{owner}: {name.lower()} is not supported yet; ignored")
    surface = _shader_surface(follow_link(output.inputs["Surface"]), owner, messages)
    if bump_map_correction(material, surface):
        surface = surface._replace(bump_correction=True)
    return surface


def _distribution_note(node, read, owner, what="GGX", handled=('GGX', 'SHARP')):
    """Report a rough microfacet node whose distribution is not among ``handled``."""
    distribution = getattr(node, "distribution", 'GGX')
    if distribution not in handled and read.value(node, "Roughness") > 0:
        read.messages.add(f"{owner}: {distribution} distribution of node '{node_name(node)}' "
                          f"is not supported yet; rendered as {what}")


def _shader_surface(source, owner, messages, depth=0):
    """Translate the shader node feeding a Surface socket (``source = (node, socket)``)."""
    if source is None:
        return _BLACK
    node, _ = source
    read = NodeReader(owner, messages)
    kind = node.bl_idname
    if kind == 'ShaderNodeMixShader' and depth < 16:
        return _mix_shader(node, read, owner, messages, depth)
    normal, bump = (normal_input(node, owner, messages)
                    if kind != 'ShaderNodeEmission' else (None, None))
    texture = surface_texture(node, owner, messages)
    rough = roughness_texture(node, owner, messages)
    rough = {} if rough is None else {"roughness_texture": rough[0],
                                      "roughness_texture_mode": rough[1]}
    if kind == 'ShaderNodeBsdfPrincipled':
        metal = _metallic_texture(node, owner, messages, depth)
        alpha = principled_alpha_texture(node, owner, messages, depth)
        surface = _principled_surface(node, read, owner, texture, rough, metal, alpha)
        return surface._replace(normal_map=normal, bump=bump, metallic_texture=metal)
    surface = _node_surface(node, read, owner, messages)
    if texture is not None:
        surface = surface._replace(texture=texture[0], texture_mode=texture[1])
    return surface._replace(normal_map=normal, bump=bump, **rough)


def _mix_shader(node, read, owner, messages, depth):
    """A Mix Shader: Cycles weighs input 1 by 1 - Fac and input 2 by Fac (nested mixes
    multiply). An Image Texture into the Fac with a Transparent BSDF on one side is a textured
    alpha (:mod:`.alpha`): laid out for Fac 0.5, the Transparent side marked clear."""
    textured = mix_fac_texture(node, owner, messages, depth)
    if textured is None:
        fac = min(max(read.value(node, "Fac", 0.5), 0.0), 1.0)
    elif textured[0] is None:  # reported by the texture reader
        fac = min(max(float(node.inputs[0].default_value), 0.0), 1.0)
    else:
        fac = LAYOUT
    parts = [(1.0 - fac, _shader_surface(follow_link(node.inputs[1]), owner, messages,
                                         depth + 1)),
             (fac, _shader_surface(follow_link(node.inputs[2]), owner, messages, depth + 1))]
    if textured is None or textured[0] is None:
        return mix_surfaces(parts, owner, messages)._replace(
            **mixed_normal_input(parts, owner, messages))
    pixels, mode, clear = textured
    parts[clear - 1] = (parts[clear - 1][0], parts[clear - 1][1]._replace(alpha_clear=True))
    opaque = parts[2 - clear][1]
    emission = mean_opacity(pixels, clear == 2) * np.asarray(opaque.emission, np.float64)
    if np.any(emission > 0):
        emission_note(owner, node, messages)
    return mix_surfaces(parts, owner, messages)._replace(
        emission=emission, alpha_texture=(pixels, mode, clear == 2),
        **mixed_normal_input(parts, owner, messages))


def _metallic_texture(node, owner, messages, depth):
    """``(pixels, mode)`` of an Image Texture into the Metallic of Principled ``node``, or
    None; only a material's own Principled (not one inside a Mix Shader) is re-weighted per
    hit, others are reported and use the socket's value."""
    return own_principled_texture(node, "Metallic", owner, messages, depth)


def _node_surface(node, read, owner, messages):
    """Translate one shader node other than a Mix Shader or a Principled BSDF."""
    kind = node.bl_idname
    name = node_name(node)

    if kind == 'ShaderNodeBsdfDiffuse':
        if read.value(node, "Roughness") > 0:
            messages.add(f"{owner}: Oren-Nayar roughness of node '{name}' is not "
                         f"supported yet; rendered as Lambertian")
        return _diffuse(read.color(node, "Color"))

    if kind == 'ShaderNodeEmission':
        emission = read.color(node, "Color") * read.value(node, "Strength")
        return Surface(MAT_DIFFUSE, np.zeros(3), emission)

    if kind in {'ShaderNodeBsdfGlossy', 'ShaderNodeBsdfAnisotropic'}:
        # Multiscatter GGX: Cycles' energy compensation, modelled for conductors.
        _distribution_note(node, read, owner, handled=('GGX', 'SHARP', 'MULTI_GGX'))
        return Surface(MAT_CONDUCTOR, read.color(node, "Color", (1.0, 1.0, 1.0)), np.zeros(3),
                       roughness=read.value(node, "Roughness", 0.5),
                       multiscatter=getattr(node, "distribution", 'GGX') == 'MULTI_GGX',
                       **glossy_anisotropy(node, read, owner))

    if kind in {'ShaderNodeBsdfGlass', 'ShaderNodeBsdfRefraction'}:
        # Multiscatter GGX: Cycles' compensation of glass (the Glass BSDF's rule).
        glass = kind == 'ShaderNodeBsdfGlass'
        _distribution_note(node, read, owner,
                           handled=('GGX', 'SHARP', 'MULTI_GGX') if glass else ('GGX', 'SHARP'))
        if kind == 'ShaderNodeBsdfRefraction':
            messages.add(f"{owner}: node '{name}' (refraction only) is not supported yet; "
                         f"rendered as glass (with Fresnel reflection)")
        color = read.color(node, "Color", (1.0, 1.0, 1.0))
        return Surface(MAT_DIELECTRIC, color, np.zeros(3),
                       roughness=read.value(node, "Roughness", 0.0),
                       ior=read.value(node, "IOR", 1.5), transmission=1.0, specular_tint=color,
                       multiscatter=glass and getattr(node, "distribution", 'GGX') == 'MULTI_GGX')

    if kind == 'ShaderNodeBsdfTransparent':
        return _transparent(read.color(node, "Color", (1.0, 1.0, 1.0)))

    if kind == 'ShaderNodeBsdfSheen':
        return _sheen_node(node, read, owner)

    messages.add(f"{owner}: node '{name}' is not supported yet; rendered as diffuse")
    if node.inputs.get("Color") is not None and node.inputs["Color"].type == 'RGBA':
        return _diffuse(read.color(node, "Color"))
    return _diffuse(DEFAULT_SURFACE_COLOR)


def _sheen_node(node, read, owner):
    """Sheen BSDF node: the microfiber sheen over nothing (a black base); its Ashikhmin
    distribution is reported and rendered as Microfiber."""
    distribution = getattr(node, "distribution", 'MICROFIBER')
    if distribution != 'MICROFIBER':
        read.messages.add(f"{owner}: {distribution} distribution of node '{node_name(node)}' "
                          f"is not supported yet; rendered as Microfiber")
    return Surface(MAT_DIFFUSE, np.zeros(3), np.zeros(3), sheen_weight=1.0,
                   sheen_roughness=min(max(read.value(node, "Roughness", 0.5), 0.0), 1.0),
                   sheen_tint=np.maximum(read.color(node, "Color", (0.8, 0.8, 0.8)), 0.0))


def _transparent(color):
    """Transparent BSDF: a smooth dielectric of IOR 1 (straight through, tinted by ``color``)."""
    color = np.asarray(color, np.float64)
    return Surface(MAT_DIELECTRIC, color, np.zeros(3), roughness=0.0, ior=1.0,
                   transmission=1.0, specular_tint=color)


def _surface_key(surface):
    """What makes two plain surfaces the same BSDF (to merge equal mixture components)."""
    return (surface.kind, tuple(np.round(surface.base_color, 9)), surface.roughness,
            surface.ior, surface.specular_ior_level, tuple(np.round(surface.specular_tint, 9)),
            surface.multiscatter, id(surface.texture), surface.texture_mode,
            surface.coat_weight, surface.coat_roughness, surface.coat_ior,
            tuple(np.round(surface.coat_tint, 9)), id(surface.roughness_texture),
            surface.roughness_texture_mode, surface.sheen_weight, surface.sheen_roughness,
            tuple(np.round(surface.sheen_tint, 9)), surface.aniso_scale,
            surface.aniso_rotation, surface.tangent_axis, surface.alpha_clear,
            _texture_key(surface.specular_level_texture),
            _texture_key(surface.coat_weight_texture), surface.coat_mapped)


def _texture_key(texture):
    """What identifies a ``(pixels, mode)`` texture field (None: none)."""
    return None if texture is None else (id(texture[0]), texture[1])


def mix_surfaces(parts, owner, messages):
    """The mixture of ``parts = [(weight, Surface), ...]`` (weights summing to 1).

    Nested mixtures are flattened (their weights multiply); emission is the weighted sum;
    components of zero weight are dropped and equal ones merged. A mixture of untextured
    diffuse surfaces is the diffuse surface of the blended colour (Lambert is linear in its
    albedo); a mixture left with one component is that component.
    """
    flat = []
    emission = np.zeros(3)
    for weight, surface in parts:
        emission = emission + weight * np.asarray(surface.emission, np.float64)
        inner = surface.components or ((1.0, surface),)
        for w, component in inner:
            if weight * w > 0:
                flat.append((weight * w, component._replace(
                    emission=np.zeros(3), components=(), normal_map=None, bump=None,
                    metallic_texture=None, alpha_texture=None,
                    alpha_clear=surface.alpha_clear or component.alpha_clear)))
    merged = {}
    for w, component in flat:
        key = _surface_key(component)
        w0, _ = merged.get(key, (0.0, component))
        merged[key] = (w0 + w, component)
    flat = sorted(merged.values(), key=lambda wc: -wc[0])
    if not flat:
        return _BLACK._replace(emission=emission)
    if all(c.kind == MAT_DIFFUSE and c.texture is None and c.coat_weight == 0
           and c.sheen_weight == 0 and c.roughness_texture is None for _, c in flat):
        color = sum(w * np.asarray(c.base_color, np.float64) for w, c in flat)
        return _diffuse(color / sum(w for w, _ in flat), emission)
    if len(flat) == 1:
        return flat[0][1]._replace(emission=emission)
    if len(flat) > MAX_COMPONENTS:
        messages.add(f"{owner}: mixtures of more than {MAX_COMPONENTS} BSDFs are not "
                     f"supported yet; the {MAX_COMPONENTS} largest are kept")
        flat = flat[:MAX_COMPONENTS]
    total = sum(w for w, _ in flat)
    components = tuple((w / total, c) for w, c in flat)
    main = components[0][1]
    return main._replace(emission=emission, texture=None, components=components,
                         alpha_clear=False)


def _principled_surface(node, read, owner, texture=None, rough=None, metal=None, alpha_tex=None):
    """Principled BSDF -> a mixture of conductor (metallic), dielectric (transmission), coat
    over diffuse and, for Alpha < 1, a transparent pass-through.

    Weights as Cycles' Principled: transparent ``1 - a``, then of the rest ``a``: metal ``m``,
    glass ``(1 - m) t`` and the opaque dielectric ``(1 - m)(1 - t)``; emission is scaled by
    ``a`` too. ``texture`` (pixels, modes) drives the base colour of every component but the
    transparent one, ``rough`` (the :class:`Surface` fields of a roughness texture) their
    roughness. With ``metal`` (a metallic texture) the mixture is laid out for Metallic 0.5
    and re-weighted at every hit (:mod:`core.metallic`); with ``alpha_tex`` (an alpha texture)
    the same for Alpha 0.5, the pass-through marked clear (:mod:`core.alpha`).
    """
    messages = read.messages
    name = node_name(node)
    base = read.color(node, "Base Color", DEFAULT_SURFACE_COLOR)
    emission = read.color(node, "Emission Color") * read.value(node, "Emission Strength")
    metallic = 0.5 if metal is not None else min(max(read.value(node, "Metallic"), 0.0), 1.0)
    transmission = min(max(read.value(node, "Transmission Weight"), 0.0), 1.0)
    roughness = min(max(read.value(node, "Roughness", 0.5), 0.0), 1.0)
    ior = read.value(node, "IOR", 1.5)
    level = min(max(read.value(node, "Specular IOR Level", 0.5), 0.0), 1.0)
    tint = read.color(node, "Specular Tint", (1.0, 1.0, 1.0))
    if read.value(node, "Subsurface Weight") > 0:
        messages.add(f"{owner}: subsurface scattering of node '{name}' is approximated as "
                     f"diffuse reflection of the base colour")
    layer_textures = _principled_layer_textures(node, owner, messages)
    coat = _principled_coat(node, read, owner, layer_textures["coat_weight_texture"])
    sheen = _principled_sheen(node, read)
    if sheen["sheen_weight"] > 0 and np.any(emission > 0):
        messages.add(f"{owner}: emission under the sheen of node '{name}' is not attenuated "
                     f"by the sheen yet")
    if layer_textures["coat_weight_texture"] is not None and np.any(emission > 0):
        messages.add(f"{owner}: emission under the coat weight texture of node '{name}' is "
                     f"attenuated by a full coat, not per hit")
    if coat["coat_weight"] > 0 and np.any(emission > 0):
        messages.add(f"{owner}: emission under the coat of node '{name}' is attenuated by the "
                     f"coat everywhere; Cycles' light sampling leaves out the coat's reflection, "
                     f"so what it lights is darker than in Cycles")
    alpha = (LAYOUT if alpha_tex is not None
             else min(max(read.value(node, "Alpha", 1.0), 0.0), 1.0))
    aniso = principled_anisotropy(node, read, owner)
    weights = {MAT_CONDUCTOR: metallic, MAT_DIELECTRIC: (1 - metallic) * transmission,
               MAT_LAYERED: (1 - metallic) * (1 - transmission)}
    distribution = getattr(node, "distribution", 'GGX')
    multiscatter = distribution == 'MULTI_GGX'
    # Cycles' Multiscatter GGX on the transmission uses F_ss = 1, ours the transmission tint:
    # the same for white, untextured glass only.
    white_glass = texture is None and bool(np.all(base >= 0.999))
    _principled_distribution_note(distribution, weights, roughness, owner, name, messages,
                                  white_glass)
    if metallic > 0 and np.any(tint != 1.0):
        messages.add(f"{owner}: metallic specular tint (F82) of node '{name}' is not "
                     f"supported yet; ignored")
    if weights[MAT_DIELECTRIC] > 0 and (level != 0.5
                                        or layer_textures["specular_level_texture"] is not None):
        messages.add(f"{owner}: specular IOR level of transmissive node '{name}' is not "
                     f"supported yet; ignored")
    pixels, mode = texture if texture is not None else (None, ("Linear", "REPEAT"))
    if weights[MAT_DIELECTRIC] > 0 and pixels is not None:
        messages.add(f"{owner}: the base colour texture of transmissive node '{name}' tints "
                     f"each pass through the surface by the texture itself, not by its square "
                     f"root as Cycles does")
    # Cycles tints each pass through a Principled glass surface by sqrt(Base Color), so that
    # entering and leaving give the base colour.
    colors = {MAT_DIELECTRIC: np.sqrt(np.maximum(base, 0.0)) if pixels is None else base}
    compensated = {MAT_CONDUCTOR: True, MAT_LAYERED: True, MAT_DIELECTRIC: white_glass}
    parts = [(w, Surface(kind, colors.get(kind, base), np.zeros(3), roughness, ior,
                         float(kind == MAT_CONDUCTOR), float(kind == MAT_DIELECTRIC), level,
                         tint, multiscatter and compensated[kind], pixels, mode))
             for kind, w in weights.items() if w > 0]
    parts = [(alpha * w, surface._replace(**coat, **sheen, **(rough or {}), **layer_textures,
                                          **(aniso if surface.kind != MAT_DIELECTRIC else {})))
             for w, surface in parts]
    if alpha < 1.0:
        parts.append((1.0 - alpha, _transparent((1.0, 1.0, 1.0))._replace(
            alpha_clear=alpha_tex is not None)))
    surface = mix_surfaces(parts, owner, messages)
    if alpha_tex is not None:
        alpha = mean_opacity(alpha_tex[0])
        if np.any(emission > 0):
            emission_note(owner, node, messages)
        surface = surface._replace(alpha_texture=(*alpha_tex, False))
    return surface._replace(emission=alpha * emission, metallic=metallic,
                            transmission=transmission)


def _principled_layer_textures(node, owner, messages):
    """The Image Textures into the Specular IOR Level and Coat Weight of Principled ``node``
    as :class:`Surface` fields (None: the socket's value)."""
    return {"specular_level_texture": scalar_texture(node, "Specular IOR Level", owner,
                                                     messages),
            "coat_weight_texture": scalar_texture(node, "Coat Weight", owner, messages)}


def _principled_coat(node, read, owner, weight_texture=None):
    """The Coat inputs of Principled ``node`` as :class:`Surface` fields (weight 0: no coat;
    1 with ``weight_texture``, which gives the weight per hit). The coat shades around the
    smooth normal when Coat Normal is unlinked (Cycles), around the Normal input's normal when
    Coat Normal is linked to the same output; another Coat Normal link is reported (the
    smooth normal is used)."""
    weight = (1.0 if weight_texture is not None
              else min(max(read.value(node, "Coat Weight"), 0.0), 1.0))
    if weight <= 0:
        return {"coat_weight": 0.0}
    return {"coat_weight": weight, "coat_mapped": _coat_follows_normal(node, read, owner),
            "coat_roughness": min(max(read.value(node, "Coat Roughness", 0.03), 0.0), 1.0),
            "coat_ior": max(read.value(node, "Coat IOR", 1.5), 1.0),
            "coat_tint": np.maximum(read.color(node, "Coat Tint", (1.0, 1.0, 1.0)), 0.0)}


def _coat_follows_normal(node, read, owner):
    """Whether Principled ``node``'s Coat Normal is linked to the output its Normal input is
    linked to (then the coat follows the mapped normal); any other link is reported."""
    coat = node.inputs.get("Coat Normal")
    link = follow_link(coat) if coat is not None else None
    if link is None:
        return False
    normal = node.inputs.get("Normal")
    same = normal is not None and follow_link(normal)
    if same and same[0] == link[0] and same[1] == link[1]:
        return True
    read.messages.add(f"{owner}: a Coat Normal other than the Normal input's normal is not "
                      f"supported yet; the coat uses the smooth normal")
    return False


def _principled_sheen(node, read):
    """The Sheen inputs of Principled ``node`` as :class:`Surface` fields (weight 0: none)."""
    weight = max(read.value(node, "Sheen Weight"), 0.0)
    if weight <= 0:
        return {"sheen_weight": 0.0}
    return {"sheen_weight": weight,
            "sheen_roughness": min(max(read.value(node, "Sheen Roughness", 0.5), 0.0), 1.0),
            "sheen_tint": np.maximum(read.color(node, "Sheen Tint", (1.0, 1.0, 1.0)), 0.0)}


def _principled_distribution_note(distribution, weights, roughness, owner, name, messages,
                                  white_glass):
    """Report what of a rough Principled BSDF's distribution is not modelled: Multiscatter GGX
    is compensated on the metallic lobe, the specular layer (as Cycles does,
    :mod:`core.materials.multiscatter`) and white untextured transmission
    (:mod:`core.materials.glass_albedo`), not on coloured or textured transmission."""
    if roughness <= 0 or distribution == 'GGX':
        return
    if distribution != 'MULTI_GGX':
        messages.add(f"{owner}: {distribution} distribution of node '{name}' is not "
                     f"supported yet; rendered as GGX")
        return
    if weights[MAT_DIELECTRIC] > 0 and not white_glass:
        messages.add(f"{owner}: Multiscatter GGX on the coloured transmission of node "
                     f"'{name}' is not supported yet; rendered as single-scattering GGX")
