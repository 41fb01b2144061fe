"""The exporter: Blender data (real bpy) -> core scene tables, in Cycles' units."""

import math
import time

import bpy
import numpy as np
import pytest

import scenes

VIS_ALL = 31
VIS_CAMERA = 1
VIS_SHADOW = 16


def export_current(export):
    return export.export_scene(bpy.context.evaluated_depsgraph_get())


def light_row(lights, name):
    i = lights.names.index(name)
    return {field: getattr(lights, field)[i] for field in lights.__dataclass_fields__
            if field != "names"}


def rotation_x(deg):
    a = math.radians(deg)
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


# --------------------------------------------------------------------------- geometry, materials


def test_cornell_box_exports_every_triangle_with_its_material(empty_scene, export):
    scenes.cornell_box_mesh_light(empty_scene)
    s = export_current(export)
    # 5 wall quads, 2 closed blocks, 1 lamp quad.
    assert s.n_triangles == 5 * 2 + 2 * 12 + 2
    assert s.vertices.dtype == np.float32 and s.triangles.dtype == np.int32
    assert s.triangles.max() < s.vertices.shape[0]
    assert sorted(s.materials.names) == ["Green", "Light", "Red", "White"]
    names = np.array(s.materials.names)[s.material]
    assert (names == "Red").sum() == 2 and (names == "Green").sum() == 2
    assert (names == "Light").sum() == 2 and (names == "White").sum() == 30
    red = s.materials.names.index("Red")
    np.testing.assert_allclose(s.materials.base_color[red], scenes.RED, rtol=1e-6)
    np.testing.assert_allclose(s.materials.emission[red], 0.0)
    lamp = s.materials.names.index("Light")
    np.testing.assert_allclose(s.materials.emission[lamp], 10.0)
    np.testing.assert_allclose(s.materials.base_color[lamp], 0.0)
    assert len(s.lights) == 0
    np.testing.assert_allclose(s.world_color, 0.0)
    assert (s.visibility == VIS_ALL).all()
    assert s.messages == []


def test_vertices_are_in_world_space(empty_scene, export):
    ob = scenes.add_quad(empty_scene, "Quad", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    ob.location = (10.0, -5.0, 2.0)
    ob.rotation_euler = (0.0, 0.0, math.radians(90))
    ob.scale = (2.0, 2.0, 2.0)
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    expected = np.array([(10, -5, 2), (10, -3, 2), (8, -3, 2), (8, -5, 2)], np.float32)
    np.testing.assert_allclose(np.sort(s.vertices, axis=0), np.sort(expected, axis=0), atol=1e-5)


def test_object_without_material_is_cycles_default_grey(empty_scene, export):
    scenes.add_quad(empty_scene, "Bare", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    assert s.materials.names == [export.DEFAULT_SURFACE_NAME]
    np.testing.assert_allclose(s.materials.base_color[0], 0.8, rtol=1e-6)
    np.testing.assert_allclose(s.materials.emission[0], 0.0)
    assert s.messages == []


def test_material_index_selects_slot_per_face(empty_scene, export):
    a = scenes.diffuse_material("A", (1.0, 0.0, 0.0))
    b = scenes.diffuse_material("B", (0.0, 0.0, 1.0))
    verts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2, 1, 0), (3, 0, 0)]
    ob = scenes.add_mesh(empty_scene, "TwoMats", verts, [(0, 1, 2, 3), (1, 4, 5, 2), (4, 6, 5)], a)
    ob.data.materials.append(b)
    ob.data.polygons[1].material_index = 1
    ob.data.polygons[2].material_index = 7  # out of range: Blender clamps to the last slot
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    names = np.array(s.materials.names)[s.material]
    assert list(names) == ["A", "A", "B", "B", "B"]


