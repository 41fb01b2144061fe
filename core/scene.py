"""Scene tables: the flat, struct-of-arrays description every integrator reads.

The exporter (``addon/export/``) and the built-in scenes (``core/scenes.py``) both produce a
:class:`Scene`. Everything is in world space, in Blender units and Cycles' light units (see
``docs/CONVENTIONS.md``): lights carry the *radiometric* quantity the integrators need
(intensity, radiance or irradiance), already converted from Blender's Watts by
:func:`core.lights` helpers.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# Material kinds: the codes of core/materials/bsdf.py's KIND_* (one module per family).
MAT_DIFFUSE = 0
MAT_CONDUCTOR = 1
MAT_DIELECTRIC = 2
MAT_LAYERED = 3

# Blender's defaults for the optional material columns.
DEFAULT_ROUGHNESS = 0.5
DEFAULT_IOR = 1.5
DEFAULT_SPECULAR_IOR_LEVEL = 0.5
DEFAULT_COAT_ROUGHNESS = 0.03
DEFAULT_COAT_IOR = 1.5

# Light kinds.
LIGHT_POINT = 0   # point or spot, optionally a sphere of `radius`
LIGHT_SUN = 1     # distant light, optionally a disk of angular diameter `angle`
LIGHT_RECT = 2    # area light: square or rectangle, one-sided toward its local -Z
LIGHT_DISK = 3    # area light: disk or ellipse, one-sided toward its local -Z

# Ray visibility bits, as Cycles' object ray visibility.
VIS_CAMERA = 1
VIS_DIFFUSE = 2
VIS_GLOSSY = 4
VIS_TRANSMISSION = 8
VIS_SHADOW = 16
VIS_ALL = 31


@dataclass
class Camera:
    """Blender's camera (perspective or orthographic) at a resolution.

    Parameters
    ----------
    to_world : (4, 4) float64
        Camera object matrix (orthonormal rotation + translation; the camera looks down its
        local -Z with +Y up, as in Blender).
    width, height : int
        Render resolution in pixels (after the resolution percentage).
    type : str
        ``'PERSP'`` or ``'ORTHO'``.
    lens : float
        Focal length in mm (perspective).
    sensor_width, sensor_height : float
        Sensor size in mm.
    sensor_fit : str
        ``'AUTO'``, ``'HORIZONTAL'`` or ``'VERTICAL'``.
    shift_x, shift_y : float
        Lens shift in units of the fitted sensor dimension.
    clip_start, clip_end : float
        Clipping distances, measured along the view axis (as Cycles does).
    ortho_scale : float
        Width of the fitted dimension in Blender units (orthographic).
    pixel_aspect_x, pixel_aspect_y : float
        Pixel aspect ratio.
    """

    to_world: np.ndarray
    width: int
    height: int
    type: str = "PERSP"
    lens: float = 50.0
    sensor_width: float = 36.0
    sensor_height: float = 24.0
    sensor_fit: str = "AUTO"
    shift_x: float = 0.0
    shift_y: float = 0.0
    clip_start: float = 0.1
    clip_end: float = 1000.0
    ortho_scale: float = 6.0
    pixel_aspect_x: float = 1.0
    pixel_aspect_y: float = 1.0


def bool_column(values, m):
    """An ``(m,) bool`` column of a material table (default False)."""
    if values is None:
        return np.zeros(m, bool)
    return np.broadcast_to(np.asarray(values, bool), (m,)).copy()


def texture_column(values, m):
    """The ``(m,) int32`` texture index column of a material table (-1 = untextured)."""
    if values is None:
        return np.full(m, -1, np.int32)
    return np.broadcast_to(np.asarray(values, np.int32), (m,)).copy()


# Image texture lookups modelled (Cycles' Image Texture node's interpolation and extension).
TEXTURE_INTERPOLATIONS = ("Linear", "Closest")
TEXTURE_EXTENSIONS = ("REPEAT", "EXTEND", "CLIP", "MIRROR")


def _texture_modes(values, n, default, allowed):
    """One mode per texture (``default`` when ``values`` is None), checked against ``allowed``."""
    modes = [default] * n if values is None else list(values)
    if len(modes) != n or any(m not in allowed for m in modes):
        raise ValueError(f"expected {n} texture modes among {allowed}, got {modes}")
    return modes


@dataclass
class Materials:
    """Material table, one row per material.

    Attributes
    ----------
    kind : (m,) int32
        ``MAT_*`` code (equal to :mod:`core.materials.bsdf`'s ``KIND_*``).
    base_color : (m, 3) float32
        Diffuse albedo (diffuse, layered), F0 (conductor) or transmission tint (dielectric), in
        [0, 1].
    emission : (m, 3) float32
        Emitted radiance (W / (sr m^2)), from both faces; zero for non-emitters.
    names : list of str
        Material names, for messages.
    roughness : (m,) float32
        Blender roughness in [0, 1] (GGX alpha = roughness^2); default 0.5.
    ior : (m,) float32
        Index of refraction (dielectric, layered coat); default 1.5.
    metallic : (m,) float32
        Principled Metallic as exported (informative: ``kind`` already encodes the lobe); 0.
    transmission : (m,) float32
        Principled Transmission Weight as exported (informative, like ``metallic``); 0.
    specular_ior_level : (m,) float32
        Principled Specular IOR Level (layered rows); default 0.5 (keeps the IOR).
    specular_tint : (m, 3) float32
        Reflection tint (dielectric) or coat tint (layered); default white.
    multiscatter : (m,) bool
        Blender's *Multiscatter GGX*: rough conductor and layered rows get Cycles' energy
        compensation for light that bounces between microfacets
        (:mod:`core.materials.multiscatter`). Ignored on other kinds (the exporter reports
        it there). Default False: single scattering.
    coat_weight : (m,) float32
        Principled Coat Weight in [0, 1]: a clear coat over the row's BSDF
        (:mod:`core.materials.coat`); default 0 (none).
    coat_roughness, coat_ior : (m,) float32
        The coat's roughness and IOR; defaults 0.03 and 1.5, Blender's.
    coat_tint : (m, 3) float32
        Coat Tint (transmittance of the coat at normal incidence); default white.
    sheen_weight : (m,) float32
        Principled Sheen Weight (>= 0): a microfiber sheen over the row's BSDF and coat
        (:mod:`core.materials.sheen`); default 0 (none).
    sheen_roughness : (m,) float32
        Sheen Roughness in [0, 1]; default 0.5, Blender's.
    sheen_tint : (m, 3) float32
        Sheen Tint; default white.
    aniso_scale : (m,) float32
        Anisotropic GGX of conductor and layered rows (:mod:`core.materials.anisotropic`):
        ``alpha_x = alpha k``, ``alpha_y = alpha / k`` along the tangent
        (:attr:`Scene.aniso_tangents`) and the bitangent; default 1 (isotropic).
    aniso_rotation : (m,) float32
        Anisotropic Rotation, in turns about the normal (Blender's); default 0.
    texture : (m,) int32
        Row of :attr:`Scene.textures` whose lookup replaces ``base_color`` at shading time
        (an Image Texture into the base colour); -1 (the default) for none.
    roughness_texture : (m,) int32
        Row of :attr:`Scene.textures` whose lookup (its luminance, as Blender converts a
        colour to a float socket) replaces ``roughness`` at shading time (an Image Texture
        into the Roughness input); -1 (the default) for none.
    normal_texture : (m,) int32
        Row of :attr:`Scene.textures` of a tangent-space Normal Map node feeding the row's
        Normal input (Non-Color data; :mod:`core.normal_maps`); -1 (the default) for none.
        It perturbs the shading normal of the triangles whose own row this is (a mixture's
        normal map applies to all its components).
    normal_strength : (m,) float32
        The Normal Map node's Strength; default 1.
    bump_texture : (m,) int32
        Row of :attr:`Scene.textures` whose luminance is the Height of a Bump node feeding the
        row's Normal input (after its normal map, if the Bump node's own Normal is one;
        :mod:`core.bump`); -1 (the default) for none. Applies like ``normal_texture``.
    metallic_texture : (m,) int32
        Row of :attr:`Scene.textures` whose luminance is a Principled mixture row's Metallic
        (:mod:`core.metallic`: the row's components are re-weighted at each hit from the
        ``metallic`` the mixture was laid out for); -1 (the default) for none.
    specular_level_texture, coat_weight_texture : (m,) int32
        Rows of :attr:`Scene.textures` whose luminance (Non-Color data as stored) replaces
        the row's ``specular_ior_level`` or ``coat_weight`` at each hit, as ``roughness_texture``
        does the roughness (the exporter sets ``coat_weight`` 1 so that the coat exists);
        -1 (the default) for none.
    alpha_texture : (m,) int32
        Row of :attr:`Scene.textures` whose luminance (a one-channel image: its value) is a
        mixture row's opacity per hit (:mod:`core.alpha`: Principled Alpha, or a Mix Shader
        with Transparent BSDF whose Fac is a texture); -1 (the default) for none.
    alpha_invert : (m,) bool
        The opacity is one minus the lookup (a Mix Shader whose second input is the Transparent
        BSDF); default False.
    alpha_clear : (m,) bool
        Component rows on the transparent side of their mixture's textured alpha: their weight
        follows ``1 - opacity``, the other components' ``opacity``; default False.
    bump_distance, bump_strength : (m,) float32
        The Bump node's Distance (negated when Invert is on) and Strength; defaults 1, 1.
    bump_correction : (m,) bool
        Cycles' Bump Map Correction on the diffuse lobes of the triangles whose own row this
        is (:mod:`core.materials.bump_correction`), where a normal map or bump perturbs their
        normal; default False.
    coat_mapped : (m,) bool
        The coat shades around the row's (mapped) shading normal: the Principled Coat Normal
        is linked to the same normal as its Normal input. False (the default): the coat keeps
        the smooth normal under normal maps and bumps, as Cycles' unlinked Coat Normal
        (:mod:`core.materials.coat`).
    mix_rows : (m, c) int32
        Component rows of each material: a row whose ``mix_rows`` is more than itself is a
        *mixture* (a Principled BSDF with fractional Metallic, Transmission or Alpha, a Mix
        Shader between different kinds) of the BSDFs of those rows, one chosen per shading
        point with probability ``mix_weights`` (see :meth:`core.prepare.PreparedScene.
        choose_bsdf`). Components are plain rows (their own ``mix_rows`` is themselves);
        short mixtures are padded with weight 0. Default: every row is its own single
        component. A mixture row's own BSDF columns are unused; its ``emission`` is the
        mixture's. Components carry no emission.
    mix_weights : (m, c) float32
        Mixing weights, >= 0, summing to 1 per row.
    """

    kind: np.ndarray
    base_color: np.ndarray
    emission: np.ndarray
    names: list = field(default_factory=list)
    roughness: np.ndarray = None
    ior: np.ndarray = None
    metallic: np.ndarray = None
    transmission: np.ndarray = None
    specular_ior_level: np.ndarray = None
    specular_tint: np.ndarray = None
    multiscatter: np.ndarray = None
    coat_weight: np.ndarray = None
    coat_roughness: np.ndarray = None
    coat_ior: np.ndarray = None
    coat_tint: np.ndarray = None
    sheen_weight: np.ndarray = None
    sheen_roughness: np.ndarray = None
    sheen_tint: np.ndarray = None
    aniso_scale: np.ndarray = None
    aniso_rotation: np.ndarray = None
    texture: np.ndarray = None
    roughness_texture: np.ndarray = None
    normal_texture: np.ndarray = None
    normal_strength: np.ndarray = None
    bump_texture: np.ndarray = None
    metallic_texture: np.ndarray = None
    specular_level_texture: np.ndarray = None
    coat_weight_texture: np.ndarray = None
    alpha_texture: np.ndarray = None
    alpha_invert: np.ndarray = None
    alpha_clear: np.ndarray = None
    bump_distance: np.ndarray = None
    bump_strength: np.ndarray = None
    bump_correction: np.ndarray = None
    coat_mapped: np.ndarray = None
    mix_rows: np.ndarray = None
    mix_weights: np.ndarray = None

    def __post_init__(self):
        # Absent columns take Blender's defaults, so every table has every column.
        m = np.shape(self.kind)[0]

        def column(values, default, shape=()):
            if values is None:
                return np.full((m,) + shape, default, np.float32)
            return np.broadcast_to(np.asarray(values, np.float32), (m,) + shape).copy()

        self.roughness = column(self.roughness, DEFAULT_ROUGHNESS)
        self.ior = column(self.ior, DEFAULT_IOR)
        self.metallic = column(self.metallic, 0.0)
        self.transmission = column(self.transmission, 0.0)
        self.specular_ior_level = column(self.specular_ior_level, DEFAULT_SPECULAR_IOR_LEVEL)
        self.specular_tint = column(self.specular_tint, 1.0, (3,))
        self.multiscatter = (np.zeros(m, bool) if self.multiscatter is None
                             else np.broadcast_to(np.asarray(self.multiscatter, bool), (m,)).copy())
        self.coat_weight = np.clip(column(self.coat_weight, 0.0), 0.0, 1.0)
        self.coat_roughness = column(self.coat_roughness, DEFAULT_COAT_ROUGHNESS)
        self.coat_ior = column(self.coat_ior, DEFAULT_COAT_IOR)
        self.coat_tint = column(self.coat_tint, 1.0, (3,))
        self.sheen_weight = np.maximum(column(self.sheen_weight, 0.0), 0.0)
        self.sheen_roughness = np.clip(column(self.sheen_roughness, 0.5), 0.0, 1.0)
        self.sheen_tint = np.maximum(column(self.sheen_tint, 1.0, (3,)), 0.0)
        self.aniso_scale = column(self.aniso_scale, 1.0)
        self.aniso_rotation = column(self.aniso_rotation, 0.0)
        self.texture = texture_column(self.texture, m)
        self.roughness_texture = texture_column(self.roughness_texture, m)
        self.normal_texture = texture_column(self.normal_texture, m)
        self.normal_strength = column(self.normal_strength, 1.0)
        self.bump_texture = texture_column(self.bump_texture, m)
        self.metallic_texture = texture_column(self.metallic_texture, m)
        self.alpha_texture = texture_column(self.alpha_texture, m)
        self.specular_level_texture = texture_column(self.specular_level_texture, m)
        self.coat_weight_texture = texture_column(self.coat_weight_texture, m)
        self.alpha_invert = bool_column(self.alpha_invert, m)
        self.alpha_clear = bool_column(self.alpha_clear, m)
        self.bump_distance = column(self.bump_distance, 1.0)
        self.bump_strength = column(self.bump_strength, 1.0)
        self.bump_correction = (np.zeros(m, bool) if self.bump_correction is None else
                                np.broadcast_to(np.asarray(self.bump_correction, bool),
                                                (m,)).copy())
        self.coat_mapped = (np.zeros(m, bool) if self.coat_mapped is None else
                            np.broadcast_to(np.asarray(self.coat_mapped, bool), (m,)).copy())
        self._check_mix(m)

    def _check_mix(self, m):
        """Normalise the mixture table (default: each row its own component) and check it."""
        if self.mix_rows is None:
            self.mix_rows = np.arange(m, dtype=np.int32)[:, None]
            self.mix_weights = np.ones((m, 1), np.float32)
            return
        rows = np.asarray(self.mix_rows, np.int32).reshape(m, -1)
        weights = np.asarray(self.mix_weights, np.float32).reshape(rows.shape)
        if rows.size and (rows.min() < 0 or rows.max() >= m):
            raise ValueError("mix_rows must index rows of the material table")
        if np.any(~np.isfinite(weights)) or np.any(weights < 0):
            raise ValueError("mix_weights must be finite and >= 0")
        total = weights.sum(axis=1)
        if m and np.any(np.abs(total - 1.0) > 1e-4):
            raise ValueError("mix_weights must sum to 1 per material")
        component = np.unique(rows[weights > 0])
        own = np.arange(m)
        flat = (rows[component] == own[component, None]) | (weights[component] == 0)
        if not flat.all():
            raise ValueError("mixture components must be single rows, not mixtures")
        self.mix_rows = np.ascontiguousarray(rows)
        self.mix_weights = np.ascontiguousarray(weights)

    @property
    def mixed(self):
        """``(m,) bool``: rows shaded by other rows (mixtures, even of a single component)."""
        own = np.arange(self.mix_rows.shape[0])[:, None]
        return np.any((self.mix_rows != own) & (self.mix_weights > 0), axis=1)

    @staticmethod
    def from_lists(names, base_colors, emissions, kinds=None, roughness=None, ior=None,
                   metallic=None, transmission=None, specular_ior_level=None,
                   specular_tint=None, texture=None, mix_rows=None,
                   mix_weights=None, multiscatter=None, coat_weight=None,
                   coat_roughness=None, coat_ior=None, coat_tint=None,
                   roughness_texture=None, sheen_weight=None, sheen_roughness=None,
                   sheen_tint=None, aniso_scale=None, aniso_rotation=None,
                   normal_texture=None, normal_strength=None, bump_texture=None,
                   bump_distance=None, bump_strength=None,
                   metallic_texture=None, bump_correction=None, alpha_texture=None,
                   alpha_invert=None, alpha_clear=None, specular_level_texture=None,
                   coat_weight_texture=None, coat_mapped=None) -> "Materials":
        """A table from per-material lists; omitted columns take Blender's defaults."""
        m = len(names)
        return Materials(
            kind=np.zeros(m, np.int32) if kinds is None else np.asarray(kinds, np.int32),
            base_color=np.asarray(base_colors, np.float32).reshape(m, 3),
            emission=np.asarray(emissions, np.float32).reshape(m, 3),
            names=list(names),
            roughness=roughness, ior=ior, metallic=metallic, transmission=transmission,
            specular_ior_level=specular_ior_level,
            specular_tint=None if specular_tint is None
            else np.asarray(specular_tint, np.float32).reshape(-1, 3),
            multiscatter=multiscatter, texture=texture, mix_rows=mix_rows,
            mix_weights=mix_weights, coat_weight=coat_weight, coat_roughness=coat_roughness,
            coat_ior=coat_ior, roughness_texture=roughness_texture,
            normal_texture=normal_texture, normal_strength=normal_strength,
            bump_texture=bump_texture, bump_distance=bump_distance, bump_strength=bump_strength,
            bump_correction=bump_correction, metallic_texture=metallic_texture,
            alpha_texture=alpha_texture, alpha_invert=alpha_invert, alpha_clear=alpha_clear,
            specular_level_texture=specular_level_texture,
            coat_weight_texture=coat_weight_texture, coat_mapped=coat_mapped,
            coat_tint=None if coat_tint is None
            else np.asarray(coat_tint, np.float32).reshape(-1, 3),
            sheen_weight=sheen_weight, sheen_roughness=sheen_roughness,
            aniso_scale=aniso_scale, aniso_rotation=aniso_rotation,
            sheen_tint=None if sheen_tint is None
            else np.asarray(sheen_tint, np.float32).reshape(-1, 3),
        )


