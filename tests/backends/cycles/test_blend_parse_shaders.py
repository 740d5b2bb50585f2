"""attach_blend parses more of what files use into the IR (for Mitsuba and pyrender) and says what it
approximates: Glass / Refraction, Add Shader with an Emission, other Mix / Add shaders, Glossy anisotropy,
image textures through a Mapping node, extension modes. The file is written by Blender itself."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from blendify_blender.blendfile import BlendAttachWarning, attach_blend

from blendify_core.ir.scene import Scene

#: shared by the scripts: Cycles, a square image, fixed samples, box filter, Standard view
SETTINGS = """
def settings(sc, size, spp):
    r, cy = sc.render, sc.cycles
    r.engine = "CYCLES"; r.resolution_x = r.resolution_y = size; r.resolution_percentage = 100
    cy.samples = spp; cy.use_denoising = False; cy.use_adaptive_sampling = False
    cy.pixel_filter_type = "BOX"; cy.filter_width = 1.0
    sc.view_settings.view_transform = "Standard"

def top_view(sc, x, grey):
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.type, cam.data.ortho_scale = "ORTHO", 1.0
    cam.location = (x, 0, 3)
    sc.collection.objects.link(cam)
    sc.camera = cam
    w = bpy.data.worlds.new("World")
    w.node_tree.nodes["Background"].inputs["Color"].default_value = (grey, grey, grey, 1)
    sc.world = w
"""

WRITE = (
    SETTINGS
    + """
import bpy, sys, json, math
dest, mode = sys.argv[1], sys.argv[2]
bpy.ops.wm.read_factory_settings(use_empty=True)
sc = bpy.context.scene

def obj(name, x):
    bpy.ops.mesh.primitive_plane_add(size=1, location=(x, 0, 0))
    ob = bpy.context.active_object
    ob.name = name
    m = bpy.data.materials.new(name + " mat")
    ob.data.materials.append(m)
    nt = m.node_tree
    out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
    p = next(n for n in nt.nodes if n.type == "BSDF_PRINCIPLED")
    return nt, out, p

nt, out, p = obj("Glass", 0)
g = nt.nodes.new("ShaderNodeBsdfGlass"); g.name = "My Glass"
g.inputs["Roughness"].default_value = 0.2; g.inputs["IOR"].default_value = 1.33
g.distribution = "GGX"
nt.links.new(g.outputs[0], out.inputs["Surface"])

nt, out, p = obj("Glowing", 2)
p.inputs["Base Color"].default_value = (0.2, 0.3, 0.4, 1)
e = nt.nodes.new("ShaderNodeEmission")
e.inputs["Color"].default_value = (1.0, 0.5, 0.25, 1); e.inputs["Strength"].default_value = 4.0
add = nt.nodes.new("ShaderNodeAddShader"); add.name = "Glow Add"
nt.links.new(p.outputs[0], add.inputs[0]); nt.links.new(e.outputs[0], add.inputs[1])
nt.links.new(add.outputs[0], out.inputs["Surface"])

nt, out, p = obj("Mixed", 4)
d = nt.nodes.new("ShaderNodeBsdfDiffuse"); d.name = "Matte"
gl = nt.nodes.new("ShaderNodeBsdfGlossy"); gl.name = "Shiny"
gl.inputs["Anisotropy"].default_value = 0.5
mix = nt.nodes.new("ShaderNodeMixShader"); mix.name = "Blend Mix"
mix.inputs[0].default_value = 0.3
nt.links.new(d.outputs[0], mix.inputs[1]); nt.links.new(gl.outputs[0], mix.inputs[2])
nt.links.new(mix.outputs[0], out.inputs["Surface"])