def test_modifiers_are_applied(empty_scene, export):
    ob = scenes.add_block(empty_scene, "Cube", (0, 0, 0), (1, 1, 1))
    mod = ob.modifiers.new("Subdivision", 'SUBSURF')
    mod.levels = mod.render_levels = 2
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    # Each of 6 quads splits into 4**2 quads of 2 triangles.
    assert s.n_triangles == 6 * 16 * 2


def test_collection_instances_are_exported_at_their_transforms(empty_scene, export):
    coll = bpy.data.collections.new("Source")
    mesh_ob = scenes.add_quad(empty_scene, "Tile", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    empty_scene.collection.objects.unlink(mesh_ob)
    coll.objects.link(mesh_ob)
    for i, x in enumerate((5.0, 10.0)):
        inst = bpy.data.objects.new(f"Instance{i}", None)
        inst.instance_type = 'COLLECTION'
        inst.instance_collection = coll
        inst.location = (x, 0.0, 0.0)
        empty_scene.collection.objects.link(inst)
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    assert s.n_triangles == 4
    xs = np.unique(np.round(s.vertices[:, 0], 4))
    np.testing.assert_allclose(xs, [5, 6, 10, 11])


def test_text_objects_are_triangulated(empty_scene, export):
    curve = bpy.data.curves.new("Text", 'FONT')
    curve.body = "Hi"
    ob = bpy.data.objects.new("Text", curve)
    empty_scene.collection.objects.link(ob)
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    assert s.n_triangles > 10


def test_object_ray_visibility_becomes_triangle_bits(empty_scene, export):
    hidden = scenes.add_quad(empty_scene, "Hidden", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    hidden.visible_camera = False
    hidden.visible_shadow = False
    scenes.add_quad(empty_scene, "Shown", [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)])
    lamp = scenes.add_light(empty_scene, 'POINT', "Lamp", (0, 0, 3), energy=10.0)
    lamp.visible_camera = False
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    z = s.vertices[s.triangles[:, 0], 2]
    assert (s.visibility[z < 0.5] == VIS_ALL & ~VIS_CAMERA & ~VIS_SHADOW).all()
    assert (s.visibility[z > 0.5] == VIS_ALL).all()
    assert not light_row(s.lights, "Lamp")["visible_camera"]


def test_one_million_triangle_mesh_exports(empty_scene, export):
    n = 708  # quads per side: 2 * 708**2 = 1,002,528 triangles
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=n, y_subdivisions=n, size=2.0)
    scenes.add_camera(empty_scene, (0, 0, 5), (0, 0, 0))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    t0 = time.perf_counter()
    s = export.export_scene(depsgraph)
    elapsed = time.perf_counter() - t0
    print(f"\nexport of {s.n_triangles:,} triangles: {elapsed:.3f} s")
    assert s.n_triangles == 2 * n * n
    assert s.vertices.shape == ((n + 1) ** 2, 3)
    assert np.isfinite(s.vertices).all()
    np.testing.assert_allclose(s.vertices.min(axis=0), [-1, -1, 0], atol=1e-6)


# --------------------------------------------------------------------------- node trees


def test_unsupported_node_is_reported_once(empty_scene, export):
    toon = scenes.shader_material("Toon", "ShaderNodeBsdfToon", color=(0.9, 0.9, 0.9))
    for i in range(3):
        scenes.add_quad(empty_scene, f"Pane{i}",
                        [(0, 0, i), (1, 0, i), (1, 1, i), (0, 1, i)], toon)
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    assert s.messages == [
        "Material 'Toon': node 'Toon BSDF' is not supported yet; rendered as diffuse"]
    row = s.materials.names.index("Toon")
    assert s.materials.kind[row] == 0
    np.testing.assert_allclose(s.materials.base_color[row], 0.9, rtol=1e-6)


def _principled(name, **inputs):
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.distribution = 'GGX'
    for key, value in inputs.items():
        bsdf.inputs[key].default_value = value
    return mat


