"""approximate_colors_from_camera: back-facing points get back_color, per-point view directions."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.utils import approximate_colors_from_camera


def test_view_direction_vector_blendify_behaviour():
    normals = np.array([[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0]])
    colors = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    out = approximate_colors_from_camera(np.array([0, 0, -1.0]), normals, colors)
    assert out.shape == (3, 4) and out.dtype == np.float32
    np.testing.assert_allclose(out[0], [1, 0, 0, 1])
    np.testing.assert_allclose(out[1], [0.6, 0.6, 0.6, 1])  # faces away (normal along the view direction)
    np.testing.assert_allclose(out[2], [0, 0, 1, 1])  # silhouette counts as front


def test_camera_object_and_per_point_directions():
    scene = bf.Scene()
    cam = scene.set_perspective_camera((64, 64), fov_x=1.5, translation=(0, 0, 5))  # looks down -Z
    # a point far to the side with a normal facing +X: the optical axis says "silhouette" (front), but
    # seen from the camera the point's normal points away
    pts = np.array([[-4.0, 0.0, 0.0], [4.0, 0.0, 0.0]])
    normals = np.array([[-1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    colors = np.array([[1.0, 0.0, 0.0, 1.0]] * 2)
    axis_only = approximate_colors_from_camera(cam, normals, colors, back_color=(0, 0, 0, 0))
    np.testing.assert_allclose(axis_only[:, 3], [1, 1])
    per_point = approximate_colors_from_camera(cam, normals, colors, back_color=(0, 0, 0, 0), points=pts)
    np.testing.assert_allclose(per_point, [[0, 0, 0, 0], [1, 0, 0, 1]])  # alpha 0 hides the back point


def test_orthographic_uses_the_axis_and_uint8_colours():
    scene = bf.Scene()
    cam = scene.set_orthographic_camera((32, 32), ortho_scale=4, translation=(0, 0, 5))
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    out = approximate_colors_from_camera(cam, normals, np.array([255, 0, 0], np.uint8), points=np.zeros((2, 3)))
    np.testing.assert_allclose(out, [[1, 0, 0, 1], [0.6, 0.6, 0.6, 1]], atol=1e-6)


def test_bad_inputs():
    n = np.zeros((2, 3))
    with pytest.raises(bf.InvalidSceneError, match="colors"):
        approximate_colors_from_camera(np.array([0, 0, 1.0]), n, np.zeros((3, 3)))
    with pytest.raises(bf.InvalidSceneError, match="back_color"):
        approximate_colors_from_camera(np.array([0, 0, 1.0]), n, np.zeros((2, 3)), back_color=(1, 2))
    with pytest.raises(bf.InvalidSceneError, match="camera"):
        approximate_colors_from_camera(np.zeros(3), n, np.zeros((2, 3)))
    with pytest.raises(bf.InvalidSceneError, match="points"):
        approximate_colors_from_camera(np.array([0, 0, 1.0]), n, np.zeros((2, 3)), points=np.zeros((2, 3)))
