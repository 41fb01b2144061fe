"""Render Properties panels of Sampling Lab, and Blender's own panels enabled for the engine."""

import bpy
from bpy.types import Panel

from .presets import draw_preset_row

ENGINE_ID = 'SAMPLING_LAB'


def settings_layout(panel, context):
    """A panel's property-split layout and the scene's Sampling Lab settings."""
    layout = panel.layout
    layout.use_property_split = True
    layout.use_property_decorate = False
    return layout, context.scene.sampling_lab


class SamplingLabButtonsPanel:
    """Mixin of every Sampling Lab panel in the Render Properties."""

    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = 'render'
    COMPAT_ENGINES = {ENGINE_ID}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class SAMPLINGLAB_RENDER_PT_sampling(SamplingLabButtonsPanel, Panel):
    bl_label = "Sampling"

    def draw(self, context):
        layout, settings = settings_layout(self, context)

        draw_preset_row(layout)
        col = layout.column()
        col.prop(settings, "integrator")
        col.prop(settings, "sampler")
        col.operator("samplinglab.sampler_lab", icon='GRAPH')
        col.separator()
        col.prop(settings, "samples")
        col.prop(settings, "viewport_samples")
        col.prop(settings, "time_limit")
        row = col.row(align=True)
        row.prop(settings, "seed")
        row.prop(settings, "use_animated_seed", text="", icon='TIME')


class SAMPLINGLAB_RENDER_PT_light_sampling(SamplingLabButtonsPanel, Panel):
    bl_label = "Light Sampling"
    bl_parent_id = "SAMPLINGLAB_RENDER_PT_sampling"

    def draw(self, context):
        layout, settings = settings_layout(self, context)

        light_tracing = settings.integrator == 'LIGHT'
        photon = settings.integrator in {'PHOTON', 'SPPM'}
        radiosity = settings.integrator == 'RADIOSITY'
        col = layout.column()
        mis = col.column()
        # Light tracing has one strategy per path, photon mapping one per light contribution
        # (direct light by light sampling alone), radiosity no strategies: nothing to weight.
        mis.active = not (light_tracing or photon or radiosity)
        mis.prop(settings, "mis_heuristic")
        # Each heuristic's parameter is shown only with the heuristic that reads it.
        if settings.mis_heuristic == 'POWER':
            mis.prop(settings, "mis_beta")
        elif settings.mis_heuristic == 'CUTOFF':
            mis.prop(settings, "mis_alpha")
        col.separator()
        sub = col.column()
        # BSDF sampling alone never samples lights, so the light sampler's options do nothing;
        # light tracing always starts at a light.
        sub.active = light_tracing or settings.mis_heuristic != 'BSDF'
        if radiosity:
            # Radiosity samples lights only in its final gather (core.applied_settings.used_settings).
            sub.active = settings.radiosity_display == 'FINAL_GATHER'
        sub.prop(settings, "light_selection")
        area = sub.column()
        # The path tracer, photon mapping's direct light and radiosity's final gather sample
        # emitters toward a receiving point (Metropolis runs the path tracer): light and BDPT
        # paths start on emitters sampled by area (core.applied_settings.used_settings).
        area.active = sub.active and (settings.integrator in {'PATH', 'MLT', 'RADIOSITY'}
                                      or photon)
        area.prop(settings, "light_sampling")
        # Where Bidirectional's s = 1 connections take their points on lights: its alone
        # (whatever the MIS: its light paths always sample lights).
        points = col.column()
        points.active = settings.integrator == 'BDPT'
        points.prop(settings, "light_points")
        # Also draws mixed materials' components: active whatever the light sampling.
        col.prop(settings, "distribution")


class SAMPLINGLAB_RENDER_PT_strategy_views(SamplingLabButtonsPanel, Panel):
    bl_label = "Strategy Views"
    bl_parent_id = "SAMPLINGLAB_RENDER_PT_sampling"
    bl_options = {'DEFAULT_CLOSED'}

    def draw_header(self, context):
        settings = context.scene.sampling_lab
        # Only Bidirectional writes per-strategy images.
        self.layout.active = settings.integrator == 'BDPT'
        self.layout.prop(settings, "use_strategy_views", text="")

    def draw(self, context):
        layout, settings = settings_layout(self, context)

        col = layout.column()
        col.active = settings.integrator == 'BDPT' and settings.use_strategy_views
        col.prop(settings, "strategy_max_length")


