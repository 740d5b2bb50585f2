"""Tiny Mitsuba renders (scalar_rgb, <= 160x120, few samples): the camera self-test, exact depth,
light units against analytic values, textures, outputs, determinism and clear errors."""

from __future__ import annotations

import numpy as np
import pytest
from blendify_mitsuba import MitsubaBackend

import blendify_core as bf
from blendify_core import testing
from blendify_core.ir.colors import UniformColors, VertexColors
from blendify_core.ir.materials import DiffuseMaterial, PrincipledBSDFMaterial

_status = MitsubaBackend.probe()
if not _status.available:  # pragma: no cover - depends on the machine
    print(f"\nskipping the mitsuba backend tests: {_status.reason}")
    pytest.skip(f"mitsuba backend unavailable: {_status.reason}", allow_module_level=True)

pytestmark = pytest.mark.mitsuba

ALL = ("rgb", "depth", "normal", "albedo", "instance")


def _render(backend, scene, **kw):
    return bf.render(scene, backend=backend, **kw)


def _centroids(result, pixels: np.ndarray, window: int = 9) -> np.ndarray:
    """Alpha-weighted marker centroids (OpenCV pixel coordinates) in a window around each expected pixel."""
    a = result.rgba[..., 3].astype(np.float64)
    vv, uu = np.mgrid[0 : a.shape[0], 0 : a.shape[1]]
    out = []
    for u, v in pixels:
        w = a * (np.abs(uu - u) <= window) * (np.abs(vv - v) <= window)
        out.append([(w * uu).sum() / w.sum(), (w * vv).sum() / w.sum()])
    return np.array(out)


@pytest.mark.parametrize(
    "kwargs",
    [dict(), dict(center=None), dict(orthographic=True)],
    ids=["perspective-offcentre", "perspective-centred", "orthographic-offcentre"],
)
def test_camera_self_test_markers(scalar_backend, kwargs):
    scene, pixels = testing.marker_scene(**kwargs)
    r = _render(scalar_backend, scene, samples=64, outputs=("rgb", "instance"))
    err = np.linalg.norm(_centroids(r, pixels) - pixels, axis=1)
    print(f"marker centroid errors (px): {np.round(err, 4)}")
    assert err.max() < 0.1
    # the pixel-centre instance mask agrees with the projected marker centres
    for i, (u, v) in enumerate(pixels):
        assert r.instance[int(round(v)), int(round(u))] == i


@pytest.mark.parametrize("fy", [185.0, 120.0])
def test_camera_self_test_non_square_pixels(scalar_backend, fy):
    """fx != fy: a resampled square-pixel render for the colour, exact ray casts for the geometry."""
    scene, pixels = testing.marker_scene(fx=150.0, fy=fy)
    r = _render(scalar_backend, scene, samples=64, outputs=("rgb", "instance", "depth"))
    assert r.rgba.shape == (120, 160, 4) and r.meta["rendered_spp"] < 64
    assert "camera.anisotropic" in " ".join(r.meta["approximations"])
    err = np.linalg.norm(_centroids(r, pixels) - pixels, axis=1)
    print(f"fy={fy}: marker centroid errors (px): {np.round(err, 4)}")
    assert err.max() < 0.1
    for i, (u, v) in enumerate(pixels):
        assert r.instance[int(round(v)), int(round(u))] == i


def test_row_resampling_is_exact_for_smooth_images():
    from blendify_mitsuba.aniso import plan_square_pixels, resample_rows

    from blendify_core.ir.cameras import PerspectiveCamera

    cam = PerspectiveCamera((40, 30), K=[[50.0, 0, 19.5], [0, 37.0, 14.5], [0, 0, 1]])
    plan = plan_square_pixels(cam, 64)
    h_r, w_r = plan.camera.height, plan.camera.width
    assert w_r == 40 * plan.k and h_r >= round(30 * plan.row_scale)
    # constants are preserved exactly (the overlap weights of every target row sum to one)
    const = np.full((h_r, w_r, 2), 0.7)
    np.testing.assert_allclose(resample_rows(const, 40, 30, plan.k, plan.row_scale), 0.7, rtol=1e-12)
    # a ramp in the rendered row coordinate averages to the target rows' centres, up to the split
    # boundary rows (assumed uniform): well under a tenth of a rendered row
    ramp = (np.arange(h_r) + 0.5)[:, None, None] * np.ones((1, w_r, 1))
    out = resample_rows(ramp, 40, 30, plan.k, plan.row_scale)
    np.testing.assert_allclose(out[:, 0, 0], (np.arange(30) + 0.5) * plan.row_scale, atol=0.1)
    # the square-pixel camera sees the same rays through corresponding continuous coordinates
    u, v = 7.0, 21.0
    _, d_t = cam.pixel_rays(np.array([[u, v]]))
    ur = (u + 0.5) * plan.k - 0.5
    vr = (v + 0.5) * plan.row_scale - 0.5
    _, d_r = plan.camera.pixel_rays(np.array([[ur, vr]]))
    np.testing.assert_allclose(d_t, d_r, atol=1e-12)


def test_depth_of_a_tilted_plane_is_exact(scalar_backend):
    scene = testing.depth_plane_scene()
    r = _render(scalar_backend, scene, samples=1, outputs=("depth", "normal", "instance"))
    expected = testing.expected_plane_depth(scene)
    hit = np.isfinite(expected)
    assert np.array_equal(np.isfinite(r.depth), hit)
    rel = np.abs(r.depth[hit] - expected[hit]) / expected[hit]
    assert rel.max() < 1e-4
    assert np.all(r.instance[hit] == 0) and np.all(r.instance[~hit] == -1)
    n = scene.renderables["plane"].rotation_matrix[:, 2]
    np.testing.assert_allclose(r.normal[hit], np.broadcast_to(n, r.normal[hit].shape), atol=1e-5)


