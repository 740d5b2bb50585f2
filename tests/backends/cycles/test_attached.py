"""Attached .blend files: what the IR cannot represent (here hair curves) still renders with Cycles."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import blendify_core as bf

pytestmark = pytest.mark.cycles


def _hair_blend(bpy, path):
    from blendify_blender import session as _runtime

    _runtime.factory_reset()
    sc = bpy.context.scene
    hc = bpy.data.hair_curves.new("hair")
    n = 50
    hc.add_curves([2] * n)
    pos = np.zeros((n, 2, 3), np.float32)
    pos[:, :, 0] = np.linspace(-0.8, 0.8, n)[:, None]
    pos[:, 1, 2] = 1.0
    hc.position_data.foreach_set("vector", pos.ravel())
    rad = hc.attributes.get("radius") or hc.attributes.new("radius", "FLOAT", "POINT")
    rad.data.foreach_set("value", np.full(2 * n, 0.01, np.float32))
    sc.collection.objects.link(bpy.data.objects.new("hair", hc))
    me = bpy.data.meshes.new("ground")
    me.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    sc.collection.objects.link(bpy.data.objects.new("ground", me))
    bpy.data.libraries.write(str(path), {sc}, fake_user=True)
    _runtime.factory_reset()


def test_unparsed_objects_render_from_the_attached_file(cycles, bpy, tmp_path):
    path = tmp_path / "hair.blend"
    _hair_blend(bpy, path)
    scene = bf.Scene()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        added = scene.attach_blend(path)
    assert [r.tag for r in added] == ["ground"]
    scene.set_orthographic_camera(
        (32, 32), ortho_scale=2.4, translation=(0, -3, 0.6), rotation_mode="look_at", rotation=(0, 0, 0.6)
    )
    scene.lights.set_background_light(1.0)
    r = bf.render(scene, backend=cycles, samples=4, outputs=("rgb", "instance"))
    assert r.meta["translation"]["attached_blends"] == 1
    hair = (r.rgba[..., 3] > 0.05) & (r.instance == -1)
    assert hair[8:15].sum() > 20  # the hair strands (z 0..1) above the ground, from the file itself
    names = [o.name for o in bpy.context.scene.objects]
    # the ground is exactly as parsed: it renders from the file too, under its IR index
    assert names.count("hair") == 1 and names.count("ground") == 1
    assert r.meta["translation"]["from_file"]["renderables"] == 1
    assert bpy.context.scene.objects["ground"].pass_index == 1  # the instance output's index (edge-on here)
    cycles.clear()
    assert not any(o.name == "hair" for o in bpy.data.objects)


def test_attached_content_renders_in_the_isolated_worker(cycles, bpy, tmp_path):
    from blendify_blender import CyclesBackend

    path = tmp_path / "hair.blend"
    _hair_blend(bpy, path)
    scene = bf.Scene()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene.attach_blend(path)
    scene.set_orthographic_camera(
        (32, 32), ortho_scale=2.4, translation=(0, -3, 0.6), rotation_mode="look_at", rotation=(0, 0, 0.6)
    )
    scene.lights.set_background_light(1.0)
    local = bf.render(scene, backend=cycles, samples=2)
    with CyclesBackend(isolate=True) as b:
        isolated = bf.render(scene, backend=b, samples=2)
    assert np.array_equal(local.rgba, isolated.rgba)
