"""The glTF export read by Blender's own glTF importer (bpy's io_scene_gltf2): the objects come back under
their tags at their IR poses (the +Y-up root undone), lights in the IR's watts and W/m^2 (the importer's
683 lm/W is the exporter's), Principled parameters through the PBR extensions, the camera's field of view,
linear vertex colours."""

from __future__ import annotations

import math
import warnings

import numpy as np

import blendify_core as bf
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
    if o.type == "MESH" and o.material_slots and o.material_slots[0].material:
        tree = o.material_slots[0].material.node_tree
        bsdf = next((n for n in tree.nodes if n.type == "BSDF_PRINCIPLED"), None)
        if bsdf is not None:
            names = ("Metallic", "Roughness", "IOR", "Transmission Weight", "Coat Weight", "Specular IOR Level")
            item["principled"] = {k: bsdf.inputs[k].default_value for k in names}
    if o.type == "CAMERA":
        out["camera"] = {"name": o.name, "angle_y": o.data.angle_y, "sensor_fit": o.data.sensor_fit,
                         "translation": list(o.matrix_world.translation)}
    out["objects"][o.name] = item
print(json.dumps(out))
"""


def test_blender_imports_the_gltf_as_the_ir_describes_it(tmp_path, bpy_script):
    scene = every_feature_scene((64, 48))
    grey = bf.UniformColors((0.5, 0.5, 0.5))
    glass = bf.PrincipledBSDFMaterial(transmission_weight=0.8, ior=1.5, roughness=0.1)
    scene.renderables.add_cube_mesh(0.2, glass, grey, translation=(0, 1, 0), tag="glass")
    coat = bf.PrincipledBSDFMaterial(coat_weight=0.6, specular_ior=0.3, ior=1.6)
    scene.renderables.add_cube_mesh(0.2, coat, grey, translation=(1, 1, 0), tag="coat")
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
    # Principled parameters come back through pbrMetallicRoughness and the KHR_materials_* extensions
    # (the specular level up to 0.5: glTF's specularFactor stops at 1)
    for tag in ("ground", "cube", "cylinder", "sphere", "ellipsoid", "circle", "curve", "glass", "coat"):
        m = scene.renderables[tag].material
        want = {
            "Metallic": m.metallic,
            "Roughness": m.roughness,
            "IOR": m.ior,
            "Transmission Weight": m.transmission_weight,
            "Coat Weight": m.coat_weight,
            "Specular IOR Level": min(m.specular_ior, 0.5),
        }
        for name, value in want.items():
            assert math.isclose(objects[tag]["principled"][name], value, abs_tol=1e-5), (tag, name)
    cam = got["camera"]
    assert math.isclose(cam["angle_y"], scene.camera.fov_y, rel_tol=1e-5)
    np.testing.assert_allclose(cam["translation"], scene.camera.translation, atol=1e-5)