def _export_materials(empty_scene, export, *materials):
    for i, mat in enumerate(materials):
        scenes.add_quad(empty_scene, f"Q{i}", [(0, 0, i), (1, 0, i), (1, 1, i), (0, 1, i)], mat)
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    return s, {name: i for i, name in enumerate(s.materials.names)}


def test_principled_bsdf_maps_metal_glass_and_coat_with_their_inputs(empty_scene, export):
    gold = _principled("Gold", **{"Base Color": (1.0, 0.8, 0.3, 1.0), "Metallic": 1.0,
                                  "Roughness": 0.2, "Emission Color": (1.0, 0.5, 0.25, 1.0),
                                  "Emission Strength": 4.0})
    glass = _principled("Glass", **{"Transmission Weight": 1.0, "IOR": 1.33, "Roughness": 0.0})
    plastic = _principled("Plastic", **{"Base Color": (0.2, 0.4, 0.6, 1.0), "Roughness": 0.3,
                                        "Specular IOR Level": 0.7,
                                        "Specular Tint": (1.0, 0.9, 0.8, 1.0)})
    s, row = _export_materials(empty_scene, export, gold, glass, plastic)
    m = s.materials
    assert s.messages == []
    assert [m.kind[row[k]] for k in ("Gold", "Glass", "Plastic")] == [1, 2, 3]
    np.testing.assert_allclose(m.base_color[row["Gold"]], [1.0, 0.8, 0.3], rtol=1e-6)
    np.testing.assert_allclose(m.emission[row["Gold"]], [4.0, 2.0, 1.0], rtol=1e-6)
    np.testing.assert_allclose(m.roughness[[row["Gold"], row["Glass"], row["Plastic"]]],
                               [0.2, 0.0, 0.3], rtol=1e-6)
    assert m.metallic[row["Gold"]] == 1.0 and m.transmission[row["Glass"]] == 1.0
    np.testing.assert_allclose(m.ior[row["Glass"]], 1.33, rtol=1e-6)
    np.testing.assert_allclose(m.specular_ior_level[row["Plastic"]], 0.7, rtol=1e-6)
    np.testing.assert_allclose(m.specular_tint[row["Plastic"]], [1.0, 0.9, 0.8], rtol=1e-6)


def _mixture(m, row):
    """``{kind: weight}`` of the components of material row ``row``."""
    out = {}
    for r, w in zip(m.mix_rows[row], m.mix_weights[row]):
        if w > 0:
            out[int(m.kind[r])] = out.get(int(m.kind[r]), 0.0) + float(w)
    return out


def test_fractional_principled_exports_a_mixture_with_cycles_weights(empty_scene, export):
    mat = _principled("Half", **{"Metallic": 0.7, "Transmission Weight": 0.4, "Alpha": 0.5,
                                 "Coat Weight": 0.5, "Emission Strength": 2.0,
                                 "Emission Color": (1.0, 1.0, 1.0, 1.0)})
    s, row = _export_materials(empty_scene, export, mat)
    m = s.materials
    # Transparent 1 - a; of the rest a: metal m, glass (1 - m) t, opaque (1 - m)(1 - t).
    mix = _mixture(m, row["Half"])
    assert set(mix) == {1, 2, 3}
    np.testing.assert_allclose(mix[1], 0.5 * 0.7, rtol=1e-6)
    np.testing.assert_allclose(mix[3], 0.5 * 0.3 * 0.6, rtol=1e-6)
    np.testing.assert_allclose(mix[2], 0.5 + 0.5 * 0.3 * 0.4, rtol=1e-6)
    clear = [r for r, w in zip(m.mix_rows[row["Half"]], m.mix_weights[row["Half"]])
             if w > 0 and m.kind[r] == 2 and m.ior[r] == 1.0]
    assert len(clear) == 1 and m.roughness[clear[0]] == 0.0
    np.testing.assert_allclose(m.emission[row["Half"]], 0.5 * 2.0, rtol=1e-6)
    assert m.mixed[row["Half"]]
    components = m.mix_rows[row["Half"]]
    np.testing.assert_allclose(m.emission[components], 0.0)
    # The coat covers every component but the transparent one.
    np.testing.assert_allclose(m.coat_weight[components], np.where(m.ior[components] == 1.0
                                                                   , 0.0, 0.5), rtol=1e-6)
    # Alpha is no approximation any more (shadow rays pass it, core/integrators/shadows.py).
    assert len(s.messages) == 1, s.messages
    assert any("emission under the coat" in msg for msg in s.messages)


