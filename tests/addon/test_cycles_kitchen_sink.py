"""The kitchen-sink scene (``sampling_lab.tools.kitchen_sink``: mesh light, sphere and area
lamps, HDRI world, textured Principled with coat, a Normal Map node, smooth and rough glass,
alpha leaves, a mirror, a rough metal at Multiscatter GGX) with each engine's *defaults* agrees
with Cycles, and nothing in it is reported as approximated.

Our path tracer runs with our defaults (Sobol sampler, light tree, Cycles' bounce limits);
Cycles with its defaults (Tabulated Sobol, the same bounce limits, caustics on), except the
options that make Cycles deliberately biased or adaptive and which we do not have: indirect
clamping (10), Filter Glossy (1), the light threshold (0.01), adaptive sampling and
denoising are off. Sobol samples within a pixel are correlated, so the per-pixel variance is
no error estimate here: both engines render independent replicates (different seeds) and the
image means per channel are compared with a Welch t interval.
"""

import bpy
import numpy as np
import pytest

import scenes as S
from sampling_lab.core.metrics import student_t_quantile
from sampling_lab.tools.kitchen_sink import kitchen_sink
from tests.helpers import POWER, smallest_detectable

RESOLUTION = (48, 32)
SPP = 48
RUNS = 10  # replicates per engine
MEAN_RTOL = 0.01
# Smallest shift of one channel's image mean this test detects with 99 % power: 1 % plus
# (t_crit + t_power) standard errors of the difference, measured 1.4 - 1.5 % (0.05 % standard
# error per engine). Asserted so that a noisier render cannot weaken the test unnoticed.
DETECTS = 0.02

LIMITS = ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
          "transparent_max_bounces")


def set_cycles_defaults(scene, samples, seed):
    """Cycles as a new scene has it, but for what biases or adapts it (see the module
    docstring)."""
    scene.render.engine = 'CYCLES'
    c = scene.cycles
    c.device = 'CPU'
    c.samples = samples
    c.seed = seed
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.light_sampling_threshold = 0.0


def set_our_defaults(scene, samples, seed):
    """Sampling Lab with its defaults, but for the sample count and seed."""
    scene.render.engine = S.ENGINE_ID
    scene.sampling_lab.samples = samples
    scene.sampling_lab.seed = seed


def assert_image_means_agree(ours, cycles, p_false=1e-4):
    """Image mean per channel of replicates ``ours``, ``cycles`` ``(runs, h, w, 3)``: within
    ``MEAN_RTOL`` of Cycles' plus the Welch t interval of the difference (Bonferroni over the
    three channels). Returns (ratio, smallest detectable relative error) per channel."""
    a, b = ours.mean(axis=(1, 2)), cycles.mean(axis=(1, 2))
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    va, vb = a.var(axis=0, ddof=1) / len(a), b.var(axis=0, ddof=1) / len(b)
    se = np.sqrt(va + vb)
    welch = (va + vb) ** 2 / (va**2 / (len(a) - 1) + vb**2 / (len(b) - 1))
    dof = float(np.clip(welch.min(), min(len(a), len(b)) - 1, len(a) + len(b) - 2))
    t_crit = -student_t_quantile(0.5 * p_false / 3, dof)
    t_power = -student_t_quantile(1.0 - POWER, dof)
    detect = MEAN_RTOL + smallest_detectable(se, mb, t_crit, t_power)
    print(f"kitchen sink: image mean ours / Cycles {ma / mb}, standard error of the "
          f"difference {se / mb} (ours {np.sqrt(va) / mb}, Cycles {np.sqrt(vb) / mb}), detects {detect} ({dof:.1f} dof)")
    assert np.all(np.abs(ma - mb) <= MEAN_RTOL * mb + t_crit * se), (
        f"image means differ: ours {ma}, Cycles {mb} (se {se}, t {t_crit:.3g})")
    assert np.all(detect <= DETECTS), f"test too noisy: detects only {detect}"
    return ma / mb, detect


