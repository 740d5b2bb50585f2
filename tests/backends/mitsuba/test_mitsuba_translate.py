"""Translation of the IR into the ``mi.load_dict`` dictionary, checked without rendering: types,
to_world matrices, fov, principal-point offsets, radiometric values, BSDF choice, mesh buffers."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from blendify_mitsuba import MitsubaBackend
from blendify_mitsuba.translate import MitsubaContext, MitsubaTranslator

import blendify_core as bf
from blendify_core import testing
from blendify_core.ir.colors import UniformColors, VertexColors
from blendify_core.ir.materials import (
    DiffuseMaterial,
    GlossyBSDFMaterial,
    MetalMaterial,
    PrincipledBSDFMaterial,
)
from blendify_core.pipeline.capabilities import ALL_FEATURES
from blendify_core.pipeline.settings import resolve_settings

_status = MitsubaBackend.probe()
if not _status.available:  # pragma: no cover - depends on the machine
    print(f"\nskipping the mitsuba backend tests: {_status.reason}")
    pytest.skip(f"mitsuba backend unavailable: {_status.reason}", allow_module_level=True)

pytestmark = pytest.mark.mitsuba

SETTINGS = resolve_settings(samples=4, max_bounces=2)


def _translate(scene, mi_scalar, max_spheres=1000, settings=SETTINGS):
    return MitsubaTranslator(settings, max_analytic_spheres=max_spheres).translate(scene)


def _handle(obj, *args, scene=None):
    """What the translator's handler for ``obj`` returns (one object, without walking a scene)."""
    return MitsubaTranslator(SETTINGS).dispatch(obj, MitsubaContext(scene=scene), *args)


def _emitters(scene):
    return MitsubaTranslator(SETTINGS).emitters(MitsubaContext(scene=scene))


def _m(t) -> np.ndarray:
    return np.array(t.matrix, dtype=np.float64)


def test_import_does_not_load_the_engine():
    code = "import sys, blendify_mitsuba; b = blendify_mitsuba.MitsubaBackend.probe(); "
    code += "print(b.available, 'mitsuba' in sys.modules, 'drjit' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", "False", "False"]


def test_capability_table_declares_every_feature():
    caps = MitsubaBackend.capabilities()
    assert set(caps) == set(ALL_FEATURES)
    for name, cap in caps.items():
        assert cap.level in ("exact", "approximate", "unsupported")
        if cap.level != "exact":
            assert cap.note, f"{name}: approximations and unsupported features need a note"


def test_perspective_camera(mi_scalar):
    scene = bf.Scene()
    k = np.array([[70.0, 0, 30.2], [0, 70.0, 20.7], [0, 0, 1]])
    cam = scene.set_perspective_camera(
        (64, 48), K=k, rotation_mode="look_at", rotation=(0, 0, 0), translation=(1, -3, 2), near=0.2, far=50
    )
    d = _handle(cam)
    assert d["type"] == "perspective" and d["fov_axis"] == "x"
    assert d["fov"] == pytest.approx(math.degrees(2 * math.atan(64 / 140.0)))
    assert d["principal_point_offset_x"] == pytest.approx((32 - 30.7) / 64)
    assert d["principal_point_offset_y"] == pytest.approx((24 - 21.2) / 48)
    assert (d["near_clip"], d["far_clip"]) == (0.2, 50)
    m = _m(d["to_world"])
    r, t = cam.opencv_extrinsics()
    # T_cv . diag(-1, -1, 1, 1): Mitsuba +Z = OpenCV +Z (forward), Mitsuba +X = OpenCV -X, +Y = -Y
    np.testing.assert_allclose(m[:3, 3], cam.translation, atol=1e-6)
    np.testing.assert_allclose(m[:3, 2], r[2], atol=1e-6)
    np.testing.assert_allclose(m[:3, 0], -r[0], atol=1e-6)
    np.testing.assert_allclose(m[:3, 1], -r[1], atol=1e-6)
    np.testing.assert_allclose(m[:3, 2], cam.viewdir, atol=1e-6)


