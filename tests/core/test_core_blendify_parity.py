"""blendify 2.1 parity (docs/BLENDIFY_REFERENCE.md sections 1 and 6.4): every class and method has a
counterpart with blendify's parameter names, order and defaults (deliberate differences are listed
here with their reason), and none of blendify's confirmed bugs exists here."""

from __future__ import annotations

import inspect
import subprocess
import sys

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.ir.lights import LightsCollection
from blendify_core.ir.renderables import RenderablesCollection

POSE = ["rotation_mode", "rotation", "translation", "tag"]
MISSING = object()

# Deliberate differences from blendify 2.1 defaults (parameter -> (blendify, here, reason)).
DELIBERATE = {
    ("add_pointcloud", "point_size"): (0.006, 0.01, "point_size is the sphere DIAMETER in world units"),
    ("add_pointcloud", "base_primitive"): ("CUBE", "SPHERE", "points are spheres in every backend"),
    ("add_pointcloud", "particle_emission_strength"): (1, 0.0, "points do not self-illuminate unless asked"),
    ("PrincipledBSDFMaterial", "coat_ior"): (0.0, 1.5, "Blender clamps Coat IOR to >= 1; 1.5 is Blender's default"),
    ("MetalMaterial", "coat_ior"): (0.0, 1.5, "as PrincipledBSDFMaterial"),
    ("PlasticMaterial", "coat_ior"): (0.0, 1.5, "as PrincipledBSDFMaterial"),
}


def _params(fn) -> list[inspect.Parameter]:
    return [
        p
        for p in inspect.signature(fn).parameters.values()
        if p.name != "self" and p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)
    ]


def _assert_signature(owner: str, fn, expected: list[tuple[str, object]]) -> None:
    """``expected`` lists blendify's (name, default) in blendify's order; our parameters must contain
    them in the same relative order, the leading required ones at the same positions, with the same
    defaults unless listed in DELIBERATE."""
    params = _params(fn)
    names = [p.name for p in params]
    positions = []
    for name, default in expected:
        assert name in names, f"{owner}: missing blendify parameter {name!r} (have {names})"
        positions.append(names.index(name))
        ours = params[names.index(name)].default
        ours = MISSING if ours is inspect.Parameter.empty else ours
        if (owner, name) in DELIBERATE:
            blendify_default, here, _reason = DELIBERATE[(owner, name)]
            assert default == blendify_default and ours == here, (owner, name, ours)
            continue
        if default is MISSING or ours is MISSING:
            assert default is ours, f"{owner}.{name}: required in one API but not the other"
        elif isinstance(default, float) or isinstance(ours, float):
            assert np.isclose(float(ours), float(default), rtol=1e-6), f"{owner}.{name}: {ours!r} != {default!r}"
        elif isinstance(default, tuple):
            assert tuple(ours) == default, f"{owner}.{name}: {ours!r} != {default!r}"
        else:
            assert ours == default, f"{owner}.{name}: {ours!r} != {default!r}"
    assert positions == sorted(positions), f"{owner}: blendify's parameter order is not kept: {names}"
    required = [n for n, d in expected if d is MISSING]
    assert names[: len(required)] == required, f"{owner}: positional parameters differ: {names}"


POSE_DEFAULTS = [
    ("rotation_mode", "quaternionWXYZ"),
    ("rotation", None),
    ("translation", (0, 0, 0)),
    ("tag", None),
]
MCF = [("material", MISSING), ("colors", MISSING), ("faces_material", None)]
MC = [("material", MISSING), ("colors", MISSING)]

RENDERABLE_SIGNATURES = {
    "add_pointcloud": [
        ("vertices", MISSING),
        ("material", MISSING),
        ("colors", MISSING),
        ("point_size", 0.006),
        ("base_primitive", "CUBE"),
        ("particle_emission_strength", 1),
    ],
    "add_mesh": [("vertices", MISSING), ("faces", MISSING), *MCF],
    "add_cube_mesh": [("size", MISSING), *MCF],
    "add_circle_mesh": [("radius", MISSING), *MCF, ("num_vertices", 32), ("fill_type", "NGON")],
    "add_cylinder_mesh": [("radius", MISSING), ("height", MISSING), *MCF, ("num_vertices", 32), ("fill_type", "NGON")],
    "add_plane_mesh": [("size", MISSING), *MCF, ("shadow_catcher", False)],
    "add_ellipsoid_nurbs": [("radius", MISSING), *MC],
    "add_sphere_nurbs": [("radius", MISSING), *MC],
    "add_curve_nurbs": [("keypoints", MISSING), ("radius", MISSING), *MC],
}


@pytest.mark.parametrize("method", sorted(RENDERABLE_SIGNATURES))
def test_renderables_add_signatures(method):
    fn = getattr(RenderablesCollection, method)
    _assert_signature(method, fn, RENDERABLE_SIGNATURES[method] + POSE_DEFAULTS)


