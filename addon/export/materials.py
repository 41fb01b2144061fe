"""Blender materials -> rows of :class:`core.scene.Materials`.

A material's surface shader becomes a :class:`Surface`: one of the core's closed set of BSDFs
(diffuse, conductor, dielectric, layered coat over diffuse) or a mixture of them. The Principled
BSDF becomes the mixture Cycles' Principled weighs; Mix Shaders are flattened into mixtures;
the other BSDF nodes map one to one; anything else is reported and rendered as diffuse.
:class:`MaterialTable` numbers the materials a scene uses and lays out their rows.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...core.scene import (
    MAT_CONDUCTOR,
    MAT_DIELECTRIC,
    MAT_DIFFUSE,
    MAT_LAYERED,
    Materials,
)
from .alpha import (LAYOUT, emission_note, mean_opacity, mix_fac_texture,
                    principled_alpha_texture)
from .anisotropy import AXES, glossy_anisotropy, principled_anisotropy
from .nodes import NodeReader, active_output, follow_link, node_name, uses_nodes
from .normal_maps import bump_map_correction, mixed_normal_input, normal_input
from .textures import roughness_texture, scalar_texture, surface_texture

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
    metal = scalar_texture(node, "Metallic", owner, messages)
    if metal is not None and depth > 0:
        messages.add(f"{owner}: the metallic texture of node '{node_name(node)}' inside a mix "
                     f"is not supported yet; using the input's own value")
        return None
    return metal


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
            _texture_key(surface.coat_weight_texture))


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
    1 with ``weight_texture``, which gives the weight per hit); a linked Coat Normal is
    reported (the coat uses the shading normal)."""
    weight = (1.0 if weight_texture is not None
              else min(max(read.value(node, "Coat Weight"), 0.0), 1.0))
    if weight <= 0:
        return {"coat_weight": 0.0}
    read.ignored_if_linked(node, "Coat Normal", "the coat normal input")
    return {"coat_weight": weight,
            "coat_roughness": min(max(read.value(node, "Coat Roughness", 0.03), 0.0), 1.0),
            "coat_ior": max(read.value(node, "Coat IOR", 1.5), 1.0),
            "coat_tint": np.maximum(read.color(node, "Coat Tint", (1.0, 1.0, 1.0)), 0.0)}


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


# Textures a mixture's components carry (the mesh needs UVs when any is set).
_COMPONENT_TEXTURES = ("texture", "roughness_texture", "specular_level_texture",
                       "coat_weight_texture")


