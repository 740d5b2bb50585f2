"""blendify-core: describe a scene once in numpy, render it with Blender Cycles, Mitsuba 3 or pyrender.

Importing this package loads numpy and scipy only; engines are imported by their backends on first use.
"""

from __future__ import annotations

from .backend import (
    Backend,
    BackendStatus,
    Capability,
    available_backends,
    backend_names,
    close_backends,
    get_backend,
    get_backend_class,
    register_backend,
)
from .batch import BatchReport, RenderJob, render_many
from .cameras import Camera, OrthographicCamera, PerspectiveCamera
from .colors import (
    FacesUV,
    FileTextureColors,
    NormalMap,
    TextureColors,
    TextureMap,
    UniformColors,
    VertexColors,
    VertexUV,
)
from .compare import CompareReport, CrosscheckReport, compare, crosscheck
from .effects import Effects, analyse_effects
from .errors import (
    BackendUnavailableError,
    BlendifyError,
    InvalidSceneError,
    OutputError,
    RenderError,
    UnsupportedFeatureError,
)
from .lights import (
    AreaLight,
    BackgroundLight,
    EnvironmentMap,
    PointLight,
    SpotLight,
    SunLight,
)
from .materials import (
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
from .render import render
from .renderables import (
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
from .result import RenderResult
from .scene import Scene
from .settings import RenderSettings, resolve_settings
from .utils.animation import render_frames as render_frames

__version__ = "0.1.0"

__all__ = [
    "__version__",
    "Scene",
    "render",
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
]
