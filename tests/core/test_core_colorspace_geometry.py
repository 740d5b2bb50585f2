"""Colour-space functions at known values and the colour rule of every IR class; geometry helpers:
triangulation, NaN-free normals, closed outward-facing tessellations of every primitive."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import blendify_core as bf
from blendify_core.ir.colorspace import linear_to_srgb, linear_to_srgb8, srgb8_to_linear, srgb_to_linear
from blendify_core.ir.geometry import (
    face_normals,
    icosphere,
    triangulate_polygons,
    tube_along_polyline,
    uv_sphere,
    vertex_normals,
)

# ---------------------------------------------------------------------------------------------------
# colour space
# ---------------------------------------------------------------------------------------------------


def test_srgb_decode_known_values():
    assert srgb_to_linear(0.0) == 0.0 and srgb_to_linear(1.0) == 1.0
    assert srgb_to_linear(0.04045) == pytest.approx(0.04045 / 12.92, abs=1e-15)  # linear segment
    assert srgb_to_linear(0.5) == pytest.approx(((0.5 + 0.055) / 1.055) ** 2.4, abs=1e-15)
    assert srgb_to_linear(0.5) == pytest.approx(0.21404114048223255, abs=1e-15)
    assert srgb_to_linear(188 / 255) == pytest.approx(0.5028864580325687, abs=1e-12)


def test_srgb_encode_known_values():
    assert linear_to_srgb(0.0) == 0.0 and linear_to_srgb(1.0) == pytest.approx(1.0, abs=1e-15)
    assert linear_to_srgb(0.0031308) == pytest.approx(0.0031308 * 12.92, abs=1e-15)
    assert linear_to_srgb(0.5) == pytest.approx(1.055 * 0.5 ** (1 / 2.4) - 0.055, abs=1e-15)
    assert linear_to_srgb(0.5) == pytest.approx(0.7353569830524495, abs=1e-15)
    assert linear_to_srgb(-0.5) == 0.0 and linear_to_srgb(7.0) == pytest.approx(1.0)  # clipped
    assert linear_to_srgb8(np.array([0.5]))[0] == 188
    assert linear_to_srgb8(np.array([0.0, 1.0, 0.5, 0.2142])).tolist() == [0, 255, 188, 128]


def test_srgb8_table_round_trips_every_byte():
    codes = np.arange(256, dtype=np.uint8)
    lin = srgb8_to_linear(codes)
    assert lin.dtype == np.float32 and np.all(np.diff(lin) > 0)
    assert np.array_equal(linear_to_srgb8(lin), codes)
    assert np.allclose(lin, srgb_to_linear(codes / 255.0), atol=1e-7)


@settings(max_examples=200, deadline=None)
@given(x=st.floats(0.0, 1.0))
def test_encode_decode_round_trip(x):
    # the IEC 61966-2-1 constants meet with a ~3e-8 mismatch at the knee (0.04045 vs 12.92 * 0.0031308)
    tol = 1e-7 if 0.003 < x < 0.05 else 1e-12
    assert abs(float(linear_to_srgb(srgb_to_linear(x))) - x) < tol
    assert abs(float(srgb_to_linear(linear_to_srgb(x))) - x) < tol


def test_dtypes_are_kept():
    a32 = np.linspace(0, 1, 5, dtype=np.float32)
    assert srgb_to_linear(a32).dtype == np.float32 and linear_to_srgb(a32).dtype == np.float32
    assert srgb_to_linear(np.linspace(0, 1, 5)).dtype == np.float64
    assert srgb_to_linear(np.array([0, 1])).dtype == np.float32  # integers become float


def test_one_colour_rule_for_every_class():
    half = srgb_to_linear(0.5)
    assert np.allclose(bf.UniformColors((0.5, 0.5, 0.5)).linear_rgba, [half, half, half, 1.0])
    assert np.allclose(bf.UniformColors((0.5, 0.5, 0.5, 0.5)).linear_rgba, [half, half, half, 0.5])  # alpha as is
    assert np.allclose(bf.UniformColors((0.5, 0.5, 0.5), color_space="linear").linear_rgba, [0.5, 0.5, 0.5, 1])
    vc = bf.VertexColors(np.full((2, 3), 0.5))
    assert vc.linear_rgba.dtype == np.float32 and np.allclose(vc.linear_rgba, [half, half, half, 1], atol=1e-7)
    assert not vc.linear_rgba.flags.writeable
    vc8 = bf.VertexColors(np.full((2, 4), 188, np.uint8))
    assert np.allclose(vc8.linear_rgba[0], [srgb_to_linear(188 / 255)] * 3 + [188 / 255], atol=1e-6)
    uv = bf.VertexUV(np.zeros((3, 2)))
    tex8 = bf.TextureColors(np.full((2, 2, 3), 188, np.uint8), uv).linear_rgba_image()
    assert tex8.shape == (2, 2, 4) and tex8.dtype == np.float32
    assert np.allclose(tex8[..., :3], srgb8_to_linear(np.uint8(188))) and np.all(tex8[..., 3] == 1)
    texf = bf.TextureColors(np.full((2, 2), 0.5, np.float32), uv).linear_rgba_image()
    assert np.allclose(texf[..., :3], half, atol=1e-7)
    texl = bf.TextureColors(np.full((2, 2, 3), 128, np.uint8), uv, color_space="linear").linear_rgba_image()
    assert np.allclose(texl[..., :3], 128 / 255)
    mat = bf.PrincipledBSDFMaterial(emission_color=(0.5, 0.5, 0.5))
    assert np.allclose(mat.linear("emission_color"), [half, half, half, 1.0])
    mat_lin = bf.PrincipledBSDFMaterial(emission_color=(0.5, 0.5, 0.5), color_space="linear")
    assert np.allclose(mat_lin.linear("emission_color"), [0.5, 0.5, 0.5, 1.0])
    lights = bf.Scene().lights
    assert np.allclose(lights.add_point(color=(0.5, 0.5, 0.5)).linear_color, half)
    assert np.allclose(lights.set_background_light(2.0, (0.5, 0.5, 0.5)).radiance, 2 * half)


def test_texture_rows_and_data_maps_are_not_colour_managed():
    img = np.array([[0.25], [0.75]], dtype=np.float32)
    tm = bf.TextureMap(img)
    assert np.array_equal(tm.values(), img)  # (H, W) as given: row 0 = top, no decoding
    nm = bf.NormalMap(np.full((1, 1, 3), (128, 128, 255), np.uint8))
    assert np.allclose(nm.normals()[0, 0], [128 / 255 * 2 - 1, 128 / 255 * 2 - 1, 1.0], atol=1e-6)


def test_environment_map_colour_space_defaults():
    lights = bf.Scene().lights
    hdr = lights.set_environment_map(np.full((2, 4, 3), 4.0, np.float32))
    assert hdr.color_space == "linear" and np.allclose(hdr.linear_rgb_image(), 4.0)
    ldr = lights.set_environment_map(np.full((2, 4, 3), 188, np.uint8))
    assert ldr.color_space == "srgb" and np.allclose(ldr.linear_rgb_image(), srgb8_to_linear(np.uint8(188)))


def test_area_light_radiance_units():
    light = bf.Scene().lights.add_area("rectangle", (0.5, 2.0), strength=100.0)
    assert np.allclose(light.radiance, 100.0 / (np.pi * 1.0))
    disk = bf.Scene().lights.add_area("circle", 2.0, strength=50.0)
    assert np.allclose(disk.radiance, 50.0 / (np.pi * np.pi))


# ---------------------------------------------------------------------------------------------------
# triangulation and normals
# ---------------------------------------------------------------------------------------------------


def test_triangulate_quads():
    tris, poly, corner = triangulate_polygons(np.array([[0, 1, 2, 3], [4, 5, 6, 7]]))
    assert tris.dtype == np.int32 and tris.tolist() == [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]]
    assert poly.tolist() == [0, 0, 1, 1]
    assert corner.tolist() == [[0, 1, 2], [0, 2, 3]] * 2


def test_triangulate_ragged_polygons():
    polys = [np.array([0, 1, 2]), np.array([3, 4, 5, 6, 7]), np.array([8, 9, 10, 11])]
    tris, poly, corner = triangulate_polygons(polys)
    assert len(tris) == 1 + 3 + 2
    assert poly.tolist() == [0, 1, 1, 1, 2, 2]
    for t, p, c in zip(tris, poly, corner):
        assert np.array_equal(polys[p][c], t)  # corners index back into the polygon
    assert triangulate_polygons([])[0].shape == (0, 3)


def _shoelace(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


@settings(max_examples=60, deadline=None)
@given(n=st.integers(3, 12), seed=st.integers(0, 1000))
def test_fan_triangulation_keeps_convex_polygon_area_and_winding(n, seed):
    rng = np.random.default_rng(seed)
    ang = np.sort(rng.uniform(0, 2 * np.pi, n))
    ang = np.unique(np.round(ang, 3))
    if len(ang) < 3:
        return
    pts = np.c_[np.cos(ang), np.sin(ang), np.zeros(len(ang))]
    s = bf.Scene()
    mesh = s.renderables.add_mesh(pts, [list(range(len(ang)))], bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))
    fn = face_normals(mesh.vertices, mesh.faces)
    v = mesh.vertices[mesh.faces]
    areas = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    assert np.isclose(areas.sum(), _shoelace(pts), rtol=1e-9)
    assert np.all(fn[areas > 1e-12] @ [0, 0, 1] > 0.999)  # counter-clockwise polygon faces +Z


def test_mesh_with_quads_and_faces_uv():
    s = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    uv = np.array([[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]])
    m = s.renderables.add_mesh(
        v, [[0, 1, 2, 3]], bf.DiffuseMaterial(), bf.TextureColors(np.zeros((2, 2, 3)), bf.FacesUV(uv))
    )
    assert m.faces.shape == (2, 3) and m.faces.dtype == np.int32 and m.n_polygons == 1
    tuv = m.triangle_uvs()
    assert tuv.shape == (2, 3, 2)
    assert np.array_equal(tuv, uv[0][[[0, 1, 2], [0, 2, 3]]])
    # per-vertex UVs give the same corners
    m2 = s.renderables.add_mesh(
        v, [[0, 1, 2, 3]], bf.DiffuseMaterial(), bf.TextureColors(np.zeros((2, 2, 3)), bf.VertexUV(uv[0]))
    )
    assert np.array_equal(m2.triangle_uvs(), tuv)


def test_normals_never_nan_on_degenerate_triangles():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [0, 0, 0], [1e-200, 0, 0]], dtype=float)
    f = np.array([[0, 1, 2], [0, 0, 3], [0, 4, 5], [0, 1, 3]])  # collinear, repeated, zero-size, fine
    with np.errstate(all="raise"):
        fn = face_normals(v, f)
        vn = vertex_normals(v, f)
    assert np.all(np.isfinite(fn)) and np.all(np.isfinite(vn))
    assert np.all(fn[:3] == 0) and np.allclose(fn[3], [0, 0, 1])
    assert np.allclose(np.linalg.norm(vn[[0, 1, 3]], axis=1), 1.0)
    assert np.all(vn[5] == 0)  # only in a degenerate triangle
    s = bf.Scene()
    m = s.renderables.add_mesh(v, f, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)), smooth=True)
    assert np.all(np.isfinite(m.to_mesh().normals))


def test_vertex_normals_are_angle_weighted():
    """One rule (angle-weighted, Blender's and trimesh's): a corner of a box weighs its three faces equally
    however each face is cut into triangles; an n-gon cap weighs the same fanned from any vertex."""
    # the corner (0, 0, 0) of a unit box: on the z=0 face one triangle (area 1/2) has the corner, on the
    # y=0 and x=0 faces two (area 1): area weighting would tilt the normal away from -Z
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, 0, 1], [0, 1, 1]], float)
    f = np.array([[0, 2, 1], [1, 2, 4], [0, 3, 5], [0, 5, 1], [0, 6, 3], [0, 2, 6]])
    n = vertex_normals(v, f)
    np.testing.assert_allclose(n[0], np.array([1.0, 1.0, -1.0]) / np.sqrt(3), atol=1e-12)
    # a 12-gon cap on a prism: the rim normals do not depend on where the cap's fan starts
    k = 12
    phi = np.arange(k) * 2 * np.pi / k
    ring = np.c_[np.cos(phi), np.sin(phi)]
    pv = np.concatenate([np.c_[ring, np.zeros(k)], np.c_[ring, np.ones(k)]])
    sides = [[i, (i + 1) % k, k + (i + 1) % k] for i in range(k)] + [[i, k + (i + 1) % k, k + i] for i in range(k)]
    normals = []
    for start in (0, 5):
        top = [[k + start, k + (start + i) % k, k + (start + i + 1) % k] for i in range(1, k - 1)]
        normals.append(vertex_normals(pv, np.array(sides + top)))
    np.testing.assert_allclose(normals[0], normals[1], atol=1e-12)
    # the rim: two side-quad corners (180 degrees in all) and the cap's corner, as Blender weighs polygons
    rim = normals[0][k]
    # (the two quads' unit normals are pi / k off the radial direction, on either side)
    cap_angle = np.pi * (k - 2) / k
    want = np.array([np.pi * np.cos(np.pi / k), 0.0, cap_angle])
    np.testing.assert_allclose(rim, want / np.linalg.norm(want), atol=1e-12)


def test_vertex_normals_match_trimesh():
    trimesh = pytest.importorskip("trimesh", reason="trimesh not installed")
    m = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=24)
    np.testing.assert_allclose(vertex_normals(m.vertices, m.faces), m.vertex_normals, atol=1e-12)


# ---------------------------------------------------------------------------------------------------
# closed, outward-facing tessellations
# ---------------------------------------------------------------------------------------------------


def _weld(vertices: np.ndarray, faces: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    key = np.round(vertices / tol).astype(np.int64)
    _, inverse = np.unique(key, axis=0, return_inverse=True)
    return inverse.reshape(-1)[faces]


def _assert_closed_and_outward(vertices, faces, expected_volume=None, rtol=0.05):
    f = _weld(np.asarray(vertices), np.asarray(faces))
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]  # drop pole slivers
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    directed, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 1), "an edge is used twice in the same direction (inconsistent winding)"
    opposite = {tuple(e) for e in directed}
    assert all((b, a) in opposite for a, b in directed), "the surface has a hole (unmatched edge)"
    v = np.asarray(vertices, dtype=np.float64)
    t = v[np.asarray(faces)]
    volume = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0
    assert volume > 0, f"faces point inwards (signed volume {volume})"
    if expected_volume is not None:
        assert volume == pytest.approx(expected_volume, rel=rtol)
    return volume


@pytest.mark.parametrize(("segments", "rings"), [(64, 32), (8, 4), (3, 2)])
def test_uv_sphere_closed_outward(segments, rings):
    m = uv_sphere(2.0, segments, rings)
    exp = 4 / 3 * np.pi * 8 if segments >= 64 else None
    _assert_closed_and_outward(m.vertices, m.faces, exp)
    assert np.allclose(np.linalg.norm(m.vertices, axis=1), 2.0)
    assert np.all(np.einsum("ij,ij->i", m.normals, m.vertices) > 0)
    assert m.uv.shape == (len(m.faces), 3, 2)


@pytest.mark.parametrize("subdivisions", [0, 1, 3])
def test_icosphere_closed_outward(subdivisions):
    m = icosphere(subdivisions, radius=1.5)
    vol = _assert_closed_and_outward(m.vertices, m.faces)
    assert vol < 4 / 3 * np.pi * 1.5**3
    assert np.allclose(np.linalg.norm(m.vertices, axis=1), 1.5)
    assert len(m.vertices) - 3 * len(m.faces) // 2 + len(m.faces) == 2  # Euler characteristic of a sphere


@pytest.mark.parametrize(
    "points",
    [
        [[0, 0, 0], [1, 0, 0]],
        [[0, 0, 0], [0, 0, 1]],  # along Z: the helper axis switches
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 1, 1]],
        [[0, 0, 0], [1, 0, 0], [1, 0, 0], [2, 0.5, 0]],  # duplicate keypoint
        [[0, 0, 0], [1, 0, 0], [0, 0, 0.001]],  # sharp hairpin
    ],
)
def test_tube_closed_outward(points):
    pts = np.array(points, dtype=float)
    m = tube_along_polyline(pts, 0.1, 16)
    with np.errstate(all="raise"):
        vol = _assert_closed_and_outward(m.vertices, m.faces)
    assert np.all(np.isfinite(m.normals))
    if len(points) == 2:
        n = 16
        assert vol == pytest.approx(0.5 * n * np.sin(2 * np.pi / n) * 0.01 * 1.0, rel=1e-9)


def _prim(kind):
    s, m, c = bf.Scene(), bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1))
    r = s.renderables
    return {
        "cube": lambda: (r.add_cube_mesh(0.7, m, c), 0.7**3),
        "cylinder-ngon": lambda: (r.add_cylinder_mesh(0.5, 2.0, m, c), 0.5 * 32 * np.sin(2 * np.pi / 32) * 0.25 * 2),
        "cylinder-trifan": lambda: (
            r.add_cylinder_mesh(0.5, 2.0, m, c, num_vertices=7, fill_type="TRIFAN"),
            0.5 * 7 * np.sin(2 * np.pi / 7) * 0.25 * 2,
        ),
        "sphere": lambda: (r.add_sphere_nurbs(0.4, m, c), 4 / 3 * np.pi * 0.4**3),
        "ellipsoid": lambda: (r.add_ellipsoid_nurbs((0.2, 0.3, 0.5), m, c), 4 / 3 * np.pi * 0.03),
        "curve": lambda: (r.add_curve_nurbs([[0, 0, 0], [0, 0, 1], [1, 0, 1]], 0.05, m, c), None),
        "pointcloud": lambda: (r.add_pointcloud(np.eye(3) * 5, m, c, point_size=0.2), None),
    }[kind]()


@pytest.mark.parametrize(
    "kind", ["cube", "cylinder-ngon", "cylinder-trifan", "sphere", "ellipsoid", "curve", "pointcloud"]
)
def test_primitive_tessellations_are_closed_and_outward(kind):
    obj, volume = _prim(kind)
    tm = obj.to_mesh()
    exact = kind in ("cube", "cylinder-ngon", "cylinder-trifan")
    _assert_closed_and_outward(tm.vertices, tm.faces, volume, rtol=1e-9 if exact else 0.02)
    assert tm.faces.dtype == np.int32 and tm.vertices.dtype == np.float64
    if tm.normals is not None:
        assert np.allclose(np.linalg.norm(tm.normals, axis=1), 1.0)


def test_flat_primitives_face_plus_z():
    s, m, c = bf.Scene(), bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1))
    for obj in (
        s.renderables.add_plane_mesh(2.0, m, c),
        s.renderables.add_circle_mesh(1.0, m, c),
        s.renderables.add_circle_mesh(1.0, m, c, fill_type="TRIFAN"),
    ):
        tm = obj.to_mesh()
        fn = face_normals(tm.vertices, tm.faces)
        assert np.allclose(fn, [0, 0, 1]), type(obj).__name__
    plane = s.renderables.add_plane_mesh(2.0, m, c).to_mesh()
    assert np.allclose(np.abs(plane.vertices[:, :2]), 1.0) and plane.uv.shape == (2, 3, 2)
    assert len(s.renderables.add_circle_mesh(1.0, m, c, fill_type="NOTHING").to_mesh().faces) == 0


def test_world_bounds_follow_the_pose():
    s = bf.Scene()
    cube = s.renderables.add_cube_mesh(
        2.0,
        bf.DiffuseMaterial(),
        bf.UniformColors((1, 1, 1)),
        rotation_mode="eulerXYZ",
        rotation=(0, 0, 45),
        translation=(1, 2, 3),
    )
    lo, hi = cube.world_bounds()
    r = np.sqrt(2)
    assert np.allclose(lo, [1 - r, 2 - r, 2]) and np.allclose(hi, [1 + r, 2 + r, 4])
    lo, hi = s.bounds()
    assert np.allclose(hi, [1 + r, 2 + r, 4])


def _vertex_bounds(obj):
    """The bounds of the object's tessellation, rotated and translated (the definition world_bounds keeps)."""
    v = obj.to_mesh().vertices @ obj.rotation_matrix.T + obj.translation
    return v.min(axis=0), v.max(axis=0)


