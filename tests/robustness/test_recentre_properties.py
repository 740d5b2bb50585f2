"""Property tests of the core re-centring (blendify_core/recentre.py) with stated error bounds.

For scenes at any offset (up to 1e8 m) and scale (1e-3 to 1e3 m), given in object coordinates or in
world coordinates: the re-centred view a backend receives
- keeps every vertex's camera-space position (float64, |error| <= 1e-12 x the largest coordinate),
- hands the engine small numbers (every coordinate <= 2 x the scene size: float32 then resolves
  ~1e-6 of the scene size, whatever the offset),
- leaves the original scene untouched (same arrays, same revisions).
"""

from __future__ import annotations

import numpy as np
from hypothesis import event, given, settings
from hypothesis import strategies as st

import blendify_core as bf
from blendify_core.pipeline.recentre import FAR_RATIO, needs_recentring, recentred_view

SETTINGS = settings(max_examples=300, deadline=None)

offsets = st.tuples(*[st.floats(-1e8, 1e8, allow_nan=False, allow_infinity=False)] * 3).map(np.array)
scales = st.floats(1e-3, 1e3)
unit = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
directions = st.tuples(unit, unit, unit).filter(lambda d: np.linalg.norm(d) > 0.2).map(np.array)


def _scene(offset: np.ndarray, scale: float, direction: np.ndarray, world_vertices: bool) -> bf.Scene:
    scene = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float) * scale
    faces = [[0, 1, 2], [0, 1, 3], [1, 2, 4]]
    material, colors = bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5))
    if world_vertices:
        scene.renderables.add_mesh(v + offset, faces, material, colors, tag="mesh")
    else:
        scene.renderables.add_mesh(v, faces, material, colors, translation=offset, tag="mesh")
    scene.renderables.add_pointcloud(v + offset, material, colors, point_size=0.1 * scale, tag="points")
    scene.renderables.add_curve_nurbs(v[:4] + offset, 0.05 * scale, material, colors, tag="curve")
    cam_pos = offset + direction / np.linalg.norm(direction) * 4.0 * scale
    scene.set_perspective_camera(
        (16, 16), fov_x=0.8, rotation_mode="look_at", rotation=offset, translation=cam_pos, near=1e-3 * scale
    )
    scene.lights.add_point(100.0, translation=cam_pos)
    return scene


def _world_points(r) -> np.ndarray:
    for attr in ("_vertices", "keypoints"):
        v = getattr(r, attr, None)
        if v is not None:
            m = r.matrix_world
            return np.asarray(v, float) @ m[:3, :3].T + m[:3, 3]
    raise AssertionError(f"{r.tag}: no vertices")


@SETTINGS
@given(offsets, scales, directions, st.booleans())
def test_recentred_view_keeps_camera_space_geometry(offset, scale, direction, world_vertices):
    """Offsets to 1e8 m, scales 1e-3..1e3: camera-space error <= 1e-12 x offset, engine coordinates <= 2 sizes."""
    scene = _scene(offset, scale, direction, world_vertices)
    before = {
        r.tag: (_world_points(r).copy(), r.revision("transform"), r.revision("geometry")) for r in scene.renderables
    }
    magnitude = max(float(np.abs(offset).max()), scale)
    # the scene's size (bounds diagonal, camera distance) is < 8 x scale; the origin snaps to a grid of up to
    # twice that, so the engine's numbers stay within 2 sizes
    size = 16.0 * scale
    if not needs_recentring(scene):
        event("not re-centred")
        assert magnitude <= FAR_RATIO * size, "a far scene was not re-centred"
        return
    event("re-centred")
    view, origin = recentred_view(scene)
    assert np.all(np.isfinite(origin))
    for r, rv in zip(scene.renderables, view.renderables, strict=True):
        original = scene.camera.world_to_camera_cv(_world_points(r))
        moved = view.camera.world_to_camera_cv(_world_points(rv))
        err = np.abs(original - moved).max()
        assert err <= 1e-12 * magnitude + 1e-12 * scale, f"{r.tag}: camera-space error {err:.3g}"
        # what an engine receives: the object's translation and its vertices, both small
        m = rv.matrix_world
        engine = np.abs(np.concatenate([_world_points(rv).ravel(), m[:3, 3]])).max()
        assert engine <= size, f"{r.tag}: the engine still gets coordinates of {engine:.3g} (scene size {size:.3g})"
    assert np.abs(view.camera.translation).max() <= size
    for light, lv in zip(scene.lights, view.lights, strict=True):
        np.testing.assert_allclose(lv.translation + origin, light.translation, rtol=0, atol=1e-12 * magnitude)
    for r in scene.renderables:  # the original is untouched
        pts, rev_t, rev_g = before[r.tag]
        np.testing.assert_array_equal(_world_points(r), pts)
        assert r.revision("transform") == rev_t and r.revision("geometry") == rev_g


@SETTINGS
@given(st.tuples(unit, unit, unit).map(np.array), scales, directions)
def test_scenes_near_the_origin_are_not_recentred(position, scale, direction):
    """No needless work: a scene within 10 sizes of the origin is handed over as it is."""
    assert not needs_recentring(_scene(position * 10.0 * scale, scale, direction, world_vertices=True))
