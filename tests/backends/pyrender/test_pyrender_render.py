"""Small renders with the pyrender backend: camera self-test, depth, instance ids, light units, colour
handling, anti-aliasing, shadows, every feature, unsupported requests, sessions."""

from __future__ import annotations

import numpy as np
import pytest
from blendify_pyrender import PyrenderBackend
from blendify_pyrender._platform import egl_available, osmesa_available, resolve_platform
from pyrender_test_utils import alpha_centroids

from blendify_core import (
    DiffuseMaterial,
    PrincipledBSDFMaterial,
    Scene,
    UniformColors,
    VertexColors,
    render,
    testing,
)
from blendify_core.errors import UnsupportedFeatureError
from blendify_core.pipeline.backend import Backend
from blendify_core.pipeline.capabilities import Capability

pytestmark = pytest.mark.pyrender
ALL = ("rgb", "depth", "normal", "albedo", "instance")


# -- camera self-test ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs",
    [dict(), dict(fy=185.0), dict(orthographic=True), dict(orthographic=True, center=(70.2, 64.9))],
    ids=["square", "fx!=fy", "ortho", "ortho-offset"],
)
def test_markers_land_on_the_projected_pixels(pyr, kwargs):
    scene, pixels = testing.marker_scene(**kwargs)
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"))
    c = alpha_centroids(res.rgba, pixels)
    err = np.abs(c - pixels).max()
    assert err < 0.1, f"max centroid error {err:.3f} px"
    # each marker's instance id is its index in scene.renderables
    for i, (u, v) in enumerate(pixels):
        assert res.instance[int(round(v)), int(round(u))] == i


def test_markers_with_msaa_and_supersampling():
    scene, pixels = testing.marker_scene(fy=185.0)
    for aa in ("msaa", "ssaa"):
        with PyrenderBackend(antialias=aa, supersample=3) as be:
            res = render(scene, backend=be, quality="preview")
        assert np.abs(alpha_centroids(res.rgba, pixels) - pixels).max() < 0.1, aa
        a = res.rgba[..., 3]
        assert ((a > 0.05) & (a < 0.95)).sum() > 20, aa  # soft silhouettes
        # premultiplied at the anti-aliased edges: the grey markers' colour never exceeds their alpha
        assert np.all(res.rgba[..., :3] <= a[..., None] + 1e-6), aa


# -- depth and geometric outputs -------------------------------------------------------------------------
def test_plane_depth_is_exact(pyr):
    scene = testing.depth_plane_scene()
    res = render(scene, backend=pyr, quality="preview", outputs=("depth",))
    expected = testing.expected_plane_depth(scene)
    hit = np.isfinite(expected)
    assert np.array_equal(np.isfinite(res.depth), hit)
    rel = np.abs(res.depth[hit] - expected[hit]) / expected[hit]
    assert rel.max() < 1e-4
    assert res.rgba is None and res.depth.dtype == np.float32


def test_orthographic_depth_is_planar(pyr):
    scene = testing.plane_scene("sun")  # ortho camera at z=5 looking down at the plane z=0
    res = render(scene, backend=pyr, quality="preview", outputs=("depth", "normal"))
    assert np.isfinite(res.depth).all()
    np.testing.assert_allclose(res.depth, 5.0, rtol=1e-5)
    np.testing.assert_allclose(res.normal.reshape(-1, 3), np.tile([0, 0, 1.0], (64 * 64, 1)), atol=1e-5)


def _two_squares() -> Scene:
    """Two overlapping axis-aligned squares under an orthographic camera; edges on pixel boundaries."""
    scene = Scene()
    r = scene.renderables
    r.add_plane_mesh(1.0, DiffuseMaterial(), UniformColors((0.2, 0.4, 0.6), color_space="linear"), tag="a")
    r.add_plane_mesh(
        0.5,
        DiffuseMaterial(),
        UniformColors((0.9, 0.1, 0.1), color_space="linear"),
        translation=(0.25, 0.25, 0.5),
        tag="b",
    )
    scene.set_orthographic_camera((64, 64), ortho_scale=2.0, translation=(0, 0, 5.0), near=0.1, far=20)
    scene.lights.set_background_light(1.0)
    return scene


