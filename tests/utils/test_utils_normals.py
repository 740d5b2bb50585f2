"""estimate_normals / orient_normals / normals_from_mesh: accuracy, orientation, degenerate inputs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import blendify_core as bf
from blendify_core.ir.geometry import icosphere
from blendify_core.utils import estimate_normals, normals_from_mesh, orient_normals


def _sphere(rng, n, radius=1.0, center=(0.0, 0.0, 0.0)):
    p = rng.normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    return p * radius + np.asarray(center), p


def _angle_deg(a, b):
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0)))


def test_sphere_normals_are_accurate_and_point_outwards(rng):
    p, truth = _sphere(rng, 4000, radius=2.0, center=(1.0, -2.0, 0.5))
    n = estimate_normals(p, k=16)
    err = _angle_deg(n, truth)
    assert err.mean() < 1.5 and err.max() < 10.0, (err.mean(), err.max())
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)


def test_noisy_plane_normals(rng):
    xy = rng.uniform(-1, 1, size=(3000, 2))
    p = np.c_[xy, 0.002 * rng.normal(size=3000)]
    n = estimate_normals(p, k=20)
    assert np.all(n[:, 2] > 0)  # flat patch: +Z by convention
    assert _angle_deg(n, np.tile([0.0, 0.0, 1.0], (3000, 1))).mean() < 3.0


def test_viewpoint_orientation(rng):
    p, truth = _sphere(rng, 2000)
    inward = estimate_normals(p, orient="viewpoint", viewpoint=(0, 0, 0))
    assert np.all(np.sum(inward * truth, axis=1) < 0)
    # propagate + viewpoint: the patch faces the viewpoint by majority (outside the sphere -> outwards)
    out = estimate_normals(p, orient="propagate", viewpoint=(0, 0, 10))
    assert np.mean(np.sum(out * truth, axis=1) > 0) > 0.99


def test_two_separate_components_each_outwards(rng):
    a, ta = _sphere(rng, 1500, 0.5, (-3, 0, 0))
    b, tb = _sphere(rng, 1500, 0.5, (3, 0, 0))
    n = estimate_normals(np.r_[a, b], k=12)
    assert np.mean(np.sum(n * np.r_[ta, tb], axis=1) > 0) > 0.99


def test_orientation_propagates_through_flipped_input(rng):
    p, truth = _sphere(rng, 3000)
    flipped = truth * rng.choice([-1.0, 1.0], size=(3000, 1))
    n = orient_normals(p, flipped)
    assert np.all(np.sum(n * truth, axis=1) > 0.99)
    towards = orient_normals(p, flipped, orient="viewpoint", viewpoint=(0, 0, 0))
    assert np.all(np.sum(towards * truth, axis=1) < -0.99)


def test_colinear_points_get_a_deterministic_perpendicular():
    line = np.c_[np.linspace(0, 1, 30), np.linspace(0, 2, 30), np.zeros(30)]
    n = estimate_normals(line)
    d = np.array([1.0, 2.0, 0.0]) / np.sqrt(5)
    assert np.all(np.isfinite(n))
    np.testing.assert_allclose(n @ d, 0.0, atol=1e-9)
    np.testing.assert_allclose(n, np.tile(n[0], (30, 1)), atol=1e-9)  # same perpendicular everywhere
    np.testing.assert_array_equal(n, estimate_normals(line))  # deterministic


def test_degenerate_inputs_never_nan():
    assert estimate_normals(np.zeros((0, 3))).shape == (0, 3)
    np.testing.assert_array_equal(estimate_normals([[1.0, 2.0, 3.0]]), [[0.0, 0.0, 1.0]])
    v = estimate_normals([[1.0, 0.0, 0.0]], viewpoint=(3.0, 0.0, 0.0))
    np.testing.assert_allclose(v, [[1.0, 0.0, 0.0]])
    np.testing.assert_array_equal(estimate_normals(np.ones((7, 3))), np.tile([0.0, 0.0, 1.0], (7, 1)))
    two = estimate_normals([[0, 0, 0], [1, 0, 0]])
    assert np.all(np.isfinite(two)) and np.allclose(two[:, 0], 0.0)
    small = estimate_normals(np.eye(3), k=100)  # k > N
    assert small.shape == (3, 3) and np.all(np.isfinite(small))


def test_coincident_points_share_the_surface_normal(rng):
    xy = rng.uniform(-1, 1, size=(500, 2))
    p = np.c_[xy, np.zeros(500)]
    dup = np.r_[p, np.repeat(p[:5], 40, axis=0)]  # 40 copies of 5 points: more than k
    n = estimate_normals(dup, k=16)
    np.testing.assert_allclose(n, np.tile([0.0, 0.0, 1.0], (len(dup), 1)), atol=1e-6)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    pts=arrays(np.float64, st.tuples(st.integers(1, 40), st.just(3)), elements=st.sampled_from([-1.0, 0.0, 0.5, 2.0])),
    k=st.integers(1, 50),
    orient=st.sampled_from(["propagate", None]),
)
def test_any_point_set_gives_finite_unit_normals(pts, k, orient):
    n = estimate_normals(pts, k=k, orient=orient)
    assert n.shape == pts.shape and np.all(np.isfinite(n))
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-9)


def test_bad_arguments_name_the_argument():
    with pytest.raises(bf.InvalidSceneError, match="points"):
        estimate_normals(np.zeros((4, 2)))
    with pytest.raises(bf.InvalidSceneError, match="points"):
        estimate_normals([[0, 0, np.nan]])
    with pytest.raises(bf.InvalidSceneError, match="k"):
        estimate_normals(np.zeros((4, 3)), k=0)
    with pytest.raises(bf.InvalidSceneError, match="orient"):
        estimate_normals(np.zeros((4, 3)), orient="up")
    with pytest.raises(bf.InvalidSceneError, match="viewpoint"):
        estimate_normals(np.zeros((4, 3)), orient="viewpoint")


def test_normals_from_mesh_sphere(rng):
    mesh = icosphere(3)
    _, truth = _sphere(rng, 3000)
    p = truth * rng.uniform(0.97, 1.03, size=(3000, 1))
    n = normals_from_mesh(p, mesh.vertices, mesh.faces)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)  # L2, not blendify's L1
    assert _angle_deg(n, truth).mean() < 1.0
    nf = normals_from_mesh(p, mesh.vertices, mesh.faces, method="face")
    assert _angle_deg(nf, truth).max() < 15.0


def test_normals_from_mesh_closest_surface_point_not_nearest_vertex():
    # a big quad made of two triangles; points above its middle are far from every vertex
    v = np.array([[-10, -10, 0], [10, -10, 0], [10, 10, 0], [-10, 10, 0], [0, 0, -20]], float)
    f = np.array([[0, 1, 2], [0, 2, 3], [0, 1, 4]])  # plus a steep triangle below
    p = np.array([[0.5, 0.3, 0.1], [-3.0, 4.0, 0.5]])
    n = normals_from_mesh(p, v, f, method="face")
    np.testing.assert_allclose(n, [[0, 0, 1], [0, 0, 1]], atol=1e-12)


def test_normals_from_mesh_accepts_a_renderable():
    scene = bf.Scene()
    sphere = scene.renderables.add_sphere_nurbs(
        1.0, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)), translation=(5, 0, 0)
    )
    p = np.array([[6.2, 0.0, 0.0], [5.0, 0.0, -1.1]])
    n = normals_from_mesh(p, sphere)
    np.testing.assert_allclose(n, [[1, 0, 0], [0, 0, -1]], atol=0.02)
    with pytest.raises(bf.InvalidSceneError, match="mesh_faces"):
        normals_from_mesh(p, np.zeros((3, 3)))
    with pytest.raises(bf.InvalidSceneError, match="mesh_faces"):
        normals_from_mesh(p, np.zeros((3, 3)), [[0, 1, 5]])
    with pytest.raises(bf.InvalidSceneError, match="method"):
        normals_from_mesh(p, np.eye(3), [[0, 1, 2]], method="nearest")
