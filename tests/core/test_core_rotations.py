"""Property tests of every rotation mode: orthonormal proper rotations, agreement with scipy and between
equivalent modes, look_at frames (including the degenerate cases) and blendify's equivalences."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import blendify_core as bf
from blendify_core.errors import InvalidSceneError
from blendify_core.ir.transforms import look_at_rotation, quaternion_from_rotation, quaternion_to_matrix

SETTINGS = settings(max_examples=150, deadline=None)

finite = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
quat4 = st.tuples(finite, finite, finite, finite).filter(lambda q: np.linalg.norm(q) > 1e-3)
scales = st.floats(1e-3, 1e3)
coords = st.floats(-50.0, 50.0, allow_nan=False, allow_infinity=False)
point3 = st.tuples(coords, coords, coords).map(np.array)
angles_deg = st.floats(-720.0, 720.0, allow_nan=False, allow_infinity=False)


def _matrix(mode: str, rotation, position=None) -> np.ndarray:
    q = quaternion_from_rotation(mode, rotation, position)
    assert q.shape == (4,) and q.dtype == np.float64
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12
    assert q[0] >= 0.0
    return quaternion_to_matrix(q)


def _assert_proper(m: np.ndarray) -> None:
    assert np.all(np.isfinite(m))
    assert np.max(np.abs(m.T @ m - np.eye(3))) < 1e-12, "not orthonormal"
    assert abs(np.linalg.det(m) - 1.0) < 1e-12, "not a proper rotation"


def _random_rotation(q) -> np.ndarray:
    return Rotation.from_quat(np.asarray(q, dtype=float)).as_matrix()  # scipy: scalar-last


# ---------------------------------------------------------------------------------------------------
# quaternions
# ---------------------------------------------------------------------------------------------------


@SETTINGS
@given(q=quat4, scale=scales)
def test_quaternion_wxyz_unnormalised_matches_scipy(q, scale):
    wxyz = np.asarray(q) * scale
    m = _matrix("quaternionWXYZ", wxyz)
    _assert_proper(m)
    ref = Rotation.from_quat([wxyz[1], wxyz[2], wxyz[3], wxyz[0]]).as_matrix()
    assert np.max(np.abs(m - ref)) < 1e-9


@SETTINGS
@given(q=quat4, scale=scales)
def test_quaternion_xyzw_equals_wxyz(q, scale):
    wxyz = np.asarray(q) * scale
    xyzw = np.array([wxyz[1], wxyz[2], wxyz[3], wxyz[0]])
    a = quaternion_from_rotation("quaternionWXYZ", wxyz)
    b = quaternion_from_rotation("quaternionXYZW", xyzw)
    assert np.max(np.abs(a - b)) < 1e-12
    _assert_proper(quaternion_to_matrix(b))


@SETTINGS
@given(q=quat4)
def test_quaternion_sign_does_not_matter(q):
    a = quaternion_from_rotation("quaternionWXYZ", q)
    b = quaternion_from_rotation("quaternionWXYZ", -np.asarray(q))
    assert a[0] >= 0 and b[0] >= 0  # canonical hemisphere
    if abs(a[0]) > 1e-9:
        assert np.max(np.abs(a - b)) < 1e-12
    assert np.max(np.abs(quaternion_to_matrix(a) - quaternion_to_matrix(b))) < 1e-12


def test_zero_quaternion_is_rejected():
    with pytest.raises(InvalidSceneError, match="rotation"):
        quaternion_from_rotation("quaternionWXYZ", (0, 0, 0, 0))


# ---------------------------------------------------------------------------------------------------
# rotvec, rotmat, euler
# ---------------------------------------------------------------------------------------------------


@SETTINGS
@given(axis=point3, angle=st.floats(-3 * np.pi, 3 * np.pi))
def test_rotvec_matches_scipy_and_quaternion(axis, angle):
    n = np.linalg.norm(axis)
    assume(n > 1e-6)
    v = axis / n * angle
    m = _matrix("rotvec", v)
    _assert_proper(m)
    ref = Rotation.from_rotvec(v)
    assert np.max(np.abs(m - ref.as_matrix())) < 1e-9
    xyzw = ref.as_quat()
    m2 = _matrix("quaternionWXYZ", [xyzw[3], xyzw[0], xyzw[1], xyzw[2]])
    assert np.max(np.abs(m - m2)) < 1e-9


@SETTINGS
@given(q=quat4)
def test_rotmat_exact_round_trip(q):
    r = _random_rotation(q)
    m = _matrix("rotmat", r)
    _assert_proper(m)
    assert np.max(np.abs(m - r)) < 1e-9


@SETTINGS
@given(q=quat4, noise=st.lists(st.floats(-1e-5, 1e-5), min_size=9, max_size=9))
def test_rotmat_slightly_perturbed_is_reorthonormalised(q, noise):
    r = _random_rotation(q)
    perturbed = r + np.reshape(noise, (3, 3))
    m = _matrix("rotmat", perturbed)
    _assert_proper(m)
    assert np.max(np.abs(m - r)) < 1e-4  # the nearest rotation, not something else


_ORDERS = sorted(
    {"".join(p) for p in itertools.product("xyz", repeat=3) if p[0] != p[1] and p[1] != p[2]}
    | {"".join(p) for p in itertools.permutations("xyz", 2)}
    | {"x", "y", "z"}
)


@SETTINGS
@given(order=st.sampled_from(_ORDERS), intrinsic=st.booleans(), angles=st.lists(angles_deg, min_size=3, max_size=3))
def test_euler_degrees_matches_scipy(order, intrinsic, angles):
    seq = order.upper() if intrinsic else order
    a = np.array(angles[: len(seq)])
    m = _matrix(f"euler{seq}", a if len(seq) > 1 else float(a[0]))
    _assert_proper(m)
    ref = Rotation.from_euler(seq, a, degrees=True).as_matrix()
    assert np.max(np.abs(m - ref)) < 1e-9


def test_intrinsic_and_extrinsic_differ_as_in_scipy():
    a = (30.0, 45.0, 60.0)
    intrinsic = _matrix("eulerXYZ", a)
    extrinsic = _matrix("eulerxyz", a)
    assert np.max(np.abs(intrinsic - extrinsic)) > 0.1
    # extrinsic xyz == intrinsic ZYX with reversed angles
    assert np.max(np.abs(extrinsic - _matrix("eulerZYX", a[::-1]))) < 1e-12


@pytest.mark.parametrize("mode", ["eulerXyz", "eulerXYZW", "euler", "eulerABC", "eulerXYZXYZ"])
def test_bad_euler_strings_are_rejected(mode):
    with pytest.raises(InvalidSceneError, match="rotation_mode"):
        quaternion_from_rotation(mode, (1, 2, 3))


def test_euler_angle_count_must_match_axes():
    with pytest.raises(InvalidSceneError, match="rotation"):
        quaternion_from_rotation("eulerXY", (1.0, 2.0, 3.0))


# ---------------------------------------------------------------------------------------------------
# look_at
# ---------------------------------------------------------------------------------------------------


@SETTINGS
@given(position=point3, target=point3)
def test_look_at_points_local_minus_z_at_the_target(position, target):
    d = target - position
    assume(np.linalg.norm(d) > 1e-3)
    m = _matrix("look_at", target, position)
    _assert_proper(m)
    view = -m[:, 2]
    assert np.max(np.abs(view - d / np.linalg.norm(d))) < 1e-9
    # image up (+Y) as close to world +Z as possible: x horizontal, y has a non-negative z
    horizontal = np.hypot(d[0], d[1]) > 1e-6 * np.linalg.norm(d)
    if horizontal:
        assert abs(m[2, 0]) < 1e-9
        assert m[2, 1] >= -1e-12


@SETTINGS
@given(position=point3, target=point3, roll=angles_deg)
def test_look_at_roll_rotates_about_the_view_axis(position, target, roll):
    assume(np.linalg.norm(target - position) > 1e-3)
    base = _matrix("look_at", target, position)
    rolled = _matrix("look_at", (target, roll), position)
    _assert_proper(rolled)
    a = np.deg2rad(roll)
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    assert np.max(np.abs(rolled - base @ rz)) < 1e-9
    assert np.max(np.abs(rolled[:, 2] - base[:, 2])) < 1e-9


def test_look_at_roll_180_flips_the_image():
    base = _matrix("look_at", np.zeros(3), np.array([3.0, -4.0, 2.0]))
    rolled = _matrix("look_at", (np.zeros(3), 180.0), np.array([3.0, -4.0, 2.0]))
    assert np.max(np.abs(rolled[:, 0] + base[:, 0])) < 1e-12
    assert np.max(np.abs(rolled[:, 1] + base[:, 1])) < 1e-12
    assert np.max(np.abs(rolled[:, 2] - base[:, 2])) < 1e-12


@pytest.mark.parametrize("sign", [1.0, -1.0], ids=["looking-down", "looking-up"])
@pytest.mark.parametrize("offset", [0.0, 1e-300, 1e-14, 1e-9])
def test_look_at_parallel_to_z_is_well_defined(sign, offset):
    position = np.array([offset, 0.0, 5.0 * sign])
    m = _matrix("look_at", np.zeros(3), position)
    _assert_proper(m)
    assert np.max(np.abs(-m[:, 2] - np.array([0, 0, -sign]))) < 1e-8
    if offset == 0.0:
        # blendify's fallback: world +Y is the image up when the view is parallel to Z
        assert np.max(np.abs(m[:, 1] - np.array([0.0, 1.0, 0.0]))) < 1e-12


@SETTINGS
@given(position=point3)
def test_look_at_own_position_is_identity(position):
    m = _matrix("look_at", position.copy(), position)
    assert np.max(np.abs(m - np.eye(3))) < 1e-12


def test_look_at_accepts_an_object_as_target():
    scene = bf.Scene()
    sphere = scene.renderables.add_sphere_nurbs(
        0.1, bf.PrincipledBSDFMaterial(), bf.UniformColors((1, 1, 1)), translation=(1.0, 2.0, 0.5)
    )
    cam = scene.set_perspective_camera(
        (64, 48), focal_dist=50, rotation_mode="look_at", rotation=sphere, translation=(4, -3, 2)
    )
    d = sphere.translation - cam.translation
    assert np.max(np.abs(cam.viewdir - d / np.linalg.norm(d))) < 1e-12
    # lookat is blendify's alternative spelling
    cam2 = scene.set_perspective_camera(
        (64, 48), focal_dist=50, rotation_mode="lookat", rotation=(1.0, 2.0, 0.5), translation=(4, -3, 2)
    )
    assert np.max(np.abs(cam2.quaternion - cam.quaternion)) < 1e-12


def test_look_at_helper_matches_mode():
    p, t = np.array([1.0, 2.0, 3.0]), np.array([-1.0, 0.5, 0.0])
    assert np.max(np.abs(look_at_rotation(p, t, 30.0) - _matrix("look_at", (t, 30.0), p))) < 1e-12


# ---------------------------------------------------------------------------------------------------
# blendify equivalences and objects
# ---------------------------------------------------------------------------------------------------


def test_blendify_equivalence_euler_rotvec_quaternion():
    a = _matrix("eulerXYZ", (90, 0, 0))
    b = _matrix("rotvec", (np.pi / 2, 0, 0))
    c = _matrix("quaternionWXYZ", (0.7071, 0.7071, 0, 0))
    d = _matrix("quaternionXYZW", (0.7071, 0, 0, 0.7071))
    for m in (b, c, d):
        assert np.max(np.abs(a - m)) < 1e-9
    assert np.allclose(a @ [0, 1, 0], [0, 0, 1], atol=1e-12)  # +90 deg about X takes +Y to +Z


@SETTINGS
@given(q=quat4, t=point3)
def test_every_positionable_agrees(q, t):
    """Cameras, lights and renderables resolve rotations identically; matrix_world composes them."""
    scene = bf.Scene()
    pose = dict(rotation_mode="quaternionWXYZ", rotation=q, translation=t)
    objs = [
        scene.set_perspective_camera((32, 32), focal_dist=30, **pose),
        scene.lights.add_spot(**pose),
        scene.renderables.add_cube_mesh(1.0, bf.PrincipledBSDFMaterial(), bf.UniformColors((1, 1, 1)), **pose),
    ]
    expected = _matrix("quaternionWXYZ", q)
    for o in objs:
        mw = o.matrix_world
        assert mw.shape == (4, 4) and mw.dtype == np.float64
        assert np.max(np.abs(mw[:3, :3] - expected)) < 1e-12
        assert np.array_equal(mw[:3, 3], t)
        assert np.array_equal(mw[3], [0, 0, 0, 1])


def test_set_position_translation_first_for_look_at():
    scene = bf.Scene()
    light = scene.lights.add_spot(translation=(0, 0, 5))
    light.set_position(rotation_mode="look_at", rotation=(0, 0, 0), translation=(5, 0, 0))
    assert np.allclose(light.direction, [-1, 0, 0], atol=1e-12)


def test_quaternion_and_translation_are_read_only_and_settable():
    scene = bf.Scene()
    light = scene.lights.add_point(translation=(1, 2, 3))
    with pytest.raises(ValueError):
        light.translation[0] = 5.0  # read-only array
    rev = light.revision("transform")
    light.quaternion = (0.0, 0.0, 0.0, 2.0)
    assert np.allclose(light.quaternion, [0, 0, 0, 1])
    light.translation = (4, 5, 6)
    assert np.array_equal(light.translation, [4, 5, 6])
    assert light.revision("transform") == rev + 2


def test_unknown_rotation_mode_is_rejected():
    with pytest.raises(InvalidSceneError, match="rotation_mode"):
        quaternion_from_rotation("axis_angle", (1, 0, 0))