def test_instance_depth_albedo_are_exact(pyr):
    scene = _two_squares()
    res = render(scene, backend=pyr, quality="preview", outputs=ALL)
    # pixel size 1/32: square a covers x, y in [-0.5, 0.5] -> pixels 16..47; b covers [0, 0.5] -> 32..47
    expected = np.full((64, 64), -1)
    expected[16:48, 16:48] = 0
    expected[16:32, 32:48] = 1  # +y is up: rows 16..31 are y in [0, 0.5]
    assert np.array_equal(res.instance, expected)
    assert res.instance_tags == ["a", "b"]
    np.testing.assert_allclose(res.depth[expected == 0], 5.0, rtol=1e-6)
    np.testing.assert_allclose(res.depth[expected == 1], 4.5, rtol=1e-6)
    assert np.isinf(res.depth[expected == -1]).all()
    np.testing.assert_allclose(
        res.albedo[expected == 0], np.tile([0.2, 0.4, 0.6], ((expected == 0).sum(), 1)), atol=1e-6
    )
    np.testing.assert_allclose(
        res.albedo[expected == 1], np.tile([0.9, 0.1, 0.1], ((expected == 1).sum(), 1)), atol=1e-6
    )
    assert (res.normal[expected == -1] == 0).all() and (res.albedo[expected == -1] == 0).all()
    # the background light shades albedo x radiance exactly (ambient x 0.96 x base / 0.96), 8-bit precision
    np.testing.assert_allclose(res.rgba[32, 20, :3], [0.2, 0.4, 0.6], rtol=0.03)
    assert res.rgba[0, 0, 3] == 0.0 and res.rgba[20, 20, 3] == 1.0


def test_back_faces_are_two_sided(pyr):
    scene = testing.plane_scene("sun")
    scene.camera.translation = (0, 0, -5.0)
    scene.camera.set_position(rotation_mode="look_at", rotation=(0, 0, 0), translation=(0, 0, -5.0))
    scene.lights.clear()
    scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(180, 0, 0))  # shining upwards (+Z)
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "normal"))
    centre = res.normal[32, 32]
    np.testing.assert_allclose(centre, [0, 0, -1.0], atol=1e-5)
    assert res.rgba[32, 32, :3].mean() > 0.3  # lit from below: shaded with the flipped normal


# -- light units and colours ---------------------------------------------------------------------------
@pytest.mark.parametrize("light", ["sun", "point", "background"])
def test_light_units_on_a_lambert_plane(pyr, light):
    scene = testing.plane_scene(light)
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb",), samples=1)
    rho = 0.5
    if light == "sun":
        expected = rho / np.pi * 3.0 * np.cos(np.deg2rad(20.0))
        got = res.rgba[32, 32, 0]
        tol = 0.04  # GGX F0 0.04 lobe
    elif light == "point":
        # pixel (32, 32) centre: x = y = 1/64 world units from the axis, light 2 m above
        d2 = 2.0**2 + 2 * (1 / 64) ** 2
        expected = rho / np.pi * 100.0 / (4 * np.pi) / d2 * (2.0 / np.sqrt(d2))
        got = res.rgba[32, 32, 0]
        tol = 0.04
    else:
        expected, got, tol = rho * 1.0, res.rgba[32, 32, 0], 0.02
    assert got == pytest.approx(expected, rel=tol)


def _rectangle_form_factor(half_x: float, half_y: float, height: float) -> float:
    """Point-to-rectangle form factor for a point under the rectangle's centre (four corner rectangles)."""
    a, b = half_x / height, half_y / height
    ra, rb = np.sqrt(1 + a * a), np.sqrt(1 + b * b)
    return 4 * (a / ra * np.arctan(b / ra) + b / rb * np.arctan(a / rb)) / (2 * np.pi)


