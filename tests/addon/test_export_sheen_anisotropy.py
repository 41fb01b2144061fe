"""The exporter's sheen and anisotropy (real bpy): the Principled Sheen inputs and the Sheen
BSDF node reach the material table, anisotropic metals get Cycles' roughness scale and the
radial tangents Cycles uses, and what is approximated is reported once by name."""

import math

import bpy
import numpy as np

import scenes


def _export(scene, export):
    scenes.add_camera(scene, (0, 0, 10), (0, 0, 0))
    s = export.export_scene(bpy.context.evaluated_depsgraph_get())
    return s, {name: i for i, name in enumerate(s.materials.names)}


def _principled(name, **inputs):
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    return mat, node


def _node_material(name, idname, **inputs):
    mat = scenes.shader_material(name, idname)
    node = next(n for n in mat.node_tree.nodes if n.bl_idname == idname)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    return mat, node


def _quads(scene, *materials):
    for i, mat in enumerate(materials):
        scenes.add_quad(scene, f"Q{i}", [(0, 0, i), (1, 0, i), (1, 1, i), (0, 1, i)], mat)


def test_principled_sheen_and_sheen_node_reach_the_material_table(empty_scene, export):
    velvet, _ = _principled("Velvet", **{"Sheen Weight": 0.7, "Sheen Roughness": 0.2,
                                         "Sheen Tint": (1.0, 0.5, 0.25, 1.0)})
    glowing, _ = _principled("Glowing", **{"Sheen Weight": 0.5, "Emission Strength": 1.0,
                                           "Emission Color": (1.0, 1.0, 1.0, 1.0)})
    cloth, _ = _node_material("Cloth", "ShaderNodeBsdfSheen", Roughness=0.3,
                              Color=(0.9, 0.8, 0.7, 1.0))
    old, node = _node_material("Old", "ShaderNodeBsdfSheen")
    node.distribution = 'ASHIKHMIN'
    _quads(empty_scene, velvet, glowing, cloth, old)
    s, row = _export(empty_scene, export)
    m = s.materials
    v, c = row["Velvet"], row["Cloth"]
    np.testing.assert_allclose([m.sheen_weight[v], m.sheen_roughness[v]], [0.7, 0.2], rtol=1e-6)
    np.testing.assert_allclose(m.sheen_tint[v], [1.0, 0.5, 0.25], rtol=1e-6)
    # The Sheen BSDF node: a sheen of weight 1 tinted by its colour over a black base.
    np.testing.assert_allclose([m.sheen_weight[c], m.sheen_roughness[c]], [1.0, 0.3], rtol=1e-6)
    np.testing.assert_allclose(m.sheen_tint[c], [0.9, 0.8, 0.7], rtol=1e-6)
    np.testing.assert_array_equal(m.base_color[c], 0.0)
    assert sorted(s.messages) == sorted([
        "Material 'Glowing': emission under the sheen of node 'Principled BSDF' is not "
        "attenuated by the sheen yet",
        "Material 'Old': ASHIKHMIN distribution of node 'Sheen BSDF' is not supported yet; "
        "rendered as Microfiber"]), s.messages


def test_anisotropic_metals_get_cycles_scales_and_only_approximations_are_reported(
        empty_scene, export):
    brushed, _ = _principled("Brushed", **{"Metallic": 1.0, "Anisotropic": 0.5,
                                           "Anisotropic Rotation": 0.25})
    plastic, _ = _principled("Plastic", **{"Anisotropic": 0.5})
    glossy, node = _node_material("Glossy", "ShaderNodeBsdfAnisotropic", Anisotropy=0.3,
                                  Rotation=0.1)
    uv, uv_node = _node_material("UV", "ShaderNodeBsdfAnisotropic", Anisotropy=-0.3)
    tangent = uv.node_tree.nodes.new("ShaderNodeTangent")
    tangent.direction_type = 'UV_MAP'
    uv.node_tree.links.new(tangent.outputs["Tangent"], uv_node.inputs["Tangent"])
    _quads(empty_scene, brushed, plastic, glossy, uv)
    s, row = _export(empty_scene, export)
    m = s.materials
    b, g = row["Brushed"], row["Glossy"]
    np.testing.assert_allclose([m.aniso_scale[b], m.aniso_rotation[b]],
                               [1 / math.sqrt(1 - 0.45), 0.25], rtol=1e-6)
    np.testing.assert_allclose([m.aniso_scale[g], m.aniso_rotation[g]], [0.7, 0.1], rtol=1e-6)
    np.testing.assert_allclose(m.aniso_scale[row["UV"]], 1 / 0.7, rtol=1e-6)
    # The non-metallic Principled: its specular layer is anisotropic too, as in Cycles.
    np.testing.assert_allclose(m.aniso_scale[row["Plastic"]], 1 / math.sqrt(1 - 0.45),
                               rtol=1e-6)
    assert m.kind[row["Plastic"]] == 3
    # The quads have no UV map: the UV Map tangent falls back to the radial one, reported.
    assert s.messages == ["Object 'Q3': no UV map for its UV Map tangent nodes; the radial "
                          "tangent about Z is used"], s.messages
    assert s.aniso_tangents is not None