def _plane_expected(scene, light: str) -> np.ndarray:
    """Analytic radiance (H, W) of the Lambertian plane of testing.plane_scene at the pixel centres."""
    cam = scene.camera
    o, d = cam.pixel_rays()
    p = o - d * (o[:, 2:3] / d[:, 2:3])  # hit points on z = 0
    rho = 0.5
    lt = list(scene.lights)
    if light == "sun":
        s = lt[0]
        e = s.strength * max(0.0, -s.direction[2]) * np.ones(len(p))
    elif light in ("point", "spot"):
        s = lt[0]
        v = s.translation - p
        dist = np.linalg.norm(v, axis=1)
        e = s.strength / (4 * np.pi) * (v[:, 2] / dist) / dist**2
    elif light in ("area", "area_disk"):
        s = lt[0]
        n = 200
        g = (np.arange(n) + 0.5) / n - 0.5
        gx, gy = np.meshgrid(g * s.size[0], g * s.size[1])
        pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
        da = s.size[0] * s.size[1] / n**2
        if light == "area_disk":
            keep = (pts[:, 0] / (s.size[0] / 2)) ** 2 + (pts[:, 1] / (s.size[1] / 2)) ** 2 <= 1
            pts = pts[keep] * np.sqrt(np.pi / 4 * s.size[0] * s.size[1] / (keep.sum() * da))
        q = np.concatenate([pts, np.zeros((len(pts), 1))], axis=1) + s.translation
        e = np.zeros(len(p))
        for chunk in np.array_split(np.arange(len(p)), 16):
            v = q[None] - p[chunk, None]
            r2 = (v**2).sum(-1)
            cos_p = v[..., 2] / np.sqrt(r2)
            e[chunk] = (s.radiance[0] * cos_p * cos_p / r2).sum(1) * da
    elif light == "background":
        e = np.pi * np.ones(len(p))
    else:  # pragma: no cover
        raise ValueError(light)
    return (rho / np.pi * e).reshape(cam.height, cam.width)


@pytest.mark.parametrize(
    "light,spp,tol",
    [("sun", 4, 1e-4), ("point", 4, 1e-3), ("spot", 4, 1e-3), ("area", 64, 0.01), ("area_disk", 64, 0.01)],
)
def test_light_units_match_blender_radiometry(scalar_backend, light, spp, tol):
    scene = testing.plane_scene(light, resolution=(32, 32))
    r = _render(scalar_backend, scene, samples=spp)
    exp = _plane_expected(scene, light)
    got = r.rgba[..., 0].astype(np.float64)
    inner = slice(4, 28)
    ratio = got[inner, inner].sum() / exp[inner, inner].sum()
    print(f"{light}: Mitsuba / analytic = {ratio:.5f}")
    assert abs(ratio - 1) < tol


def test_sphere_light_matches_point_light_irradiance(scalar_backend):
    """A uniform sphere light's irradiance equals the point light's where it is fully visible; the sphere
    (between the camera and the plane) is invisible to the camera, as Cycles lights are."""
    scene = testing.plane_scene("point", resolution=(16, 16))
    delta = _render(scalar_backend, scene, samples=4).rgba
    scene.lights["Point_000"].shadow_soft_size = 0.3
    sphere = _render(scalar_backend, scene, samples=64).rgba
    ratio = sphere[2:14, 2:14, 0].sum() / delta[2:14, 2:14, 0].sum()
    print(f"sphere light / point light = {ratio:.5f}")
    assert abs(ratio - 1) < 0.005


def _light_in_frame_scene(light: str, emissive: bool) -> bf.Scene:
    """A camera at the origin looking along +Y at a grey world (radiance 0.3), light ``light`` straight ahead
    (its shape, if it has one, covers the image centre), and with ``emissive`` a glowing cube low on the left."""
    scene = bf.Scene()
    scene.set_perspective_camera(
        (32, 24), fov_x=np.deg2rad(50), rotation_mode="look_at", rotation=(0, 1, 0), translation=(0, 0, 0)
    )
    scene.lights.set_background_light(0.3)
    ahead = dict(rotation_mode="look_at", rotation=(0, 0, 0), translation=(0, 3, 0))  # facing the camera
    if light == "point":
        scene.lights.add_point(strength=50.0, shadow_soft_size=0.4, translation=(0, 3, 0))
    elif light == "spot":
        scene.lights.add_spot(strength=50.0, spot_size=np.deg2rad(60), shadow_soft_size=0.4, **ahead)
    elif light in ("square", "disk"):
        scene.lights.add_area("square" if light == "square" else "circle", 0.8, strength=50.0, **ahead)
    elif light == "sun":  # the sun straight ahead: its light travels towards the camera
        scene.lights.add_sun(3.0, angular_diameter=np.deg2rad(20), rotation_mode="look_at", rotation=(0, -1, 0))
    if emissive:
        glow = DiffuseMaterial(emission_color=(1.0, 0.5, 0.25, 1.0), emission_strength=4.0)
        scene.renderables.add_cube_mesh(0.6, glow, UniformColors((0.5,) * 3), translation=(-0.9, 3, -0.6), tag="glow")
    return scene


@pytest.mark.parametrize("emissive", [False, True], ids=["lights-only", "with-emissive-surface"])
@pytest.mark.parametrize("light", ["point", "spot", "square", "disk", "sun"])
def test_lights_in_frame_show_the_world_behind_them_on_an_opaque_film(scalar_backend, light, emissive):
    """Cycles' lights are not seen by camera rays: on an opaque film the world behind a light's sphere, area
    or sun disk is what the camera sees, with or without emissive surfaces (which stay visible)."""
    scene = _light_in_frame_scene(light, emissive)
    r = _render(scalar_backend, scene, samples=16, transparent_background=False)
    centre = r.rgba[9:15, 13:19, :3]  # the light's shape covers these pixels and more
    print(f"{light}, emissive={emissive}: centre {centre.min():.4f}..{centre.max():.4f}")
    np.testing.assert_allclose(centre, 0.3, atol=0.003)
    assert np.all(r.rgba[..., 3] == 1.0)
    if emissive:  # the glowing cube is seen (its emission 4 x (1, 0.5, 0.25) and some reflected light)
        ((u, v),), _ = scene.camera.project([[-0.9, 2.7, -0.6]])  # its face's centre
        assert r.rgba[int(v), int(u), 0] > 3.9 and not r.meta["hide_emitters"]
        # spots are delta lights, and the sun's disk lies beyond the far clip (unreachable): nothing to remove
        assert r.meta["lights_removed"] == (light not in ("spot", "sun"))
    else:  # away from the light, only the world
        np.testing.assert_allclose(r.rgba[:4, :, :3], 0.3, atol=1e-5)


def test_lights_in_frame_are_hidden_by_the_no_shadow_integrator_too(scalar_backend):
    """The integrator of non-shadowing lights hides what the camera sees through a light's null surfaces:
    the world behind the sphere is added once (not also through the sphere)."""
    scene = _light_in_frame_scene("point", emissive=False)
    scene.lights["Point_000"].use_shadow = False
    r = _render(scalar_backend, scene, samples=4, transparent_background=False)
    assert r.meta["integrator"] == "blendify_path"
    np.testing.assert_allclose(r.rgba[..., :3], 0.3, atol=1e-5)
    t = _render(scalar_backend, scene, samples=4, transparent_background=True)
    assert np.all(t.rgba == 0.0)  # nothing but the world: transparent and black


