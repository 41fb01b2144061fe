"""Final renders in Blender run their work units in worker processes (core.workers): the
children import the extension under Blender's package name (``bl_ext.<repo>.sampling_lab``,
whose parents exist only in Blender) and render the threads image bit for bit."""

import importlib

import numpy as np
import pytest

import scenes
from scenes import ADDON_MODULE


@pytest.mark.parametrize("integrator", ['PATH', 'BDPT'])
def test_blender_renders_with_worker_processes_the_threads_image(empty_scene, tmp_path, capfd,
                                                                 integrator):
    workers = importlib.import_module(f"{ADDON_MODULE}.core.workers")
    assert workers.package_name() == ADDON_MODULE
    scenes.cornell_box_mesh_light(empty_scene, resolution=(16, 12))
    scenes.set_sampling_lab(empty_scene, samples=3, seed=5)
    empty_scene.sampling_lab.integrator = integrator
    empty_scene.render.threads_mode, empty_scene.render.threads = 'FIXED', 2
    assert empty_scene.sampling_lab.workers == 'PROCESSES'  # the add-on's default
    capfd.readouterr()
    processes = scenes.render_to_exr(empty_scene, tmp_path / "processes.exr")
    assert "on 2 worker processes" in capfd.readouterr().out
    assert all(child.alive() for child in workers.pool().children)
    empty_scene.sampling_lab.workers = 'THREADS'
    threads = scenes.render_to_exr(empty_scene, tmp_path / "threads.exr")
    assert "on 2 threads" in capfd.readouterr().out
    assert processes.keys() == threads.keys()
    for name in processes:
        np.testing.assert_array_equal(processes[name], threads[name], err_msg=name)
    assert processes["Combined"][..., :3].mean() > 0


def test_worker_processes_send_back_the_classes_of_blenders_package(addon):
    core = {name: importlib.import_module(f"{ADDON_MODULE}.core.{name}")
            for name in ("workers", "render", "scenes")}
    scene = core["scenes"].cornell_box(8, 8)
    settings = core["render"].RenderSettings(spp=1, threads=2, workers="processes")
    units = core["workers"].ProcessUnits(2, scene, settings,
                                         core["render"].preparation_key(scene, settings),
                                         (0, 0, 8, 8), 8)
    try:
        sums, out, counters, taps = units.submit((0, 64, 0, 1)).result(timeout=120)
    finally:
        units.release()
    # Pickles name classes by module: the child imported the extension as Blender names it.
    assert type(out).__module__ == f"{ADDON_MODULE}.core.integrators.base"
    assert type(sums).__module__ == f"{ADDON_MODULE}.core.film"
    # One sample per pixel: the unit's 64 pixels' totals (their squares formed where added).
    assert sums.total.shape == (64, 3) and counters.camera_samples == 64


@pytest.mark.parametrize("integrator, threads, active", [
    ('PATH', 2, True), ('BDPT', 2, True), ('LIGHT', 2, True), ('SPPM', 2, False),
    ('RADIOSITY', 2, False), ('PATH', 1, False)])
def test_workers_is_greyed_out_where_a_render_would_use_threads(empty_scene, integrator,
                                                               threads, active):
    from panels import drawn_rows

    empty_scene.sampling_lab.integrator = integrator
    empty_scene.render.threads_mode, empty_scene.render.threads = 'FIXED', threads
    rows = drawn_rows("SAMPLINGLAB_RENDER_PT_performance", empty_scene)
    assert rows["workers"] is active
    # The core says the same: what the render uses, and what the add-on greys out.
    render = importlib.import_module(f"{ADDON_MODULE}.core.render")
    applied = importlib.import_module(f"{ADDON_MODULE}.core.applied_settings")
    settings = render.RenderSettings(integrator=integrator.lower(), threads=threads,
                                     workers="processes")
    assert (applied.used_settings(settings)["workers"] == "processes") is active
