"""The realistic benchmark scenes of blendify_core.testing (accuracy_vs_time at realistic size): they build
(every input is validated on construction), are deterministic, survive scene files (validated again on
load), and are what their docstrings say."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf
from blendify_core import testing

pytest.importorskip("trimesh", reason="trimesh is not installed")

BUILDERS = {
    "textured_scan": testing.textured_scan_scene,
    "cornell_room": testing.cornell_room_scene,
    "pointcloud_catcher": testing.pointcloud_catcher_scene,
}


@pytest.mark.parametrize("name", sorted(BUILDERS))
def test_realistic_scene_builds_validates_and_round_trips(tmp_path, name):
    a, b = BUILDERS[name]((40, 30)), BUILDERS[name]((40, 30))
    assert a.camera is not None and tuple(a.camera.resolution) == (40, 30)
    assert a.fingerprint() == b.fingerprint()
    a.save(tmp_path / f"{name}.npz")
    assert bf.Scene.load(tmp_path / f"{name}.npz").fingerprint() == a.fingerprint()


def test_cornell_room_is_closed_with_one_light_and_the_camera_inside():
    s = testing.cornell_room_scene((32, 32))
    walls = [s.renderables[t] for t in ("floor", "ceiling", "back_wall", "front_wall", "red_wall", "green_wall")]
    lo = np.min([w.vertices.min(axis=0) for w in walls], axis=0)
    hi = np.max([w.vertices.max(axis=0) for w in walls], axis=0)
    assert np.allclose(lo, (-1, -1, 0)) and np.allclose(hi, (1, 1, 2))
    centre = (lo + hi) / 2
    for w in walls:  # every wall faces into the room
        v = w.vertices
        n = np.cross(v[1] - v[0], v[2] - v[0])
        assert float(n @ (centre - v.mean(axis=0))) > 0
    assert len(s.lights) == 1 and s.lights.background is None
    assert bf.analyse_effects(s).indirect_diffuse
    assert np.all(s.camera.translation > lo) and np.all(s.camera.translation < hi)


def test_textured_scan_has_a_texture_and_stands_on_the_table():
    s = testing.textured_scan_scene((32, 32))
    fuze = s.renderables["fuze"]
    assert isinstance(fuze.colors, bf.TextureColors)
    zmin = float((fuze.vertices + np.asarray(fuze.translation)).min(axis=0)[2])
    assert abs(zmin) < 1e-6


def test_pointcloud_catcher_stands_on_a_shadow_catcher():
    s = testing.pointcloud_catcher_scene((32, 32), n=500)
    assert s.renderables["catcher"].shadow_catcher
    pts = s.renderables["points"].vertices
    assert len(pts) == 500 and np.isclose(pts[:, 2].min(), 0.0, atol=1e-3)