LIGHT_COLOR = ("color", (1.0, 1.0, 1.0))
LIGHT_SIGNATURES = {
    "add_point": [("strength", 100.0), ("shadow_soft_size", 0.25), LIGHT_COLOR, ("use_shadow", True)],
    "add_sun": [("strength", 10.0), ("angular_diameter", 0.00918043), LIGHT_COLOR, ("use_shadow", True)],
    "add_spot": [
        ("strength", 100.0),
        ("spot_size", 0.785398),
        ("spot_blend", 0.15),
        ("shadow_soft_size", 0.25),
        LIGHT_COLOR,
        ("use_shadow", True),
    ],
    "add_area": [("shape", MISSING), ("size", MISSING), ("strength", 100.0), LIGHT_COLOR, ("use_shadow", True)],
}


@pytest.mark.parametrize("method", sorted(LIGHT_SIGNATURES))
def test_lights_add_signatures_and_defaults(method):
    _assert_signature(method, getattr(LightsCollection, method), LIGHT_SIGNATURES[method] + POSE_DEFAULTS)


def test_light_defaults_take_effect():
    lights = bf.Scene().lights
    p = lights.add_point()
    assert (p.strength, p.shadow_soft_size, p.color, p.use_shadow) == (100.0, 0.25, (1.0, 1.0, 1.0), True)
    s = lights.add_sun()
    assert (s.strength, s.angular_diameter) == (10.0, 0.00918043)
    sp = lights.add_spot()
    assert (sp.strength, sp.spot_blend, sp.shadow_soft_size) == (100.0, 0.15, 0.25)
    assert np.isclose(sp.spot_size, 0.785398, atol=1e-6)
    a = lights.add_area("square", 2.0)
    assert a.strength == 100.0 and a.size == (2.0, 2.0)
    _assert_signature("set_background_light", LightsCollection.set_background_light, [("strength", 1.0), LIGHT_COLOR])
    assert hasattr(lights, "remove_background_light")
    # light properties are readable and settable (blendify: color, strength, use_shadow)
    p.color = (0.5, 0.25, 1.0)
    p.strength = 42.0
    p.use_shadow = False
    assert (p.color, p.strength, p.use_shadow) == ((0.5, 0.25, 1.0), 42.0, False)


def test_scene_camera_signatures():
    _assert_signature(
        "set_perspective_camera",
        bf.Scene.set_perspective_camera,
        [
            ("resolution", MISSING),
            ("focal_dist", None),
            ("fov_x", None),
            ("fov_y", None),
            ("center", None),
            ("near", 0.1),
            ("far", 100.0),
            ("tag", "camera"),
            ("rotation_mode", "quaternionWXYZ"),
            ("rotation", None),
            ("translation", (0, 0, 0)),
            ("resolution_percentage", 100),
        ],
    )
    _assert_signature(
        "set_orthographic_camera",
        bf.Scene.set_orthographic_camera,
        [
            ("resolution", MISSING),
            ("ortho_scale", 1.0),
            ("near", 0.1),
            ("far", 100.0),
            ("tag", "camera"),
            ("rotation_mode", "quaternionWXYZ"),
            ("rotation", None),
            ("translation", (0, 0, 0)),
            ("resolution_percentage", 100),
        ],
    )


def test_positionable_api():
    _assert_signature(
        "set_position",
        bf.Mesh.set_position,
        [("rotation_mode", "quaternionWXYZ"), ("rotation", None), ("translation", None)],
    )
    light = bf.Scene().lights.add_point()
    for name in ("quaternion", "translation", "tag", "set_position"):
        assert hasattr(light, name)


def test_colour_and_material_signatures():
    _assert_signature("UniformColors", bf.UniformColors.__init__, [("uniform_color", MISSING)])
    _assert_signature("VertexColors", bf.VertexColors.__init__, [("vertex_colors", MISSING)])
    _assert_signature("VertexUV", bf.VertexUV.__init__, [("data", MISSING)])
    _assert_signature("FacesUV", bf.FacesUV.__init__, [("data", MISSING)])
    _assert_signature("TextureColors", bf.TextureColors.__init__, [("texture", MISSING), ("uv_map", MISSING)])
    _assert_signature(
        "FileTextureColors", bf.FileTextureColors.__init__, [("texture_path", MISSING), ("uv_map", MISSING)]
    )
    _assert_signature(
        "GlossyBSDFMaterial", bf.GlossyBSDFMaterial.__init__, [("roughness", 0.4), ("distribution", "GGX")]
    )
    _assert_signature(
        "PrincipledBSDFWireframeMaterial",
        bf.PrincipledBSDFWireframeMaterial.__init__,
        [("wireframe_thickness", 0.01), ("wireframe_color", (0, 0, 0, 1))],
    )
    _assert_signature(
        "MetalMaterial",
        bf.MetalMaterial.__init__,
        [("roughness", 0.55), ("metallic", 0.9), ("coat_ior", 0.0), ("specular_ior", 0.5), ("coat_roughness", 0.0)],
    )
    _assert_signature(
        "PlasticMaterial",
        bf.PlasticMaterial.__init__,
        [("roughness", 0.3), ("ior", 1.45), ("coat_ior", 0.0), ("specular_ior", 0.5), ("coat_roughness", 0.0)],
    )