@pytest.mark.parametrize("light", ["area", "area_disk"])
def test_plane_radiance_above_one_is_kept(pyr, light):
    """The colour pass is float: the plane under the canonical area light reaches radiance ~2.2 (the
    8-bit pass clipped it at 1)."""
    scene = testing.plane_scene(light, resolution=(32, 32))
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb",), samples=1)
    assert not any("8-bit" in a for a in res.meta["approximations"]), res.meta["approximations"]
    got = res.rgba[15:17, 15:17, :3].mean()
    if light == "area":  # a 0.5 x 0.5 square of 100 W, 1.5 above the plane's centre, albedo 0.5
        radiance = 100.0 / (np.pi * 0.25)
        expected = 0.5 / np.pi * np.pi * radiance * _rectangle_form_factor(0.25, 0.25, 1.5)
        assert got == pytest.approx(expected, rel=0.04)  # area integration within 2 %, F0 lobe -0.8 %
    assert got > 1.9
    # the whole image: above 1 wherever the irradiance is, no plateau at 1
    assert np.count_nonzero(np.isclose(res.rgba[..., :3], 1.0, atol=1e-3)) < 0.01 * res.rgba[..., :3].size


def test_emission_above_one_keeps_its_value(pyr):
    scene = Scene()
    black = UniformColors((0.0, 0.0, 0.0), color_space="linear")
    mat = PrincipledBSDFMaterial(emission_color=(1.0, 0.5, 0.25, 1.0), emission_strength=3.0)
    scene.renderables.add_plane_mesh(1.0, mat, black, tag="emitter")
    scene.set_orthographic_camera((32, 32), ortho_scale=2.0, translation=(0, 0, 5.0))
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb",), samples=1)
    expected = 3.0 * mat.linear("emission_color")[:3]
    np.testing.assert_allclose(res.rgba[16, 16, :3], expected, rtol=1e-3)
    assert res.rgba[16, 16, 0] > 2.9


def test_dark_gradient_is_not_quantised(pyr):
    """A dim gradient (radiance 0 .. 0.005) keeps its 64 distinct values in proportion to the albedo (the 8-bit
    pass at gamma 2.2 gave 21 levels, up to 14 % off)."""
    scene = Scene()
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float)
    ramp = np.repeat(((v[:, 0] + 1) / 2)[:, None], 3, axis=1)
    scene.renderables.add_mesh(
        v, np.array([[0, 1, 2], [0, 2, 3]]), DiffuseMaterial(), VertexColors(ramp, color_space="linear")
    )
    scene.set_orthographic_camera((64, 64), ortho_scale=2.0, translation=(0, 0, 5.0))
    scene.lights.set_background_light(0.005)
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "albedo"), samples=1)
    row, albedo = res.rgba[32, :, 0].astype(np.float64), res.albedo[32, :, 0].astype(np.float64)
    assert len(np.unique(row)) == 64
    assert np.all(np.diff(row) > 0)
    ratio = row[albedo > 0.05] / albedo[albedo > 0.05]
    assert np.abs(ratio / np.median(ratio) - 1).max() < 0.005
    assert np.median(ratio) == pytest.approx(0.005, rel=0.03)


def test_eight_bit_fallback_clips_and_says_so(pyr):
    """Where a driver has no float targets, the colour pass is pyrender's 8-bit output: clipped at 1 and
    listed in the approximations (forced here on this driver)."""
    renderer = pyr.engine_instance.renderer
    assert renderer.float_color, f"{renderer.gl_renderer}: no float colour targets"
    scene = testing.plane_scene("area", resolution=(32, 32))
    renderer.float_color = False
    try:
        res = render(scene, backend=pyr, quality="preview", outputs=("rgb",), samples=1)
    finally:
        renderer.float_color = True
    assert any("8-bit colour pass" in a for a in res.meta["approximations"])
    assert res.rgba[..., :3].max() == pytest.approx(1.0, abs=1e-6)
    again = render(scene, backend=pyr, quality="preview", outputs=("rgb",), samples=1)
    assert again.rgba[..., :3].max() > 1.9


