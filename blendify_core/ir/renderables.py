"""Renderables: meshes, point clouds, mesh primitives, parametric primitives and curve tubes.

All renderables are positionable (any rotation mode), carry a material (or a list of materials with
``faces_material``) and a colour source, and are two-sided in every backend. Geometry is stored in
OBJECT space, float64 (backends re-centre in float64 before handing float32 to an engine).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from blendify_core._memo import bounds_memo
from blendify_core.errors import InvalidSceneError
from blendify_core.ir.colors import (
    Colors,
    FacesUV,
    FileTextureColors,
    TextureColors,
    UniformColors,
    UVMap,
    VertexColors,
    VertexUV,
    uv_to_dict,
)
from blendify_core.ir.from_trimesh import add_trimesh
from blendify_core.ir.geometry import (
    TriMesh,
    icosphere,
    triangulate_polygons,
    tube_along_polyline,
    uv_sphere,
    vertex_normals,
)
from blendify_core.ir.materials import Material, check_material
from blendify_core.ir.transforms import Positionable, ValidatedParam
from blendify_core.ir.validate import (
    _describe,
    as_array,
    as_bool,
    as_choice,
    as_float,
    as_int,
    check_tag,
    frozen,
    raw_array,
    strict_arguments,
)

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
]


def _column_bounds(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-column min and max of an (N, 3) array (15x faster than ``min(axis=0)`` on millions of rows)."""
    return (
        np.array([v[:, k].min() for k in range(v.shape[1])]),
        np.array([v[:, k].max() for k in range(v.shape[1])]),
    )