def test_sphere_light_over_a_floor_in_a_scene_with_emission(scalar_backend):
    """With emissive materials (emitters stay visible, the lights' directly seen emission is subtracted) the
    floor seen through a point light's sphere on an opaque film is lit as by the point light. Inside the
    outline only: at the outline the subtraction leaves about one sample of the sphere's radiance per pixel
    (the 4x4 block with the outline measured 1.09)."""
    scene = testing.plane_scene("point", resolution=(16, 16))
    delta = _render(scalar_backend, scene, samples=4, transparent_background=False).rgba
    scene.lights["Point_000"].shadow_soft_size = 0.3
    glow = DiffuseMaterial(emission_color=(1.0, 1.0, 1.0, 1.0), emission_strength=2.0)
    scene.renderables.add_plane_mesh(0.25, glow, UniformColors((0.5,) * 3), translation=(0.8, 0.8, 1e-3), tag="glow")
    r = _render(scalar_backend, scene, samples=64, transparent_background=False)
    assert r.meta["lights_removed"]
    behind = slice(7, 9)  # inside the sphere's outline: the floor below the light, seen through it
    ratio = r.rgba[behind, behind, 0].sum() / delta[behind, behind, 0].sum()
    print(f"floor behind the sphere / point light = {ratio:.5f}")
    assert abs(ratio - 1) < 0.01
    assert r.rgba[1, 14, 0] > 2.0  # the glowing quad is seen


def test_background_light_units(scalar_backend):
    scene = testing.plane_scene("background", resolution=(16, 16))
    r = _render(scalar_backend, scene, samples=64)
    ratio = float(r.rgba[..., 0].mean()) / 0.5
    print(f"background: Mitsuba / analytic = {ratio:.5f}")
    assert abs(ratio - 1) < 0.01
    assert np.all(r.rgba[..., 3] == 1.0)  # the plane covers the image


def test_background_and_environment_add_up(scalar_backend):
    scene = testing.plane_scene("background", resolution=(16, 16))  # background radiance 1
    scene.lights.set_environment_map(np.full((8, 16, 3), 0.5, np.float32), strength=1.0)
    r = _render(scalar_backend, scene, samples=64)
    ratio = float(r.rgba[..., 0].mean()) / (0.5 * 1.5)
    print(f"background + environment: Mitsuba / analytic = {ratio:.4f}")
    assert abs(ratio - 1) < 0.01


def test_sun_with_a_background_is_not_noisy(scalar_backend):
    """A sun beside a uniform background: the background's light-sampling weight is small (BSDF sampling
    finds it), so the sun's direct light is not lost on half of the light samples (with equal weights
    this lit plane's pixels scattered by ~25 % at 16 spp)."""
    scene = testing.plane_scene("sun", resolution=(24, 24))  # albedo 0.5, irradiance 3, 20 degrees off
    scene.lights.set_background_light(0.3)
    r = _render(scalar_backend, scene, samples=16)
    lum = r.rgba[..., 0].astype(np.float64)
    expected = 0.5 / np.pi * 3.0 * np.cos(np.deg2rad(20.0)) + 0.5 * 0.3
    print(f"sun + background: mean / analytic = {lum.mean() / expected:.5f}, pixel spread {lum.std() / lum.mean():.4f}")
    assert abs(lum.mean() / expected - 1) < 0.01
    assert lum.std() / lum.mean() < 0.02
    assert r.meta["sampler"] == "multijitter"  # the default


@pytest.mark.parametrize("faces_uv", [False, True])
def test_texture_orientation(scalar_backend, faces_uv):
    r = _render(scalar_backend, testing.textured_quad_scene(faces_uv=faces_uv), samples=4, outputs=("rgb", "albedo"))
    # 2x2 texture: top-left red, top-right green, bottom-left blue, bottom-right white
    expected = {(16, 16): [1, 0, 0], (16, 48): [0, 1, 0], (48, 16): [0, 0, 1], (48, 48): [1, 1, 1]}
    for (row, col), rgb in expected.items():
        np.testing.assert_allclose(r.albedo[row, col], rgb, atol=1e-6)
        assert np.argmax(r.rgba[row, col, :3]) == int(np.argmax(rgb)) or rgb == [1, 1, 1]


def test_srgb_textures_interpolate_encoded_values_like_cycles(scalar_backend):
    """Cycles interpolates 8-bit sRGB texels before decoding them; so does the backend (upsampling)."""
    from blendify_core.ir.colors import TextureColors, VertexUV
    from blendify_core.ir.colorspace import srgb_to_linear

    tex = (np.indices((8, 8)).sum(axis=0) % 2 * 200 + 30).astype(np.uint8)
    scene = bf.Scene()
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float)
    uv = VertexUV(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float))
    scene.renderables.add_mesh(v, [[0, 1, 2, 3]], DiffuseMaterial(), TextureColors(np.dstack([tex] * 3), uv), tag="q")
    scene.set_orthographic_camera((64, 64), ortho_scale=2.0, translation=(0, 0, 3))
    scene.lights.set_background_light(1.0)
    r = _render(scalar_backend, scene, samples=1, outputs=("albedo",))
    # reference: bilinear interpolation of the bytes (texel centres at (i + 0.5) / 8), then decode
    x = (np.arange(64) + 0.5) / 64 * 8 - 0.5
    i0 = np.floor(x).astype(int)
    f = x - i0
    t = tex.astype(np.float64) / 255
    rows = t[np.clip(i0, 0, 7)] * (1 - f)[:, None] + t[np.clip(i0 + 1, 0, 7) % 8] * f[:, None]
    ref = rows[:, np.clip(i0, 0, 7)] * (1 - f)[None] + rows[:, np.clip(i0 + 1, 0, 7) % 8] * f[None]
    inner = slice(4, 60)  # away from the wrap-around border
    err = np.abs(r.albedo[inner, inner, 0] - srgb_to_linear(ref[inner, inner]))
    print(f"max |albedo - decode(bilinear(bytes))| = {err.max():.4f}")
    assert err.max() < 0.01


