"""The preview's look against the path tracers: point clouds as exact spheres (coverage, depth, normals),
tiny renders."""

from __future__ import annotations

import numpy as np
import pytest

from blendify_core import DiffuseMaterial, MetalMaterial, PrincipledBSDFMaterial, Scene, UniformColors, render, testing
from blendify_core.registry import available_backends


def _one_point_scene(diameter_px: float, centre=(0.0, 0.0, 0.0)) -> Scene:
    """One sphere seen by an orthographic camera (64x48, 0.05 world units per pixel) from +Z, 5 units away."""
    scene = Scene()
    scene.set_orthographic_camera((64, 48), ortho_scale=3.2, translation=(0, 0, 5.0), near=0.1, far=20)
    scene.renderables.add_pointcloud(
        np.array([centre], dtype=float),
        DiffuseMaterial(),
        UniformColors((0.8, 0.8, 0.8)),
        point_size=0.05 * diameter_px,
        tag="points",
    )
    scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(0, 0, 0))
    return scene


@pytest.mark.parametrize("diameter_px", [6.0, 15.0])
def test_impostor_is_a_sphere_of_the_ir_diameter(pyr, diameter_px):
    scene = _one_point_scene(diameter_px)
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "depth", "normal", "instance"))
    hit = res.instance == 0
    # pixel centres inside the projected disc (area pi d^2 / 4 within its boundary pixels)
    area = np.pi * diameter_px**2 / 4
    assert abs(hit.sum() - area) <= np.pi * diameter_px, (hit.sum(), area)
    ys, xs = np.nonzero(hit)
    assert abs(xs.mean() + 0.5 - 32) < 0.6 and abs(ys.mean() + 0.5 - 24) < 0.6  # centred on the point
    # the sphere's depth and normal at each pixel centre (orthographic: exact)
    radius = 0.05 * diameter_px / 2
    px = (xs + 0.5 - 32) * 0.05
    py = (24 - ys - 0.5) * 0.05
    nz = np.sqrt(np.clip(1 - (px**2 + py**2) / radius**2, 0, None))
    inner = nz > 0.3  # away from the silhouette (a pixel centre there may round either way)
    np.testing.assert_allclose(res.depth[hit][inner], 5.0 - radius * nz[inner], atol=2e-3)
    expected_n = np.stack([px / radius, py / radius, nz], axis=1)
    np.testing.assert_allclose(res.normal[hit][inner], expected_n[inner], atol=0.05)
    # shaded as a sphere lit from the camera's side: the rim is darker than the centre
    lum = res.rgba[..., :3].mean(axis=-1)[hit]
    assert lum[nz > 0.9].mean() > 1.5 * lum[(nz < 0.5) & (nz > 0)].mean()


@pytest.mark.parametrize("antialias", ["coverage", "msaa", "ssaa"])
@pytest.mark.parametrize("diameter_px", [4.0, 15.0])
def test_sphere_silhouette_is_antialiased(pyr, antialias, diameter_px):
    """Every anti-aliasing scheme covers the sphere's disc by its area, with partly covered edge pixels: the
    coverage scheme blends its edge by the covered fraction, MSAA intersects each sample, SSAA each subpixel."""
    from blendify_pyrender import PyrenderBackend

    scene = _one_point_scene(diameter_px, centre=(0.013, 0.021, 0.0))
    alpha = render(scene, backend=PyrenderBackend(antialias=antialias), quality="preview").rgba[..., 3]
    area = np.pi * diameter_px**2 / 4
    assert abs(alpha.sum() - area) <= 0.03 * area, (alpha.sum(), area)
    assert ((alpha > 0.02) & (alpha < 0.98)).sum() >= 4


