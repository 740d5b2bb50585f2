"""Parametric primitives, kept parametric (backends may render them analytically): sphere, ellipsoid, tube."""

from __future__ import annotations

from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.errors import describe as _describe
from blendify_core.ir.geometry import TriMesh, tube_along_polyline, uv_sphere
from blendify_core.ir.renderables.base import Renderable
from blendify_core.ir.renderables.primitives import _RADIUS
from blendify_core.ir.transforms import ValidatedParam
from blendify_core.ir.validate import as_array, as_bool, as_float
from blendify_core.typing import AnyArray

__all__ = ["ParametricPrimitive", "SphereNURBS", "EllipsoidNURBS", "CurveBezier", "PARAMETRIC"]


class ParametricPrimitive(Renderable):
    """Sphere, ellipsoid and curve tube: one material and one UniformColors; always smooth."""

    @property
    def smooth(self) -> bool:
        """Always True: parametric primitives are smooth-shaded."""
        return True

    @smooth.setter
    def smooth(self, value: bool) -> None:
        self.set_smooth(value)

    def set_smooth(self, smooth: bool = True) -> None:
        if not as_bool("smooth", smooth):
            raise InvalidSceneError(f"smooth: a {type(self).__name__} is always smooth-shaded")

    def to_dict(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
        d = self._base_dict(arrays, prefix)
        d["params"] = self._params(arrays, prefix)
        return d

    def _params(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:  # pragma: no cover
        raise NotImplementedError


class SphereNURBS(ParametricPrimitive):
    """A sphere of ``radius`` centred at its origin (analytic where the engine has spheres)."""

    kind = "sphere"
    prefix = "Sphere"
    radius = _RADIUS

    def __init__(self, radius: float, material: Any, colors: Any, tag: str = "", **pose: Any):
        self.radius = as_float("radius", radius, min_value=0.0, exclusive_min=True)
        super().__init__(material, colors, tag, **pose)

    def to_mesh(self, segments: int = 64, rings: int = 32) -> TriMesh:
        return uv_sphere(self.radius, segments, rings)

    def world_bounds(self) -> tuple[AnyArray, AnyArray]:
        """The sphere's own bounds (centre +- radius; no tessellation)."""
        return self.translation - self.radius, self.translation + self.radius

    def _params(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
        return {"radius": self.radius}


class EllipsoidNURBS(ParametricPrimitive):
    """An axis-aligned ellipsoid with semi-axes ``radius`` = (rx, ry, rz) in object space."""

    kind = "ellipsoid"
    prefix = "Ellipsoid"

    @staticmethod
    def _check_radius(obj: Any, name: str, value: Any) -> AnyArray:
        r = as_array(name, value, shape=(3,))
        if np.any(r <= 0):
            raise InvalidSceneError(f"{name}: expected three positive semi-axes, got {r.tolist()}")
        return r

    radius = ValidatedParam(_check_radius, "geometry", "Semi-axes (rx, ry, rz) in object space.")

    def __init__(self, radius: Any, material: Any, colors: Any, tag: str = "", **pose: Any):
        self.radius = radius
        super().__init__(material, colors, tag, **pose)

    def world_bounds(self) -> tuple[AnyArray, AnyArray]:
        """The rotated ellipsoid's own bounds (no tessellation): along world axis i, the half extent is the
        norm of row i of rotation x diag(radius)."""
        half = np.linalg.norm(self.rotation_matrix * np.asarray(self.radius, dtype=np.float64), axis=1)
        return self.translation - half, self.translation + half

    def to_mesh(self, segments: int = 64, rings: int = 32) -> TriMesh:
        m = uv_sphere(1.0, segments, rings)
        m.vertices = m.vertices * self.radius
        n = m.normals / self.radius
        m.normals = n / np.linalg.norm(n, axis=1, keepdims=True)
        return m

    def _params(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
        return {"radius": self.radius.tolist()}


class CurveBezier(ParametricPrimitive):
    """A tube of ``radius`` through ``keypoints`` (K >= 2, a polyline, as blendify's curves), closed with
    flat caps."""

    kind = "curve"
    prefix = "Curve"

    @staticmethod
    def _check_keypoints(obj: Any, name: str, value: Any) -> AnyArray:
        k = as_array(name, value, ndim=2)
        if k.shape[1] != 3 or k.shape[0] < 2:
            raise InvalidSceneError(f"{name}: expected shape (K >= 2, 3), got {_describe(k)}")
        if np.all(np.linalg.norm(k - k[0], axis=1) <= 1e-12 * max(1.0, float(np.abs(k).max()))):
            raise InvalidSceneError(f"{name}: all keypoints coincide; a curve needs two distinct points")
        return k

    keypoints = ValidatedParam(_check_keypoints, "geometry", "(K >= 2, 3) polyline through the tube's centre.")
    radius = _RADIUS

    def __init__(self, keypoints: Any, radius: float, material: Any, colors: Any, tag: str = "", **pose: Any):
        self.keypoints = keypoints
        self.radius = as_float("radius", radius, min_value=0.0, exclusive_min=True)
        super().__init__(material, colors, tag, **pose)

    def to_mesh(self, segments: int = 16) -> TriMesh:
        return tube_along_polyline(self.keypoints, self.radius, segments)

    def _params(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
        arrays[prefix + "keypoints"] = self.keypoints
        return {"keypoints": prefix + "keypoints", "radius": self.radius}


PARAMETRIC = {c.kind: c for c in (SphereNURBS, EllipsoidNURBS, CurveBezier)}
