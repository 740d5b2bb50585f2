"""The Cycles capability table: declared beside the translator's handlers, identical to the table of
before the translator refactor (a frozen copy: feature -> (level, note))."""

from __future__ import annotations

import pytest
from blendify_blender import CyclesBackend

from blendify_core.pipeline.capabilities import ALL_FEATURES

pytestmark = pytest.mark.cycles

_SPHERE = "the IR's shared tessellation (64x32 UV sphere, exact normals)"
#: the table as it was before the capabilities moved next to the handlers (issue 14): do not edit to make
#: a test pass -- a change here is a behaviour change of the backend
FROZEN: dict[str, tuple[str, str]] = {
    "mesh": ("exact", ""),
    "mesh.vertex_colors": ("exact", ""),
    "mesh.texture": ("exact", ""),
    "mesh.file_texture": ("exact", ""),
    "mesh.faces_material": ("exact", ""),
    "mesh.smooth": ("exact", "the IR's angle-weighted vertex normals as custom normals"),
    "pointcloud": ("exact", "native Cycles points (Geometry Nodes Mesh to Points)"),
    "pointcloud.vertex_colors": ("exact", ""),
    "pointcloud.emission": ("exact", ""),
    "primitive.cube": ("exact", ""),
    "primitive.circle": ("exact", ""),
    "primitive.cylinder": ("exact", ""),
    "primitive.plane": ("exact", ""),
    "primitive.sphere": ("exact", _SPHERE),
    "primitive.ellipsoid": ("exact", "the IR's shared tessellation (64x32, exact normals)"),
    "primitive.curve": (
        "exact",
        "the IR's tessellation (tube along the polyline, flat caps), the mesh Mitsuba and pyrender render",
    ),
    "shadow_catcher": ("exact", ""),
    "object.no_shadow": ("exact", ""),
    "material.principled": ("exact", ""),
    "material.diffuse_only": ("exact", ""),
    "material.metallic": ("exact", ""),
    "material.glossy": ("exact", ""),
    "material.transmission": ("exact", ""),
    "material.coat": ("exact", ""),
    "material.sheen": ("exact", ""),
    "material.subsurface": ("exact", ""),
    "material.emission": ("exact", ""),
    "material.alpha": ("exact", ""),
    "material.wireframe": ("exact", ""),
    "material.roughness_map": ("exact", ""),
    "material.metallic_map": ("exact", ""),
    "material.normal_map": ("exact", ""),
    "light.point": ("exact", ""),
    "light.point.soft": ("exact", "sphere light, soft falloff off (matches a sphere emitter)"),
    "light.sun": ("exact", ""),
    "light.sun.soft": ("exact", ""),
    "light.spot": ("exact", ""),
    "light.spot.blend": ("exact", "Blender's own smoothstep cone edge"),
    "light.area": ("exact", ""),
    "light.area.disk": ("exact", ""),
    "light.no_shadow": ("exact", ""),
    "light.background": ("exact", ""),
    "light.environment": ("exact", ""),
    "camera.perspective": ("exact", ""),
    "camera.orthographic": ("exact", ""),
    "camera.anisotropic": ("exact", "pixel aspect ratio"),
    "output.rgb": ("exact", ""),
    "output.depth": ("exact", "Cycles Z pass (one sample per pixel, not anti-aliased)"),
    "output.normal": ("exact", ""),
    "output.albedo": ("exact", "material colour input through a shader AOV"),
    "output.instance": ("exact", "object index pass (not anti-aliased)"),
}


def test_frozen_copy_names_every_feature():
    assert set(FROZEN) == set(ALL_FEATURES)


def test_capability_table_equals_the_frozen_copy():
    caps = CyclesBackend.capabilities()
    assert set(caps) == set(ALL_FEATURES)
    assert {k: (c.level, c.note) for k, c in caps.items()} == FROZEN