def test_impostor_writes_the_sphere_depth(pyr):
    """A plane cutting the sphere (radius 0.375) at z = 0.34: the sphere's cap pokes through it near the
    axis (z = 0.373 at the centre pixel), the plane hides the sphere 0.23 from the axis (z = 0.30 there); a
    flat sprite at the centre's (or the front's) depth would show one of them everywhere."""
    scene = _one_point_scene(15.0)
    scene.renderables.add_plane_mesh(0.5, DiffuseMaterial(), UniformColors((0.1, 0.9, 0.1)), translation=(0, 0, 0.34))
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"))
    assert res.instance[24, 32] == 0  # 0.035 from the axis: the sphere
    assert res.instance[24, 36] == 1 and res.instance[24, 27] == 1  # 0.23 from the axis: the plane
    assert res.instance[24, 38] == 0  # beyond the plane's edge (0.25): the sphere again


def test_sphere_casts_its_exact_shadow(pyr):
    """A sphere (radius 0.3) 1 above a floor under a tilted sun: the floor pixels in shadow are those whose
    ray towards the sun meets the sphere (the shadow maps intersect the exact sphere too)."""
    scene = Scene()
    scene.set_orthographic_camera((64, 48), ortho_scale=3.2, translation=(0, 0, 5.0), near=0.1, far=20)
    scene.renderables.add_plane_mesh(4.0, DiffuseMaterial(), UniformColors((0.8, 0.8, 0.8)), tag="floor")
    centre = np.array([-0.6, 0.0, 1.0])
    scene.renderables.add_pointcloud(
        centre[None], DiffuseMaterial(), UniformColors((0.8, 0.2, 0.2)), point_size=0.6, tag="point"
    )
    sun = scene.lights.add_sun(3.0, angular_diameter=0.0, rotation_mode="eulerXYZ", rotation=(0, 40, 0))
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"))
    floor = res.instance == 0
    lum = res.rgba[..., :3].mean(axis=-1)
    shadow = floor & (lum < 0.5 * np.median(lum[floor]))
    pad = np.pad(floor, 1)
    floor_only = np.all([pad[1 + dy : 49 + dy, 1 + dx : 65 + dx] for dy in (-1, 0, 1) for dx in (-1, 0, 1)], axis=0)
    ys, xs = np.mgrid[0:48, 0:64]
    x = np.stack([(xs + 0.5 - 32) * 0.05, (24 - ys - 0.5) * 0.05, np.zeros_like(xs, dtype=float)], axis=-1)
    to_sun = -np.asarray(sun.direction)
    off = centre - x
    dist = np.linalg.norm(np.cross(off, to_sun), axis=-1)  # from the sphere's centre to each pixel's sun ray
    expected = floor & (dist < 0.3)
    # a pixel from the shadow's edge, or from the sphere's (its anti-aliased edge lies over the floor)
    near_edge = (np.abs(dist - 0.3) < 0.05) | ~floor_only
    assert expected.sum() > 80
    assert not np.any((shadow != expected) & ~near_edge)
    assert abs(int((shadow & floor_only).sum()) - int((expected & floor_only).sum())) <= 0.05 * expected.sum()


@pytest.mark.parametrize("splat", [True, False])
@pytest.mark.parametrize("d_px", [0.4, 0.8])
def test_sub_pixel_spheres_cover_their_area(pyr, d_px, splat, monkeypatch):
    """Spheres far below a pixel: a cloud of them covers 1 - exp(-sum of their projected areas per pixel) of the
    image, as a path tracer's alpha, whether the coverage scheme splats every sphere (render.SPLAT) or blends
    them in the colour pass (a random subset of wider spheres of the same summed area from the second frame)."""
    from blendify_pyrender import render as pr

    monkeypatch.setattr(pr, "SPLAT", splat)
    rng = np.random.default_rng(3)
    n = 4000
    scene = Scene()
    scene.set_orthographic_camera((48, 36), ortho_scale=2.4, translation=(0, 0, 5.0), near=0.1, far=20)
    pts = np.c_[rng.uniform(-1.2, 1.2, n), rng.uniform(-0.9, 0.9, n), rng.uniform(-0.5, 0.5, n)]
    scene.renderables.add_pointcloud(pts, DiffuseMaterial(), UniformColors((0.8, 0.8, 0.8)), point_size=0.05 * d_px)
    scene.lights.set_background_light(1.0)
    res = render(scene, backend=pyr, quality="preview")
    expected = 1 - np.exp(-n * np.pi * d_px**2 / 4 / (48 * 36))  # 0.25, 0.69
    assert abs(res.rgba[..., 3].mean() - expected) < 0.05 * expected
    again = render(scene, backend=pyr, quality="preview")
    notes = again.meta["approximations"]
    assert (pr.SPLAT_NOTE in notes) == splat
    thinned = any("sub-pixel spheres" in a for a in notes)
    assert thinned == (not splat and d_px < pr.SUBPIXEL_DRAWN_DIAMETER)
    assert abs(again.rgba[..., 3].mean() - expected) < 0.05 * expected


