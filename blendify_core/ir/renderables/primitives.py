"""Mesh primitives (cube, circle, cylinder, plane): parametric meshes with per-face materials."""

from __future__ import annotations

from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.geometry import TriMesh, triangulate_polygons, vertex_normals
from blendify_core.ir.renderables.base import Renderable
from blendify_core.ir.transforms import ValidatedParam
from blendify_core.ir.validate import as_array, as_bool, as_choice, as_float, as_int
from blendify_core.typing import AnyArray

__all__ = ["MeshPrimitive", "CubeMesh", "CircleMesh", "CylinderMesh", "PlaneMesh", "FILL_TYPES", "PRIMITIVES"]

FILL_TYPES = ("NOTHING", "NGON", "TRIFAN")


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
    ``faces_material`` indexes the primitive's polygons (cube: 6 faces, plane: 1, ...).

    Shaded as blendify 2.1 shades them: smooth with an edge split at 30 degrees (a cylinder of 12 or more
    sides is round, its caps and a cube's edges stay sharp); ``set_smooth(False)`` gives flat faces."""

    #: blendify 2.1's EDGE_SPLIT angle: edges between faces meeting at a larger angle stay sharp
    SPLIT_ANGLE = 30.0

    def __init__(self, material: Any, colors: Any, faces_material: Any = None, tag: str = "", **pose: Any):
        super().__init__(material, colors, tag, **pose)
        self._smooth = True
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

    def _polygons(self) -> tuple[AnyArray, list[AnyArray], AnyArray | None]:  # pragma: no cover
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
        """Smooth shading with edges sharper than :attr:`SPLIT_ANGLE` kept (the default, as blendify 2.1's
        shade-smooth + edge split) or flat faces (``False``)."""
        self._smooth = as_bool("smooth", smooth)
        self._bump("geometry")

    def _bounds_vertices(self) -> AnyArray:
        """The polygons' corners (the mesh's vertices, without its triangulation and normals)."""
        return self._polygons()[0]

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
    def faces_material(self) -> AnyArray | None:
        if self._faces_material_poly is None:
            return None
        return self._faces_material_poly[self.to_mesh().face_polygon]

    def to_dict(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
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

    def _polygons(self) -> tuple[AnyArray, list[AnyArray], AnyArray | None]:
        h = self.size / 2.0
        verts: list[AnyArray] = []
        polys: list[AnyArray] = []
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


def _ring(radius: float, n: int, z: float = 0.0) -> AnyArray:
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.stack([radius * np.cos(a), radius * np.sin(a), np.full(n, z)], axis=1)


def _fill(ring_idx: AnyArray, verts: list[AnyArray], centre: AnyArray, fill: str, flip: bool) -> list[AnyArray]:
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

    def _polygons(self) -> tuple[AnyArray, list[AnyArray], AnyArray | None]:
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

    def _polygons(self) -> tuple[AnyArray, list[AnyArray], AnyArray | None]:
        n, h = self.num_vertices, self.height / 2.0
        bottom, top = _ring(self.radius, n, -h), _ring(self.radius, n, h)
        if 360.0 / n <= self.SPLIT_ANGLE:  # round sides: shared vertices with radial normals
            verts = list(bottom) + list(top)
            normals = [np.array([p[0], p[1], 0.0]) / self.radius for p in bottom] * 2
            polys = [np.array([j, (j + 1) % n, n + (j + 1) % n, n + j]) for j in range(n)]
        else:  # the edge split keeps every side edge sharp: flat sides, vertices split per side
            verts, normals, polys = [], [], []
            for j in range(n):
                k = (j + 1) % n
                mid = (bottom[j] + bottom[k]) / 2.0
                normal = np.array([mid[0], mid[1], 0.0]) / np.hypot(mid[0], mid[1])
                polys.append(np.arange(len(verts), len(verts) + 4))
                verts += [bottom[j], bottom[k], top[k], top[j]]
                normals += [normal] * 4
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

    def _polygons(self) -> tuple[AnyArray, list[AnyArray], AnyArray | None]:
        h = self.size / 2.0
        v = np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]])
        return v, [np.arange(4)], None

    def to_mesh(self) -> TriMesh:
        m = super().to_mesh()
        m.uv = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], dtype=np.float32)
        return m

    def _params(self) -> dict[str, Any]:
        return {"size": self.size, "shadow_catcher": self._shadow_catcher}


PRIMITIVES = {c.kind: c for c in (CubeMesh, CircleMesh, CylinderMesh, PlaneMesh)}
