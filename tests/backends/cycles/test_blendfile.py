"""Tests of .blend files on the Cycles backend (``blendify_blender.blendfile``): attach never runs Python
embedded in a file, bad paths give clear errors, IR -> export_blend -> attach_blend round-trips, and a
hand-built .blend (every area-light shape, an off-centre principal point, modifiers, colour attributes,
a packed texture) parses correctly.

Test .blend files are built at test time in a subprocess (``python -c`` with bpy), so this process's bpy
session is never reset by the fixtures.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

if importlib.util.find_spec("bpy") is None:  # pragma: no cover - depends on the environment
    print("tests/backends/cycles/test_blendfile.py: skipped, the 'bpy' package is not installed")
    pytest.skip("the 'bpy' package (Blender as a module) is not installed", allow_module_level=True)

from blendify_blender.blendfile import BlendAttachWarning, attach_blend, blender_camera_intrinsics
from blendify_blender.export import export_blend

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.colors import (
    FacesUV,
    FileTextureColors,
    NormalMap,
    TextureColors,
    TextureMap,
    UniformColors,
    VertexColors,
    VertexUV,
)
from blendify_core.ir.materials import (
    DiffuseMaterial,
    GlossyBSDFMaterial,
    PlasticWireframeMaterial,
    PrincipledBSDFMaterial,
    PrincipledBSDFWireframeMaterial,
)
from blendify_core.ir.scene import Scene

pytestmark = pytest.mark.cycles


# ---------------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------------


def run_bpy_script(code: str, *args: str, timeout: float = 120.0) -> dict[str, Any]:
    """Run ``code`` with bpy in a fresh interpreter; returns the JSON object printed on its last line."""
    env = dict(os.environ)
    proc = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
    )
    if proc.returncode != 0:
        raise AssertionError(f"bpy script failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    return json.loads(lines[-1]) if lines else {}


def world_corners(r: Any) -> np.ndarray:
    """(F, 3, 3) world-space triangle corners of a mesh renderable."""
    v = r.vertices @ r.rotation_matrix.T + r.translation
    return v[r.faces]


def datablock_ids() -> set[tuple[str, str]]:
    import bpy

    out = set()
    for name in ("objects", "meshes", "materials", "images", "lights", "cameras", "worlds", "scenes", "texts"):
        out |= {(name, idb.name) for idb in getattr(bpy.data, name)}
    out |= {("libraries", lib.filepath) for lib in bpy.data.libraries}
    return out


# ---------------------------------------------------------------------------------------------------
# security
# ---------------------------------------------------------------------------------------------------

EVIL_SCRIPT = """
import bpy, sys, json
out, marker_text, marker_driver = sys.argv[1:4]
bpy.ops.wm.read_factory_settings(use_empty=True)
sc = bpy.context.scene
me = bpy.data.meshes.new("tri")
me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
ob = bpy.data.objects.new("Tri", me)
sc.collection.objects.link(ob)
txt = bpy.data.texts.new("evil.py")
txt.write(f"open({marker_text!r}, 'w').write('text block ran')\\n")
txt.use_module = True  # a registered text block: runs when the file is opened with auto-run allowed
fc = ob.driver_add("location", 0)
fc.driver.type = "SCRIPTED"
fc.driver.expression = f"(open({marker_driver!r}, 'w').write('driver ran') and 0) or 0.5"
mat = bpy.data.materials.new("m")  # a second driver hidden in a material's node tree
me.materials.append(mat)
fc2 = mat.node_tree.nodes["Principled BSDF"].inputs["Roughness"].driver_add("default_value")
fc2.driver.type = "SCRIPTED"
fc2.driver.expression = f"(open({marker_driver!r}, 'w').write('node driver ran') and 0) or 0.5"
bpy.ops.wm.save_as_mainfile(filepath=out)
print(json.dumps({"ok": True}))
"""

OPEN_WITH_AUTORUN = """
import bpy, sys, json
bpy.context.preferences.filepaths.use_scripts_auto_execute = True
bpy.ops.wm.open_mainfile(filepath=sys.argv[1])
bpy.context.view_layer.update()
print(json.dumps({"ok": True}))
"""


@pytest.fixture(scope="module")
def evil_blend(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    d = tmp_path_factory.mktemp("evil")
    path, m_text, m_driver = d / "evil.blend", d / "text_marker.txt", d / "driver_marker.txt"
    run_bpy_script(EVIL_SCRIPT, str(path), str(m_text), str(m_driver))
    return path, m_text, m_driver


def test_fixture_is_live_when_opened_as_main_file_with_autorun(evil_blend: tuple[Path, Path, Path], tmp_path: Path):
    """Sanity check of the fixture: Blender's own open_mainfile with auto-run DOES run both payloads."""
    path, m_text, m_driver = evil_blend
    copy = tmp_path / "copy.blend"
    copy.write_bytes(path.read_bytes())
    run_bpy_script(OPEN_WITH_AUTORUN, str(copy))
    assert m_text.exists() and m_driver.exists()
    m_text.unlink()
    m_driver.unlink()


def test_attaching_the_same_file_twice_lists_the_removed_drivers_both_times(evil_blend: tuple[Path, Path, Path]):
    """Issue 15: the second attach of the same .blend in one process gave an empty warning."""
    path = evil_blend[0]
    scene = Scene()
    for _ in range(2):
        with pytest.warns(BlendAttachWarning, match="Python driver") as rec:
            attach_blend(scene, path)
        assert str(rec[0].message).count("Python driver") == 2


def test_attach_never_runs_embedded_python(evil_blend: tuple[Path, Path, Path]):
    import bpy

    path, m_text, m_driver = evil_blend
    for m in (m_text, m_driver):
        if m.exists():
            m.unlink()
    prefs = bpy.context.preferences.filepaths
    old = prefs.use_scripts_auto_execute
    prefs.use_scripts_auto_execute = True  # the user's preferences ALLOW auto-run
    before = datablock_ids()
    try:
        scene = Scene()
        with pytest.warns(BlendAttachWarning, match="Python driver") as rec:
            added = attach_blend(scene, path)
        assert str(rec[0].message).count("Python driver") == 2
        assert prefs.use_scripts_auto_execute is True  # restored
        bpy.context.view_layer.update()  # any later evaluation must not run it either
    finally:
        prefs.use_scripts_auto_execute = old
    assert not m_text.exists(), "a registered text block ran"
    assert not m_driver.exists(), "a Python driver expression ran"
    assert [r.tag for r in added] == ["Tri"]
    np.testing.assert_allclose(world_corners(added[0])[0], [[0, 0, 0], [1, 0, 0], [0, 1, 0]], atol=1e-7)
    assert scene.attached_blends == (str(path.resolve()),)
    assert datablock_ids() == before  # nothing left in the bpy session
    with pytest.raises(InvalidSceneError, match="no camera"):
        attach_blend(Scene(), path, with_camera=True)
    with pytest.raises(InvalidSceneError, match="scene_name"):
        attach_blend(Scene(), path, scene_name="Nope")
    assert datablock_ids() == before