BLENDIFY_PRINCIPLED = [
    ("alpha", 1.0),
    ("anisotropic", 0.0),
    ("anisotropic_rotation", 0.0),
    ("coat_ior", 0.0),
    ("coat_roughness", 0.0),
    ("coat_tint", (1.0, 1.0, 1.0, 1.0)),
    ("coat_weight", 0.0),
    ("diffuse_roughness", 0.0),
    ("emission_color", (0, 0, 0, 0)),
    ("emission_strength", 0.0),
    ("ior", 1.45),
    ("metallic", 0.0),
    ("roughness", 0.4),
    ("sheen_weight", 0.0),
    ("sheen_roughness", 0.5),
    ("sheen_tint", (0.5, 0.5, 0.5, 1.0)),
    ("specular_ior", 0.3),
    ("specular_tint", (0.0, 0.0, 0.0, 1.0)),
    ("subsurface_anisotropy", 0.0),
    ("subsurface_radius", (1.0, 0.2, 1.0)),
    ("subsurface_scale", 0.05),
    ("subsurface_weight", 0.0),
    ("thin_film_ior", 1.33),
    ("thin_film_thickness", 0.0),
    ("transmission_weight", 0.0),
]


def test_principled_signature_and_defaults():
    _assert_signature("PrincipledBSDFMaterial", bf.PrincipledBSDFMaterial.__init__, BLENDIFY_PRINCIPLED)
    mat = bf.PrincipledBSDFMaterial()
    for name, default in BLENDIFY_PRINCIPLED:
        value = getattr(mat, name)
        if ("PrincipledBSDFMaterial", name) in DELIBERATE:
            default = DELIBERATE[("PrincipledBSDFMaterial", name)][1]
        assert np.allclose(value, default), (name, value, default)


def test_principled_rejects_old_names_like_blendify():
    for old in ("clearcoat", "clearcoat_roughness", "specular"):
        with pytest.raises(bf.InvalidSceneError, match=old):
            bf.PrincipledBSDFMaterial(**{old: 0.5})


@pytest.mark.parametrize(
    "cls",
    [
        bf.PrincipledBSDFMaterial,
        bf.GlossyBSDFMaterial,
        bf.MetalMaterial,
        bf.PlasticMaterial,
        bf.PrincipledBSDFWireframeMaterial,
        bf.PlasticWireframeMaterial,
        bf.MetalWireframeMaterial,
    ],
)
def test_material_attributes_are_settable_and_read_back(cls):
    """blendify bug 5 (assignments were silent no-ops, getters returned property objects) and bug 4
    (MetalWireframeMaterial() raised NameError)."""
    mat = cls()
    assert isinstance(mat.roughness, float)
    rev = mat.revision
    mat.roughness = 0.123
    assert mat.roughness == 0.123 and mat.get("roughness") == 0.123
    assert mat.revision == rev + 1
    assert mat.parameters()["roughness"] == 0.123
    if "wireframe_thickness" in cls.parameter_names():
        mat.wireframe_thickness = 0.05
        mat.wireframe_color = (1.0, 0.0, 0.0, 1.0)
        assert mat.wireframe_thickness == 0.05 and mat.wireframe_color == (1.0, 0.0, 0.0, 1.0)
        assert mat.has_wireframe
    if "metallic" in cls.parameter_names():
        mat.metallic = 0.7
        assert mat.metallic == 0.7


def test_metal_wireframe_material_constructs_with_blendify_defaults():
    mat = bf.MetalWireframeMaterial()
    assert (mat.roughness, mat.metallic, mat.specular_ior) == (0.55, 0.9, 0.5)
    assert mat.wireframe_thickness == 0.01 and mat.wireframe_color == (0.0, 0.0, 0.0, 1.0)


def test_auto_tags_use_blendify_prefixes():
    s = bf.Scene()
    r, m, c = s.renderables, bf.PrincipledBSDFMaterial(), bf.UniformColors((1, 1, 1))
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    objs = [
        r.add_mesh(v, [[0, 1, 2]], m, c),
        r.add_mesh(v, [[0, 1, 2]], m, c),
        r.add_pointcloud(v, m, c),
        r.add_cube_mesh(1, m, c),
        r.add_circle_mesh(1, m, c),
        r.add_cylinder_mesh(1, 1, m, c),
        r.add_plane_mesh(1, m, c),
        r.add_ellipsoid_nurbs((1, 2, 3), m, c),
        r.add_sphere_nurbs(1, m, c),
        r.add_curve_nurbs(v, 0.1, m, c),
    ]
    assert [o.tag for o in objs] == [
        "Mesh_000",
        "Mesh_001",
        "PointCloud_000",
        "Cube_000",
        "Circle_000",
        "Cylinder_000",
        "Plane_000",
        "Ellipsoid_000",
        "Sphere_000",
        "Curve_000",
    ]
    lights = [s.lights.add_point(), s.lights.add_sun(), s.lights.add_spot(), s.lights.add_area("circle", 1.0)]
    assert [light.tag for light in lights] == ["Point_000", "Sun_000", "Spot_000", "Area_000"]