class Renderable(Positionable):
    """Base of everything that can be seen. ``materials`` / ``colors_list`` are parallel lists (one entry
    unless per-face materials are used)."""

    kind = "renderable"
    prefix = "Renderable"
    allowed_colors: tuple[type, ...] = (UniformColors,)

    def __init__(self, material: Any, colors: Any, tag: str = "", **pose: Any):
        self._tag = tag
        self._emit_shadows = True
        self.materials: list[Material] = []
        self.colors_list: list[Colors] = []
        self._set_appearance(material, colors)
        super().__init__(**pose)

    # -- appearance ------------------------------------------------------------------------------
    def _check_colors(self, name: str, colors: Any) -> Colors:
        if not isinstance(colors, Colors):
            raise InvalidSceneError(
                f"{name}: expected a colour source such as UniformColors((r, g, b)), got {_describe(colors)}"
            )
        if not isinstance(colors, self.allowed_colors):
            allowed = ", ".join(c.__name__ for c in self.allowed_colors)
            raise InvalidSceneError(f"{name}: a {type(self).__name__} takes {allowed}, got {type(colors).__name__}")
        return colors

    def _set_appearance(self, material: Any, colors: Any) -> None:
        mats = list(material) if isinstance(material, (list, tuple)) else [material]
        cols = (
            list(colors) if isinstance(colors, (list, tuple)) and colors and isinstance(colors[0], Colors) else [colors]
        )
        if not mats:
            raise InvalidSceneError("material: expected a Material or a non-empty list of Materials, got []")
        if len(mats) != len(cols):
            raise InvalidSceneError(f"colors: expected one colour source per material ({len(mats)}), got {len(cols)}")
        if len(mats) > 1 and not self._supports_multi_material():
            raise InvalidSceneError(f"material: a {type(self).__name__} takes exactly one material, got {len(mats)}")
        self.materials = [
            check_material(f"material[{i}]" if len(mats) > 1 else "material", m) for i, m in enumerate(mats)
        ]
        self.colors_list = [
            self._check_colors(f"colors[{i}]" if len(cols) > 1 else "colors", c) for i, c in enumerate(cols)
        ]
        self._validate_colors()

    def _supports_multi_material(self) -> bool:
        return False

    def _validate_colors(self) -> None:
        pass

    @property
    def material(self) -> Material | list[Material]:
        """The material (a list with per-face materials); assigning calls :meth:`update_material`."""
        return self.materials[0] if len(self.materials) == 1 else list(self.materials)

    @material.setter
    def material(self, value: Material | Sequence[Material]) -> None:
        self.update_material(value)

    @property
    def colors(self) -> Colors | list[Colors]:
        """The colour source (a list with per-face materials); assigning calls :meth:`update_colors`."""
        return self.colors_list[0] if len(self.colors_list) == 1 else list(self.colors_list)

    @colors.setter
    def colors(self, value: Colors | Sequence[Colors]) -> None:
        self.update_colors(value)

    def update_material(self, material: Material | Sequence[Material]) -> None:
        """Replace the material(s); a list must have as many entries as the current one."""
        mats = list(material) if isinstance(material, (list, tuple)) else [material]
        if len(mats) != len(self.materials):
            raise InvalidSceneError(f"material: expected {len(self.materials)} material(s), got {len(mats)}")
        self.materials = [check_material("material", m) for m in mats]
        self._bump("appearance")

    def update_colors(self, colors: Colors | Sequence[Colors]) -> None:
        """Replace the colour source(s); a list must have as many entries as there are materials."""
        cols = (
            list(colors) if isinstance(colors, (list, tuple)) and colors and isinstance(colors[0], Colors) else [colors]
        )
        if len(cols) != len(self.materials):
            raise InvalidSceneError(f"colors: expected {len(self.materials)} colour source(s), got {len(cols)}")
        old = self.colors_list
        self.colors_list = [self._check_colors("colors", c) for c in cols]
        try:
            self._validate_colors()
        except InvalidSceneError:
            self.colors_list = old
            raise
        self._bump("appearance")

    @property
    def emit_shadows(self) -> bool:
        """Whether the object casts shadows (blendify's name)."""
        return self._emit_shadows

    @emit_shadows.setter
    def emit_shadows(self, value: bool) -> None:
        self._emit_shadows = as_bool("emit_shadows", value)
        self._bump("appearance")

    emit_shadow = emit_shadows

    # -- geometry --------------------------------------------------------------------------------
    def to_mesh(self) -> TriMesh:  # pragma: no cover - overridden
        """A triangle mesh in object space (the shared tessellation)."""
        raise NotImplementedError

    def world_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds (min, max) in world space."""
        m = self.to_mesh()
        if len(m.vertices) == 0:
            return self.translation.copy(), self.translation.copy()
        v = m.vertices @ self.rotation_matrix.T + self.translation
        return v.min(axis=0), v.max(axis=0)

    def _base_dict(self, arrays: dict[str, np.ndarray], prefix: str) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "tag": self.tag,
            "emit_shadows": self._emit_shadows,
            "quaternion": self.quaternion.tolist(),
            "translation": self.translation.tolist(),
            "materials": [m.to_dict(arrays, f"{prefix}mat{i}.") for i, m in enumerate(self.materials)],
            "colors": [c.to_dict(arrays, f"{prefix}col{i}.") for i, c in enumerate(self.colors_list)],
        }

    def __repr__(self) -> str:
        return f"{type(self).__name__}(tag={self.tag!r})"


def _check_faces(
    faces: Any, n_vertices: int, vertices: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int | None]:
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
            raise InvalidSceneError(f"uv_map: expected a VertexUV or FacesUV, got {_describe(uv_map)}")
        self._uv_map = uv_map
        self._faces_material_poly: np.ndarray | None = None
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
            if self.polygon_size is None or uv.data.shape[1] != self.polygon_size:
                raise InvalidSceneError(
                    f"{name}: expected {self.polygon_size or 'equal-sized'} corners per face, got {uv.data.shape[1]}"
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
    def vertices(self) -> np.ndarray:
        """(N, 3) float64 object-space positions (a read-only array; assigning calls update_vertices)."""
        return self._vertices

    @vertices.setter
    def vertices(self, value: Any) -> None:
        self.update_vertices(value)

    @property
    def faces(self) -> np.ndarray:
        """(F, 3) int32 triangles (after triangulation)."""
        return self._faces

    @property
    def face_polygon(self) -> np.ndarray:
        """(F,) int32: the input polygon each triangle came from."""
        return self._face_polygon

    @property
    def faces_material(self) -> np.ndarray | None:
        """(F,) int32 material index per TRIANGLE, or None (one material)."""
        if self._faces_material_poly is None:
            return None
        return self._faces_material_poly[self._face_polygon]

    @property
    def polygon_faces_material(self) -> np.ndarray | None:
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

    def triangle_uvs(self, uv_map: UVMap | None = None) -> np.ndarray | None:
        """(F, 3, 2) float32 UV per triangle corner for ``uv_map`` (default: :attr:`uv_map`)."""
        uv = uv_map or self.uv_map
        if uv is None:
            return None
        if isinstance(uv, VertexUV):
            return uv.data[self._faces]
        return uv.data[self._face_polygon[:, None], self._face_corner]

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

    def vertex_normals(self) -> np.ndarray:
        return vertex_normals(self._vertices, self._faces)

    def update_vertices(self, vertices: Any) -> None:
        """New positions for the same vertices (same count)."""
        v = as_array("vertices", vertices, shape=(len(self._vertices), 3))
        self._vertices = v
        self._bump("geometry")

    def world_bounds(self) -> tuple[np.ndarray, np.ndarray]:
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

    def to_dict(self, arrays: dict[str, np.ndarray], prefix: str) -> dict[str, Any]:
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


class PointCloud(Renderable):
    """Points rendered as spheres of diameter ``point_size`` (world units; a scalar or one per point),
    coloured by ``UniformColors`` or ``VertexColors`` (one per point)."""

    kind = "pointcloud"
    prefix = "PointCloud"
    allowed_colors = (UniformColors, VertexColors)
    particle_emission_strength = ValidatedParam(
        lambda obj, name, v: as_float(name, v, min_value=0.0),
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

    def _check_size(self, point_size: Any) -> float | np.ndarray:
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
    def vertices(self) -> np.ndarray:
        """(N, 3) float64 point positions (a read-only array; assigning calls update_vertices)."""
        return self._vertices

    @vertices.setter
    def vertices(self, value: Any) -> None:
        self.update_vertices(value)

    @property
    def num_vertices(self) -> int:
        return len(self._vertices)

    @property
    def point_size(self) -> float | np.ndarray:
        return self._point_size

    @point_size.setter
    def point_size(self, value: Any) -> None:
        self._point_size = self._check_size(value)
        self._bump("geometry")

    def radii(self) -> np.ndarray:
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

    def world_bounds(self) -> tuple[np.ndarray, np.ndarray]:
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

    def to_dict(self, arrays: dict[str, np.ndarray], prefix: str) -> dict[str, Any]:
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


# ---------------------------------------------------------------------------------------------------
# Mesh primitives
# ---------------------------------------------------------------------------------------------------


def _positive(obj: Any, name: str, value: Any) -> float:
    return as_float(name, value, min_value=0.0, exclusive_min=True)


def _fixed(check: Any) -> Any:
    """A parameter fixed at creation (the face count and per-face materials depend on it)."""

    def fixed(obj: Any, name: str, value: Any) -> Any:
        if "_revisions" in obj.__dict__:
            raise InvalidSceneError(f"{name}: fixed at creation (got {value!r}); add a new object instead")
        return check(name, value)

    return fixed


# geometry parameters of primitives: validated on assignment, and a change bumps revision("geometry")
_SIZE = ValidatedParam(_positive, "geometry", "Edge length (world units).")
_RADIUS = ValidatedParam(_positive, "geometry", "Radius (world units).")
_NUM_VERTICES = ValidatedParam(
    _fixed(lambda name, v: as_int(name, v, min_value=3, max_value=100000)), "geometry", "Vertices around the circle."
)
_FILL_TYPE = ValidatedParam(_fixed(lambda name, v: as_choice(name, v, FILL_TYPES)), "geometry", "Cap fill.")


class MeshPrimitive(Renderable):
    """A parametric mesh (cube, circle, cylinder, plane). Colours: UniformColors (one per material).
    ``faces_material`` indexes the primitive's polygons (cube: 6 faces, plane: 1, ...)."""

    def __init__(self, material: Any, colors: Any, faces_material: Any = None, tag: str = "", **pose: Any):
        super().__init__(material, colors, tag, **pose)
        self._smooth = False
        poly = self._polygons()[1]
        n = len(poly)
        if faces_material is None:
            if len(self.materials) > 1:
                raise InvalidSceneError(
                    "faces_material: expected a material index per face when several materials are given, got None"
                )
            self._faces_material_poly = None
        else:
            fm = as_array("faces_material", faces_material, dtype=np.int32, shape=(n,))
            if fm.size and (fm.min() < 0 or fm.max() >= len(self.materials)):
                raise InvalidSceneError(f"faces_material: expected indices in [0, {len(self.materials) - 1}]")
            self._faces_material_poly = fm

    def _supports_multi_material(self) -> bool:
        return True

    def _polygons(self) -> tuple[np.ndarray, list[np.ndarray], np.ndarray | None]:  # pragma: no cover
        """Vertices, polygons and optional per-vertex normals (hard edges are split vertices)."""
        raise NotImplementedError

    @property
    def smooth(self) -> bool:
        """Smooth shading (assigning calls :meth:`set_smooth`)."""
        return self._smooth

    @smooth.setter
    def smooth(self, value: bool) -> None:
        self.set_smooth(value)

    def set_smooth(self, smooth: bool = True) -> None:
        """Smooth shading with sharp edges kept (the primitives' vertices are split at hard edges)."""
        self._smooth = as_bool("smooth", smooth)
        self._bump("geometry")

    def to_mesh(self) -> TriMesh:
        v, polys, normals = self._polygons()
        tris, poly_idx, _ = triangulate_polygons(polys)
        if self._smooth and normals is None:
            normals = vertex_normals(v, tris)
        return TriMesh(
            vertices=v,
            faces=tris,
            normals=normals if self._smooth else None,
            face_polygon=poly_idx,
            smooth=self._smooth,
        )

    @property
    def faces_material(self) -> np.ndarray | None:
        if self._faces_material_poly is None:
            return None
        return self._faces_material_poly[self.to_mesh().face_polygon]

    def to_dict(self, arrays: dict[str, np.ndarray], prefix: str) -> dict[str, Any]:
        d = self._base_dict(arrays, prefix)
        d["smooth"] = self._smooth
        d["faces_material"] = None if self._faces_material_poly is None else self._faces_material_poly.tolist()
        d["params"] = self._params()
        return d

    def _params(self) -> dict[str, Any]:  # pragma: no cover
        raise NotImplementedError