class SAMPLINGLAB_RENDER_PT_photons(SamplingLabButtonsPanel, Panel):
    bl_label = "Photon Mapping"
    bl_parent_id = "SAMPLINGLAB_RENDER_PT_sampling"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout, settings = settings_layout(self, context)

        # Biased but consistent estimators: only they read these settings
        # (core.applied_settings.used_settings says which ones each uses).
        jensen = settings.integrator == 'PHOTON'
        sppm = settings.integrator == 'SPPM'
        col = layout.column()
        col.active = jensen or sppm
        col.prop(settings, "photons")
        col.prop(settings, "photon_memory")
        sub = col.column()
        sub.active = sppm
        sub.prop(settings, "sppm_alpha")
        sub = col.column()
        sub.active = jensen
        sub.prop(settings, "photon_lookup")
        row = sub.column()
        row.active = jensen and settings.photon_lookup == 'KNN'
        row.prop(settings, "photon_k")
        row = col.column()
        # SPPM's initial radius; photon mapping's fixed radius.
        row.active = sppm or (jensen and settings.photon_lookup == 'RADIUS')
        row.prop(settings, "photon_radius")
        row = col.column()
        # Footprint radii replace the automatic initial radius only (core.applied_settings.used_settings).
        row.active = sppm and settings.photon_radius == 0.0
        row.prop(settings, "sppm_radius")
        row = col.column()
        row.active = sppm
        row.prop(settings, "use_sppm_coverage")
        col.prop(settings, "use_photon_surface_test")
        sub = col.column()
        sub.active = jensen
        sub.prop(settings, "photon_kernel")
        sub.prop(settings, "gather_rays")


class SAMPLINGLAB_RENDER_PT_mlt(SamplingLabButtonsPanel, Panel):
    bl_label = "Metropolis"
    bl_parent_id = "SAMPLINGLAB_RENDER_PT_sampling"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout, settings = settings_layout(self, context)

        col = layout.column()
        # Only Metropolis light transport mutates paths (core.applied_settings.used_settings).
        col.active = settings.integrator == 'MLT'
        col.prop(settings, "mlt_large_step")
        col.prop(settings, "mlt_bootstrap")
        col.prop(settings, "mlt_chains")
        if settings.integrator == 'MLT':
            note = layout.column(align=True)
            note.label(text="Consistent; b is estimated (its error is in the stats).",
                       icon='INFO')
            note.label(text="Samples are mutations per pixel.")


class SAMPLINGLAB_RENDER_PT_radiosity(SamplingLabButtonsPanel, Panel):
    bl_label = "Radiosity"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout, settings = settings_layout(self, context)

        col = layout.column()
        # Only the Radiosity integrator meshes the scene and solves; the others ignore these.
        col.active = settings.integrator == 'RADIOSITY'
        col.prop(settings, "radiosity_solver")
        col.prop(settings, "radiosity_patch_size")
        col.prop(settings, "radiosity_samples")
        adaptive = col.column()
        # Hierarchical radiosity's links adapt instead (core.applied_settings.used_settings).
        adaptive.active = col.active and settings.radiosity_solver != 'HIERARCHICAL'
        adaptive.prop(settings, "radiosity_adaptive")
        col.prop(settings, "radiosity_display")
        col.prop(settings, "use_radiosity_patches")
        if settings.integrator == 'RADIOSITY':
            note = layout.column(align=True)
            note.label(text="Biased: not consistent unless the patches shrink.", icon='INFO')
            note.label(text="Every material is treated as diffuse (its Base Color).")


