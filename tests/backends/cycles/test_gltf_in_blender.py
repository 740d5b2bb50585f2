"""The glTF export read by Blender's own glTF importer (bpy's io_scene_gltf2): the objects come back under
their tags at their IR poses (the +Y-up root undone), lights in the IR's watts and W/m^2 (the importer's
683 lm/W is the exporter's), the camera's field of view, linear vertex colours."""

from __future__ import annotations

import math
import warnings

import numpy as np

from blendify_core.testing import every_feature_scene

IMPORT_GLTF = """
import bpy, sys, json
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=sys.argv[1])
out = {"objects": {}, "camera": None}
for o in bpy.data.objects:
    item = {"type": o.type, "translation": list(o.matrix_world.translation)}
    if o.type == "LIGHT":
        item.update(light=o.data.type, energy=o.data.energy, color=list(o.data.color))
    if o.type == "MESH":
        corners = [list(o.matrix_world @ v.co) for v in o.data.vertices]
        item["bounds"] = [[f(c[k] for c in corners) for k in range(3)] for f in (min, max)]
        attrs = o.data.color_attributes
        if len(attrs):
            item["colors"] = sorted({tuple(round(x, 3) for x in d.color[:3]) for d in attrs[0].data})
    if o.type == "CAMERA":
        out["camera"] = {"name": o.name, "angle_y": o.data.angle_y, "sensor_fit": o.data.sensor_fit,
                         "translation": list(o.matrix_world.translation)}
    out["objects"][o.name] = item
print(json.dumps(out))
"""


def test_blender_imports_the_gltf_as_the_ir_describes_it(tmp_path, bpy_script):
    scene = every_feature_scene((64, 48))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        path = scene.export(tmp_path / "every.glb")
    got = bpy_script(IMPORT_GLTF, str(path))
    objects = got["objects"]
    for tag, r in scene.renderables.items():
        o = objects[tag]
        assert o["type"] == "MESH", tag
        np.testing.assert_allclose(o["translation"], r.translation, atol=1e-5, err_msg=tag)
        if tag != "points":  # a POINTS primitive: Blender makes loose vertices of the point centres
            lo, hi = r.world_bounds()
            np.testing.assert_allclose(o["bounds"], [lo, hi], atol=1e-4, err_msg=tag)
    wire = scene.renderables["wire_pyramid"].colors.linear_rgba[:, :3]
    want = sorted({tuple(np.round(c, 3)) for c in wire})
    # Blender keeps them as 8-bit sRGB colour attributes: half a step at 0.8 linear is 0.004
    np.testing.assert_allclose(objects["wire_pyramid"]["colors"], want, atol=5e-3)
    expected = {"PointLight": ("POINT", 1.0), "SpotLight": ("SPOT", 1.0), "SunLight": ("SUN", 1.0)}
    for light in scene.lights:
        o = objects[light.tag]
        kind = type(light).__name__
        if kind in expected:  # back in the IR's units: watts, W/m^2
            assert o["light"] == expected[kind][0], light.tag
            assert math.isclose(o["energy"], light.strength, rel_tol=1e-4), (light.tag, o["energy"])
        np.testing.assert_allclose(o["translation"], light.translation, atol=1e-5)
    cam = got["camera"]
    assert math.isclose(cam["angle_y"], scene.camera.fov_y, rel_tol=1e-5)
    np.testing.assert_allclose(cam["translation"], scene.camera.translation, atol=1e-5)
