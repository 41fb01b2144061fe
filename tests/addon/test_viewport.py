"""Rendered viewport, everything that runs without a display (``addon/viewport.py``).

- Restart rules: real depsgraph updates (captured in a ``depsgraph_update_post`` handler) of
  edits that change the image restart the render; selection, the active object and color
  management do not; engine settings restart through ``settings_key``.
- View to camera: Blender's own projection (``Object.calc_matrix_camera``) with the camera's
  inverse matrix as the view gives the exporter's render camera; a real ``RegionView3D`` in
  camera view holds the render camera's rays inside the camera frame.
- Progressive film: the frame view_draw would upload after pass k is the film mean of a k-sample
  render, previews are reduced films, a restart clears the frame.
- Cancel: the worker polls the cancel flag between work units of bounded size and stops after
  the units in flight; a restart returns at once (the UI thread never joins a worker) and the
  new render waits for the old one's unit. The wall-clock latency is measured by
  ``tools/viewport_cancel.py``, not asserted here (a loaded CI machine would make it flaky).
"""

import dataclasses
import importlib
import math
import threading
from contextlib import contextmanager

import bpy
import numpy as np
import pytest

import scenes
from scenes import ADDON_MODULE

from sampling_lab.core import progressive
from sampling_lab.core.camera import generate_rays
from sampling_lab.core.integrators import integrator_class
from sampling_lab.core.passes import PASS_UNITS
from sampling_lab.core.view_camera import camera_frame, film_camera, zoom_factor


@pytest.fixture(scope="module")
def viewport(addon):
    return importlib.import_module(f"{ADDON_MODULE}.addon.viewport")


@pytest.fixture(scope="module")
def core_render(addon):
    # The add-on's own copy of core.render (Blender imports the extension under bl_ext).
    return importlib.import_module(f"{ADDON_MODULE}.core.render")


def pixel_centres(width, height):
    y, x = np.mgrid[0:height, 0:width]
    return np.c_[x.ravel() + 0.5, y.ravel() + 0.5].astype(np.float64)


def assert_same_rays(cam_a, xy_a, cam_b, xy_b, atol=2e-5):
    oa, da, ta = generate_rays(cam_a, xy_a)
    ob, db, tb = generate_rays(cam_b, xy_b)
    np.testing.assert_allclose(da, db, atol=atol)
    np.testing.assert_allclose(oa, ob, atol=atol * 10)
    np.testing.assert_allclose(ta, tb, rtol=1e-5)


def region_3d():
    """A real ``RegionView3D`` (the startup file's screens exist in background mode too)."""
    for screen in bpy.data.screens:
        for area in screen.areas:
            if area.type == 'VIEW_3D':
                return area.spaces.active.region_3d
    raise AssertionError("no 3D viewport in the startup screens")


# --------------------------------------------------------------------------- restart rules


@contextmanager
def captured_restarts(viewport):
    """Decisions of ``needs_restart`` on every depsgraph update while the block runs."""
    decisions = []

    def handler(scene, depsgraph):
        decisions.append(viewport.needs_restart(depsgraph.updates))

    bpy.app.handlers.depsgraph_update_post.append(handler)
    try:
        yield decisions
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(handler)


def _move(objs):
    objs["box"].location.x += 0.1


def _edit_mesh(objs):
    mesh = objs["box"].data
    mesh.vertices[0].co.z += 0.05
    mesh.update()


def _material(objs):
    objs["box"].active_material.diffuse_color = (1.0, 0.0, 0.0, 1.0)


def _material_node(objs):
    tree = objs["box"].active_material.node_tree
    node = next(n for n in tree.nodes if n.type == 'BSDF_DIFFUSE')
    node.inputs["Color"].default_value = (0.1, 0.9, 0.1, 1.0)


def _light(objs):
    objs["light"].data.energy *= 2.0


def _world(objs):
    bpy.context.scene.world.color = (0.3, 0.3, 0.3)