@pytest.mark.parametrize("color_space,expected", [("srgb", 0.2158605), ("linear", 128 / 255)])
def test_file_texture(scalar_backend, tmp_path, color_space, expected):
    from PIL import Image

    from blendify_core.ir.colors import FileTextureColors, VertexUV

    tex = np.array([[[255, 0, 0], [0, 128, 0]], [[0, 0, 255], [128, 128, 128]]], dtype=np.uint8)
    path = tmp_path / "tex.png"
    Image.fromarray(tex).save(path)
    scene = bf.Scene()
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float)
    uv = VertexUV(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float))
    colors = FileTextureColors(path, uv, color_space=color_space, interpolation="closest")
    scene.renderables.add_mesh(v, [[0, 1, 2, 3]], DiffuseMaterial(), colors, tag="q")
    scene.set_orthographic_camera((32, 32), ortho_scale=2.0, translation=(0, 0, 3))
    scene.lights.set_background_light(1.0)
    r = _render(scalar_backend, scene, samples=4, outputs=("albedo",))
    np.testing.assert_allclose(r.albedo[8, 8], [1, 0, 0], atol=1e-6)  # top-left red
    np.testing.assert_allclose(r.albedo[8, 24], [0, expected, 0], rtol=1e-4)
    np.testing.assert_allclose(r.albedo[24, 8], [0, 0, 1], atol=1e-6)


def _mesh_hit(r, origin: np.ndarray, direction: np.ndarray) -> tuple[float, np.ndarray]:
    """The nearest hit of a ray with renderable ``r``'s tessellation (world space): distance and the
    interpolated vertex normal (Moller-Trumbore over every triangle, edges included)."""
    tm = r.to_mesh()
    m = r.matrix_world
    v = tm.vertices @ m[:3, :3].T + m[:3, 3]
    p0, p1, p2 = (v[tm.faces[:, k]] for k in range(3))
    e1, e2 = p1 - p0, p2 - p0
    h = np.cross(direction, e2)
    a = np.einsum("ij,ij->i", e1, h)
    ok = np.abs(a) > 1e-15
    a = np.where(ok, a, 1.0)
    s = origin - p0
    u = np.einsum("ij,ij->i", s, h) / a
    q = np.cross(s, e1)
    w = (q @ direction) / a
    t = np.einsum("ij,ij->i", e2, q) / a
    hit = ok & (u >= -1e-12) & (w >= -1e-12) & (u + w <= 1 + 1e-12) & (t > 0)
    k = np.flatnonzero(hit)[np.argmin(t[hit])]
    nv = tm.normals[tm.faces[k]] @ m[:3, :3].T
    n = (1 - u[k] - w[k]) * nv[0] + u[k] * nv[1] + w[k] * nv[2]
    return float(t[k]), n / np.linalg.norm(n)


def test_vertex_colours_and_outputs(scalar_backend):
    scene = bf.Scene()
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    cols = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.5, 0.5, 0.5]])
    scene.renderables.add_mesh(
        v, [[0, 1, 2], [0, 2, 3]], DiffuseMaterial(), VertexColors(cols, color_space="linear"), tag="quad"
    )
    scene.renderables.add_sphere_nurbs(0.3, DiffuseMaterial(), UniformColors((0.8, 0.8, 0.8)), translation=(0, 0, 1))
    scene.set_orthographic_camera((32, 32), ortho_scale=2.0, translation=(0, 0, 3))
    scene.lights.set_background_light(1.0)
    r = _render(scalar_backend, scene, samples=4, outputs=ALL)
    # corner pixels: albedo close to the vertex colours (interpolated at the pixel centre)
    np.testing.assert_allclose(r.albedo[31, 0], cols[0], atol=0.08)
    np.testing.assert_allclose(r.albedo[31, 31], cols[1], atol=0.08)
    np.testing.assert_allclose(r.albedo[0, 31], cols[2], atol=0.08)
    assert r.instance[16, 16] == 1 and r.instance[0, 0] == 0
    assert r.instance_tags == ["quad", "Sphere_000"]
    # the sphere is the IR's tessellation (as in every backend): depth and interpolated normal of its mesh;
    # the pixel-centre ray passes exactly through an edge of it (the 45 degree meridian) and must not slip
    o, d = scene.camera.pixel_rays(np.array([[16.0, 16.0]]))
    t, n = _mesh_hit(scene.renderables["Sphere_000"], o[0], d[0])
    assert r.depth[16, 16] == pytest.approx(t, abs=1e-5)
    assert r.depth[0, 0] == pytest.approx(3.0, abs=1e-5)
    np.testing.assert_allclose(r.normal[16, 16], n, atol=1e-4)
    np.testing.assert_allclose(r.albedo[16, 16], UniformColors((0.8, 0.8, 0.8)).linear_rgba[:3], atol=1e-6)


def test_per_face_materials_with_their_own_vertex_colours(scalar_backend):
    scene = bf.Scene()
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    red = np.tile([1.0, 0.0, 0.0], (4, 1))
    blue = np.tile([0.0, 0.0, 1.0], (4, 1))
    scene.renderables.add_mesh(
        v,
        [[0, 1, 2], [0, 2, 3]],
        [DiffuseMaterial(), DiffuseMaterial()],
        [VertexColors(red, color_space="linear"), VertexColors(blue, color_space="linear")],
        faces_material=[0, 1],
        tag="quad",
    )
    scene.set_orthographic_camera((16, 16), ortho_scale=2.0, translation=(0, 0, 3))
    scene.lights.set_background_light(1.0)
    r = _render(scalar_backend, scene, samples=4, outputs=("albedo", "instance"))
    np.testing.assert_allclose(r.albedo[14, 12], [1, 0, 0], atol=1e-6)  # below the diagonal: face 0
    np.testing.assert_allclose(r.albedo[2, 3], [0, 0, 1], atol=1e-6)  # above it: face 1
    assert np.all(r.instance == 0)


def test_alpha_is_coverage_and_premultiplied(scalar_backend):
    scene = testing.plane_scene("sun", resolution=(32, 32))
    scene.renderables["plane"].set_position(translation=(1.5, 0, 0))  # covers x in [-0.5, 3.5]
    r = _render(scalar_backend, scene, samples=64, outputs=("rgb", "instance"))
    a = r.rgba[..., 3]
    assert np.all(a[:, :8] == 0) and np.all(r.rgba[:, :8, :3] == 0)
    assert np.all(a[:, 9:] == 1)
    assert np.all(r.instance[:, :8] == -1) and np.all(r.instance[:, 9:] == 0)
    # premultiplied: colour / alpha is the plane's radiance where partially covered
    edge = (a > 0.05) & (a < 0.95)
    full = r.rgba[:, 20, 0].mean()
    if edge.any():
        np.testing.assert_allclose(r.rgba[..., 0][edge] / a[edge], full, rtol=0.02)


