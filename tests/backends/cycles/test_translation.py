"""Translation tests on bpy state (no rendering): what the IR becomes inside Blender."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from blendify_blender import CyclesBackend

import blendify_core as bf
from blendify_core import testing
from blendify_core.errors import InvalidSceneError, RenderError
from blendify_core.pipeline.capabilities import ALL_FEATURES
from blendify_core.pipeline.settings import resolve_settings

pytestmark = pytest.mark.cycles


def _obj(bpy, tag):
    hits = [o for o in bpy.data.objects if o.name.endswith("_" + tag) and o.name.startswith("bf_")]
    assert len(hits) == 1, [o.name for o in bpy.data.objects]
    return hits[0]


def test_import_does_not_load_bpy():
    code = "import blendify_blender, sys; blendify_blender.CyclesBackend.probe(); print('bpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_capability_table_declares_every_feature():
    caps = CyclesBackend.capabilities()
    assert set(caps) == set(ALL_FEATURES)
    assert all(c.level == "exact" for c in caps.values())


def test_bad_options_are_clear():
    with pytest.raises(InvalidSceneError, match="unknown option"):
        CyclesBackend(samplez=3)
    with pytest.raises(InvalidSceneError, match="device"):
        CyclesBackend(device="TPU")
    with pytest.raises(InvalidSceneError, match="verbose"):
        CyclesBackend(verbose="yes")
    with pytest.raises(InvalidSceneError, match="worker_max_renders"):
        CyclesBackend(worker_max_renders=0)


def test_scene_without_camera_is_rejected(cycles):
    scene = bf.Scene()
    with pytest.raises(InvalidSceneError, match="camera"):
        cycles.translate(scene, resolve_settings())


def test_mesh_data(cycles, bpy):
    scene = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]], dtype=float) + 1000.0
    f = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    vc = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [0.5, 0.5, 0.5]])
    uv = bf.VertexUV(v[:, :2] - 1000.0)
    tex = np.zeros((4, 8, 3), dtype=np.uint8)
    tex[0, 0] = 255
    scene.renderables.add_mesh(v, f, bf.DiffuseMaterial(), bf.VertexColors(vc), smooth=True, tag="m")
    scene.renderables.add_mesh(
        v,
        f,
        [bf.DiffuseMaterial(), bf.PlasticMaterial()],
        [bf.TextureColors(tex, uv), bf.UniformColors((0.2, 0.3, 0.4))],
        faces_material=[0, 1, 1, 0],
        tag="t",
    )
    scene.set_perspective_camera((32, 24), fov_x=0.8, translation=(1000, 1000, 5))
    cycles.translate(scene, resolve_settings())
    me = _obj(bpy, "m").data
    assert (len(me.vertices), len(me.polygons), len(me.loops)) == (5, 4, 12)
    co = np.zeros(15, dtype=np.float32)
    me.vertices.foreach_get("co", co)
    world = np.array(_obj(bpy, "m").matrix_world) @ np.c_[co.reshape(-1, 3), np.ones(5)].T
    np.testing.assert_allclose(world[:3].T, v, atol=1e-4)
    assert np.abs(co).max() < 1.0  # re-centred: float32 keeps the precision
    col = np.zeros(20, dtype=np.float32)
    me.color_attributes["bf_color_0"].data.foreach_get("color", col)
    np.testing.assert_allclose(col.reshape(-1, 4), bf.VertexColors(vc).linear_rgba, atol=1e-6)
    smooth = np.zeros(4, dtype=bool)
    me.polygons.foreach_get("use_smooth", smooth)
    assert smooth.all()
    mt = _obj(bpy, "t").data
    mi = np.zeros(4, dtype=np.int32)
    mt.polygons.foreach_get("material_index", mi)
    assert mi.tolist() == [0, 1, 1, 0]
    assert len(mt.materials) == 2
    uvs = np.zeros(24, dtype=np.float32)
    mt.uv_layers["UVMap"].data.foreach_get("uv", uvs)
    np.testing.assert_allclose(uvs.reshape(4, 3, 2), uv.data[f], atol=1e-6)
    flat = np.zeros(4, dtype=bool)
    mt.polygons.foreach_get("use_smooth", flat)
    assert not flat.any()
    img = next(n for n in mt.materials[0].node_tree.nodes if n.bl_idname == "ShaderNodeTexImage").image
    assert (img.size[0], img.size[1]) == (8, 4)
    px = np.zeros(8 * 4 * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    px = px.reshape(4, 8, 4)
    assert px[3, 0, 0] == pytest.approx(1.0) and px[0, 0, 0] == 0.0  # row 0 of the IR = top = last in Blender
    base = mt.materials[1].node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value
    np.testing.assert_allclose(base[:3], bf.UniformColors((0.2, 0.3, 0.4)).linear_rgba[:3], atol=1e-6)


def test_principled_inputs_and_wireframe(cycles, bpy):
    scene = bf.Scene()
    mat = bf.PlasticWireframeMaterial(
        roughness=0.25, metallic=0.1, ior=1.6, coat_weight=0.3, emission_color=(1, 0, 0), emission_strength=2.0
    )
    scene.renderables.add_sphere_nurbs(1.0, mat, bf.UniformColors((0.5, 0.5, 0.5)), tag="s")
    scene.renderables.add_cube_mesh(
        1.0, bf.GlossyBSDFMaterial(roughness=0.1, distribution="BECKMANN"), bf.UniformColors((1, 1, 1)), tag="g"
    )
    scene.set_perspective_camera((32, 24), fov_x=0.8, translation=(0, 0, 5))
    cycles.translate(scene, resolve_settings())
    nt = _obj(bpy, "s").material_slots[0].material.node_tree
    bsdfs = [n for n in nt.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"]
    assert len(bsdfs) == 2  # surface + wire colour
    p = bsdfs[0].inputs
    assert p["Roughness"].default_value == pytest.approx(0.25)
    assert p["Metallic"].default_value == pytest.approx(0.1)
    assert p["IOR"].default_value == pytest.approx(1.6)
    assert p["Specular IOR Level"].default_value == pytest.approx(0.5)
    assert p["Coat Weight"].default_value == pytest.approx(0.3)
    assert p["Emission Strength"].default_value == pytest.approx(2.0)
    assert bsdfs[0].distribution == bsdfs[1].distribution == "MULTI_GGX"  # the IR's default, Blender's too
    assert tuple(p["Emission Color"].default_value)[:3] == pytest.approx((1.0, 0.0, 0.0))
    wire = [n for n in nt.nodes if n.bl_idname == "ShaderNodeWireframe"]
    assert len(wire) == 1 and wire[0].inputs["Size"].default_value == pytest.approx(0.01)
    assert not wire[0].use_pixel_size
    assert any(n.bl_idname == "ShaderNodeOutputAOV" and n.aov_name == "bf_albedo" for n in nt.nodes)
    g = [
        n
        for n in _obj(bpy, "g").material_slots[0].material.node_tree.nodes
        if n.bl_idname in ("ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic")
    ][0]
    assert g.distribution == "BECKMANN" and g.inputs["Roughness"].default_value == pytest.approx(0.1)
    me = _obj(bpy, "s").data
    assert me.has_custom_normals and len(me.vertices) > 1000  # the IR's shared sphere tessellation


def test_principled_distribution_reaches_the_node(cycles, bpy):
    scene = bf.Scene()
    for tag, dist in (("single", "ggx"), ("multi", "MULTI_GGX")):
        scene.renderables.add_sphere_nurbs(
            0.5, bf.PrincipledBSDFMaterial(distribution=dist), bf.UniformColors((0.5, 0.5, 0.5)), tag=tag
        )
    scene.set_perspective_camera((16, 16), fov_x=0.8, translation=(0, 0, 5))
    cycles.translate(scene, resolve_settings())
    for tag, want in (("single", "GGX"), ("multi", "MULTI_GGX")):
        nodes = _obj(bpy, tag).material_slots[0].material.node_tree.nodes
        assert [n.distribution for n in nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"] == [want]


def test_identical_primitives_share_one_mesh(cycles, bpy):
    scene = bf.Scene()
    for i in range(5):
        scene.renderables.add_sphere_nurbs(
            0.2, bf.DiffuseMaterial(), bf.UniformColors((i / 5, 0, 0)), tag=f"s{i}", translation=(i, 0, 0)
        )
    scene.renderables.add_sphere_nurbs(0.3, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)), tag="big")
    scene.renderables.add_cube_mesh(
        1.0,
        [bf.DiffuseMaterial(), bf.PlasticMaterial()],
        [bf.UniformColors((1, 0, 0)), bf.UniformColors((0, 1, 0))],
        faces_material=[0, 1, 0, 1, 0, 1],
        tag="c",
    )
    scene.set_perspective_camera(
        (16, 16), fov_x=0.8, translation=(0, -5, 0), rotation_mode="look_at", rotation=(0, 0, 0)
    )
    cycles.translate(scene, resolve_settings())
    small = {_obj(bpy, f"s{i}").data.as_pointer() for i in range(5)}
    assert len(small) == 1 and _obj(bpy, "big").data.as_pointer() not in small
    cols = [
        tuple(
            _obj(bpy, f"s{i}")
            .material_slots[0]
            .material.node_tree.nodes["Principled BSDF"]
            .inputs["Base Color"]
            .default_value
        )[0]
        for i in range(5)
    ]
    assert len(set(cols)) == 5  # one material per object (object-linked slots)
    c = _obj(bpy, "c")
    mi = np.zeros(12, dtype=np.int32)
    c.data.polygons.foreach_get("material_index", mi)
    assert sorted(set(mi.tolist())) == [0, 1] and len(c.material_slots) == 2
    r = bf.render(scene, backend=cycles, samples=1, outputs=("instance",))
    assert {1, 2, 6} <= set(np.unique(r.instance).tolist())  # shared-mesh objects keep their own ids


def test_pointclouds_native(cycles, bpy):
    scene = bf.Scene()
    rng = np.random.default_rng(0)
    p = rng.normal(size=(300, 3))
    sizes = rng.uniform(0.01, 0.05, 300)
    scene.renderables.add_pointcloud(
        p, bf.DiffuseMaterial(), bf.VertexColors(rng.uniform(size=(300, 3))), point_size=sizes, tag="a"
    )
    scene.renderables.add_pointcloud(p[:10], bf.DiffuseMaterial(), bf.UniformColors((1, 0, 0)), point_size=0.1, tag="b")
    scene.set_perspective_camera((32, 24), fov_x=0.8, translation=(0, 0, 5))
    cycles.translate(scene, resolve_settings())
    a, b = _obj(bpy, "a"), _obj(bpy, "b")
    assert len(a.data.vertices) == 300 and len(a.data.polygons) == 0
    r = np.zeros(300, dtype=np.float32)
    a.data.attributes["bf_radius"].data.foreach_get("value", r)
    np.testing.assert_allclose(r, sizes / 2, rtol=1e-6)
    mod = a.modifiers[0]
    kinds = {n.bl_idname for n in mod.node_group.nodes}
    assert {"GeometryNodeMeshToPoints", "GeometryNodeSetMaterial"} <= kinds
    setmat = next(n for n in mod.node_group.nodes if n.bl_idname == "GeometryNodeSetMaterial")
    assert setmat.inputs["Material"].default_value == a.data.materials[0]
    m2p = next(n for n in b.modifiers[0].node_group.nodes if n.bl_idname == "GeometryNodeMeshToPoints")
    assert m2p.inputs["Radius"].default_value == pytest.approx(0.05)
    ev = a.evaluated_get(bpy.context.evaluated_depsgraph_get())
    assert ev.data is not None


def test_camera_parameters(cycles, bpy):
    scene = bf.Scene()
    scene.renderables.add_cube_mesh(1.0, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))
    k = np.array([[150.0, 0, 83.3], [0, 185.0, 57.1], [0, 0, 1]])
    scene.set_perspective_camera((160, 120), K=k, translation=(1, 2, 3), near=0.2, far=50)
    cycles.translate(scene, resolve_settings())
    cam = bpy.context.scene.camera
    d, r = cam.data, bpy.context.scene.render
    assert d.type == "PERSP" and d.sensor_fit == "HORIZONTAL"
    assert d.lens == pytest.approx(150.0 * d.sensor_width / 160)
    assert (r.pixel_aspect_x, r.pixel_aspect_y) == pytest.approx((185 / 150, 1.0))
    assert d.shift_x == pytest.approx((80 - 83.8) / 160)
    assert d.shift_y == pytest.approx((57.6 - 60) * (1 / (185 / 150)) / 160)
    assert (d.clip_start, d.clip_end) == pytest.approx((0.2, 50))
    np.testing.assert_allclose(np.array(cam.matrix_world), scene.camera.matrix_world, atol=1e-6)
    scene.set_orthographic_camera((64, 32), ortho_scale=3.0, translation=(0, 0, 4))
    cycles.translate(scene, resolve_settings())
    d = bpy.context.scene.camera.data
    assert d.type == "ORTHO" and d.ortho_scale == pytest.approx(3.0)
    assert (r.resolution_x, r.resolution_y, r.pixel_aspect_x) == (64, 32, 1.0)


def test_lights_and_world(cycles, bpy):
    scene = testing.every_feature_scene()
    scene.lights.add_sun(2.0, angular_diameter=0.01, use_shadow=False, tag="sun2")
    scene.lights.set_background_light(0.7, (0.5, 0.5, 0.5))
    cycles.translate(scene, resolve_settings())
    lights = {o.name.split("_", 3)[-1]: o for o in bpy.data.objects if o.type == "LIGHT"}
    assert len(lights) == len(scene.lights)
    for light in scene.lights:
        d = lights[light.tag].data
        assert d.energy == pytest.approx(light.strength)
        assert not lights[light.tag].visible_camera
        assert d.use_shadow == light.use_shadow
        if d.type in ("POINT", "SPOT"):
            assert d.shadow_soft_size == pytest.approx(light.shadow_soft_size) and not d.use_soft_falloff
        if d.type == "SPOT":
            assert (d.spot_size, d.spot_blend) == pytest.approx((light.spot_size, light.spot_blend))
        if d.type == "AREA":
            assert d.normalize and (d.size, d.size_y) == pytest.approx(light.size)
            assert d.shape == {"rectangle": "RECTANGLE", "circle": "DISK"}[light.shape]
        if d.type == "SUN":
            assert d.angle == pytest.approx(light.angular_diameter)
    world = bpy.context.scene.world
    bgs = [n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeBackground"]
    assert len(bgs) == 1
    assert bgs[0].inputs["Strength"].default_value == pytest.approx(0.7)
    lin = bf.ir.lights.BackgroundLight(0.7, (0.5, 0.5, 0.5)).linear_color
    assert tuple(bgs[0].inputs["Color"].default_value)[:3] == pytest.approx(tuple(lin), abs=1e-6)
    scene.lights.remove_background_light() if hasattr(scene.lights, "remove_background_light") else None
    scene.lights.background = None
    scene.lights.revision += 1
    cycles.translate(scene, resolve_settings())
    bgs = [n for n in bpy.context.scene.world.node_tree.nodes if n.bl_idname == "ShaderNodeBackground"]
    assert all(b.inputs["Strength"].default_value == 0.0 for b in bgs)  # no 0.05 grey


def test_engine_settings_and_effects(cycles, bpy):
    scene = testing.plane_scene("sun")
    settings = resolve_settings("final", samples=17, seed=5, threads=1)
    cycles.translate(scene, settings)
    sc = bpy.context.scene
    cy = sc.cycles
    assert (sc.render.engine, cy.device, cy.samples, cy.seed) == ("CYCLES", "CPU", 17, 5)
    assert not cy.use_denoising and not cy.use_adaptive_sampling and not cy.use_animated_seed
    assert (cy.pixel_filter_type, cy.filter_width) == ("BOX", 1.0)
    assert cy.sample_clamp_indirect == 0 and cy.sample_clamp_direct == 0
    assert sc.view_settings.view_transform == "Standard" and sc.render.film_transparent
    assert (sc.render.threads_mode, sc.render.threads) == ("FIXED", 1)
    # a single diffuse plane: no glossy, transmission, caustics, transparency, indirect diffuse
    assert (cy.glossy_bounces, cy.transmission_bounces, cy.diffuse_bounces, cy.transparent_max_bounces) == (0, 0, 0, 0)
    assert not cy.caustics_reflective and not cy.caustics_refractive
    cycles.translate(scene, resolve_settings("preview", effects=False, pixel_filter="gaussian", adaptive=True))
    assert cy.use_denoising and cy.use_adaptive_sampling and cy.pixel_filter_type == "GAUSSIAN"
    assert cy.glossy_bounces == 4 and cy.max_bounces == 4
    assert cy.caustics_reflective and cy.caustics_refractive
    # caustics=False (final's caustics pilot): the switches off, the bounces kept
    cycles.translate(scene, resolve_settings("preview", effects=False, caustics=False))
    assert not cy.caustics_reflective and not cy.caustics_refractive and cy.glossy_bounces == 4


def test_incremental_updates_do_not_rebuild_meshes(cycles, bpy):
    scene = testing.bunny_scene((32, 32))
    cycles.translate(scene, resolve_settings())
    assert cycles._session.last_stats["new_scene"]
    me = _obj(bpy, "bunny").data
    ptr = me.as_pointer()
    scene.camera.translation = scene.camera.translation + 0.01
    scene.lights.add_point(10.0, translation=(0, 0, 1))
    cycles.translate(scene, resolve_settings())
    st = cycles._session.last_stats
    assert (st["new_scene"], st["built"], st["moved"], st["lights_rebuilt"]) == (False, 0, 0, True)
    assert _obj(bpy, "bunny").data.as_pointer() == ptr
    scene.renderables["ground"].translation = (0, 0, -0.1)
    cycles.translate(scene, resolve_settings())
    st = cycles._session.last_stats
    assert (st["built"], st["moved"]) == (0, 1)
    assert _obj(bpy, "ground").matrix_world.translation.z == pytest.approx(-0.1)
    scene.renderables["ground"].update_material(bf.PlasticMaterial())
    scene.renderables.remove("bunny")
    cycles.translate(scene, resolve_settings())
    st = cycles._session.last_stats
    assert (st["built"], st["removed"]) == (1, 1)


def test_clear_removes_every_datablock(bpy):
    from blendify_blender import session

    with CyclesBackend() as b:
        b.translate(testing.every_feature_scene(), resolve_settings())
        session.factory_reset()
        baseline = session.datablock_counts()
        b.render_scene(testing.every_feature_scene((16, 12)), resolve_settings(samples=1, outputs=("rgb", "albedo")))
        assert session.datablock_counts()["objects"] > 10
        b.clear()
        assert session.datablock_counts() == baseline


def test_engine_errors_become_render_errors(bpy):
    from blendify_blender import session

    with pytest.raises(RenderError, match="poll"), session.engine_errors("switching mode"):
        bpy.ops.object.mode_set(mode="EDIT")


def test_texture_without_uv_is_a_clear_error(cycles):
    scene = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    rough = bf.TextureMap(np.ones((2, 2), dtype=np.float32))
    scene.renderables.add_mesh(
        v, [[0, 1, 2]], bf.PrincipledBSDFMaterial(roughness_map=rough), bf.UniformColors((1, 1, 1)), tag="nouv"
    )
    scene.set_perspective_camera((16, 16), fov_x=0.8, translation=(0, 0, 5))
    with pytest.raises(InvalidSceneError, match="uv_map"):
        cycles.translate(scene, resolve_settings())


def test_unreadable_texture_file_is_a_clear_error(cycles, tmp_path):
    bad = tmp_path / "broken.png"
    bad.write_bytes(b"not a png")
    scene = testing.plane_scene("sun", resolution=(8, 8))
    # the IR reads files lazily; bypass its own check to reach Blender's loader
    tex = bf.FileTextureColors.__new__(bf.FileTextureColors)
    tex.texture_path, tex.uv_map, tex.color_space, tex.interpolation = (
        str(bad),
        bf.VertexUV(np.zeros((4, 2))),
        "srgb",
        "linear",
    )
    tex._cache = np.zeros((1, 1, 3), np.uint8)
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    scene.renderables.add_mesh(v, [[0, 1, 2, 3]], bf.DiffuseMaterial(), tex, tag="broken")
    with pytest.raises(InvalidSceneError, match="broken.png"):
        cycles.translate(scene, resolve_settings())


def test_equal_materials_with_uniform_colours_are_shared(cycles, bpy):
    scene = bf.Scene()
    for i in range(3):
        scene.renderables.add_cube_mesh(
            0.5, bf.DiffuseMaterial(), bf.UniformColors((0.2, 0.3, 0.4)), tag=f"a{i}", translation=(i, 0, 0)
        )
    scene.renderables.add_cube_mesh(0.5, bf.DiffuseMaterial(), bf.UniformColors((0.9, 0.3, 0.4)), tag="b")
    scene.renderables.add_cube_mesh(0.5, bf.PlasticMaterial(), bf.UniformColors((0.2, 0.3, 0.4)), tag="c")
    scene.set_perspective_camera(
        (16, 16), fov_x=0.8, translation=(0, -5, 0), rotation_mode="look_at", rotation=(0, 0, 0)
    )
    cycles.translate(scene, resolve_settings())
    mats = {t: _obj(bpy, t).material_slots[0].material.as_pointer() for t in ("a0", "a1", "a2", "b", "c")}
    assert mats["a0"] == mats["a1"] == mats["a2"]
    assert len({mats["a0"], mats["b"], mats["c"]}) == 3
    scene.renderables["a1"].update_material(bf.DiffuseMaterial(alpha=0.5))  # its own material now
    cycles.translate(scene, resolve_settings())
    assert (
        _obj(bpy, "a1").material_slots[0].material.as_pointer()
        != _obj(bpy, "a0").material_slots[0].material.as_pointer()
    )
    assert (
        _obj(bpy, "a0").material_slots[0].material.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value
        == 1.0
    )


def test_render_translates_again_when_another_translation_ran_in_between(cycles):
    """translate(a), translate(b), render(a) renders a (as when another thread translates in between)."""
    a = testing.plane_scene("sun", resolution=(8, 8))
    b = testing.pointcloud_scene(n=50, resolution=(8, 8))
    settings = resolve_settings(samples=1)
    ref = cycles.render(cycles.translate(a, settings), settings)
    native_a = cycles.translate(a, settings)
    assert not cycles._session.last_stats["new_scene"]
    cycles.translate(b, settings)
    r = cycles.render(native_a, settings)
    assert r.meta["translation"]["new_scene"]  # a was built again
    assert np.array_equal(r.rgba, ref.rgba)


def test_lights_world_and_environment_changes_rebuild_only_them(cycles, bpy):
    scene = testing.plane_scene("sun", resolution=(8, 8))
    env = scene.lights.set_environment_map(np.full((8, 16, 3), 0.5, np.float32))
    cycles.translate(scene, resolve_settings())
    mapping = next(n for n in bpy.context.scene.world.node_tree.nodes if n.bl_idname == "ShaderNodeMapping")
    assert tuple(mapping.inputs["Rotation"].default_value) == pytest.approx((0, 0, 0), abs=1e-6)
    env.quaternion = (np.cos(0.25), 0.0, 0.0, np.sin(0.25))  # 0.5 rad about z
    cycles.translate(scene, resolve_settings())
    st = cycles._session.last_stats
    assert (st["built"], st["lights_rebuilt"], st.get("world_rebuilt")) == (0, False, True)
    mapping = next(n for n in bpy.context.scene.world.node_tree.nodes if n.bl_idname == "ShaderNodeMapping")
    assert mapping.inputs["Rotation"].default_value[2] == pytest.approx(-0.5, abs=1e-5)
    next(iter(scene.lights)).strength = 5.0
    cycles.translate(scene, resolve_settings())
    st = cycles._session.last_stats
    assert (st["built"], st["lights_rebuilt"], st.get("world_rebuilt")) == (0, True, None)