def test_orthographic_camera_translates_for_the_principal_point(mi_scalar):
    scene = bf.Scene()
    cam = scene.set_orthographic_camera((64, 48), ortho_scale=3.2, center=(40.5, 20.0), translation=(0, 0, 5))
    d = _handle(cam)
    assert d["type"] == "orthographic"
    m = _m(d["to_world"])
    np.testing.assert_allclose(np.linalg.norm(m[:3, :3], axis=0), [1.6, 1.6, 1.0], rtol=1e-6)
    # the image centre ray must come from the pixel (W/2 - 0.5, H/2 - 0.5) of the IR camera
    o, _ = cam.pixel_rays(np.array([[31.5, 23.5]]))
    np.testing.assert_allclose(m[:3, 3], o[0], atol=1e-6)


def test_lights_radiometry(mi_scalar):
    scene = bf.Scene()
    scene.lights.add_point(100.0, shadow_soft_size=0.0, translation=(0, 0, 2), color=(1, 1, 1))
    scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(20, 0, 0))
    scene.lights.add_spot(200.0, spot_size=np.deg2rad(90), spot_blend=0.3, translation=(0, 0, 3))
    scene.lights.add_area("rectangle", (0.5, 0.2), 40.0, translation=(1, 0, 2))
    scene.lights.add_area("circle", 0.4, 30.0, translation=(-1, 0, 2))
    scene.lights.set_background_light(0.5, (1, 1, 1))
    d = _emitters(scene)
    point, sun, spot, rect, disk = (d[f"light{i:04d}"] for i in range(5))
    assert point["type"] == "point"
    assert point["intensity"]["value"] == pytest.approx([100 / (4 * np.pi)] * 3)
    assert point["position"] == pytest.approx([0, 0, 2])
    assert sun["type"] == "directional" and sun["irradiance"]["value"] == pytest.approx([3.0] * 3)
    sun_dir = scene.lights["Sun_000"].direction
    assert sun["direction"] == pytest.approx(list(sun_dir))
    assert spot["type"] == "spot" and spot["intensity"]["value"] == pytest.approx([200 / (4 * np.pi)] * 3)
    assert spot["cutoff_angle"] == pytest.approx(45.0)
    assert spot["beam_width"] == pytest.approx(45.0)  # no built-in ramp: Blender's falloff is the texture
    assert _m(spot["to_world"])[:3, 2] == pytest.approx([0, 0, -1])  # Mitsuba +Z = Blender -Z: downwards
    assert rect["type"] == "rectangle" and rect["flip_normals"] and rect["bsdf"]["type"] == "null"
    assert rect["emitter"]["radiance"]["value"] == pytest.approx([40 / (np.pi * 0.1)] * 3)
    np.testing.assert_allclose(np.linalg.norm(_m(rect["to_world"])[:3, :3], axis=0), [0.25, 0.1, 1.0])
    assert disk["type"] == "disk"
    assert disk["emitter"]["radiance"]["value"] == pytest.approx([30 / (np.pi * np.pi * 0.04)] * 3)
    assert d["background"]["type"] == "constant" and d["background"]["radiance"]["value"] == pytest.approx([0.5] * 3)


