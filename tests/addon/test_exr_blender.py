"""EXR files against real Blender: we read Blender's multilayer files the right way up, and
Blender reads ours as a multilayer image with our passes."""

from __future__ import annotations

import bpy
import numpy as np

from sampling_lab.core import exr

SIZE = 8


def _bottom_half_bright_scene(bpy, tmp_path):
    """An 8x8 Cycles scene: an orthographic camera looking down -Z at an emissive strip that
    fills the lower half of the frame (world y in [-1, 0]) over a black world."""
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene

    cam_data = bpy.data.cameras.new("Cam")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 2.0  # the square frame spans x, y in [-1, 1]
    cam = bpy.data.objects.new("Cam", cam_data)
    cam.location = (0.0, 0.0, 5.0)  # identity rotation: looks down -Z with +Y up
    scene.collection.objects.link(cam)
    scene.camera = cam

    mesh = bpy.data.meshes.new("Strip")
    mesh.from_pydata([(-3, -3, 0), (3, -3, 0), (3, 0, 0), (-3, 0, 0)], [], [(0, 1, 2, 3)])
    mat = bpy.data.materials.new("Glow")
    if mat.node_tree is None:  # Blender < 5 creates node trees on request only
        mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    emission = nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = 1.0
    out = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(emission.outputs["Emission"], out.inputs["Surface"])
    mesh.materials.append(mat)
    strip = bpy.data.objects.new("Strip", mesh)
    scene.collection.objects.link(strip)

    world = bpy.data.worlds.new("Black")
    world.color = (0.0, 0.0, 0.0)
    # Cycles shades the world with its node tree when there is one: zero its background.
    for node in world.node_tree.nodes if world.node_tree else ():
        if node.type == "BACKGROUND":
            node.inputs["Strength"].default_value = 0.0
    scene.world = world

    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 4
    scene.cycles.use_denoising = False
    scene.render.resolution_x = SIZE
    scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    scene.view_layers[0].use_pass_z = True
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):  # Blender 5: choose the multilayer medium first
        settings.media_type = "MULTI_LAYER_IMAGE"
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    path = tmp_path / "blender.exr"
    scene.render.filepath = str(path)
    return scene, path


def test_blender_render_reads_back_with_bottom_row_first(tmp_path):
    import OpenEXR

    _, path = _bottom_half_bright_scene(bpy, tmp_path)
    bpy.ops.render.render(write_still=True)

    f = OpenEXR.File(str(path), separate_channels=True)
    names = {name for part in f.parts for name in part.channels}
    assert {"ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B",
            "ViewLayer.Combined.A", "ViewLayer.Depth.Z"} <= names

    passes = exr.read_multilayer(path)
    combined = passes["Combined"]
    assert combined.shape == (SIZE, SIZE, 4) and combined.dtype == np.float32
    assert passes["Depth"].shape == (SIZE, SIZE, 1)
    # Rows 0-2 see the emitter (radiance 1), rows 5-7 the black world; the pixel filter blurs
    # only the rows next to the edge between rows 3 and 4.
    np.testing.assert_allclose(combined[:3, :, :3], 1.0, atol=0.02)
    np.testing.assert_allclose(combined[5:, :, :3], 0.0, atol=0.02)
    np.testing.assert_allclose(passes["Depth"][:3, :, 0], 5.0, rtol=1e-4)


def test_blender_reads_our_multilayer_file_as_passes(tmp_path):
    path = tmp_path / "ours.exr"
    rng = np.random.default_rng(0)
    exr.write_multilayer(path, {
        "Combined": rng.random((SIZE, SIZE, 4)).astype(np.float32),
        "Variance": rng.random((SIZE, SIZE, 3)).astype(np.float32),
        "Sample Count": np.full((SIZE, SIZE, 1), 16, np.float32),
    })
    bpy.ops.wm.read_homefile(use_empty=True)
    image = bpy.data.images.load(str(path))
    image.size[:]  # loading is lazy: touching the size reads the file and sets its type
    assert image.type == "MULTILAYER"
    tree = bpy.data.node_groups.new("Inspect", "CompositorNodeTree")
    node = tree.nodes.new("CompositorNodeImage")
    node.image = image
    outputs = {o.name: o.type for o in node.outputs}
    assert outputs.get("Combined") == "RGBA"
    assert "Variance" in outputs
    assert outputs.get("Sample Count") == "VALUE"
    assert node.layer == "ViewLayer"
