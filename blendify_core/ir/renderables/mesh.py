"""Polygon meshes: any polygon size (triangulated once, here), per-face materials, UVs, smooth shading."""

from __future__ import annotations

from typing import Any

import numpy as np

from blendify_core._memo import bounds_memo, normals_memo
from blendify_core.errors import InvalidSceneError
from blendify_core.errors import describe as _describe
from blendify_core.ir.colors import (
    FacesUV,
    FileTextureColors,
    TextureColors,
    UniformColors,
    UVMap,
    VertexColors,
    VertexUV,
    uv_to_dict,
)
from blendify_core.ir.geometry import TriMesh, triangulate_polygons, vertex_normals
from blendify_core.ir.renderables.base import Renderable, _column_bounds
from blendify_core.ir.validate import as_array, as_bool, frozen
from blendify_core.typing import AnyArray

__all__ = ["Mesh"]


def _check_faces(
    faces: Any, n_vertices: int, vertices: AnyArray | None = None
) -> tuple[AnyArray, AnyArray, AnyArray, int, int | None]:
    """Validate polygons and triangulate them. Returns triangles, polygon index, corner index, polygon
    count and the common polygon size (None when sizes differ)."""
    if isinstance(faces, np.ndarray) or (
        isinstance(faces, (list, tuple))
        and faces
        and all(isinstance(f, (list, tuple, np.ndarray)) for f in faces)
        and len({len(f) for f in faces}) == 1
    ):
        arr = as_array("faces", faces, dtype=np.int64, ndim=2)
        if arr.shape[0] and arr.shape[1] < 3:
            raise InvalidSceneError(f"faces: expected polygons of at least 3 vertices, got shape {arr.shape}")
        if arr.size and (arr.min() < 0 or arr.max() >= n_vertices):
            raise InvalidSceneError(
                f"faces: vertex indices must be in [0, {n_vertices - 1}], got range [{arr.min()}, {arr.max()}]"
            )
        tris, poly, corner = triangulate_polygons(arr, vertices)
        return tris, poly, corner, arr.shape[0], (arr.shape[1] if arr.shape[0] else 3)
    if not isinstance(faces, (list, tuple)):
        raise InvalidSceneError(
            f"faces: expected an (M, k) integer array or a list of polygons, got {_describe(faces)}"
        )
    polys = []
    for i, f in enumerate(faces):
        p = as_array(f"faces[{i}]", f, dtype=np.int64, ndim=1)
        if len(p) < 3:
            raise InvalidSceneError(f"faces[{i}]: expected a polygon of at least 3 vertices, got {len(p)}")
        if p.min() < 0 or p.max() >= n_vertices:
            raise InvalidSceneError(f"faces[{i}]: vertex indices must be in [0, {n_vertices - 1}], got {p.tolist()}")
        polys.append(p)
    tris, poly, corner = triangulate_polygons(polys, vertices)
    return tris, poly, corner, len(polys), None