@pytest.mark.slow
def test_small_point_cloud_coverage_matches_cycles(pyr):
    st = available_backends().get("cycles")
    if st is None or not st.available:
        reason = f"Cycles unavailable: {st.reason if st else 'not registered'}"
        print(reason)
        pytest.skip(reason)
    scene = testing.pointcloud_scene(n=20000, resolution=(48, 36), point_size=0.01)
    preview = render(scene, backend=pyr, quality="preview")
    final = render(scene, backend="cycles", samples=32, seed=0)
    a, b = preview.rgba[..., 3].mean(), final.rgba[..., 3].mean()
    assert 0.05 < b < 0.95
    print(f"coverage: preview {a:.4f}, Cycles {b:.4f}")
    assert abs(a - b) <= 0.05 * b, (a, b)


# -- emissive surfaces light the scene -------------------------------------------------------------------
def _panel_scene(emission: float = 5.0, with_area_light: bool = False) -> Scene:
    """testing.plane_scene's Lambertian plane (albedo 0.5, orthographic camera from above) under a 0.6 x 0.4
    panel 1.5 above it that emits downwards (and upwards: Cycles' mesh emission is two-sided), or under the
    area light of the same power (pi x radiance x area) instead."""
    scene = testing.plane_scene("sun", resolution=(32, 32))
    for light in list(scene.lights):
        scene.lights.remove(light)
    if with_area_light:
        scene.lights.add_area("rectangle", (0.6, 0.4), strength=np.pi * 0.24 * emission, translation=(0, 0, 1.5))
        return scene
    panel = np.array([[-0.3, -0.2, 1.5], [0.3, -0.2, 1.5], [0.3, 0.2, 1.5], [-0.3, 0.2, 1.5]])
    scene.renderables.add_mesh(
        panel,
        [[0, 1, 2, 3]],
        PrincipledBSDFMaterial(emission_color=(1.0, 1.0, 1.0), emission_strength=emission),
        UniformColors((0.0, 0.0, 0.0)),
        tag="panel",
    )
    return scene


def test_emitter_lights_have_the_emitted_power():
    from blendify_pyrender.translate import emitter_lights

    scene = _panel_scene(emission=5.0)
    lights = emitter_lights(scene.renderables["panel"])
    assert len(lights) == 2 and all(type(lt).__name__ == "AreaLight" for lt in lights)
    for lt in lights:
        assert lt.strength == pytest.approx(np.pi * 0.24 * 5.0)  # pi x radiance x area, per side
        assert lt.area == pytest.approx(0.24)
        np.testing.assert_allclose(lt.matrix_world[:3, 3], [0, 0, 1.5], atol=1e-3)
        np.testing.assert_allclose(np.linalg.det(lt.matrix_world[:3, :3]), 1.0, atol=1e-9)
    directions = sorted(float(-lt.matrix_world[2, 2]) for lt in lights)  # each emits along its local -Z
    np.testing.assert_allclose(directions, [-1.0, 1.0], atol=1e-9)
    sphere = Scene().renderables.add_sphere_nurbs(
        0.5, PrincipledBSDFMaterial(emission_color=(1.0, 0.5, 0.25), emission_strength=2.0), UniformColors((1, 1, 1))
    )
    (point,) = emitter_lights(sphere)
    area = float(sum(0.5 * np.linalg.norm(np.cross(*np.diff(t, axis=0)), axis=-1) for t in _triangles(sphere)))
    assert type(point).__name__ == "PointLight"
    assert point.strength == pytest.approx(2 * np.pi * area * 2.0)
    assert emitter_lights(Scene().renderables.add_sphere_nurbs(0.5, DiffuseMaterial(), UniformColors((1, 1, 1)))) == []