def _hide(objs):
    objs["box"].hide_viewport = True


def _camera_lens(objs):
    bpy.context.scene.camera.data.lens = 70.0


def _select(objs):
    objs["box"].select_set(not objs["box"].select_get())


def _active(objs):
    bpy.context.view_layer.objects.active = objs["light"]


def _exposure(objs):
    bpy.context.scene.view_settings.exposure = 1.5


RESTARTS = {"move": _move, "edit mesh": _edit_mesh, "material": _material,
            "material node": _material_node, "light": _light, "world": _world,
            "hide object": _hide, "camera lens": _camera_lens}
KEEPS = {"select": _select, "active object": _active, "color management": _exposure}


def restart_scene(scene):
    """A diffuse box (node material) lit by a point light, a camera, a world."""
    scenes.set_world(scene, (0.05, 0.05, 0.05))
    box = scenes.add_block(scene, "Box", (0.0, 0.0, 0.5), (1.0, 1.0, 1.0),
                           material=scenes.diffuse_material("Grey", (0.5, 0.5, 0.5)))
    light = scenes.add_light(scene, 'POINT', "Lamp", (2.0, -2.0, 3.0), energy=100.0)
    scenes.add_camera(scene, (0.0, -6.0, 2.0), (math.radians(75), 0.0, 0.0))
    bpy.context.view_layer.update()
    return {"box": box, "light": light}


@pytest.mark.parametrize("name", list(RESTARTS) + list(KEEPS))
def test_depsgraph_updates_restart_only_when_the_image_changes(empty_scene, viewport, name):
    objs = restart_scene(empty_scene)
    edit = {**RESTARTS, **KEEPS}[name]
    with captured_restarts(viewport) as decisions:
        edit(objs)
        bpy.context.view_layer.update()
    if name in RESTARTS:
        assert decisions and any(decisions), f"{name}: no update restarted ({decisions})"
    else:
        assert not any(decisions), f"{name}: restarted ({decisions})"


def test_settings_restart_through_their_key(empty_scene, viewport):
    restart_scene(empty_scene)
    props = empty_scene.sampling_lab
    key = viewport.settings_key(empty_scene)
    # Final-render-only settings and color management leave the viewport alone ...
    props.samples += 7
    props.time_limit = 3.0
    empty_scene.view_settings.exposure = 2.0
    assert viewport.settings_key(empty_scene) == key
    # ... engine settings the viewport renders with do not.
    for name, value in (("viewport_samples", 3), ("max_bounces", 2), ("seed", 5),
                        ("integrator", 'BDPT'), ("filter_width", 2.5)):
        before = getattr(props, name)
        setattr(props, name, value)
        assert viewport.settings_key(empty_scene) != key, name
        setattr(props, name, before)
        assert viewport.settings_key(empty_scene) == key, name
    empty_scene.world = bpy.data.worlds.new("Other")
    assert viewport.settings_key(empty_scene) != key


def test_session_exports_again_only_when_asked(empty_scene, viewport):
    restart_scene(empty_scene)
    session = viewport.ViewportSession()
    try:
        depsgraph = bpy.context.evaluated_depsgraph_get()
        assert session.sync(depsgraph) is True and session.scene is not None
        first = session.scene
        assert session.sync(depsgraph, updates=[]) is False and session.scene is first
        empty_scene.sampling_lab.max_bounces = 3
        assert session.sync(depsgraph, updates=[]) is True and session.scene is not first
        assert session.settings.max_bounces == 3
    finally:
        session.free()


def test_viewport_settings_are_the_render_settings_with_viewport_samples(empty_scene, viewport):
    restart_scene(empty_scene)
    props = empty_scene.sampling_lab
    props.samples, props.time_limit, props.viewport_samples = 64, 2.0, 12
    settings = viewport.viewport_settings(empty_scene)
    assert (settings.spp, settings.time_limit) == (12, 0.0)
    props.viewport_samples = 0
    settings = viewport.viewport_settings(empty_scene)
    assert settings.spp == 0 and settings.time_limit == math.inf
    assert settings.max_bounces == props.max_bounces and settings.seed == props.seed