def test_collection_protocol():
    s = bf.Scene()
    m, c = bf.PrincipledBSDFMaterial(), bf.UniformColors((1, 1, 1))
    a = s.renderables.add_sphere_nurbs(1.0, m, c, tag="a")
    b = s.renderables.add_cube_mesh(1.0, m, c, tag="b")
    assert len(s.renderables) == 2 and list(s.renderables) == [a, b]
    assert s.renderables.keys() == ["a", "b"] and s.renderables.values() == [a, b]
    assert s.renderables.items() == [("a", a), ("b", b)]
    assert s.renderables["b"] is b and "a" in s.renderables
    del s.renderables["a"]
    s.renderables.remove(b)
    assert len(s.renderables) == 0
    # a removed tag can be reused (blendify example 06 removes and re-adds curves every frame)
    s.renderables.add_curve_nurbs([[0, 0, 0], [1, 1, 1]], 0.1, m, c, tag="a")
    light = s.lights.add_point(tag="key")
    assert s.lights["key"] is light and len(s.lights) == 1
    del s.lights["key"]
    assert len(s.lights) == 0


def test_scene_is_not_a_singleton():
    a, b = bf.Scene(), bf.Scene()
    assert a is not b and a.renderables is not b.renderables and a.lights is not b.lights
    a.renderables.add_sphere_nurbs(1.0, bf.PrincipledBSDFMaterial(), bf.UniformColors((1, 1, 1)), tag="x")
    a.set_perspective_camera((8, 8), fov_x=1.0)
    assert len(b.renderables) == 0 and b.camera is None
    b.renderables.add_cube_mesh(1.0, bf.PrincipledBSDFMaterial(), bf.UniformColors((1, 1, 1)), tag="x")
    assert type(a.renderables["x"]) is not type(b.renderables["x"])
    a.clear()
    assert len(a.renderables) == 0 and a.camera is None and len(b.renderables) == 1


def test_two_point_clouds_coexist_and_update():
    """blendify bugs 1 (a second point cloud raised KeyError), 2 (PointCloud.update_vertices raised
    AttributeError) and 3 (PointCloud.emit_shadow raised AttributeError)."""
    s = bf.Scene()
    rng = np.random.default_rng(0)
    p1 = s.renderables.add_pointcloud(rng.normal(size=(50, 3)), bf.DiffuseMaterial(), bf.UniformColors((1, 0, 0)))
    p2 = s.renderables.add_pointcloud(
        rng.normal(size=(70, 3)), bf.DiffuseMaterial(), bf.VertexColors(rng.uniform(size=(70, 3)))
    )
    assert (p1.tag, p2.tag) == ("PointCloud_000", "PointCloud_001")
    assert (p1.num_vertices, p2.num_vertices) == (50, 70)
    new = rng.normal(size=(50, 3))
    rev = p1.revision("geometry")
    p1.update_vertices(new)
    assert np.array_equal(p1.vertices, new) and p1.revision("geometry") == rev + 1
    p1.update_vertices(rng.normal(size=(80, 3)))  # uniform colour: the count may change
    assert p1.num_vertices == 80
    with pytest.raises(bf.InvalidSceneError, match="vertices"):
        p2.update_vertices(rng.normal(size=(10, 3)))  # per-point colours: it may not
    assert p2.emit_shadow is True
    p2.emit_shadow = False
    assert p2.emit_shadows is False and p2.emit_shadow is False
    p2.update_colors(bf.UniformColors((0.2, 0.2, 0.2)))
    assert isinstance(p2.colors, bf.UniformColors)
    assert p2.particle_emission_strength == 0.0


def test_mesh_updates_and_smoothing():
    s = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])
    mesh = s.renderables.add_mesh(v, [[0, 1, 2, 3]], bf.PrincipledBSDFMaterial(), bf.UniformColors((1, 1, 1)))
    assert mesh.smooth is False  # flat by default, as blendify
    mesh.set_smooth()
    assert mesh.smooth is True and mesh.to_mesh().normals is not None
    mesh.set_smooth(False)
    assert mesh.to_mesh().normals is None
    mesh.update_vertices(v * 2)
    assert np.array_equal(mesh.vertices, v * 2)
    mesh.update_colors(bf.VertexColors(np.full((4, 3), 0.5)))
    assert isinstance(mesh.colors, bf.VertexColors)
    new_mat = bf.MetalMaterial()
    mesh.update_material(new_mat)
    assert mesh.material is new_mat
    assert mesh.emit_shadows is True
    mesh.emit_shadows = False
    assert mesh.emit_shadows is False
    cube = s.renderables.add_cube_mesh(1.0, bf.PrincipledBSDFMaterial(), bf.UniformColors((1, 1, 1)))
    cube.set_smooth(True)
    cube.update_colors(bf.UniformColors((0.2, 0.3, 0.4)))
    cube.update_colors(bf.UniformColors((0.2, 0.3, 0.5)))  # no accumulating state (blendify: EDGE_SPLIT pile-up)
    assert cube.smooth and len(cube.colors_list) == 1