def test_append_blend_scenes_for_cycles_strips_python(evil_blend: tuple[Path, Path, Path]):
    """The raw-content helper the Cycles backend may use applies the same protections."""
    import bpy
    from blendify_blender.blendfile import append_blend_scenes
    from blendify_blender.blendfile.safety import all_ids

    path, m_text, m_driver = evil_blend
    prefs = bpy.context.preferences.filepaths
    old = prefs.use_scripts_auto_execute
    prefs.use_scripts_auto_execute = True
    before = set(all_ids(bpy))
    try:
        scenes, removed = append_blend_scenes(path)
        assert len(scenes) == 1 and sum("Python driver" in r for r in removed) == 2
        obj = next(o for o in scenes[0].objects if o.type == "MESH")
        assert obj.animation_data is None or len(obj.animation_data.drivers) == 0
        assert prefs.use_scripts_auto_execute is True
        with bpy.context.temp_override(scene=scenes[0], view_layer=scenes[0].view_layers[0]):
            bpy.context.evaluated_depsgraph_get().update()
    finally:
        prefs.use_scripts_auto_execute = old
        bpy.data.batch_remove([i for ptr, i in all_ids(bpy).items() if ptr not in before])
    assert not m_text.exists() and not m_driver.exists()


LINKED_SCRIPT = """
import bpy, sys, json
d = sys.argv[1]
bpy.ops.wm.read_factory_settings(use_empty=True)
me = bpy.data.meshes.new("tri")
me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
ob = bpy.data.objects.new("Linked", me)
bpy.context.scene.collection.objects.link(ob)
fc = ob.driver_add("location", 0)
fc.driver.type = "SCRIPTED"
fc.driver.expression = f"(open({d + '/linked_marker'!r}, 'w').write('x') and 0) or 0.5"
bpy.ops.wm.save_as_mainfile(filepath=d + "/lib.blend")
bpy.ops.wm.read_factory_settings(use_empty=True)
with bpy.data.libraries.load(d + "/lib.blend", link=True) as (src, dst):
    dst.objects = ["Linked"]
bpy.context.scene.collection.objects.link(dst.objects[0])
bpy.ops.wm.save_as_mainfile(filepath=d + "/main.blend")
print(json.dumps({"ok": True}))
"""


def test_attach_file_linking_another_library(tmp_path: Path):
    """A driver on data the file LINKS from another .blend is removed too (or the file refused)."""
    import bpy

    run_bpy_script(LINKED_SCRIPT, str(tmp_path))
    prefs = bpy.context.preferences.filepaths
    old = prefs.use_scripts_auto_execute
    prefs.use_scripts_auto_execute = True
    before = datablock_ids()
    try:
        scene = Scene()
        with pytest.warns(BlendAttachWarning, match="Python driver"):
            added = attach_blend(scene, tmp_path / "main.blend")
        bpy.context.view_layer.update()
    finally:
        prefs.use_scripts_auto_execute = old
    assert not (tmp_path / "linked_marker").exists()
    assert [r.tag for r in added] == ["Linked"]
    assert datablock_ids() == before  # the indirectly loaded library is gone as well


TWO_SCENES = """
import bpy, sys, json
bpy.ops.wm.read_factory_settings(use_empty=True)
a = bpy.context.scene
a.name = "A"
b = bpy.data.scenes.new("B")
for sc, name, n in ((a, "InA", 3), (b, "InB", 4)):
    me = bpy.data.meshes.new(name)
    me.from_pydata([(i, 0, 0) for i in range(n - 1)] + [(0, 1, 0)], [], [tuple(range(n))])
    sc.collection.objects.link(bpy.data.objects.new(name, me))
cam = bpy.data.objects.new("CamB", bpy.data.cameras.new("CamB"))
b.collection.objects.link(cam)
b.camera = cam
b.render.resolution_x, b.render.resolution_y = 40, 20
bpy.data.libraries.write(sys.argv[1], {a, b})
print(json.dumps({"ok": True}))
"""


def test_attach_chooses_a_scene(tmp_path: Path):
    path = tmp_path / "two.blend"
    run_bpy_script(TWO_SCENES, str(path))
    first = Scene()
    with pytest.warns(BlendAttachWarning, match="2 scenes"):
        added = attach_blend(first, path)
    assert [r.tag for r in added] == ["InA"] and added.scene_name == "A"
    second = Scene()
    added = attach_blend(second, path, scene_name="B", with_camera=True)
    assert [r.tag for r in added] == ["InB"] and second.camera.tag == "CamB"
    assert tuple(second.camera.resolution) == (40, 20)


def test_attach_bad_paths(tmp_path: Path):
    scene = Scene()
    missing = tmp_path / "missing.blend"
    with pytest.raises(InvalidSceneError, match="missing.blend"):
        attach_blend(scene, missing)
    not_blend = tmp_path / "notes.blend"
    not_blend.write_text("this is not a blend file\n")
    with pytest.raises(InvalidSceneError, match=r"notes\.blend.*not a \.blend file"):
        attach_blend(scene, not_blend)
    with pytest.raises(InvalidSceneError, match="directory"):
        attach_blend(scene, tmp_path)
    with pytest.raises(InvalidSceneError, match="path"):
        attach_blend(scene, 42)  # type: ignore[arg-type]
    with pytest.raises(InvalidSceneError, match="with_camera"):
        attach_blend(scene, not_blend, with_camera="yes")  # type: ignore[arg-type]
    assert len(scene.renderables) == 0 and scene.attached_blends == ()


# ---------------------------------------------------------------------------------------------------
# round trip IR -> .blend -> IR
# ---------------------------------------------------------------------------------------------------


