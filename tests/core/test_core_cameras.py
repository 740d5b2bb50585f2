"""Camera conventions as properties: OpenCV (K, R, t) <-> IR round trips, projection, pixel rays,
look_at framing, orthographic cameras, fov/focal conversions and blendify's pixel model."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import blendify_core as bf
from blendify_core.ir.cameras import CV_FROM_BLENDER

SETTINGS = settings(max_examples=120, deadline=None)

unit = st.floats(-1.0, 1.0, allow_nan=False)
quat4 = st.tuples(unit, unit, unit, unit).filter(lambda q: np.linalg.norm(q) > 1e-2)
coords = st.floats(-20.0, 20.0, allow_nan=False)
point3 = st.tuples(coords, coords, coords).map(np.array)
resolutions = st.tuples(st.integers(8, 4000), st.integers(8, 4000))


@st.composite
def intrinsics(draw):
    w, h = draw(resolutions)
    fx = draw(st.floats(20.0, 5000.0))
    fy = draw(st.one_of(st.just(fx), st.floats(20.0, 5000.0)))  # fx != fy allowed
    cx = draw(st.floats(-0.5 * w, 1.5 * w))
    cy = draw(st.floats(-0.5 * h, 1.5 * h))
    return (w, h), np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def _rot(q) -> np.ndarray:
    return Rotation.from_quat(np.asarray(q, float)).as_matrix()


@SETTINGS
@given(intr=intrinsics(), q=quat4, t=point3)
def test_opencv_round_trip(intr, q, t):
    res, k = intr
    r = _rot(q)
    scene = bf.Scene()
    cam = scene.set_camera_from_opencv(k, r, t, res)
    assert scene.camera is cam
    assert np.max(np.abs(cam.K - k)) <= 1e-9 * max(1.0, np.abs(k).max())
    r2, t2 = cam.opencv_extrinsics()
    assert np.max(np.abs(r2 - r)) < 1e-9
    assert np.max(np.abs(t2 - t)) < 1e-9
    assert tuple(cam.resolution) == res
    # the IR pose is the Blender frame: rotation = R^T diag(1, -1, -1), position = -R^T t
    assert np.max(np.abs(cam.rotation_matrix - r.T @ CV_FROM_BLENDER)) < 1e-9
    assert np.max(np.abs(cam.translation + r.T @ t)) < 1e-9


depth = st.floats(0.1, 50.0)
front = st.tuples(coords, coords, depth).map(np.array)  # camera-space points in front of the camera


@SETTINGS
@given(intr=intrinsics(), q=quat4, t=point3, pts=st.lists(front, min_size=1, max_size=8))
def test_project_matches_k_r_x_plus_t(intr, q, t, pts):
    res, k = intr
    r = _rot(q)
    cam = bf.Scene().set_camera_from_opencv(k, r, t, res)
    x = (np.array(pts) - t) @ r  # world points: R^T (x_cam - t)
    xc = x @ r.T + t
    uv, z = cam.project(x)
    hom = xc @ k.T
    expected = hom[:, :2] / hom[:, 2:3]
    assert np.max(np.abs(uv - expected)) < 1e-6
    assert np.max(np.abs(z - xc[:, 2])) < 1e-9


@SETTINGS
@given(intr=intrinsics(), q=quat4, t=point3, pts=st.lists(front, min_size=1, max_size=8))
def test_pixel_rays_pass_through_projected_points(intr, q, t, pts):
    res, k = intr
    r = _rot(q)
    cam = bf.Scene().set_camera_from_opencv(k, r, t, res)
    x = (np.array(pts) - t) @ r
    uv, z = cam.project(x)
    assert np.all(z > 0.09)
    origins, dirs = cam.pixel_rays(uv)
    assert np.max(np.abs(np.linalg.norm(dirs, axis=1) - 1.0)) < 1e-12
    assert np.max(np.abs(origins - cam.translation)) < 1e-12
    # the point lies on its ray, in front of the camera
    rel = x - origins
    along = np.sum(rel * dirs, axis=1)
    assert np.all(along > 0)
    dist = np.linalg.norm(rel - along[:, None] * dirs, axis=1)
    assert np.max(dist) < 1e-9 * max(1.0, np.abs(x).max())


def test_pixel_rays_default_order_is_row_major():
    cam = bf.Scene().set_perspective_camera((5, 3), focal_dist=4.0)
    origins, dirs = cam.pixel_rays()
    assert dirs.shape == (15, 3)
    vv, uu = np.mgrid[0:3, 0:5]
    _, d2 = cam.pixel_rays(np.stack([uu.ravel(), vv.ravel()], 1).astype(float))
    assert np.array_equal(dirs, d2)
    # pixel (u=0, v=0) is top-left: ray goes left (-X) and up (+Y) for the identity camera
    assert dirs[0, 0] < 0 and dirs[0, 1] > 0


@SETTINGS
@given(
    position=point3,
    target=point3,
    roll=st.floats(-180, 180),
    res=resolutions,
    f=st.floats(20.0, 3000.0),
    c=st.tuples(st.floats(0, 1), st.floats(0, 1)),
)
def test_look_at_camera_sees_its_target_at_the_principal_point(position, target, roll, res, f, c):
    assume(np.linalg.norm(target - position) > 1e-2)
    center = (c[0] * (res[0] - 1), c[1] * (res[1] - 1))
    cam = bf.Scene().set_perspective_camera(
        res, focal_dist=f, center=center, rotation_mode="look_at", rotation=(target, roll), translation=position
    )
    uv, z = cam.project(target[None])
    assert np.max(np.abs(uv[0] - center)) < 1e-6
    assert abs(z[0] - np.linalg.norm(target - position)) < 1e-9


@SETTINGS
@given(
    res=resolutions,
    scale=st.floats(0.01, 100.0),
    q=quat4,
    t=point3,
    pix=st.lists(st.tuples(st.floats(-10, 4000), st.floats(-10, 4000)), min_size=1, max_size=6),
    depth=st.floats(0.5, 50.0),
)
def test_orthographic_project_and_pixel_rays_agree(res, scale, q, t, pix, depth):
    cam = bf.Scene().set_orthographic_camera(res, ortho_scale=scale, rotation=q, translation=t)
    assert abs(cam.pixel_size - scale / res[0]) < 1e-15
    pixels = np.array(pix, dtype=float)
    origins, dirs = cam.pixel_rays(pixels)
    assert np.max(np.abs(dirs - cam.viewdir)) < 1e-12  # all rays parallel to the view direction
    uv, z = cam.project(origins + depth * dirs)
    assert np.max(np.abs(uv - pixels)) < 1e-6
    assert np.max(np.abs(z - depth)) < 1e-9
    uv0, z0 = cam.project(origins)
    assert np.max(np.abs(uv0 - pixels)) < 1e-6 and np.max(np.abs(z0)) < 1e-9


def test_orthographic_blendify_pixel_model():
    """u = W/2 + X_c W / ortho_scale, v = H/2 - Y_c W / ortho_scale (blendify, pixel centres at +0.5)."""
    w, h, s = 200, 100, 4.0
    cam = bf.Scene().set_orthographic_camera((w, h), ortho_scale=s, translation=(0, 0, 10))
    uv, z = cam.project(np.array([[1.0, 0.5, 0.0]]))
    assert np.allclose(uv[0], [w / 2 + 1.0 * w / s - 0.5, h / 2 - 0.5 * w / s - 0.5], atol=1e-12)
    assert np.isclose(z[0], 10.0)


def test_blendify_perspective_pixel_model_and_default_principal_point():
    """u = W/2 + f X_c / (-Z_c), v = H/2 - f Y_c / (-Z_c) in blendify's pixel-corner units, i.e. the
    OpenCV principal point defaults to ((W - 1) / 2, (H - 1) / 2)."""
    w, h, f = 320, 240, 200.0
    cam = bf.Scene().set_perspective_camera((w, h), focal_dist=f)
    assert np.array_equal(cam.center, [(w - 1) / 2, (h - 1) / 2])
    assert cam.fx == cam.fy == f == cam.focal_dist
    x = np.array([[0.3, 0.2, -2.0]])
    uv, z = cam.project(x)
    u_blendify = w / 2 + f * 0.3 / 2.0
    v_blendify = h / 2 - f * 0.2 / 2.0
    assert np.allclose(uv[0], [u_blendify - 0.5, v_blendify - 0.5], atol=1e-12)
    assert np.isclose(z[0], 2.0)


@pytest.mark.parametrize("res", [(320, 240), (240, 320), (100, 100)])
def test_fov_and_focal_conversions(res):
    w, h = res
    s = bf.Scene()
    cam = s.set_perspective_camera(res, fov_x=np.deg2rad(60))
    assert np.isclose(cam.fx, w / (2 * np.tan(np.deg2rad(30))), rtol=1e-12)
    assert np.isclose(cam.fov_x, np.deg2rad(60), rtol=1e-12)
    cam = s.set_perspective_camera(res, fov_y=np.deg2rad(45))
    assert np.isclose(cam.fy, h / (2 * np.tan(np.deg2rad(22.5))), rtol=1e-12)
    assert np.isclose(cam.fov_y, np.deg2rad(45), rtol=1e-12)
    assert cam.fx == cam.fy
    cam = s.set_perspective_camera(res, focal_dist=100.0)
    assert np.isclose(cam.fov_x, 2 * np.arctan(w / 200.0), rtol=1e-12)


def test_k_with_non_square_pixels_and_explicit_center():
    k = np.array([[300.0, 0, 10.5], [0, 200.0, 70.25], [0, 0, 1]])
    s = bf.Scene()
    cam = s.set_perspective_camera((64, 48), K=k)
    assert np.array_equal(cam.K, k)
    cam = s.set_perspective_camera((64, 48), K=k, center=(30.0, 20.0))
    assert np.array_equal(cam.center, [30.0, 20.0])  # center overrides K's principal point


@SETTINGS
@given(cx=st.floats(-100, 400), cy=st.floats(-100, 400), f=st.floats(10, 1000))
def test_principal_point_round_trip(cx, cy, f):
    """blendify bug 8: the principal point's setter, getter and projection disagreed."""
    cam = bf.Scene().set_perspective_camera((320, 240), focal_dist=f, center=(cx, cy))
    assert cam.cx == cx and cam.cy == cy
    assert np.array_equal(cam.center, [cx, cy])
    assert np.array_equal(cam.K[:2, 2], [cx, cy])
    uv, _ = cam.project(np.array([[0.0, 0.0, -3.0]]))  # on the optical axis
    assert np.allclose(uv[0], [cx, cy], atol=1e-9)


def test_camera_viewdir_and_identity_pose():
    cam = bf.Scene().set_perspective_camera((32, 32), focal_dist=20)
    assert np.array_equal(cam.viewdir, [0, 0, -1])
    assert np.array_equal(cam.get_camera_viewdir(), cam.viewdir)
    r, t = cam.opencv_extrinsics()
    assert np.array_equal(r, np.diag([1.0, -1.0, -1.0])) and np.array_equal(t, [0, 0, 0])


def test_resolution_percentage_scaling_keeps_the_framing():
    cam = bf.Scene().set_perspective_camera(
        (200, 100), K=np.array([[150.0, 0, 90.3], [0, 120.0, 40.7], [0, 0, 1]]), resolution_percentage=50
    )
    small = cam._scaled(0.5)
    assert tuple(small.resolution) == (100, 50)
    x = np.array([[0.3, -0.2, -4.0], [1.0, 0.5, -3.0]])
    uv_big, _ = cam.project(x)
    uv_small, _ = small.project(x)
    # the same point lands at the same relative position (pixel-corner coordinates scale by 0.5)
    assert np.allclose((uv_small + 0.5), (uv_big + 0.5) * 0.5, atol=1e-9)