class Mesh(Renderable):
    """A polygon mesh: ``vertices`` (N, 3), ``faces`` (M, k) or a list of polygons of any size
    (triangulated: a fan for convex polygons, ear clipping for concave ones). ``faces_material`` (M,)
    gives a material index per polygon when ``material`` and ``colors`` are lists. ``uv_map`` gives UVs
    for data textures when the colours have none."""

    kind = "mesh"
    prefix = "Mesh"
    allowed_colors = (UniformColors, VertexColors, TextureColors, FileTextureColors)

    def __init__(
        self,
        vertices: Any,
        faces: Any,
        material: Any,
        colors: Any,
        faces_material: Any = None,
        uv_map: UVMap | None = None,
        smooth: bool = False,
        tag: str = "",
        **pose: Any,
    ):
        v = as_array("vertices", vertices, ndim=2)
        if v.shape[1] != 3:
            raise InvalidSceneError(f"vertices: expected shape (N, 3), got {_describe(v)}")
        self._vertices = v
        tris, poly, corner, n_poly, k = _check_faces(faces, len(v), v)
        self._faces, self._face_polygon, self._face_corner = frozen(tris), frozen(poly), frozen(corner)
        self.n_polygons, self.polygon_size = n_poly, k
        if uv_map is not None and not isinstance(uv_map, UVMap):
            hint = (
                " (blendify 2.1's add_mesh took rotation_mode there: pass the pose by keyword, rotation_mode=...)"
                if isinstance(uv_map, str)
                else ""
            )
            raise InvalidSceneError(f"uv_map: expected a VertexUV or FacesUV, got {_describe(uv_map)}{hint}")
        self._uv_map = uv_map
        self._faces_material_poly: AnyArray | None = None
        self._smooth = as_bool("smooth", smooth)
        self._pending_faces_material = faces_material
        super().__init__(material, colors, tag, **pose)
        self._set_faces_material(faces_material)
        self._check_uv("uv_map", uv_map)

    def _supports_multi_material(self) -> bool:
        return True

    def _set_faces_material(self, faces_material: Any) -> None:
        n_mat = len(self.materials)
        if faces_material is None:
            if n_mat > 1:
                raise InvalidSceneError(
                    f"faces_material: expected a material index per face when {n_mat} materials are given, got None"
                )
            self._faces_material_poly = None
            return
        fm = as_array("faces_material", faces_material, dtype=np.int32, shape=(self.n_polygons,))
        if fm.size and (fm.min() < 0 or fm.max() >= n_mat):
            raise InvalidSceneError(
                f"faces_material: expected indices in [0, {n_mat - 1}], got range [{fm.min()}, {fm.max()}]"
            )
        self._faces_material_poly = fm

    def _check_uv(self, name: str, uv: UVMap | None) -> None:
        if uv is None:
            return
        if isinstance(uv, VertexUV) and uv.data.shape[0] != len(self._vertices):
            raise InvalidSceneError(
                f"{name}: expected one UV per vertex ({len(self._vertices)}), got {uv.data.shape[0]}"
            )
        if isinstance(uv, FacesUV):
            if uv.data.shape[0] != self.n_polygons:
                raise InvalidSceneError(
                    f"{name}: expected one UV set per face ({self.n_polygons}), got {uv.data.shape[0]}"
                )
            if self.polygon_size is not None and uv.data.shape[1] != self.polygon_size:
                raise InvalidSceneError(
                    f"{name}: expected {self.polygon_size} corners per face, got {uv.data.shape[1]}"
                )
            # polygons of mixed sizes: (M, k_max, 2), a face of k corners uses its first k UVs (FacesUV pads
            # a list of per-face (k, 2) arrays this way)
            k_max = int(self._face_corner.max()) + 1 if self._face_corner.size else 0
            if self.polygon_size is None and uv.data.shape[1] != k_max:
                raise InvalidSceneError(
                    f"{name}: the faces have from 3 to {k_max} corners: expected (M, {k_max}, 2) UVs (a face of k "
                    f"corners uses its first k) or a list of per-face (k, 2) arrays, got {uv.data.shape[1]} per face"
                )

    def _validate_colors(self) -> None:
        if not hasattr(self, "_vertices"):
            return
        for i, c in enumerate(self.colors_list):
            name = "colors" if len(self.colors_list) == 1 else f"colors[{i}]"
            if isinstance(c, VertexColors) and len(c) != len(self._vertices):
                raise InvalidSceneError(f"{name}: expected one colour per vertex ({len(self._vertices)}), got {len(c)}")
            if isinstance(c, (TextureColors, FileTextureColors)):
                self._check_uv(f"{name}.uv_map", c.uv_map)

    # -- data --------------------------------------------------------------------------------------
    @property
    def vertices(self) -> AnyArray:
        """(N, 3) float64 object-space positions (a read-only array; assigning calls update_vertices)."""
        return self._vertices

    @vertices.setter
    def vertices(self, value: Any) -> None:
        self.update_vertices(value)

    @property
    def faces(self) -> AnyArray:
        """(F, 3) int32 triangles (after triangulation)."""
        return self._faces

    @property
    def face_polygon(self) -> AnyArray:
        """(F,) int32: the input polygon each triangle came from."""
        return self._face_polygon

    @property
    def faces_material(self) -> AnyArray | None:
        """(F,) int32 material index per TRIANGLE, or None (one material)."""
        if self._faces_material_poly is None:
            return None
        return self._faces_material_poly[self._face_polygon]

    @property
    def polygon_faces_material(self) -> AnyArray | None:
        """(M,) int32 material index per input polygon, or None."""
        return self._faces_material_poly

    @property
    def uv_map(self) -> UVMap | None:
        """The UV map used for textures: the explicit ``uv_map`` or the texture colours' one."""
        if self._uv_map is not None:
            return self._uv_map
        for c in self.colors_list:
            if isinstance(c, (TextureColors, FileTextureColors)):
                return c.uv_map
        return None

    def triangle_uvs(self, uv_map: UVMap | None = None) -> AnyArray | None:
        """(F, 3, 2) float32 UV per triangle corner for ``uv_map`` (default: :attr:`uv_map`)."""
        uv = uv_map or self.uv_map
        if uv is None:
            return None
        corners: AnyArray
        if isinstance(uv, VertexUV):
            corners = uv.data[self._faces]
        else:
            corners = uv.data[self._face_polygon[:, None], self._face_corner]
        return corners

    @property
    def smooth(self) -> bool:
        """Smooth shading (assigning calls :meth:`set_smooth`)."""
        return self._smooth

    @smooth.setter
    def smooth(self, value: bool) -> None:
        self.set_smooth(value)

    def set_smooth(self, smooth: bool = True) -> None:
        """Smooth (interpolated vertex normals) or flat shading (the default, as in blendify)."""
        self._smooth = as_bool("smooth", smooth)
        self._bump("geometry")

    def vertex_normals(self) -> AnyArray:
        """The IR's angle-weighted vertex normals (read-only; computed once while the vertices and faces
        arrays live: every render and backend of an unchanged mesh reuses them)."""
        normals: AnyArray = normals_memo(self._vertices, self._faces, _frozen_vertex_normals)
        return normals

    def update_vertices(self, vertices: Any) -> None:
        """New positions for the same vertices (same count)."""
        v = as_array("vertices", vertices, shape=(len(self._vertices), 3))
        self._vertices = v
        self._bump("geometry")

    def world_bounds(self) -> tuple[AnyArray, AnyArray]:
        if len(self._vertices) == 0:
            return self.translation.copy(), self.translation.copy()
        lo, hi = bounds_memo(self._vertices, _column_bounds)
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        v = corners @ self.rotation_matrix.T + self.translation
        return v.min(axis=0), v.max(axis=0)

    def to_mesh(self) -> TriMesh:
        return TriMesh(
            vertices=self._vertices,
            faces=self._faces,
            normals=self.vertex_normals() if self._smooth else None,
            uv=self.triangle_uvs(),
            face_polygon=self._face_polygon,
            smooth=self._smooth,
        )

    def to_dict(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
        d = self._base_dict(arrays, prefix)
        arrays[prefix + "vertices"] = self._vertices
        # store the triangulation with its polygon structure so FacesUV round-trips exactly
        arrays[prefix + "faces"] = self._faces
        arrays[prefix + "face_polygon"] = self._face_polygon
        arrays[prefix + "face_corner"] = self._face_corner
        if self._faces_material_poly is not None:
            arrays[prefix + "faces_material"] = self._faces_material_poly
        d.update(
            vertices=prefix + "vertices",
            faces=prefix + "faces",
            n_polygons=self.n_polygons,
            polygon_size=self.polygon_size,
            smooth=self._smooth,
            faces_material=None if self._faces_material_poly is None else prefix + "faces_material",
            uv_map=uv_to_dict(self._uv_map, arrays, prefix + "uvmap."),
        )
        return d


def _frozen_vertex_normals(vertices: AnyArray, faces: AnyArray) -> AnyArray:
    n = vertex_normals(vertices, faces)
    n.flags.writeable = False
    return n