def test_principled_coat_inputs_and_subsurface_as_diffuse(empty_scene, export):
    coated = _principled("Coated", **{"Base Color": (0.5, 0.1, 0.1, 1.0), "Coat Weight": 0.8,
                                      "Coat Roughness": 0.2, "Coat IOR": 1.7,
                                      "Coat Tint": (0.9, 0.7, 0.5, 1.0)})
    skin = _principled("Skin", **{"Base Color": (0.8, 0.5, 0.4, 1.0), "Subsurface Weight": 1.0})
    plain = _principled("Plain", **{"Base Color": (0.8, 0.5, 0.4, 1.0)})
    s, row = _export_materials(empty_scene, export, coated, skin, plain)
    m = s.materials
    c = row["Coated"]
    np.testing.assert_allclose([m.coat_weight[c], m.coat_roughness[c], m.coat_ior[c]],
                               [0.8, 0.2, 1.7], rtol=1e-6)
    np.testing.assert_allclose(m.coat_tint[c], [0.9, 0.7, 0.5], rtol=1e-6)
    assert m.coat_weight[row["Skin"]] == 0 and m.coat_weight[row["Plain"]] == 0
    # Subsurface renders as the diffuse base: the same row as without it, and said once.
    for column in ("kind", "base_color", "roughness", "ior", "specular_ior_level"):
        np.testing.assert_array_equal(getattr(m, column)[row["Skin"]],
                                      getattr(m, column)[row["Plain"]])
    assert s.messages == ["Material 'Skin': subsurface scattering of node 'Principled BSDF' "
                          "is approximated as diffuse reflection of the base colour"], s.messages


def test_mix_of_diffuse_shaders_is_the_diffuse_of_the_blended_colour(empty_scene, export):
    mix = scenes.shader_material("Blend", "ShaderNodeMixShader")
    tree = mix.node_tree
    shader = tree.nodes["Mix Shader"]
    shader.inputs["Fac"].default_value = 0.25
    a = tree.nodes.new("ShaderNodeBsdfDiffuse")
    a.inputs["Color"].default_value = (1.0, 0.0, 0.0, 1.0)
    b = tree.nodes.new("ShaderNodeBsdfDiffuse")
    b.inputs["Color"].default_value = (0.0, 0.0, 1.0, 1.0)
    tree.links.new(a.outputs[0], shader.inputs[1])
    tree.links.new(b.outputs[0], shader.inputs[2])
    s, row = _export_materials(empty_scene, export, mix)
    m = s.materials
    assert s.messages == [] and not m.mixed.any() and len(m.kind) == 1
    np.testing.assert_allclose(m.base_color[row["Blend"]], [0.75, 0.0, 0.25], rtol=1e-6)