def test_per_face_materials_like_blendify_example_08(tmp_path):
    s = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]], dtype=float)
    mats = [bf.PrincipledBSDFMaterial(), bf.PlasticMaterial(), bf.MetalMaterial()]
    cols = [bf.UniformColors((1, 0, 0)), bf.UniformColors((0, 1, 0)), bf.UniformColors((0, 0, 1))]
    mesh = s.renderables.add_mesh(v, [[0, 1, 2], [0, 2, 3], [1, 4, 2]], mats, cols, faces_material=[2, 0, 1])
    assert mesh.material == mats and mesh.colors == cols
    assert np.array_equal(mesh.faces_material, [2, 0, 1])
    mesh.update_colors([bf.UniformColors((1, 1, 0))] * 3)
    with pytest.raises(bf.InvalidSceneError, match="colors"):
        mesh.update_colors(bf.UniformColors((1, 1, 0)))


def test_set_background_light_rgba_and_int_colours():
    """blendify bug 9: an RGBA colour raised ValueError and an int tuple AssertionError."""
    lights = bf.Scene().lights
    bg = lights.set_background_light(0.5, (0.2, 0.4, 0.6, 1.0))
    assert bg.color == (0.2, 0.4, 0.6) and bg.strength == 0.5
    bg = lights.set_background_light(1, (1, 1, 1))
    assert bg.color == (1.0, 1.0, 1.0)
    lights.remove_background_light()
    assert lights.background is None


def test_all_area_light_shapes():
    """blendify bug 10 (rectangle/ellipse/disk could not be attached)."""
    lights = bf.Scene().lights
    sizes = {"square": 1.0, "circle": 1.0, "rectangle": (1.0, 2.0), "ellipse": (1.0, 2.0)}
    areas = {shape: lights.add_area(shape, size).area for shape, size in sizes.items()}
    assert areas["square"] == 1.0 and areas["rectangle"] == 2.0
    assert np.isclose(areas["circle"], np.pi / 4) and np.isclose(areas["ellipse"], np.pi / 2)
    assert bf.ir.lights.SquareAreaLight is bf.AreaLight  # blendify's class names resolve


def test_camera_properties_like_blendify():
    s = bf.Scene()
    cam = s.set_perspective_camera((320, 240), focal_dist=200.0, center=(150.0, 100.0))
    assert s.camera is cam
    assert np.array_equal(cam.resolution, [320, 240])
    assert (cam.near, cam.far, cam.focal_dist) == (0.1, 100.0, 200.0)
    assert np.array_equal(cam.center, [150.0, 100.0])
    assert np.isclose(cam.fov_x, 2 * np.arctan(160 / 200)) and np.isclose(cam.fov_y, 2 * np.arctan(120 / 200))
    assert np.array_equal(cam.get_camera_viewdir(), [0, 0, -1])
    ortho = s.set_orthographic_camera((64, 64), ortho_scale=3.0)
    assert s.camera is ortho and ortho.ortho_scale == 3.0


def test_blendify_rotation_modes_on_every_object():
    s = bf.Scene()
    m, c = bf.PrincipledBSDFMaterial(), bf.UniformColors((1, 1, 1))
    modes = [
        ("quaternionWXYZ", (1, 0, 0, 0)),
        ("quaternionXYZW", (0, 0, 0, 1)),
        ("rotvec", (0, 0, 0)),
        ("rotmat", np.eye(3)),
        ("eulerXYZ", (0, 0, 0)),
        ("euleryz", (0, 0)),
        ("look_at", (0, 0, -1)),
    ]
    for mode, rot in modes:
        obj = s.renderables.add_cube_mesh(1.0, m, c, rotation_mode=mode, rotation=rot)
        assert np.allclose(obj.rotation_matrix, np.eye(3), atol=1e-12), mode
        light = s.lights.add_sun(rotation_mode=mode, rotation=rot)
        assert np.allclose(light.direction, [0, 0, -1], atol=1e-12), mode
        cam = s.set_perspective_camera((8, 8), fov_x=1.0, rotation_mode=mode, rotation=rot)
        assert np.allclose(cam.viewdir, [0, 0, -1], atol=1e-12), mode


