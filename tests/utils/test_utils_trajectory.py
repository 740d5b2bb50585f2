"""Trajectory: keypoints in any rotation mode, smooth refinement, 180-degree turns, serialisation."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import blendify_core as bf
from blendify_core.ir.transforms import quaternion_from_rotation, quaternion_to_matrix
from blendify_core.utils import Pose, Trajectory, apply_pose


def _yaw_deg(q):
    m = quaternion_to_matrix(q)
    return np.degrees(np.arctan2(m[1, 0], m[0, 0]))


def _angle_between(q0, q1):
    return np.degrees(2 * np.arccos(np.clip(abs(np.dot(q0, q1)), -1, 1)))


def test_two_keypoints_linear_and_cubic_agree():
    t = Trajectory()
    t.add_keypoint((0, 0, 0), (0, 0, 0), 0.0, rotation_mode="eulerXYZ")
    t.add_keypoint((1, 2, 3), (0, 0, 90), 1.0, rotation_mode="eulerXYZ")
    for mode in ("linear", "quadratic", "cubic", "slerp", "squad"):
        poses = t.refine(0.25, interpolation=mode)
        assert [p.time for p in poses] == [0.0, 0.25, 0.5, 0.75, 1.0]
        np.testing.assert_allclose(poses[2].position, [0.5, 1.0, 1.5])
        assert _yaw_deg(poses[2].quaternion) == pytest.approx(45.0)


def test_keypoints_sorted_and_repeated_time_last_wins():
    t = Trajectory()
    t.add_keypoint((2, 0, 0), time=2.0)
    t.add_keypoint((0, 0, 0), time=0.0)
    t.add_keypoint((1, 0, 0), time=1.0)
    t.add_keypoint((5, 5, 5), time=1.0)  # replaces
    assert len(t) == 3
    np.testing.assert_array_equal(t.times, [0, 1, 2])
    np.testing.assert_array_equal(t[1].position, [5, 5, 5])
    t.add_keypoint((9, 9, 9))  # time None: one second after the last
    assert t.times[-1] == 3.0 and len(list(t)) == 4


def test_cubic_positions_pass_through_keypoints_and_are_smooth():
    t = Trajectory()
    pts = [(0, 0, 0), (1, 1, 0), (2, 0, 1), (3, 1, 1), (4, 0, 0)]
    for i, p in enumerate(pts):
        t.add_keypoint(p, time=i)
    poses = t.refine(0.05, interpolation="cubic")
    by_time = {round(p.time, 6): p.position for p in poses}
    for i, p in enumerate(pts):
        np.testing.assert_allclose(by_time[float(i)], p, atol=1e-9)
    pos = np.array([p.position for p in poses])
    second = np.diff(pos, 2, axis=0)
    assert np.abs(second).max() < 0.02  # C2 spline sampled every 0.05 s: small second differences


def test_180_degree_turn_never_spins_360():
    t = Trajectory()
    t.add_keypoint((0, 0, 0), 0.0, 0.0, rotation_mode="eulerz")
    t.add_keypoint((1, 0, 0), 180.0, 1.0, rotation_mode="eulerz")
    poses = t.refine(0.1, interpolation="linear")
    steps = [_angle_between(a.quaternion, b.quaternion) for a, b in zip(poses, poses[1:])]
    np.testing.assert_allclose(steps, 18.0, atol=1e-6)


@pytest.mark.parametrize("rot", ["slerp", "squad"])
def test_full_turn_in_quarter_keypoints_is_uniform(rot):
    t = Trajectory()
    for i, yaw in enumerate([0, 90, 180, 270, 360, 450]):
        t.add_keypoint((i, 0, 0), yaw, i, rotation_mode="eulerz")
    poses = t.refine(0.1, interpolation="cubic", rotation_interpolation=rot)
    yaw = np.unwrap(np.radians([_yaw_deg(p.quaternion) for p in poses]))
    np.testing.assert_allclose(np.degrees(np.diff(yaw)), 9.0, atol=1e-6)
    assert all(p.quaternion[0] >= 0 for p in poses)  # canonical sign


def test_squad_is_smoother_than_slerp_at_keypoints():
    t = Trajectory()
    for i, yaw in enumerate([0, 60, 70, 160]):
        t.add_keypoint((0, 0, 0), (20 * (i % 2), 0, yaw), i, rotation_mode="eulerXYZ")

    def max_jump(mode):
        poses = t.refine(0.02, rotation_interpolation=mode)
        q = np.array([p.quaternion for p in poses])
        w = [_angle_between(a, b) for a, b in zip(q, q[1:])]
        return np.abs(np.diff(w)).max()  # change of angular speed between frames

    assert max_jump("squad") < 0.5 * max_jump("slerp")


def test_rotation_modes_and_look_at():
    t = Trajectory()
    t.add_keypoint((0, -5, 0), (0, 0, 0), 0.0, rotation_mode="look_at")
    t.add_keypoint((5, 0, 0), [0.0, 0.0, 0.0], 1.0, rotation_mode="look_at")
    t.add_keypoint((0, 5, 0), np.eye(3), 2.0, rotation_mode="rotmat")
    t.add_keypoint((0, 5, 0), (0, 0, 0, 1), 3.0, rotation_mode="quaternionXYZW")
    t.add_keypoint((0, 5, 0), (0, 0, np.pi / 2), 4.0, rotation_mode="rotvec")
    expected = quaternion_from_rotation("look_at", (0, 0, 0), np.array([0.0, -5.0, 0.0]))
    np.testing.assert_allclose(t[0].quaternion, expected)
    np.testing.assert_allclose(t[2].quaternion, [1, 0, 0, 0])
    assert _yaw_deg(t[4].quaternion) == pytest.approx(90.0)
    with pytest.raises(bf.InvalidSceneError, match="rotation_mode"):
        t.add_keypoint((0, 0, 0), (1, 2, 3), 5.0, rotation_mode="eulerQRS")


def test_single_keypoint_and_smoothing():
    t = Trajectory()
    t.add_keypoint((1, 2, 3), (0, 0, 30), 0.0, rotation_mode="eulerXYZ")
    poses = t.refine(0.1)
    assert len(poses) == 1 and poses[0].time == 0.0
    t.add_keypoint((1, 2, 3), (0, 0, 30), 1.0, rotation_mode="eulerXYZ")
    t.add_keypoint((10, 2, 3), (0, 0, 30), 1.1, rotation_mode="eulerXYZ")  # a jump
    raw = np.array([p.position[0] for p in t.refine(0.01, interpolation="linear")])
    smooth = np.array([p.position[0] for p in t.refine(0.01, interpolation="linear", smoothness=10.0)])
    assert np.abs(np.diff(smooth)).max() < 0.5 * np.abs(np.diff(raw)).max()
    q = np.array([p.quaternion for p in t.refine(0.01, smoothness=5.0)])
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0)


def test_serialisation_round_trip_and_dict_access():
    t = Trajectory.orbit(center=(0, 0, 1), radius=2.0, n_keypoints=6, duration=3.0)
    data = json.loads(json.dumps(t.to_dict()))
    back = Trajectory.from_dict(data)
    assert len(back) == len(t)
    np.testing.assert_allclose(back.positions, t.positions)
    np.testing.assert_allclose(back.quaternions, t.quaternions)
    pose = back.refine(0.5)[1]
    assert isinstance(pose, Pose) and set(pose.keys()) == {"position", "quaternion", "time"}
    np.testing.assert_array_equal(pose["position"], pose.position)
    with pytest.raises(bf.InvalidSceneError, match="keypoints"):
        Trajectory.from_dict({"keypoints": [{"position": [0, 0, 0]}]})


def test_orbit_stays_on_its_circle_and_looks_at_the_centre():
    t = Trajectory.orbit(center=(1, 1, 0), radius=3.0, height=0.5, n_keypoints=12, duration=2.0)
    for p in t.refine(1 / 24):
        r = np.linalg.norm(p.position[:2] - np.array([1, 1]))
        assert r == pytest.approx(3.0, rel=2e-3)
        viewdir = -quaternion_to_matrix(p.quaternion)[:, 2]
        to_centre = np.array([1, 1, 0]) - p.position
        assert np.dot(viewdir, to_centre / np.linalg.norm(to_centre)) > 0.999


def test_apply_pose_moves_the_camera():
    scene = bf.Scene()
    cam = scene.set_perspective_camera((32, 32), fov_x=1.0)
    t = Trajectory()
    t.add_keypoint((0, -4, 1), (0, 0, 0), 0, rotation_mode="look_at")
    t.add_keypoint((4, 0, 1), (0, 0, 0), 1, rotation_mode="look_at")
    pose = t.refine(0.5)[1]
    apply_pose(cam, pose)
    np.testing.assert_allclose(cam.translation, pose.position)
    Trajectory.apply(cam, t[0])
    np.testing.assert_allclose(cam.translation, [0, -4, 1])
    apply_pose(cam, pose)
    np.testing.assert_allclose(cam.quaternion, pose.quaternion)
    with pytest.raises(bf.InvalidSceneError, match="camera"):
        apply_pose("camera", pose)


def test_bad_arguments():
    t = Trajectory()
    with pytest.raises(bf.InvalidSceneError, match="no keypoints"):
        t.refine(0.1)
    t.add_keypoint((0, 0, 0), time=0)
    with pytest.raises(bf.InvalidSceneError, match="time_step"):
        t.refine(0.0)
    with pytest.raises(bf.InvalidSceneError, match="interpolation"):
        t.refine(0.1, interpolation="bezier")
    with pytest.raises(bf.InvalidSceneError, match="position"):
        t.add_keypoint((0, 0), time=1)
    with pytest.raises(bf.InvalidSceneError, match="time"):
        t.add_keypoint((0, 0, 0), time=float("nan"))


@settings(max_examples=30, deadline=None)
@given(
    times=st.lists(st.floats(0, 10, allow_nan=False), min_size=1, max_size=6),
    yaws=st.lists(st.floats(-720, 720, allow_nan=False), min_size=6, max_size=6),
    mode=st.sampled_from(["linear", "quadratic", "cubic"]),
)
def test_refine_is_robust_to_any_keypoints(times, yaws, mode):
    t = Trajectory()
    for i, tm in enumerate(times):
        t.add_keypoint((i, -i, 0.5 * i), yaws[i], tm, rotation_mode="eulerz")
    poses = t.refine(0.05, interpolation=mode)
    q = np.array([p.quaternion for p in poses])
    pos = np.array([p.position for p in poses])
    assert np.all(np.isfinite(q)) and np.all(np.isfinite(pos))
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-9)
    # never faster than the shortest-arc angle between neighbouring keypoints allows (no extra spins)
    if len(t) >= 2:
        kq = t.quaternions
        max_seg = max(_angle_between(a, b) for a, b in zip(kq, kq[1:]))
        steps = [_angle_between(a, b) for a, b in zip(q, q[1:])]
        min_dt = np.diff(t.times).min()
        assert max(steps, default=0) <= max_seg * 0.05 / min_dt * 1.6 + 1e-6
