"""The Sampling Lab render engine: export, render with core, write the passes back.

This is a thin adapter: :mod:`.export` turns the depsgraph into a :class:`core.scene.Scene`,
:func:`core.render.render` does all the work, and :mod:`.passes` copies its images into the
render result. Nothing raised here may escape into Blender: every error becomes an ``ERROR``
report (which also makes ``bpy.ops.render.render`` raise ``RuntimeError`` for scripts): a
refusal (:class:`core.errors.RenderRefused`, an export error) as one line naming the cause,
anything else as a failure with its traceback printed to the console.
"""

import importlib.util
import sys
import time
import traceback

import bpy

from . import passes

ENGINE_ID = 'SAMPLING_LAB'

# Python modules the core needs besides numpy (which Blender ships).
REQUIRED_MODULES = ("embreex",)

# Seconds between progressive refreshes of the image in Blender.
UPDATE_INTERVAL = 0.5


def missing_modules():
    """Names of :data:`REQUIRED_MODULES` that cannot be imported."""
    return [name for name in REQUIRED_MODULES if importlib.util.find_spec(name) is None]


def render_settings(props):
    """``core.render.RenderSettings`` from the scene's ``SamplingLabSettings``: every option of
    the registry (``core.options``) read through ``properties.core_values``."""
    from ..core.render import RenderSettings
    from .properties import core_values

    values = core_values(props)
    # Animate Seed, and Render > Performance > Threads: Blender resolves Auto to the core
    # count, as Cycles reads it.
    values.update(seed=frame_seed(props), threads=int(props.id_data.render.threads))
    return RenderSettings(**values)


def frame_seed(props):
    """The seed of the scene's current frame: Seed, plus the frame number when Animate Seed is
    on (as Cycles' ``use_animated_seed``), kept in ``[0, 2^31)``."""
    seed = int(props.seed)
    if props.use_animated_seed:
        seed = (seed + int(props.id_data.frame_current)) % (1 << 31)
    return seed


def used_text(stats):
    """The strategy settings a render used, as the stats line shows them (options that did
    not apply are left out: ``core.applied_settings.used_settings``)."""
    parts = []
    heuristic = stats.get("mis_heuristic", "n/a")
    if heuristic != "n/a":
        value = {"power": stats.get("mis_beta"), "cutoff": stats.get("mis_alpha")}.get(heuristic)
        parts.append(f"MIS {heuristic}" + (f" {value:g}" if isinstance(value, float) else ""))
    if stats.get("light_selection", "n/a") != "n/a":
        parts.append(f"lights {stats['light_selection']} by {stats.get('distribution')}, "
                     f"emitters by {stats.get('light_sampling')}")
    else:
        parts.append(f"no light sampling, mixtures by {stats.get('distribution')}")
    return ", ".join(parts)


def estimator_text(stats):
    """What a biased or estimated-normalisation estimator adds to the stats line: photon,
    radiosity and Metropolis figures (empty for the unbiased integrators, whose stats have
    none of them)."""
    if "photons_emitted" in stats:
        return (f", {stats.get('estimator_bias')}: {stats['photons_emitted'] / 1e6:.2f} M photons "
                f"({stats.get('photons_per_s', 0.0) / 1e6:.2f} M/s, peak "
                f"{stats.get('photon_memory_peak_mb', 0.0):.1f} MB)")
    if "mlt_b" in stats:
        rel = stats.get("mlt_b_rel_se")
        return (f", {stats.get('estimator_bias')}: b {stats['mlt_b']:.4g}"
                + (f" +- {rel:.1%}" if rel is not None else "")
                + f", acceptance {stats.get('mlt_acceptance', 0.0):.0%}")
    if "radiosity_patch_count" in stats:
        return (f", biased (radiosity): {stats['radiosity_patch_count']} patches, "
                f"{stats.get('radiosity_solver')} in {stats.get('radiosity_iterations')} "
                f"iterations (residual {stats.get('radiosity_residual', 0.0):.2g})")
    return ""