def test_errors_are_exceptions_and_exit_codes_are_kept():
    """blendify bug 11: importing blendify forced exit status 0 and errors became SystemExit(1)."""
    code = (
        "import blendify_core as bf\n"
        "s = bf.Scene()\n"
        "try:\n"
        "    bf.render(s)\n"
        "except bf.InvalidSceneError as e:\n"
        "    print('caught', type(e).__name__)\n"
        "import sys\n"
        "sys.exit(3)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "caught InvalidSceneError" in out.stdout, out.stderr
    assert out.returncode == 3
    crash = subprocess.run(
        [sys.executable, "-c", "import blendify_core\nraise RuntimeError('boom')"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert crash.returncode == 1 and "boom" in crash.stderr


def test_curve_needs_two_keypoints_and_is_a_tube():
    s = bf.Scene()
    curve = s.renderables.add_curve_nurbs(
        [[0, 0, 0], [1, 0, 0], [1, 1, 0]], 0.05, bf.PrincipledBSDFMaterial(), bf.UniformColors((1, 1, 1))
    )
    tm = curve.to_mesh()
    # the end rings lie at the radius from their segments, around the end points
    first, last = tm.vertices[:16], tm.vertices[32:48]
    assert np.allclose(np.linalg.norm(np.cross(first - [0, 0, 0], [1, 0, 0]), axis=1), 0.05, atol=1e-9)
    assert np.allclose(first[:, 0], 0.0, atol=1e-12)
    assert np.allclose(np.linalg.norm(np.cross(last - [1, 1, 0], [0, 1, 0]), axis=1), 0.05, atol=1e-9)
    assert np.allclose(last[:, 1], 1.0, atol=1e-12)
    with pytest.raises(bf.InvalidSceneError, match="keypoints"):
        s.renderables.add_curve_nurbs([[0, 0, 0]], 0.05, bf.PrincipledBSDFMaterial(), bf.UniformColors((1, 1, 1)))


def test_counterparts_of_scene_level_blendify_methods():
    """Scene.render/preview -> bf.render(quality=...); Scene.export -> export_blend; attach_blend kept."""
    assert callable(bf.render)
    assert "quality" in inspect.signature(bf.render).parameters
    for name in ("clear", "attach_blend", "export_blend", "set_camera_from_opencv", "save", "load", "fingerprint"):
        assert callable(getattr(bf.Scene, name)), name
    assert isinstance(bf.Scene.camera, property)


def test_copied_material_is_independent():
    import copy

    mat = bf.MetalMaterial(roughness=0.3)
    twin = copy.copy(mat)
    twin.roughness = 0.9
    assert mat.roughness == 0.3 and twin.roughness == 0.9
    assert mat.revision == 0 and twin.revision == 1
    deep = copy.deepcopy(mat)
    deep.metallic = 0.1
    assert mat.metallic == 0.9
    changed = mat.copy(roughness=0.5)
    assert type(changed) is bf.MetalMaterial and changed.roughness == 0.5 and mat.roughness == 0.3
    assert mat.copy() == mat


def test_deliberate_differences_are_in_the_migration_guide():
    from pathlib import Path

    readme = Path(__file__).resolve().parents[2] / "README.md"
    if not readme.is_file():
        pytest.skip(f"README.md not found at {readme}")
    text = readme.read_text(encoding="utf-8")
    assert "Migrating from blendify" in text
    guide = text[text.index("Migrating from blendify") :]
    for (_owner, param), (old, new, _why) in DELIBERATE.items():
        assert param in guide, f"README migration guide does not mention {param} ({old!r} -> {new!r})"
    for phrase in ('color_space="linear"', "center", "SystemExit", "bf.render"):
        assert phrase in guide, phrase


def test_camera_properties_are_settable_and_validated():
    s = bf.Scene()
    cam = s.set_perspective_camera((320, 240), focal_dist=200.0)
    cam.fov_x = np.deg2rad(60)
    assert np.isclose(cam.fov_x, np.deg2rad(60)) and cam.fx == cam.fy
    cam.fov_y = np.deg2rad(40)
    assert np.isclose(cam.fov_y, np.deg2rad(40)) and cam.fx == cam.fy
    cam.focal_dist = 150.0
    assert np.array_equal(cam.K[[0, 1], [0, 1]], [150.0, 150.0])
    cam.center = (100.0, 80.0)
    assert np.array_equal(cam.K[:2, 2], [100.0, 80.0])
    cam.near, cam.far = 0.5, 20.0
    assert (cam.near, cam.far) == (0.5, 20.0)
    cam.resolution_percentage = 50
    assert cam._scaled(0.5).width == 160
    for name, value in [("near", 30.0), ("far", 0.1), ("fov_x", 0.0), ("focal_dist", -1.0), ("center", (1, 2, 3))]:
        with pytest.raises(bf.InvalidSceneError, match=name):
            setattr(cam, name, value)
    with pytest.raises(bf.InvalidSceneError, match="resolution_percentage"):
        cam.resolution_percentage = 0
    for name, value in (("fx", -1.0), ("fy", np.inf), ("cx", np.nan), ("cy", "middle")):
        with pytest.raises(bf.InvalidSceneError, match=name):
            setattr(cam, name, value)
    cam.fx = 123.0
    assert cam.K[0, 0] == 123.0 and cam.K[1, 1] == 150.0  # non-square pixels by hand
    ortho = s.set_orthographic_camera((64, 64), ortho_scale=2.0)
    ortho.ortho_scale = 4.0
    assert ortho.pixel_size == 4.0 / 64
    with pytest.raises(bf.InvalidSceneError, match="ortho_scale"):
        ortho.ortho_scale = 0.0


def test_tags_are_read_only_like_blendify():
    s = bf.Scene()
    sphere = s.renderables.add_sphere_nurbs(1.0, bf.PrincipledBSDFMaterial(), bf.UniformColors((1, 1, 1)), tag="ball")
    light = s.lights.add_point(tag="key")
    cam = s.set_perspective_camera((8, 8), fov_x=1.0)
    for obj, name in ((sphere, "ball"), (light, "key"), (cam, "camera")):
        with pytest.raises(bf.InvalidSceneError, match="tag"):
            obj.tag = "renamed"
        assert obj.tag == name
    s.renderables.remove(sphere)  # the collection still finds it by its (unchanged) tag
    s.lights.remove(light)
    assert len(s.renderables) == 0 and len(s.lights) == 0


@pytest.mark.parametrize(
    ("make", "name", "good", "bad"),
    [
        (lambda lights: lights.add_point(), "shadow_soft_size", 0.5, -1.0),
        (lambda lights: lights.add_sun(), "angular_diameter", 0.1, 4.0),
        (lambda lights: lights.add_spot(), "spot_size", 1.0, 0.0),
        (lambda lights: lights.add_spot(), "spot_blend", 0.5, 1.5),
        (lambda lights: lights.add_spot(), "shadow_soft_size", 0.0, np.nan),
        (lambda lights: lights.add_area("rectangle", (1.0, 2.0)), "size", (2.0, 3.0), 1.0),
        (lambda lights: lights.add_area("circle", 1.0), "size", 2.0, (1.0, 2.0)),
        (lambda lights: lights.add_point(), "strength", 5.0, -5.0),
        (lambda lights: lights.add_point(), "color", (0.5, 0.5, 0.5), (2.0, 0.0, 0.0)),
    ],
)
def test_light_parameters_settable_validated_and_seen_by_backends(make, name, good, bad):
    """Changing a light parameter bumps its appearance revision (backends cache lights by revision)."""
    light = make(bf.Scene().lights)
    rev = light.revision("appearance")
    setattr(light, name, good)
    value = getattr(light, name)
    assert value == (tuple(good) if isinstance(good, tuple) else (good, good) if name == "size" else good)
    assert light.revision("appearance") == rev + 1
    with pytest.raises(bf.InvalidSceneError, match=name):
        setattr(light, name, bad)
    assert getattr(light, name) == value and light.revision("appearance") == rev + 1


def test_area_shape_is_fixed_and_point_cloud_emission_is_tracked():
    area = bf.Scene().lights.add_area("square", 1.0)
    with pytest.raises(bf.InvalidSceneError, match="shape"):
        area.shape = "circle"
    pc = bf.Scene().renderables.add_pointcloud(np.zeros((3, 3)), bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))
    rev = pc.revision("appearance")
    pc.particle_emission_strength = 1.5
    assert pc.particle_emission_strength == 1.5 and pc.revision("appearance") == rev + 1
    with pytest.raises(bf.InvalidSceneError, match="particle_emission_strength"):
        pc.particle_emission_strength = -1


@pytest.mark.parametrize(
    ("make", "name", "good", "bad"),
    [
        (lambda r, m, c: r.add_cube_mesh(1.0, m, c), "size", 2.0, 0.0),
        (lambda r, m, c: r.add_plane_mesh(1.0, m, c), "size", 3.0, -1.0),
        (lambda r, m, c: r.add_sphere_nurbs(1.0, m, c), "radius", 0.5, np.inf),
        (lambda r, m, c: r.add_circle_mesh(1.0, m, c), "radius", 0.5, 0.0),
        (lambda r, m, c: r.add_cylinder_mesh(1.0, 2.0, m, c), "height", 0.5, -2.0),
        (lambda r, m, c: r.add_ellipsoid_nurbs((1, 2, 3), m, c), "radius", (3.0, 2.0, 1.0), (1.0, 0.0, 1.0)),
        (lambda r, m, c: r.add_curve_nurbs([[0, 0, 0], [1, 0, 0]], 0.1, m, c), "radius", 0.2, 0.0),
        (
            lambda r, m, c: r.add_curve_nurbs([[0, 0, 0], [1, 0, 0]], 0.1, m, c),
            "keypoints",
            [[0, 0, 0], [0, 1, 0], [1, 1, 0]],
            [[1, 1, 1], [1, 1, 1]],
        ),
    ],
)
def test_primitive_geometry_parameters_are_validated_and_tracked(make, name, good, bad):
    obj = make(bf.Scene().renderables, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))
    rev = obj.revision("geometry")
    setattr(obj, name, good)
    assert np.array_equal(np.asarray(getattr(obj, name)), np.asarray(good, dtype=float))
    assert obj.revision("geometry") == rev + 1
    before = obj.to_mesh().vertices
    with pytest.raises(bf.InvalidSceneError, match=name):
        setattr(obj, name, bad)
    assert np.array_equal(obj.to_mesh().vertices, before)


def test_primitive_face_structure_is_fixed():
    cyl = bf.Scene().renderables.add_cylinder_mesh(1.0, 1.0, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))
    for name, value in (("num_vertices", 8), ("fill_type", "TRIFAN")):
        with pytest.raises(bf.InvalidSceneError, match=name):
            setattr(cyl, name, value)


