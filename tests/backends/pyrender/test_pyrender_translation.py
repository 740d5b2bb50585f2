"""Translation tests on the pyrender scene graph (projection, node poses, materials, lights, caching);
nothing is rendered here."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from blendify_pyrender import PyrenderBackend
from blendify_pyrender._platform import resolve_platform

from blendify_core import (
    DiffuseMaterial,
    GlossyBSDFMaterial,
    PrincipledBSDFMaterial,
    Scene,
    UniformColors,
    VertexColors,
    testing,
)
from blendify_core.errors import InvalidSceneError
from blendify_core.ir.materials import PlasticWireframeMaterial
from blendify_core.pipeline.capabilities import ALL_FEATURES
from blendify_core.pipeline.settings import resolve_settings

pytestmark = pytest.mark.pyrender
PLATFORM = resolve_platform(None)


def _ndc_to_opencv(p_clip: np.ndarray, w: int, h: int) -> np.ndarray:
    ndc = p_clip[:, :3] / p_clip[:, 3:4]
    u = (ndc[:, 0] + 1.0) / 2.0 * w - 0.5
    v = (1.0 - ndc[:, 1]) / 2.0 * h - 0.5
    return np.stack([u, v], axis=1)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(),
        dict(fy=185.0),
        dict(center=(20.0, 100.0)),
        dict(orthographic=True),
        dict(orthographic=True, center=(30.0, 20.0)),
    ],
)
def test_projection_matches_the_ir_camera(pyr, kwargs):
    """P @ V of the pyrender camera node maps world points to the IR camera's OpenCV pixels."""
    scene, _ = testing.marker_scene(**kwargs)
    frame = pyr.translate(scene, resolve_settings())
    eng = pyr.engine_instance
    cam = scene.camera
    node = eng._camera_node
    np.testing.assert_allclose(eng.pscene.get_pose(node), cam.matrix_world, atol=1e-12)
    proj = node.camera.get_projection_matrix(cam.width, cam.height)
    pts = np.array([r.translation for r in scene.renderables])
    clip = (proj @ np.linalg.inv(cam.matrix_world) @ np.c_[pts, np.ones(len(pts))].T).T
    uv = _ndc_to_opencv(clip, cam.width, cam.height)
    expected, _ = cam.project(pts)
    np.testing.assert_allclose(uv, expected, atol=1e-9)
    assert frame.rebuilt >= 0


def test_node_poses_place_vertices_in_world(pyr):
    scene = testing.primitives_scene()
    frame = pyr.translate(scene, resolve_settings())
    eng = pyr.engine_instance
    for r, node in zip(scene.renderables, frame.nodes):
        assert node is not None
        pose = eng.pscene.get_pose(node)
        prim = node.mesh.primitives[0]
        world = (pose @ np.c_[prim.positions, np.ones(len(prim.positions))].T).T[:, :3]
        tm = r.to_mesh()
        expected = tm.vertices @ r.rotation_matrix.T + r.translation
        lo, hi = world.min(axis=0), world.max(axis=0)
        np.testing.assert_allclose(lo, expected.min(axis=0), atol=1e-5)
        np.testing.assert_allclose(hi, expected.max(axis=0), atol=1e-5)
        assert all(p.material.doubleSided for p in node.mesh.primitives)


def test_material_factors():
    from blendify_pyrender.translate import PyrenderTranslator

    from blendify_core.pipeline.translator import TranslationContext

    tr, ctx = PyrenderTranslator(), TranslationContext()
    surf = tr.dispatch(UniformColors((0.5, 0.25, 0.1), color_space="linear"), ctx)
    pm, albedo = tr.pyrender_material(DiffuseMaterial(), surf, False, ctx)
    np.testing.assert_allclose(pm.baseColorFactor[:3], np.array([0.5, 0.25, 0.1]) / 0.96, rtol=1e-6)
    assert pm.metallicFactor == 0.0 and pm.roughnessFactor == 1.0 and pm.alphaMode == "OPAQUE"
    np.testing.assert_allclose(albedo[:3], [0.5, 0.25, 0.1])

    metal = PrincipledBSDFMaterial(metallic=1.0, roughness=0.3)
    pm, _ = tr.pyrender_material(metal, surf, False, ctx)
    np.testing.assert_allclose(pm.baseColorFactor[:3], [0.5, 0.25, 0.1], rtol=1e-6)  # no compensation
    assert pm.metallicFactor == 1.0 and abs(pm.roughnessFactor - 0.3) < 1e-9

    pm, _ = tr.pyrender_material(GlossyBSDFMaterial(roughness=0.2), surf, False, ctx)
    assert pm.metallicFactor == 1.0 and abs(pm.roughnessFactor - 0.2) < 1e-9

    # the material's own roughness (the IR default 0.4), no private fallback
    pm, _ = tr.pyrender_material(PrincipledBSDFMaterial(), surf, False, ctx)
    assert abs(pm.roughnessFactor - 0.4) < 1e-9

    emissive = PrincipledBSDFMaterial(emission_color=(1.0, 0.5, 0.0), emission_strength=4.0, color_space="linear")
    pm, _ = tr.pyrender_material(emissive, surf, False, ctx)
    np.testing.assert_allclose(pm.emissiveFactor**2, [4.0, 2.0, 0.0], rtol=1e-6)  # mesh.frag squares it

    pm, _ = tr.pyrender_material(PrincipledBSDFMaterial(alpha=0.5), surf, False, ctx)
    assert pm.alphaMode == "BLEND" and abs(pm.baseColorFactor[3] - 0.5) < 1e-9

    vsurf = tr.dispatch(VertexColors(np.full((3, 3), 0.5), color_space="linear"), ctx)
    pm, albedo = tr.pyrender_material(DiffuseMaterial(), vsurf, False, ctx)
    np.testing.assert_allclose(pm.baseColorFactor[:3], 1 / 0.96)
    np.testing.assert_allclose(vsurf.vertex_rgba[:, :3], 0.5)