def test_environment_light_keeps_coverage_alpha(scalar_backend):
    scene = bf.Scene()
    scene.renderables.add_sphere_nurbs(0.5, DiffuseMaterial(), UniformColors((0.8, 0.8, 0.8)))
    scene.set_perspective_camera((32, 32), fov_x=np.deg2rad(40), translation=(0, 0, 4))
    sky = np.ones((8, 16, 3), np.float32) * 0.7
    scene.lights.set_environment_map(sky, strength=1.0)
    r = _render(scalar_backend, scene, samples=16)
    assert r.rgba[0, 0, 3] == 0 and r.rgba[16, 16, 3] == 1
    assert r.meta["hide_emitters"]


def test_emissive_surfaces_are_visible(scalar_backend):
    scene = bf.Scene()
    emit = PrincipledBSDFMaterial(emission_color=(1, 1, 1), emission_strength=2.0, specular_ior=0.0, roughness=1.0)
    scene.renderables.add_sphere_nurbs(0.5, emit, UniformColors((0.0, 0.0, 0.0)), tag="glow")
    scene.set_perspective_camera((32, 32), fov_x=np.deg2rad(40), translation=(0, 0, 4))
    # an area light between the camera and the sphere, emitting away from the camera (its back is invisible)
    scene.lights.add_area("square", 0.2, 10.0, translation=(0, 0, 3))
    r = _render(scalar_backend, scene, samples=16)
    centre = r.rgba[16, 16]
    assert centre[:3] == pytest.approx([2.0, 2.0, 2.0], rel=1e-4)
    assert centre[3] == 1.0 and r.rgba[0, 0, 3] == 0.0
    assert not r.meta["hide_emitters"] and not r.meta["alpha_compositing"]


def test_emissive_surfaces_under_a_sky_keep_coverage_alpha(scalar_backend):
    scene = bf.Scene()
    emit = PrincipledBSDFMaterial(emission_color=(1, 1, 1), emission_strength=2.0, specular_ior=0.0, roughness=1.0)
    scene.renderables.add_sphere_nurbs(0.5, emit, UniformColors((0.0, 0.0, 0.0)), tag="glow")
    scene.set_perspective_camera((32, 32), fov_x=np.deg2rad(40), translation=(0, 0, 4))
    scene.lights.set_background_light(0.7)
    # a non-emissive mesh too (regression: the coverage pass must count non-emitters)
    scene.renderables.add_cube_mesh(0.3, DiffuseMaterial(), UniformColors((0.5, 0.5, 0.5)), translation=(0.9, 0, 0))
    r = _render(scalar_backend, scene, samples=16, outputs=("rgb", "instance"))
    assert r.meta["alpha_compositing"]
    cube = r.instance == 1
    interior = cube.copy()
    for dv, du in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        interior &= np.roll(cube, (dv, du), axis=(0, 1))
    assert interior.sum() >= 4 and np.all(r.rgba[..., 3][interior] == 1.0)
    assert r.rgba[0, 0, 3] == 0.0 and np.allclose(r.rgba[0, 0, :3], 0.0, atol=1e-6)
    assert r.rgba[16, 16, 3] == 1.0 and r.rgba[16, 16, :3] == pytest.approx([2.0] * 3, rel=1e-4)
    vv, uu = np.mgrid[0:32, 0:32]
    near_sphere = np.hypot(uu - 15.5, vv - 15.5) < 8.0
    edge = (r.rgba[..., 3] > 0.0) & (r.rgba[..., 3] < 1.0) & near_sphere
    assert edge.any()
    # premultiplied, without the sky behind partly covered pixels (alpha comes from another pass: per-pixel
    # noise, so compare sums over the silhouette)
    ratio = r.rgba[..., 0][edge].sum() / r.rgba[..., 3][edge].sum()
    assert ratio == pytest.approx(2.0, rel=0.05)


def test_translation_is_cached_until_the_scene_changes():
    scene = testing.plane_scene("sun", resolution=(16, 16))
    with MitsubaBackend(variant="scalar_rgb") as b:
        a = bf.render(scene, backend=b, samples=2)
        c = bf.render(scene, backend=b, samples=2, seed=5)
        assert not a.meta["translate_cached"] and c.meta["translate_cached"]
        scene.lights["Sun_000"].strength = 6.0
        d = bf.render(scene, backend=b, samples=2)
        assert not d.meta["translate_cached"]
        assert d.rgba[8, 8, 0] == pytest.approx(2 * a.rgba[8, 8, 0], rel=1e-5)
        # a new sample count reuses the loaded scene (final's passes of new sizes) and renders what a new
        # translation renders at that count
        e = bf.render(scene, backend=b, samples=7, seed=2)
        assert e.meta["translate_cached"] and e.meta["samples"] == 7
    with MitsubaBackend(variant="scalar_rgb") as fresh:
        f = bf.render(scene, backend=fresh, samples=7, seed=2)
    assert np.array_equal(e.rgba, f.rgba)


def test_final_pilot_settings_and_full_settings_keep_their_translations():
    """final's pilot renders other settings (no bounces, no caustics) between full passes: both translations
    stay loaded (each loaded once), each renders what a new translation renders, and a scene change drops both."""
    scene = testing.occluder_scene("sun", True, (16, 16))  # a cube over a plane: indirect light
    with MitsubaBackend(variant="scalar_rgb") as b:
        full = [bf.render(scene, backend=b, samples=2, seed=1)]
        direct = [bf.render(scene, backend=b, samples=2, seed=1, max_bounces=0)]
        full.append(bf.render(scene, backend=b, samples=3, seed=1))
        direct.append(bf.render(scene, backend=b, samples=2, seed=1, max_bounces=0))
        assert [r.meta["translate_cached"] for r in full + direct] == [False, True, False, True]
        assert full[1].meta["max_depth"] > direct[1].meta["max_depth"] == 2
        assert np.array_equal(direct[0].rgba, direct[1].rgba)
        strength = scene.lights["Sun_000"].strength
        scene.lights["Sun_000"].strength = 6.0
        again = bf.render(scene, backend=b, samples=2, seed=1, max_bounces=0)
        assert not again.meta["translate_cached"]
        assert again.rgba[..., 0].sum() == pytest.approx(6.0 / strength * direct[0].rgba[..., 0].sum(), rel=1e-5)
        assert not bf.render(scene, backend=b, samples=2, seed=1).meta["translate_cached"]
    with MitsubaBackend(variant="scalar_rgb") as fresh:
        assert np.array_equal(bf.render(scene, backend=fresh, samples=2, seed=1, max_bounces=0).rgba, again.rgba)