def _triangles(r):
    tm = r.to_mesh()
    return np.asarray(tm.vertices)[np.asarray(tm.faces)]


def test_emissive_panel_lights_the_plane_as_its_area_light(pyr):
    lit = render(_panel_scene(), backend=pyr, quality="preview", outputs=("rgb", "instance"))
    ref = render(_panel_scene(with_area_light=True), backend=pyr, quality="preview", outputs=("rgb",))
    plane = lit.instance == 0  # the panel hides part of the plane from the camera
    assert plane.sum() > 500
    a, b = lit.rgba[..., :3][plane].mean(), ref.rgba[..., :3][plane].mean()
    assert b > 0.05 and abs(a - b) < 0.03 * b, (a, b)
    assert any("emissive surfaces light the scene" in n for n in lit.meta["approximations"])
    # the lights follow the emitter when it moves (the session rebuilds them)
    scene = _panel_scene()
    render(scene, backend=pyr, quality="preview")
    scene.renderables["panel"].set_position(translation=(0.5, 0, 0))
    moved = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"))
    lum = moved.rgba[..., :3].mean(axis=-1)
    assert lum[:, 24:].mean() > 1.2 * lum[:, :8].mean()  # brighter towards +x (right)


# -- environment maps light the scene with their directional distribution ----------------------------------
def _two_tone_map(top: float, bottom: float, sun: float = 0.0) -> np.ndarray:
    """(16, 32) HDR map: radiance ``top`` above the horizon, ``bottom`` below; a 2 x 2 texel sun of radiance
    ``sun`` near the zenith when given."""
    img = np.full((16, 32, 3), bottom, dtype=np.float32)
    img[:8] = top
    if sun:
        img[:2, 15:17] = sun
    return img


def test_environment_sh_and_sun():
    from blendify_pyrender.translate import environment_light, environment_sun, sh_basis, uniform_sh

    from blendify_core.ir.lights import EnvironmentMap

    flat = environment_light(EnvironmentMap(np.full((16, 32, 3), 0.5, np.float32), strength=2.0))
    assert flat.sun_direction is None
    np.testing.assert_allclose(flat.sh, uniform_sh([1.0, 1.0, 1.0]), atol=0.01)
    # irradiance / pi of a two-tone sky: 1 facing up, 0 facing down, 0.5 sideways (exact for band <= 2)
    sky = environment_light(EnvironmentMap(_two_tone_map(1.0, 0.0)))
    up, down, side = sh_basis(np.array([[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0]])) @ sky.sh[:, 0]
    assert up == pytest.approx(1.0, abs=0.08) and down == pytest.approx(0.0, abs=0.08)
    assert side == pytest.approx(0.5, abs=0.02)
    lit = environment_light(EnvironmentMap(_two_tone_map(0.2, 0.1, sun=500.0)))
    assert lit.sun_direction is not None and lit.sun_direction[2] > 0.95  # near the zenith
    texel = (2 * np.pi / 32) * (np.pi / 16) * np.cos(np.pi * (0.5 - np.array([0.5, 1.5]) / 16))
    np.testing.assert_allclose(lit.sun_irradiance, 500.0 * 2 * texel.sum(), rtol=1e-6)
    sun = environment_sun(lit)
    np.testing.assert_allclose(sun.linear_color * sun.strength, lit.sun_irradiance, rtol=1e-6)
    np.testing.assert_allclose(sun.direction, -lit.sun_direction, atol=1e-9)  # shines from the sun