class MaterialTable:
    """Rows of :class:`core.scene.Materials`: one per distinct Blender material used, plus the
    component rows of the mixtures among them (after their mixture row)."""

    def __init__(self, messages):
        self.messages = messages
        self._rows = {}
        self.names = []
        self.surfaces = []
        self.mixes = []  # per row: ((component row, weight), ...)

    def row(self, material):
        """Row index of ``material`` (None: Cycles' default surface), adding it if new."""
        key = material.original.as_pointer() if material is not None else 0
        index = self._rows.get(key)
        if index is None:
            surface = material_surface(material, self.messages)
            name = material.name if material is not None else DEFAULT_SURFACE_NAME
            index = self._add(name, surface)
            self._rows[key] = index
            if surface.components:
                self.mixes[index] = tuple(
                    (self._add(f"{name} [{i}]", component), weight)
                    for i, (weight, component) in enumerate(surface.components))
        return index

    def _add(self, name, surface):
        index = len(self.names)
        self.names.append(name)
        self.surfaces.append(surface._replace(
            base_color=np.clip(surface.base_color, 0.0, 1.0),
            emission=np.maximum(surface.emission, 0.0),
            specular_tint=np.clip(surface.specular_tint, 0.0, 1.0)))
        self.mixes.append(((index, 1.0),))
        return index

    def build(self):
        if not self.names:
            return Materials.from_lists([], np.zeros((0, 3)), np.zeros((0, 3)))
        col = {field: [getattr(s, field) for s in self.surfaces] for field in Surface._fields}
        width = max(len(mix) for mix in self.mixes)
        mix_rows = np.zeros((len(self.names), width), np.int32)
        mix_weights = np.zeros((len(self.names), width), np.float32)
        for index, mix in enumerate(self.mixes):
            rows, weights = zip(*mix)
            mix_rows[index] = rows[0]  # padding: the first component, of weight 0
            mix_rows[index, :len(rows)] = rows
            mix_weights[index, :len(rows)] = np.asarray(weights) / np.sum(weights)
        return Materials.from_lists(
            self.names, col["base_color"], col["emission"], kinds=col["kind"],
            roughness=col["roughness"], ior=col["ior"], metallic=col["metallic"],
            transmission=col["transmission"], specular_ior_level=col["specular_ior_level"],
            specular_tint=col["specular_tint"], multiscatter=col["multiscatter"],
            coat_weight=col["coat_weight"], coat_roughness=col["coat_roughness"],
            coat_ior=col["coat_ior"], coat_tint=col["coat_tint"],
            sheen_weight=col["sheen_weight"], sheen_roughness=col["sheen_roughness"],
            sheen_tint=col["sheen_tint"], aniso_scale=col["aniso_scale"],
            aniso_rotation=col["aniso_rotation"],
            texture=self._texture_index()[0], roughness_texture=self._texture_index()[1],
            normal_texture=self._texture_index()[3],
            normal_strength=[1.0 if s.normal_map is None else s.normal_map.strength
                             for s in self.surfaces],
            bump_texture=self._texture_index()[4],
            bump_distance=[1.0 if s.bump is None else s.bump.distance for s in self.surfaces],
            bump_strength=[1.0 if s.bump is None else s.bump.strength for s in self.surfaces],
            metallic_texture=self._texture_index()[5], bump_correction=col["bump_correction"],
            alpha_texture=self._texture_index()[6],
            alpha_invert=[s.alpha_texture is not None and bool(s.alpha_texture[2])
                          for s in self.surfaces],
            alpha_clear=col["alpha_clear"], specular_level_texture=self._texture_index()[7],
            coat_weight_texture=self._texture_index()[8], mix_rows=mix_rows,
            mix_weights=mix_weights)

    def _texture_index(self):
        """``(m,) int32`` indices into the distinct textures per row for the base colour and
        for the roughness (-1 for none), those textures as
        ``[(pixels, (interpolation, extension)), ...]``, and the indices for the normal map and
        the bump height."""
        columns, distinct, found = tuple([] for _ in range(8)), [], {}
        for s in self.surfaces:
            normal = s.normal_map or (None, None, None)
            bump = s.bump or (None, None)
            metal = s.metallic_texture or (None, None)
            alpha = s.alpha_texture or (None, None)
            level = s.specular_level_texture or (None, None)
            coat = s.coat_weight_texture or (None, None)
            for column, pixels, mode in ((columns[0], s.texture, s.texture_mode),
                                         (columns[1], s.roughness_texture,
                                          s.roughness_texture_mode),
                                         (columns[2], normal[0], normal[1]),
                                         (columns[3], bump[0], bump[1]),
                                         (columns[4], metal[0], metal[1]),
                                         (columns[5], alpha[0], alpha[1]),
                                         (columns[6], level[0], level[1]),
                                         (columns[7], coat[0], coat[1])):
                if pixels is None:
                    column.append(-1)
                    continue
                key = (id(pixels), mode)
                if key not in found:
                    found[key] = len(distinct)
                    distinct.append((pixels, mode))
                column.append(found[key])
        return (np.asarray(columns[0], np.int32), np.asarray(columns[1], np.int32), distinct,
                np.asarray(columns[2], np.int32), np.asarray(columns[3], np.int32),
                *(np.asarray(c, np.int32) for c in columns[4:]))

    @property
    def textures(self):
        """Distinct images in order of first use (``Scene.textures``)."""
        return [pixels for pixels, _ in self._texture_index()[2]]

    @property
    def texture_modes(self):
        """``(interpolations, extensions)`` of :attr:`textures` (``Scene.texture_*``)."""
        modes = [mode for _, mode in self._texture_index()[2]]
        return [m[0] for m in modes], [m[1] for m in modes]

    def texture_rows(self):
        """``(m,) int32`` index into :attr:`textures` per row, -1 for untextured rows."""
        return self._texture_index()[0]

    def tangent_axes(self, rows):
        """``(t,) int8`` axis code (:data:`.anisotropy.AXES`) of the radial tangent each
        triangle of material rows ``rows (t,)`` needs: its first anisotropic component's."""
        codes = np.zeros(len(self.names), np.int8)
        for r, mix in enumerate(self.mixes):
            axes = [self.surfaces[c].tangent_axis for c, _ in mix
                    if self.surfaces[c].tangent_axis is not None]
            codes[r] = AXES[axes[0]] if axes else 0
        return codes[np.asarray(rows, np.int64)]

    def textured(self, rows):
        """Whether any of the material rows ``rows`` (or their components) has a texture."""
        return self.normal_mapped(rows) or self._bumped(rows) or any(
            any(getattr(self.surfaces[c], field) is not None for field in _COMPONENT_TEXTURES)
            for r in np.unique(rows) for c, _ in self.mixes[int(r)])

    def normal_mapped(self, rows):
        """Whether any of the material rows ``rows`` has a normal map."""
        return any(self.surfaces[int(r)].normal_map is not None for r in np.unique(rows))

    def _bumped(self, rows):
        """Whether any of the material rows ``rows`` has a Bump node, a Metallic or an alpha
        on an image (textures of the row itself, not of its components)."""
        return any(self.surfaces[int(r)].bump is not None
                   or self.surfaces[int(r)].metallic_texture is not None
                   or self.surfaces[int(r)].alpha_texture is not None for r in np.unique(rows))