def round_trip_scene(scale: float = 1.0, texture_file: Path | None = None) -> Scene:
    """Two meshes (vertex colours; texture + uniform with per-face materials), every light type and
    area shape, a background, and a camera with fx != fy and an off-centre principal point."""
    rng = np.random.default_rng(7)
    s = Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]], float)
    f = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [0, 2, 1], [0, 3, 2]])
    vc = rng.uniform(0, 1, (5, 4)).astype(np.float32)
    vc[:, 3] = 1
    s.renderables.add_mesh(
        v,
        f,
        PrincipledBSDFMaterial(roughness=0.3, metallic=0.2, coat_weight=0.1),
        VertexColors(vc),
        tag="pyramid",
        translation=(0.2, 0.1, 0.3),
        rotation_mode="eulerXYZ",
        rotation=(10, 20, 30),
    )
    tex = (rng.uniform(0, 1, (8, 8, 3)) * 255).astype(np.uint8)
    uv = FacesUV(rng.uniform(0, 1, (2, 3, 2)))
    s.renderables.add_mesh(
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) + (-1.5, -0.5, 0.0),
        [[0, 1, 2], [0, 2, 3]],
        [DiffuseMaterial(), PrincipledBSDFMaterial(metallic=1.0, roughness=0.2)],
        [TextureColors(tex, uv), UniformColors((0.2, 0.4, 0.6))],
        faces_material=[0, 1],
        tag="quad",
        smooth=True,
    )
    if texture_file is not None:
        from PIL import Image

        Image.fromarray((rng.uniform(0, 1, (4, 6, 3)) * 255).astype(np.uint8)).save(texture_file)
        s.renderables.add_mesh(
            [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
            [[0, 1, 2]],
            DiffuseMaterial(),
            FileTextureColors(texture_file, FacesUV([[[0, 0], [1, 0], [0, 1]]])),
            tag="filetex",
            translation=(0, 0, -1),
        )
        s.lights.set_environment_map(
            rng.uniform(0, 2, (8, 16, 3)).astype(np.float32),
            strength=0.5,
            rotation_mode="eulerXYZ",
            rotation=(0, 0, 30),
        )
    s.lights.add_point(50, shadow_soft_size=0.1, color=(1, 0.5, 0.2), translation=(0, 0, 4), tag="pt")
    s.lights.add_area(
        "ellipse", (1, 2), 30, translation=(1, 0, 4), rotation_mode="eulerXYZ", rotation=(10, 0, 0), tag="ell"
    )
    s.lights.add_area("circle", 1.5, 31, translation=(1, 0, 4), tag="disk")
    s.lights.add_area("rectangle", (1, 2), 32, translation=(1, 0, 4), tag="rect")
    s.lights.add_area("square", 0.5, 33, translation=(1, 0, 4), tag="sq")
    s.lights.add_spot(100, spot_size=0.7, spot_blend=0.1, translation=(0, 0, 3), tag="spot")
    s.lights.add_sun(4, translation=(0, 0, 3), rotation_mode="eulerXYZ", rotation=(20, 0, 0), tag="sun")
    s.lights.set_background_light(0.3, (0.5, 0.6, 0.7))
    k = np.array([[100.0, 0, 40.3], [0, 120.0, 25.2], [0, 0, 1]])  # fx != fy, off-centre principal point
    k[:2] *= scale
    s.set_perspective_camera(
        (round(80 * scale), round(60 * scale)),
        K=k,
        rotation_mode="look_at",
        rotation=(0, 0, 0),
        translation=(1.5, -2.0, 2.5),
        tag="cam",
    )
    return s


def test_export_attach_round_trip(tmp_path: Path):
    src = round_trip_scene(texture_file=tmp_path / "tex.png")
    cwd = os.getcwd()
    out = export_blend(src, tmp_path / "sub" / "scene.blend", samples=4)
    assert os.getcwd() == cwd
    assert out == (tmp_path / "sub" / "scene.blend").absolute() and out.is_file()
    assert sorted(p.name for p in out.parent.iterdir()) == ["scene.blend"]  # no .blend1, no temp file
    src_pixels = src.renderables["filetex"].colors.linear_rgba_image()
    (tmp_path / "tex.png").unlink()  # the texture is packed in the .blend

    dst = Scene()
    with warnings.catch_warnings():
        warnings.simplefilter("error", BlendAttachWarning)  # everything exported must parse
        added = attach_blend(dst, out, with_camera=True, texture_dir=tmp_path / "tex")
    assert [r.tag for r in added] == ["pyramid", "quad", "filetex"]
    ft = dst.renderables["filetex"].colors
    assert isinstance(ft, FileTextureColors) and ft.color_space == "srgb"
    np.testing.assert_allclose(ft.linear_rgba_image(), src_pixels, atol=1e-6)  # the PNG bytes came back
    env_a, env_b = src.lights.environment, dst.lights.environment
    assert env_b is not None and env_b.strength == pytest.approx(0.5)
    np.testing.assert_allclose(env_b.rotation_matrix, env_a.rotation_matrix, atol=1e-6)
    np.testing.assert_allclose(env_b.linear_rgb_image(), env_a.linear_rgb_image(), atol=1e-6)
    for a in src.renderables:
        if a.tag == "filetex":
            continue
        b = dst.renderables[a.tag]
        assert b.faces.shape == a.faces.shape
        np.testing.assert_allclose(world_corners(b), world_corners(a), atol=1e-5)
        assert b.smooth == a.smooth
        for ma, mb in zip(a.materials, b.materials):
            for name in ("roughness", "metallic", "specular_ior", "coat_weight", "ior"):
                assert abs(getattr(mb, name) - getattr(ma, name)) < 1e-6, name
        for ca, cb in zip(a.colors_list, b.colors_list):
            if isinstance(ca, VertexColors):
                assert isinstance(cb, VertexColors)
                np.testing.assert_allclose(cb.linear_rgba, ca.linear_rgba, atol=1e-6)
            elif isinstance(ca, UniformColors):
                np.testing.assert_allclose(cb.linear_rgba, ca.linear_rgba, atol=1e-6)
            else:  # textures come back as the packed image, unpacked into texture_dir
                assert isinstance(cb, (FileTextureColors, TextureColors))
                if isinstance(cb, FileTextureColors):
                    assert Path(cb.texture_path).parent == (tmp_path / "tex").resolve()
                np.testing.assert_allclose(cb.linear_rgba_image(), ca.linear_rgba_image(), atol=2e-3)
                np.testing.assert_allclose(b.triangle_uvs(cb.uv_map), a.triangle_uvs(ca.uv_map), atol=1e-6)
    np.testing.assert_array_equal(dst.renderables["quad"].faces_material, [0, 1])

    assert sorted(dst.lights.keys()) == sorted(src.lights.keys())
    for la in src.lights:
        lb = dst.lights[la.tag]
        assert type(lb) is type(la)
        assert lb.strength == pytest.approx(la.strength, rel=1e-6)
        np.testing.assert_allclose(lb.linear_color, la.linear_color, atol=1e-6)
        np.testing.assert_allclose(lb.matrix_world, la.matrix_world, atol=1e-6)
        for attr in ("shape", "size", "spot_size", "spot_blend", "shadow_soft_size", "angular_diameter"):
            if hasattr(la, attr):
                va, vb = getattr(la, attr), getattr(lb, attr)
                if isinstance(va, str):
                    assert va == vb
                else:
                    np.testing.assert_allclose(vb, va, rtol=1e-6, err_msg=f"{la.tag}.{attr}")
    bg = dst.lights.background
    assert bg is not None
    np.testing.assert_allclose(bg.radiance, src.lights.background.radiance, rtol=1e-6)

    cam_a, cam_b = src.camera, dst.camera
    assert cam_b is not None and cam_b.tag == "cam"
    assert tuple(cam_b.resolution) == (80, 60)
    np.testing.assert_allclose(cam_b.K, cam_a.K, atol=1e-4)
    np.testing.assert_allclose(cam_b.matrix_world, cam_a.matrix_world, atol=1e-6)
    assert cam_b.near == pytest.approx(cam_a.near) and cam_b.far == pytest.approx(cam_a.far)


def test_round_trip_points_wireframe_transparency_curves(tmp_path: Path):
    rng = np.random.default_rng(3)
    s = Scene()
    pts = rng.uniform(-1, 1, (50, 3))
    s.renderables.add_pointcloud(
        pts,
        PrincipledBSDFMaterial(roughness=0.6),
        VertexColors(rng.uniform(0, 1, (50, 3))),
        point_size=rng.uniform(0.01, 0.05, 50),
        particle_emission_strength=0.5,
        tag="points",
        translation=(0, 0, 1),
    )
    s.renderables.add_pointcloud(
        pts[:5], PrincipledBSDFMaterial(), UniformColors((1, 0, 0)), point_size=0.02, tag="few"
    )
    s.renderables.add_cube_mesh(
        1.0,
        PlasticWireframeMaterial(wireframe_thickness=0.02, wireframe_color=(0.1, 0.2, 0.3)),
        UniformColors((0.5, 0.5, 0.5)),
        tag="wire",
    )
    s.renderables.add_sphere_nurbs(
        0.5, GlossyBSDFMaterial(roughness=0.2, alpha=0.5), UniformColors((0.9, 0.8, 0.1)), tag="glossy"
    )
    s.renderables.add_cube_mesh(
        0.5, PrincipledBSDFMaterial(alpha=0.7), UniformColors((0.1, 0.9, 0.1, 0.5)), tag="translucent"
    )
    curve = s.renderables.add_curve_nurbs(
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 1]], float),
        0.05,
        DiffuseMaterial(),
        UniformColors((1, 1, 1)),
        tag="tube",
    )
    curve.emit_shadows = False
    s.set_perspective_camera((64, 48), fov_x=0.8, translation=(0, -5, 1), rotation_mode="look_at", rotation=(0, 0, 0))
    path = tmp_path / "more.blend"
    s.export_blend(path)  # the Scene method delegates to the cycles backend
    dst = Scene()
    with warnings.catch_warnings():
        warnings.simplefilter("error", BlendAttachWarning)
        dst.attach_blend(path)
    assert sorted(dst.renderables.keys()) == sorted(s.renderables.keys())  # one object each (no duplicates)

    a, b = s.renderables["points"], dst.renderables["points"]
    assert type(b).__name__ == "PointCloud"
    np.testing.assert_allclose(
        b.vertices @ b.rotation_matrix.T + b.translation, a.vertices @ a.rotation_matrix.T + a.translation, atol=1e-6
    )
    np.testing.assert_allclose(b.point_size, a.point_size, rtol=1e-6)
    np.testing.assert_allclose(b.colors.linear_rgba, a.colors.linear_rgba, atol=1e-6)
    assert b.particle_emission_strength == pytest.approx(0.5)
    assert b.material.roughness == pytest.approx(0.6)
    assert dst.renderables["few"].point_size == pytest.approx(0.02)

    wire = dst.renderables["wire"].material
    assert isinstance(wire, PrincipledBSDFWireframeMaterial)
    assert wire.wireframe_thickness == pytest.approx(0.02)
    np.testing.assert_allclose(wire.linear("wireframe_color"), s.renderables["wire"].material.linear("wireframe_color"))
    glossy = dst.renderables["glossy"].material
    assert isinstance(glossy, GlossyBSDFMaterial) and glossy.alpha == pytest.approx(0.5)
    assert glossy.roughness == pytest.approx(0.2)
    # material alpha x colour alpha is the alpha Blender renders with
    assert dst.renderables["translucent"].material.alpha == pytest.approx(0.35)
    assert dst.renderables["translucent"].colors.linear_rgba[3] == 1.0
    tube = dst.renderables["tube"]
    assert tube.emit_shadows is False and len(tube.faces) > 50
    wc = tube.vertices @ tube.rotation_matrix.T + tube.translation
    dist = np.full(len(wc), np.inf)  # distance of every tube vertex to the polyline
    for p0, p1 in ((np.zeros(3), np.array([1.0, 0, 0])), (np.array([1.0, 0, 0]), np.ones(3))):
        d = p1 - p0
        t = np.clip((wc - p0) @ d / (d @ d), 0.0, 1.0)
        dist = np.minimum(dist, np.linalg.norm(wc - (p0 + t[:, None] * d), axis=1))
    assert dist.max() < 0.0505 and np.median(dist) > 0.045