def test_viewport_samples_setting(empty_scene):
    props = empty_scene.sampling_lab
    rna = props.bl_rna.properties["viewport_samples"]
    assert (rna.default, rna.hard_min) == (1024, 0)
    props.viewport_samples = 0
    assert props.viewport_samples == 0


def test_session_restarts_on_a_new_view_and_renders_viewport_samples(empty_scene, viewport):
    restart_scene(empty_scene)
    empty_scene.sampling_lab.viewport_samples = 2
    empty_scene.sampling_lab.max_bounces = 1
    session = viewport.ViewportSession()
    try:
        session.sync(bpy.context.evaluated_depsgraph_get())
        rv3d = region_3d()
        rv3d.view_perspective = 'CAMERA'
        rv3d.view_camera_zoom = 0.0
        rv3d.view_camera_offset = (0.0, 0.0)
        view = viewport.View.from_region(rv3d, 40, 30)
        assert session.ensure_view(view) is True
        assert session.ensure_view(view) is False
        rv3d.view_camera_zoom = 10.0
        moved = viewport.View.from_region(rv3d, 40, 30)
        assert moved != view and session.ensure_view(moved) is True
        assert session.renderer.wait(timeout=60)
        frame = session.renderer.frame()
        assert frame.final and frame.spp == 2 and frame.pixels.shape == (30, 40, 4)
        assert session.status() == "Sampling Lab | Sample 2/2 | Done"
        # view_draw uploads a frame once (what _draw records after making the texture).
        assert session.frame_to_upload() is frame
        session.texture = (frame.serial, frame.pixel_size, "texture")
        assert session.frame_to_upload() is None
    finally:
        session.free(timeout=60)


def test_free_view_renders_a_scene_without_a_camera_and_camera_view_reports_it(empty_scene,
                                                                               viewport):
    # The final render needs a camera object; the viewport's free view brings its own.
    scenes.add_light(empty_scene, 'POINT', "Lamp", (0.0, 0.0, 2.0))
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    empty_scene.sampling_lab.viewport_samples = 1
    session = viewport.ViewportSession()
    try:
        assert session.sync(bpy.context.evaluated_depsgraph_get()) is True
        rv3d = region_3d()
        rv3d.view_perspective = 'PERSP'
        assert session.ensure_view(viewport.View.from_region(rv3d, 16, 12)) is True
        assert session.renderer.wait(timeout=60)
        frame = session.renderer.frame()
        assert session.renderer.error == "" and frame.final and frame.pixels.shape == (12, 16, 4)
        rv3d.view_perspective = 'CAMERA'
        assert session.ensure_view(viewport.View.from_region(rv3d, 16, 12)) is False
        assert "camera" in session.status()
    finally:
        session.free(timeout=60)


# --------------------------------------------------------------------------- view to camera


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
@pytest.mark.parametrize("fit,resolution", [("AUTO", (48, 32)), ("VERTICAL", (40, 44)),
                                            ("HORIZONTAL", (30, 50))])
def test_free_view_of_blenders_camera_projection_is_the_render_camera(
        empty_scene, export, viewport, kind, fit, resolution):
    scenes.cornell_box_mesh_light(empty_scene, resolution=resolution)
    cam = empty_scene.camera
    cam.data.type = kind
    cam.data.sensor_fit = fit
    cam.data.shift_x, cam.data.shift_y = 0.12, -0.07
    cam.data.ortho_scale = 3.0
    depsgraph = bpy.context.evaluated_depsgraph_get()
    render_camera = export.export_scene(depsgraph).camera
    evaluated = cam.evaluated_get(depsgraph)
    window = evaluated.calc_matrix_camera(depsgraph, x=resolution[0], y=resolution[1])
    view = viewport.View(kind, tuple(np.array(evaluated.matrix_world.inverted()).ravel()),
                         tuple(np.array(window).ravel()), *resolution,
                         clip=(cam.data.clip_start, cam.data.clip_end))
    camera = viewport.view_camera(view)
    assert camera.type == kind
    xy = pixel_centres(*resolution)
    assert_same_rays(camera, xy, render_camera, xy)
    # Without the clipping distances, the far one comes from the float32 matrix.
    unclipped = viewport.view_camera(dataclasses.replace(view, clip=None))
    assert unclipped.clip_end == pytest.approx(render_camera.clip_end, rel=2e-3)
    assert unclipped.clip_start == pytest.approx(render_camera.clip_start, rel=2e-3)