def test_vertex_colours_go_to_color_0(pyr):
    scene = Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    cols = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    scene.renderables.add_mesh(v, [[0, 1, 2]], DiffuseMaterial(), VertexColors(cols, color_space="linear"), tag="tri")
    testing.look_at_camera(scene, (32, 32), (0, 0, 3))
    frame = pyr.translate(scene, resolve_settings())
    prim = frame.nodes[0].mesh.primitives[0]
    assert prim.color_0 is not None
    # flat shading unwelds the triangle: corner k gets vertex k's colour
    np.testing.assert_allclose(prim.color_0[:, :3], cols, atol=1e-6)


def test_lights_units(pyr):
    scene = testing.plane_scene("point")
    scene.lights.add_sun(3.0, tag="sun")
    scene.lights.add_spot(200.0, spot_size=np.deg2rad(60), spot_blend=0.0, tag="spot")
    scene.lights.add_area("square", 0.5, strength=100.0, tag="area")
    scene.lights.set_background_light(0.5, (1, 1, 1))
    pyr.translate(scene, resolve_settings())
    eng = pyr.engine_instance
    by_tag = {light.tag: node.light for node, light, _ in eng._light_nodes}
    assert abs(by_tag["Point_000"].intensity - 100.0 / (4 * np.pi)) < 1e-9
    assert abs(by_tag["sun"].intensity - 3.0) < 1e-9
    assert abs(by_tag["spot"].intensity - 200.0 / (4 * np.pi)) < 1e-9
    assert abs(by_tag["spot"].outerConeAngle - np.deg2rad(30)) < 1e-9
    assert abs(by_tag["spot"].innerConeAngle - np.deg2rad(30)) < 1e-9  # blend 0: hard edge
    # an area light: its radiance P / (pi A) (integrated over the surface by the shader) and its half sizes
    assert abs(by_tag["area"].intensity - 100.0 / (np.pi * 0.25)) < 1e-9
    assert by_tag["area"].blendify_area == (1.0, 0.25, 0.25)
    np.testing.assert_allclose(eng.pscene.ambient_light, 0.5 * 0.96, rtol=1e-9)
    for node, light, _ in eng._light_nodes:
        np.testing.assert_allclose(eng.pscene.get_pose(node), light.matrix_world)


def test_wireframe_adds_a_tube_primitive(pyr):
    scene = Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])
    scene.renderables.add_mesh(
        v, [[0, 1, 2, 3]], PlasticWireframeMaterial(wireframe_thickness=0.02), UniformColors((1, 1, 1))
    )
    testing.look_at_camera(scene, (32, 32), (0.5, 0.5, 3), (0.5, 0.5, 0))
    frame = pyr.translate(scene, resolve_settings())
    prims = frame.nodes[0].mesh.primitives
    assert len(prims) == 2
    wire = prims[1]
    assert len(wire.indices) == 5 * 8  # 5 unique edges (4 sides + diagonal), 8 triangles each
    dz = np.abs(wire.positions[:, 2])
    assert 0.0 < dz.max() <= 0.02 + 1e-6


def test_faces_material_split_into_primitives(pyr):
    scene = testing.every_feature_scene()
    frame = pyr.translate(scene, resolve_settings())
    i = [r.tag for r in scene.renderables].index("pyramid")
    prims = frame.nodes[i].mesh.primitives
    assert len(prims) == 2
    assert sorted(len(p.indices) for p in prims) == [2, 2]


