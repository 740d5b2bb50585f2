"""Tiny Cycles renders: camera self-test, light units, outputs, determinism, textures, environment map."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf
from blendify_core import testing
from blendify_core.ir.lights import equirect_uv

pytestmark = pytest.mark.cycles


def alpha_centroids(rgba: np.ndarray, pixels: np.ndarray, window: int = 6) -> np.ndarray:
    """Alpha-weighted centroids (OpenCV pixel coordinates) in a window around each expected pixel."""
    from blendify_core.evaluate.metrics import alpha_centroids as centroids
    from blendify_core.pipeline.result import RenderResult

    return centroids(RenderResult(rgba=rgba), pixels, window)


# -- camera self-test ---------------------------------------------------------------------------------
@pytest.mark.parametrize("kw", [{}, {"fy": 185.0}, {"orthographic": True}], ids=["square", "fx_ne_fy", "orthographic"])
def test_camera_markers_land_within_0_1_px(cycles, kw):
    scene, pixels = testing.marker_scene(**kw)
    r = bf.render(scene, backend=cycles, samples=32, outputs=("rgb", "depth", "normal", "albedo", "instance"))
    assert r.rgba.shape == (120, 160, 4)
    err = np.linalg.norm(alpha_centroids(r.rgba, pixels) - pixels, axis=1)
    assert err.max() < 0.1, err
    # every marker gets its own id at its expected pixel (non-square pixels use the per-pass EXR path)
    for i, (u, v) in enumerate(pixels):
        assert r.instance[int(round(v)), int(round(u))] == i
        assert r.instance_tags[i] == f"marker_{i}"
    assert (r.instance == -1).mean() > 0.9 and np.isinf(r.depth[r.instance == -1]).all()


# -- light units: Lambert plane rho = 0.5, L = rho / pi * E --------------------------------------------
def _pixel_centres(scene):
    origins, _ = scene.camera.pixel_rays()
    h, w = scene.camera.height, scene.camera.width
    return origins[:, :2].reshape(h, w, 2)


def _area_irradiance(xy, size, height, power, disk=False, n=160):
    a = size
    g = (np.arange(n) + 0.5) / n * a - a / 2
    ex, ey = np.meshgrid(g, g)
    keep = (ex**2 + ey**2 <= (a / 2) ** 2) if disk else np.ones_like(ex, bool)
    ex, ey = ex[keep], ey[keep]
    area = np.pi * a * a / 4 if disk else a * a
    da = area / keep.sum() if disk else (a / n) ** 2
    le = power / (np.pi * area)
    d2 = (xy[..., 0:1] - ex) ** 2 + (xy[..., 1:2] - ey) ** 2 + height**2
    return (le * height**2 / d2**2 * da).sum(axis=-1)


@pytest.mark.parametrize("light", ["point", "sun", "spot", "area", "area_disk", "background"])
def test_light_units_match_analytic_radiance(cycles, light):
    scene = testing.plane_scene(light)
    r = bf.render(scene, backend=cycles, samples=64, max_bounces=0)
    xy = _pixel_centres(scene)
    if light == "point":
        d2 = (xy**2).sum(-1) + 4.0
        e = 100.0 / (4 * np.pi) * 2.0 / d2**1.5
    elif light == "spot":
        d2 = (xy**2).sum(-1) + 4.0
        e = 200.0 / (4 * np.pi) * 2.0 / d2**1.5
    elif light == "sun":
        e = np.full(xy.shape[:2], 3.0 * np.cos(np.deg2rad(20)))
    elif light == "background":
        e = np.full(xy.shape[:2], np.pi)
    else:
        e = _area_irradiance(xy[24:40, 24:40], 0.5, 1.5, 100.0, disk=light == "area_disk")
    expected = 0.5 / np.pi * e
    got = r.rgba[..., 0].astype(np.float64)
    if light.startswith("area"):
        ratio = got[24:40, 24:40].mean() / expected.mean()
    else:
        ratio = np.median(got / expected)
        assert np.abs(got / expected - 1).max() < 0.02
    assert ratio == pytest.approx(1.0, abs=0.01), ratio


# -- outputs ------------------------------------------------------------------------------------------
def test_depth_is_planar_and_not_antialiased(cycles):
    scene = testing.depth_plane_scene()
    r = bf.render(scene, backend=cycles, samples=4, outputs=("depth",))
    assert r.rgba is None and r.depth.dtype == np.float32
    e = testing.expected_plane_depth(scene)
    hit = np.isfinite(e)
    np.testing.assert_allclose(r.depth[hit], e[hit], rtol=1e-3)
    assert np.isinf(r.depth[~hit]).all()


def test_albedo_normal_instance(cycles):
    scene = bf.Scene()
    scene.renderables.add_plane_mesh(4.0, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.2, 0.1)), tag="ground")
    scene.renderables.add_sphere_nurbs(
        0.5, bf.MetalMaterial(), bf.UniformColors((0.2, 0.4, 0.9)), translation=(0, 0, 0.5), tag="ball"
    )
    scene.set_orthographic_camera((48, 48), ortho_scale=3.0, translation=(0, 0, 5))
    scene.lights.set_background_light(1.0)
    r = bf.render(scene, backend=cycles, samples=8, outputs=("rgb", "albedo", "normal", "instance"))
    assert r.instance[24, 24] == 1 and r.instance[2, 2] == 0
    assert r.instance_tags == ["ground", "ball"]
    np.testing.assert_allclose(r.albedo[2, 2], bf.UniformColors((0.8, 0.2, 0.1)).linear_rgba[:3], atol=1e-5)
    # a metal's albedo is its colour input (Cycles' Diffuse Color pass would be 0)
    np.testing.assert_allclose(r.albedo[24, 24], bf.UniformColors((0.2, 0.4, 0.9)).linear_rgba[:3], atol=1e-5)
    np.testing.assert_allclose(r.normal[2, 2], [0, 0, 1], atol=1e-5)
    np.testing.assert_allclose(r.normal[24, 24], [0, 0, 1], atol=0.1)
    nrm = np.linalg.norm(r.normal, axis=-1)
    assert np.allclose(nrm[r.instance >= 0], 1.0, atol=1e-4)


@pytest.mark.parametrize("faces_uv", [False, True])
def test_texture_orientation(cycles, faces_uv):
    scene = testing.textured_quad_scene(faces_uv=faces_uv)
    r = bf.render(scene, backend=cycles, samples=4, outputs=("rgb", "albedo"))
    for (v, u), c in zip([(16, 16), (16, 48), (48, 16), (48, 48)], [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)]):
        np.testing.assert_allclose(r.rgba[v, u, :3], c, atol=1e-4)
        np.testing.assert_allclose(r.albedo[v, u], c, atol=1e-4)


def test_vertex_colors_reach_the_albedo(cycles):
    scene = bf.Scene()
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float)
    cols = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.5, 0.5, 0.5]])
    scene.renderables.add_mesh(v, [[0, 1, 2], [0, 2, 3]], bf.DiffuseMaterial(), bf.VertexColors(cols))
    scene.set_orthographic_camera((64, 64), ortho_scale=2.0, translation=(0, 0, 3))
    r = bf.render(scene, backend=cycles, samples=1, outputs=("albedo",))
    lin = bf.VertexColors(cols).linear_rgba[:, :3]
    np.testing.assert_allclose(r.albedo[63, 0], lin[0], atol=0.03)  # bottom-left = vertex 0
    np.testing.assert_allclose(r.albedo[0, 63], lin[2], atol=0.03)  # top-right = vertex 2


def test_environment_map_matches_the_ir_mapping(cycles):
    """Cycles' equirectangular lookup == blendify_core.ir.lights.equirect_uv (rotation included)."""
    h, w = 64, 128
    img = np.zeros((h, w, 3), np.float32)
    img[..., 0] = ((np.arange(w) + 0.5) / w)[None, :]
    img[..., 1] = (1 - (np.arange(h) + 0.5) / h)[:, None]
    scene = bf.Scene()
    env = scene.lights.set_environment_map(img, rotation_mode="eulerXYZ", rotation=(10, 0, 30))
    for d in np.array([[1, 0, 0], [-1, 0.2, 0.1], [0.3, -1, 0.4], [0.2, 0.3, -0.8]], float):
        d = d / np.linalg.norm(d)
        scene.set_perspective_camera(
            (8, 8), fov_x=np.deg2rad(0.5), rotation_mode="look_at", rotation=d * 10, translation=(0, 0, 0)
        )
        r = bf.render(scene, backend=cycles, samples=2, transparent_background=False)
        uv = r.rgba[3:5, 3:5, :2].mean(axis=(0, 1))
        expected = equirect_uv(env.rotation_matrix.T @ d)
        np.testing.assert_allclose(uv, expected, atol=2e-3)