@dataclass
class Lights:
    """Light table (non-mesh lights), one row per light.

    Attributes
    ----------
    kind : (k,) int32
        ``LIGHT_*`` code.
    position : (k, 3) float64
        World position (point, spot, area centre). Unused for suns.
    axis_x, axis_y : (k, 3) float64
        Area light edge vectors scaled to the full size (rect: the quad spans
        ``position ± axis_x/2 ± axis_y/2``; disk/ellipse: semi-axes are half of them).
    direction : (k, 3) float64
        Unit emission direction: the area light's and spot's local -Z; for a sun the
        direction light travels (so ``-direction`` points at the sun).
    radius : (k,) float64
        Sphere radius of point / spot lights (0 = delta point).
    angle : (k,) float64
        Sun angular diameter in radians (0 = delta direction).
    radiance : (k, 3) float64
        Point/spot of radius 0: intensity in W/sr. Sphere point/spot: radiance of the sphere.
        Sun of angle 0: irradiance in W/m^2; sun with angle: radiance of the disk.
        Area: radiance of the emitting face.
    spot_cos_half : (k,) float64
        cos(spot_size / 2); -1 for a point light (no cone).
    spot_smooth : (k,) float64
        1 / ((1 - cos_half) * blend); inf for a hard-edged cone.
    power : (k,) float64
        Estimated emitted power (W) for light selection.
    visible_camera : (k,) bool
        Whether camera rays see the lamp's own shape.
    soft_falloff : (k,) bool
        Blender's *Soft Falloff* of point and spot lights with a radius (on by default in
        Blender): the lamp is a disk of ``radius`` facing each receiving point, as Cycles (and
        Blender up to 3.6) does, instead of a sphere.
    names : list of str
    """

    kind: np.ndarray
    position: np.ndarray
    axis_x: np.ndarray
    axis_y: np.ndarray
    direction: np.ndarray
    radius: np.ndarray
    angle: np.ndarray
    radiance: np.ndarray
    spot_cos_half: np.ndarray
    spot_smooth: np.ndarray
    power: np.ndarray
    visible_camera: np.ndarray
    soft_falloff: np.ndarray
    names: list = field(default_factory=list)

    def __len__(self) -> int:
        return int(self.kind.shape[0])

    @staticmethod
    def empty() -> "Lights":
        z3 = np.zeros((0, 3))
        z = np.zeros(0)
        return Lights(np.zeros(0, np.int32), z3, z3, z3, z3, z, z, z3, z, z, z,
                      np.zeros(0, bool), np.zeros(0, bool), [])

    @staticmethod
    def concat(rows: list) -> "Lights":
        """Build a table from a list of single-light tables (see ``core.lights``)."""
        if not rows:
            return Lights.empty()
        out = {}
        for name in Lights.__dataclass_fields__:
            if name == "names":
                continue
            out[name] = np.concatenate([getattr(r, name) for r in rows])
        return Lights(**out, names=sum((r.names for r in rows), []))