class CubeMesh(MeshPrimitive):
    """An axis-aligned cube of edge ``size`` centred at its origin (6 faces: -X, +X, -Y, +Y, -Z, +Z)."""

    kind = "cube"
    prefix = "Cube"
    size = _SIZE

    def __init__(self, size: float, material: Any, colors: Any, faces_material: Any = None, tag: str = "", **pose: Any):
        self.size = as_float("size", size, min_value=0.0, exclusive_min=True)
        super().__init__(material, colors, faces_material, tag, **pose)

    def _polygons(self) -> tuple[np.ndarray, list[np.ndarray], np.ndarray | None]:
        h = self.size / 2.0
        verts, polys = [], []
        for axis in range(3):
            for sign in (-1.0, 1.0):
                u, w = [a for a in range(3) if a != axis]
                quad = []
                for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                    p = np.zeros(3)
                    p[axis], p[u], p[w] = sign * h, a * h, b * h
                    quad.append(p)
                quad_arr = np.array(quad)
                n = np.cross(quad_arr[1] - quad_arr[0], quad_arr[2] - quad_arr[0])
                if n[axis] * sign < 0:
                    quad_arr = quad_arr[::-1]
                base = len(verts)
                verts.extend(quad_arr)
                polys.append(np.arange(base, base + 4))
        return np.array(verts), polys, None

    def _params(self) -> dict[str, Any]:
        return {"size": self.size}