@pytest.mark.parametrize("zoom,offset", [(0.0, (0.0, 0.0)), (12.0, (0.04, -0.03))])
@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_camera_view_holds_the_render_camera_inside_the_frame(empty_scene, export, viewport,
                                                              zoom, offset, kind):
    scenes.cornell_box_mesh_light(empty_scene, resolution=(40, 30))
    empty_scene.camera.data.type = kind
    empty_scene.camera.data.shift_x = 0.1
    render_camera = export.export_scene(bpy.context.evaluated_depsgraph_get()).camera
    rv3d = region_3d()
    rv3d.view_perspective = 'CAMERA'
    rv3d.view_camera_zoom = zoom
    rv3d.view_camera_offset = offset
    # A region twice the render's size: the frame is zoom_factor of it, moved by the offset.
    view = viewport.View.from_region(rv3d, 80, 60)
    assert (view.perspective, view.camera_zoom) == ('CAMERA', pytest.approx(zoom))
    camera = viewport.view_camera(view, render_camera)
    fac = zoom_factor(zoom)
    x0 = 80 * (0.5 - 2 * fac * offset[0] - fac / 2)
    y0 = 60 * (0.5 - 2 * fac * offset[1] - fac / 2)
    np.testing.assert_allclose(camera_frame(render_camera, 80, 60, zoom, offset),
                               (x0, x0 + 80 * fac, y0, y0 + 60 * fac), atol=1e-4)
    xy = pixel_centres(40, 30)
    region_xy = np.c_[x0 + xy[:, 0] * 2 * fac, y0 + xy[:, 1] * 2 * fac]
    assert_same_rays(camera, region_xy, render_camera, xy)