def test_glossy_glass_refraction_transparent_and_mix_nodes_map_to_core_kinds(empty_scene,
                                                                             export):
    glossy = scenes.shader_material("Glossy", "ShaderNodeBsdfGlossy", color=(0.9, 0.8, 0.7))
    glossy.node_tree.nodes["Glossy BSDF"].inputs["Roughness"].default_value = 0.3
    glass = scenes.shader_material("Glass", "ShaderNodeBsdfGlass", color=(0.9, 0.9, 0.9))
    glass.node_tree.nodes["Glass BSDF"].inputs["Roughness"].default_value = 0.0
    glass.node_tree.nodes["Glass BSDF"].inputs["IOR"].default_value = 1.45
    refraction = scenes.shader_material("Refr", "ShaderNodeBsdfRefraction")
    refraction.node_tree.nodes["Refraction BSDF"].inputs["Roughness"].default_value = 0.0
    clear = scenes.shader_material("Clear", "ShaderNodeBsdfTransparent")
    mix = scenes.shader_material("Mix", "ShaderNodeMixShader")
    tree = mix.node_tree
    shader = tree.nodes["Mix Shader"]
    shader.inputs["Fac"].default_value = 0.8
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    metal = tree.nodes.new("ShaderNodeBsdfGlossy")
    metal.distribution = 'GGX'
    tree.links.new(diffuse.outputs[0], shader.inputs[1])
    tree.links.new(metal.outputs[0], shader.inputs[2])
    s, row = _export_materials(empty_scene, export, glossy, glass, refraction, clear, mix)
    m = s.materials
    assert [m.kind[row[k]] for k in ("Glossy", "Glass", "Refr", "Clear", "Mix")] == \
        [1, 2, 2, 2, 1]
    np.testing.assert_allclose(m.base_color[row["Glossy"]], [0.9, 0.8, 0.7], rtol=1e-6)
    np.testing.assert_allclose(m.ior[row["Glass"]], 1.45, rtol=1e-6)
    assert m.ior[row["Clear"]] == 1.0 and m.roughness[row["Clear"]] == 0.0
    text = "\n".join(s.messages)
    # Refraction-only is reported; transparent no longer is (shadow rays pass it). Multiscatter
    # GGX (the Glossy default) is modelled on conductors, so it is not reported.
    assert "Material 'Glossy'" not in text
    assert "Material 'Glass'" not in text
    assert "Material 'Refr': node 'Refraction BSDF' (refraction only)" in text
    assert "Material 'Clear'" not in text
    assert "Mix Shader" not in text
    assert len(s.messages) == 1, s.messages
    assert m.multiscatter[row["Glossy"]] and not m.multiscatter[row["Mix"]]
    # Mix: diffuse 1 - Fac, glossy Fac.
    mix = _mixture(m, row["Mix"])
    np.testing.assert_allclose([mix[0], mix[1]], [0.2, 0.8], rtol=1e-6)


def test_multiscatter_ggx_is_flagged_on_metals_specular_layers_and_glass(empty_scene, export):
    from sampling_lab.core.materials.bsdf import (KIND_CONDUCTOR_MS, KIND_DIELECTRIC_MS,
                                                  KIND_LAYERED_MS, BSDFParams)

    def glossy(name, distribution):
        return scenes.glossy_material(name, (0.9, 0.7, 0.5), 0.4, distribution)

    def principled(name, distribution, **inputs):
        mat = _principled(name, Roughness=0.5, **inputs)
        next(n for n in mat.node_tree.nodes
             if n.bl_idname == "ShaderNodeBsdfPrincipled").distribution = distribution
        return mat

    glass = scenes.glass_material("RoughGlass", roughness=0.3, distribution='MULTI_GGX')
    s, row = _export_materials(
        empty_scene, export, glossy("MultiGlossy", 'MULTI_GGX'), glossy("Glossy", 'GGX'),
        principled("Metal", 'MULTI_GGX', Metallic=1.0),
        principled("GGXMetal", 'GGX', Metallic=1.0),
        principled("HalfMetal", 'MULTI_GGX', Metallic=0.5), glass)
    m = s.materials
    assert [bool(m.multiscatter[row[k]]) for k in ("MultiGlossy", "Glossy", "Metal", "GGXMetal")] \
        == [True, False, True, False]
    # The mixture: its metal component and its specular layer are compensated.
    components = {int(m.kind[r]): bool(m.multiscatter[r])
                  for r, w in zip(m.mix_rows[row["HalfMetal"]], m.mix_weights[row["HalfMetal"]])
                  if w > 0}
    assert components == {1: True, 3: True}
    assert s.messages == [], s.messages
    # The core shades the flagged rows with the compensated BSDFs.
    layered = [r for r in m.mix_rows[row["HalfMetal"]] if m.kind[r] == 3][0]
    kinds = BSDFParams.from_materials(m, np.array([row["MultiGlossy"], row["Glossy"],
                                                   layered, row["RoughGlass"]])).kind
    assert kinds.tolist() == [KIND_CONDUCTOR_MS, 1, KIND_LAYERED_MS, KIND_DIELECTRIC_MS]