def test_pointclouds_any_number(cycles):
    scene = testing.pointcloud_scene(n=500, resolution=(48, 48))
    scene.renderables.add_pointcloud(
        np.zeros((1, 3)), bf.DiffuseMaterial(), bf.UniformColors((1, 0, 0)), point_size=0.6, tag="big"
    )
    r = bf.render(scene, backend=cycles, samples=4, outputs=("rgb", "instance"))
    assert set(np.unique(r.instance)) == {-1, 0, 1}
    assert (r.instance == 0).sum() > 20


# -- shadows ------------------------------------------------------------------------------------------
def _shadow_scene(catcher=False, emit=True, light_shadow=True):
    scene = bf.Scene()
    scene.renderables.add_plane_mesh(
        4.0, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), shadow_catcher=catcher, tag="ground"
    )
    ball = scene.renderables.add_sphere_nurbs(
        0.3, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), translation=(0.8, 0.8, 1.0), tag="ball"
    )
    ball.emit_shadows = emit
    # light travels along (0, sin 30, -cos 30): the shadow falls at y = 0.8 + tan 30 ~ 1.38 (pixel row ~4.5)
    scene.lights.add_sun(
        3.0, angular_diameter=0.0, use_shadow=light_shadow, rotation_mode="eulerXYZ", rotation=(30, 0, 0)
    )
    scene.set_orthographic_camera((32, 32), ortho_scale=4.0, translation=(0, 0, 5))
    return scene


