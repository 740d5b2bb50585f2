"""glTF export: the file's structure is valid (accessor bounds, buffer views, GLB chunks), and what trimesh
reads back (``add_trimesh`` of the exported file) is the scene's geometry, colours, UVs and textures."""

from __future__ import annotations

import io
import json
import math
import struct
import warnings

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.errors import InvalidSceneError
from blendify_core.export.gltf import LUMENS_PER_WATT, gltf_document
from blendify_core.ir.colorspace import srgb_to_linear
from blendify_core.ir.transforms import quaternion_to_matrix
from blendify_core.testing import every_feature_scene, textured_quad_scene

_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
_DTYPES = {5126: np.float32, 5125: np.uint32}
#: the root node's rotation as a matrix: IR (+Z up) -> glTF (+Y up)
Y_UP = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])


def read_glb(path):
    """(json, binary chunk) of a .glb, checking the container: magic, version, lengths, 4-byte chunks."""
    data = path.read_bytes()
    magic, version, length = struct.unpack_from("<III", data, 0)
    assert (magic, version, length) == (0x46546C67, 2, len(data))
    json_len, json_type = struct.unpack_from("<II", data, 12)
    assert json_type == 0x4E4F534A and json_len % 4 == 0
    gltf = json.loads(data[20 : 20 + json_len])
    rest = data[20 + json_len :]
    if not rest:
        return gltf, b""
    bin_len, bin_type = struct.unpack_from("<II", rest, 0)
    assert bin_type == 0x004E4942 and bin_len % 4 == 0 and len(rest) == 8 + bin_len
    return gltf, rest[8:]