def test_world_bounds_of_every_primitive_enclose_its_tessellation_tightly():
    """Spheres and ellipsoids give their own bounds (the tessellation lies inside, within its chord error),
    mesh primitives and curves the tessellation's, for any rotation; and they follow pose and size changes."""
    s, m, c = bf.Scene(), bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1))
    pose = {"rotation_mode": "eulerXYZ", "rotation": (30, 50, 10), "translation": (1, 2, 3)}
    rng = np.random.default_rng(1)
    objs = {
        "sphere": s.renderables.add_sphere_nurbs(0.4, m, c, **pose),
        "ellipsoid": s.renderables.add_ellipsoid_nurbs((0.3, 0.1, 0.5), m, c, **pose),
        "cube": s.renderables.add_cube_mesh(0.3, m, c, **pose),
        "cylinder": s.renderables.add_cylinder_mesh(0.2, 0.7, m, c, **pose),
        "plane": s.renderables.add_plane_mesh(2.0, m, c, **pose),
        "circle": s.renderables.add_circle_mesh(0.5, m, c, **pose),
        "curve": s.renderables.add_curve_nurbs(rng.normal(size=(5, 3)), 0.05, m, c, **pose),
    }
    for name, obj in objs.items():
        for step in range(3):
            lo, hi = obj.world_bounds()
            vlo, vhi = _vertex_bounds(obj)
            tol = 2e-3 * float(np.max(vhi - vlo)) if name in ("sphere", "ellipsoid") else 1e-12
            assert np.all(lo <= vlo + 1e-12) and np.all(hi >= vhi - 1e-12), (name, step)
            assert np.allclose(lo, vlo, atol=tol) and np.allclose(hi, vhi, atol=tol), (name, step)
            if step == 0:
                obj.set_position(rotation_mode="eulerXYZ", rotation=(-20, 10, 80), translation=(-4, 0, 1))
            elif name in ("sphere", "cylinder", "circle", "curve"):
                obj.radius = 0.9
            elif name in ("cube", "plane"):
                obj.size = 1.7
    sphere = objs["sphere"]
    assert np.allclose(sphere.world_bounds()[1] - sphere.world_bounds()[0], 1.8)


