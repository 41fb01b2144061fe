"""Rendered shading in the 3D viewport: progressive renders on a worker thread.

Blender calls the engine's ``view_update`` when the depsgraph changed and ``view_draw`` whenever
the region redraws, both on the main thread. A :class:`ViewportSession` per engine instance
keeps the exported scene and a :class:`ProgressiveRender`, whose worker thread runs
:func:`core.render.render` and publishes a :class:`Frame` after every pass:

1. ``view_update`` asks :func:`needs_restart` whether the depsgraph's updates change the image
   (geometry, transforms, materials, lights, world, visibility) and compares the engine settings
   (:func:`settings_key`); only then is the scene exported again (on the main thread: ``bpy``
   data is not thread-safe).
2. ``view_draw`` turns the region's view into a core camera (:func:`view_camera`); a new view
   restarts the render with the same exported scene and the new camera.
3. A restart sets the running render's cancel flag and returns at once: the new worker waits for
   the old one, which stops after the work units in flight (``core.render`` polls the flag
   between units of a quarter of the integrator's ``unit_paths``: ``core.progressive.unit_paths``),
   so the UI never waits for a render.
4. Every render starts with coarse previews of one sample per pixel, a film pixel covering
   ``2^k`` region pixels (as Cycles' viewport does), then renders the full film progressively up
   to the Viewport Samples limit (0: until the view changes). A main-thread timer redraws the
   rendered viewports when a new frame is published; ``view_draw`` uploads it as an RGBA float
   texture and draws it through Blender's display transform (``gpu`` is imported there only: it
   does not exist in background mode).

The render settings are the final render's (integrator, sampler, bounces, MIS, seed, filter,
threads), but the units always run on threads (no worker processes: see ``core.workers``); the sample count is Viewport Samples and the final render's time limit does not apply.
"""

from __future__ import annotations

import dataclasses
import math
import traceback
import weakref

import bpy
import numpy as np

from ..core.progressive import (  # noqa: F401  (the viewport's worker, re-exported)
    START_RESOLUTION, Frame, ProgressiveRender, progressive_stages, texture_pixels)
from ..core.scene import Camera
from ..core.view_camera import camera_from_matrices, camera_view_camera

# Seconds between the redraw timer's looks at the running renders.
REDRAW_INTERVAL = 0.05
# Seconds unregistering the add-on waits for each worker thread.
STOP_TIMEOUT = 2.0

# Data-blocks whose updates can change the rendered image; a Scene update alone (selection,
# active object, color management, frame change without animation) cannot: the settings that
# matter are compared by settings_key.
RESTART_TYPES = tuple(
    getattr(bpy.types, name) for name in (
        "Object", "Mesh", "Curve", "Curves", "PointCloud", "Volume", "MetaBall", "Material",
        "Light", "World", "Camera", "Collection", "Image", "Texture", "NodeTree")
    if hasattr(bpy.types, name))


# --------------------------------------------------------------------------- restart rules


def update_restarts(update):
    """Whether one ``bpy.types.DepsgraphUpdate`` can change the rendered image.

    A geometry, transform or shading update of a render-relevant data-block (objects, their
    data, materials and node trees, lights, the world, cameras, collections (visibility),
    images, textures) does; an update with none of the three flags (selection) or of another
    data-block (the scene itself, screens, brushes) does not.
    """
    if not isinstance(update.id, RESTART_TYPES):
        return False
    return bool(update.is_updated_geometry or update.is_updated_transform
                or update.is_updated_shading)


def needs_restart(updates):
    """Whether any of ``depsgraph.updates`` restarts the render (:func:`update_restarts`)."""
    return any(update_restarts(u) for u in updates)


def viewport_settings(scene):
    """``core.render.RenderSettings`` of the viewport: the final render's, with Viewport Samples.

    Viewport Samples 0 renders until the view or the scene changes (no sample count, an
    infinite time limit); the final render's time limit does not apply to the viewport.
    """
    from .engine import render_settings

    props = scene.sampling_lab
    samples = int(props.viewport_samples)
    # Threads: the viewport re-renders on every change and needs no worker start-up or
    # shipping of the scene (Render > Performance > Workers is for final renders).
    return dataclasses.replace(render_settings(props), spp=samples,
                               time_limit=0.0 if samples > 0 else math.inf, workers="threads")