def test_round_trip_texture_maps_and_unpacked_textures(tmp_path: Path):
    from PIL import Image

    rng = np.random.default_rng(5)
    rough = rng.uniform(0, 1, (4, 4)).astype(np.float32)
    normals = rng.uniform(0, 1, (4, 4, 3)).astype(np.float32)
    png = tmp_path / "albedo.png"
    Image.fromarray((rng.uniform(0, 1, (4, 4, 3)) * 255).astype(np.uint8)).save(png)
    s = Scene()
    s.renderables.add_mesh(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
        [[0, 1, 2]],
        PrincipledBSDFMaterial(
            roughness_map=TextureMap(rough), metallic_map=TextureMap(rough), normal_map=NormalMap(normals, 0.7)
        ),
        FileTextureColors(png, VertexUV([[0, 0], [1, 0], [0, 1]])),
        tag="maps",
    )
    s.set_perspective_camera((32, 32), fov_x=0.8, translation=(0, 0, 5))
    out = export_blend(s, tmp_path / "maps.blend", pack_textures=False)
    dst = Scene()
    with warnings.catch_warnings():
        warnings.simplefilter("error", BlendAttachWarning)
        attach_blend(dst, out, texture_dir=tmp_path / "unpacked")
    m = dst.renderables["maps"].material
    np.testing.assert_allclose(m.roughness_map.values(), rough, atol=1e-6)
    np.testing.assert_allclose(m.metallic_map.values(), rough, atol=1e-6)
    np.testing.assert_allclose(m.normal_map.normals(), NormalMap(normals).normals(), atol=1e-6)
    assert m.normal_map.strength == pytest.approx(0.7)
    # not packed: the external file is referenced where it is
    assert dst.renderables["maps"].colors.texture_path == str(png.resolve())


def test_export_orthographic_camera_and_bad_inputs(tmp_path: Path):
    s = Scene()
    s.renderables.add_mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], DiffuseMaterial(), UniformColors((1, 1, 1)))
    s.set_orthographic_camera((64, 32), ortho_scale=3.0, center=(20.25, 10.5), translation=(0, 0, 5))
    out = export_blend(s, tmp_path / "ortho.blend")
    out2 = export_blend(s, tmp_path / "ortho.blend")  # overwriting leaves no backup
    assert out2 == out and sorted(p.name for p in tmp_path.iterdir()) == ["ortho.blend"]
    dst = Scene()
    attach_blend(dst, out, with_camera=True)
    cam = dst.camera
    assert cam.kind == "orthographic"
    assert cam.ortho_scale == pytest.approx(3.0, rel=1e-6)
    np.testing.assert_allclose(cam.center, (20.25, 10.5), atol=1e-4)
    np.testing.assert_allclose(cam.matrix_world, s.camera.matrix_world, atol=1e-6)

    with pytest.raises(InvalidSceneError, match=r"\.blend"):
        export_blend(s, tmp_path / "scene.png")
    with pytest.raises(InvalidSceneError, match="camera"):
        export_blend(Scene(), tmp_path / "nocam.blend")
    with pytest.raises(InvalidSceneError, match="scene"):
        export_blend("not a scene", tmp_path / "x.blend")  # type: ignore[arg-type]
    with pytest.raises(InvalidSceneError, match="sampels"):
        export_blend(s, tmp_path / "x.blend", sampels=4)
    with pytest.raises(InvalidSceneError, match="samples"):
        export_blend(s, tmp_path / "x.blend", samples=0)
    assert not (tmp_path / "x.blend").exists()