def _ring(radius: float, n: int, z: float = 0.0) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.stack([radius * np.cos(a), radius * np.sin(a), np.full(n, z)], axis=1)


FILL_TYPES = ("NOTHING", "NGON", "TRIFAN")


def _fill(ring_idx: np.ndarray, verts: list[np.ndarray], centre: np.ndarray, fill: str, flip: bool) -> list[np.ndarray]:
    if fill == "NOTHING":
        return []
    if fill == "NGON":
        return [ring_idx[::-1] if flip else ring_idx]
    c = len(verts)
    verts.append(centre)
    n = len(ring_idx)
    out = []
    for j in range(n):
        tri = np.array([c, ring_idx[j], ring_idx[(j + 1) % n]])
        out.append(tri[[0, 2, 1]] if flip else tri)
    return out


class CircleMesh(MeshPrimitive):
    """A disc of ``radius`` in the XY plane facing +Z; ``fill_type`` "NGON" (one polygon), "TRIFAN" (one
    triangle per segment) or "NOTHING" (no faces: renders nothing)."""

    kind = "circle"
    prefix = "Circle"
    radius, num_vertices, fill_type = _RADIUS, _NUM_VERTICES, _FILL_TYPE

    def __init__(
        self,
        radius: float,
        material: Any,
        colors: Any,
        faces_material: Any = None,
        num_vertices: int = 32,
        fill_type: str = "NGON",
        tag: str = "",
        **pose: Any,
    ):
        self.radius = as_float("radius", radius, min_value=0.0, exclusive_min=True)
        self.num_vertices = as_int("num_vertices", num_vertices, min_value=3, max_value=100000)
        self.fill_type = as_choice("fill_type", fill_type, FILL_TYPES)
        super().__init__(material, colors, faces_material, tag, **pose)

    def _polygons(self) -> tuple[np.ndarray, list[np.ndarray], np.ndarray | None]:
        verts = list(_ring(self.radius, self.num_vertices))
        polys = _fill(np.arange(self.num_vertices), verts, np.zeros(3), self.fill_type, flip=False)
        return np.array(verts), polys, None

    def _params(self) -> dict[str, Any]:
        return {"radius": self.radius, "num_vertices": self.num_vertices, "fill_type": self.fill_type}