def test_anisotropic_pixels_translate_again_for_a_new_sample_count():
    """fx != fy: the square-pixel plan (rows rendered and resampled) depends on the sample count."""
    scene, _ = testing.marker_scene(fx=150.0, fy=75.0)
    with MitsubaBackend(variant="scalar_rgb") as b:
        a = bf.render(scene, backend=b, samples=4)
        c = bf.render(scene, backend=b, samples=4, seed=1)
        d = bf.render(scene, backend=b, samples=16)
    assert not a.meta["translate_cached"] and c.meta["translate_cached"] and not d.meta["translate_cached"]


def test_same_seed_same_image(scalar_backend):
    scene = testing.bunny_scene((32, 32))
    a = _render(scalar_backend, scene, samples=4, seed=3)
    b = _render(scalar_backend, scene, samples=4, seed=3)
    c = _render(scalar_backend, scene, samples=4, seed=4)
    assert np.array_equal(a.rgba, b.rgba)
    assert not np.array_equal(a.rgba, c.rgba)
    assert a.meta["variant"] == "scalar_rgb" and a.meta["spp"] == 4
    assert a.meta["integrator"] == "path" and a.meta["max_depth"] == a.meta["settings"]["max_bounces"] + 2


def test_primitives_and_pointclouds_render(scalar_backend):
    scene = testing.primitives_scene((48, 36))
    r = _render(scalar_backend, scene, samples=4, outputs=ALL)
    assert set(np.unique(r.instance)) == {-1, *range(len(scene.renderables))}
    scene = testing.pointcloud_scene(n=300, resolution=(32, 32))
    r1 = _render(scalar_backend, scene, samples=4, outputs=("rgb", "instance"))
    with MitsubaBackend(variant="scalar_rgb", max_analytic_spheres=0) as merged:
        r2 = bf.render(scene, backend=merged, samples=4, outputs=("rgb", "instance"))
    assert r1.meta["analytic_spheres"] == 300 and r2.meta["analytic_spheres"] == 0
    # analytic spheres vs icospheres of the same radius: nearly the same silhouettes
    assert np.mean(r1.instance != r2.instance) < 0.05


def test_wireframe_bands_along_the_edges(scalar_backend):
    from blendify_core.ir.materials import PrincipledBSDFWireframeMaterial

    scene = bf.Scene()
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float) * 0.8
    mat = PrincipledBSDFWireframeMaterial(
        wireframe_thickness=0.1, wireframe_color=(0, 0, 0, 1), specular_ior=0.0, roughness=1.0
    )
    scene.renderables.add_mesh(v, [[0, 1, 2, 3]], mat, UniformColors((0.8, 0.8, 0.8)), tag="quad")
    scene.set_orthographic_camera((32, 32), ortho_scale=2.0, translation=(0, 0, 3))
    scene.lights.set_background_light(1.0)
    r = _render(scalar_backend, scene, samples=4, outputs=("albedo", "instance"))
    grey = UniformColors((0.8, 0.8, 0.8)).linear_rgba[0]
    diag = [(31 - i, i) for i in range(6, 26)]  # the fan triangulation's diagonal (0, 2)
    assert all(r.albedo[p][0] == 0.0 for p in diag)  # the wire colour
    assert r.albedo[8, 8, 0] == pytest.approx(grey) and r.albedo[24, 24, 0] == pytest.approx(grey)
    assert np.all(r.instance[4:28, 4:28] == 0)


@pytest.mark.parametrize("max_spheres", [1000, 0])
def test_pointcloud_per_point_alpha(max_spheres):
    scene = bf.Scene()
    pts = np.array([[-0.5, 0, 0], [0.5, 0, 0]], float)
    cols = np.array([[1, 1, 1, 1.0], [1, 1, 1, 0.25]])
    scene.renderables.add_pointcloud(pts, DiffuseMaterial(), VertexColors(cols), point_size=0.8, tag="p")
    scene.set_orthographic_camera((32, 16), ortho_scale=2.0, translation=(0, 0, 3))
    scene.lights.set_background_light(1.0)
    with MitsubaBackend(variant="scalar_rgb", max_analytic_spheres=max_spheres) as b:
        r = bf.render(scene, backend=b, samples=256)
    assert r.rgba[8, 8, 3] == pytest.approx(1.0)
    # the second sphere is 25 % opaque: front and back surfaces both mask (1 - 0.75^2 = 0.44)
    assert r.rgba[8, 24, 3] == pytest.approx(1 - 0.75**2, abs=0.08)


def test_large_pointclouds_are_one_curve_shape_matching_the_spheres():
    """Beyond max_analytic_spheres an opaque cloud is one curve shape of spheres (blendify_mitsuba.points):
    coverage, brightness and per-point colours agree with the exact analytic spheres."""
    scene = testing.pointcloud_scene(300, (64, 64), point_size=0.12)
    results = {}
    for max_spheres in (1000, 0):
        with MitsubaBackend(variant="scalar_rgb", max_analytic_spheres=max_spheres) as b:
            r = bf.render(scene, backend=b, samples=64, outputs=("rgb", "albedo", "instance"))
            keys = list(b.session.native.shapes)
        results[max_spheres] = (r, keys)
    spheres, curves = results[1000][0], results[0][0]
    assert results[0][1] == ["r00000_curves"] and len(results[1000][1]) == 300
    cov_s, cov_c = spheres.rgba[..., 3].mean(), curves.rgba[..., 3].mean()
    mean_s, mean_c = spheres.rgba[..., :3].mean(), curves.rgba[..., :3].mean()
    both = (spheres.instance >= 0) & (curves.instance >= 0)
    same_colour = np.all(np.abs(spheres.albedo[both] - curves.albedo[both]) < 1e-5, axis=1).mean()
    print(f"coverage {cov_c / cov_s:.4f}, mean {mean_c / mean_s:.4f}, same albedo at {same_colour:.3f} of the pixels")
    assert abs(cov_c / cov_s - 1) < 0.01 and abs(mean_c / mean_s - 1) < 0.02
    assert same_colour > 0.97  # silhouettes of overlapping points may differ


def _interior(result, margin: int = 2) -> np.ndarray:
    """Hit pixels whose neighbours within ``margin`` pixels hit the same renderable."""
    inst = result.instance
    h, w = inst.shape
    pad = np.pad(inst, margin, mode="constant", constant_values=-1)
    ok = inst >= 0
    for dy in range(-margin, margin + 1):
        for dx in range(-margin, margin + 1):
            ok &= pad[margin + dy : margin + dy + h, margin + dx : margin + dx + w] == inst
    return ok


