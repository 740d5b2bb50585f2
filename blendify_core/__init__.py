"""blendify-core: describe a scene once in numpy, render it with Blender Cycles, Mitsuba 3 or pyrender.

Importing this package loads numpy and scipy only; engines are imported by their backends on first use.
"""

from __future__ import annotations

import logging

from blendify_core.batch.run import BatchReport, RenderJob, render_many
from blendify_core.errors import (
    BackendUnavailableError,
    BlendifyError,
    InvalidSceneError,
    OutputError,
    RenderError,
    UnsupportedFeatureError,
)
from blendify_core.evaluate.compare import compare
from blendify_core.evaluate.crosscheck import crosscheck
from blendify_core.evaluate.report import CompareReport, CrosscheckReport
from blendify_core.ir.cameras import Camera, OrthographicCamera, PerspectiveCamera
from blendify_core.ir.colors import (
    FacesUV,
    FileTextureColors,
    NormalMap,
    TextureColors,
    TextureMap,
    UniformColors,
    VertexColors,
    VertexUV,
)
from blendify_core.ir.lights import (
    AreaLight,
    BackgroundLight,
    EnvironmentMap,
    PointLight,
    SpotLight,
    SunLight,
)
from blendify_core.ir.materials import (
    DiffuseMaterial,
    GlossyBSDFMaterial,
    Material,
    MetalMaterial,
    MetalWireframeMaterial,
    PlasticMaterial,
    PlasticWireframeMaterial,
    PrincipledBSDFMaterial,
    PrincipledBSDFWireframeMaterial,
)
from blendify_core.ir.params import BlenderClampWarning
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
from blendify_core.pipeline.backend import Backend, Capability
from blendify_core.pipeline.cost import CostEstimate, estimate_cost
from blendify_core.pipeline.effects import Effects, analyse_effects
from blendify_core.pipeline.render import render
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import FINAL_TARGET_ERROR, RenderSettings, resolve_settings
from blendify_core.registry import (
    BackendStatus,
    available_backends,
    backend_names,
    close_backends,
    get_backend,
    get_backend_class,
    register_backend,
)
from blendify_core.utils.animation import render_frames as render_frames

# a library logs, the application decides where to: no "No handlers could be found" output by default
logging.getLogger("blendify_core").addHandler(logging.NullHandler())

__version__ = "0.1.0"

__all__ = [
    "__version__",
    "Scene",
    "render",
    "estimate_cost",
    "CostEstimate",
    "render_many",
    "render_frames",
    "RenderJob",
    "BatchReport",
    "compare",
    "crosscheck",
    "CompareReport",
    "CrosscheckReport",
    "RenderResult",
    "RenderSettings",
    "FINAL_TARGET_ERROR",
    "resolve_settings",
    "Effects",
    "analyse_effects",
    "Backend",
    "BackendStatus",
    "Capability",
    "available_backends",
    "backend_names",
    "close_backends",
    "get_backend",
    "get_backend_class",
    "register_backend",
    "Camera",
    "PerspectiveCamera",
    "OrthographicCamera",
    "UniformColors",
    "VertexColors",
    "TextureColors",
    "FileTextureColors",
    "VertexUV",
    "FacesUV",
    "TextureMap",
    "NormalMap",
    "Material",
    "PrincipledBSDFMaterial",
    "DiffuseMaterial",
    "GlossyBSDFMaterial",
    "MetalMaterial",
    "PlasticMaterial",
    "PrincipledBSDFWireframeMaterial",
    "PlasticWireframeMaterial",
    "MetalWireframeMaterial",
    "PointLight",
    "SunLight",
    "SpotLight",
    "AreaLight",
    "BackgroundLight",
    "EnvironmentMap",
    "Mesh",
    "PointCloud",
    "CubeMesh",
    "CircleMesh",
    "CylinderMesh",
    "PlaneMesh",
    "SphereNURBS",
    "EllipsoidNURBS",
    "CurveBezier",
    "BlendifyError",
    "InvalidSceneError",
    "UnsupportedFeatureError",
    "BackendUnavailableError",
    "RenderError",
    "OutputError",
    "BlenderClampWarning",
]