def test_texture_orientation(pyr):
    scene = testing.textured_quad_scene()
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "albedo"), samples=1)
    # top-left red, top-right green, bottom-left blue, bottom-right white (linear 1 under a unit background)
    for (y, x), rgb in {(16, 16): (1, 0, 0), (16, 48): (0, 1, 0), (48, 16): (0, 0, 1), (48, 48): (1, 1, 1)}.items():
        np.testing.assert_allclose(res.rgba[y, x, :3], rgb, atol=0.02)
        np.testing.assert_allclose(res.albedo[y, x], rgb, atol=1e-3)


def test_anti_aliased_alpha_and_plain_frames(pyr):
    scene, _ = testing.marker_scene()
    aa = render(scene, backend=pyr, quality="preview")
    plain = render(scene, backend=pyr, quality="preview", samples=1)
    a = aa.rgba[..., 3]
    assert ((a > 0.05) & (a < 0.95)).sum() > 20  # soft silhouettes
    assert set(np.unique(plain.rgba[..., 3])) <= {0.0, 1.0}
    assert aa.meta["antialiasing"]["mode"] in ("coverage", "msaa", "ssaa")
    assert plain.meta["antialiasing"]["mode"] == "none"
    # premultiplied: colour never exceeds alpha for these grey markers
    assert np.all(aa.rgba[..., :3] <= aa.rgba[..., 3:4] + 1e-6)


@pytest.mark.parametrize("samples", [1, 8])
def test_translucent_alpha_is_composited_over(pyr, samples):
    scene = Scene()
    r = scene.renderables
    grey = UniformColors((0.5, 0.5, 0.5), color_space="linear")
    r.add_plane_mesh(1.0, DiffuseMaterial(alpha=0.5), grey, tag="glass")
    dark = UniformColors((0.2, 0.2, 0.2), color_space="linear")
    r.add_plane_mesh(0.5, DiffuseMaterial(), dark, translation=(0.25, 0.25, -0.5), tag="behind")
    scene.set_orthographic_camera((64, 64), ortho_scale=2.0, translation=(0, 0, 5.0))
    scene.lights.set_background_light(1.0)
    res = render(scene, backend=pyr, quality="preview", samples=samples)
    over_bg, over_opaque = res.rgba[40, 20], res.rgba[20, 40]
    assert over_bg[3] == pytest.approx(0.5, abs=1e-4)
    np.testing.assert_allclose(over_bg[:3] / over_bg[3], 0.5, rtol=1e-3)  # straight colour kept
    assert over_opaque[3] == 1.0
    # blended in linear radiance, as the path tracers (the 8-bit pass blended gamma-encoded values: 0.33)
    assert over_opaque[0] == pytest.approx(0.5 * 0.5 + 0.5 * 0.2, rel=1e-3)


def test_opaque_background_option(pyr):
    scene, _ = testing.marker_scene()
    res = render(scene, backend=pyr, quality="preview", transparent_background=False)
    assert np.all(res.rgba[..., 3] == 1.0)
    np.testing.assert_allclose(res.rgba[0, 0, :3], 1.0, atol=1e-6)  # background light 1.0 white


# -- shadows ---------------------------------------------------------------------------------------------
def _shadow_scene(catcher: bool = False, casts: bool = True) -> Scene:
    scene = Scene()
    r = scene.renderables
    r.add_plane_mesh(4.0, DiffuseMaterial(), UniformColors((0.8, 0.8, 0.8)), shadow_catcher=catcher, tag="ground")
    s = r.add_sphere_nurbs(0.4, DiffuseMaterial(), UniformColors((0.8, 0.2, 0.2)), translation=(0, 0, 0.6), tag="ball")
    s.emit_shadows = casts
    scene.set_orthographic_camera((64, 64), ortho_scale=3.0, translation=(0, 0, 5.0), near=0.1, far=20)
    scene.lights.add_sun(3.0, angular_diameter=0.0)  # straight down: shadow right under the ball
    return scene


