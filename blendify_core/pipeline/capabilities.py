"""Names of the IR features a backend declares in its capability table, and which ones a scene uses.

A backend's ``capabilities()`` maps every name in :data:`ALL_FEATURES` to a :class:`Capability`:
"exact", "approximate" (with a note saying how) or "unsupported" (with a reason). The core checks a
scene's features against that table before calling the backend: approximations are listed in
``result.meta["approximations"]`` (and raise with ``strict=True``); unsupported features raise
:class:`~blendify_core.errors.UnsupportedFeatureError` naming the feature and the backend.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.cameras import PerspectiveCamera
from blendify_core.ir.colors import FileTextureColors, TextureColors, VertexColors
from blendify_core.ir.lights import AreaLight, PointLight, SpotLight, SunLight
from blendify_core.ir.physics import material_lobes
from blendify_core.ir.renderables import (
    CircleMesh,
    CubeMesh,
    CurveBezier,
    CylinderMesh,
    EllipsoidNURBS,
    Mesh,
    PlaneMesh,
    PointCloud,
    SphereNURBS,
)
from blendify_core.ir.scene import Scene
from blendify_core.ir.validate import strict_api

__all__ = ["Capability", "ALL_FEATURES", "scene_features"]

ALL_FEATURES: dict[str, str] = {
    "mesh": "triangle meshes with uniform colours",
    "mesh.vertex_colors": "per-vertex colours on meshes",
    "mesh.texture": "in-memory texture colours (VertexUV or FacesUV)",
    "mesh.file_texture": "texture colours read from a file",
    "mesh.faces_material": "per-face materials",
    "mesh.smooth": "smooth shading (interpolated vertex normals)",
    "pointcloud": "point clouds as spheres of diameter point_size",
    "pointcloud.vertex_colors": "per-point colours",
    "pointcloud.emission": "self-illuminated points (particle_emission_strength > 0)",
    "primitive.cube": "cube primitive",
    "primitive.circle": "circle (disc) primitive",
    "primitive.cylinder": "cylinder primitive",
    "primitive.plane": "plane primitive",
    "primitive.sphere": "sphere primitive",
    "primitive.ellipsoid": "ellipsoid primitive",
    "primitive.curve": "curve tube primitive",
    "shadow_catcher": "shadow-catcher planes",
    "object.no_shadow": "objects that cast no shadow (emit_shadows=False)",
    "material.principled": "Principled BSDF (dielectric specular layer)",
    "material.diffuse_only": "Principled with no specular layer (Lambertian)",
    "material.metallic": "metallic Principled",
    "material.glossy": "Glossy BSDF",
    "material.transmission": "transmission / glass (transmission_weight > 0)",
    "material.coat": "clear coat (coat_weight > 0)",
    "material.sheen": "sheen (sheen_weight > 0)",
    "material.subsurface": "subsurface scattering (subsurface_weight > 0)",
    "material.emission": "emissive materials",
    "material.alpha": "alpha < 1 (material alpha or colour alpha)",
    "material.wireframe": "wireframe overlays",
    "material.roughness_map": "texture-driven roughness",
    "material.metallic_map": "texture-driven metallic",
    "material.normal_map": "normal maps",
    "light.point": "point lights",
    "light.point.soft": "point/spot lights with a radius (shadow_soft_size > 0)",
    "light.sun": "sun lights",
    "light.sun.soft": "sun lights with an angular diameter > 0",
    "light.spot": "spot lights",
    "light.spot.blend": "spot lights with spot_blend > 0 (soft cone edge)",
    "light.area": "rectangular area lights (square, rectangle)",
    "light.area.disk": "round area lights (circle, ellipse)",
    "light.no_shadow": "lights that cast no shadow (use_shadow=False)",
    "light.background": "uniform background light",
    "light.environment": "environment maps (HDRI)",
    "camera.perspective": "pinhole cameras",
    "camera.orthographic": "orthographic cameras",
    "camera.anisotropic": "non-square pixels (fx != fy)",
    "output.rgb": "colour output",
    "output.depth": "planar depth output",
    "output.normal": "world-space normal output",
    "output.albedo": "albedo output",
    "output.instance": "instance id output",
}


@strict_api
@dataclass(frozen=True)
class Capability:
    """How a backend handles one feature: ``level`` is "exact", "approximate" or "unsupported"."""

    level: str
    note: str = ""

    def __post_init__(self) -> None:
        if self.level not in ("exact", "approximate", "unsupported"):
            raise InvalidSceneError(f"Capability.level: expected exact/approximate/unsupported, got {self.level!r}")


def scene_features(scene: Scene, outputs: tuple[str, ...] = ("rgb",)) -> dict[str, str]:
    """The features a scene (and the requested outputs) use: feature name -> the first object using it."""
    used: dict[str, str] = {}

    def add(name: str, where: str) -> None:
        used.setdefault(name, where)

    for r in scene.renderables:
        where = f"renderable {r.tag!r}"
        if isinstance(r, Mesh):
            add("mesh", where)
            if r.smooth:
                add("mesh.smooth", where)
            if r.polygon_faces_material is not None and len(r.materials) > 1:
                add("mesh.faces_material", where)
        elif isinstance(r, PointCloud):
            add("pointcloud", where)
            if r.particle_emission_strength > 0:
                add("pointcloud.emission", where)
        elif isinstance(r, CubeMesh):
            add("primitive.cube", where)
        elif isinstance(r, CircleMesh):
            add("primitive.circle", where)
        elif isinstance(r, CylinderMesh):
            add("primitive.cylinder", where)
        elif isinstance(r, PlaneMesh):
            add("primitive.plane", where)
            if r.shadow_catcher:
                add("shadow_catcher", where)
        elif isinstance(r, SphereNURBS):
            add("primitive.sphere", where)
        elif isinstance(r, EllipsoidNURBS):
            add("primitive.ellipsoid", where)
        elif isinstance(r, CurveBezier):
            add("primitive.curve", where)
        if not r.emit_shadows:
            add("object.no_shadow", where)
        if len(r.materials) > 1 and not isinstance(r, Mesh):
            add("mesh.faces_material", where)
        for c in r.colors_list:
            if isinstance(c, VertexColors):
                add("pointcloud.vertex_colors" if isinstance(r, PointCloud) else "mesh.vertex_colors", where)
            elif isinstance(c, TextureColors):
                add("mesh.texture", where)
            elif isinstance(c, FileTextureColors):
                add("mesh.file_texture", where)
            if getattr(c, "has_alpha", False):
                add("material.alpha", where)
        for m in r.materials:
            lobes = material_lobes(m)
            if m.kind == "glossy":
                add("material.glossy", where)
            elif lobes.diffuse_only:
                add("material.diffuse_only", where)
            else:
                add("material.principled", where)
            for flag, feat in (
                (lobes.metallic, "material.metallic"),
                (lobes.transmission, "material.transmission"),
                (lobes.coat, "material.coat"),
                (lobes.sheen, "material.sheen"),
                (lobes.subsurface, "material.subsurface"),
                (lobes.emission, "material.emission"),
                (lobes.alpha, "material.alpha"),
            ):
                if flag:
                    add(feat, where)
            if m.has_wireframe:
                add("material.wireframe", where)
            for key in ("roughness_map", "metallic_map", "normal_map"):
                if getattr(m, key, None) is not None:
                    add(f"material.{key}", where)
    for light in scene.lights:
        where = f"light {light.tag!r}"
        if light.strength <= 0:
            continue
        if isinstance(light, PointLight):
            add("light.point", where)
            if light.shadow_soft_size > 0:
                add("light.point.soft", where)
        elif isinstance(light, SunLight):
            add("light.sun", where)
            if light.angular_diameter > 0:
                add("light.sun.soft", where)
        elif isinstance(light, SpotLight):
            add("light.spot", where)
            if light.shadow_soft_size > 0:
                add("light.point.soft", where)
            if light.spot_blend > 0:
                add("light.spot.blend", where)
        elif isinstance(light, AreaLight):
            add("light.area.disk" if light.shape in ("circle", "ellipse") else "light.area", where)
        if not light.use_shadow:
            add("light.no_shadow", where)
    if scene.lights.background is not None and scene.lights.background.strength > 0:
        add("light.background", "background light")
    if scene.lights.environment is not None and scene.lights.environment.strength > 0:
        add("light.environment", "environment map")
    cam = scene.camera
    if cam is not None:
        add(f"camera.{cam.kind}", "camera")
        if isinstance(cam, PerspectiveCamera) and not np.isclose(cam.fx, cam.fy, rtol=1e-9):
            add("camera.anisotropic", "camera")
    for o in outputs:
        add(f"output.{o}", "outputs")
    return used