def test_environment_lights_by_direction_and_is_seen_behind(pyr):
    """The plane facing up is lit by the upper hemisphere: bright sky and dark ground light it 1 x albedo
    (irradiance pi), the reverse 0 (the old uniform ambient gave both the mean, 0.5); on an opaque film the
    map shows where nothing is hit."""
    means = {}
    for name, img in (("sky", _two_tone_map(1.0, 0.0)), ("ground", _two_tone_map(0.0, 1.0))):
        scene = testing.plane_scene("background", resolution=(32, 32), albedo=0.5)
        scene.lights.set_environment_map(img)
        scene.lights.set_background_light(0.0)
        res = render(scene, backend=pyr, quality="preview", outputs=("rgb",))
        means[name] = float(res.rgba[8:24, 8:24, :3].mean())
        assert any("light.environment" in a for a in res.meta["approximations"])
    assert means["sky"] == pytest.approx(0.5, rel=0.1) and means["ground"] < 0.05
    scene = testing.plane_scene("background", resolution=(32, 32))
    scene.lights.set_environment_map(_two_tone_map(1.0, 0.25))
    scene.lights.set_background_light(0.0)
    scene.set_perspective_camera(
        (32, 32), fov_x=np.deg2rad(60), rotation_mode="look_at", rotation=(0, 10, 0.5), translation=(0, -1, 0.5)
    )
    res = render(scene, backend=pyr, quality="preview", transparent_background=False)
    miss = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance")).instance < 0
    assert miss[:8].all()  # the sky above the plane's horizon
    np.testing.assert_allclose(res.rgba[:8, :, :3], 1.0, atol=1e-5)


# -- glass: see-through with a Fresnel-weighted opacity ------------------------------------------------------
def _glass_scene(tint=(1.0, 1.0, 1.0), behind=(0.8, 0.1, 0.1), with_plane: bool = True) -> Scene:
    """A glass quad (transmission 1, IOR 1.5) head-on in front of a Lambertian plane, uniform background."""
    scene = Scene()
    scene.set_orthographic_camera((32, 32), ortho_scale=2.0, translation=(0, 0, 5.0), near=0.1, far=20)
    if with_plane:
        scene.renderables.add_plane_mesh(4.0, DiffuseMaterial(), UniformColors(behind, color_space="linear"))
    scene.renderables.add_plane_mesh(
        1.0,
        PrincipledBSDFMaterial(transmission_weight=1.0, roughness=0.0, ior=1.5),
        UniformColors(tint, color_space="linear"),
        translation=(0, 0, 1.0),
        tag="glass",
    )
    scene.lights.set_background_light(1.0)
    return scene


def test_glass_shows_what_is_behind_tinted(pyr):
    clear = render(_glass_scene(), backend=pyr, quality="preview").rgba
    behind = clear[2, 2, :3]  # the plane beside the glass
    through = clear[16, 16, :3]  # the plane through the glass: (1 - F0) of it plus the reflection
    # F0 = 0.04 (IOR 1.5) of the unit sky reflected, the rest of the plane transmitted (blended in linear radiance)
    np.testing.assert_allclose(through, 0.96 * behind + 0.04, rtol=0.03, atol=0.01)
    tinted = render(_glass_scene(tint=(0.9, 0.3, 0.9), behind=(0.5, 0.5, 0.5)), backend=pyr, quality="preview").rgba
    plane, glass = tinted[2, 2, :3], tinted[16, 16, :3]
    print(f"plane {plane}, through the tinted glass {glass}")
    # green absorbed (as far as blending can: 1 - opacity = 1 - 0.96 x 0.9 = 0.864 for every channel, blended in
    # linear radiance; the 8-bit pass blended gamma-encoded values, which darkened it to 0.73 by accident), red passes
    assert glass[1] <= 0.87 * plane[1] and glass[0] > 0.85 * plane[0]
    alone = render(_glass_scene(with_plane=False), backend=pyr, quality="preview").rgba
    assert 0.0 < alone[16, 16, 3] < 0.1  # on a transparent film: opacity = the reflected share (F0 = 0.04)
    res = render(_glass_scene(), backend=pyr, quality="preview")
    assert any("Fresnel-weighted opacity" in a for a in res.meta["approximations"])