def film_window(render, width, height):
    """The window ``(x0, y0, x1, y1)`` of the frame whose memory a render takes, or None for
    the whole frame, before Blender allocates the result: the Render Region when it is cropped
    to; without Crop to Render Region Blender pastes the region into a full-frame image, so the
    whole frame's memory is needed. Blender truncates the region's corners to whole pixels."""
    if not (render.use_border and render.use_crop_to_border):
        return None
    x0, x1 = int(render.border_min_x * width), int(render.border_max_x * width)
    y0, y1 = int(render.border_min_y * height), int(render.border_max_y * height)
    return (x0, y0, x1, y1) if x1 > x0 and y1 > y0 else None


def render_region(render, width, height, result_width, result_height):
    """The window of the full frame that Blender's result covers (Render Region).

    Blender gives the engine a result of the region's size whether or not Crop to Render Region
    is on (without it, Blender itself places the region in a full-frame image afterwards).

    Parameters
    ----------
    render : bpy.types.RenderSettings
    width, height : int
        Full frame size.
    result_width, result_height : int
        Size of the result ``begin_result`` returned (Blender crops it to the region).

    Returns
    -------
    (x0, y0, x1, y1) or None
        Frame pixels ``x0 <= x < x1``, ``y0 <= y < y1`` (from the bottom), as
        ``core.render.RenderSettings.region``; ``None`` when the result is the whole frame.
    """
    if (result_width, result_height) == (width, height):
        return None
    # Blender truncates the region's corner to whole pixels.
    x0 = min(max(int(render.border_min_x * width), 0), width - result_width)
    y0 = min(max(int(render.border_min_y * height), 0), height - result_height)
    return x0, y0, x0 + result_width, y0 + result_height