def test_exported_blend_renders_the_same_picture(tmp_path: Path, blender_render):
    import blendify_core as bf

    src = round_trip_scene(scale=0.5)
    res = bf.render(src, backend="cycles", samples=4, seed=3, outputs=("rgba",))
    out = export_blend(src, tmp_path / "r.blend", samples=4, seed=3, outputs=("rgba",))
    info, img = blender_render(out, tmp_path / "r.exr")
    assert info["engine"] == "CYCLES" and info["samples"] == 4
    ref = np.asarray(res.rgba, dtype=np.float32)
    assert img.shape == ref.shape
    assert ref[..., 3].mean() > 0.15 and ref[..., :3].mean() > 0.03  # the objects are in view and lit
    assert float(np.abs(img - ref).max()) < 1e-3
    # export and attach leave the shared in-process backend usable: the same render again
    attach_blend(Scene(), out, with_camera=True)
    again = bf.render(src, backend="cycles", samples=4, seed=3, outputs=("rgba",))
    np.testing.assert_array_equal(np.asarray(again.rgba), ref)


# ---------------------------------------------------------------------------------------------------
# a hand-built .blend (what blendify 2.1 could not parse)
# ---------------------------------------------------------------------------------------------------

HAND_BUILT = """
import bpy, sys, json
import numpy as np
out = sys.argv[1]
bpy.ops.wm.read_factory_settings(use_empty=True)
sc = bpy.context.scene
sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 160, 120, 50
# a quad with UVs and a POINT colour attribute read by the material
me = bpy.data.meshes.new("quad")
me.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [], [(0, 1, 2, 3)])
uv = me.uv_layers.new(name="UVMap")
uv.uv.foreach_set("vector", np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32).ravel())
ca = me.color_attributes.new("Col", "FLOAT_COLOR", "POINT")
ca.data.foreach_set("color", np.array([[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1], [.5, .5, .5, 1]], np.float32).ravel())
mat = bpy.data.materials.new("vc")
p = mat.node_tree.nodes["Principled BSDF"]
vcn = mat.node_tree.nodes.new("ShaderNodeVertexColor")
vcn.layer_name = "Col"
mat.node_tree.links.new(vcn.outputs["Color"], p.inputs["Base Color"])
p.inputs["Roughness"].default_value = 0.25
p.inputs["Metallic"].default_value = 0.5
p.inputs["Emission Color"].default_value = (2.0, 1.0, 0.0, 1.0)
p.inputs["Emission Strength"].default_value = 3.0
me.materials.append(mat)
ob = bpy.data.objects.new("Quad", me)
sc.collection.objects.link(ob)
ob.location = (1, 2, 3)
ob.rotation_euler = (0.1, 0.2, 0.3)
ob.scale = (2, 2, 2)
# a cube with a render-only subdivision and a packed image on the base colour
me2 = bpy.data.meshes.new("cube")
h = 0.5
cv = [(x, y, z) for x in (-h, h) for y in (-h, h) for z in (-h, h)]
me2.from_pydata(cv, [], [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
me2.uv_layers.new(name="UVMap")
cube = bpy.data.objects.new("Cube", me2)
sc.collection.objects.link(cube)
cube.location = (-2, 0, 0)
img = bpy.data.images.new("checker", 4, 4)
px = np.zeros((4, 4, 4), np.float32)
px[..., 3] = 1
px[::2, ::2, 0] = 1
img.pixels.foreach_set(px.ravel())
img.pack()
m2 = bpy.data.materials.new("tex")
t = m2.node_tree.nodes.new("ShaderNodeTexImage")
t.image = img
m2.node_tree.links.new(t.outputs["Color"], m2.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
me2.materials.append(m2)
md = cube.modifiers.new("sub", "SUBSURF")
md.levels, md.render_levels = 0, 1
# a procedural material (cannot be parsed -> listed in the warning)
m3 = bpy.data.materials.new("noise")
noise = m3.node_tree.nodes.new("ShaderNodeTexNoise")
m3.node_tree.links.new(noise.outputs["Color"], m3.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
me3 = bpy.data.meshes.new("tri")
me3.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
me3.materials.append(m3)
tri = bpy.data.objects.new("Noisy", me3)
sc.collection.objects.link(tri)
def light(name, typ, **kw):
    d = bpy.data.lights.new(name, typ)
    for k, v in kw.items():
        setattr(d, k, v)
    o = bpy.data.objects.new(name, d)
    sc.collection.objects.link(o)
    return o
light("Rect", "AREA", energy=50, shape="RECTANGLE", size=2, size_y=0.5).location = (1, 0, 4)
light("Disk", "AREA", energy=60, shape="DISK", size=1.5).location = (2, 0, 4)
e = light("Ell", "AREA", energy=70, shape="ELLIPSE", size=1, size_y=3)
e.location, e.scale = (3, 0, 4), (2, 1, 1)
light("Sq", "AREA", energy=80, shape="SQUARE", size=0.7, exposure=1.0).location = (4, 0, 4)
light("Raw", "AREA", energy=10, shape="SQUARE", size=2.0, normalize=False).location = (5, 0, 4)
noded = light("Noded", "POINT", energy=10, temperature=3000, use_temperature=True)
noded.data.use_nodes = True
noded.data.node_tree.nodes["Emission"].inputs["Strength"].default_value = 3.0
temperature_color = list(noded.data.temperature_color)
light("Pt", "POINT", energy=100, shadow_soft_size=0.1).location = (0, 0, 5)
light("Sun", "SUN", energy=3, angle=0.01).rotation_euler = (0.3, 0, 0)
light("Spot", "SPOT", energy=200, spot_size=0.8, spot_blend=0.2, color=(1, 0.5, 0.25)).location = (0, 3, 3)
cd = bpy.data.cameras.new("Cam")
cd.lens, cd.sensor_width, cd.sensor_fit = 40, 32, "HORIZONTAL"
cd.shift_x, cd.shift_y = 0.1, -0.05
cd.clip_start, cd.clip_end = 0.5, 50
co = bpy.data.objects.new("Cam", cd)
sc.collection.objects.link(co)
sc.camera = co
co.location, co.rotation_euler = (0, -6, 2), (1.3, 0, 0.1)
w = bpy.data.worlds.new("W")
sc.world = w
bg = w.node_tree.nodes["Background"]
bg.inputs["Color"].default_value = (0.2, 0.3, 0.4, 1)
bg.inputs["Strength"].default_value = 0.5
# an environment texture (external PNG, relative path) added to the colour background
import os
env_img = bpy.data.images.new("env", 8, 4)
env_img.filepath_raw = os.path.join(os.path.dirname(out), "env.png")
env_img.file_format = "PNG"
env_img.save()
env_img.filepath = "//env.png"
envn = w.node_tree.nodes.new("ShaderNodeTexEnvironment")
envn.image = env_img
bg2 = w.node_tree.nodes.new("ShaderNodeBackground")
bg2.inputs["Strength"].default_value = 2.0
w.node_tree.links.new(envn.outputs["Color"], bg2.inputs["Color"])
add = w.node_tree.nodes.new("ShaderNodeAddShader")
w.node_tree.links.new(bg.outputs[0], add.inputs[0])
w.node_tree.links.new(bg2.outputs[0], add.inputs[1])
w.node_tree.links.new(add.outputs[0], w.node_tree.nodes["World Output"].inputs["Surface"])
# a collection instanced by two empties
inst = bpy.data.collections.new("Inst")  # not linked to the scene itself
leaf_me = bpy.data.meshes.new("leaf")
leaf_me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
inst.objects.link(bpy.data.objects.new("Leaf", leaf_me))
for i, x in enumerate((10.0, 20.0)):
    emp = bpy.data.objects.new(f"Spawner{i}", None)
    emp.instance_type, emp.instance_collection, emp.location = "COLLECTION", inst, (x, 0, 0)
    sc.collection.objects.link(emp)
# an RGBA image whose alpha is NOT connected: Blender renders it opaque
aimg = bpy.data.images.new("half_alpha", 2, 2, alpha=True)
aimg.pixels.foreach_set(np.array([0.2, 0.4, 0.6, 0.5] * 4, np.float32))
aimg.pack()
am = bpy.data.materials.new("alpha_tex")
at = am.node_tree.nodes.new("ShaderNodeTexImage")
at.image = aimg
am.node_tree.links.new(at.outputs["Color"], am.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
ame = leaf_me.copy()
ame.uv_layers.new(name="UVMap")
ame.materials.append(am)
sc.collection.objects.link(bpy.data.objects.new("AlphaTex", ame))
# hidden in the viewport only (eye icon): rendered, so parsed; hidden in renders: skipped
eye = bpy.data.objects.new("EyeHidden", leaf_me)
sc.collection.objects.link(eye)
eye.location = (0, 0, 7)
eye.hide_set(True)
no_render = bpy.data.objects.new("NoRender", leaf_me)
sc.collection.objects.link(no_render)
no_render.hide_render = True
# vertex instancing: the child appears at each parent vertex; the parent's own geometry does not render
pverts = bpy.data.meshes.new("pverts")
pverts.from_pydata([(0, 0, 0), (0, 3, 0)], [], [])
vpar = bpy.data.objects.new("VertParent", pverts)
sc.collection.objects.link(vpar)
vpar.location, vpar.instance_type, vpar.show_instancer_for_render = (30, 0, 0), "VERTS", False
vchild = bpy.data.objects.new("Child", leaf_me)
sc.collection.objects.link(vchild)
vchild.parent = vpar
# mixed shading: a cube with five smooth faces and one flat face
me4 = bpy.data.meshes.new("mixed")
me4.from_pydata(cv, [], [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
me4.polygons.foreach_set("use_smooth", [True, True, True, True, True, False])
sc.collection.objects.link(bpy.data.objects.new("Mixed", me4))
# per-corner (byte) colours that differ across a shared edge
me5 = bpy.data.meshes.new("corners")
me5.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [], [(0, 1, 2), (0, 2, 3)])
cc = me5.color_attributes.new("CornerCol", "BYTE_COLOR", "CORNER")
cc.data.foreach_set("color", [1, 0, 0, 1] * 3 + [0, 0, 1, 1] * 3)
m5 = bpy.data.materials.new("corner_mat")
an = m5.node_tree.nodes.new("ShaderNodeAttribute")
an.attribute_name = "CornerCol"
m5.node_tree.links.new(an.outputs["Color"], m5.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
me5.materials.append(m5)
cobj = bpy.data.objects.new("Corners", me5)
cobj.location = (0, 0, -3)
sc.collection.objects.link(cobj)
bpy.context.view_layer.update()
frame = [tuple(v) for v in cd.view_frame(scene=sc)]  # Blender's own view frame (camera space)
bpy.data.libraries.write(out, {sc}, compress=True)
print(json.dumps({"frame": frame, "cam_matrix": [list(r) for r in co.matrix_world], "tcol": temperature_color}))
"""