@dataclass
class Scene:
    """Everything a render needs, as flat arrays.

    Attributes
    ----------
    vertices : (v, 3) float32
        World-space vertex positions.
    triangles : (t, 3) int32
        Vertex indices per triangle.
    material : (t,) int32
        Material row per triangle.
    visibility : (t,) int32
        ``VIS_*`` bit mask per triangle (object ray visibility).
    materials : Materials
    lights : Lights
    world_color : (3,) float64
        Constant background radiance (World Background Color x Strength); unused when
        ``world_map`` is given.
    world_map : (h, w, 3) float32 or None
        Equirectangular environment radiance (an Environment Texture into the Background node:
        image RGB x Strength), or None for a constant world. Row 0 is the bottom row (the
        nadir), as Blender stores images. Cycles' mapping (``direction_to_equirectangular``):
        a world direction d = (x, y, z) looks up ``u = 0.5 - atan2(y, x) / (2 pi)``,
        ``v = 0.5 + atan2(z, hypot(x, y)) / pi`` (u = 0.5 faces +X, u = 0.25 faces +Y,
        v = 1 is the zenith), with bilinear interpolation between pixel centres, wrapping on
        both axes (Cycles' default Linear interpolation and Repeat extension); see
        :func:`core.lights.environment_lookup`.
    textures : list of (h, w, 3) or (h, w, 1) float32
        Images (row 0 at the bottom, v = 0; one channel: an Image Texture's Alpha output,
        :mod:`core.alpha`), indexed by the ``Materials.*texture`` columns, looked up at the
        hit's interpolated UV as Cycles' Image Texture node does with
        ``texture_interpolation`` and ``texture_extension``, see
        :func:`core.textures.texture_lookup`.
    texture_interpolation : list of str
        Per texture, ``'Linear'`` (the default) or ``'Closest'``.
    texture_extension : list of str
        Per texture, ``'REPEAT'`` (the default), ``'EXTEND'``, ``'CLIP'`` or ``'MIRROR'``.
    corner_uvs : (t, 3, 2) float32 or None
        UV (active UV map) at each triangle corner, in vertex order; None when no material
        is textured. Rows of untextured meshes are zero.
    camera : Camera or None
    messages : list of str
        What the exporter approximated or ignored, said once per render.
    corner_normals : (t, 3, 3) float32 or None
        Unit world-space shading normals at each triangle's three corners (Blender's corner
        normals, smooth shading), or None when every face is flat (shading normal = geometric
        normal). See :func:`core.integrators.common.shading_normals`. Filled with the face
        normals when a material has a normal map and every face is flat.
    aniso_tangents : (t, 3, 3) float32 or None
        World-space tangents (any length) at each triangle's corners for anisotropic BSDFs
        (Cycles' Tangent input: by default a radial tangent around the object's Z axis),
        interpolated with the hit's barycentrics and projected on the shading normal's plane
        (:func:`core.integrators.common.shading_tangents`); zero rows, or None, give the
        default frame. Non-finite values become zero.
    corner_tangents : (t, 3, 4) float32 or None
        World-space UV tangent (xyz, MikkTSpace, of the active UV map) and bitangent sign (w)
        at each triangle corner, for tangent-space normal maps (:mod:`core.normal_maps`);
        None when no material has one (scenes without normal maps pay nothing). Rows of
        meshes without normal maps are zero.
    film_transparent : bool
        Blender's Film > Transparent: camera rays that escape to the world (also through
        transparent surfaces) show alpha 0 instead of the world, which still lights the scene.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    material: np.ndarray
    materials: Materials
    lights: Lights
    camera: Camera | None
    world_color: np.ndarray = field(default_factory=lambda: np.zeros(3))
    world_map: np.ndarray | None = None
    visibility: np.ndarray | None = None
    messages: list = field(default_factory=list)
    textures: list = field(default_factory=list)
    corner_uvs: np.ndarray | None = None
    corner_normals: np.ndarray | None = None
    aniso_tangents: np.ndarray | None = None
    corner_tangents: np.ndarray | None = None
    texture_interpolation: list = None
    texture_extension: list = None
    film_transparent: bool = False

    def __post_init__(self):
        self._check_corner_normals()
        if self.aniso_tangents is not None:
            self.aniso_tangents = np.ascontiguousarray(np.nan_to_num(
                np.asarray(self.aniso_tangents, np.float32), nan=0.0, posinf=0.0,
                neginf=0.0).reshape(-1, 3, 3))
            if self.aniso_tangents.shape[0] != np.shape(self.triangles)[0]:
                raise ValueError("aniso_tangents must have one (3, 3) row per triangle")
        self.vertices = np.ascontiguousarray(self.vertices, np.float32).reshape(-1, 3)
        self.triangles = np.ascontiguousarray(self.triangles, np.int32).reshape(-1, 3)
        self.material = np.ascontiguousarray(self.material, np.int32).reshape(-1)
        self.world_color = np.asarray(self.world_color, np.float64).reshape(3)
        if self.world_map is not None:
            self.world_map = np.ascontiguousarray(self.world_map, np.float32)
            if self.world_map.ndim != 3 or self.world_map.shape[2] != 3 \
                    or 0 in self.world_map.shape:
                raise ValueError(f"world_map must be a non-empty (h, w, 3) array, got shape "
                                 f"{self.world_map.shape}")
        if self.visibility is None:
            self.visibility = np.full(self.triangles.shape[0], VIS_ALL, np.int32)
        self._check_textures()

    def _check_textures(self):
        """Normalise ``textures`` and ``corner_uvs`` (textured scenes need both)."""
        self.textures = [np.ascontiguousarray(t, np.float32) for t in self.textures]
        for t in self.textures:
            if t.ndim != 3 or t.shape[2] not in (1, 3) or 0 in t.shape:
                raise ValueError(f"textures must be non-empty (h, w, 3) or (h, w, 1) arrays, "
                                 f"got {t.shape}")
        if self.corner_uvs is not None:
            self.corner_uvs = np.ascontiguousarray(self.corner_uvs, np.float32).reshape(
                self.triangles.shape[0], 3, 2)
        n = len(self.textures)
        self.texture_interpolation = _texture_modes(self.texture_interpolation, n, "Linear",
                                                    TEXTURE_INTERPOLATIONS)
        self.texture_extension = _texture_modes(self.texture_extension, n, "REPEAT",
                                                TEXTURE_EXTENSIONS)
        m = self.materials
        if max(m.texture.max(initial=-1), m.roughness_texture.max(initial=-1),
               m.normal_texture.max(initial=-1), m.bump_texture.max(initial=-1),
               m.metallic_texture.max(initial=-1), m.alpha_texture.max(initial=-1),
               m.specular_level_texture.max(initial=-1),
               m.coat_weight_texture.max(initial=-1)) >= n:
            raise ValueError("a material's texture index is past the end of textures")
        if self.textures and self.corner_uvs is None:
            raise ValueError("textured scenes need corner_uvs")
        self._check_corner_tangents()

    def _check_corner_tangents(self):
        """Normalise ``corner_tangents`` to (t, 3, 4) float32 in normal-mapped scenes (zero
        when not given: maps then keep the normal's direction, as Cycles without tangents), and
        give them corner normals (the face normals where every face is flat)."""
        m = self.materials
        if not (np.any(m.normal_texture >= 0) or np.any(m.bump_texture >= 0)):
            return
        t = self.triangles.shape[0]
        if self.corner_tangents is None and np.any(m.normal_texture >= 0):
            self.corner_tangents = np.zeros((t, 3, 4), np.float32)
        if self.corner_tangents is not None:
            self.corner_tangents = np.ascontiguousarray(
                np.nan_to_num(np.asarray(self.corner_tangents, np.float32)),
                np.float32).reshape(t, 3, 4)
        if self.corner_normals is None:
            tri = self.vertices.astype(np.float64)[self.triangles]
            face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            self.corner_normals = np.repeat(face[:, None, :], 3, axis=1)
            self._check_corner_normals()

    def _check_corner_normals(self):
        """Normalise ``corner_normals`` to unit (t, 3, 3) float32 (zero stays zero)."""
        if self.corner_normals is None:
            return
        n = np.asarray(self.corner_normals, np.float64).reshape(-1, 3, 3)
        if n.shape[0] != np.asarray(self.triangles).reshape(-1, 3).shape[0]:
            raise ValueError(f"corner_normals must have one (3, 3) row per triangle, got shape "
                             f"{n.shape}")
        length = np.linalg.norm(n, axis=2, keepdims=True)
        n = np.where(length > 0, n / np.maximum(length, 1e-300), 0.0)
        self.corner_normals = np.ascontiguousarray(np.nan_to_num(n), np.float32)

    @property
    def n_triangles(self) -> int:
        return int(self.triangles.shape[0])