class SAMPLINGLAB_RenderEngine(bpy.types.RenderEngine):
    """Sampling Lab: Monte Carlo estimators and samplers on NumPy + Embree."""

    bl_idname = ENGINE_ID
    bl_label = "Sampling Lab"
    bl_use_preview = False
    bl_use_postprocess = True
    # The viewport's Material Preview uses EEVEE; renders use Blender's own shader nodes.
    bl_use_eevee_viewport = True
    bl_use_shading_nodes_custom = False

    def cancel_requested(self):
        """True once the user cancelled the render (Esc); polled by the core between batches."""
        return self.test_break()

    def update_render_passes(self, scene=None, renderlayer=None):
        passes.register_passes(self, scene, renderlayer)

    def view_update(self, context, depsgraph):
        """Rendered viewport: export again when the depsgraph's updates change the image."""
        from . import viewport

        viewport.view_update(self, context, depsgraph)

    def view_draw(self, context, depsgraph):
        """Rendered viewport: restart on a new view, draw the latest progressive frame."""
        from . import viewport

        viewport.view_draw(self, context, depsgraph)

    def __del__(self):
        # Blender frees the engine when rendered shading ends: stop its viewport render.
        try:
            from . import viewport

            viewport.free(self)
        except Exception:  # noqa: BLE001 - also called while Python shuts down
            pass

    def render(self, depsgraph):
        try:
            self._render(depsgraph)
        except Exception as ex:  # noqa: BLE001 - nothing may take Blender down
            from ..core.errors import RenderRefused
            from .export import ExportError

            if isinstance(ex, ExportError):
                self.report({'ERROR'}, str(ex))
            elif isinstance(ex, MemoryError):
                self.report({'ERROR'}, "Sampling Lab: out of memory: lower the resolution or "
                                       "the photon count")
            elif isinstance(ex, RenderRefused):
                # The core refuses what it cannot render with a message for the user (as the
                # command line prints it): one line, no traceback.
                self.report({'ERROR'}, f"Sampling Lab: {ex}")
            else:  # a bug (a NumPy ValueError too): its traceback goes to the console
                traceback.print_exc()
                self.report({'ERROR'}, f"Sampling Lab: render failed: {type(ex).__name__}: {ex} "
                                       f"(traceback in the console)")

    def _render(self, depsgraph):
        from . import export

        missing = missing_modules()
        if missing:
            raise export.ExportError(
                f"Sampling Lab needs the Python module(s) {', '.join(missing)}, which are not "
                f"installed; install the extension build that bundles them, or pip install "
                f"{' '.join(missing)} into Blender's Python")
        from ..core.film import check_film_memory
        from ..core.render import preparation_key
        from ..core.render import render as core_render

        scene = depsgraph.scene
        self.update_stats("", "Sampling Lab | Exporting scene")
        t0 = time.perf_counter()
        sl_scene = export.export_scene(depsgraph, self.camera_override)
        export_s = time.perf_counter() - t0
        if self.test_break():  # Esc while exporting: nothing rendered, nothing to keep
            self.update_stats("", "Sampling Lab | cancelled while exporting")
            return
        for message in sl_scene.messages:
            self.report({'WARNING'}, f"Sampling Lab: {message}")
        reported = set(sl_scene.messages)

        width, height = sl_scene.camera.width, sl_scene.camera.height
        # Before Blender allocates the result: a huge image is refused, not half allocated.
        check_film_memory(width, height, film_window(scene.render, width, height))
        result = self.begin_result(0, 0, width, height, layer=depsgraph.view_layer.name)
        layer = result.layers[0]
        settings = render_settings(scene.sampling_lab)
        # Only the region's pixels are traced; the film is the region.
        settings.region = render_region(scene.render, width, height, result.resolution_x,
                                        result.resolution_y)
        last_update = [time.perf_counter()]

        def progress(fraction, text):
            self.update_progress(fraction)
            self.update_stats("", f"Sampling Lab | {text}")

        def on_update(partial):
            now = time.perf_counter()
            if now - last_update[0] < UPDATE_INTERVAL:
                return
            last_update[0] = now
            passes.write_passes(layer, passes.pass_images(partial))
            self.update_result(result)

        # Persistent Data: Blender keeps this engine between frames and renders; the prepared
        # scene (BVH, light tables) is kept with it and reused while only the camera changes.
        persistent = scene.render.use_persistent_data
        key = preparation_key(sl_scene, settings) if persistent else None
        kept = getattr(self, "_prepared", None) if persistent else None
        try:
            out = core_render(sl_scene, settings, progress=progress,
                              cancel=self.cancel_requested, on_update=on_update,
                              prepared=kept[1] if kept is not None and kept[0] == key else None)
            passes.write_passes(layer, passes.pass_images(out))
        finally:
            # A cancelled render keeps the samples it took.
            self.end_result(result)
        self._prepared = (key, out.prepared) if persistent else None

        if out.traceback:
            print(out.traceback, file=sys.stderr)
        for message in out.messages:
            if message not in reported:
                self.report({'WARNING'}, f"Sampling Lab: {message}")
        if out.error and out.stats.get("samples", 0):
            # A warning, not an error: Blender then still saves the samples taken (an error
            # report stops an animation or write_still from writing the frame).
            self.report({'WARNING'}, f"Sampling Lab: render failed part-way: {out.error}; "
                        f"the {out.stats['samples']:,} samples taken before it are kept")
        elif out.error:
            self.report({'ERROR'}, f"Sampling Lab: render failed: {out.error}")
        stats = out.stats
        region = settings.region
        # Which ran: "2 worker processes" or "2 threads" (core.render._worker_processes).
        workers = stats.get("workers_text") or f"{stats.get('threads', 1)} threads"
        summary = (f"frame {scene.frame_current}: {stats.get('spp', 0)} spp "
                   f"({stats.get('samples', 0)} samples"
                   + (f", region {region[2] - region[0]} x {region[3] - region[1]} of "
                      f"{width} x {height}" if region else "")
                   + f") in {stats.get('time_s', 0.0):.2f} s "
                   f"on {workers}"
                   + (f" ({stats['workers_note']})" if stats.get("workers_note") else "")
                   + " "
                   f"(export {export_s:.2f} s, "
                   + ("scene kept from the last render" if stats.get("prepared_reused") else
                      f"prepare {stats.get('prepare_s', 0.0):.2f} s")
                   + "), "
                   f"{stats.get('samples_per_s', 0.0) / 1e6:.2f} M samples/s, "
                   f"{stats.get('rays_per_s', 0.0) / 1e6:.2f} M rays/s, "
                   f"{used_text(stats)}, build "
                   f"{1e3 * stats.get('distribution_build_s', 0.0):.2f} ms, sampling "
                   f"{1e3 * stats.get('distribution_sample_s', 0.0):.1f} ms"
                   + estimator_text(stats)
                   + (", failed" if out.error else ", cancelled" if out.cancelled else ""))
        self.update_stats("", f"Sampling Lab | {summary}")
        self.report({'INFO'}, f"Sampling Lab: {summary}")


classes = (SAMPLINGLAB_RenderEngine,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    from . import viewport

    viewport.stop_all()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
