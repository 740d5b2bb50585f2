"""Point clouds: spheres of a given diameter, one colour or one per point."""

from __future__ import annotations

from typing import Any

import numpy as np

from blendify_core._memo import bounds_memo
from blendify_core.errors import InvalidSceneError
from blendify_core.errors import describe as _describe
from blendify_core.ir.colors import UniformColors, VertexColors
from blendify_core.ir.geometry import TriMesh, icosphere
from blendify_core.ir.params import MAX_EMISSION
from blendify_core.ir.renderables.base import Renderable, _column_bounds
from blendify_core.ir.transforms import ValidatedParam
from blendify_core.ir.validate import as_array, as_choice, as_float, raw_array
from blendify_core.typing import AnyArray

__all__ = ["PointCloud"]


class PointCloud(Renderable):
    """Points rendered as spheres of diameter ``point_size`` (world units; a scalar or one per point),
    coloured by ``UniformColors`` or ``VertexColors`` (one per point)."""

    kind = "pointcloud"
    prefix = "PointCloud"
    allowed_colors = (UniformColors, VertexColors)
    particle_emission_strength = ValidatedParam(
        lambda obj, name, v: as_float(name, v, min_value=0.0, max_value=MAX_EMISSION),
        doc="Self-illumination of the points (0 = lit like everything else).",
    )

    def __init__(
        self,
        vertices: Any,
        material: Any,
        colors: Any,
        point_size: Any = 0.01,
        base_primitive: str = "SPHERE",
        particle_emission_strength: float = 0.0,
        tag: str = "",
        **pose: Any,
    ):
        v = as_array("vertices", vertices, ndim=2)
        if v.shape[1] != 3:
            raise InvalidSceneError(f"vertices: expected shape (N, 3), got {_describe(v)}")
        self._vertices = v
        self._point_size = self._check_size(point_size)
        self.base_primitive = as_choice("base_primitive", base_primitive, ("SPHERE",))
        self.particle_emission_strength = particle_emission_strength
        super().__init__(material, colors, tag, **pose)

    def _check_size(self, point_size: Any) -> float | AnyArray:
        if raw_array("point_size", point_size).ndim == 0:
            return as_float("point_size", point_size, min_value=0.0, exclusive_min=True)
        s = as_array("point_size", point_size, shape=(len(self._vertices),), min_value=0.0)
        if s.size and s.min() <= 0:
            raise InvalidSceneError("point_size: expected positive sizes, got a minimum of 0")
        return s

    def _validate_colors(self) -> None:
        c = self.colors_list[0]
        if isinstance(c, VertexColors) and len(c) != len(self._vertices):
            raise InvalidSceneError(f"colors: expected one colour per point ({len(self._vertices)}), got {len(c)}")

    @property
    def vertices(self) -> AnyArray:
        """(N, 3) float64 point positions (a read-only array; assigning calls update_vertices)."""
        return self._vertices

    @vertices.setter
    def vertices(self, value: Any) -> None:
        self.update_vertices(value)

    @property
    def num_vertices(self) -> int:
        return len(self._vertices)

    @property
    def point_size(self) -> float | AnyArray:
        return self._point_size

    @point_size.setter
    def point_size(self, value: Any) -> None:
        self._point_size = self._check_size(value)
        self._bump("geometry")

    def radii(self) -> AnyArray:
        """(N,) float64 sphere radii."""
        s = self._point_size
        return np.full(len(self._vertices), s / 2.0) if np.ndim(s) == 0 else np.asarray(s) / 2.0

    def update_vertices(self, vertices: Any) -> None:
        """New point positions; the count may change only if the colours and sizes are uniform."""
        v = as_array("vertices", vertices, ndim=2)
        if v.shape[1] != 3:
            raise InvalidSceneError(f"vertices: expected shape (N, 3), got {_describe(v)}")
        if len(v) != len(self._vertices) and (
            isinstance(self.colors_list[0], VertexColors) or np.ndim(self._point_size) != 0
        ):
            raise InvalidSceneError(
                f"vertices: expected {len(self._vertices)} points (per-point colours or sizes "
                f"are set), got {len(v)}; call update_colors first"
            )
        self._vertices = v
        self._bump("geometry")

    def to_mesh(self, subdivisions: int = 1) -> TriMesh:
        """Merged icospheres (one per point): the shared tessellation for engines without spheres."""
        base = icosphere(subdivisions)
        r = self.radii()
        n, nv = len(self._vertices), len(base.vertices)
        verts = (base.vertices[None] * r[:, None, None] + self._vertices[:, None]).reshape(-1, 3)
        faces = (base.faces[None] + (np.arange(n) * nv)[:, None, None]).reshape(-1, 3).astype(np.int32)
        normals = np.broadcast_to(base.normals, (n, nv, 3)).reshape(-1, 3)  # type: ignore[arg-type]
        return TriMesh(vertices=verts, faces=faces, normals=normals, smooth=True)

    def world_bounds(self) -> tuple[AnyArray, AnyArray]:
        if len(self._vertices) == 0:
            return self.translation.copy(), self.translation.copy()
        # cheap on millions of points: the object-space box grown by the largest radius, then its corners
        # transformed (as Mesh.world_bounds; exact for unrotated clouds, conservative otherwise)
        r = float(self._point_size) / 2.0 if np.ndim(self._point_size) == 0 else float(np.max(self._point_size)) / 2.0
        lo, hi = bounds_memo(self._vertices, _column_bounds)
        lo, hi = lo - r, hi + r
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        v = corners @ self.rotation_matrix.T + self.translation
        return v.min(axis=0), v.max(axis=0)

    def to_dict(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
        d = self._base_dict(arrays, prefix)
        arrays[prefix + "vertices"] = self._vertices
        if np.ndim(self._point_size):
            arrays[prefix + "point_size"] = np.asarray(self._point_size)
            size: Any = prefix + "point_size"
        else:
            size = self._point_size
        d.update(
            vertices=prefix + "vertices",
            point_size=size,
            base_primitive=self.base_primitive,
            particle_emission_strength=self.particle_emission_strength,
        )
        return d