def settings_key(scene):
    """What, besides the depsgraph updates, restarts the render when it changes: the viewport
    render settings, the scene's world and camera, and the viewport pixel size."""
    return (dataclasses.astuple(viewport_settings(scene)),
            scene.world.as_pointer() if scene.world else 0,
            scene.camera.as_pointer() if scene.camera else 0,
            scene.render.preview_pixel_size, scene.render.film_transparent)


def pixel_size(scene, preferences=None):
    """Region pixels per film pixel at full resolution: Render > Performance > Viewport >
    Pixel Size (Automatic follows the interface's pixel size, 2 on high-DPI screens)."""
    value = scene.render.preview_pixel_size
    if value == 'AUTO':
        preferences = preferences or bpy.context.preferences
        return max(1, int(round(preferences.system.pixel_size)))
    return int(value)


# --------------------------------------------------------------------------- the view


@dataclasses.dataclass(frozen=True)
class View:
    """What a 3D viewport region shows, in plain numbers (hashable: a change restarts).

    Attributes
    ----------
    perspective : str
        ``RegionView3D.view_perspective``: ``'PERSP'``, ``'ORTHO'`` or ``'CAMERA'``.
    view_matrix, window_matrix : tuple of 16 float
        World to view and projection, row-major.
    width, height : int
        Region size in pixels.
    camera_zoom : float
    camera_offset : (float, float)
    clip : (float, float) or None
        Clipping distances of a free view (None: read from the window matrix).
    """

    perspective: str
    view_matrix: tuple
    window_matrix: tuple
    width: int
    height: int
    camera_zoom: float = 0.0
    camera_offset: tuple = (0.0, 0.0)
    clip: tuple = None

    @classmethod
    def from_region(cls, region_data, width, height, space=None):
        """The view of a ``bpy.types.RegionView3D`` drawn in a region of ``width x height``.

        ``space`` (``bpy.types.SpaceView3D``) gives the clipping distances of free views as
        Blender sets them: ``clip_start`` to ``clip_end`` in perspective, ``-clip_end / 2`` to
        ``clip_end / 2`` in orthographic views.
        """
        perspective = region_data.view_perspective
        clip = None
        if space is not None and perspective == 'PERSP':
            clip = (float(space.clip_start), float(space.clip_end))
        elif space is not None and perspective == 'ORTHO':
            clip = (-0.5 * float(space.clip_end), 0.5 * float(space.clip_end))
        return cls(
            perspective=perspective,
            view_matrix=tuple(np.array(region_data.view_matrix, np.float64).ravel()),
            window_matrix=tuple(np.array(region_data.window_matrix, np.float64).ravel()),
            width=int(width), height=int(height),
            camera_zoom=float(region_data.view_camera_zoom),
            camera_offset=tuple(float(v) for v in region_data.view_camera_offset), clip=clip)


def view_camera(view: View, render_camera=None):
    """The core camera of a viewport region (full resolution, one film pixel per region pixel).

    Parameters
    ----------
    view : View
    render_camera : core.scene.Camera or None
        The final render's camera of the viewed camera object; required in camera view.

    Returns
    -------
    core.scene.Camera
        In camera view, the render camera widened to the region by the zoom and offset
        (:func:`core.view_camera.camera_view_camera`); otherwise the camera of the region's view
        and window matrices (:func:`core.view_camera.camera_from_matrices`).
    """
    if view.perspective == 'CAMERA':
        if render_camera is None:
            raise ValueError("camera view needs the scene camera")
        return camera_view_camera(render_camera, view.width, view.height, view.camera_zoom,
                                  view.camera_offset)
    return camera_from_matrices(np.reshape(view.view_matrix, (4, 4)),
                                np.reshape(view.window_matrix, (4, 4)), view.width, view.height,
                                view.clip)