class CylinderMesh(MeshPrimitive):
    """A cylinder of ``radius`` and ``height`` along Z, centred (z in [-h/2, h/2]); caps filled as
    ``fill_type``. Faces: the ``num_vertices`` side quads, then the bottom and top caps."""

    kind = "cylinder"
    prefix = "Cylinder"
    radius, num_vertices, fill_type = _RADIUS, _NUM_VERTICES, _FILL_TYPE
    height = ValidatedParam(_positive, "geometry", "Height along Z (world units).")

    def __init__(
        self,
        radius: float,
        height: float,
        material: Any,
        colors: Any,
        faces_material: Any = None,
        num_vertices: int = 32,
        fill_type: str = "NGON",
        tag: str = "",
        **pose: Any,
    ):
        self.radius = as_float("radius", radius, min_value=0.0, exclusive_min=True)
        self.height = as_float("height", height, min_value=0.0, exclusive_min=True)
        self.num_vertices = as_int("num_vertices", num_vertices, min_value=3, max_value=100000)
        self.fill_type = as_choice("fill_type", fill_type, FILL_TYPES)
        super().__init__(material, colors, faces_material, tag, **pose)

    def _polygons(self) -> tuple[np.ndarray, list[np.ndarray], np.ndarray | None]:
        n, h = self.num_vertices, self.height / 2.0
        bottom, top = _ring(self.radius, n, -h), _ring(self.radius, n, h)
        verts = list(bottom) + list(top)
        normals = [np.array([p[0], p[1], 0.0]) / self.radius for p in bottom] * 2
        polys = [np.array([j, (j + 1) % n, n + (j + 1) % n, n + j]) for j in range(n)]
        start = len(verts)  # caps get their own vertices (hard edge)
        verts += list(bottom) + list(top)
        normals += [np.array([0, 0, -1.0])] * n + [np.array([0, 0, 1.0])] * n
        before = len(verts)
        polys += _fill(np.arange(start, start + n), verts, np.array([0, 0, -h]), self.fill_type, flip=True)
        normals += [np.array([0, 0, -1.0])] * (len(verts) - before)
        before = len(verts)
        polys += _fill(np.arange(start + n, start + 2 * n), verts, np.array([0, 0, h]), self.fill_type, flip=False)
        normals += [np.array([0, 0, 1.0])] * (len(verts) - before)
        return np.array(verts), polys, np.array(normals)

    def _params(self) -> dict[str, Any]:
        return {
            "radius": self.radius,
            "height": self.height,
            "num_vertices": self.num_vertices,
            "fill_type": self.fill_type,
        }