class SAMPLINGLAB_RENDER_PT_light_paths(SamplingLabButtonsPanel, Panel):
    bl_label = "Light Paths"

    def draw(self, context):
        layout, settings = settings_layout(self, context)

        col = layout.column()
        # Radiosity has no path bounces: its transport is the solved system.
        col.active = settings.integrator != 'RADIOSITY'
        # Cycles' Light Paths > Max Bounces layout: Total, then one limit per kind, which
        # only the path tracer counts (core.applied_settings.used_settings).
        bounces = col.column(align=True, heading="Max Bounces")
        bounces.prop(settings, "max_bounces")
        kinds = col.column(align=True)
        kinds.active = settings.integrator in {'PATH', 'MLT'}
        kinds.prop(settings, "diffuse_bounces")
        kinds.prop(settings, "glossy_bounces")
        kinds.prop(settings, "transmission_bounces")
        # Light tracing's and BDPT's subpaths and connections cross at most this many
        # transparent surfaces together; photons and the photon estimators' camera paths each.
        transparent = col.column(align=True)
        transparent.active = settings.integrator in {'PATH', 'MLT', 'LIGHT', 'BDPT', 'PHOTON',
                                                     'SPPM'}
        transparent.prop(settings, "transparent_max_bounces")
        col.separator()
        rr = col.column()
        # Photon mapping's camera paths stop at the first rough surface, and its photons
        # always use roulette by albedo: the roulette settings do not apply.
        rr.active = settings.integrator not in {'PHOTON', 'SPPM'}
        rr.prop(settings, "use_russian_roulette")
        sub = rr.column()
        # The threshold only matters while roulette is on.
        sub.active = rr.active and settings.use_russian_roulette
        sub.prop(settings, "rr_min_bounces")
        sub.prop(settings, "rr_survival")
        # Roulette of connections (before their shadow rays): Bidirectional's alone.
        connection = col.column()
        connection.active = settings.integrator == 'BDPT'
        connection.prop(settings, "connection_roulette")


class SAMPLINGLAB_RENDER_PT_film(SamplingLabButtonsPanel, Panel):
    bl_label = "Film"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout, settings = settings_layout(self, context)

        col = layout.column()
        col.prop(settings, "filter_type")
        col.prop(settings, "filter_width")
        # Blender's own Film > Transparent, rendered as alpha by every estimator (from the
        # camera rays that escape; core.render.FILM_TRANSPARENT_INTEGRATORS).
        sub = col.column()
        sub.active = settings.integrator in {'PATH', 'LIGHT', 'BDPT', 'PHOTON', 'SPPM', 'MLT',
                                             'RADIOSITY'}
        sub.prop(context.scene.render, "film_transparent", text="Transparent")


class SAMPLINGLAB_RENDER_PT_performance(SamplingLabButtonsPanel, Panel):
    bl_label = "Performance"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout, settings = settings_layout(self, context)

        rd = context.scene.render
        col = layout.column()
        # Blender's own thread setting, read as Cycles reads it: Auto is one thread per core.
        col.prop(rd, "threads_mode")
        sub = col.column(align=True)
        sub.enabled = rd.threads_mode == 'FIXED'
        sub.prop(rd, "threads")
        # Worker processes run the units of path, light and BDPT final renders on more than
        # one thread (core.applied_settings.worker_mode); the viewport always uses threads.
        sub = col.column()
        # (rd.threads is the resolved count under Auto too.)
        sub.active = settings.integrator in {'PATH', 'LIGHT', 'BDPT'} and rd.threads > 1
        sub.prop(settings, "workers")


class SAMPLINGLAB_OBJECT_PT_ray_visibility(Panel):
    bl_label = "Ray Visibility"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = 'object'
    bl_parent_id = "OBJECT_PT_visibility"
    COMPAT_ENGINES = {ENGINE_ID}

    @classmethod
    def poll(cls, context):
        ob = context.object
        return (context.engine in cls.COMPAT_ENGINES and ob is not None
                and ob.type in {'MESH', 'CURVE', 'SURFACE', 'META', 'FONT', 'LIGHT'})

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        ob = context.object

        col = layout.column(heading="Visible To")
        col.prop(ob, "visible_camera", text="Camera", toggle=False)
        bounces = col.column()
        # Light Tracing and Bidirectional trace every segment of a camera path with the camera
        # rays' visibility and every light path segment with the shadow rays' (core.integrators.bdpt);
        # Metropolis runs the path tracer.
        path_tracing = context.scene.sampling_lab.integrator in {'PATH', 'MLT'}
        bounces.active = path_tracing
        bounces.prop(ob, "visible_diffuse", text="Diffuse", toggle=False)
        bounces.prop(ob, "visible_glossy", text="Glossy", toggle=False)
        bounces.prop(ob, "visible_transmission", text="Transmission", toggle=False)
        col.prop(ob, "visible_shadow", text="Shadow", toggle=False)
        if not path_tracing:
            note = layout.column(align=True)
            note.label(text="Path Tracing and Metropolis only: Diffuse, Glossy, Transmission.",
                       icon='INFO')
            note.label(text="Camera paths bounce with Camera visibility, light paths with Shadow.")