def test_solid_glass_shows_the_world_refracted_upside_down(pyr):
    """A glass ball over a black floor under a white sky: rays through its upper part leave it going down (the
    floor: dark), through its lower part going up (the sky: bright), as through a ball lens; it is opaque (no
    blending of its front and back faces)."""
    scene = Scene()
    scene.set_orthographic_camera(
        (32, 32), ortho_scale=2.4, translation=(0, -5.0, 1.0), rotation=(0.7071068, 0.7071068, 0, 0)
    )
    scene.renderables.add_plane_mesh(10.0, DiffuseMaterial(), UniformColors((0.0, 0.0, 0.0)), tag="floor")
    scene.renderables.add_sphere_nurbs(
        1.0,
        PrincipledBSDFMaterial(transmission_weight=1.0, roughness=0.0, ior=1.5),
        UniformColors((1.0, 1.0, 1.0)),
        translation=(0, 0, 1.0),
        tag="ball",
    )
    scene.lights.set_background_light(1.0)
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"))
    ball = res.instance == 1
    rows = np.nonzero(ball.any(axis=1))[0]
    top, bottom = rows.min(), rows.max()
    upper = res.rgba[top + 3 : top + 8, 14:18, 1].mean()
    lower = res.rgba[bottom - 7 : bottom - 2, 14:18, 1].mean()
    print(f"upper part {upper:.3f}, lower part {lower:.3f}")
    assert lower > 0.5 and upper < 0.8 * lower  # straight see-through would give the reverse
    assert np.all(res.rgba[top + 2 : bottom - 1, 12:20, 3] == 1.0)  # inside the silhouette


def test_solid_glass_is_tinted_once(pyr):
    """A tinted glass ball alone in a uniform white world: every ray through it sees the world (radiance 1), so
    its colour is the transmitted share tinted by the base colour once (Cycles' Principled glass: green / red of
    0.47 measured on the preview_look glass sphere against 0.44 for its base colour), plus the reflected share."""
    scene = Scene()
    scene.set_orthographic_camera((16, 16), ortho_scale=2.4, translation=(0, 0, 5.0))
    tint = (0.9, 0.3, 0.9)
    scene.renderables.add_sphere_nurbs(
        1.0,
        PrincipledBSDFMaterial(transmission_weight=1.0, roughness=0.0, ior=1.5),
        UniformColors(tint, color_space="linear"),
    )
    scene.lights.set_background_light(1.0)
    centre = render(scene, backend=pyr, quality="preview").rgba[7:9, 7:9, :3].mean(axis=(0, 1))
    f0 = 0.04  # IOR 1.5 at normal incidence
    expected = (1 - f0) * np.array(tint) + f0
    print(f"centre {centre}, tinted once {expected}")
    np.testing.assert_allclose(centre, expected, rtol=0.1)


def test_environment_background_is_bilinear():
    """The map behind the objects is interpolated between texel centres (Cycles' "Linear"), wrapping in u."""
    from types import SimpleNamespace

    from blendify_pyrender.translate import environment_background

    from blendify_core.ir.lights import EnvironmentMap

    img = np.zeros((2, 4, 3), dtype=np.float32)
    img[0, :, 0] = [1.0, 3.0, 5.0, 7.0]  # top row
    env = EnvironmentMap(img, color_space="linear")
    lat = np.pi / 4  # v = 0.75: the top row's centre
    dirs = np.array(
        [
            [0.0, np.cos(lat), np.sin(lat)],  # u = 0.25: halfway between the first two texel centres
            [1.0, 0.0, 0.0],  # u = 0.5, v = 0.5: between columns 1 and 2 and between the rows
            [-np.cos(lat), -1e-9, np.sin(lat)],  # u = 1 - tiny: between the last column and the first (wrap)
        ]
    )
    camera = SimpleNamespace(pixel_rays=lambda: (np.zeros((3, 3)), dirs), width=3, height=1)
    bg = environment_background(env, camera, np.zeros(3))[0, :, 0]
    np.testing.assert_allclose(bg, [2.0, 2.0, 4.0], atol=1e-4)