def test_world_bounds_tessellate_a_primitive_once_per_geometry_and_rotation(monkeypatch):
    """A render asks for every object's bounds several times (scene bounds, effect analysis): a curve is
    tessellated once while its geometry and rotation stay, not again for a new translation, and again after
    either changes."""
    from blendify_core.ir.renderables.parametric import CurveBezier

    s = bf.Scene()
    curve = s.renderables.add_curve_nurbs(
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0]], dtype=float),
        0.05,
        bf.DiffuseMaterial(),
        bf.UniformColors((1, 1, 1)),
    )
    calls = []
    original = CurveBezier.to_mesh
    monkeypatch.setattr(CurveBezier, "to_mesh", lambda self, *a, **k: calls.append(1) or original(self, *a, **k))
    first = curve.world_bounds()
    curve.world_bounds()
    s.bounds()
    assert len(calls) == 1
    curve.set_position(translation=(0, 0, 5))
    lo, hi = curve.world_bounds()
    assert len(calls) == 1 and np.allclose(lo - first[0], [0, 0, 5]) and np.allclose(hi - first[1], [0, 0, 5])
    curve.set_position(rotation_mode="eulerXYZ", rotation=(0, 0, 90), translation=(0, 0, 5))
    lo, hi = curve.world_bounds()
    assert len(calls) == 2
    assert np.allclose(lo, _vertex_bounds(curve)[0]) and np.allclose(hi, _vertex_bounds(curve)[1])
    curve.radius = 0.2
    lo, hi = curve.world_bounds()
    assert len(calls) == 5  # (two more for _vertex_bounds above)
    assert np.allclose(lo, _vertex_bounds(curve)[0]) and np.allclose(lo[2], 4.8)