def test_colour_sources_cannot_change_in_place():
    """Backends cache colour sources by identity: an in-place change would never reach them, so it is
    refused with a pointer to update_colors."""
    uniform = bf.UniformColors((0.5, 0.5, 0.5))
    uv = bf.VertexUV(np.zeros((3, 2)))
    tex = bf.TextureColors(np.zeros((2, 2, 3)), uv)
    tmap = bf.TextureMap(np.zeros((2, 2)))
    for obj, name, value in (
        (uniform, "color", np.ones(3)),
        (uniform, "color_space", "linear"),
        (uv, "data", np.ones((3, 2))),
        (tex, "uv_map", uv),
        (tex, "interpolation", "closest"),
        (tmap, "channel", 1),
    ):
        with pytest.raises(bf.InvalidSceneError, match="update_colors"):
            setattr(obj, name, value)
    assert np.array_equal(uniform.color, [0.5, 0.5, 0.5]) and uniform.color_space == "srgb"


def test_assigning_properties_goes_through_the_update_methods():
    s = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    mesh = s.renderables.add_mesh(v, [[0, 1, 2]], bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))
    rev = mesh.revision("geometry")
    mesh.vertices = v * 2
    mesh.smooth = True
    assert np.array_equal(mesh.vertices, v * 2) and mesh.smooth and mesh.revision("geometry") == rev + 2
    metal = bf.MetalMaterial()
    mesh.material = metal
    mesh.colors = bf.VertexColors(np.full((3, 3), 0.2))
    assert mesh.material is metal and isinstance(mesh.colors, bf.VertexColors)
    with pytest.raises(bf.InvalidSceneError, match="vertices"):
        mesh.vertices = v[:2]
    pc = s.renderables.add_pointcloud(v, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))
    pc.vertices = v + 1
    assert np.array_equal(pc.vertices, v + 1)
    sphere = s.renderables.add_sphere_nurbs(1.0, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))
    sphere.smooth = True
    with pytest.raises(bf.InvalidSceneError, match="smooth"):
        sphere.smooth = False
    assert sphere.smooth is True
    cube = s.renderables.add_cube_mesh(1.0, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))
    cube.smooth = True
    assert cube.smooth and cube.to_mesh().normals is not None