def test_cache_updates_only_what_changed(pyr):
    scene = testing.primitives_scene()
    settings = resolve_settings()
    first = pyr.translate(scene, settings)
    again = pyr.translate(scene, settings)
    assert again.rebuilt == 0 and again.nodes == first.nodes
    cam = scene.camera
    cam.translation = cam.translation + [0.1, 0, 0]
    moved = pyr.translate(scene, settings)
    assert moved.rebuilt == 0
    np.testing.assert_allclose(pyr.engine_instance.pscene.get_pose(pyr.engine_instance._camera_node), cam.matrix_world)
    cube = scene.renderables["cube"]
    cube.translation = (0.0, 1.0, 2.0)
    after = pyr.translate(scene, settings)
    assert after.rebuilt == 0
    node = after.nodes[[r.tag for r in scene.renderables].index("cube")]
    assert np.allclose(pyr.engine_instance.pscene.get_pose(node)[:3, 3], [0.0, 1.0, 2.0])
    cube.materials[0].alpha = 0.9  # material revision (a DiffuseMaterial: roughness is fixed)
    assert pyr.translate(scene, settings).rebuilt == 1
    scene.renderables.remove("cube")
    gone = pyr.translate(scene, settings)
    assert node not in pyr.engine_instance.pscene.mesh_nodes and len(gone.nodes) == len(scene.renderables)


def test_indices_stay_exact_uint32():
    """pyrender's ``indices`` setter converts to float32 (inexact from 2^24 vertices): we keep uint32."""
    from blendify_pyrender import translate as tr

    from blendify_core.pipeline.translator import TranslationContext

    built = tr.PyrenderTranslator().dispatch(testing.primitives_scene().renderables["sphere"], TranslationContext())
    for prim in built.mesh.primitives:
        assert prim.indices.dtype == np.uint32
    big = np.array([[2**24 + 1, 2**24 + 2, 2**24 + 3]])
    prim = tr._primitive(np.zeros((3, 3)), np.zeros((3, 3)), big, None, np.ones(4))
    assert int(prim.indices[0, 0]) == 2**24 + 1


def test_point_cloud_is_one_quad_per_point():
    """Every cloud size: 4 vertices at each centre (texcoord_0 = diameter, corner 0..3), 2 triangles."""
    from blendify_pyrender import translate as tr

    from blendify_core.pipeline.translator import TranslationContext

    corners, tris = tr.sphere_quads(3)
    assert corners.tolist() == [0, 1, 2, 3] * 3
    assert tris.dtype == np.uint32 and tris.shape == (6, 3) and tris.max() == 11
    scene = testing.pointcloud_scene(n=1000, point_size=0.05)
    ctx = TranslationContext()
    built = tr.PyrenderTranslator().dispatch(scene.renderables["points"], ctx)
    (prim,) = built.mesh.primitives
    assert prim.positions.shape == (4000, 3) and prim.indices.shape == (2000, 3)
    np.testing.assert_allclose(prim.texcoord_0[:, 0], 0.05)
    assert prim.texcoord_0[:4, 1].tolist() == [0, 1, 2, 3]
    np.testing.assert_array_equal(prim.positions[0::4], prim.positions[3::4])  # the 4 corners share the centre


def test_capability_table_declares_every_feature():
    caps = PyrenderBackend.capabilities()
    assert set(caps) == set(ALL_FEATURES)
    from blendify_pyrender.translate import PyrenderTranslator

    assert set(PyrenderTranslator.declared()) == set(ALL_FEATURES), "declare new features explicitly"
    for name, cap in caps.items():
        assert cap.level in ("exact", "approximate", "unsupported")
        if cap.level != "exact":
            assert cap.note, name


def test_options_are_validated():
    with pytest.raises(InvalidSceneError, match="platform"):
        PyrenderBackend(platform="glx")
    with pytest.raises(InvalidSceneError, match="antialias"):
        PyrenderBackend(antialias="fxaa")
    with pytest.raises(InvalidSceneError, match="supersample"):
        PyrenderBackend(supersample=0)
    with pytest.raises(InvalidSceneError, match="unknown option"):
        PyrenderBackend(quality="x")


def test_import_is_lazy_and_probe_is_cheap():
    code = (
        "import sys, blendify_pyrender\n"
        "st = blendify_pyrender.PyrenderBackend.probe()\n"
        "assert st.available, st\n"
        "assert 'pyrender' not in sys.modules and 'OpenGL' not in sys.modules, 'engine imported'\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and "ok" in out.stdout, out.stderr


def test_platform_conflict_is_a_clear_error():
    other = "osmesa" if PLATFORM == "egl" else "egl"
    code = (
        "import os\n"
        f"os.environ['PYOPENGL_PLATFORM'] = {PLATFORM!r}\n"
        "import OpenGL.GL\n"
        "os.environ.pop('PYOPENGL_PLATFORM')\n"
        "import blendify_core as bf\n"
        "from blendify_core import testing\n"
        "from blendify_core.errors import BackendUnavailableError\n"
        "from blendify_pyrender import PyrenderBackend\n"
        f"be = PyrenderBackend(platform={other!r})\n"
        "try:\n"
        "    bf.render(testing.depth_plane_scene(), backend=be, outputs=('depth',))\n"
        "except BackendUnavailableError as exc:\n"
        "    print('refused:', exc)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert "refused:" in out.stdout and "already imported" in out.stdout, out.stdout + out.stderr