def test_shadow_switches(cycles):
    base = bf.render(_shadow_scene(), backend=cycles, samples=4, max_bounces=0).rgba
    v, u = 4, 22  # (x, y) = (0.81, 1.44): in the ball's shadow, not under the ball
    assert base[v, u, 0] < 0.05 and base[2, 2, 0] > 0.15
    no_emit = bf.render(_shadow_scene(emit=False), backend=cycles, samples=4, max_bounces=0).rgba
    assert no_emit[v, u, 0] > 0.15
    no_light_shadow = bf.render(_shadow_scene(light_shadow=False), backend=cycles, samples=4, max_bounces=0).rgba
    assert no_light_shadow[v, u, 0] > 0.15
    catcher = bf.render(_shadow_scene(catcher=True), backend=cycles, samples=8, max_bounces=0).rgba
    assert catcher[2, 2, 3] < 0.02  # the catcher is invisible where it is lit
    assert catcher[v, u, 3] > 0.9  # and opaque (dark) in the shadow


# -- determinism and hygiene --------------------------------------------------------------------------
def test_seed_determinism(cycles):
    scene = testing.pointcloud_scene(n=300, resolution=(32, 32))
    a = bf.render(scene, backend=cycles, samples=2, seed=3).rgba
    b = bf.render(scene, backend=cycles, samples=2, seed=3).rgba
    c = bf.render(scene, backend=cycles, samples=2, seed=4).rgba
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def _sphere_edge_pixel() -> bf.Scene:
    """One pixel half covered by a sphere's silhouette (its converged coverage about 0.52)."""
    scene = bf.Scene()
    testing.look_at_camera(scene, (1, 1), (0.0, -5.0, 0.0), (1.0, 0.0, 0.0), fov_x=2 * np.arctan(0.25 / 5))
    scene.renderables.add_sphere_nurbs(1.0, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)))
    scene.lights.add_point(strength=100.0, translation=(0, -4, 3))
    return scene