def accessor_data(gltf, blob, index):
    acc = gltf["accessors"][index]
    view = gltf["bufferViews"][acc["bufferView"]]
    n = _COMPONENTS[acc["type"]]
    dtype = _DTYPES[acc["componentType"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    return np.frombuffer(blob, dtype=dtype, count=acc["count"] * n, offset=start).reshape(acc["count"], n)


def validate(gltf, blob):
    """The structural rules of glTF 2.0 this exporter must keep (what the Khronos validator checks first)."""
    assert gltf["asset"]["version"] == "2.0"
    if blob:
        assert gltf["buffers"][0]["byteLength"] == len(blob)
    for view in gltf.get("bufferViews", []):
        assert view["byteOffset"] % 4 == 0
        assert view["byteOffset"] + view["byteLength"] <= len(blob)
    for i, acc in enumerate(gltf.get("accessors", [])):
        view = gltf["bufferViews"][acc["bufferView"]]
        size = acc["count"] * _COMPONENTS[acc["type"]] * 4
        assert size <= view["byteLength"], f"accessor {i} overruns its view"
        data = accessor_data(gltf, blob, i)
        assert np.all(np.isfinite(data))
        if acc["count"]:
            np.testing.assert_array_equal(np.asarray(acc["min"], dtype=data.dtype), data.min(axis=0))
            np.testing.assert_array_equal(np.asarray(acc["max"], dtype=data.dtype), data.max(axis=0))
    used = set()
    for mesh in gltf.get("meshes", []):
        for prim in mesh["primitives"]:
            pos = gltf["accessors"][prim["attributes"]["POSITION"]]
            assert "min" in pos and "max" in pos and pos["type"] == "VEC3"
            for name, a in prim["attributes"].items():
                assert gltf["accessors"][a]["count"] == pos["count"], name
            if "indices" in prim:
                idx = accessor_data(gltf, blob, prim["indices"])
                assert idx.size % 3 == 0 and (idx.size == 0 or idx.max() < pos["count"])
                assert gltf["bufferViews"][gltf["accessors"][prim["indices"]]["bufferView"]]["target"] == 34963
            assert 0 <= prim["material"] < len(gltf["materials"])
    for mat in gltf.get("materials", []):
        used.update(mat.get("extensions", {}))
        for key in ("baseColorTexture", "metallicRoughnessTexture"):
            if key in mat["pbrMetallicRoughness"]:
                assert mat["pbrMetallicRoughness"][key]["index"] < len(gltf["textures"])
    for tex in gltf.get("textures", []):
        assert tex["source"] < len(gltf["images"]) and tex["sampler"] < len(gltf["samplers"])
    for node in gltf["nodes"]:
        used.update(node.get("extensions", {}))
        for c in node.get("children", []):
            assert 0 <= c < len(gltf["nodes"])
        if "rotation" in node:
            assert math.isclose(np.linalg.norm(node["rotation"]), 1.0, rel_tol=1e-9)
    assert used <= set(gltf.get("extensionsUsed", []))


def node(gltf, name):
    return next(n for n in gltf["nodes"] if n.get("name") == name)


def test_every_feature_scene_writes_a_valid_glb_and_gltf(tmp_path):
    scene = every_feature_scene()
    with pytest.warns(UserWarning, match="wireframe"):
        path = scene.export(tmp_path / "scene.glb")
    validate(*read_glb(path))
    with pytest.warns(UserWarning):
        scene.export(tmp_path / "scene.gltf")
    gltf = json.loads((tmp_path / "scene.gltf").read_text())
    assert gltf["buffers"][0]["uri"] == "scene.bin"
    validate(gltf, (tmp_path / "scene.bin").read_bytes())
    assert gltf["meshes"] == read_glb(path)[0]["meshes"]
    # every renderable is a node of that tag; the area, point and spot lights are punctual lights
    names = {n.get("name") for n in gltf["nodes"]}
    assert set(scene.renderables.keys()) <= names
    assert len(gltf["extensions"]["KHR_lights_punctual"]["lights"]) == len(scene.lights)
    assert "wireframe" in " ".join(gltf["asset"]["extras"]["blendify_approximations"])


def test_round_trip_through_add_trimesh_keeps_geometry_and_vertex_colours(tmp_path, rng):
    v = rng.uniform(-1, 1, size=(50, 3))
    f = rng.integers(0, 50, size=(80, 3))
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    colours = rng.uniform(size=(50, 3))
    scene = bf.Scene()
    scene.renderables.add_mesh(
        v,
        f,
        bf.DiffuseMaterial(),
        bf.VertexColors(colours),
        translation=(0.5, -2, 1),
        rotation_mode="eulerXYZ",
        rotation=(10, 20, 30),
        tag="blob",
    )
    for y_up in (False, True):
        path = scene.export(tmp_path / f"blob_{y_up}.glb", y_up=y_up)
        back = bf.Scene()
        # the +Y-up root of blendify's own export is undone on reading (a third-party glTF is left as it is)
        mesh = back.renderables.add_trimesh(path)
        original = scene.renderables["blob"]
        world = lambda r: r.vertices @ r.rotation_matrix.T + r.translation  # noqa: E731
        np.testing.assert_allclose(world(mesh), world(original), atol=1e-5)
        np.testing.assert_array_equal(mesh.faces, original.faces)
        got = mesh.colors.linear_rgba[:, :3]
        np.testing.assert_allclose(got, original.colors.linear_rgba[:, :3], atol=1.5 / 255)
        assert mesh.colors.color_space == "linear"


def test_round_trip_keeps_uvs_and_the_texture(tmp_path):
    for faces_uv in (False, True):
        scene = textured_quad_scene(faces_uv=faces_uv)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # the world light is not expressible
            path = scene.export(tmp_path / "quad.glb", y_up=False)
        back = bf.Scene()
        mesh = back.renderables.add_trimesh(path)
        quad = scene.renderables["quad"]
        tex = quad.colors.image()
        np.testing.assert_array_equal(mesh.colors.image()[..., :3], tex)
        # each triangle corner keeps its position and its UV (bottom-left origin, as the IR's)
        got = {
            tuple(np.round(np.r_[p, uv], 5))
            for p, uv in zip(mesh.vertices[mesh.faces].reshape(-1, 3), mesh.triangle_uvs().reshape(-1, 2))
        }
        want = {
            tuple(np.round(np.r_[p, uv], 5))
            for p, uv in zip(quad.vertices[quad.faces].reshape(-1, 3), quad.triangle_uvs().reshape(-1, 2))
        }
        assert got == want
        gltf, _ = read_glb(path)
        sampler = gltf["samplers"][gltf["textures"][0]["sampler"]]
        assert sampler["magFilter"] == 9728  # interpolation="closest"


def test_materials_map_to_metallic_roughness_pbr_and_extensions(tmp_path):
    scene = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    mat = bf.PrincipledBSDFMaterial(
        roughness=0.3,
        metallic=0.7,
        ior=1.6,
        transmission_weight=0.4,
        coat_weight=0.5,
        coat_roughness=0.2,
        emission_color=(1.0, 0.5, 0.0),
        emission_strength=4.0,
        alpha=0.5,
        specular_ior=0.25,
        roughness_map=bf.TextureMap(np.linspace(0, 1, 12).reshape(3, 4).astype(np.float32)),
    )
    uv = bf.VertexUV(v[:, :2])
    scene.renderables.add_mesh(v, [[0, 1, 2]], mat, bf.UniformColors((0.5, 0.25, 1.0)), uv_map=uv, tag="tri")
    gltf, blob, notes = gltf_document(scene)
    validate(gltf, blob)
    m = gltf["materials"][0]
    pbr = m["pbrMetallicRoughness"]
    want_base = list(srgb_to_linear(np.array([0.5, 0.25, 1.0]))) + [0.5]
    np.testing.assert_allclose(pbr["baseColorFactor"], want_base, rtol=1e-6)
    assert pbr["metallicFactor"] == pytest.approx(0.7)
    assert pbr["roughnessFactor"] == 1.0  # the map holds the roughness (G channel)
    assert m["alphaMode"] == "BLEND" and m["doubleSided"] is True
    ext = m["extensions"]
    assert ext["KHR_materials_ior"]["ior"] == pytest.approx(1.6)
    assert ext["KHR_materials_transmission"]["transmissionFactor"] == pytest.approx(0.4)
    assert ext["KHR_materials_clearcoat"] == {"clearcoatFactor": 0.5, "clearcoatRoughnessFactor": 0.2}
    assert ext["KHR_materials_specular"]["specularFactor"] == pytest.approx(0.5)
    emission = np.array(m["emissiveFactor"]) * ext["KHR_materials_emissive_strength"]["emissiveStrength"]
    np.testing.assert_allclose(emission, srgb_to_linear(np.array([1.0, 0.5, 0.0])) * 4.0, rtol=1e-6)
    # the packed metallicRoughness image: G = the roughness map (row 0 = top), B = 1 (no metallic map)
    from PIL import Image

    image = gltf["images"][gltf["textures"][pbr["metallicRoughnessTexture"]["index"]]["source"]]
    view = gltf["bufferViews"][image["bufferView"]]
    png = np.asarray(Image.open(io.BytesIO(blob[view["byteOffset"] : view["byteOffset"] + view["byteLength"]])))
    np.testing.assert_array_equal(png[..., 1], np.round(np.linspace(0, 1, 12).reshape(3, 4) * 255))
    assert np.all(png[..., 2] == 255)
    assert notes == []


def test_camera_lights_and_points(tmp_path):
    scene = bf.Scene()
    cam = scene.set_perspective_camera((64, 48), fov_x=np.deg2rad(50), translation=(1, 2, 3), near=0.5, far=50)
    scene.lights.add_point(100.0, translation=(0, 0, 2), tag="pt")
    scene.lights.add_sun(3.0, tag="sun")
    scene.lights.add_spot(40.0, spot_size=np.deg2rad(60), spot_blend=0.2, tag="spot")
    pts = np.random.default_rng(0).uniform(size=(30, 3))
    scene.renderables.add_pointcloud(pts, bf.DiffuseMaterial(), bf.VertexColors(pts), point_size=0.02, tag="pc")
    gltf, blob, notes = gltf_document(scene)
    validate(gltf, blob)
    persp = gltf["cameras"][0]["perspective"]
    assert persp["yfov"] == pytest.approx(cam.fov_y) and persp["aspectRatio"] == pytest.approx(64 / 48)
    assert (persp["znear"], persp["zfar"]) == (0.5, 50.0)
    camnode = node(gltf, "camera")
    assert camnode["translation"] == [1.0, 2.0, 3.0]
    lights = gltf["extensions"]["KHR_lights_punctual"]["lights"]
    by_name = {light["name"]: light for light in lights}
    assert by_name["pt"]["type"] == "point"
    assert by_name["pt"]["intensity"] == pytest.approx(100.0 / (4 * math.pi) * LUMENS_PER_WATT)
    assert by_name["sun"]["type"] == "directional" and by_name["sun"]["intensity"] == pytest.approx(3.0 * 683)
    spot = by_name["spot"]["spot"]
    assert spot["outerConeAngle"] == pytest.approx(np.deg2rad(30))
    assert 0 < spot["innerConeAngle"] < spot["outerConeAngle"]
    assert node(gltf, "pt")["extras"] == {"blendify_light": "PointLight", "strength": 100.0, "unit": "W"}
    # the point cloud: a POINTS primitive with linear colours and its size in the extras
    prim = gltf["meshes"][0]["primitives"][0]
    assert prim["mode"] == 0 and prim["extras"]["point_size"] == 0.02
    np.testing.assert_allclose(accessor_data(gltf, blob, prim["attributes"]["POSITION"]), pts, rtol=1e-6)
    np.testing.assert_allclose(
        accessor_data(gltf, blob, prim["attributes"]["COLOR_0"])[:, :3], srgb_to_linear(pts), rtol=1e-5
    )
    assert any("POINTS" in n for n in notes)
    # per-point sizes: their mean in the extras, each in the _POINT_SIZE attribute
    sizes = np.linspace(0.01, 0.05, 30)
    scene.renderables["pc"].point_size = sizes
    gltf3, blob3, _ = gltf_document(scene)
    validate(gltf3, blob3)
    prim3 = gltf3["meshes"][0]["primitives"][0]
    assert prim3["extras"]["point_size"] == pytest.approx(sizes.mean())
    np.testing.assert_allclose(accessor_data(gltf3, blob3, prim3["attributes"]["_POINT_SIZE"])[:, 0], sizes, rtol=1e-6)
    # and as spheres: the same tessellation the renders use
    gltf2, blob2, _ = gltf_document(scene, points="spheres")
    validate(gltf2, blob2)
    assert gltf2["meshes"][0]["primitives"][0]["mode"] == 4


def test_y_up_root_rotation_maps_z_up_to_y_up():
    scene = bf.Scene()
    scene.renderables.add_cube_mesh(1.0, bf.DiffuseMaterial(), bf.UniformColors((1, 0, 0)), tag="c")
    gltf, _, _ = gltf_document(scene)
    from blendify_core.ir.from_trimesh import GLTF_Y_UP

    np.testing.assert_array_equal(GLTF_Y_UP, Y_UP)  # what add_trimesh undoes is what the exporter does
    root = node(gltf, "blendify_scene")
    x, y, z, w = root["rotation"]
    np.testing.assert_allclose(quaternion_to_matrix([w, x, y, z]), Y_UP, atol=1e-12)
    assert "rotation" not in node(gltf_document(scene, y_up=False)[0], "blendify_scene")


def test_primitives_are_tessellated_flat_or_smooth(tmp_path):
    scene = bf.Scene()
    cube = scene.renderables.add_cube_mesh(1.0, bf.DiffuseMaterial(), bf.UniformColors((1, 0, 0)), tag="flat")
    cube.set_smooth(False)
    cyl = scene.renderables.add_cylinder_mesh(0.5, 1.0, bf.DiffuseMaterial(), bf.UniformColors((0, 1, 0)), tag="cyl")
    cyl.set_smooth(True)
    gltf, blob, _ = gltf_document(scene)
    flat, smooth = gltf["meshes"]
    assert "NORMAL" not in flat["primitives"][0]["attributes"]  # glTF viewers shade flat
    normals = accessor_data(gltf, blob, smooth["primitives"][0]["attributes"]["NORMAL"])
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, rtol=1e-6)
    positions = accessor_data(gltf, blob, flat["primitives"][0]["attributes"]["POSITION"])
    np.testing.assert_allclose(positions, cube.to_mesh().vertices, rtol=1e-6)


def test_bad_arguments_are_named(tmp_path):
    scene = textured_quad_scene()
    with pytest.raises(InvalidSceneError, match="suffix"):
        scene.export(tmp_path / "x.obj")
    with pytest.raises(InvalidSceneError, match="points"):
        scene.export(tmp_path / "x.glb", points="cubes")
    with pytest.raises(InvalidSceneError, match="format"):
        scene.export(tmp_path / "x.glb", format="fbx")
    assert not list(tmp_path.iterdir())


def test_engine_formats_are_found_through_the_registry(tmp_path):
    """scene.export picks the writer by suffix: core formats by name, engine formats from the backends'
    file_formats (the first available backend by name that declares the format)."""
    from blendify_core.registry import BackendStatus, register_backend, unregister_backend

    calls = []

    class Exporter:
        _is_blendify_backend = True
        file_formats = ("blend", "mitsuba")

        @classmethod
        def probe(cls):
            return BackendStatus(True, None, "0")

        @classmethod
        def export_file(cls, scene, file_format, path, **kwargs):
            calls.append((file_format, path, kwargs))
            return path

    register_backend("aaa_exporter", Exporter)  # sorts before every real backend
    try:
        scene = textured_quad_scene()
        assert scene.export(tmp_path / "a.blend", pack_textures=False) == tmp_path / "a.blend"
        scene.export_mitsuba(tmp_path / "b.xml", samples=4)
        scene.export(tmp_path / "c.XML")
    finally:
        unregister_backend("aaa_exporter")
    assert calls == [
        ("blend", tmp_path / "a.blend", {"pack_textures": False}),
        ("mitsuba", tmp_path / "b.xml", {"samples": 4}),
        ("mitsuba", tmp_path / "c.XML", {}),
    ]


def test_every_hard_case_exports_a_valid_gltf_and_html_page():
    """The numerically awkward scenes of blendify_core.testing (far from the origin, degenerate geometry,
    empty objects, extreme cameras and lights): a structurally valid glTF and a viewer page each."""
    from blendify_core.export.html import html_document
    from blendify_core.testing import hard_cases

    for name, build in hard_cases().items():
        scene = build()
        gltf, blob, _ = gltf_document(scene)
        validate(gltf, blob)
        for acc in gltf.get("accessors", []):
            assert acc["count"] >= 1, name  # glTF: an accessor holds at least one element
        assert "blendify-glb" in html_document(scene), name


def test_round_trip_of_every_renderable_keeps_tags_and_world_geometry(tmp_path):
    scene = every_feature_scene()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        path = scene.export(tmp_path / "every.glb", y_up=False, points="spheres")
    back = bf.Scene()
    back.renderables.add_trimesh(path, merge=False)
    # a mesh of two material slots comes back as two meshes (trimesh splits glTF primitives)
    assert set(back.renderables.keys()) == set(scene.renderables.keys()) | {"pyramid_1"}

    def world_triangles(*renderables):
        tris = [(r.to_mesh().vertices @ r.rotation_matrix.T + r.translation)[r.to_mesh().faces] for r in renderables]
        return np.concatenate(tris).reshape(-1, 9)

    from scipy.spatial import cKDTree

    for tag, original in scene.renderables.items():
        got = [back.renderables[tag]] + ([back.renderables["pyramid_1"]] if tag == "pyramid" else [])
        a, b = world_triangles(*got), world_triangles(original)
        assert len(a) == len(b), tag
        # every triangle (its three corners, in order) has its twin on the other side
        assert cKDTree(b).query(a)[0].max() < 1e-4 and cKDTree(a).query(b)[0].max() < 1e-4, tag
