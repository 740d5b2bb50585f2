"""Renderables: meshes, point clouds, mesh primitives, parametric primitives and curve tubes.

All renderables are positionable (any rotation mode), carry a material (or a list of materials with
``faces_material``) and a colour source, and are two-sided in every backend. Geometry is stored in
OBJECT space, float64 (backends re-centre in float64 before handing float32 to an engine).

``base`` (Renderable), ``mesh``, ``pointcloud``, ``primitives`` (cube, circle, cylinder, plane),
``parametric`` (sphere, ellipsoid, curve) and ``collection`` (RenderablesCollection); every name is
re-exported here.
"""

from __future__ import annotations

from blendify_core.ir.renderables.base import Renderable, _column_bounds
from blendify_core.ir.renderables.collection import RenderablesCollection
from blendify_core.ir.renderables.mesh import Mesh, _check_faces
from blendify_core.ir.renderables.parametric import (
    PARAMETRIC,
    CurveBezier,
    EllipsoidNURBS,
    ParametricPrimitive,
    SphereNURBS,
)
from blendify_core.ir.renderables.pointcloud import PointCloud
from blendify_core.ir.renderables.primitives import (
    FILL_TYPES,
    PRIMITIVES,
    CircleMesh,
    CubeMesh,
    CylinderMesh,
    MeshPrimitive,
    PlaneMesh,
)

_PRIMITIVES = PRIMITIVES  # the names of 0.1 (scene-file code and tests of that time)
_PARAMETRIC = PARAMETRIC

__all__ = [
    "Renderable",
    "Mesh",
    "PointCloud",
    "MeshPrimitive",
    "CubeMesh",
    "CircleMesh",
    "CylinderMesh",
    "PlaneMesh",
    "ParametricPrimitive",
    "SphereNURBS",
    "EllipsoidNURBS",
    "CurveBezier",
    "RenderablesCollection",
    "FILL_TYPES",
    "PRIMITIVES",
    "PARAMETRIC",
    "_column_bounds",
    "_check_faces",
]