# large and small for their distance (radius / camera distance 0.08, 4e-3, 4e-4: the mesh before, under 1e-3)
@pytest.mark.parametrize(("point_size", "fov"), [(0.4, 45.0), (0.02, 1.5), (0.002, 0.15)])
def test_curve_points_have_the_spheres_depth_and_normals(point_size, fov):
    """The curve spheres (blendify_mitsuba.points) keep the exactness bounds the path tracers' spheres are held
    to (depth q99 <= 1e-4 relative, normals q99 <= 0.5 deg, 2 px inside the silhouettes): Embree intersects
    each point's own sphere."""
    g = np.linspace(-0.6, 0.6, 3)
    p = np.stack(np.meshgrid(g, g, [0.0]), axis=-1).reshape(-1, 3)
    scene = bf.Scene()
    scene.renderables.add_pointcloud(p, DiffuseMaterial(), VertexColors(p * 0.5 + 0.5), point_size=point_size)
    testing.look_at_camera(scene, (64, 64), (1.2, -1.5, 1.6), (0, 0, 0), fov_x=np.deg2rad(fov))
    scene.lights.add_sun(3.0, angular_diameter=0.0)
    out = {}
    for max_spheres in (1000, 0):
        with MitsubaBackend(variant="scalar_rgb", max_analytic_spheres=max_spheres) as b:
            out[max_spheres] = bf.render(scene, backend=b, samples=4, outputs=("depth", "normal", "instance"))
            assert list(b.session.native.shapes)[0].endswith("_curves" if max_spheres == 0 else "_p0000000")
    a, c = out[1000], out[0]
    mask = _interior(a) & _interior(c)
    assert mask.sum() > 50
    depth = np.abs(c.depth[mask] / a.depth[mask] - 1.0)
    cos = np.sum(a.normal[mask] * c.normal[mask], axis=1)
    cos /= np.linalg.norm(a.normal[mask], axis=1) * np.linalg.norm(c.normal[mask], axis=1)
    angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    print(f"depth q99 {np.quantile(depth, 0.99):.2e}, normal q99 {np.quantile(angle, 0.99):.3f} deg")
    assert np.quantile(depth, 0.99) <= 1e-4
    assert np.quantile(angle, 0.99) <= 0.5


def test_every_feature_scene_renders(scalar_backend):
    scene = testing.every_feature_scene((48, 36))
    r = _render(scalar_backend, scene, samples=4, outputs=ALL)
    assert np.isfinite(r.rgba).all() and np.isfinite(r.normal).all() and np.isfinite(r.albedo).all()
    visible = set(np.unique(r.instance)) - {-1}
    assert len(visible) >= len(scene.renderables) - 2  # a couple of tiny objects may fall between pixels
    assert r.meta["approximations"]


def test_shadow_catcher_emulation(scalar_backend):
    scene = testing.plane_scene("sun", resolution=(32, 32))
    scene.renderables["plane"].shadow_catcher = True
    scene.renderables.add_cube_mesh(
        0.5, DiffuseMaterial(), UniformColors((0.8, 0.2, 0.2)), translation=(0, 0, 0.6), tag="cube"
    )
    r = _render(scalar_backend, scene, samples=16, outputs=("rgb", "instance"))
    assert r.meta["shadow_catcher_emulated"]
    # where the plane is seen: black, alpha = shadow; the sun comes from 20 deg off vertical (about X)
    plane = r.instance == 0
    sun = scene.lights["Sun_000"].direction
    o, d = scene.camera.pixel_rays()
    p = o - d * (o[:, 2:3] / d[:, 2:3])  # plane points (z = 0)
    t = (0.6 - p[:, 2]) / -sun[2]
    q = p - sun * t[:, None]  # where the ray towards the sun crosses the cube's top face height
    inside = (np.abs(q[:, 0]) < 0.2) & (np.abs(q[:, 1]) < 0.2)
    shadow = plane & inside.reshape(32, 32)
    lit = plane & ~(np.abs(q[:, 0]) < 0.3).reshape(32, 32)
    assert shadow.sum() > 5 and lit.sum() > 100
    assert np.all(r.rgba[plane][:, :3] == 0)
    assert r.rgba[..., 3][shadow].min() > 0.95
    assert r.rgba[..., 3][lit].max() < 0.05
    cube = r.instance == 1
    assert np.all(r.rgba[..., 3][cube] == 1) and r.rgba[..., 0][cube].mean() > 0.2


@pytest.mark.parametrize(
    "feature,build",
    [
        ("object.no_shadow", "no_shadow"),
    ],
)
def test_unsupported_features_are_clear_errors(scalar_backend, feature, build):
    scene = testing.plane_scene("sun", resolution=(16, 16))
    scene.renderables["plane"].emit_shadows = False
    with pytest.raises(bf.UnsupportedFeatureError, match=feature.replace(".", r"\.")):
        _render(scalar_backend, scene, samples=1)
    # and the translator itself refuses too (when called without the core's capability check)
    with pytest.raises(bf.UnsupportedFeatureError):
        scalar_backend.translate(scene, bf.pipeline.settings.resolve_settings(samples=1))


@pytest.mark.parametrize("height,listed", [(0.0, True), (0.05, False)])
def test_area_light_in_the_plane_of_an_emitter_is_listed(scalar_backend, height, listed):
    """An area light lying in the plane of an emissive quad (as some .blend files have it) is a difference by
    design (coincident emitters); it is listed in meta["approximations"], a light above the quad is not."""
    scene = testing.plane_scene("point", resolution=(16, 16))
    for light in list(scene.lights):
        scene.lights.remove(light.tag)
    v = np.array([[-0.3, -0.3, 1], [0.3, -0.3, 1], [0.3, 0.3, 1], [-0.3, 0.3, 1]], float)
    glow = PrincipledBSDFMaterial(emission_color=(1, 1, 1), emission_strength=2.0)
    scene.renderables.add_mesh(v, [[0, 1, 2, 3]], glow, UniformColors((1, 1, 1)), tag="panel")
    scene.lights.add_area("square", 0.4, strength=10.0, translation=(0.1, 0, 1 + height), tag="lamp")
    r = _render(scalar_backend, scene, samples=1)
    found = [a for a in r.meta["approximations"] if "'lamp'" in a and "'panel'" in a]
    assert bool(found) == listed, r.meta["approximations"]