@pytest.fixture(scope="module")
def hand_built(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    d = tmp_path_factory.mktemp("hand")
    path = d / "hand.blend"
    info = run_bpy_script(HAND_BUILT, str(path))
    return path, info


def test_attach_hand_built_blend(hand_built: tuple[Path, dict[str, Any]], tmp_path: Path):
    path, info = hand_built
    before = datablock_ids()
    scene = Scene()
    with pytest.warns(BlendAttachWarning) as rec:
        added = attach_blend(scene, path, with_camera=True, texture_dir=tmp_path)
    msg = "\n".join(str(w.message) for w in rec)
    assert "ShaderNodeTexNoise" in msg  # the procedural material is listed
    assert datablock_ids() == before
    assert sorted(r.tag for r in added) == [
        "AlphaTex",
        "Corners",
        "Cube",
        "EyeHidden",
        "Mixed",
        "Noisy",
        "Quad",
        "Spawner0/Leaf",
        "Spawner1/Leaf",
        "VertParent/Child",
        "VertParent/Child.001",
    ]
    origins = sorted(tuple(np.round(world_corners(r)[0, 0], 6)) for r in added if r.tag.startswith("VertParent/"))
    assert origins == [(30.0, 0.0, 0.0), (30.0, 3.0, 0.0)]
    for i, x in enumerate((10.0, 20.0)):  # collection instances at their empties' world transform
        np.testing.assert_allclose(
            world_corners(scene.renderables[f"Spawner{i}/Leaf"])[0], [[x, 0, 0], [x + 1, 0, 0], [x, 1, 0]], atol=1e-6
        )
    alpha_tex = scene.renderables["AlphaTex"].colors  # alpha not connected in Blender: opaque in the IR
    assert not alpha_tex.has_alpha and alpha_tex.linear_rgba_image().shape == (2, 2, 4)
    mixed = scene.renderables["Mixed"]  # the flat face's 4 corners become their own vertices
    assert mixed.smooth and mixed.vertices.shape == (12, 3) and mixed.faces.shape == (12, 3)
    normals = mixed.vertex_normals()
    top = np.all(mixed.vertices[mixed.faces][..., 2] > 0.49, axis=1)  # the flat face is the top (+Z) one
    assert top.sum() == 2
    np.testing.assert_allclose(normals[np.unique(mixed.faces[top])], [[0, 0, 1]] * 4, atol=1e-6)
    side = np.unique(mixed.faces[~top])  # smooth faces keep smooth (diagonal) normals at the corners
    assert np.abs(normals[side]).min(axis=1).max() > 0.5
    corners = scene.renderables["Corners"]  # vertices 0 and 2 are split by their corner colours
    assert corners.vertices.shape == (6, 3)
    tri_cols = corners.colors.linear_rgba[corners.faces]
    np.testing.assert_allclose(tri_cols[0, :, :3], [[1, 0, 0]] * 3, atol=1e-6)
    np.testing.assert_allclose(tri_cols[1, :, :3], [[0, 0, 1]] * 3, atol=1e-6)
    env = scene.lights.environment  # relative image path resolved against the .blend's folder
    assert env is not None and env.path == str((path.parent / "env.png").resolve()) and env.strength == 2.0

    quad = scene.renderables["Quad"]
    np.testing.assert_allclose(quad.translation, (1, 2, 3), atol=1e-6)
    corners = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) * 2.0  # scale baked in
    np.testing.assert_allclose(quad.vertices, corners, atol=1e-6)
    assert quad.faces.shape == (2, 3)
    col = quad.colors_list[0]
    assert isinstance(col, VertexColors) and col.color_space == "linear"
    np.testing.assert_allclose(col.linear_rgba, [[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1], [0.5, 0.5, 0.5, 1]])
    mat = quad.materials[0]
    assert isinstance(mat, PrincipledBSDFMaterial) and mat.color_space == "linear"
    assert mat.roughness == pytest.approx(0.25) and mat.metallic == pytest.approx(0.5)
    # emission colour (2, 1, 0) x 3 -> colour (1, 0.5, 0) x 6
    np.testing.assert_allclose(mat.linear("emission_color")[:3], (1, 0.5, 0), atol=1e-6)
    assert mat.emission_strength == pytest.approx(6.0)
    assert isinstance(quad.uv_map, FacesUV)

    cube = scene.renderables["Cube"]
    assert cube.vertices.shape == (26, 3) and cube.faces.shape == (48, 3)  # render subdivision level 1
    tex = cube.colors_list[0]
    assert isinstance(tex, FileTextureColors) and Path(tex.texture_path).parent == tmp_path.resolve()
    img = tex.image()
    assert img.shape[:2] == (4, 4) and img[-1, 0, 0] == 255 and img[-1, 1, 0] == 0  # bottom row, UV (0, 0)

    lights = {lt.tag: lt for lt in scene.lights}
    assert (lights["Rect"].shape, lights["Rect"].size) == ("rectangle", (2.0, 0.5))
    assert (lights["Disk"].shape, lights["Disk"].size) == ("circle", (1.5, 1.5))
    assert lights["Ell"].shape == "ellipse"
    np.testing.assert_allclose(lights["Ell"].size, (2.0, 3.0), rtol=1e-6)  # object scale applied
    assert lights["Sq"].shape == "square" and lights["Sq"].strength == pytest.approx(160.0)  # exposure 1
    assert lights["Raw"].strength == pytest.approx(10.0 * 4.0)  # normalize off: energy x area
    tcol = np.array(info["tcol"])  # temperature colour and the Emission node's strength folded in
    noded = lights["Noded"]
    np.testing.assert_allclose(noded.linear_color * noded.strength, tcol * 30.0, rtol=1e-5)
    assert lights["Rect"].strength == pytest.approx(50.0) and lights["Ell"].strength == pytest.approx(70.0)
    assert type(lights["Pt"]).__name__ == "PointLight" and lights["Pt"].shadow_soft_size == pytest.approx(0.1)
    assert lights["Spot"].spot_size == pytest.approx(0.8) and lights["Spot"].spot_blend == pytest.approx(0.2)
    np.testing.assert_allclose(lights["Spot"].linear_color, (1, 0.5, 0.25), atol=1e-6)
    assert lights["Sun"].angular_diameter == pytest.approx(0.01)
    bg = scene.lights.background
    np.testing.assert_allclose(bg.radiance, np.array([0.2, 0.3, 0.4]) * 0.5, atol=1e-6)

    # camera: K from Blender's own view frame (continuous image coordinates, pixel centres at +0.5)
    cam = scene.camera
    assert tuple(cam.resolution) == (160, 120) and cam.resolution_percentage == 50
    fr = np.array(info["frame"])  # corners: (+x,+y), (+x,-y), (-x,-y), (-x,+y) at depth z
    z = -fr[0, 2]
    xmin, xmax, ymin, ymax = fr[:, 0].min() / z, fr[:, 0].max() / z, fr[:, 1].min() / z, fr[:, 1].max() / z
    fx, fy = 160 / (xmax - xmin), 120 / (ymax - ymin)
    cx, cy = -xmin * fx - 0.5, ymax * fy - 0.5
    np.testing.assert_allclose(cam.K, [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], atol=1e-3)
    assert cam.cx == pytest.approx(63.5, abs=1e-3) and cam.cy == pytest.approx(51.5, abs=1e-3)  # not mirrored
    np.testing.assert_allclose(cam.matrix_world, np.array(info["cam_matrix"]), atol=1e-6)
    assert (cam.near, cam.far) == (pytest.approx(0.5), pytest.approx(50.0))