def test_shadows_follow_the_scene(pyr):
    # a tilted sun throws the ball's shadow beside it on the ground (seen from straight above)
    scene = _shadow_scene()
    scene.lights.clear()
    scene.lights.add_sun(3.0, angular_diameter=0.0, rotation_mode="eulerXYZ", rotation=(0, 40, 0))
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"), samples=1)
    ground = res.rgba[..., 0][res.instance == 0]
    assert ground.min() < 0.2 * ground.max()  # a shadow
    scene.renderables["ball"].emit_shadows = False
    res2 = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"), samples=1)
    ground2 = res2.rgba[..., 0][res2.instance == 0]
    assert ground2.min() > 0.9 * ground2.max()  # no shadow any more
    scene.renderables["ball"].emit_shadows = True
    scene.lights.values()[0].use_shadow = False
    res3 = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"), samples=1)
    ground3 = res3.rgba[..., 0][res3.instance == 0]
    assert ground3.min() > 0.9 * ground3.max()


def test_cached_shadow_maps_follow_moving_objects(pyr):
    scene = _shadow_scene()
    scene.lights.clear()
    scene.lights.add_sun(3.0, angular_diameter=0.0, rotation_mode="eulerXYZ", rotation=(0, 40, 0))

    def shadow_x() -> float:
        res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"), samples=1)
        dark = (res.instance == 0) & (res.rgba[..., 0] < 0.5 * res.rgba[..., 0][res.instance == 0].max())
        return float(np.nonzero(dark)[1].mean())

    x0 = shadow_x()
    scene.camera.translation = (0.0, 0.0, 5.5)  # camera only: the cached maps stay valid
    assert shadow_x() == pytest.approx(x0, abs=1.5)
    scene.camera.translation = (0.0, 0.0, 5.0)
    scene.renderables["ball"].translation = (0.5, 0.0, 0.6)  # the object moves: maps are re-rendered
    assert shadow_x() > x0 + 5


def test_shadow_catcher(pyr):
    scene = _shadow_scene(catcher=True)
    scene.lights.clear()
    scene.lights.add_sun(3.0, angular_diameter=0.0, rotation_mode="eulerXYZ", rotation=(0, 40, 0))
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"), samples=1)
    ground = res.instance == 0
    a = res.rgba[..., 3][ground]
    assert a.max() > 0.8 and np.median(a) < 0.05  # dark only in the shadow, transparent elsewhere
    assert np.all(res.rgba[..., :3][ground] == 0.0)
    ball = res.instance == 1
    assert np.all(res.rgba[..., 3][ball] == 1.0)


# -- every feature, unsupported requests, sessions ---------------------------------------------------------
def test_every_feature_scene_renders(pyr):
    scene = testing.every_feature_scene()
    res = render(scene, backend=pyr, quality="preview", outputs=ALL)
    assert res.rgba.shape == (72, 96, 4) and np.isfinite(res.rgba).all()
    assert res.meta["approximations"]
    assert set(np.unique(res.instance)) - {-1} <= set(range(len(scene.renderables)))
    assert (res.rgba[..., 3] > 0).mean() > 0.2


def test_pointcloud_scene_renders(pyr):
    scene = testing.pointcloud_scene(n=500, resolution=(64, 64))
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"))
    assert (res.instance == 0).sum() > 100
    # exact spheres: what is approximated is the colour of small spheres only
    notes = [a for a in res.meta["approximations"] if a.startswith("pointcloud:")]
    assert all("colour" in a for a in notes), notes


def test_point_cloud_spheres_depth_and_normals(pyr):
    scene = testing.pointcloud_scene(n=3000, resolution=(64, 64), point_size=0.05)
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "depth", "normal", "instance"))
    hit = res.instance == 0
    assert hit.sum() > 300 and np.isfinite(res.depth[hit]).all()
    np.testing.assert_allclose(np.linalg.norm(res.normal[hit], axis=1), 1.0, atol=1e-4)
    assert res.rgba[..., 3][hit].mean() > 0.5