def test_first_sample_moves_with_the_seed(cycles):
    """Cycles fixes each pixel's first sample at its centre whatever the seed; colour renders skip it: at 1 spp
    the edge pixel differs between seeds, and the mean over seeds of a 16-spp render is its converged coverage
    (with the centre sample: 0.547 against 0.517, 200 seeds)."""
    scene = _sphere_edge_pixel()
    reference = float(bf.render(scene, backend=cycles, samples=4096).rgba[0, 0, 3])
    one = [float(bf.render(scene, backend=cycles, samples=1, seed=s).rgba[0, 0, 3]) for s in range(12)]
    assert 0.0 in one and 1.0 in one, one  # the centre is inside: always 1.0 before
    r16 = [bf.render(scene, backend=cycles, samples=16, seed=s) for s in range(40)]
    mean = float(np.mean([r.rgba[0, 0, 3] for r in r16]))
    assert abs(mean - reference) < 0.012, (mean, reference)  # standard error about 0.003
    assert r16[0].meta["engine_settings"]["sample_offset"] == 16
    # the depth and object-index passes come from Cycles' first sample: rendered apart, the colour is the same
    every = bf.render(scene, backend=cycles, samples=16, outputs=("rgb", "depth", "instance", "normal", "albedo"))
    assert every.meta["engine_settings"]["sample_offset"] == 16
    assert np.array_equal(every.rgba, r16[0].rgba)
    assert np.isfinite(every.depth[0, 0]) and every.instance[0, 0] == 0
    assert np.linalg.norm(every.normal[0, 0]) == pytest.approx(1.0, abs=1e-3) and every.albedo[0, 0].max() > 0.1


def test_sample_window_is_an_aligned_block_after_the_first_sample():
    from blendify_blender.render import sample_window

    assert [sample_window(n, ("rgb",)) for n in (1, 2, 3, 16, 17, 1000)] == [1, 2, 4, 16, 32, 1024]
    assert sample_window(1 << 24, ("rgb",)) == 0  # no room: Cycles' own samples
    assert sample_window((1 << 23) + 1, ("rgb",)) == 1
    for first_sample_only in ("depth", "instance"):
        assert sample_window(16, ("rgb", first_sample_only)) == 0
    assert sample_window(16, ("rgb", "normal", "albedo")) == 16  # accumulated over the samples
    assert sample_window(16, ("normal",)) == 0  # no colour: Cycles' own first sample


def test_uint8_texture_decoded_like_the_ir(cycles):
    scene = bf.Scene()
    tex = np.full((4, 4, 3), 128, dtype=np.uint8)
    tex[..., 2] = 30
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float)
    uv = bf.VertexUV(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float))
    colors = bf.TextureColors(tex, uv)
    scene.renderables.add_mesh(v, [[0, 1, 2, 3]], bf.DiffuseMaterial(), colors)
    scene.set_orthographic_camera((16, 16), ortho_scale=2.0, translation=(0, 0, 3))
    r = bf.render(scene, backend=cycles, samples=1, outputs=("albedo",))
    np.testing.assert_allclose(r.albedo[8, 8], colors.linear_rgba_image()[0, 0, :3], rtol=1e-4)


def test_emissive_points_and_materials_without_lights(cycles):
    scene = bf.Scene()
    scene.renderables.add_pointcloud(
        np.zeros((1, 3)),
        bf.DiffuseMaterial(),
        bf.UniformColors((1.0, 0.5, 0.25), color_space="linear"),
        point_size=1.0,
        particle_emission_strength=2.0,
    )
    scene.set_orthographic_camera((16, 16), ortho_scale=2.0, translation=(0, 0, 3))
    with pytest.warns(UserWarning, match="no lights"):
        r = bf.render(scene, backend=cycles, samples=4, max_bounces=0)
    np.testing.assert_allclose(r.rgba[8, 8, :3], [2.0, 1.0, 0.5], rtol=1e-3)