@pytest.mark.parametrize(
    "width, height, pax, pay, fit, kind",
    [
        (100, 200, 1, 1, "AUTO", "PERSP"),
        (200, 100, 1, 1, "AUTO", "PERSP"),
        (100, 200, 1, 2, "VERTICAL", "PERSP"),
        (200, 100, 2, 1, "HORIZONTAL", "PERSP"),
        (100, 120, 1, 1.5, "AUTO", "PERSP"),
        (120, 100, 1.3, 1, "VERTICAL", "PERSP"),
        (100, 200, 1, 1, "AUTO", "ORTHO"),
        (200, 100, 1, 1, "VERTICAL", "ORTHO"),
    ],
)
def test_camera_intrinsics_match_blender_view_frame(width, height, pax, pay, fit, kind):
    """K for every sensor fit and pixel aspect agrees with Blender's own view frame."""
    import bpy

    sc = bpy.data.scenes.new("bf_test_intrinsics")
    cam = bpy.data.cameras.new("bf_test_intrinsics")
    try:
        r = sc.render
        r.resolution_x, r.resolution_y, r.pixel_aspect_x, r.pixel_aspect_y = width, height, pax, pay
        cam.type, cam.sensor_fit, cam.lens, cam.sensor_width, cam.sensor_height = kind, fit, 50.0, 36.0, 24.0
        cam.shift_x, cam.shift_y, cam.ortho_scale = 0.1, 0.2, 3.0
        fr = np.array([tuple(v) for v in cam.view_frame(scene=sc)])
        k = blender_camera_intrinsics(cam, width, height, pax, pay)
    finally:
        bpy.data.cameras.remove(cam)
        bpy.data.scenes.remove(sc)
    if kind == "PERSP":
        xs, ys = fr[:, 0] / -fr[0, 2], fr[:, 1] / -fr[0, 2]
        fx, fy = width / np.ptp(xs), height / np.ptp(ys)
        expected = (fx, fy, -xs.min() * fx - 0.5, ys.max() * fy - 0.5)
        np.testing.assert_allclose((k["fx"], k["fy"], k["cx"], k["cy"]), expected, atol=1e-3)
    else:
        xs, ys = fr[:, 0], fr[:, 1]
        px = np.ptp(xs) / width
        assert k["ortho_scale"] == pytest.approx(np.ptp(xs), rel=1e-6)
        np.testing.assert_allclose((k["cx"], k["cy"]), (-xs.min() / px - 0.5, ys.max() / px - 0.5), atol=1e-3)