class PlaneMesh(MeshPrimitive):
    """A square of edge ``size`` in the XY plane facing +Z. ``shadow_catcher=True`` makes it invisible
    except for the shadows it receives (composited over a transparent background)."""

    kind = "plane"
    prefix = "Plane"
    size = _SIZE

    def __init__(
        self,
        size: float,
        material: Any,
        colors: Any,
        faces_material: Any = None,
        shadow_catcher: bool = False,
        tag: str = "",
        **pose: Any,
    ):
        self.size = as_float("size", size, min_value=0.0, exclusive_min=True)
        self._shadow_catcher = as_bool("shadow_catcher", shadow_catcher)
        super().__init__(material, colors, faces_material, tag, **pose)

    @property
    def shadow_catcher(self) -> bool:
        return self._shadow_catcher

    @shadow_catcher.setter
    def shadow_catcher(self, value: bool) -> None:
        self._shadow_catcher = as_bool("shadow_catcher", value)
        self._bump("appearance")

    def _polygons(self) -> tuple[np.ndarray, list[np.ndarray], np.ndarray | None]:
        h = self.size / 2.0
        v = np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]])
        return v, [np.arange(4)], None

    def to_mesh(self) -> TriMesh:
        m = super().to_mesh()
        m.uv = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], dtype=np.float32)
        return m

    def _params(self) -> dict[str, Any]:
        return {"size": self.size, "shadow_catcher": self._shadow_catcher}


# ---------------------------------------------------------------------------------------------------
# Parametric primitives (kept parametric; backends may render them analytically)
# ---------------------------------------------------------------------------------------------------


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

    def to_dict(self, arrays: dict[str, np.ndarray], prefix: str) -> dict[str, Any]:
        d = self._base_dict(arrays, prefix)
        d["params"] = self._params(arrays, prefix)
        return d

    def _params(self, arrays: dict[str, np.ndarray], prefix: str) -> dict[str, Any]:  # pragma: no cover
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

    def _params(self, arrays: dict[str, np.ndarray], prefix: str) -> dict[str, Any]:
        return {"radius": self.radius}


class EllipsoidNURBS(ParametricPrimitive):
    """An axis-aligned ellipsoid with semi-axes ``radius`` = (rx, ry, rz) in object space."""

    kind = "ellipsoid"
    prefix = "Ellipsoid"

    @staticmethod
    def _check_radius(obj: Any, name: str, value: Any) -> np.ndarray:
        r = as_array(name, value, shape=(3,))
        if np.any(r <= 0):
            raise InvalidSceneError(f"{name}: expected three positive semi-axes, got {r.tolist()}")
        return r

    radius = ValidatedParam(_check_radius, "geometry", "Semi-axes (rx, ry, rz) in object space.")

    def __init__(self, radius: Any, material: Any, colors: Any, tag: str = "", **pose: Any):
        self.radius = radius
        super().__init__(material, colors, tag, **pose)

    def to_mesh(self, segments: int = 64, rings: int = 32) -> TriMesh:
        m = uv_sphere(1.0, segments, rings)
        m.vertices = m.vertices * self.radius
        n = m.normals / self.radius  # type: ignore[operator]
        m.normals = n / np.linalg.norm(n, axis=1, keepdims=True)
        return m

    def _params(self, arrays: dict[str, np.ndarray], prefix: str) -> dict[str, Any]:
        return {"radius": self.radius.tolist()}


