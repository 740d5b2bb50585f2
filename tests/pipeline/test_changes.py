"""Change detection computed once in the core: what changed since the last translation."""

from __future__ import annotations

import numpy as np

import blendify_core as bf
from blendify_core.ir.attachments import Attachment
from blendify_core.pipeline.changes import ChangeTracker
from blendify_core.testing import every_feature_scene


def test_first_update_then_no_change():
    s = every_feature_scene()
    t = ChangeTracker()
    assert t.update(s).first
    c = t.update(s)
    assert not c.first and not c.any


def test_each_kind_of_change_is_reported_alone():
    s = every_feature_scene()
    t = ChangeTracker()
    t.update(s)
    r = list(s.renderables)[0]
    r.set_position(translation=(0.1, 0.2, 0.3))
    c = t.update(s)
    assert c.moved == (r.uid,) and not c.rebuilt and not c.lights and not c.camera
    r.materials[0].alpha = 0.9  # a DiffuseMaterial: roughness is fixed
    c = t.update(s)
    assert c.rebuilt == (r.uid,) and not c.moved
    r.update_colors(bf.UniformColors((0.1, 0.2, 0.3)))
    assert t.update(s).rebuilt == (r.uid,)
    light = list(s.lights)[0]
    light.strength = light.strength * 2
    c = t.update(s)
    assert c.lights and not c.world and not c.rebuilt
    s.lights.set_background_light(0.4)
    c = t.update(s)
    assert c.world and not c.lights
    s.camera.set_position(translation=(4.0, -4.0, 3.0))
    c = t.update(s)
    assert c.camera and c.geometry_only_camera
    s.attachments.append(Attachment("blend", "/tmp/x.blend"))
    assert t.update(s).attachments


def test_added_removed_and_reordered():
    s = every_feature_scene()
    t = ChangeTracker()
    t.update(s)
    first = list(s.renderables)[0]
    s.renderables.remove(first)
    c = t.update(s)
    assert c.removed == (first.uid,) and not c.added
    new = s.renderables.add_sphere_nurbs(0.2, bf.DiffuseMaterial(), bf.UniformColors((1, 0, 0)))
    c = t.update(s)
    assert c.added == (new.uid,)


def test_peek_does_not_record_and_reset_starts_over():
    s = every_feature_scene()
    t = ChangeTracker()
    t.update(s)
    s.camera.set_position(translation=(1.0, 2.0, 3.0))
    assert t.peek(s).camera and t.peek(s).camera
    assert t.update(s).camera and not t.update(s).camera
    t.reset()
    assert t.update(s).first


def test_geometry_change_of_a_mesh_is_a_rebuild():
    s = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    m = s.renderables.add_mesh(v, np.array([[0, 1, 2]]), bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)))
    t = ChangeTracker()
    t.update(s)
    m.update_vertices(v * 2)
    assert t.update(s).rebuilt == (m.uid,)


def test_a_camera_copy_is_no_change_but_a_clip_change_is():
    s = every_feature_scene()
    t = ChangeTracker()
    t.update(s)
    view = s.with_camera(s.camera.copy())
    assert not t.update(view).camera
    s.camera.near = s.camera.near * 0.5
    assert t.update(s).camera


def test_a_texture_file_rewritten_between_renders_is_a_rebuild(tmp_path):
    from PIL import Image

    path = tmp_path / "tex.png"
    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(path)
    s = bf.Scene()
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    uv = bf.VertexUV(np.array([[0, 0], [1, 0], [0, 1]], float))
    m = s.renderables.add_mesh(v, np.array([[0, 1, 2]]), bf.DiffuseMaterial(), bf.FileTextureColors(path, uv))
    t = ChangeTracker()
    t.update(s)
    assert not t.update(s).rebuilt
    Image.fromarray(np.full((4, 4, 3), 255, np.uint8)).save(path)
    import os

    st = os.stat(path)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000))
    assert t.update(s).rebuilt == (m.uid,)


def test_environment_rotation_or_replacement_is_a_world_change():
    s = every_feature_scene()
    s.lights.set_environment_map(np.ones((4, 8, 3), np.float32), 1.0)
    t = ChangeTracker()
    t.update(s)
    s.lights.set_environment_map(np.ones((4, 8, 3), np.float32), 1.0, rotation=(0.9238795, 0.0, 0.0, 0.3826834))
    assert t.update(s).world
    s.lights.set_environment_map(np.zeros((4, 8, 3), np.float32), 1.0)  # a new map, maybe at a reused address
    assert t.update(s).world