RENDER_FILE = """
import bpy, sys, json, math
import numpy as np
out = sys.argv[1]
bpy.ops.wm.read_factory_settings(use_empty=True)
sc = bpy.context.scene
def diffuse(name):
    m = bpy.data.materials.new(name)
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Specular IOR Level"].default_value = 0.0
    p.inputs["Roughness"].default_value = 1.0
    return m, p
me = bpy.data.meshes.new("floor")
me.from_pydata([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], [], [(0, 1, 2, 3)])
ca = me.color_attributes.new("Col", "FLOAT_COLOR", "POINT")
cols = [[0.8, 0.2, 0.2, 1], [0.2, 0.8, 0.2, 1], [0.2, 0.2, 0.8, 1], [0.8, 0.8, 0.8, 1]]
ca.data.foreach_set("color", np.array(cols, np.float32).ravel())
m, p = diffuse("floor")
vc = m.node_tree.nodes.new("ShaderNodeVertexColor"); vc.layer_name = "Col"
m.node_tree.links.new(vc.outputs["Color"], p.inputs["Base Color"])
me.materials.append(m)
sc.collection.objects.link(bpy.data.objects.new("Floor", me))
bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.3, 0.2, 0.5), rotation=(0, 0, 0.4))
cube = bpy.context.object
img = bpy.data.images.new("checker", 4, 4)
px = np.full((4, 4, 4), 0.9, np.float32); px[::2, ::2, :3] = 0.1; px[1::2, 1::2, :3] = 0.1
img.pixels.foreach_set(px.ravel()); img.pack()
m2, p2 = diffuse("tex")
t = m2.node_tree.nodes.new("ShaderNodeTexImage"); t.image = img; t.interpolation = "Closest"
m2.node_tree.links.new(t.outputs["Color"], p2.inputs["Base Color"])
cube.data.materials.append(m2)
def light(name, typ, loc, rot=(0, 0, 0), scale=(1, 1, 1), **kw):
    d = bpy.data.lights.new(name, typ)
    for k, v in kw.items(): setattr(d, k, v)
    o = bpy.data.objects.new(name, d); sc.collection.objects.link(o)
    o.location, o.rotation_euler, o.scale = loc, rot, scale
light("Pt", "POINT", (1.5, -1, 2), energy=40, shadow_soft_size=0.0, use_soft_falloff=False, color=(1, 0.9, 0.8))
light("Spot", "SPOT", (-1.5, -1, 2.5), rot=(0.4, -0.3, 0), energy=150, spot_size=1.2, spot_blend=0.0,
      shadow_soft_size=0.0, use_soft_falloff=False)
light("Rect", "AREA", (0, 1.5, 2), rot=(-0.4, 0, 0), energy=30, shape="RECTANGLE", size=1.0, size_y=0.4)
light("Disk", "AREA", (1.5, 1.5, 2.5), energy=20, shape="DISK", size=0.6)
light("Ell", "AREA", (-1.5, 1.5, 2.5), scale=(2, 1, 1), energy=20, shape="ELLIPSE", size=0.4, size_y=0.8)
light("Sun", "SUN", (0, 0, 5), rot=(0.5, 0.2, 0), energy=1.5, angle=0.0)
w = bpy.data.worlds.new("W"); sc.world = w
bg = w.node_tree.nodes["Background"]; bg.inputs["Color"].default_value = (0.05, 0.06, 0.08, 1)
cd = bpy.data.cameras.new("Cam"); cd.lens = 30; cd.sensor_width = 36; cd.sensor_fit = "AUTO"
cd.shift_x, cd.shift_y = 0.08, -0.04
co = bpy.data.objects.new("Cam", cd); sc.collection.objects.link(co); sc.camera = co
co.location, co.rotation_euler = (0, -5.5, 3.2), (math.radians(58), 0, 0)
r = sc.render; r.engine = "CYCLES"; r.resolution_x, r.resolution_y, r.resolution_percentage = 48, 36, 100
r.film_transparent = True
cy = sc.cycles
cy.device = "CPU"; cy.samples = 16; cy.seed = 1; cy.use_denoising = False; cy.use_adaptive_sampling = False
cy.pixel_filter_type, cy.filter_width = "BOX", 1.0
cy.sample_clamp_direct = cy.sample_clamp_indirect = 0.0
cy.max_bounces = 0
bpy.ops.wm.save_as_mainfile(filepath=out)
print(json.dumps({"ok": True}))
"""


def test_attached_scene_renders_like_the_file(tmp_path: Path, blender_render):
    """End to end: a hand-built .blend (vertex colours, packed texture, every light type and area shape,
    world colour, shifted camera) rendered by Blender itself, and the same file attached to the IR and
    rendered by the cycles backend, give the same picture."""
    import blendify_core as bf

    path = tmp_path / "file.blend"
    run_bpy_script(RENDER_FILE, str(path))
    _info, ref = blender_render(path, tmp_path / "file.exr")
    scene = Scene()
    with warnings.catch_warnings():
        warnings.simplefilter("error", BlendAttachWarning)
        att = attach_blend(scene, path, with_camera=True, render_settings=True)
    assert att.render_settings is not None and att.cycles_settings is not None
    assert att.render_settings["samples"] == 16 and att.render_settings["seed"] == 1
    assert att.render_settings["max_bounces"] == 0 and att.render_settings["pixel_filter"] == "box"
    assert att.render_settings["filter_glossy"] == 1.0  # the file's filter glossy, Blender's default
    settings = {**att.render_settings, "outputs": ("rgba",)}
    img = np.asarray(bf.render(scene, backend="cycles", cycles_settings=att.cycles_settings, **settings).rgba)
    assert img.shape == ref.shape == (36, 48, 4)
    assert ref[..., :3].mean() > 0.05  # a lit scene, not a black frame
    assert np.abs(img - ref)[..., :3].mean() < 0.005 * ref[..., :3].mean()
    np.testing.assert_array_equal(img[..., 3], ref[..., 3])  # same silhouettes


def test_attached_objects_rendered_from_the_file_have_normals(tmp_path: Path):
    """Objects Cycles renders from an attached file's own node trees write no ``bf_normal`` AOV: the normal
    output takes Cycles' Normal pass there (unit normals on every hit pixel, facing the camera)."""
    import blendify_core as bf

    path = tmp_path / "file.blend"
    run_bpy_script(RENDER_FILE, str(path))
    scene = Scene()
    attach_blend(scene, path, with_camera=True)
    r = bf.render(scene, backend="cycles", samples=4, outputs=("rgb", "depth", "normal"))
    hit = np.isfinite(r.depth)
    assert hit.mean() > 0.1
    length = np.linalg.norm(r.normal, axis=-1)
    assert np.all(np.abs(length[hit] - 1) < 1e-3)
    assert np.all(length[~hit] == 0)