def test_spot_blend_is_blenders_falloff_as_projected_texture(mi_scalar):
    """The spot's texture holds spot_falloff at the direction each texel looks along (Mitsuba's spot: uv =
    0.5 + 0.5 tan(angle) / tan(cutoff)); a spot too wide for the texture keeps the linear ramp, listed."""
    from blendify_core.ir.physics import spot_cone, spot_falloff

    size, blend = np.deg2rad(90), 0.3
    scene = bf.Scene()
    scene.lights.add_spot(200.0, spot_size=size, spot_blend=blend, translation=(0, 0, 3))
    tex = np.array(_emitters(scene)["light0000"]["texture"]["data"])[..., 0]
    n = tex.shape[0]
    assert tex.shape == (n, n) and n >= 64
    uv = (np.arange(n) + 0.5) / n
    tan = 2.0 * np.hypot(uv[:, None] - 0.5, uv[None, :] - 0.5) * np.tan(0.5 * size)
    np.testing.assert_allclose(tex, spot_falloff(1.0 / np.sqrt(1.0 + tan**2), size, blend), atol=1e-6)
    half, inner = spot_cone(size, blend)
    band = (tan > np.tan(inner)) & (tan < np.tan(half))
    assert band.sum() > 100 and 0.0 < tex[band].min() < 0.1 and 0.9 < tex[band].max() < 1.0
    assert tex[n // 2, n // 2] == pytest.approx(1.0) and tex[0, 0] == 0.0

    for size_deg, b in ((179.0, blend), (45.0, 0.01)):  # too wide; band too narrow for the largest texture
        other = bf.Scene()
        other.lights.add_spot(200.0, spot_size=np.deg2rad(size_deg), spot_blend=b, translation=(0, 0, 3))
        ctx = MitsubaContext(scene=other)
        d = MitsubaTranslator(SETTINGS).emitters(ctx)["light0000"]
        assert "texture" not in d and d["beam_width"] < d["cutoff_angle"] == pytest.approx(size_deg / 2)
        assert any("light.spot.blend" in a and "Spot_000" in a for a in ctx.approximations)


def test_point_light_with_radius_is_a_sphere_emitter(mi_scalar):
    scene = bf.Scene()
    scene.lights.add_point(100.0, shadow_soft_size=0.2, translation=(0, 0, 2))
    d = _emitters(scene)["light0000"]
    assert d["type"] == "sphere" and d["radius"] == 0.2 and d["bsdf"]["type"] == "null"
    assert d["emitter"]["radiance"]["value"] == pytest.approx([100 / (4 * np.pi**2 * 0.04)] * 3)


def test_environment_map_follows_equirect_uv(mi_scalar):
    """The envmap emitter must look up the texel that blendify_core.ir.lights.equirect_uv names."""
    mi = mi_scalar
    from blendify_core.ir.lights import equirect_uv

    h, w = 64, 128
    jj, ii = np.meshgrid((np.arange(w) + 0.5) / w, 1.0 - (np.arange(h) + 0.5) / h)
    img = np.dstack([jj, ii, np.zeros_like(jj)]).astype(np.float32)  # R = u, G = v (v up)
    scene = bf.Scene()
    scene.lights.set_environment_map(img, strength=1.0, rotation_mode="eulerXYZ", rotation=(0, 0, 30))
    env = mi.load_dict(_handle(scene.lights.environment, scene=scene))
    rng = np.random.default_rng(3)
    dirs = rng.normal(size=(40, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    rot = scene.lights.environment.rotation_matrix
    for d in dirs:
        uv = equirect_uv(rot.T @ d)
        if min(uv[0], 1 - uv[0]) < 0.03 or min(uv[1], 1 - uv[1]) < 0.05:
            continue  # bilinear filtering across the seam / poles
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*(-d))
        val = np.array(env.eval(si))
        assert val[:2] == pytest.approx(uv, abs=0.01)


def test_materials_map_to_the_documented_bsdfs(mi_scalar):
    col = {"type": "rgb", "value": [0.5, 0.5, 0.5]}
    d = _handle(DiffuseMaterial(), col)
    assert d["type"] == "twosided" and d["bsdf"]["type"] == "diffuse"
    d = _handle(PrincipledBSDFMaterial(specular_ior=0.0, roughness=0.5), col)
    assert d["bsdf"]["type"] == "diffuse"  # no specular layer: exact Lambert
    d = _handle(GlossyBSDFMaterial(roughness=0.3), col)
    assert d["type"] == "twosided" and d["bsdf"]["type"] == "roughconductor"
    assert d["bsdf"]["alpha"] == pytest.approx(0.09)
    d = _handle(GlossyBSDFMaterial(roughness=0.0), col)
    assert d["bsdf"]["type"] == "conductor"
    # uniform colours: Cycles' layers as a sum of built-in lobes (blendify_mitsuba.principled)
    d = _handle(MetalMaterial(), col)
    assert d["bsdf"]["type"] == "blendbsdf"
    kinds = {d["bsdf"]["bsdf_0"]["type"], d["bsdf"]["bsdf_1"]["bsdf_0"]["type"]}
    assert kinds == {"roughconductor"}  # metal (0.9) and the dielectric specular (0.1), then the diffuse
    d = _handle(PrincipledBSDFMaterial(roughness=0.2, transmission_weight=1.0), col)
    assert d["type"] == "roughdielectric" and d["int_ior"] == pytest.approx(1.45)  # a solid: one-sided
    # texture colours keep Mitsuba's principled; Specular IOR Level 0.5 leaves the IOR unchanged
    tex = mi_scalar.load_dict({"type": "checkerboard"})
    d = _handle(PrincipledBSDFMaterial(ior=1.5, specular_ior=0.5), tex)
    assert d["bsdf"]["type"] == "principled" and d["bsdf"]["eta"] == pytest.approx(1.5)


def test_meshes_from_numpy_buffers(mi_scalar):
    scene = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    cols = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    scene.renderables.add_mesh(
        v,
        [[0, 1, 2], [0, 2, 3]],
        [DiffuseMaterial(), PrincipledBSDFMaterial(alpha=0.5)],
        [VertexColors(cols, color_space="linear"), UniformColors((0.2, 0.3, 0.4, 0.5))],
        faces_material=[0, 1],
        translation=(10, 0, 0),
        rotation_mode="eulerXYZ",
        rotation=(0, 0, 90),
        tag="m",
    )
    scene.set_perspective_camera((64, 48), fov_x=1.0, translation=(0, 0, 5))
    tr = _translate(scene, mi_scalar)
    keys = sorted(k for k in tr.scene_dict if k.startswith("r"))
    assert keys == ["r00000_m000", "r00000_m001"]
    m0 = tr.scene_dict["r00000_m000"]
    params = mi_scalar.traverse(m0)
    pos = np.array(params["vertex_positions"]).reshape(-1, 3)
    world = v[[0, 1, 2]] @ scene.renderables["m"].rotation_matrix.T + [10, 0, 0]
    np.testing.assert_allclose(np.sort(pos, axis=0), np.sort(world, axis=0), atol=1e-5)
    assert m0.has_attribute("vertex_color")
    assert tr.shapes["r00000_m000"].albedo is None  # varies: evaluated at hits
    np.testing.assert_allclose(
        tr.shapes["r00000_m001"].albedo, UniformColors((0.2, 0.3, 0.4)).linear_rgba[:3], rtol=1e-6
    )
    # alpha (material 0.5 x colour 0.5) -> mask wrapper
    assert "Mask" in str(tr.scene_dict["r00000_m001"].bsdf()) or "mask" in str(tr.scene_dict["r00000_m001"].bsdf())


def test_texture_uvs_are_flipped(mi_scalar):
    scene = testing.textured_quad_scene()
    tr = _translate(scene, mi_scalar)
    mesh = tr.scene_dict["r00000_m000"]
    params = mi_scalar.traverse(mesh)
    uv = np.array(params["vertex_texcoords"]).reshape(-1, 2)
    src = scene.renderables["quad"].triangle_uvs().reshape(-1, 2)
    np.testing.assert_allclose(uv[:, 0], src[:, 0])
    np.testing.assert_allclose(uv[:, 1], 1.0 - src[:, 1])


def test_pointcloud_analytic_then_merged(mi_scalar):
    scene = testing.pointcloud_scene(n=50)
    tr = _translate(scene, mi_scalar, max_spheres=100)
    spheres = [k for k, v in tr.scene_dict.items() if isinstance(v, dict) and v.get("type") == "sphere"]
    assert len(spheres) == 50 and tr.n_analytic_spheres == 50
    pc = scene.renderables["points"]
    first = tr.scene_dict["r00000_p0000000"]
    assert first["radius"] == pytest.approx(pc.radii()[0])
    assert first["center"] == pytest.approx(list(pc.vertices[0]))
    tr = _translate(scene, mi_scalar, max_spheres=10)  # opaque: one curve shape (blendify_mitsuba.points)
    assert tr.n_analytic_spheres == 0 and list(k for k in tr.scene_dict if k.startswith("r")) == ["r00000_curves"]
    assert tr.scene_dict["r00000_curves"].primitive_count() == 2 * 50  # a sphere's segment and a spacer per point
    far = testing.pointcloud_scene(n=50, point_size=0.0002)  # radius 1e-4 seen from ~5 units: too small
    tr = _translate(far, mi_scalar, max_spheres=10)
    assert list(k for k in tr.scene_dict if k.startswith("r")) == ["r00000_mesh"]
    pc.materials[0].alpha = 0.5  # partly transparent points need their inside: the merged icosphere mesh
    tr = _translate(scene, mi_scalar, max_spheres=10)
    assert list(k for k in tr.scene_dict if k.startswith("r")) == ["r00000_mesh"]
    assert tr.scene_dict["r00000_mesh"].face_count() == len(pc.to_mesh().faces)


def test_pointcloud_opaque_limit(mi_scalar):
    """Clouds that can be curves leave the analytic spheres at max_analytic_opaque points, the others at
    max_analytic_spheres; the backend's defaults are 500 and the variant's limit, an explicit value is both."""
    from blendify_mitsuba import DEFAULT_MAX_ANALYTIC_OPAQUE, DEFAULT_MAX_ANALYTIC_SPHERES, MitsubaBackend

    scene = testing.pointcloud_scene(n=50)
    tr = MitsubaTranslator(SETTINGS, max_analytic_spheres=1000, max_analytic_opaque=10).translate(scene)
    assert [k for k in tr.scene_dict if k.startswith("r")] == ["r00000_curves"]
    scene.renderables["points"].materials[0].alpha = 0.5  # no curves: analytic spheres up to 1000
    tr = MitsubaTranslator(SETTINGS, max_analytic_spheres=1000, max_analytic_opaque=10).translate(scene)
    assert tr.n_analytic_spheres == 50
    session = MitsubaBackend(variant="scalar_rgb").session
    assert session.max_analytic_opaque == DEFAULT_MAX_ANALYTIC_OPAQUE == 500
    assert session.max_analytic_spheres == DEFAULT_MAX_ANALYTIC_SPHERES["scalar"]
    explicit = MitsubaBackend(variant="scalar_rgb", max_analytic_spheres=2000).session
    assert explicit.max_analytic_opaque == explicit.max_analytic_spheres == 2000


def test_emission_builds_an_emitter_and_compositing_scenes(mi_scalar):
    scene = bf.Scene()
    scene.renderables.add_sphere_nurbs(
        0.5, PrincipledBSDFMaterial(emission_color=(1, 0.5, 0.25), emission_strength=3.0), UniformColors((1, 1, 1))
    )
    scene.set_perspective_camera((64, 48), fov_x=1.0, translation=(0, 0, 5))
    tr = _translate(scene, mi_scalar)
    shape = tr.scene_dict["r00000_m000"]  # the sphere's tessellation, an area emitter on it
    expected = PrincipledBSDFMaterial(emission_color=(1, 0.5, 0.25)).linear("emission_color")[:3] * 3.0
    radiance = mi_scalar.traverse(shape.emitter())["radiance.value"]
    assert [radiance[i] for i in range(3)] == pytest.approx(list(expected), rel=1e-6)
    assert tr.coverage_dict is None  # no sky: no compositing needed
    scene.lights.set_background_light(0.5)
    tr = _translate(scene, mi_scalar, 10, resolve_settings(samples=4, transparent_background=True))
    assert tr.coverage_dict["integrator"]["max_depth"] == 2 and "background" not in tr.coverage_dict
    assert "r00000_m000" in tr.coverage_dict
    assert "background" in tr.background_dict and "r00000_m000" not in tr.background_dict


def test_settings_drive_integrator(mi_scalar):
    def integrator_for(scene, settings):
        tr = _translate(scene, mi_scalar, settings=settings)
        assert tr.scene_dict["integrator"] is tr.integrator
        return tr.integrator, tr.effects

    scene = testing.plane_scene("sun")
    integ, eff = integrator_for(scene, resolve_settings(max_bounces=5))
    assert integ["max_depth"] == 2 and not eff.indirect_diffuse  # one convex plane: direct light only
    integ, _ = integrator_for(scene, resolve_settings(max_bounces=5, effects=False))
    assert integ["max_depth"] == 7
    integ, _ = integrator_for(testing.plane_scene("area"), resolve_settings(max_bounces=5))
    assert integ["max_depth"] == 3  # camera rays may pass through the light's null surface
    integ, _ = integrator_for(testing.bunny_scene(), resolve_settings(max_bounces=5))
    assert integ["max_depth"] == 7 and integ["hide_emitters"]


def test_bad_options_and_inputs():
    with pytest.raises(bf.InvalidSceneError, match="variant"):
        MitsubaBackend(variant="opengl")
    with pytest.raises(bf.InvalidSceneError, match="RGB variants"):
        MitsubaBackend(variant="scalar_spectral")
    with pytest.raises(bf.InvalidSceneError, match="max_analytic_spheres"):
        MitsubaBackend(max_analytic_spheres=-1)
    with pytest.raises(bf.InvalidSceneError, match="unknown option"):
        MitsubaBackend(foo=1)
    with pytest.raises(bf.InvalidSceneError, match="scene"):
        MitsubaBackend(variant="scalar_rgb").translate("not a scene", resolve_settings())


def test_sphere_is_the_irs_tessellation_with_its_wireframe(mi_scalar):
    """A sphere is the IR's UV-sphere mesh (the surface Cycles and pyrender render), so a wireframe material
    on it gets its tubes as on any mesh (it was dropped on Mitsuba's analytic sphere)."""
    scene = bf.Scene()
    s = scene.renderables.add_sphere_nurbs(
        0.5, bf.PrincipledBSDFWireframeMaterial(wireframe_thickness=0.01), UniformColors((0.5, 0.5, 0.5))
    )
    scene.set_perspective_camera((32, 24), fov_x=1.0, translation=(0, 0, 5))
    tr = _translate(scene, mi_scalar)
    mesh = tr.scene_dict["r00000_m000"]
    tm = s.to_mesh()
    assert mesh.face_count() == len(tm.faces)  # (vertices split per corner for the UVs)
    assert "r00000_w000" in tr.scene_dict and tr.n_analytic_spheres == 0


def test_wire_bands_sit_below_mitsubas_ray_offset():
    """The wireframe bands are lifted over their triangle by less than the offset Mitsuba gives rays leaving
    the surface beneath (so they cast no shadow on it: 6-8 % darker wireframes before) and by far more than
    float precision (so camera rays meet the band, not the surface)."""
    from blendify_mitsuba.translate import wire_bands

    ray_eps = 1500.0 * 2.0**-24
    for scale in (1.0, 50.0):
        v = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]) * scale
        verts, tris = wire_bands(v, np.array([[0, 1, 2]]), 0.1 * scale)
        lift = verts[:, 2] - scale
        reach = 1.0 + np.abs(v).max()
        assert len(tris) == 6
        assert np.all(lift > 100 * reach * 2.0**-24)
        assert np.all(lift < 0.5 * reach * ray_eps)
