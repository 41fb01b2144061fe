"""The rows of :class:`core.scene.Materials` of a scene: one per distinct Blender material
used (translated by :func:`.materials.material_surface`), plus the component rows of the
mixtures among them, and the distinct textures they use."""

from __future__ import annotations

import numpy as np

from ...core.scene import Materials
from .anisotropy import AXES
from .materials import DEFAULT_SURFACE_NAME, Surface, material_surface


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
            coat_weight_texture=self._texture_index()[8], coat_mapped=col["coat_mapped"],
            mix_rows=mix_rows,
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