def test_principled_glass_tints_each_pass_by_the_square_root_of_its_base_colour(empty_scene,
                                                                              export):
    def glass(name, color):
        mat = _principled(name, **{"Transmission Weight": 1.0, "Roughness": 0.4,
                                   "Base Color": (*color, 1.0)})
        next(n for n in mat.node_tree.nodes
             if n.bl_idname == "ShaderNodeBsdfPrincipled").distribution = 'MULTI_GGX'
        return mat

    s, row = _export_materials(empty_scene, export, glass("White", (1.0, 1.0, 1.0)),
                               glass("Green", (0.25, 0.64, 0.09)))
    m = s.materials
    np.testing.assert_allclose(m.base_color[row["Green"]], [0.5, 0.8, 0.3], rtol=1e-6)
    # Multiscatter GGX is compensated on white glass only (Cycles' F_ss = 1 there).
    assert m.multiscatter[row["White"]] and not m.multiscatter[row["Green"]]
    assert s.messages == ["Material 'Green': Multiscatter GGX on the coloured transmission of "
                          "node 'Principled BSDF' is not supported yet; rendered as "
                          "single-scattering GGX"], s.messages


def test_texture_driven_color_uses_socket_value_and_is_reported(empty_scene, export):
    mat = scenes.diffuse_material("Checker", (0.2, 0.4, 0.6))
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexChecker")
    diffuse = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfDiffuse")
    tree.links.new(tex.outputs["Color"], diffuse.inputs["Color"])
    scenes.add_quad(empty_scene, "Q", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], mat)
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    np.testing.assert_allclose(s.materials.base_color[0], [0.2, 0.4, 0.6], rtol=1e-6)
    assert len(s.messages) == 1 and "Checker Texture" in s.messages[0]


def test_rgb_node_and_reroute_are_followed_exactly(empty_scene, export):
    mat = scenes.diffuse_material("Routed", (0.0, 0.0, 0.0))
    tree = mat.node_tree
    rgb = tree.nodes.new("ShaderNodeRGB")
    rgb.outputs[0].default_value = (0.3, 0.2, 0.1, 1.0)
    reroute = tree.nodes.new("NodeReroute")
    diffuse = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfDiffuse")
    tree.links.new(rgb.outputs[0], reroute.inputs[0])
    tree.links.new(reroute.outputs[0], diffuse.inputs["Color"])
    scenes.add_quad(empty_scene, "Q", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], mat)
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    np.testing.assert_allclose(s.materials.base_color[0], [0.3, 0.2, 0.1], rtol=1e-6)
    assert s.messages == []


def test_world_background_color_times_strength(empty_scene, export):
    scenes.set_world(empty_scene, (0.2, 0.3, 0.4), 2.5)
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    np.testing.assert_allclose(s.world_color, [0.5, 0.75, 1.0], rtol=1e-6)