classes = (
    SAMPLINGLAB_RENDER_PT_sampling,
    SAMPLINGLAB_RENDER_PT_light_sampling,
    SAMPLINGLAB_RENDER_PT_strategy_views,
    SAMPLINGLAB_RENDER_PT_photons,
    SAMPLINGLAB_RENDER_PT_mlt,
    SAMPLINGLAB_RENDER_PT_radiosity,
    SAMPLINGLAB_RENDER_PT_light_paths,
    SAMPLINGLAB_RENDER_PT_film,
    SAMPLINGLAB_RENDER_PT_performance,
    SAMPLINGLAB_OBJECT_PT_ray_visibility,
)


# Blender's own panels that show for "any engine": the generic ones list 'BLENDER_RENDER'.
_COMPAT_MARKER = 'BLENDER_RENDER'
# Contexts whose generic panels describe things this engine honours.
_COMPAT_CONTEXTS = {'render', 'output', 'view_layer', 'data', 'object', 'world', 'material'}
# Generic panels for features the engine does not render.
_COMPAT_EXCLUDE_PREFIXES = (
    "RENDER_PT_freestyle", "VIEWLAYER_PT_freestyle", "MATERIAL_PT_freestyle",
    "DATA_PT_lightprobe", "DATA_PT_context_lightprobe", "RENDER_PT_gpencil",
    "RENDER_PT_grease_pencil", "RENDER_PT_simplify_greasepencil", "DATA_PT_preview",
    # Only the light type; DATA_PT_EEVEE_light below shows it with everything else.
    "DATA_PT_light",
)
# EEVEE-only panels whose content is engine-neutral: the material and world node trees, the
# material slots and the light settings. Cycles draws its own copies of these.
_COMPAT_EXTRA = (
    "EEVEE_MATERIAL_PT_context_material",
    "EEVEE_MATERIAL_PT_surface",
    "EEVEE_WORLD_PT_surface",
    "DATA_PT_EEVEE_light",
)

# Panels this add-on added itself to, so unregister removes exactly those.
_compat_added = []


def compatible_panels():
    """Blender's built-in panels that should show for Sampling Lab.

    Returns
    -------
    list of type
        ``bpy.types.Panel`` subclasses from ``bl_ui`` that are drawn for any engine (their
        ``COMPAT_ENGINES`` list ``'BLENDER_RENDER'``) in the render, output, view layer,
        object data, object, world and material contexts, plus a few engine-neutral EEVEE
        panels (material slots and surface, world surface, light settings).
    """
    panels = []
    for name in dir(bpy.types):
        cls = getattr(bpy.types, name, None)
        if not (isinstance(cls, type) and issubclass(cls, Panel)):
            continue
        engines = getattr(cls, "COMPAT_ENGINES", None)
        if engines is None or not cls.__module__.startswith("bl_ui"):
            continue
        if name in _COMPAT_EXTRA:
            panels.append(cls)
        elif (_COMPAT_MARKER in engines
              and getattr(cls, "bl_context", "") in _COMPAT_CONTEXTS
              and not name.startswith(_COMPAT_EXCLUDE_PREFIXES)):
            panels.append(cls)
    return panels


def register_compat_panels():
    for cls in compatible_panels():
        if ENGINE_ID not in cls.COMPAT_ENGINES:
            cls.COMPAT_ENGINES.add(ENGINE_ID)
            _compat_added.append(cls)


def unregister_compat_panels():
    for cls in _compat_added:
        cls.COMPAT_ENGINES.discard(ENGINE_ID)
    _compat_added.clear()


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    register_compat_panels()


def unregister():
    unregister_compat_panels()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
