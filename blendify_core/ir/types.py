"""Every concrete IR type, grouped by role: what a backend's translator must handle (one handler each).

A backend translator registers a handler for every type listed here (:mod:`blendify_core.pipeline.translator`);
``tests`` check that no backend misses one. A type that is not listed (a user's subclass, say) has no
handler anywhere and is refused by name before any engine sees it.
"""

from __future__ import annotations

from collections.abc import Iterator

from blendify_core.ir.attachments import Attachment
from blendify_core.ir.cameras import OrthographicCamera, PerspectiveCamera
from blendify_core.ir.colors import FileTextureColors, TextureColors, UniformColors, VertexColors
from blendify_core.ir.lights import AreaLight, BackgroundLight, EnvironmentMap, PointLight, SpotLight, SunLight
from blendify_core.ir.materials import (
    DiffuseMaterial,
    GlossyBSDFMaterial,
    MetalMaterial,
    MetalWireframeMaterial,
    PlasticMaterial,
    PlasticWireframeMaterial,
    PrincipledBSDFMaterial,
    PrincipledBSDFWireframeMaterial,
)
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

__all__ = [
    "RENDERABLE_TYPES",
    "LIGHT_TYPES",
    "WORLD_TYPES",
    "CAMERA_TYPES",
    "MATERIAL_TYPES",
    "COLOR_TYPES",
    "ATTACHMENT_TYPES",
    "IR_TYPES",
    "iter_ir_objects",
]

RENDERABLE_TYPES: tuple[type, ...] = (
    Mesh,
    PointCloud,
    CubeMesh,
    CircleMesh,
    CylinderMesh,
    PlaneMesh,
    SphereNURBS,
    EllipsoidNURBS,
    CurveBezier,
)
LIGHT_TYPES: tuple[type, ...] = (PointLight, SunLight, SpotLight, AreaLight)
WORLD_TYPES: tuple[type, ...] = (BackgroundLight, EnvironmentMap)
CAMERA_TYPES: tuple[type, ...] = (PerspectiveCamera, OrthographicCamera)
MATERIAL_TYPES: tuple[type, ...] = (
    PrincipledBSDFMaterial,
    DiffuseMaterial,
    MetalMaterial,
    PlasticMaterial,
    PrincipledBSDFWireframeMaterial,
    PlasticWireframeMaterial,
    MetalWireframeMaterial,
    GlossyBSDFMaterial,
)
COLOR_TYPES: tuple[type, ...] = (UniformColors, VertexColors, TextureColors, FileTextureColors)
ATTACHMENT_TYPES: tuple[type, ...] = (Attachment,)
IR_TYPES: tuple[type, ...] = (
    RENDERABLE_TYPES + LIGHT_TYPES + WORLD_TYPES + CAMERA_TYPES + MATERIAL_TYPES + COLOR_TYPES + ATTACHMENT_TYPES
)


def iter_ir_objects(scene: object) -> Iterator[tuple[object, str]]:
    """Every IR object of ``scene`` with where it is used: renderables, their materials and colour
    sources, lights, the background and environment, the camera and the attachments."""
    for r in scene.renderables:  # type: ignore[attr-defined]
        where = f"renderable {r.tag!r}"
        yield r, where
        for m in r.materials:
            yield m, f"the material of {where}"
        for c in r.colors_list:
            yield c, f"the colours of {where}"
    lights = scene.lights  # type: ignore[attr-defined]
    for light in lights:
        yield light, f"light {light.tag!r}"
    if lights.background is not None:
        yield lights.background, "the background light"
    if lights.environment is not None:
        yield lights.environment, "the environment map"
    if scene.camera is not None:  # type: ignore[attr-defined]
        yield scene.camera, "the camera"  # type: ignore[attr-defined]
    for a in scene.attachments:  # type: ignore[attr-defined]
        yield a, f"the attached {a.format} file {a.path!r}"