# --------------------------------------------------------------------------- the session


class ViewportSession:
    """One engine instance's viewport: exported scene, view and progressive render."""

    def __init__(self):
        self.renderer = ProgressiveRender()
        self.scene = None          # core.scene.Scene as exported (camera: the render camera)
        self.scene_has_camera = False
        self.settings = None
        self.key = None            # settings_key of the export
        self.view = None           # View of the running render
        self.pixel_size = 1
        self.dirty = True          # the export changed since the render started
        self.error = ""
        self.texture = None        # (frame serial, pixel size, GPUTexture) drawn last
        _SESSIONS.add(self)

    def sync(self, depsgraph, updates=None, camera_object=None):
        """Export the scene again if the depsgraph's updates or the settings ask for it.

        Parameters
        ----------
        depsgraph : bpy.types.Depsgraph
        updates : iterable of bpy.types.DepsgraphUpdate or None
            ``depsgraph.updates`` (None: export unconditionally).
        camera_object : bpy.types.Object or None
            Camera of the camera view (the viewport's local camera or the scene camera).

        Returns
        -------
        bool
            Whether the render must restart.
        """
        scene = depsgraph.scene
        key = settings_key(scene)
        restart = (self.scene is None or updates is None or key != self.key
                   or needs_restart(updates))
        if not restart:
            return False
        from . import export
        from .engine import missing_modules

        self.error = ""
        missing = missing_modules()
        if missing:
            self.error = (f"needs the Python module(s) {', '.join(missing)}: install the "
                          f"extension build that bundles them")
            self.scene = None
            self.renderer.cancel()
            return False
        camera_object = camera_object or scene.camera
        # A free view needs no camera object: it replaces the camera by the view's own (a
        # camera view of a scene without camera objects is reported by view_camera).
        placeholder = None if camera_object is not None else Camera(np.eye(4), 1, 1)
        try:
            self.scene = export.export_scene(depsgraph, camera_object, camera=placeholder)
            self.scene_has_camera = placeholder is None
        except export.ExportError as ex:
            self.error = str(ex).removeprefix("Sampling Lab: ")
            self.scene = None
            self.renderer.cancel()
            return False
        self.settings = viewport_settings(scene)
        self.pixel_size = pixel_size(scene)
        self.key = key
        self.dirty = True
        return True

    def ensure_view(self, view: View):
        """Start a render if the export or the view changed since the running one started.

        Returns
        -------
        bool
            Whether a render started.
        """
        if self.scene is None or (not self.dirty and view == self.view):
            return False
        try:
            camera = view_camera(view, self.scene.camera if self.scene_has_camera else None)
        except ValueError as ex:
            self.error = str(ex)
            self.renderer.cancel()
            return False
        self.view = view
        self.dirty = False
        self.error = ""
        self.renderer.start(dataclasses.replace(self.scene, camera=camera), self.settings,
                            progressive_stages(view.width, view.height, self.pixel_size,
                                               self.settings.spp))
        _ensure_redraw_timer()
        return True

    def frame_to_upload(self):
        """The latest frame if view_draw has not made a texture of it yet, else None."""
        frame = self.renderer.frame()
        if frame is None or (self.texture is not None and self.texture[0] == frame.serial):
            return None
        return frame

    def status(self):
        """The line shown in the viewport's corner."""
        if self.error or self.renderer.error:
            return f"Sampling Lab | Error: {self.error or self.renderer.error}"
        frame = self.renderer.frame()
        if frame is None:
            return "Sampling Lab | Rendering"
        total = self.settings.spp if self.settings is not None else 0
        if not frame.final:
            return f"Sampling Lab | Preview 1/{frame.pixel_size} resolution"
        done = "" if self.renderer.running else " | Done"
        return f"Sampling Lab | Sample {frame.spp}" + (f"/{total}" if total else "") + done

    def free(self, timeout=None):
        """Stop the render (wait at most ``timeout`` seconds; None: do not wait)."""
        _SESSIONS.discard(self)
        self.texture = None
        if timeout is None:
            self.renderer.cancel()
            return True
        return self.renderer.stop(timeout)