@pytest.fixture()
def sink(empty_scene, tmp_path):
    kitchen_sink(empty_scene, tmp_path, RESOLUTION)
    return empty_scene


def test_kitchen_sink_reports_no_approximation(sink, export):
    assert bpy.data.materials["Metal"].node_tree.nodes["Principled BSDF"].distribution \
        == 'MULTI_GGX'
    messages = list(export.export_scene(bpy.context.evaluated_depsgraph_get()).messages)
    assert messages == []
    assert bpy.data.materials["Bumpy"].cycles.use_bump_map_correction  # rendered with it
    assert len(bpy.data.objects["Bumpy"].data.uv_layers) == 1


def test_kitchen_sink_at_defaults_agrees_with_cycles(sink, tmp_path):
    scene = sink
    fresh = bpy.data.scenes.new("Defaults")
    try:
        for name in LIMITS:  # both engines at the same default bounce limits
            assert getattr(scene.sampling_lab, name) == getattr(fresh.cycles, name), name
        assert scene.cycles.caustics_reflective and scene.cycles.caustics_refractive
    finally:
        bpy.data.scenes.remove(fresh)
    assert (scene.sampling_lab.integrator, scene.sampling_lab.sampler,
            scene.sampling_lab.light_selection) == ('PATH', 'SOBOL', 'TREE')
    cycles, ours = [], []
    for run in range(RUNS):
        set_cycles_defaults(scene, SPP, seed=41 + run)
        cycles.append(S.render_to_exr(scene, tmp_path / f"cycles_{run}.exr")["Combined"])
        set_our_defaults(scene, SPP, seed=7 + run)
        ours.append(S.render_to_exr(scene, tmp_path / f"ours_{run}.exr")["Combined"])
    cycles, ours = np.stack(cycles)[..., :3], np.stack(ours)[..., :3]
    assert np.isfinite(ours).all() and np.isfinite(cycles).all()
    assert_image_means_agree(ours, cycles)


@pytest.mark.parametrize("space", [None, 'Linear Rec.2020'])
def test_float_image_pixels_are_the_values_cycles_renders(empty_scene, export, tmp_path, space):
    """A float EXR that Blender wrote loads tagged 'sRGB' (its stored values are encoded);
    Blender's pixels are converted to linear whatever the colour space, and they are what
    Cycles renders of a uniform map (within 0.1 %, Cycles' half-float precision). Only a
    non-linear space is reported (Cycles interpolates such an image before converting)."""
    scene = empty_scene
    value = np.float32([0.5, 2.0, 0.1])
    image = S.float_image("Uniform", np.tile(value, (2, 4, 1)))
    image.filepath_raw = str(tmp_path / "uniform.exr")
    image.file_format = 'OPEN_EXR'
    image.save()
    loaded = bpy.data.images.load(str(tmp_path / "uniform.exr"))
    assert loaded.colorspace_settings.name == 'sRGB'
    if space is not None:
        loaded.colorspace_settings.name = space
    S.set_environment_world(scene, loaded)
    S.add_camera(scene, (0.0, 0.0, 0.0), (1.5, 0.0, 0.0))
    S.set_resolution(scene, 4, 4)
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get())
    S.set_cycles_unbiased(scene, samples=4)
    cycles = S.render_to_exr(scene, tmp_path / "cycles.exr")["Combined"][..., :3]
    ours = exported.world_map
    np.testing.assert_allclose(ours, np.broadcast_to(ours[0, 0], ours.shape), rtol=1e-6)
    np.testing.assert_allclose(cycles.mean(axis=(0, 1)), ours[0, 0], rtol=1e-3)
    noted = [m for m in exported.messages if "interpolated after conversion" in m]
    assert len(noted) == (space is None) and len(exported.messages) == len(noted)
    if space is not None:  # the gamut conversion happened (the values moved)
        assert np.abs(ours[0, 0] / value - 1).max() > 0.05