def test_recentring_does_not_touch_the_users_objects():
    from blendify_core.pipeline.recentre import recentred_view

    s = bf.Scene()
    curve = s.renderables.add_curve_nurbs(
        np.array([[0, 0, 0], [1, 0, 0]]) + 1e6, 0.1, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1))
    )
    s.set_perspective_camera(
        (8, 8), fov_x=1.0, translation=(1e6, 1e6 - 5, 1e6), rotation_mode="look_at", rotation=(1e6, 1e6, 1e6)
    )
    rev, keys = curve.revision("geometry"), curve.keypoints.copy()
    view, _ = recentred_view(s)
    assert curve.revision("geometry") == rev and np.array_equal(curve.keypoints, keys)
    assert np.abs(view.renderables[curve.tag].keypoints).max() < 10


def test_background_and_environment_attributes_are_validated():
    lights = bf.Scene().lights
    bg = lights.set_background_light(0.5, (1.0, 0.0, 0.0))
    bg.strength = 2.0
    assert np.allclose(bg.radiance, [2.0, 0.0, 0.0])
    env = lights.set_environment_map(np.ones((2, 4, 3), np.float32))
    env.quaternion = (2.0, 0.0, 0.0, 0.0)
    assert np.array_equal(env.quaternion, [1.0, 0.0, 0.0, 0.0])
    for obj, name, value in (
        (bg, "strength", -1.0),
        (bg, "color", (2.0, 0.0, 0.0)),
        (bg, "color_space", "aces"),
        (env, "strength", np.nan),
        (env, "quaternion", (0, 0, 0, 0)),
    ):
        with pytest.raises(bf.InvalidSceneError, match=name):
            setattr(obj, name, value)