# -- glass: the light through a glass ball reaches its shadow, focused -------------------------------------------
_BEAM = np.array([-np.sin(np.pi / 4), 0.0, -np.cos(np.pi / 4)])  # Blender's sun (local -Z) turned 45 deg about Y


def _ball_shadow_scene(material: object, color=(1.0, 1.0, 1.0), cube: bool = False) -> Scene:
    """A glass ball of radius 1 (or a cube of edge 1.6) 2 units up a sun's beam (45 degrees from the vertical)
    from the floor point (0, 0, 0) of a grey floor, seen from straight above (orthographic, 64x64 over 8 x 8
    units): the shadow's centre, (0, 0, 0), lies outside the object's footprint."""
    scene = Scene()
    scene.set_orthographic_camera((64, 64), ortho_scale=8.0, translation=(0.5, 0.0, 6.0), near=0.1, far=20)
    scene.renderables.add_plane_mesh(20.0, DiffuseMaterial(), UniformColors((0.8, 0.8, 0.8)), tag="floor")
    colors = UniformColors(color, color_space="linear")
    centre = tuple(-2.0 * _BEAM)
    if cube:
        scene.renderables.add_cube_mesh(1.6, material, colors, translation=centre, tag="ball")
    else:
        scene.renderables.add_sphere_nurbs(1.0, material, colors, translation=centre, tag="ball")
    scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(0, 45, 0))
    return scene


def _floor_at(scene: Scene, rgb: np.ndarray, points: list[tuple[float, float]]) -> list[np.ndarray]:
    """The mean colour of the pixels whose rays hit the floor within 0.8 pixels of each (x, y)."""
    cam = scene.camera
    o, d = cam.pixel_rays()
    hit = (o - (o[:, 2] / d[:, 2])[:, None] * d).reshape(cam.height, cam.width, 3)
    out = []
    for x, y in points:
        near = np.hypot(hit[..., 0] - x, hit[..., 1] - y) < 0.1
        assert near.any(), (x, y)
        out.append(rgb[near].mean(axis=0))
    return out


def test_glass_ball_focuses_light_into_its_shadow(pyr):
    """The light a glass ball lets through lands in its shadow, focused: the shadow's centre (on the beam
    through the ball's centre) gets more light than the open floor and far more than the shadow's edge; an
    opaque ball's shadow stays dark there (the control: the shadow is where the test computes it); a tinted
    ball's light is tinted; a glass cube does not focus (its shadow's centre and edge alike, lit through it)."""
    glass = PrincipledBSDFMaterial(transmission_weight=1.0, roughness=0.0, ior=1.5)
    spots = [(0.0, 0.0), (0.0, 0.6), (0.0, -0.6), (-3.0, 0.0)]  # centre, towards the edges across the beam, open

    def measure(material, color=(1.0, 1.0, 1.0), cube=False):
        scene = _ball_shadow_scene(material, color, cube)
        res = render(scene, backend=pyr, quality="preview")
        centre, edge_a, edge_b, lit = _floor_at(scene, res.rgba[..., :3], spots)
        return centre, 0.5 * (edge_a + edge_b), lit, res

    centre, edge, lit, _ = measure(DiffuseMaterial())
    print(f"opaque: centre {centre}, edge {edge}, lit {lit}")
    assert centre.mean() < 0.25 * lit.mean() and edge.mean() < 0.25 * lit.mean()
    centre, edge, lit, res = measure(glass)
    print(f"glass: centre {centre}, edge {edge}, lit {lit}")
    assert centre.mean() > 1.5 * lit.mean()  # focused: more light than arrives unblocked
    assert centre.mean() > 2.0 * edge.mean()
    notes = res.meta["approximations"]
    assert any(a.startswith("glass: the shadows of solid glass let its light through") for a in notes)
    centre, _, lit, _ = measure(glass, color=(1.0, 0.3, 0.3))
    print(f"tinted glass: centre {centre}")
    assert centre[0] > 1.5 * lit[0] and centre[1] < 0.5 * centre[0]
    centre, edge, lit, _ = measure(glass, color=(1.0, 0.3, 0.3), cube=True)
    print(f"tinted glass cube: centre {centre}, edge {edge}, lit {lit}")
    for spot in (centre, edge):  # lit through the cube, as much as the floor around (Fresnel: 0.92 of it)
        np.testing.assert_allclose(spot / lit, [0.92, 0.3 * 0.92, 0.3 * 0.92], rtol=0.1)


