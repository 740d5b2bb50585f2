"""attach_blend on files Blender wrote itself: what used to be dropped silently is parsed or named.

Each file is written by bpy in a fresh interpreter (as a third-party file would be): the Principled
``distribution``, the Diffuse BSDF's roughness, a tinted Transparent BSDF in a Mix Shader, the render
settings, datablock names that collide with the session's, and bpy's current main file.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from blendify_blender.blendfile import BlendAttachWarning, attach_blend

from blendify_core.ir.scene import Scene

WRITE = """
import bpy, sys, json, math
out, mode = sys.argv[1:3]
bpy.ops.wm.read_factory_settings(use_empty=True)
sc = bpy.context.scene
sc.render.engine = "CYCLES"
sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 48, 36, 100
sc.view_settings.view_transform = "Standard"
cy = sc.cycles
cy.device = "CPU"; cy.samples = 32; cy.seed = 2; cy.use_denoising = False; cy.use_adaptive_sampling = False
cy.pixel_filter_type, cy.filter_width = "BOX", 1.0
cy.blur_glossy = 0.0
cy.max_bounces = 4
sc.render.film_transparent = True

def material(name, kind, **kw):
    m = bpy.data.materials.new(name)
    nt = m.node_tree
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    p = next(n for n in nt.nodes if n.type == "BSDF_PRINCIPLED")
    if kind == "metal":
        p.distribution = kw["distribution"]
        p.inputs["Base Color"].default_value = (0.9, 0.6, 0.3, 1.0)
        p.inputs["Metallic"].default_value = 1.0
        p.inputs["Roughness"].default_value = 0.8
    elif kind == "diffuse":
        nt.nodes.remove(p)
        d = nt.nodes.new("ShaderNodeBsdfDiffuse")
        d.inputs["Color"].default_value = (0.7, 0.7, 0.7, 1.0)
        d.inputs["Roughness"].default_value = kw["roughness"]
        nt.links.new(d.outputs[0], out.inputs["Surface"])
        if kw.get("checker"):
            c = nt.nodes.new("ShaderNodeTexChecker")
            c.inputs["Scale"].default_value = 4.0
            nt.links.new(c.outputs["Color"], d.inputs["Color"])
    elif kind == "tinted":
        t = nt.nodes.new("ShaderNodeBsdfTransparent")
        t.name = "Red Glass"
        t.inputs["Color"].default_value = (1.0, 0.2, 0.2, 1.0)
        mix = nt.nodes.new("ShaderNodeMixShader")
        mix.inputs[0].default_value = 0.6
        nt.links.new(p.outputs[0], mix.inputs[1])
        nt.links.new(t.outputs[0], mix.inputs[2])
        nt.links.new(mix.outputs[0], out.inputs["Surface"])
    return m

def add(name, mesh_op, mat, **kw):
    mesh_op(**kw)
    ob = bpy.context.active_object
    ob.name = name
    ob.data.materials.append(mat)
    return ob

floor = material("Rough Floor", "diffuse", roughness=1.0, checker=mode == "settings")
add("Floor", bpy.ops.mesh.primitive_plane_add, floor, size=6)
s = add("Ball", bpy.ops.mesh.primitive_uv_sphere_add, material("Material", "metal", distribution="GGX"),
        radius=0.8, location=(0, 0, 0.8), segments=48, ring_count=24)
bpy.ops.object.shade_smooth()
if mode == "settings":
    add("Box", bpy.ops.mesh.primitive_cube_add, material("Tinted", "tinted"), size=0.5, location=(1.5, 0, 0.25))
    cy.sample_clamp_indirect = 5.0
    cy.max_bounces, cy.diffuse_bounces = 3, 2
    cy.pixel_filter_type, cy.filter_width = "GAUSSIAN", 1.5
    sc.render.film_transparent = False
light = bpy.data.lights.new("Key", "SUN")
light.energy = 3.0
lo = bpy.data.objects.new("Key", light)
lo.rotation_euler = (math.radians(35), 0, math.radians(30))
sc.collection.objects.link(lo)
cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
cam.location = (0, -6, 3.2)
cam.rotation_euler = (math.radians(64), 0, 0)
sc.collection.objects.link(cam)
sc.camera = cam
w = bpy.data.worlds.new("World")
w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.2, 0.2, 0.25, 1)
sc.world = w
bpy.ops.wm.save_as_mainfile(filepath=out)
print(json.dumps({"ok": True}))
"""

ATTACH_MAIN = """
import bpy, sys, json, warnings
from blendify_core.ir.scene import Scene
from blendify_blender.blendfile import attach_blend
bpy.ops.wm.open_mainfile(filepath=sys.argv[1])
bpy.data.objects["Ball"].location.x += 1.0  # an unsaved change
with warnings.catch_warnings(record=True) as rec:
    warnings.simplefilter("always")
    added = attach_blend(Scene(), bpy.data.filepath)