class CurveBezier(ParametricPrimitive):
    """A tube of ``radius`` through ``keypoints`` (K >= 2, a polyline, as blendify's curves), closed with
    flat caps."""

    kind = "curve"
    prefix = "Curve"

    @staticmethod
    def _check_keypoints(obj: Any, name: str, value: Any) -> np.ndarray:
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

    def _params(self, arrays: dict[str, np.ndarray], prefix: str) -> dict[str, Any]:
        arrays[prefix + "keypoints"] = self.keypoints
        return {"keypoints": prefix + "keypoints", "radius": self.radius}


_PRIMITIVES = {c.kind: c for c in (CubeMesh, CircleMesh, CylinderMesh, PlaneMesh)}
_PARAMETRIC = {c.kind: c for c in (SphereNURBS, EllipsoidNURBS, CurveBezier)}


class RenderablesCollection:
    """The renderables of one scene (blendify's ``scene.renderables``)."""

    def __init__(self) -> None:
        self._items: dict[str, Renderable] = {}
        self._counters: dict[str, int] = {}
        self.revision = 0

    def _add(self, obj: Renderable, tag: str | None) -> Any:
        if tag is None:
            n = self._counters.get(obj.prefix, 0)
            while f"{obj.prefix}_{n:03d}" in self._items:
                n += 1
            self._counters[obj.prefix] = n + 1
            tag = f"{obj.prefix}_{n:03d}"
        else:
            check_tag("tag", tag)
            if tag in self._items:
                raise InvalidSceneError(f"tag: a renderable tagged {tag!r} already exists in this scene")
        obj._tag = tag
        self._items[tag] = obj
        self.revision += 1
        return obj

    @strict_arguments
    def add_mesh(
        self,
        vertices: Any,
        faces: Any,
        material: Any,
        colors: Any,
        faces_material: Any = None,
        uv_map: UVMap | None = None,
        smooth: bool = False,
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        tag: str | None = None,
    ) -> Mesh:
        return self._add(
            Mesh(
                vertices,
                faces,
                material,
                colors,
                faces_material,
                uv_map,
                smooth,
                rotation_mode=rotation_mode,
                rotation=rotation,
                translation=translation,
            ),
            tag,
        )

    @strict_arguments
    def add_pointcloud(
        self,
        vertices: Any,
        material: Any,
        colors: Any,
        point_size: Any = 0.01,
        base_primitive: str = "SPHERE",
        particle_emission_strength: float = 0.0,
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        tag: str | None = None,
    ) -> PointCloud:
        return self._add(
            PointCloud(
                vertices,
                material,
                colors,
                point_size,
                base_primitive,
                particle_emission_strength,
                rotation_mode=rotation_mode,
                rotation=rotation,
                translation=translation,
            ),
            tag,
        )

    @strict_arguments
    def add_cube_mesh(
        self,
        size: float,
        material: Any,
        colors: Any,
        faces_material: Any = None,
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        tag: str | None = None,
    ) -> CubeMesh:
        return self._add(
            CubeMesh(
                size,
                material,
                colors,
                faces_material,
                rotation_mode=rotation_mode,
                rotation=rotation,
                translation=translation,
            ),
            tag,
        )

    @strict_arguments
    def add_circle_mesh(
        self,
        radius: float,
        material: Any,
        colors: Any,
        faces_material: Any = None,
        num_vertices: int = 32,
        fill_type: str = "NGON",
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        tag: str | None = None,
    ) -> CircleMesh:
        return self._add(
            CircleMesh(
                radius,
                material,
                colors,
                faces_material,
                num_vertices,
                fill_type,
                rotation_mode=rotation_mode,
                rotation=rotation,
                translation=translation,
            ),
            tag,
        )

    @strict_arguments
    def add_cylinder_mesh(
        self,
        radius: float,
        height: float,
        material: Any,
        colors: Any,
        faces_material: Any = None,
        num_vertices: int = 32,
        fill_type: str = "NGON",
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        tag: str | None = None,
    ) -> CylinderMesh:
        return self._add(
            CylinderMesh(
                radius,
                height,
                material,
                colors,
                faces_material,
                num_vertices,
                fill_type,
                rotation_mode=rotation_mode,
                rotation=rotation,
                translation=translation,
            ),
            tag,
        )

    @strict_arguments
    def add_plane_mesh(
        self,
        size: float,
        material: Any,
        colors: Any,
        faces_material: Any = None,
        shadow_catcher: bool = False,
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        tag: str | None = None,
    ) -> PlaneMesh:
        return self._add(
            PlaneMesh(
                size,
                material,
                colors,
                faces_material,
                shadow_catcher,
                rotation_mode=rotation_mode,
                rotation=rotation,
                translation=translation,
            ),
            tag,
        )

    @strict_arguments
    def add_sphere_nurbs(
        self,
        radius: float,
        material: Any,
        colors: Any,
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        tag: str | None = None,
    ) -> SphereNURBS:
        return self._add(
            SphereNURBS(
                radius, material, colors, rotation_mode=rotation_mode, rotation=rotation, translation=translation
            ),
            tag,
        )

    @strict_arguments
    def add_ellipsoid_nurbs(
        self,
        radius: Any,
        material: Any,
        colors: Any,
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        tag: str | None = None,
    ) -> EllipsoidNURBS:
        return self._add(
            EllipsoidNURBS(
                radius, material, colors, rotation_mode=rotation_mode, rotation=rotation, translation=translation
            ),
            tag,
        )

    @strict_arguments
    def add_curve_nurbs(
        self,
        keypoints: Any,
        radius: float,
        material: Any,
        colors: Any,
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        tag: str | None = None,
    ) -> CurveBezier:
        return self._add(
            CurveBezier(
                keypoints,
                radius,
                material,
                colors,
                rotation_mode=rotation_mode,
                rotation=rotation,
                translation=translation,
            ),
            tag,
        )

    def add_trimesh(self, mesh_or_path: Any, material: Any = None, colors: Any = None, **kwargs: Any) -> Any:
        """Add a ``trimesh.Trimesh``, ``trimesh.Scene``, ``trimesh.PointCloud`` or a mesh file (OBJ, PLY,
        GLB/glTF, STL, OFF), keeping vertex colours, UVs, textures and material groups. Returns the new
        renderable (or a list for a multi-object scene)."""
        return add_trimesh(self, mesh_or_path, material=material, colors=colors, **kwargs)

    # -- collection protocol -------------------------------------------------------------------
    def remove(self, obj_or_tag: Renderable | str) -> None:
        tag = obj_or_tag.tag if isinstance(obj_or_tag, Renderable) else obj_or_tag
        if not isinstance(tag, str) or tag not in self._items:
            raise KeyError(f"no renderable tagged {tag!r} in this scene")
        del self._items[tag]
        self.revision += 1

    def __getitem__(self, tag: str) -> Renderable:
        try:
            return self._items[tag]
        except KeyError:
            raise KeyError(f"no renderable tagged {tag!r} in this scene; tags: {list(self._items)[:20]}") from None

    def __delitem__(self, tag: str) -> None:
        self.remove(tag)

    def __contains__(self, tag: object) -> bool:
        return tag in self._items

    def __iter__(self):  # type: ignore[no-untyped-def]
        return iter(list(self._items.values()))

    def __len__(self) -> int:
        return len(self._items)

    def keys(self) -> list[str]:
        return list(self._items.keys())

    def values(self) -> list[Renderable]:
        return list(self._items.values())

    def items(self) -> list[tuple[str, Renderable]]:
        return list(self._items.items())

    def clear(self) -> None:
        self._items.clear()
        self.revision += 1