def test_biased_settings_mitsuba_cannot_apply_are_approximations(scalar_backend):
    """Indirect clamp, Filter Glossy and per-kind bounce limits (an attached .blend's own render settings, or
    quality="blendify") have no Mitsuba counterpart: listed in meta["approximations"], refused by strict."""
    from blendify_core.errors import UnsupportedFeatureError
    from blendify_core.pipeline.settings import ENGINE_LIMIT_PREFIX

    scene = testing.depth_plane_scene((16, 12))
    kw = {"samples": 1, "clamp_indirect": 10.0, "filter_glossy": 1.0, "glossy_bounces": 4, "max_bounces": 8}
    res = _render(scalar_backend, scene, **kw)
    limits = sorted(
        a[len(ENGINE_LIMIT_PREFIX) :] for a in res.meta["approximations"] if a.startswith(ENGINE_LIMIT_PREFIX)
    )
    assert [x.split(":")[0].split(" (")[0] for x in limits] == [
        "bounce limits below max_bounces",
        "clamp_indirect=10",
        "filter_glossy=1",
    ]
    assert res.meta["bias"] == [] and not any("clamp" in n or "glossy" in n for n in res.meta.get("notes", []))
    with pytest.raises(UnsupportedFeatureError, match="cannot apply the render settings"):
        _render(scalar_backend, scene, strict=True, **kw)


@pytest.mark.parametrize("row", [1, 4, 7])
def test_environment_texels_sit_where_blender_puts_them(row):
    """A single bright texel of a 16x32 map lights a Lambertian plane as Blender's mapping says: row r at
    v = (r + 1/2) / H with linear interpolation between row centres, so the plane's radiance is
    (albedo / pi) x the integral of that hat times cos(theta) over the sky. Mitsuba's own rows sit at
    v = k / (H - 1) (before: 0.80x near the zenith to 1.20x near the horizon)."""
    h = 16
    scene = bf.Scene()
    scene.set_orthographic_camera((4, 4), ortho_scale=1.0, translation=(0, 0, 3))
    scene.renderables.add_plane_mesh(50, DiffuseMaterial(), UniformColors((0.5, 0.5, 0.5), color_space="linear"))
    env = np.zeros((h, 2 * h, 3), np.float32)
    env[row, 5] = 1000.0
    scene.lights.set_environment_map(env)
    got = bf.render(scene, backend="mitsuba", samples=64, seed=0, outputs=("rgb",), variant="scalar_rgb").rgba
    theta = np.linspace(0.0, np.pi / 2, 100_001)
    hat = np.clip(1.0 - np.abs(theta / np.pi * h - (row + 0.5)), 0.0, None)
    f = hat * np.cos(theta) * np.sin(theta)
    irradiance = 1000.0 * (np.pi / h) * float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(theta)))
    expected = 0.5 / np.pi * irradiance
    print(f"row {row}: mitsuba {got[..., :3].mean():.4f}, Blender's mapping {expected:.4f}")
    assert got[..., :3].mean() == pytest.approx(expected, rel=0.01)


def _cube_on_catcher(resolution: tuple[int, int], height: float) -> bf.Scene:
    """A white shadow-catcher plane (its far edge in view) and a 0.12 cube centred ``height`` above it, seen
    from low down; sun and background."""
    scene = bf.Scene()
    scene.renderables.add_plane_mesh(
        1.0, DiffuseMaterial(), UniformColors((1.0, 1.0, 1.0)), shadow_catcher=True, tag="catcher"
    )
    scene.renderables.add_cube_mesh(
        0.12, DiffuseMaterial(), UniformColors((0.8, 0.3, 0.2)), translation=(0.0, 0.1, height), tag="cube"
    )
    scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(35, 25, 0))
    scene.lights.set_background_light(0.3)
    testing.look_at_camera(scene, resolution, (0.0, -0.9, 0.18), (0.0, 0.0, 0.1), fov_x=np.deg2rad(50.0))
    return scene


def test_shadow_catcher_edge_against_the_background_is_invisible(scalar_backend):
    """The catcher's far edge against the background: pixels whose centre sees the background but which
    partly cover the catcher (and nothing else) are catcher pixels too: no RGB, alpha only for a shadow (as in
    Cycles). Before, they kept the plane's colour: a bright line along the horizon. Pixels partly covering an
    object against the background keep the object's colour."""
    scene = _cube_on_catcher((64, 48), 0.06)
    r = _render(scalar_backend, scene, samples=16, outputs=("rgb", "instance"))
    cube = r.instance == 1
    near_cube = np.zeros_like(cube)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near_cube |= np.roll(np.roll(cube, dy, axis=0), dx, axis=1)
    background = (r.instance < 0) & ~near_cube
    horizon = np.flatnonzero((r.instance == 0).any(axis=1)).min()  # the topmost row seeing the catcher
    edge = background & (np.arange(cube.shape[0]) == horizon - 1)[:, None]  # the row above the far edge
    assert edge.sum() > 40
    rgb, alpha = r.rgba[background][:, :3], r.rgba[edge][:, 3]
    print(f"background rgb max {rgb.max():.4f}; above the far edge: alpha max {alpha.max():.4f}")
    assert np.all(rgb == 0)  # before: the lit plane's colour along the far edge (up to 0.44)
    assert alpha.max() < 0.05  # the catcher is unshadowed there
    # the cube against the background: pixels partly covering it keep its colour; the cube is opaque (its
    # bottom edge also covers some catcher: alpha there = the cube's coverage + that part's shadow)
    above = (r.instance < 0) & np.roll(cube, -1, axis=0)  # background pixels right above a cube pixel
    assert above.sum() >= 3
    assert r.rgba[above][:, 0].max() > 0.05
    assert np.all(r.rgba[_interior(r) & cube][:, 3] == 1) and r.rgba[cube][:, 3].min() > 0.8


def test_shadow_catcher_neither_lights_nor_shades_objects(scalar_backend):
    """In Cycles a shadow catcher is invisible to the other objects (no light bounced off it, no sky hidden
    by it): the objects' pixels are those of the scene without the catcher (same seed and samples). Before,
    the white catcher's bounce lit the cube from below (measured: its pixels 1.36x as bright)."""
    scene = _cube_on_catcher((48, 36), 0.08)
    with_catcher = _render(scalar_backend, scene, samples=16, outputs=("rgb", "instance"))
    cube = with_catcher.instance == 1
    scene.renderables.remove("catcher")
    alone = _render(scalar_backend, scene, samples=16, outputs=("rgb",))
    ratio = with_catcher.rgba[cube][:, :3].mean() / alone.rgba[cube][:, :3].mean()
    print(f"cube pixels with the catcher / without: {ratio:.4f}")
    assert cube.sum() > 30
    assert np.abs(with_catcher.rgba[cube] - alone.rgba[cube]).max() < 1e-5