# Every live session, for the redraw timer and for unregister.
_SESSIONS = weakref.WeakSet()
_ATTR = "_sampling_lab_viewport"


def _redraw_timer():
    """Redraw the rendered 3D viewports when a worker published a frame (main thread)."""
    sessions = list(_SESSIONS)
    fresh = False
    for session in sessions:
        if session.renderer.new_frame.is_set():
            session.renderer.new_frame.clear()
            fresh = True
    if fresh:
        try:
            for window in bpy.context.window_manager.windows:
                for area in window.screen.areas:
                    if (area.type == 'VIEW_3D'
                            and area.spaces.active.shading.type == 'RENDERED'):
                        area.tag_redraw()
        except Exception:  # noqa: BLE001 - a redraw request must never raise in Blender
            traceback.print_exc()
    if any(s.renderer.running or s.renderer.new_frame.is_set() for s in sessions):
        return REDRAW_INTERVAL
    return None


def _ensure_redraw_timer():
    if not bpy.app.timers.is_registered(_redraw_timer):
        bpy.app.timers.register(_redraw_timer, first_interval=REDRAW_INTERVAL)


def _session(engine):
    session = getattr(engine, _ATTR, None)
    if session is None:
        session = ViewportSession()
        setattr(engine, _ATTR, session)
    return session


def _view_camera_object(context):
    space = context.space_data
    if space is not None and getattr(space, "use_local_camera", False) and space.camera:
        return space.camera
    return context.scene.camera


# --------------------------------------------------------------------------- engine entry points


def view_update(engine, context, depsgraph):
    """``RenderEngine.view_update``: export again if the updates change the image."""
    session = _session(engine)
    try:
        session.sync(depsgraph, depsgraph.updates if session.scene is not None else None,
                     _view_camera_object(context))
    except Exception as ex:  # noqa: BLE001 - nothing may take Blender down
        traceback.print_exc()
        session.error = f"{type(ex).__name__}: {ex}"
        session.scene = None
        session.renderer.cancel()


def view_draw(engine, context, depsgraph):
    """``RenderEngine.view_draw``: restart on a new view, draw the latest frame."""
    session = _session(engine)
    try:
        region = context.region
        view = View.from_region(context.region_data, region.width, region.height,
                                context.space_data)
        session.ensure_view(view)
        upload = session.frame_to_upload()
        if upload is not None or session.texture is not None:
            # Until the new render's first pass: the previous image, not an empty viewport.
            _draw(engine, depsgraph.scene, session, upload)
        engine.update_stats("", session.status())
    except Exception as ex:  # noqa: BLE001 - nothing may take Blender down
        traceback.print_exc()
        session.error = f"{type(ex).__name__}: {ex}"


def _draw(engine, scene, session, frame):
    import gpu
    from gpu_extras.presets import draw_texture_2d

    if frame is not None:
        height, width = frame.pixels.shape[:2]
        data = gpu.types.Buffer('FLOAT', width * height * 4, texture_pixels(frame))
        texture = gpu.types.GPUTexture((width, height), format='RGBA32F', data=data)
        session.texture = (frame.serial, frame.pixel_size, texture)
    _, size, texture = session.texture
    gpu.state.blend_set('ALPHA_PREMULT')
    engine.bind_display_space_shader(scene)
    draw_texture_2d(texture, (0, 0), texture.width * size, texture.height * size)
    engine.unbind_display_space_shader()
    gpu.state.blend_set('NONE')


def free(engine):
    """Stop ``engine``'s viewport render without waiting (the engine is being freed)."""
    try:
        session = getattr(engine, _ATTR, None)
    except Exception:  # noqa: BLE001 - the engine's data may already be gone
        return
    if session is not None:
        session.free()


def stop_all(timeout=STOP_TIMEOUT):
    """Stop every viewport render and wait for the worker threads (add-on unregister)."""
    for session in list(_SESSIONS):
        session.free(timeout)
    if bpy.app.timers.is_registered(_redraw_timer):
        bpy.app.timers.unregister(_redraw_timer)