print(json.dumps({"tags": sorted(r.tag for r in added), "warnings": [str(w.message) for w in rec],
                  "main": bpy.data.filepath, "objects": len(bpy.data.objects)}))
"""


@pytest.fixture(scope="module")
def files(tmp_path_factory, bpy_script) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("silent")
    out = {}
    for mode in ("plain", "settings"):
        out[mode] = d / f"{mode}.blend"
        bpy_script(WRITE, str(out[mode]), mode)
    return out


def _attach(path: Path, **kw):
    scene = Scene()
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        added = attach_blend(scene, path, with_camera=True, **kw)
    msgs = [str(w.message) for w in rec if issubclass(w.category, BlendAttachWarning)]
    assert len(msgs) <= 1
    return scene, added, (msgs[0] if msgs else "")


def test_distribution_and_diffuse_roughness_are_parsed(files, bpy):
    scene, added, msg = _attach(files["plain"])
    ball, floor = scene.renderables["Ball"], scene.renderables["Floor"]
    assert ball.material.distribution == "GGX"  # the file's, not the IR's default MULTI_GGX
    assert floor.material.diffuse_roughness == pytest.approx(1.0)
    assert floor.material.specular_ior == 0.0
    assert "material" not in msg  # nothing of the materials dropped (the bounce limits are named)


def test_tint_and_render_settings_are_named_with_the_files_own_names(files, bpy):
    # the session already has datablocks called like the file's: appended ones used to be renamed 'Material.001'
    mine = [bpy.data.materials.new(n) for n in ("Tinted", "Red Glass")]
    assert mine[0].name == "Tinted"
    names, pointers = [m.name for m in mine], [m.as_pointer() for m in mine]
    try:
        scene, added, msg = _attach(files["settings"])
        assert [m.name for m in mine] == names  # given back after the load
        assert [m.as_pointer() for m in mine] == pointers
    finally:
        bpy.data.batch_remove(mine)
    assert "material 'Tinted'" in msg and ".001" not in msg
    assert "Red Glass is tinted (1, 0.2, 0.2)" in msg
    assert "render settings not imported" in msg
    for what in ("clamp_indirect=5.0", "max_bounces=3", "transparent_background=False", "pixel_filter='gaussian'"):
        assert what in msg
    assert "diffuse_bounces=2 (bf.render: 12)" in msg
    assert scene.renderables["Box"].material.alpha == pytest.approx(0.4)  # the tint is the approximation
    lost = scene.attachments[-1].approximations  # the IR parse's limits: the tint, not the settings (bf.render's)
    assert any("Red Glass is tinted" in a for a in lost) and not any("render settings" in a for a in lost)
    assert added.render_settings is None and added.cycles_settings is None


def test_render_settings_are_imported_when_asked(files, bpy):
    _scene, added, msg = _attach(files["settings"], render_settings=True)
    assert "render settings not imported" not in msg
    rs = added.render_settings
    assert rs == {
        "samples": 32,
        "seed": 2,
        "max_bounces": 3,
        "diffuse_bounces": 2,
        "glossy_bounces": 4,
        "transmission_bounces": 12,
        "transparent_bounces": 8,
        "pixel_filter": "gaussian",
        "pixel_filter_width": 1.5,
        "clamp_direct": 0.0,
        "clamp_indirect": 5.0,
        "filter_glossy": 0.0,
        "adaptive": False,
        "denoise": False,
        "transparent_background": False,
    }
    cs = added.cycles_settings
    assert cs["volume_bounces"] == 0 and cs["caustics_reflective"] is True
    assert "pixel filter" not in msg


def test_cycles_settings_option_is_checked():
    from blendify_blender import CyclesBackend

    from blendify_core.errors import InvalidSceneError

    with pytest.raises(InvalidSceneError, match="unknown key 'bogus'"):
        CyclesBackend(cycles_settings={"bogus": 1})
    with pytest.raises(InvalidSceneError, match="expected a dict"):
        CyclesBackend(cycles_settings=[1])
    with pytest.raises(InvalidSceneError, match="isolate=True"):
        CyclesBackend(isolate=True, cycles_settings={"film_exposure": 1.0})


def test_cycles_only_settings_are_named_for_a_crosscheck(cycles):
    """Cycles settings of a file no other engine applies (caustics off, film exposure) are listed in the
    result's meta["engine_only_settings"]; noise-only ones (adaptive threshold, light tree) and blendify's
    own values are not."""
    import blendify_core as bf
    from blendify_core.testing import plane_scene

    own = {"caustics_reflective": False, "film_exposure": 2.0, "use_light_tree": False, "adaptive_threshold": 0.05}
    res = bf.render(plane_scene(resolution=(8, 6)), backend="cycles", samples=1, cycles_settings=own)
    assert res.meta["engine_only_settings"] == [
        "cycles.caustics_reflective=False (blendify: True)",
        "cycles.film_exposure=2.0 (blendify: 1.0)",
    ]
    same = {"caustics_reflective": True, "film_exposure": 1.0}
    res = bf.render(plane_scene(resolution=(8, 6)), backend="cycles", samples=1, cycles_settings=same)
    assert "engine_only_settings" not in res.meta


def test_attaching_the_current_main_file(files, bpy_script):
    res = bpy_script(ATTACH_MAIN, str(files["plain"]))
    assert res["tags"] == ["Ball", "Floor"]
    assert res["main"] == str(files["plain"])
    assert any("current main file and has unsaved changes" in w for w in res["warnings"])


def _region_means(img: np.ndarray) -> tuple[float, float]:
    """Mean RGB over the ball (centre) and the floor (bottom rows)."""
    h, w = img.shape[:2]
    ball = img[h // 3 : 2 * h // 3, 2 * w // 5 : 3 * w // 5, :3].mean()
    floor = img[-h // 6 :, :, :3].mean()
    return float(ball), float(floor)


def test_parsed_materials_render_like_blender(files, blender_render, tmp_path):
    """Rendered from the IR parse, the GGX metal and the rough diffuse floor match Blender's render of the
    file (region means within 4 %); with the IR defaults (MULTI_GGX, Lambertian) they would not."""
    import blendify_core as bf

    _info, ref = blender_render(files["plain"], tmp_path / "ref.exr")
    assert ref.shape == (36, 48, 4)
    scene, added, _msg = _attach(files["plain"], render_settings=True)
    scene.attachments.clear()  # render the IR parse itself, not the attached file
    settings = {**added.render_settings, "outputs": ("rgba",), "samples": 64}

    def render() -> np.ndarray:
        return np.asarray(bf.render(scene, backend="cycles", cycles_settings=added.cycles_settings, **settings).rgba)

    img = render()
    (rb, rf), (ib, i_f) = _region_means(ref), _region_means(img)
    assert abs(ib / rb - 1) < 0.04 and abs(i_f / rf - 1) < 0.04
    scene.renderables["Ball"].material.distribution = "MULTI_GGX"
    scene.renderables["Floor"].material.diffuse_roughness = 0.0
    (wb, wf) = _region_means(render())
    assert abs(wb / rb - 1) > 0.04 and abs(wf / rf - 1) > 0.04  # the check can tell


def test_cycles_renders_attached_objects_from_the_file(files, blender_render, tmp_path):
    """Objects as parsed render from the file itself (checker texture, tinted transparency: nodes the IR
    cannot carry): the same picture as Blender's own render of the file. An object edited through the IR
    renders from the IR; the rest stays from the file."""
    import blendify_core as bf

    _info, ref = blender_render(files["settings"], tmp_path / "ref.exr")
    scene, added, msg = _attach(files["settings"], render_settings=True)
    assert "Checker" in msg  # the IR parse lost it (the other backends say so)
    settings = {**added.render_settings, "outputs": ("rgba",)}

    def render():
        return bf.render(scene, backend="cycles", cycles_settings=added.cycles_settings, **settings)

    res = render()
    img = np.asarray(res.rgba)
    assert res.meta["translation"]["from_file"] == {"renderables": 3, "lights": 1, "world": True}
    assert np.abs(img - ref)[..., :3].mean() < 0.002 * ref[..., :3].mean()
    scene.renderables["Floor"].material.roughness = 0.5  # an edit through the IR
    res = render()
    assert res.meta["translation"]["from_file"]["renderables"] == 2
    edited = np.asarray(res.rgba)
    # the floor from the IR parse: its checker baked to an image (and the box still from the file): close, not equal
    err = np.abs(edited - ref)[..., :3].mean() / ref[..., :3].mean()
    assert 0 < err < 0.02
    scene.renderables.remove(scene.renderables["Floor"])
    res = render()
    assert res.meta["translation"]["from_file"]["renderables"] == 2  # the floor is not back from the file
    bottom = np.asarray(res.rgba)[-2:, :, :3]  # the file's world where the floor was, not its checker
    np.testing.assert_allclose(bottom, np.broadcast_to([0.2, 0.2, 0.25], bottom.shape), atol=0.01)


def test_other_backends_list_what_the_ir_parse_lost_and_crosscheck_says_limited(files):
    import blendify_core as bf
    from blendify_core.errors import UnsupportedFeatureError
    from blendify_core.registry import available_backends

    if not available_backends()["mitsuba"].available:
        pytest.skip(f"mitsuba unavailable: {available_backends()['mitsuba'].reason}")
    scene, _added, _msg = _attach(files["settings"], render_settings=True)
    res = bf.render(scene, backend="mitsuba", samples=4)
    lost = [a for a in res.meta["approximations"] if a.startswith("IR parse of settings.blend: ")]
    assert any("Checker" in a for a in lost) and any("Red Glass is tinted" in a for a in lost)
    plain = Scene()  # a scene Mitsuba renders exactly, but for the attached file's IR parse
    plain.renderables.add_cube_mesh(size=1.0, material=bf.DiffuseMaterial(), colors=bf.UniformColors((0.5,) * 3))
    plain.lights.add_sun(strength=3.0, angular_diameter=0.0)
    plain.set_perspective_camera(
        (32, 24), fov_x=0.8, translation=(0, -4, 0), rotation_mode="look_at", rotation=(0, 0, 0)
    )
    bf.render(plain, backend="mitsuba", samples=2, strict=True)
    plain.attachments.append(scene.attachments[0])
    with pytest.raises(UnsupportedFeatureError, match="renders the IR parse of .*settings.blend"):
        bf.render(plain, backend="mitsuba", samples=2, strict=True)
    # Cycles renders the file itself: nothing of the parse is an approximation there
    cyc = bf.render(scene, backend="cycles", samples=4)
    assert not any(a.startswith("IR parse of") for a in cyc.meta.get("approximations", []))
    rep = bf.crosscheck(scene, backends=("cycles", "mitsuba"), outputs=("rgb",), samples=8, passes=1)
    assert set(rep.limited) == {("cycles", "mitsuba")} and not rep.pairs
    assert rep.limited[("cycles", "mitsuba")] == sorted(lost)
    assert "LIMITED BY THE IR" in rep.summary()
    # with the albedo output Cycles renders the IR parse too: the pair is judged again
    cyc_albedo = bf.render(scene, backend="cycles", samples=4, outputs=("rgb", "albedo"))
    assert cyc_albedo.meta["translation"]["from_file"]["renderables"] == 0
    assert sorted(a for a in cyc_albedo.meta["approximations"] if a.startswith("IR parse of")) == sorted(lost)


def test_procedural_colour_is_baked_for_the_ir(files, blender_render, tmp_path):
    """The floor's Checker texture becomes a baked image texture in the IR (said so); rendered from the IR
    by Cycles, the floor matches Blender's render of the file; unbaked (bake_resolution=None) it would not."""
    import blendify_core as bf
    from blendify_core.ir.colors import TextureColors, UniformColors

    _info, ref = blender_render(files["settings"], tmp_path / "ref.exr")
    floor_rows = slice(-8, None)

    def floor_error(**kw) -> tuple[float, object, str]:
        scene, added, msg = _attach(files["settings"], render_settings=True, **kw)
        floor = scene.renderables["Floor"]
        floor.material.roughness = float(floor.material.roughness)  # an IR edit: rendered from the IR
        settings = {**added.render_settings, "outputs": ("rgba",)}
        img = np.asarray(bf.render(scene, backend="cycles", cycles_settings=added.cycles_settings, **settings).rgba)
        err = float(np.abs(img - ref)[floor_rows, :, :3].mean() / ref[floor_rows, :, :3].mean())
        return err, floor.colors, msg

    err, colors, msg = floor_error(bake_resolution=64)
    assert isinstance(colors, TextureColors) and colors.texture.shape[:2] == (64, 64)
    np.testing.assert_allclose(np.unique(np.round(colors.texture, 2)), [0.2, 0.8])  # the checker's two colours
    assert "Color: colour from a ShaderNodeTexChecker node baked to a 64x64 image" in msg
    assert err < 0.02
    err_default, colors, msg = floor_error(bake_resolution=None)
    assert isinstance(colors, UniformColors) and "used its default value" in msg
    assert err_default > 0.1
