"""Porting a blendify 2.1 script: its render keywords are mapped (with a DeprecationWarning) or refused
saying what to write; unit errors name the unit; blendify's spellings and shading defaults are kept."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.pipeline.compat import LEGACY_KEYWORDS, map_legacy_keywords
from blendify_core.pipeline.settings import resolve_settings, settings_bias

REPO = Path(__file__).resolve().parents[2]


def _mapped(outputs=("rgb",), **kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out, kw = map_legacy_keywords(outputs, kwargs)
    return out, kw, [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)]


@pytest.mark.parametrize(
    ("kwargs", "outputs", "expected"),
    [
        ({"use_gpu": True}, ("rgb",), {"device": "gpu"}),
        ({"use_gpu": False}, ("rgb",), {"device": "cpu"}),
        ({"use_denoiser": True}, ("rgb",), {"denoise": True}),
        ({"aa_filter_width": 1.5}, ("rgb",), {"pixel_filter": "blackman_harris", "pixel_filter_width": 1.5}),
        ({"aa_filter_width": 0}, ("rgb",), {"pixel_filter": "blackman_harris", "pixel_filter_width": 0.01}),
        ({"save_depth": True}, ("rgb", "depth"), {}),
        ({"save_albedo": True, "save_depth": True}, ("rgb", "albedo", "depth"), {}),
        ({"save_depth": False}, ("rgb",), {}),
    ],
)
def test_blendify_render_keywords_are_mapped_with_a_deprecation_warning(kwargs, outputs, expected):
    out, kw, messages = _mapped(**kwargs)
    assert set(out) == set(outputs) and kw == expected
    assert len(messages) == len(kwargs)
    for name, message in zip(sorted(kwargs), sorted(messages)):
        assert message.startswith(name) and "mapped to" in message


def test_mapped_keywords_reach_the_settings():
    out, kw, _ = _mapped(use_denoiser=True, aa_filter_width=2.0, save_depth=True)
    s = resolve_settings("final", outputs=out, **kw)
    assert (s.denoise, s.pixel_filter, s.pixel_filter_width, s.outputs) == (
        True,
        "blackman_harris",
        2.0,
        ("rgb", "depth"),
    )


@pytest.mark.parametrize(
    ("kwargs", "hint"),
    [
        ({"filepath": "out.png"}, r"did you mean bf\.render\(\.\.\.\)\.save\('out\.png'\)"),
        ({"fast": True}, "did you mean quality='preview'"),
        ({"use_denoiser": True, "denoise": False}, "denoise= only"),
        ({"aa_filter_width": 1.5, "pixel_filter": "box"}, "pixel_filter= / pixel_filter_width= only"),
        ({"use_gpu": "yes"}, "use_gpu"),
    ],
)
def test_keywords_without_an_equivalent_are_refused_saying_what_to_write(kwargs, hint):
    with pytest.raises(bf.InvalidSceneError, match=hint):
        map_legacy_keywords(("rgb",), kwargs)


def test_every_legacy_keyword_is_in_the_readme_migration_table():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    table = readme[readme.index("## Migrating from blendify 2.1") :]
    for name in LEGACY_KEYWORDS:
        assert f"`{name}" in table, f"README migration table does not mention {name}"
    for old, new in (
        ("estimate_normals_from_pointcloud", "estimate_normals"),
        ("PCMeshifier", "meshify_pointcloud"),
        ("add_mesh", "uv_map"),
    ):
        assert old in table and new in table


def test_unknown_render_options_suggest_the_nearest_name(fake_backend, simple_scene):
    scene = simple_scene()
    with pytest.raises(bf.InvalidSceneError, match=r"unknown option\(s\) \['sample'\]; did you mean samples=\?"):
        bf.render(scene, "fake", sample=4)
    with pytest.raises(bf.InvalidSceneError, match="did you mean denoise="):
        bf.render(scene, "fake", denoiser=True)
    with pytest.raises(bf.InvalidSceneError, match=r"did you mean device='gpu'"):
        bf.render(scene, "fake", use_gpus=True)
    with pytest.raises(bf.InvalidSceneError, match=r"unknown option\(s\) \['zzz'\]$"):
        bf.render(scene, "fake", zzz=1)


def test_render_maps_outputs_and_warns(fake_backend, simple_scene):
    with pytest.warns(DeprecationWarning, match="save_depth"):
        result = bf.render(simple_scene(), "fake", samples=1, save_depth=True, use_denoiser=False)
    assert result.depth is not None and result.meta["settings"]["outputs"] == ["rgb", "depth"]


def test_blendify_scene_methods_say_what_to_call():
    scene = bf.Scene()
    with pytest.raises(AttributeError, match=r"Scene\.render: blendify 2\.1's method; did you mean bf\.render"):
        scene.render()
    with pytest.raises(AttributeError, match="quality='preview'"):
        scene.preview(fast=True)
    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        scene.nonsense  # noqa: B018
    assert not hasattr(scene, "render")


# -- units --------------------------------------------------------------------------------------------


def test_angles_in_degrees_are_refused_naming_radians():
    scene = bf.Scene()
    with pytest.raises(
        bf.InvalidSceneError, match=r"fov_x: expected radians < pi, got 40; did you mean np\.deg2rad\(40\)\?"
    ):
        scene.set_perspective_camera((32, 24), fov_x=40)
    with pytest.raises(bf.InvalidSceneError, match=r"fov_y: .*radians.*np\.deg2rad\(75\)"):
        scene.set_perspective_camera((32, 24), fov_y=75)
    with pytest.raises(bf.InvalidSceneError, match=r"spot_size: expected radians in .*np\.deg2rad\(47\.6\)"):
        scene.lights.add_spot(100.0, spot_size=47.6)
    # a radian value is accepted; a value beyond 360 gets no degree hint
    scene.set_perspective_camera((32, 24), fov_x=np.deg2rad(40))
    with pytest.raises(bf.InvalidSceneError) as err:
        scene.set_perspective_camera((32, 24), fov_x=1000)
    assert "deg2rad" not in str(err.value) and "radians" in str(err.value)


# -- spellings and defaults ------------------------------------------------------------------------------


@pytest.mark.parametrize("shape", ["disk", "DISK", "circle", "Circle"])
def test_area_light_accepts_blenders_disk_for_circle(shape):
    light = bf.Scene().lights.add_area(shape, 0.5, 10.0)
    assert light.shape == "circle"
    assert light.area == pytest.approx(np.pi * 0.25**2)


def test_per_face_uvs_on_mixed_polygon_sizes():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]], float)
    faces = [[0, 1, 2, 3], [1, 4, 2]]
    quad = np.array([[0.0, 0.0], [0.5, 0.0], [0.5, 1.0], [0.0, 1.0]])
    tri = np.array([[0.5, 0.0], [1.0, 0.0], [0.5, 1.0]])
    tex = np.zeros((4, 4, 3))
    for uv in (bf.FacesUV([quad, tri]), bf.FacesUV(np.stack([quad, np.vstack([tri, [[9.0, 9.0]]])]))):
        mesh = bf.Scene().renderables.add_mesh(v, faces, bf.DiffuseMaterial(), bf.TextureColors(tex, uv))
        uvs = mesh.triangle_uvs()
        for t, poly in enumerate(mesh.face_polygon):
            corners = [faces[poly].index(int(i)) for i in mesh.faces[t]]
            np.testing.assert_allclose(uvs[t], [quad, tri][poly][corners])
    with pytest.raises(bf.InvalidSceneError, match=r"from 3 to 4 corners: expected \(M, 4, 2\)"):
        bf.Scene().renderables.add_mesh(
            v, faces, bf.DiffuseMaterial(), bf.TextureColors(tex, bf.FacesUV(np.zeros((2, 3, 2))))
        )


def test_mixed_polygon_uvs_survive_a_scene_file(tmp_path):
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]], float)
    uv = bf.FacesUV([np.array([[0, 0], [1, 0], [1, 1], [0, 1]]), np.array([[0, 0], [1, 0], [1, 1]])])
    scene = bf.Scene()
    scene.renderables.add_mesh(
        v, [[0, 1, 2, 3], [1, 4, 2]], bf.DiffuseMaterial(), bf.TextureColors(np.zeros((2, 2, 3)), uv)
    )
    scene.save(tmp_path / "s.npz")
    back = bf.Scene.load(tmp_path / "s.npz")
    np.testing.assert_array_equal(
        back.renderables.values()[0].triangle_uvs(), scene.renderables.values()[0].triangle_uvs()
    )


def _normals(obj):
    mesh = obj.to_mesh()
    return mesh.vertices, mesh.faces, mesh.normals


def test_primitives_shade_like_blendify_smooth_with_an_edge_split():
    r = bf.Scene().renderables
    m, c = bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1))
    round_cyl = r.add_cylinder_mesh(1.0, 2.0, m, c, num_vertices=32)
    assert round_cyl.smooth
    v, f, n = _normals(round_cyl)
    side = np.abs(n[:, 2]) < 1e-9
    # round sides: radial normals at the vertices (interpolated across the faces)
    np.testing.assert_allclose(n[side], v[side] * [1, 1, 0], atol=1e-9)
    # caps stay flat
    assert np.all(np.abs(np.abs(n[~side, 2]) - 1) < 1e-9)
    # an 8-sided cylinder: 45 degrees between sides > the 30 degree split: every side is flat
    v, f, n = _normals(r.add_cylinder_mesh(1.0, 2.0, m, c, num_vertices=8))
    for tri in f:
        face_n = np.cross(v[tri[1]] - v[tri[0]], v[tri[2]] - v[tri[0]])
        face_n /= np.linalg.norm(face_n)
        np.testing.assert_allclose(n[tri], np.repeat(face_n[None], 3, axis=0), atol=1e-9)
    # a cube: all edges sharp
    v, f, n = _normals(r.add_cube_mesh(1.0, m, c))
    assert np.allclose(np.abs(n).max(axis=1), 1.0)
    flat = r.add_cylinder_mesh(1.0, 2.0, m, c)
    flat.set_smooth(False)
    assert flat.to_mesh().normals is None and not flat.to_mesh().smooth


def test_primitive_shading_round_trips_a_scene_file(tmp_path):
    scene = bf.Scene()
    a = scene.renderables.add_cylinder_mesh(1.0, 2.0, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)), tag="a")
    scene.renderables.add_cylinder_mesh(1.0, 2.0, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)), tag="b")
    a.set_smooth(False)
    scene.save(tmp_path / "s.npz")
    back = bf.Scene.load(tmp_path / "s.npz")
    assert (back.renderables["a"].smooth, back.renderables["b"].smooth) == (False, True)


# -- the blendify look -------------------------------------------------------------------------------------


def test_blendify_preset_reproduces_blenders_defaults_and_states_its_bias():
    s = resolve_settings("blendify")
    assert (s.samples, s.denoise, s.adaptive, s.clamp_indirect, s.filter_glossy) == (128, False, True, 10.0, 1.0)
    assert (s.pixel_filter, s.pixel_filter_width) == ("blackman_harris", 1.5)
    assert [s.bounces(k) for k in ("diffuse", "glossy", "transmission", "transparent")] == [4, 4, 12, 8]
    bias = " ".join(settings_bias(s))
    for word in ("clamp_indirect=10", "filter_glossy=1", "adaptive", "diffuse 4", "glossy 4"):
        assert word in bias
    # final stays unbiased; overrides win over the preset
    assert settings_bias(resolve_settings("final")) == []
    s = resolve_settings(
        "blendify", clamp_indirect=0, filter_glossy=0, adaptive=False, diffuse_bounces=12, glossy_bounces=12
    )
    assert settings_bias(s) == []


def test_bias_is_recorded_in_meta(fake_backend, simple_scene):
    result = bf.render(simple_scene(), "fake", samples=1, quality="final", filter_glossy=0.5)
    assert result.meta["bias"] == []  # the fake backend is not a path tracer
    with pytest.raises(bf.InvalidSceneError, match="pixel_filter"):
        resolve_settings(pixel_filter="mitchell")
    with pytest.raises(bf.InvalidSceneError, match="pixel_filter_width"):
        resolve_settings(pixel_filter_width=0)


def test_use_gpu_reaches_every_backend():
    """blendify's default use_gpu=True maps to device='gpu', which every backend takes (pyrender: EGL
    device 0); use_gpu=False on pyrender says what to pass instead."""
    from blendify_core.registry import get_backend_class

    # A backend that is not installed (the core-only CI step) is not registered at all.
    status = bf.available_backends()
    usable = [name for name in ("cycles", "mitsuba", "pyrender") if name in status and status[name].available]
    if not usable:
        pytest.skip("no backend is installed here (core-only environment)")
    for name in usable:
        get_backend_class(name)(device="gpu")
    if "pyrender" in usable:
        assert get_backend_class("pyrender")(device="gpu").device == 0
        with pytest.raises(bf.InvalidSceneError, match="platform='osmesa'"):
            get_backend_class("pyrender")(device="cpu")


def test_blendify_positional_pose_in_add_mesh_is_explained():
    v, f = np.eye(3), [[0, 1, 2]]
    with pytest.raises(bf.InvalidSceneError, match="blendify 2.1's add_mesh took rotation_mode there"):
        bf.Scene().renderables.add_mesh(v, f, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)), None, "quaternionWXYZ")
