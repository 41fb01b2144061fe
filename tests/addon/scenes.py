"""Test scenes, render settings, and an EXR reader.

The scene builders and their building blocks live in ``sampling_lab.tools.bpy_scenes`` (the
benchmarks render the same scenes) and are re-exported here: every builder works on the given
(normally empty, see the ``empty_scene`` fixture) scene, adds a camera and sets it as the scene
camera, and returns a dict of the objects it made by role.
"""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np

from sampling_lab.tools.bpy_scenes import (  # noqa: F401  (re-exported for the tests)
    GREEN,
    RED,
    SKY_H,
    SKY_W,
    WHITE,
    add_block,
    add_camera,
    add_light,
    add_mesh,
    add_quad,
    add_uv_sphere,
    cornell_box,
    cornell_box_area_light,
    cornell_box_mesh_light,
    cornell_box_point_light,
    cornell_smooth_sphere,
    cornell_sphere,
    diffuse_material,
    emission_material,
    environment_scene,
    float_image,
    glass_material,
    glossy_material,
    glossy_plates,
    plane_under_sun,
    set_environment_world,
    set_resolution,
    set_world,
    shader_material,
    sky_pixels,
)

# Where the add-on comes from and what Blender calls it (see conftest.py).
REPO_ROOT = Path(__file__).resolve().parents[2]
EXTENSION_REPO = "sampling_lab_dev"
ADDON_MODULE = f"bl_ext.{EXTENSION_REPO}.sampling_lab"
ENGINE_ID = "SAMPLING_LAB"


def registered_engines():
    """``bl_idname`` of every registered RenderEngine subclass (at any depth)."""
    found, stack = set(), list(bpy.types.RenderEngine.__subclasses__())
    while stack:
        cls = stack.pop()
        stack.extend(cls.__subclasses__())
        if getattr(cls, "bl_idname", None):
            found.add(cls.bl_idname)
    return found


# --------------------------------------------------------------------------- render settings


def set_cycles_unbiased(scene, samples=64, seed=0, max_bounces=8):
    """Select Cycles with settings under which it is an unbiased path tracer.

    No clamping, no glossy blur, no light threshold, no adaptive sampling, no denoising, CPU,
    Blackman-Harris 1.5 pixel filter (Cycles' default), equal bounce limits for every ray type
    (the benchmark's :func:`sampling_lab.tools.blender_scene.configure_cycles`).
    """
    from sampling_lab.tools.blender_scene import configure_cycles

    scene.render.engine = 'CYCLES'
    configure_cycles(scene, samples, seed=seed, max_bounces=max_bounces)
    scene.render.film_transparent = False
    scene.render.use_motion_blur = False


def set_sampling_lab(scene, samples=4, seed=0, max_bounces=8, filter_type='BLACKMAN_HARRIS',
                     filter_width=1.5, time_limit=0.0):
    """Select Sampling Lab with the given settings (path tracing, independent sampler, every
    per-kind bounce limit equal to ``max_bounces`` as :func:`set_cycles_unbiased` sets
    Cycles')."""
    scene.render.engine = 'SAMPLING_LAB'
    s = scene.sampling_lab
    s.integrator = 'PATH'
    s.sampler = 'INDEPENDENT'
    s.samples = samples
    s.seed = seed
    s.max_bounces = max_bounces
    for name in ("diffuse_bounces", "glossy_bounces", "transmission_bounces",
                 "transparent_max_bounces"):
        setattr(s, name, max_bounces)
    s.filter_type = filter_type
    s.filter_width = filter_width
    s.time_limit = time_limit


# --------------------------------------------------------------------------- EXR output


def set_output_multilayer_exr(scene, path):
    """Make ``render(write_still=True)`` write a 32-bit multilayer EXR exactly at ``path``."""
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):  # Blender 5: multilayer is a media type
        settings.media_type = 'MULTI_LAYER_IMAGE'
    else:
        settings.file_format = 'OPEN_EXR_MULTILAYER'
    settings.color_depth = '32'
    settings.exr_codec = 'ZIP'
    scene.render.use_file_extension = False
    scene.render.filepath = str(path)


def read_blender_exr(path):
    """Passes of an EXR that Blender wrote: pass name -> (h, w, c) float32, row 0 at the bottom."""
    from sampling_lab.core.exr import read_multilayer

    return read_multilayer(path)


def render_to_exr(scene, path):
    """Render ``scene`` with its engine, write a multilayer EXR, and read it back.

    Returns
    -------
    dict of str -> (h, w, c) float32
        See :func:`read_blender_exr`.
    """
    set_output_multilayer_exr(scene, path)
    bpy.ops.render.render(write_still=True, scene=scene.name)
    return read_blender_exr(path)


def render_ours_and_cycles(scene, folder, our_spp, cycles_spp, cycles_runs, bounces, our_seed,
                           cycles_seed):
    """Render ``scene`` ``cycles_runs`` times with unbiased Cycles (seeds ``cycles_seed + run``)
    and once with Sampling Lab, both read back from the EXR files Blender writes in ``folder``.

    Returns
    -------
    ours : dict of str -> (h, w, c) float32
        Every pass of our render.
    cycles : (cycles_runs, h, w, 3) float32
        Cycles' Combined RGB of each run.
    """
    cycles = []
    for run in range(cycles_runs):
        set_cycles_unbiased(scene, samples=cycles_spp, seed=cycles_seed + run,
                            max_bounces=bounces)
        cycles.append(render_to_exr(scene, folder / f"cycles_{run}.exr")["Combined"][..., :3])
    set_sampling_lab(scene, samples=our_spp, seed=our_seed, max_bounces=bounces)
    ours = render_to_exr(scene, folder / "ours.exr")
    return ours, np.stack(cycles)


def assert_ours_agree_with_cycles(ours, cycles, what, detect=None, spp=None, block_rtol=1e-5):
    """The checks every Cycles agreement test makes of :func:`render_ours_and_cycles`' output:
    every sample taken (``spp``: our Sample Count, when given), every image finite, and our
    Combined within the confidence intervals of Cycles' runs
    (``tests.helpers.assert_images_agree``, its default ``detect`` unless given; blocks may
    differ by ``block_rtol`` beyond their intervals). Prints and returns the agreement."""
    from tests.helpers import DETECT, assert_images_agree

    if spp is not None:
        assert (ours["Sample Count"] == spp).all()
    for img in list(ours.values()) + list(cycles):
        assert np.isfinite(img).all()
    found = assert_images_agree(ours["Combined"][..., :3], ours["Variance"], cycles,
                                detect=DETECT if detect is None else detect, what=what,
                                block_rtol=block_rtol)
    print(f"{what}: image mean ours / Cycles {found.ratio}")
    return found