def test_mesh_vertex_normals_computed_once_per_geometry():
    """A mesh's vertex normals are computed once while its arrays live (every render of an unchanged mesh
    reuses them), read-only, and recomputed when the vertices change."""
    s = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    m = s.renderables.add_mesh(v, f, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)))
    n1 = m.vertex_normals()
    assert m.vertex_normals() is n1
    assert not n1.flags.writeable
    np.testing.assert_array_equal(n1, vertex_normals(v, f))
    m.update_vertices(v * [1.0, 2.0, 3.0])
    n2 = m.vertex_normals()
    assert n2 is not n1
    np.testing.assert_allclose(n2, vertex_normals(v * [1.0, 2.0, 3.0], f), atol=1e-15)
    assert not np.allclose(n2, n1)


def test_leaning_area_fraction_finds_low_poly_smooth_meshes():
    from blendify_core.ir.geometry import icosphere, leaning_area_fraction

    v = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)])
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1]])
    f = np.concatenate([f, [[2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]])
    box_normals = vertex_normals(v, f)  # every corner 54.7 deg off its faces
    assert leaning_area_fraction(v, f, box_normals, 30.0) == 1.0
    assert leaning_area_fraction(v, f, box_normals, 60.0) == 0.0
    assert leaning_area_fraction(v, f[:, ::-1], box_normals, 30.0) == 1.0  # the winding does not matter
    fine = icosphere(3)
    assert leaning_area_fraction(fine.vertices, fine.faces, vertex_normals(fine.vertices, fine.faces), 30.0) == 0.0
    assert leaning_area_fraction(v, f[:0], box_normals, 30.0) == 0.0