def test_uv_map_tangent_node_gives_the_uv_tangents_in_world_space(empty_scene, export):
    from test_cycles_textures import add_uv_quad

    mat, node = _node_material("UV", "ShaderNodeBsdfAnisotropic", Anisotropy=0.5)
    tangent = mat.node_tree.nodes.new("ShaderNodeTangent")
    tangent.direction_type = 'UV_MAP'
    mat.node_tree.links.new(tangent.outputs["Tangent"], node.inputs["Tangent"])
    quad = add_uv_quad(empty_scene, "Quad", 1.0, mat)  # u along the object's +X
    quad.rotation_euler = (0.0, 0.0, math.radians(90.0))  # ... now along world +Y
    radial, _ = _principled("Radial", **{"Metallic": 1.0, "Anisotropic": 0.5})
    scenes.add_uv_sphere(empty_scene, "Ball", (0.0, 0.0, 3.0), 0.5, radial)
    s, row = _export(empty_scene, export)
    assert s.messages == [], s.messages
    uv = s.material == row["UV"]
    t = s.aniso_tangents[uv].reshape(-1, 3).astype(np.float64)
    np.testing.assert_allclose(t / np.linalg.norm(t, axis=1, keepdims=True),
                               np.tile([0.0, 1.0, 0.0], (len(t), 1)), atol=1e-5)
    # The radial tangent (about the object's Z) stays on the other mesh: never along Z.
    ball = s.aniso_tangents[s.material == row["Radial"]].reshape(-1, 3)
    assert np.abs(ball[:, 2]).max() < 1e-6 and np.abs(ball).max() > 0


def test_default_tangent_is_radial_about_the_objects_z_axis_in_world_space(empty_scene, export):
    metal, _ = _principled("Brushed", **{"Metallic": 1.0, "Anisotropic": 0.8})
    plain, _ = _principled("Plain", **{"Metallic": 1.0})
    ball = scenes.add_uv_sphere(empty_scene, "Ball", (1.0, 2.0, 3.0), 0.5, metal)
    ball.rotation_euler = (math.radians(90), 0.0, math.radians(30))
    scenes.add_uv_sphere(empty_scene, "Other", (-2.0, 0.0, 0.0), 0.5, plain)
    s, row = _export(empty_scene, export)
    ball_tris = np.flatnonzero(s.material == row["Brushed"])
    other = np.flatnonzero(s.material == row["Plain"])
    assert ball_tris.size and other.size
    np.testing.assert_array_equal(s.aniso_tangents[other], 0.0)
    axis = np.array(ball.matrix_world)[:3, :3] @ np.array([0.0, 0.0, 1.0])
    p = s.vertices[s.triangles[ball_tris]].reshape(-1, 3) - np.array([1.0, 2.0, 3.0])
    t = s.aniso_tangents[ball_tris].reshape(-1, 3).astype(np.float64)
    expect = np.cross(axis, p)
    off_axis = np.linalg.norm(expect, axis=1) > 1e-3
    assert off_axis.mean() > 0.9
    t, expect = t[off_axis], expect[off_axis]
    np.testing.assert_allclose(t / np.linalg.norm(t, axis=1, keepdims=True),
                               expect / np.linalg.norm(expect, axis=1, keepdims=True),
                               atol=1e-5)