def test_default_world_uses_its_background_node(empty_scene, export):
    world = bpy.data.worlds.new("Default")  # Blender's new world: one Background node
    empty_scene.world = world
    bg = next(n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeBackground")
    expected = np.array(bg.inputs["Color"].default_value[:3]) * bg.inputs["Strength"].default_value
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    assert expected.max() > 0
    np.testing.assert_allclose(s.world_color, expected, rtol=1e-6)


def test_no_world_is_black(empty_scene, export):
    empty_scene.world = None
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    np.testing.assert_allclose(export_current(export).world_color, 0.0)


# --------------------------------------------------------------------------- lights


def test_point_light_of_100_watts_has_intensity_100_over_4pi(empty_scene, export):
    scenes.cornell_box_point_light(empty_scene)
    s = export_current(export)
    assert len(s.lights) == 1
    row = light_row(s.lights, "Lamp")
    assert row["kind"] == 0  # LIGHT_POINT
    assert row["radius"] == 0.0
    np.testing.assert_allclose(row["position"], [0, 0, 1.8], atol=1e-6)
    np.testing.assert_allclose(row["radiance"], 100.0 / (4 * math.pi), rtol=1e-6)
    assert row["spot_cos_half"] == -1.0


def test_light_color_exposure_and_temperature_scale_the_power(empty_scene, export):
    lamp = scenes.add_light(empty_scene, 'POINT', "Lamp", (0, 0, 1), energy=100.0,
                            color=(1.0, 0.5, 0.25), shadow_soft_size=0.0, exposure=1.0)
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    expected = 2.0 * 100.0 * np.array([1.0, 0.5, 0.25]) / (4 * math.pi)
    np.testing.assert_allclose(light_row(s.lights, "Lamp")["radiance"], expected, rtol=1e-6)

    lamp.data.use_temperature = True
    lamp.data.temperature = 3000.0
    tint = np.array(lamp.data.temperature_color[:3])
    assert tint[2] < tint[0]  # a warm light
    s = export_current(export)
    np.testing.assert_allclose(light_row(s.lights, "Lamp")["radiance"], expected * tint,
                               rtol=1e-5)


def test_sphere_point_light_radiance(empty_scene, export):
    scenes.add_light(empty_scene, 'POINT', "Bulb", (0, 0, 1), energy=40.0, shadow_soft_size=0.1)
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    row = light_row(export_current(export).lights, "Bulb")
    assert row["radius"] == pytest.approx(0.1)
    np.testing.assert_allclose(row["radiance"], 40.0 / (4 * math.pi**2 * 0.01), rtol=1e-5)


def test_spot_light_points_down_its_local_minus_z(empty_scene, export):
    scenes.add_light(empty_scene, 'SPOT', "Spot", (0, 0, 3), (math.radians(45), 0, 0),
                     energy=100.0, shadow_soft_size=0.0, spot_size=math.radians(60),
                     spot_blend=0.25)
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    row = light_row(export_current(export).lights, "Spot")
    np.testing.assert_allclose(row["direction"], rotation_x(45) @ [0, 0, -1], atol=1e-6)
    assert row["spot_cos_half"] == pytest.approx(math.cos(math.radians(30)))
    np.testing.assert_allclose(row["radiance"], 100.0 / (4 * math.pi), rtol=1e-6)


def test_sun_direction_strength_and_world(empty_scene, export):
    objs = scenes.plane_under_sun(empty_scene, strength=3.0, angle_deg=0.526)
    s = export_current(export)
    row = light_row(s.lights, "Sun")
    assert row["kind"] == 1  # LIGHT_SUN
    np.testing.assert_allclose(row["direction"], rotation_x(30) @ [0, 0, -1], atol=1e-6)
    angle = math.radians(0.526)
    assert row["angle"] == pytest.approx(angle, rel=1e-6)
    np.testing.assert_allclose(row["radiance"], 3.0 / (math.pi * math.sin(angle / 2) ** 2),
                               rtol=1e-5)
    np.testing.assert_allclose(s.world_color, [0.05, 0.07, 0.1], rtol=1e-6)
    assert objs["plane"].name == "Plane" and s.n_triangles == 2


@pytest.mark.parametrize("shape,kind,area", [
    ('SQUARE', 2, 1.0 * 0.5),
    ('RECTANGLE', 2, 1.0 * 0.25),
    ('DISK', 3, 1.0 * 0.5 * math.pi / 4),
    ('ELLIPSE', 3, 1.0 * 0.25 * math.pi / 4),
])
def test_area_light_radiance_uses_shape_size_and_object_scale(empty_scene, export, shape, kind,
                                                              area):
    lamp = scenes.add_light(empty_scene, 'AREA', "Panel", (0, 0, 2), energy=50.0, shape=shape,
                            size=0.5, size_y=0.25)
    lamp.scale = (2.0, 1.0, 1.0)
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    row = light_row(export_current(export).lights, "Panel")
    assert row["kind"] == kind
    np.testing.assert_allclose(row["direction"], [0, 0, -1], atol=1e-6)
    np.testing.assert_allclose(row["radiance"], 50.0 / (math.pi * area), rtol=1e-6)
    np.testing.assert_allclose(row["position"], [0, 0, 2], atol=1e-6)


def test_cornell_box_area_light(empty_scene, export):
    scenes.cornell_box_area_light(empty_scene)
    s = export_current(export)
    row = light_row(s.lights, "Lamp")
    np.testing.assert_allclose(row["radiance"], 50.0 / (math.pi * 0.25), rtol=1e-6)
    assert s.n_triangles == 5 * 2 + 2 * 12


def test_unnormalized_light_is_reported(empty_scene, export):
    scenes.add_light(empty_scene, 'AREA', "Panel", (0, 0, 2), energy=50.0, normalize=False)
    scenes.add_camera(empty_scene, (0, 0, 10), (0, 0, 0))
    s = export_current(export)
    assert any("Light 'Panel'" in m and "Normalize" in m for m in s.messages)


# --------------------------------------------------------------------------- camera


def test_camera_parameters_and_resolution(empty_scene, export):
    cam_ob = scenes.add_camera(empty_scene, (1.0, 2.0, 3.0), (math.radians(90), 0, 0), lens=35.0)
    cam_ob.scale = (2.0, 3.0, 4.0)
    cam = cam_ob.data
    cam.sensor_width, cam.sensor_height, cam.sensor_fit = 32.0, 20.0, 'VERTICAL'
    cam.shift_x, cam.shift_y = 0.1, -0.2
    cam.clip_start, cam.clip_end = 0.5, 50.0
    scenes.set_resolution(empty_scene, 320, 240, percentage=50)
    empty_scene.render.pixel_aspect_x = 2.0
    c = export_current(export).camera
    assert (c.width, c.height) == (160, 120)
    assert c.type == 'PERSP' and c.lens == pytest.approx(35.0)
    assert (c.sensor_width, c.sensor_height, c.sensor_fit) == (32.0, 20.0, 'VERTICAL')
    assert (c.shift_x, c.shift_y) == (pytest.approx(0.1), pytest.approx(-0.2))
    assert (c.clip_start, c.clip_end) == (pytest.approx(0.5), pytest.approx(50.0))
    assert (c.pixel_aspect_x, c.pixel_aspect_y) == (2.0, 1.0)
    np.testing.assert_allclose(c.to_world[:3, :3], rotation_x(90), atol=1e-6)
    np.testing.assert_allclose(c.to_world[:3, 3], [1, 2, 3], atol=1e-6)


def test_orthographic_camera(empty_scene, export):
    cam_ob = scenes.add_camera(empty_scene, (0, 0, 5), (0, 0, 0))
    cam_ob.data.type = 'ORTHO'
    cam_ob.data.ortho_scale = 3.5
    c = export_current(export).camera
    assert c.type == 'ORTHO' and c.ortho_scale == pytest.approx(3.5)


def test_missing_camera_is_a_clear_export_error(empty_scene, export):
    scenes.add_quad(empty_scene, "Q", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    with pytest.raises(export.ExportError, match="no camera"):
        export_current(export)


def test_render_without_camera_raises_runtime_error_mentioning_camera(empty_scene):
    scenes.add_quad(empty_scene, "Q", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    scenes.set_resolution(empty_scene, 8, 8)
    with pytest.raises(RuntimeError, match="camera"):
        bpy.ops.render.render()