def test_dense_clouds_are_thinned_in_colour_only(pyr, monkeypatch):
    from blendify_pyrender import render as rd

    monkeypatch.setattr(rd, "POINTS_MIN_DRAWN", 100)
    monkeypatch.setattr(rd, "SPLAT", False)  # (splatted, a cloud of spheres under 1.5 px keeps every point)
    scene = testing.pointcloud_scene(n=20000, resolution=(64, 64), point_size=0.05)
    first = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"))  # uploads every point
    again = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"))
    notes = [a for a in again.meta["approximations"] if "colour from" in a]
    assert notes and "of 20000 points" in notes[0]
    # the instance (like depth and normal) still comes from every point
    np.testing.assert_array_equal(first.instance, again.instance)


def test_strict_refuses_approximations(pyr):
    scene = testing.every_feature_scene()
    with pytest.raises(UnsupportedFeatureError) as info:
        render(scene, backend=pyr, quality="preview", strict=True)
    assert "pyrender" in str(info.value) and info.value.feature in str(info.value)


class _NoNormals(PyrenderBackend):
    @classmethod
    def capabilities(cls) -> dict[str, Capability]:
        caps = dict(super().capabilities())
        caps["output.normal"] = Capability("unsupported", "test")
        return caps


def test_unsupported_request_names_the_feature():
    assert issubclass(_NoNormals, Backend)
    be = _NoNormals()
    try:
        with pytest.raises(UnsupportedFeatureError, match="output.normal"):
            render(testing.depth_plane_scene(), backend=be, outputs=("normal",))
    finally:
        be.close()


def test_session_reuses_the_translated_scene(pyr):
    scene = testing.primitives_scene((64, 48))
    first = render(scene, backend=pyr, quality="preview")
    cam = scene.camera
    cam.set_position(rotation_mode="look_at", rotation=(0, 0, 0.3), translation=(1.0, -6.0, 3.0))
    second = render(scene, backend=pyr, quality="preview")
    assert second.meta["rebuilt_renderables"] == 0
    assert not np.allclose(first.rgba, second.rgba)


def test_two_backends_share_the_egl_display():
    if resolve_platform(None) != "egl" or not egl_available():
        print("skipped: EGL is not the platform of this test run")
        pytest.skip("EGL not in use")
    scene = testing.depth_plane_scene()
    a, b = PyrenderBackend(), PyrenderBackend()
    ra = render(scene, backend=a, outputs=("depth",))
    b_first = render(scene, backend=b, outputs=("depth",))
    a.close()  # must not terminate the display under b
    rb = render(scene, backend=b, outputs=("depth",))
    b.close()
    np.testing.assert_array_equal(ra.depth, rb.depth)
    np.testing.assert_array_equal(b_first.depth, rb.depth)


def test_osmesa_platform_in_a_subprocess():
    if not osmesa_available():
        msg = "libOSMesa not found (Debian: apt-get install libosmesa6)"
        print(f"skipped: {msg}")
        pytest.skip(msg)
    import subprocess
    import sys

    code = (
        "import numpy as np\n"
        "from blendify_core import render, testing\n"
        "from blendify_pyrender import PyrenderBackend\n"
        "scene, px = testing.marker_scene()\n"
        "with PyrenderBackend(platform='osmesa') as be:\n"
        "    res = render(scene, backend=be, quality='preview', outputs=('rgb', 'depth'))\n"
        "    lit = render(testing.plane_scene('area', resolution=(16, 16)), backend=be, outputs=('rgb',), samples=1)\n"
        "a = res.rgba[..., 3]\n"
        "assert ((a > 0.05) & (a < 0.95)).sum() > 20, 'no anti-aliased alpha'\n"
        "assert lit.rgba[..., :3].max() > 1.9, ('float colour pass', lit.meta['approximations'])\n"
        "print('osmesa ok', res.meta['antialiasing'])\n"
    )
    env_code = "import os; os.environ.pop('PYOPENGL_PLATFORM', None)\n" + code
    out = subprocess.run([sys.executable, "-c", env_code], capture_output=True, text=True, timeout=300)
    assert "osmesa ok" in out.stdout, out.stdout + out.stderr