def test_mirror_ball_shows_the_floor_with_parallax(pyr):
    """A mirror ball above a floor red in front (y < -0.5) and green behind, seen level from the front: each
    pixel of the ball shows the floor where its reflected ray lands, computed here from the ray's hit on the
    ball, not where the same direction lands from the ball's centre (the probe's map looked up by direction
    alone: agreement 0.00). Counted over the pixels where the two differ in colour, clear of the boundary and
    of the silhouette."""
    scene = Scene()
    scene.set_orthographic_camera(
        (48, 48), ortho_scale=2.4, translation=(0, -5.0, 1.2), rotation=(0.7071068, 0.7071068, 0, 0)
    )
    edge = -0.5
    for colour, y in (((0.9, 0.05, 0.05), edge - 5.0), ((0.05, 0.9, 0.05), edge + 5.0)):
        scene.renderables.add_plane_mesh(
            10.0, DiffuseMaterial(), UniformColors(colour, color_space="linear"), translation=(0, y, 0)
        )
    centre = np.array([0.0, 0.0, 1.2])
    scene.renderables.add_sphere_nurbs(
        1.0, MetalMaterial(roughness=0.0), UniformColors((0.9, 0.9, 0.9)), translation=tuple(centre), tag="ball"
    )
    scene.lights.set_background_light(1.0)
    rgb = render(scene, backend=pyr, quality="preview").rgba[..., :3].reshape(-1, 3)
    o, d = scene.camera.pixel_rays()
    oc = o - centre
    b = np.einsum("ij,ij->i", oc, d)
    disc = b**2 - (np.einsum("ij,ij->i", oc, oc) - 0.9**2)  # inside 0.9 radii: clear of the silhouette
    hit = disc > 0
    p = o + (-b - np.sqrt(np.where(hit, disc, 0.0)))[:, None] * d
    n = p - centre  # radius 1
    r = d - 2.0 * np.einsum("ij,ij->i", d, n)[:, None] * n
    down = hit & (r[:, 2] < -0.2)
    rz = np.where(down, r[:, 2], -1.0)
    y_ray = p[:, 1] - r[:, 1] * p[:, 2] / rz  # where the reflected ray meets the floor
    y_dir = centre[1] - r[:, 1] * centre[2] / rz  # where the same direction from the centre meets it
    differ = down & ((y_ray < edge) != (y_dir < edge)) & (np.abs(y_ray - edge) > 0.2) & (np.abs(y_dir - edge) > 0.2)
    print(f"{differ.sum()} pixels where the ray's landing point and the centre's direction disagree")
    assert differ.sum() >= 10
    red = rgb[differ, 0] > rgb[differ, 1]
    agree = np.mean(red == (y_ray[differ] < edge))
    print(f"agreement with the ray's own landing point: {agree:.2f}")
    assert agree >= 0.8