nt, out, p = obj("Tiled", 6)
img = bpy.data.images.new("grid", 4, 4)
img.pixels = [((i // 4 + i % 4) % 2) * 1.0 if k < 3 else 1.0 for i in range(16) for k in range(4)]
img.pack()
t = nt.nodes.new("ShaderNodeTexImage"); t.image = img; t.extension = "CLIP"
mp = nt.nodes.new("ShaderNodeMapping"); mp.vector_type = "POINT"
mp.inputs["Location"].default_value = (0.25, -0.5, 0.0)
mp.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(30))
mp.inputs["Scale"].default_value = (2.0, 3.0, 1.0)
tc = nt.nodes.new("ShaderNodeTexCoord")
nt.links.new(tc.outputs["UV"], mp.inputs["Vector"]); nt.links.new(mp.outputs[0], t.inputs["Vector"])
nt.links.new(t.outputs["Color"], p.inputs["Base Color"])
nt, out, p = obj("TexGlow", 8)
e = nt.nodes.new("ShaderNodeEmission")
t2 = nt.nodes.new("ShaderNodeTexImage"); t2.image = img
nt.links.new(t2.outputs["Color"], e.inputs["Color"])
add = nt.nodes.new("ShaderNodeAddShader"); add.name = "Tex Add"
nt.links.new(e.outputs[0], add.inputs[0]); nt.links.new(p.outputs[0], add.inputs[1])
nt.links.new(add.outputs[0], out.inputs["Surface"])
if mode == "render":  # a camera over the tiled plane, a white world, REPEAT (what the IR reads)
    t.extension = "REPEAT"
    t.interpolation = "Closest"
    top_view(sc, 6, 1.0)
    settings(sc, 40, 16)
bpy.ops.wm.save_as_mainfile(filepath=dest)
print(json.dumps({"ok": True}))
"""
)


@pytest.fixture(scope="module")
def attached(tmp_path_factory, bpy_script):
    path = tmp_path_factory.mktemp("shaders") / "shaders.blend"
    bpy_script(WRITE, str(path), "")
    scene = Scene()
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        attach_blend(scene, path)
    msgs = [str(w.message) for w in rec if issubclass(w.category, BlendAttachWarning)]
    assert len(msgs) == 1
    return scene, msgs[0]


def test_glass_is_principled_transmission(attached, cycles):
    scene, msg = attached
    m = scene.renderables["Glass"].material
    assert (m.transmission_weight, m.metallic, m.distribution) == (1.0, 0.0, "GGX")
    assert m.roughness == pytest.approx(0.2) and m.ior == pytest.approx(1.33)
    assert "My Glass" not in msg  # white glass: nothing approximated


def test_add_shader_with_emission_is_the_emission(attached, cycles):
    scene, msg = attached
    m = scene.renderables["Glowing"].material
    emitted = np.asarray(m.linear("emission_color")[:3]) * m.emission_strength
    np.testing.assert_allclose(emitted, [4.0, 2.0, 1.0], rtol=1e-6)
    assert "Glow Add" not in msg


def test_add_shader_with_a_textured_emission_keeps_the_surface(attached, cycles):
    scene, msg = attached
    m = scene.renderables["TexGlow"].material
    assert m.emission_strength == 0.0 and m.metallic == 0.0  # the Principled surface, not a light
    assert "Tex Add (Emission + Principled BSDF) approximated by Principled BSDF alone" in msg


def test_other_mixes_and_anisotropy_are_named(attached, cycles):
    scene, msg = attached
    m = scene.renderables["Mixed"].material
    assert m.specular_ior == 0.0  # the Diffuse side (factor 0.3 < 0.5)
    assert "Blend Mix (factor 0.3) of Matte and Shiny approximated by one of them" in msg
    # the mix picked the matte side, so the glossy's anisotropy was never parsed: nothing said about it
    assert "Shiny anisotropy" not in msg


def test_mapping_node_transforms_the_uvs(attached, cycles):
    scene, msg = attached
    r = scene.renderables["Tiled"]
    uv = np.asarray(r.colors.uv_map.data, dtype=np.float64)
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    a = np.array([[c, -s], [s, c]]) @ np.diag([2.0, 3.0])
    base = np.asarray(r.vertices)[np.asarray(r.faces)][..., :2] + 0.5  # the plane's own UVs: its x, y + 0.5
    np.testing.assert_allclose(r.triangle_uvs(), uv, atol=1e-6)  # the mesh reads the texture's mapped UVs
    np.testing.assert_allclose(uv, base @ a.T + [0.25, -0.5], atol=1e-6)
    assert "image extension CLIP read as REPEAT" in msg


def test_mapping_node_renders_like_blender(tmp_path: Path, bpy_script, blender_render, cycles):
    """The IR parse of a texture through a Mapping node, rendered by Cycles from the IR, matches Blender's
    render of the file; without the mapping it would not."""
    import blendify_core as bf
    from blendify_core.ir.colors import FacesUV, FileTextureColors

    path = tmp_path / "tiled.blend"
    bpy_script(WRITE, str(path), "render")
    _info, ref = blender_render(path, tmp_path / "ref.exr")
    scene = Scene()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BlendAttachWarning)
        att = attach_blend(scene, path, with_camera=True, render_settings=True)
    for tag in ("Glass", "Glowing", "Mixed", "TexGlow"):
        scene.renderables.remove(scene.renderables[tag])
    tiled = scene.renderables["Tiled"]
    tiled.material.roughness = float(tiled.material.roughness)  # an IR edit: Cycles renders the IR parse
    settings = {**att.render_settings, "outputs": ("rgba",)}

    def render() -> np.ndarray:
        return np.asarray(bf.render(scene, backend="cycles", cycles_settings=att.cycles_settings, **settings).rgba)

    img = render()
    assert ref.shape == img.shape == (40, 40, 4)
    err = np.abs(img - ref)[..., :3].mean() / ref[..., :3].mean()
    assert err < 0.03
    # the same texture on the plane's own UVs (no mapping): a different picture, so the check can tell
    c = tiled.colors
    v = np.asarray(tiled.vertices)[np.asarray(tiled.faces)][..., :2] + 0.5
    plain = scene.renderables.add_mesh(
        vertices=tiled.vertices,
        faces=tiled.faces,
        material=tiled.material,
        colors=FileTextureColors(c.texture_path, FacesUV(v), color_space=c.color_space, interpolation="closest"),
        uv_map=FacesUV(v),
        rotation_mode="rotmat",
        rotation=tiled.rotation_matrix,
        translation=tiled.translation,
    )
    scene.renderables.remove(tiled)
    unmapped = render()
    assert plain.uv_map is not None
    assert np.abs(unmapped - ref)[..., :3].mean() / ref[..., :3].mean() > 5 * err + 0.05


BUMP_WRITE = (
    SETTINGS
    + """
import bpy, sys, json, math
dest, mode = sys.argv[1], (sys.argv[2] if len(sys.argv) > 2 else "")
bpy.ops.wm.read_factory_settings(use_empty=True)
sc = bpy.context.scene
bpy.ops.mesh.primitive_plane_add(size=1)
ob = bpy.context.active_object
ob.name = "Bumpy"
m = bpy.data.materials.new("Bumpy mat")
ob.data.materials.append(m)
nt = m.node_tree
p = next(n for n in nt.nodes if n.type == "BSDF_PRINCIPLED")
p.inputs["Roughness"].default_value = 0.6
wave = nt.nodes.new("ShaderNodeTexWave")
wave.inputs["Scale"].default_value = 3.0
bump = nt.nodes.new("ShaderNodeBump"); bump.name = "Ridges"
bump.inputs["Strength"].default_value = 1.0
nt.links.new(wave.outputs["Fac"], bump.inputs["Height"])
nt.links.new(bump.outputs["Normal"], p.inputs["Normal"])
if mode == "maps":  # no bump; metallic and roughness from procedural textures instead
    nt.links.remove(p.inputs["Normal"].links[0])
    chk = nt.nodes.new("ShaderNodeTexChecker"); chk.name = "Metal Tiles"
    chk.inputs["Scale"].default_value = 3.0
    chk.inputs["Color1"].default_value = (1, 1, 1, 1); chk.inputs["Color2"].default_value = (0, 0, 0, 1)
    grad = nt.nodes.new("ShaderNodeTexGradient")
    nt.links.new(chk.outputs["Fac"], p.inputs["Metallic"])
    nt.links.new(grad.outputs["Fac"], p.inputs["Roughness"])
    p.inputs["Base Color"].default_value = (0.9, 0.6, 0.3, 1)
if mode in ("object", "world"):  # no bump; an object/world-space Normal Map of a constant tilted normal
    nt.links.remove(p.inputs["Normal"].links[0])
    nmap = nt.nodes.new("ShaderNodeNormalMap"); nmap.name = "Tilt"
    nmap.space = mode.upper()
    rgb = nt.nodes.new("ShaderNodeRGB")
    n = (math.sin(0.7), 0.0, math.cos(0.7))  # tilted 40 degrees towards +x
    rgb.outputs[0].default_value = (*(0.5 * c + 0.5 for c in n), 1.0)
    nt.links.new(rgb.outputs[0], nmap.inputs["Color"])
    nt.links.new(nmap.outputs["Normal"], p.inputs["Normal"])
    ob.rotation_euler = (0.0, 0.0, math.radians(30))  # object and world space differ
if mode == "floats":  # no bump; Coat Weight from a Checker, IOR from a Value node, Alpha from a Gradient
    nt.links.remove(p.inputs["Normal"].links[0])
    chk = nt.nodes.new("ShaderNodeTexChecker"); chk.name = "Coat Tiles"
    chk.inputs["Scale"].default_value = 2.0
    chk.inputs["Color1"].default_value = (1, 1, 1, 1); chk.inputs["Color2"].default_value = (0, 0, 0, 1)
    nt.links.new(chk.outputs["Fac"], p.inputs["Coat Weight"])
    val = nt.nodes.new("ShaderNodeValue"); val.outputs[0].default_value = 1.8
    nt.links.new(val.outputs[0], p.inputs["IOR"])
    grad = nt.nodes.new("ShaderNodeTexGradient")
    nt.links.new(grad.outputs["Fac"], p.inputs["Emission Strength"])
    rgb = nt.nodes.new("ShaderNodeRGB"); rgb.outputs[0].default_value = (2.0, 1.0, 0.5, 1.0)
    nt.links.new(rgb.outputs[0], p.inputs["Emission Color"])
    tint = nt.nodes.new("ShaderNodeTexChecker"); tint.inputs["Scale"].default_value = 2.0
    tint.inputs["Color1"].default_value = (1, 0, 0, 1); tint.inputs["Color2"].default_value = (0, 0, 1, 1)
    nt.links.new(tint.outputs["Color"], p.inputs["Sheen Tint"])
sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
sun.data.energy = 3.0
sun.rotation_euler = (math.radians(60), 0, math.radians(90))
sc.collection.objects.link(sun)
top_view(sc, 0, 0.05)
settings(sc, 48, 32)
bpy.ops.wm.save_as_mainfile(filepath=dest)
print(json.dumps({"ok": True}))
"""
)


def _ir_render(path: Path, ref: np.ndarray, edit: str, **kw) -> tuple[float, object, str]:
    """Attach ``path``, touch the material parameter ``edit`` of 'Bumpy' (an IR edit: Cycles renders the IR
    parse), render; (mean relative error against ``ref``, the IR material, the warning)."""
    import blendify_core as bf

    scene = Scene()
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        att = attach_blend(scene, path, with_camera=True, render_settings=True, **kw)
    msg = " ".join(str(w.message) for w in rec if issubclass(w.category, BlendAttachWarning))
    bumpy = scene.renderables["Bumpy"]
    setattr(bumpy.material, edit, float(getattr(bumpy.material, edit)))
    settings = {**att.render_settings, "outputs": ("rgba",)}
    img = np.asarray(bf.render(scene, backend="cycles", cycles_settings=att.cycles_settings, **settings).rgba)
    return float(np.abs(img - ref)[..., :3].mean() / ref[..., :3].mean()), bumpy.material, msg


def test_bump_is_baked_into_a_normal_map(tmp_path: Path, bpy_script, blender_render, cycles):
    """A Bump node driven by a procedural texture becomes a baked tangent-space normal map in the IR (said
    so): rendered from the IR, the ridges light like Blender's render of the file; without it, flat."""

    path = tmp_path / "bumpy.blend"
    bpy_script(BUMP_WRITE, str(path))
    _info, ref = blender_render(path, tmp_path / "ref.exr")

    err, material, msg = _ir_render(path, ref, "roughness", bake_resolution=128)
    assert material.normal_map is not None
    assert "normal (tangent-space normal map) from a ShaderNodeBump node baked to a 128x128 image" in msg
    err_flat, material, msg = _ir_render(path, ref, "roughness", bake_resolution=None)
    assert material.normal_map is None and "Normal input from a ShaderNodeBump node not parsed" in msg
    assert err < 0.5 * err_flat, (err, err_flat)


def test_procedural_roughness_and_metallic_are_baked_into_maps(tmp_path: Path, bpy_script, blender_render, cycles):
    """Metallic from a Checker and Roughness from a Gradient become baked roughness / metallic maps (said
    so); rendered from the IR they light like Blender's render of the file, better than the default values."""
    from blendify_core.ir.colors import TextureMap

    path = tmp_path / "maps.blend"
    bpy_script(BUMP_WRITE, str(path), "maps")
    _info, ref = blender_render(path, tmp_path / "ref.exr")

    err, material, msg = _ir_render(path, ref, "ior", bake_resolution=64)
    assert isinstance(material.metallic_map, TextureMap) and isinstance(material.roughness_map, TextureMap)
    assert "metallic_map from a ShaderNodeTexChecker node baked to a 64x64 image" in msg
    assert "roughness_map from a ShaderNodeTexGradient node baked" in msg
    err_default, material, _msg = _ir_render(path, ref, "ior", bake_resolution=None)
    assert material.metallic_map is None
    assert err < 0.5 * err_default, (err, err_default)


@pytest.mark.parametrize("space", ["object", "world"])
def test_object_and_world_space_normal_maps_are_baked(space, tmp_path: Path, bpy_script, blender_render, cycles):
    """An object- or world-space Normal Map node (a constant tilted normal, the plane turned so the spaces
    differ) becomes a baked tangent-space normal map in the IR (said so): rendered from the IR it lights like
    Blender's render of the file, much closer than the flat normal the IR had before."""
    path = tmp_path / f"{space}.blend"
    bpy_script(BUMP_WRITE, str(path), space)
    _info, ref = blender_render(path, tmp_path / "ref.exr")

    err, material, msg = _ir_render(path, ref, "roughness", bake_resolution=32)
    assert material.normal_map is not None
    assert f"normal (tangent-space normal map) from a ShaderNodeNormalMap ({space}-space) node baked" in msg
    err_flat, material, msg = _ir_render(path, ref, "roughness", bake_resolution=None)
    assert material.normal_map is None and f"{space}-space normal map not parsed" in msg
    assert err < 0.02 and err < 0.25 * err_flat, (err, err_flat)


def test_procedural_float_inputs_without_an_ir_map_take_the_baked_mean(tmp_path: Path, bpy_script, cycles):
    """Inputs the IR holds as one value (Coat Weight from a Checker, IOR from a Value node, Emission Strength
    from a Gradient; the colours Emission Color from an RGB node brighter than 1 and Sheen Tint from a Checker)
    are baked through the same path as the maps: the IR takes the bake's mean over the surface, named in the
    warning; without a baker their default values (noted as before)."""
    path = tmp_path / "floats.blend"
    bpy_script(BUMP_WRITE, str(path), "floats")
    scene = Scene()
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        attach_blend(scene, path, with_camera=True, bake_resolution=32)
    msg = " ".join(str(w.message) for w in rec if issubclass(w.category, BlendAttachWarning))
    m = scene.renderables["Bumpy"].material
    assert m.ior == pytest.approx(1.8, abs=1e-4)
    assert m.coat_weight == pytest.approx(0.5, abs=0.05)  # a 2x2 checker: half the surface
    # a linear ramp across the plane (0.5), times 2: the baked emission colour (2, 1, 0.5) as a [0, 1] colour
    assert m.emission_strength == pytest.approx(1.0, abs=0.1)
    assert m.emission_color == pytest.approx((1.0, 0.5, 0.25, 1.0), abs=1e-3)
    assert m.sheen_tint == pytest.approx((0.5, 0.0, 0.5, 1.0), abs=0.05)  # half red, half blue
    assert "sheen_tint from a ShaderNodeTexChecker node baked" in msg
    for param, node in (("ior", "ShaderNodeValue"), ("coat_weight", "ShaderNodeTexChecker")):
        assert f"{param} from a {node} node baked with Cycles' baker (32x32); the IR holds one value" in msg
    assert "mean over the surface, 1.8, used" in msg
    plain = Scene()
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        attach_blend(plain, path, with_camera=True, bake_resolution=None)
    msg = " ".join(str(w.message) for w in rec if issubclass(w.category, BlendAttachWarning))
    m = plain.renderables["Bumpy"].material
    assert m.coat_weight == 0.0 and "Principled input 'Coat Weight' is driven by nodes, used its default value" in msg