def test_progressive_stages_start_coarse_and_end_on_the_full_film(viewport):
    stages = viewport.progressive_stages(1000, 600, pixel_size=1, samples=32)
    assert stages[-1] == (1, 32)
    divisors = [d for d, _ in stages]
    assert divisors == sorted(divisors, reverse=True) and divisors[:-1] == [16, 8, 4, 2]
    assert all(spp == 1 for _, spp in stages[:-1])
    assert -(-1000 // divisors[0]) <= viewport.START_RESOLUTION
    # Previews together cost at most a third of one full-film sample.
    assert sum((1000 / d) * (600 / d) for d in divisors[:-1]) <= 1000 * 600 / 3
    assert viewport.progressive_stages(50, 40, pixel_size=2, samples=0) == [(2, 0)]


# --------------------------------------------------------------------------- progressive film


def film_scene(export, scene, width, height, max_bounces=1):
    scenes.cornell_box_mesh_light(scene, resolution=(width, height))
    scenes.set_sampling_lab(scene, samples=4, max_bounces=max_bounces)
    scene.render.threads_mode = 'FIXED'
    scene.render.threads = 2
    return export.export_scene(bpy.context.evaluated_depsgraph_get())


class Recorder:
    """Frames the worker published, in order (``notify`` runs on the worker thread)."""

    def __init__(self):
        self.frames = []
        self.renderer = None

    def __call__(self):
        frame = self.renderer.frame()
        if frame is not None and (not self.frames or frame is not self.frames[-1]):
            self.frames.append(frame)


def one_spp_pass_size(core_render, settings):
    """A film size whose passes take one sample per pixel (see core.passes.Passes)."""
    unit = progressive.unit_paths(settings)
    n = unit * PASS_UNITS // 2 + 1
    width = 4 * int(math.ceil(math.sqrt(n / 12)))
    return width, int(math.ceil(n / width))


def test_each_pass_draws_the_film_mean_of_that_many_samples(empty_scene, export, viewport,
                                                           core_render):
    settings = viewport.viewport_settings(empty_scene)
    width, height = one_spp_pass_size(core_render, settings)
    sl_scene = film_scene(export, empty_scene, width, height)
    recorder = Recorder()
    renderer = viewport.ProgressiveRender(notify=recorder)
    recorder.renderer = renderer
    renderer.start(sl_scene, settings, [(4, 1), (1, 3)])
    assert renderer.wait(timeout=120)
    assert not renderer.error
    frames = recorder.frames
    preview, passes = frames[0], frames[1:]
    assert not preview.final and preview.pixel_size == 4
    assert preview.pixels.shape == (-(-height // 4), -(-width // 4), 4)
    assert [f.spp for f in passes] == [1, 2, 3] and all(f.final for f in passes)
    assert [f.serial for f in frames] == [1, 2, 3, 4]
    for frame in (preview, passes[0], passes[2]):
        camera = film_camera(sl_scene.camera, frame.pixel_size)
        reference = core_render.render(
            dataclasses.replace(sl_scene, camera=camera),
            dataclasses.replace(settings, spp=frame.spp, time_limit=0.0),
            unit_paths=progressive.unit_paths(settings))
        data = viewport.texture_pixels(frame)
        assert data.dtype == np.float32 and data.flags.c_contiguous
        assert data.shape == (camera.width * camera.height * 4,)
        np.testing.assert_array_equal(data, reference.combined().reshape(-1))
    assert renderer.stats["stage"] == 1 and not renderer.stats["cancelled"]


def test_restart_clears_the_film(empty_scene, export, viewport):
    sl_scene = film_scene(export, empty_scene, 64, 48)
    settings = dataclasses.replace(viewport.viewport_settings(empty_scene), spp=0)
    recorder = Recorder()
    renderer = viewport.ProgressiveRender(notify=recorder)
    recorder.renderer = renderer
    try:
        first = renderer.start(sl_scene, settings, [(1, 0)])
        while not recorder.frames and renderer.running:
            renderer.new_frame.wait(0.05)
        assert recorder.frames and recorder.frames[0].generation == first
        moved = dataclasses.replace(sl_scene, camera=film_camera(sl_scene.camera, 2))
        second = renderer.start(moved, settings, [(1, 2)])
        assert renderer.frame() is None
        count = len(recorder.frames)
        assert renderer.wait(timeout=120)
        new = recorder.frames[count:]
        assert new and all(f.generation == second for f in new)
        assert new[-1].pixels.shape == (24, 32, 4) and new[-1].spp == 2
        assert renderer.frame() is new[-1]
    finally:
        renderer.stop(timeout=120)


def test_render_error_is_reported_not_raised(empty_scene, export, viewport):
    sl_scene = film_scene(export, empty_scene, 16, 16)
    settings = dataclasses.replace(viewport.viewport_settings(empty_scene),
                                   integrator="no_such_integrator")
    renderer = viewport.ProgressiveRender()
    renderer.start(sl_scene, settings, [(1, 1)])
    assert renderer.wait(timeout=60)
    assert "no_such_integrator" in renderer.error and renderer.frame() is None


# --------------------------------------------------------------------------- cancel


def test_worker_polls_cancel_between_bounded_units_and_stops_after_those_in_flight(
        empty_scene, export, viewport, core_render):
    sl_scene = film_scene(export, empty_scene, 128, 128)
    settings = dataclasses.replace(viewport.viewport_settings(empty_scene), spp=0)
    cancel_at = 3

    class CancelAtThirdPoll(viewport.ProgressiveRender):
        polls = 0

        def _poll(self, job):
            CancelAtThirdPoll.polls += 1
            if CancelAtThirdPoll.polls == cancel_at:
                job.cancel.set()
            return super()._poll(job)

    recorder = Recorder()
    renderer = CancelAtThirdPoll(notify=recorder)
    recorder.renderer = renderer
    # Unlimited samples and a second stage: only cancel can end this render.
    renderer.start(sl_scene, settings, [(1, 0), (1, 0)])
    assert renderer.wait(timeout=120), "the worker did not stop"
    stats = renderer.stats
    assert stats["cancelled"] and stats["stage"] == 0
    # core.render polls after every unit and finishes at most threads - 1 units in flight; a
    # unit holds at most the viewport's share of the path tracer's unit_paths paths (rounded up
    # to whole pixels of one pass).
    unit = progressive.unit_paths(settings)
    assert unit == integrator_class("path").unit_paths // 4
    spp_per_pass = max(1, min(unit * PASS_UNITS // (128 * 128), 64))
    # (core.render reads the flag once more to tell a cancel from a time limit.)
    assert cancel_at <= CancelAtThirdPoll.polls <= cancel_at + 1
    assert 0 < stats["samples"] <= (cancel_at + stats["threads"] - 1) * (unit + spp_per_pass)
    # Less than one pass was done, and a cut-short pass is never shown.
    assert stats["samples"] < 128 * 128 * spp_per_pass and recorder.frames == []


def test_restart_returns_at_once_and_the_new_render_waits_for_the_old_unit(
        empty_scene, export, viewport):
    """The UI thread never waits for a render: a restart only sets the old render's flag."""
    sl_scene = film_scene(export, empty_scene, 32, 24)
    settings = dataclasses.replace(viewport.viewport_settings(empty_scene), spp=0)
    in_unit, release = threading.Event(), threading.Event()
    polls = []

    class EndlessFirstUnit(viewport.ProgressiveRender):
        def _poll(self, job):
            polls.append(job.generation)
            if job.generation == 1 and not release.is_set():
                # The first render's first poll comes after a unit that "lasts" until released.
                in_unit.set()
                release.wait(60)
            return super()._poll(job)

    recorder = Recorder()
    renderer = EndlessFirstUnit(notify=recorder)
    recorder.renderer = renderer
    try:
        renderer.start(sl_scene, settings, [(1, 0)])
        assert in_unit.wait(60)
        second = renderer.start(sl_scene, settings, [(1, 1)])
        # start() returned while the old worker is still inside its unit, and the new worker
        # has not started rendering beside it.
        assert renderer.running and polls == [1] and renderer.frame() is None
        release.set()
        assert renderer.wait(timeout=60)
        # The old render stopped at the poll after its unit; the new one then rendered.
        assert polls.count(1) <= 2 and polls[-1] == second
        assert recorder.frames and all(f.generation == second for f in recorder.frames)
    finally:
        release.set()
        renderer.stop(timeout=60)


def test_engine_delegates_to_the_viewport_and_unregister_stops_its_renders(
        empty_scene, export, viewport, addon):
    engine = importlib.import_module(f"{ADDON_MODULE}.addon.engine")
    cls = engine.SAMPLINGLAB_RenderEngine
    for method, target in (("view_update", "view_update"), ("view_draw", "view_draw"),
                           ("__del__", "free")):
        names = getattr(cls, method).__code__.co_names
        assert "viewport" in names and target in names, method
    sl_scene = film_scene(export, empty_scene, 32, 24)
    session = viewport.ViewportSession()
    session.renderer.start(sl_scene, dataclasses.replace(
        viewport.viewport_settings(empty_scene), spp=0), [(1, 0)])
    assert session.renderer.running
    viewport.stop_all()
    assert not session.renderer.running and session.renderer.stats["cancelled"]