def test_target_error_runs_passes(cycles):
    scene = testing.plane_scene("area", resolution=(16, 16))
    r = bf.render(scene, backend=cycles, samples=2, target_error=0.05, max_bounces=0)
    assert r.meta["passes"] >= 4 and r.meta["estimated_error"] > 0


def test_gpu_request_falls_back_to_cpu():
    from blendify_blender import CyclesBackend

    with CyclesBackend(device="GPU") as b:
        if b.device_choice().fallback is None:
            pytest.skip(f"this machine has a GPU: {b.device_choice().used}")
        with pytest.warns(UserWarning, match="device='gpu' is unavailable here"):
            r = bf.render(testing.plane_scene("sun", resolution=(8, 8)), backend=b, samples=1)
    es = r.meta["engine_settings"]
    assert es["device"] == "CPU" and es["compute_device_type"] == "NONE" and r.meta["device"] == "CPU"


def test_wireframe_overlay(cycles):
    scene = bf.Scene()
    mat = bf.PrincipledBSDFWireframeMaterial(wireframe_thickness=0.05, wireframe_color=(1, 0, 0), specular_ior=0.0)
    scene.renderables.add_plane_mesh(2.0, mat, bf.UniformColors((0, 0, 1)))
    scene.set_orthographic_camera((40, 40), ortho_scale=2.0, translation=(0, 0, 3))
    scene.lights.set_background_light(1.0)
    r = bf.render(scene, backend=cycles, samples=8, outputs=("rgb", "albedo"))
    assert r.rgba[10, 10, 2] > 0.5 and r.rgba[10, 10, 0] < 0.05  # face interior: blue
    assert r.rgba[20, 0, 0] > 0.3  # the border edge: red wire (its edge runs through the pixel centres)
    diag = np.array([r.rgba[i, 39 - i, 0] for i in range(5, 35)])
    assert diag.min() > 0.2  # the triangulation's diagonal (vertex 0 to 2) is an edge too
    # the albedo is the pixel centre's: red on the diagonal, blue inside the face
    assert min(r.albedo[i, 39 - i, 0] for i in range(5, 35)) > 0.9 and r.albedo[10, 10, 2] > 0.9


def test_every_feature_scene_all_outputs(cycles):
    scene = testing.every_feature_scene((48, 36))
    outputs = ("rgb", "depth", "normal", "albedo", "instance")
    r = bf.render(scene, backend=cycles, samples=2, outputs=outputs)
    ids = set(np.unique(r.instance).tolist())
    assert -1 in ids and len(ids - {-1}) >= len(scene.renderables) - 1  # (nearly) every object is seen
    assert np.isfinite(r.rgba).all() and r.meta["approximations"] == []
    es = r.meta["engine_settings"]
    assert es["glossy_bounces"] > 0 and es["transparent_max_bounces"] > 0  # glossy + alpha in the scene


def test_two_sided_shading(cycles):
    scene = testing.plane_scene("sun")
    scene.renderables["plane"].set_position(rotation_mode="eulerXYZ", rotation=(180, 0, 0))  # facing away
    scene.lights.clear()
    scene.lights.add_sun(3.0, angular_diameter=0.0)
    scene.set_orthographic_camera((16, 16), ortho_scale=2.0, translation=(0, 0, 5.0))
    r = bf.render(scene, backend=cycles, samples=4, max_bounces=0, outputs=("rgb", "normal"))
    np.testing.assert_allclose(r.rgba[8, 8, 0], 0.5 / np.pi * 3.0, rtol=1e-3)


def test_denoised_preview_render(cycles):
    scene = testing.bunny_scene((32, 32))
    r = bf.render(scene, backend=cycles, quality="preview", outputs=("rgb", "albedo", "normal"))
    es = r.meta["engine_settings"]
    assert es["denoise"] and es["samples"] == 8 and es["max_bounces"] == 4
    assert np.isfinite(r.rgba).all() and r.rgba[..., 3].max() == pytest.approx(1.0, abs=1e-3)
