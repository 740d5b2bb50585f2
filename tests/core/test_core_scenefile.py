"""Scene files: exact save/load round trip of every IR feature, stable fingerprints, clear errors for
bad files, texture paths confined to the scene's folder, and no pickle anywhere."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import blendify_core as bf
from blendify_core.errors import InvalidSceneError
from blendify_core.ir.attachments import Attachment
from blendify_core.ir.colors import TextureMap
from blendify_core.testing import every_feature_scene

# ---------------------------------------------------------------------------------------------------
# builders
# ---------------------------------------------------------------------------------------------------


def _write_png(path: Path, array: np.ndarray) -> Path:
    from PIL import Image

    Image.fromarray(array).save(path)
    return path


def full_scene(folder: Path, data_dir: Path, *, env_from_file: bool = False, ortho: bool = False) -> bf.Scene:
    """every_feature_scene plus everything it leaves out: FacesUV on quads with a file texture, ragged
    polygons, texture/normal maps from files and arrays, every light shape, an environment map,
    distortion (or an orthographic camera), emit_shadows=False, a shadow catcher, smooth shading."""
    tex_path = folder / "fuze uv.jpg"
    shutil.copy(data_dir / "fuze uv.jpg", tex_path)
    rough_png = _write_png(folder / "rough.png", (np.arange(64, dtype=np.uint8).reshape(8, 8) * 4))
    normal_png = _write_png(folder / "normal.png", np.full((4, 4, 3), (128, 128, 255), dtype=np.uint8))

    scene = every_feature_scene((96, 72))
    r = scene.renderables
    # a grid of quads with per-corner UVs and a file texture
    g = np.stack(np.meshgrid(np.arange(3.0), np.arange(3.0), indexing="xy"), -1).reshape(-1, 2)
    verts = np.c_[g * 0.2, np.zeros(len(g))]
    quads = np.array([[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]])
    faces_uv = bf.FacesUV(g[quads] / 2.0)
    quad_mesh = r.add_mesh(
        verts,
        quads,
        bf.PrincipledBSDFMaterial(
            roughness_map=TextureMap(rough_png), normal_map=bf.NormalMap(normal_png, strength=0.5), metallic=0.2
        ),
        bf.FileTextureColors(tex_path, faces_uv, interpolation="closest"),
        translation=(0, 1.5, 0.01),
        tag="fuze_quads",
    )
    quad_mesh.set_smooth(True)
    # ragged polygons (triangle, quad, pentagon) with per-face materials and vertex colours
    rv = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0], [2.5, 0.5, 0], [0.5, 1.5, 0]])
    polys = [[0, 1, 2, 3], [1, 4, 6, 5, 2], [3, 2, 7]]
    r.add_mesh(
        rv * 0.3,
        polys,
        [bf.DiffuseMaterial(), bf.MetalMaterial(color_space="linear", coat_tint=(0.2, 0.3, 0.4))],
        [bf.VertexColors(np.linspace(0, 1, 24).reshape(8, 3)), bf.UniformColors((0.1, 0.2, 0.3, 0.5))],
        faces_material=[0, 1, 0],
        uv_map=bf.VertexUV(rv[:, :2]),
        rotation_mode="eulerxyz",
        rotation=(10, 20, 30),
        tag="ragged",
    )
    r.add_mesh(
        rv * 0.3,
        polys,
        bf.PrincipledBSDFMaterial(metallic_map=TextureMap(np.linspace(0, 1, 12).reshape(3, 4), channel=0)),
        bf.TextureColors(np.linspace(0, 1, 2 * 3 * 4).reshape(2, 3, 4), bf.VertexUV(rv[:, :2]), color_space="linear"),
        tag="float_texture",
    ).emit_shadows = False
    r.add_plane_mesh(
        10.0, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)), shadow_catcher=True, translation=(0, 0, -0.01)
    )
    r.add_cylinder_mesh(
        0.1,
        0.3,
        [bf.DiffuseMaterial(), bf.GlossyBSDFMaterial(distribution="BECKMANN")],
        [bf.UniformColors((1, 0, 0)), bf.UniformColors((0, 1, 0))],
        faces_material=[0] * 8 + [1, 1],
        num_vertices=8,
        fill_type="NGON",
        translation=(1, 1, 0),
    ).set_smooth(True)
    r.add_circle_mesh(0.2, bf.PrincipledBSDFWireframeMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), fill_type="TRIFAN")
    r.add_pointcloud(
        np.linspace(0, 1, 30).reshape(10, 3),
        bf.PrincipledBSDFMaterial(distribution="GGX"),
        bf.UniformColors((0.3, 0.3, 0.9)),
        point_size=np.linspace(0.01, 0.05, 10),
        particle_emission_strength=0.5,
        tag="sized_points",
    )
    r["cube"].emit_shadows = False
    light_kw = dict(rotation_mode="look_at", rotation=(0, 0, 0))
    scene.lights.add_area("square", 0.3, 20.0, translation=(1, 1, 2), use_shadow=False, **light_kw)
    scene.lights.add_area("ellipse", (0.3, 0.6), 20.0, translation=(1, -1, 2), color=(1, 0.5, 0.2), **light_kw)
    scene.lights.add_sun(
        2.0, angular_diameter=0.1, rotation_mode="eulerXYZ", rotation=(10, 20, 0), color_space="linear"
    )
    scene.lights.set_background_light(0.25, (0.9, 0.9, 1.0, 1.0))
    if env_from_file:
        scene.lights.set_environment_map(tex_path, strength=0.7, rotation_mode="eulerXYZ", rotation=(0, 0, 30))
    else:
        env = np.linspace(0, 4, 8 * 16 * 3, dtype=np.float32).reshape(8, 16, 3)
        scene.lights.set_environment_map(env, strength=1.5, rotation_mode="rotvec", rotation=(0, 0, 0.3))
    if ortho:
        scene.set_orthographic_camera((80, 60), ortho_scale=3.5, center=(40.5, 29.0), near=0.5, far=50.0, **light_kw)
    else:
        scene.set_perspective_camera(
            (96, 72),
            K=np.array([[90.0, 0, 47.0], [0, 85.0, 36.5], [0, 0, 1]]),
            distortion=(-0.1, 0.01, 0.001, -0.002, 0.0005),
            resolution_percentage=50,
            near=0.2,
            far=40.0,
            translation=(0, -6, 3),
            **light_kw,
        )
    return scene


# ---------------------------------------------------------------------------------------------------
# attribute-level comparison (independent of the file format)
# ---------------------------------------------------------------------------------------------------


def _eq(a, b, what):
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b), what
    else:
        assert a == b, f"{what}: {a!r} != {b!r}"


def _same_texture_map(a, b, what):
    assert type(a) is type(b), what
    if a is None:
        return
    assert a.channel == b.channel, what
    assert (a.path is None) == (b.path is None), what
    if a.path is not None:
        assert Path(a.path).name == Path(b.path).name, what
    _eq(a.image(), b.image(), what + ".image")
    if isinstance(a, bf.NormalMap):
        assert a.strength == b.strength


def _same_material(a, b, what):
    assert type(a) is type(b), what
    assert a.color_space == b.color_space, what
    pa, pb = a.parameters(), b.parameters()
    assert pa.keys() == pb.keys(), what
    for k in pa:
        if isinstance(pa[k], TextureMap) or isinstance(pb[k], TextureMap):
            _same_texture_map(pa[k], pb[k], f"{what}.{k}")
        else:
            _eq(pa[k], pb[k], f"{what}.{k}")


def _same_colors(a, b, what):
    assert type(a) is type(b), what
    assert a.color_space == b.color_space, what
    if isinstance(a, bf.UniformColors):
        _eq(a.color, b.color, what)
    elif isinstance(a, bf.VertexColors):
        _eq(a.vertex_colors, b.vertex_colors, what)
    else:
        assert a.interpolation == b.interpolation
        assert type(a.uv_map) is type(b.uv_map)
        _eq(a.uv_map.data, b.uv_map.data, what + ".uv")
        if isinstance(a, bf.TextureColors):
            _eq(a.texture, b.texture, what + ".texture")
        else:
            assert Path(a.texture_path).name == Path(b.texture_path).name
            _eq(a.image(), b.image(), what + ".image")
    _eq(
        a.linear_rgba if not hasattr(a, "uv_map") else a.linear_rgba_image(),
        (b.linear_rgba if not hasattr(b, "uv_map") else b.linear_rgba_image()),
        what + ".linear",
    )


def assert_same_scene(a: bf.Scene, b: bf.Scene) -> None:
    assert a.renderables.keys() == b.renderables.keys()
    for ra, rb in zip(a.renderables, b.renderables):
        w = f"renderable {ra.tag!r}"
        assert type(ra) is type(rb), w
        _eq(ra.quaternion, rb.quaternion, w + ".quaternion")
        _eq(ra.translation, rb.translation, w + ".translation")
        _eq(ra.matrix_world, rb.matrix_world, w + ".matrix_world")
        assert ra.emit_shadows == rb.emit_shadows, w
        assert getattr(ra, "smooth", None) == getattr(rb, "smooth", None), w
        assert len(ra.materials) == len(rb.materials), w
        for i, (ma, mb) in enumerate(zip(ra.materials, rb.materials)):
            _same_material(ma, mb, f"{w}.materials[{i}]")
        for i, (ca, cb) in enumerate(zip(ra.colors_list, rb.colors_list)):
            _same_colors(ca, cb, f"{w}.colors[{i}]")
        fa, fb = getattr(ra, "faces_material", None), getattr(rb, "faces_material", None)
        assert (fa is None) == (fb is None), w
        if fa is not None:
            _eq(fa, fb, w + ".faces_material")
        if isinstance(ra, bf.Mesh):
            for attr in ("vertices", "faces", "face_polygon", "polygon_faces_material"):
                va, vb = getattr(ra, attr), getattr(rb, attr)
                if va is None:
                    assert vb is None
                else:
                    _eq(va, vb, f"{w}.{attr}")
            assert (ra.n_polygons, ra.polygon_size) == (rb.n_polygons, rb.polygon_size)
            assert type(ra.uv_map) is type(rb.uv_map)
            ta, tb = ra.triangle_uvs(), rb.triangle_uvs()
            if ta is not None:
                _eq(ta, tb, w + ".triangle_uvs")
        elif isinstance(ra, bf.PointCloud):
            _eq(ra.vertices, rb.vertices, w)
            _eq(np.asarray(ra.point_size), np.asarray(rb.point_size), w + ".point_size")
            assert ra.base_primitive == rb.base_primitive
            assert ra.particle_emission_strength == rb.particle_emission_strength
        else:
            ma, mb = ra.to_mesh(), rb.to_mesh()
            _eq(ma.vertices, mb.vertices, w + ".to_mesh.vertices")
            _eq(ma.faces, mb.faces, w + ".to_mesh.faces")
            if isinstance(ra, bf.PlaneMesh):
                assert ra.shadow_catcher == rb.shadow_catcher
            if isinstance(ra, bf.CurveBezier):
                _eq(ra.keypoints, rb.keypoints, w)
    assert a.lights.keys() == b.lights.keys()
    for la, lb in zip(a.lights, b.lights):
        w = f"light {la.tag!r}"
        assert type(la) is type(lb), w
        for attr in ("strength", "color", "use_shadow", "color_space"):
            _eq(getattr(la, attr), getattr(lb, attr), f"{w}.{attr}")
        for attr in ("shadow_soft_size", "angular_diameter", "spot_size", "spot_blend", "shape", "size"):
            if hasattr(la, attr):
                _eq(getattr(la, attr), getattr(lb, attr), f"{w}.{attr}")
        _eq(la.matrix_world, lb.matrix_world, w)
    ba, bb = a.lights.background, b.lights.background
    assert (ba is None) == (bb is None)
    if ba is not None:
        assert (ba.strength, ba.color, ba.color_space) == (bb.strength, bb.color, bb.color_space)
    ea, eb = a.lights.environment, b.lights.environment
    assert (ea is None) == (eb is None)
    if ea is not None:
        assert (ea.strength, ea.color_space) == (eb.strength, eb.color_space)
        _eq(ea.quaternion, eb.quaternion, "environment.quaternion")
        _eq(ea.image(), eb.image(), "environment.image")
        assert (ea.path is None) == (eb.path is None)
    ca, cb = a.camera, b.camera
    assert type(ca) is type(cb)
    if ca is not None:
        for attr in (
            "resolution",
            "center",
            "near",
            "far",
            "resolution_percentage",
            "quaternion",
            "translation",
            "tag",
        ):
            _eq(getattr(ca, attr), getattr(cb, attr), f"camera.{attr}")
        if isinstance(ca, bf.PerspectiveCamera):
            _eq(ca.K, cb.K, "camera.K")
            _eq(ca.distortion, cb.distortion, "camera.distortion")
        else:
            assert ca.ortho_scale == cb.ortho_scale


# ---------------------------------------------------------------------------------------------------
# round trips
# ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("variant", ["perspective-env-array", "ortho-env-file"])
def test_round_trip_of_every_feature(tmp_path, data_dir, variant):
    file_variant = variant == "ortho-env-file"
    scene = full_scene(tmp_path, data_dir, env_from_file=file_variant, ortho=file_variant)
    path = tmp_path / "scene.npz"
    scene.save(path)
    loaded = bf.Scene.load(path)
    assert loaded is not scene
    assert_same_scene(scene, loaded)
    assert loaded.fingerprint() == scene.fingerprint()
    # and a second generation is identical too
    path2 = tmp_path / "scene2.npz"
    loaded.save(path2)
    again = bf.Scene.load(path2)
    assert_same_scene(scene, again)
    assert again.fingerprint() == scene.fingerprint()


def test_loaded_arrays_are_canonical_and_read_only(tmp_path, data_dir):
    scene = full_scene(tmp_path, data_dir)
    scene.save(tmp_path / "s.npz")
    loaded = bf.Scene.load(tmp_path / "s.npz")
    mesh = loaded.renderables["ragged"]
    assert mesh.vertices.dtype == np.float64 and mesh.faces.dtype == np.int32
    assert not mesh.vertices.flags.writeable and not mesh.faces.flags.writeable
    with pytest.raises(ValueError):
        mesh.vertices[0, 0] = 1.0


def test_moving_the_folder_keeps_textures_working(tmp_path, data_dir):
    src = tmp_path / "a"
    src.mkdir()
    scene = full_scene(src, data_dir, env_from_file=True)
    scene.save(src / "scene.npz")
    dst = tmp_path / "b"
    shutil.copytree(src, dst)
    shutil.rmtree(src)
    loaded = bf.Scene.load(dst / "scene.npz")
    tex = loaded.renderables["fuze_quads"].colors
    assert Path(tex.texture_path).parent == dst.resolve()
    from PIL import Image

    with Image.open(data_dir / "fuze uv.jpg") as im:
        assert tex.image().shape == (im.height, im.width, 3)
    assert loaded.fingerprint() == bf.Scene.load(dst / "scene.npz").fingerprint()


def test_absolute_paths_when_asked(tmp_path, data_dir):
    scene = full_scene(tmp_path, data_dir)
    out = tmp_path / "sub"
    out.mkdir()
    scene.save(out / "abs.npz", relative_paths=False)
    header = _header(out / "abs.npz")
    paths = [p for p in _all_paths(header)]
    assert paths and all(os.path.isabs(p) for p in paths)
    # absolute paths outside the folder are refused too unless allowed
    with pytest.raises(InvalidSceneError, match="allow_outside"):
        bf.Scene.load(out / "abs.npz")
    assert_same_scene(scene, bf.Scene.load(out / "abs.npz", allow_outside=True))


def test_empty_scene_round_trip(tmp_path):
    s = bf.Scene()
    s.save(tmp_path / "empty.npz")
    loaded = bf.Scene.load(tmp_path / "empty.npz")
    assert len(loaded.renderables) == 0 and len(loaded.lights) == 0 and loaded.camera is None
    assert loaded.fingerprint() == s.fingerprint()


def test_no_pickle_in_scene_files(tmp_path, data_dir):
    scene = full_scene(tmp_path, data_dir)
    scene.save(tmp_path / "s.npz")
    with np.load(tmp_path / "s.npz", allow_pickle=False) as data:
        assert "__header__" in data.files
        for name in data.files:
            arr = data[name]  # would raise for object arrays
            assert arr.dtype != object
    with zipfile.ZipFile(tmp_path / "s.npz") as z:
        assert all(n.endswith(".npy") for n in z.namelist())
    header = _header(tmp_path / "s.npz")
    assert header["format"] == "blendify-core-scene" and isinstance(header["version"], int)


# ---------------------------------------------------------------------------------------------------
# fingerprints
# ---------------------------------------------------------------------------------------------------


def _child_fingerprint(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip().splitlines()[-1]


def test_fingerprint_is_stable_across_processes(tmp_path, data_dir):
    scene = full_scene(tmp_path, data_dir)
    scene.save(tmp_path / "s.npz")
    fp = scene.fingerprint()
    assert len(fp) == 64 and int(fp, 16) >= 0
    child = _child_fingerprint(
        f"import blendify_core as bf\nprint(bf.Scene.load({str(tmp_path / 's.npz')!r}).fingerprint())"
    )
    assert child == fp
    built = _child_fingerprint(
        "from blendify_core.testing import every_feature_scene\nprint(every_feature_scene().fingerprint())"
    )
    assert built == every_feature_scene().fingerprint()


def test_fingerprint_is_deterministic_in_process():
    assert every_feature_scene().fingerprint() == every_feature_scene().fingerprint()


def _mutations():
    def nudge_vertex(s):
        m = s.renderables["pyramid"]
        v = m.vertices.copy()
        v[2, 1] = np.nextafter(v[2, 1], 10.0)  # one ulp
        m.update_vertices(v)

    def colour(s):
        s.renderables["cube"].update_colors(bf.UniformColors((0.8, 0.2, 0.21)))

    def colour_space(s):
        s.renderables["cube"].update_colors(bf.UniformColors((0.8, 0.2, 0.2), color_space="linear"))

    def material_param(s):
        s.renderables["cube"].material.alpha = 0.31  # a DiffuseMaterial: roughness is fixed

    def material_class(s):
        s.renderables["cube"].update_material(bf.MetalMaterial())

    def light_strength(s):
        s.lights["Point_000"].strength = 50.0001

    def light_colour(s):
        s.lights["Point_000"].color = (1.0, 0.99, 1.0)

    def light_shadow(s):
        s.lights["Point_000"].use_shadow = False

    def camera_pose(s):
        s.camera.translation = s.camera.translation + [0, 0, 1e-9]

    def camera_rotation(s):
        q = s.camera.quaternion.copy()
        q[1] += 1e-7
        s.camera.quaternion = q

    def camera_intrinsics(s):
        s.set_perspective_camera((96, 72), fov_x=np.deg2rad(50.0001))

    def resolution(s):
        s.set_perspective_camera((96, 73), fov_x=np.deg2rad(50))

    def object_pose(s):
        s.renderables["sphere"].translation = (0.0, 0, 0.3001)

    def emit_shadows(s):
        s.renderables["sphere"].emit_shadows = False

    def smooth(s):
        s.renderables["pyramid"].set_smooth(True)

    def point_size(s):
        s.renderables["points"].point_size = 0.031

    def remove_object(s):
        s.renderables.remove("curve")

    def add_light(s):
        s.lights.add_point(1.0)

    def background(s):
        s.lights.set_background_light(0.31)

    def texture_pixel(s):
        m = s.renderables["textured"]
        tex = m.colors.texture.copy()
        tex[0, 0, 0] ^= 1
        m.update_colors(bf.TextureColors(tex, m.colors.uv_map))

    def uv_nudge(s):
        m = s.renderables["textured"]
        uv = m.colors.uv_map.data.copy()
        uv[0, 0] += 1e-6
        m.update_colors(bf.TextureColors(m.colors.texture, bf.VertexUV(uv)))

    def roughness_map(s):
        s.renderables["textured"].material.roughness_map = None

    def near_far(s):
        s.set_perspective_camera((96, 72), fov_x=np.deg2rad(50), translation=(0, -6, 3), far=99.0)

    def distortion(s):
        s.set_perspective_camera((96, 72), fov_x=np.deg2rad(50), translation=(0, -6, 3), distortion=(1e-6, 0, 0, 0))

    def principal_point(s):
        s.set_perspective_camera((96, 72), fov_x=np.deg2rad(50), translation=(0, -6, 3), center=(47.5, 35.0))

    def environment(s):
        s.lights.set_environment_map(np.ones((2, 4, 3), np.float32))

    def shadow_catcher(s):
        s.renderables["ground"].shadow_catcher = True

    def faces_material(s):
        m = s.renderables["pyramid"]
        s.renderables.remove(m)
        s.renderables.add_mesh(
            m.vertices, m.faces, m.materials, m.colors_list, faces_material=[1, 1, 0, 1], tag="pyramid"
        )

    def light_pose(s):
        s.lights["Spot_000"].set_position("look_at", (0, 0, 0.001), translation=(2, -2, 3))

    def material_colour_space(s):
        s.renderables["emitter"].update_material(
            bf.PrincipledBSDFMaterial(emission_color=(1, 0.5, 0.2), emission_strength=2.0, color_space="linear")
        )

    def tag(s):
        obj = s.renderables["circle"]
        s.renderables.remove(obj)
        s.renderables._add(obj, "circle2")

    return {k: v for k, v in locals().items() if callable(v)}


MUTATIONS = _mutations()


@pytest.mark.parametrize("name", sorted(MUTATIONS))
def test_fingerprint_changes_when_anything_changes(name):
    base = every_feature_scene()
    base.set_perspective_camera((96, 72), fov_x=np.deg2rad(50), translation=(0, -6, 3))
    before = base.fingerprint()
    MUTATIONS[name](base)
    assert base.fingerprint() != before, f"{name} did not change the fingerprint"


def test_fingerprint_follows_texture_file_content(tmp_path):
    tex = _write_png(tmp_path / "t.png", np.zeros((4, 4, 3), np.uint8))
    s = bf.Scene()
    s.renderables.add_mesh(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
        [[0, 1, 2]],
        bf.PrincipledBSDFMaterial(),
        bf.FileTextureColors(tex, bf.VertexUV([[0, 0], [1, 0], [0, 1]])),
    )
    before = s.fingerprint()
    _write_png(tex, np.full((4, 4, 3), 255, np.uint8))
    st = os.stat(tex)
    os.utime(tex, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000))
    assert s.fingerprint() != before


# ---------------------------------------------------------------------------------------------------
# bad files
# ---------------------------------------------------------------------------------------------------


def _header(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as data:
        return json.loads(bytes(data["__header__"]).decode())


def _all_paths(obj):
    if isinstance(obj, dict):
        for k, v in obj.items():
            if k in ("texture_path", "path") and isinstance(v, str):
                yield v
            else:
                yield from _all_paths(v)
    elif isinstance(obj, list):
        for v in obj:
            yield from _all_paths(v)


def _rewrite(src: Path, dst: Path, header_change=None, drop=()):
    with np.load(src, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files if k not in drop}
    header = json.loads(bytes(arrays["__header__"]).decode())
    if header_change is not None:
        header = header_change(header)
    arrays["__header__"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    np.savez(dst, **arrays)
    return dst


@pytest.fixture
def saved(tmp_path) -> Path:
    s = every_feature_scene()
    s.save(tmp_path / "good.npz")
    return tmp_path / "good.npz"


def _bad_files():
    def random_bytes(saved, d):
        p = d / "random.npz"
        p.write_bytes(np.random.default_rng(0).integers(0, 256, 4096, dtype=np.uint8).tobytes())
        return p, "not a readable scene file"

    def text_file(saved, d):
        p = d / "text.npz"
        p.write_text("hello, I am not a zip file\n")
        return p, "not a readable scene file"

    def truncated(saved, d):
        p = d / "truncated.npz"
        p.write_bytes(saved.read_bytes()[: saved.stat().st_size // 2])
        return p, "scene file"

    def npy_array(saved, d):
        p = d / "array.npz"
        with open(p, "wb") as f:
            np.save(f, np.zeros(3))
        return p, "not a blendify-core scene file"

    def plain_npz(saved, d):
        p = d / "plain.npz"
        np.savez(p, a=np.zeros(3))
        return p, "no header"

    def other_format(saved, d):
        return _rewrite(saved, d / "other.npz", lambda h: {**h, "format": "something-else"}), "not a blendify-core"

    def unknown_version(saved, d):
        return _rewrite(saved, d / "v999.npz", lambda h: {**h, "version": 999}), "version 999"

    def header_not_json(saved, d):
        p = d / "badjson.npz"
        with np.load(saved, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        arrays["__header__"] = np.frombuffer(b"{not json", dtype=np.uint8)
        np.savez(p, **arrays)
        return p, "not a readable scene file"

    def missing_array(saved, d):
        with np.load(saved, allow_pickle=False) as data:
            victim = next(k for k in data.files if k.endswith(".vertices"))
        return _rewrite(saved, d / "missing.npz", drop=(victim,)), "corrupt"

    def missing_key(saved, d):
        return _rewrite(saved, d / "nokey.npz", lambda h: {k: v for k, v in h.items() if k != "lights"}), "corrupt"

    def wrong_types(saved, d):
        return _rewrite(saved, d / "types.npz", lambda h: {**h, "renderables": ["oops"]}), "corrupt"

    def unknown_kind(saved, d):
        def change(h):
            h["renderables"][0]["kind"] = "teapot"
            return h

        return _rewrite(saved, d / "kind.npz", change), "teapot"

    def invalid_value(saved, d):
        def change(h):
            h["lights"][0]["params"]["strength"] = -5
            return h

        return _rewrite(saved, d / "neg.npz", change), "strength"

    def missing_file(saved, d):
        return d / "does_not_exist.npz", "no such scene file"

    return {k: v for k, v in locals().items() if callable(v)}


BAD_FILES = _bad_files()


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_bad_scene_files_raise_invalid_scene_error(saved, tmp_path, name):
    path, words = BAD_FILES[name](saved, tmp_path)
    with pytest.raises(InvalidSceneError) as info:
        bf.Scene.load(path)
    assert words in str(info.value)
    assert str(path.name) in str(info.value)


def test_texture_outside_the_folder_needs_allow_outside(tmp_path, data_dir):
    tex = tmp_path / "fuze uv.jpg"
    shutil.copy(data_dir / "fuze uv.jpg", tex)
    s = bf.Scene()
    s.renderables.add_mesh(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
        [[0, 1, 2]],
        bf.PrincipledBSDFMaterial(),
        bf.FileTextureColors(tex, bf.VertexUV([[0, 0], [1, 0], [0, 1]])),
    )
    sub = tmp_path / "scenes"
    sub.mkdir()
    s.save(sub / "s.npz")
    assert list(_all_paths(_header(sub / "s.npz"))) == [os.path.join("..", "fuze uv.jpg")]
    with pytest.raises(InvalidSceneError, match="outside the scene's folder") as info:
        bf.Scene.load(sub / "s.npz")
    assert "allow_outside=True" in str(info.value)
    loaded = bf.Scene.load(sub / "s.npz", allow_outside=True)
    assert Path(loaded.renderables["Mesh_000"].colors.texture_path) == tex.resolve()


def test_missing_texture_after_save_is_a_clear_error(tmp_path, data_dir):
    scene = full_scene(tmp_path, data_dir)
    scene.save(tmp_path / "s.npz")
    (tmp_path / "fuze uv.jpg").unlink()
    with pytest.raises(InvalidSceneError, match="no such file"):
        bf.Scene.load(tmp_path / "s.npz")


def test_save_errors_leave_nothing_behind(tmp_path):
    s = every_feature_scene()
    with pytest.raises(InvalidSceneError, match="path"):
        s.save(tmp_path / "scene.json")
    with pytest.raises(InvalidSceneError, match="does not exist"):
        s.save(tmp_path / "missing_folder" / "scene.npz")
    assert list(tmp_path.iterdir()) == []


def test_save_is_atomic_over_an_existing_file(tmp_path, monkeypatch):
    s = every_feature_scene()
    s.save(tmp_path / "s.npz")
    before = (tmp_path / "s.npz").read_bytes()

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez_compressed", boom)
    with pytest.raises(OSError, match="disk full"):
        s.save(tmp_path / "s.npz")
    assert (tmp_path / "s.npz").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.npz"]


# ---------------------------------------------------------------------------------------------------
# property: random poses and parameters survive a file round trip bit for bit
# ---------------------------------------------------------------------------------------------------


_f = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
_unit = st.floats(0.0, 1.0)
_quat = st.tuples(_f, _f, _f, _f).filter(lambda q: np.linalg.norm(q) > 1e-3)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    q1=_quat,
    q2=_quat,
    q3=_quat,
    t=st.tuples(_f, _f, _f),
    rough=_unit,
    colour=st.tuples(_unit, _unit, _unit),
    strength=st.floats(0.0, 1e4),
    fx=st.floats(1.0, 1e4),
    fy=st.floats(1.0, 1e4),
)
def test_random_scene_round_trips_bit_for_bit(tmp_path, q1, q2, q3, t, rough, colour, strength, fx, fy):
    s = bf.Scene()
    s.renderables.add_cube_mesh(
        1.0, bf.PrincipledBSDFMaterial(roughness=rough), bf.UniformColors(colour), rotation=q1, translation=t
    )
    s.lights.add_spot(strength, color=colour, rotation=q2, translation=t)
    s.set_perspective_camera(
        (64, 48), K=np.array([[fx, 0, 31.5], [0, fy, 23.5], [0, 0, 1]]), rotation=q3, translation=t
    )
    s.save(tmp_path / "r.npz")
    loaded = bf.Scene.load(tmp_path / "r.npz")
    assert_same_scene(s, loaded)
    assert loaded.fingerprint() == s.fingerprint()


# ---------------------------------------------------------------------------------------------------
# file textures stay lazy: the IR never decodes their pixels
# ---------------------------------------------------------------------------------------------------


def test_file_textures_are_never_decoded_by_the_core(tmp_path, data_dir, monkeypatch):
    import blendify_core.ir.colors as colors_mod

    def forbidden(path):
        raise AssertionError(f"the core decoded {path}")

    monkeypatch.setattr(colors_mod, "load_image", forbidden)
    scene = full_scene(tmp_path, data_dir, env_from_file=True)  # RGB jpg texture + environment
    tex = scene.renderables["fuze_quads"].colors
    assert tex.has_alpha is False  # from the file header
    from blendify_core.pipeline.capabilities import scene_features

    scene_features(scene, ("rgb", "depth"))
    bf.analyse_effects(scene)
    scene.fingerprint()  # hashes the file bytes, does not decode them
    scene.save(tmp_path / "lazy.npz")
    loaded = bf.Scene.load(tmp_path / "lazy.npz")
    assert loaded.fingerprint() == scene.fingerprint()
    assert tex._cache is None


def test_has_alpha_is_exact_for_small_rgba_files_and_conservative_for_huge_ones(tmp_path, monkeypatch):
    opaque = _write_png(tmp_path / "opaque.png", np.full((4, 4, 4), 255, np.uint8))
    see_through = np.full((4, 4, 4), 255, np.uint8)
    see_through[0, 0, 3] = 10
    clear = _write_png(tmp_path / "clear.png", see_through)
    uv = bf.VertexUV(np.zeros((3, 2)))
    assert bf.FileTextureColors(opaque, uv).has_alpha is False
    assert bf.FileTextureColors(clear, uv).has_alpha is True
    monkeypatch.setattr(bf.FileTextureColors, "EXACT_ALPHA_LIMIT", 8)  # pretend 4x4 is huge
    big = bf.FileTextureColors(opaque, uv)
    assert big.has_alpha is True and big._cache is None


def test_attached_blend_files_are_saved_and_fingerprinted(tmp_path):
    """scene.attached_blends (filled by attach_blend for Cycles) travels with the scene file, under the
    same path rules as textures, and its content is part of the fingerprint."""
    blend = tmp_path / "room.blend"
    blend.write_bytes(b"BLENDER-v500 fake content")
    s = every_feature_scene()
    before = s.fingerprint()
    s.attachments.append(Attachment("blend", str(blend.resolve())))
    with_blend = s.fingerprint()
    assert with_blend != before
    s.save(tmp_path / "s.npz")
    assert list(_all_paths(_header(tmp_path / "s.npz")))[-1] == "room.blend"  # relative to the scene file
    loaded = bf.Scene.load(tmp_path / "s.npz")
    assert loaded.attached_blends == (str(blend.resolve()),)
    assert loaded.attachments == [Attachment("blend", str(blend.resolve()))]
    assert loaded.fingerprint() == with_blend
    blend.write_bytes(b"BLENDER-v500 other content!")
    assert s.fingerprint() != with_blend  # the .blend's content counts
    sub = tmp_path / "sub"
    sub.mkdir()
    s.save(sub / "s.npz")
    with pytest.raises(InvalidSceneError, match="allow_outside"):
        bf.Scene.load(sub / "s.npz")
