"""The shared scene builders (blendify_core.testing) that backend, cross-backend and benchmark code rely
on: expected values they publish are right, they are deterministic, and they survive scene files."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf
from blendify_core import testing


@pytest.mark.parametrize(
    "kwargs",
    [{}, {"fy": 130.0}, {"center": None}, {"orthographic": True}, {"resolution": (96, 160), "fx": 90.0}],
    ids=["default", "non-square", "centred", "orthographic", "portrait"],
)
def test_marker_scene_expected_pixels_are_the_projections(kwargs):
    scene, pixels = testing.marker_scene(**kwargs)
    cam = scene.camera
    centres = np.array([scene.renderables[f"marker_{i}"].translation for i in range(len(pixels))])
    uv, z = cam.project(centres)
    assert np.max(np.abs(uv - pixels)) < 1e-9
    assert np.all(z > cam.near) and np.all(z < cam.far)
    w, h = cam.width, cam.height
    assert np.all((pixels >= 0) & (pixels <= [w - 1, h - 1]))


def test_expected_plane_depth_matches_ray_plane_geometry():
    scene = testing.depth_plane_scene((16, 12), distance=3.0, tilt_deg=30.0)
    depth = testing.expected_plane_depth(scene)
    cam = scene.camera
    assert depth.shape == (12, 16)
    # the centre ray hits the plane through the origin at planar depth == distance
    assert np.isclose(testing.expected_plane_depth(testing.depth_plane_scene((17, 13), 3.0, 30.0))[6, 8], 3.0)
    # every finite depth reprojects onto the plane z' = 0 of the tilted plane
    origins, dirs = cam.pixel_rays()
    t = depth.ravel() / (dirs @ cam.viewdir)
    pts = origins + t[:, None] * dirs
    normal = scene.renderables["plane"].rotation_matrix[:, 2]
    ok = np.isfinite(depth.ravel())
    assert ok.any() and np.max(np.abs(pts[ok] @ normal)) < 1e-9


@pytest.mark.parametrize("light", ["point", "sun", "spot", "area", "area_disk", "background"])
def test_plane_scene_light_types(light):
    s = testing.plane_scene(light)
    assert len(s.lights) == (0 if light == "background" else 1)
    assert (s.lights.background is not None) == (light == "background")
    with pytest.raises(ValueError, match="light"):
        testing.plane_scene("laser")


BUILDERS = {
    "marker": lambda: testing.marker_scene()[0],
    "plane": lambda: testing.plane_scene("area"),
    "depth_plane": testing.depth_plane_scene,
    "textured_quad": testing.textured_quad_scene,
    "textured_quad_faces_uv": lambda: testing.textured_quad_scene(faces_uv=True),
    "pointcloud": testing.pointcloud_scene,
    "primitives": testing.primitives_scene,
    "every_feature": testing.every_feature_scene,
}


@pytest.mark.parametrize("name", sorted(BUILDERS))
def test_builders_are_deterministic_and_round_trip(tmp_path, name):
    a, b = BUILDERS[name](), BUILDERS[name]()
    assert a.camera is not None
    assert a.fingerprint() == b.fingerprint()
    a.save(tmp_path / f"{name}.npz")
    assert bf.Scene.load(tmp_path / f"{name}.npz").fingerprint() == a.fingerprint()


def test_bunny_scene(data_dir):
    pytest.importorskip("trimesh", reason="trimesh is not installed")
    s = testing.bunny_scene((32, 32))
    bunny = s.renderables["bunny"]
    assert bunny.vertices.shape[1] == 3 and len(bunny.faces) > 1000
    assert np.isclose(bunny.vertices[:, 2].min(), 0.0)  # resting on the ground
    assert s.fingerprint() == testing.bunny_scene((32, 32)).fingerprint()


@pytest.fixture(scope="module")
def hard_case_names():
    return sorted(testing.hard_cases())


def test_hard_cases_are_deterministic_within_one_dict(hard_case_names):
    """Each builder must give the same scene every time it is called (backends are compared on them)."""
    cases = testing.hard_cases()
    for name in hard_case_names:
        assert cases[name]().fingerprint() == cases[name]().fingerprint(), name
    again = testing.hard_cases()
    for name in hard_case_names:
        assert cases[name]().fingerprint() == again[name]().fingerprint(), name


def test_hard_cases_round_trip(tmp_path, hard_case_names):
    cases = testing.hard_cases()
    for name in hard_case_names:
        s = cases[name]()
        s.save(tmp_path / "hc.npz")
        assert bf.Scene.load(tmp_path / "hc.npz").fingerprint() == s.fingerprint(), name
    assert set(testing.HARD_CASE_REFERENCE.values()) <= set(hard_case_names)
