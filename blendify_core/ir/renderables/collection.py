"""The renderables of one scene (blendify's ``scene.renderables``): ``add_*`` methods derived from the
renderable classes, tags, and the collection protocol."""

from __future__ import annotations

from typing import Any

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.facade import facade
from blendify_core.ir.from_trimesh import add_trimesh
from blendify_core.ir.renderables.base import Renderable
from blendify_core.ir.renderables.mesh import Mesh
from blendify_core.ir.renderables.parametric import CurveBezier, EllipsoidNURBS, SphereNURBS
from blendify_core.ir.renderables.pointcloud import PointCloud
from blendify_core.ir.renderables.primitives import CircleMesh, CubeMesh, CylinderMesh, PlaneMesh
from blendify_core.ir.validate import check_tag, strict_api

__all__ = ["RenderablesCollection"]


def _add(collection: RenderablesCollection, cls: type, arguments: dict[str, Any]) -> Renderable:
    tag = arguments.pop("tag")
    obj: Renderable = collection._add(cls(**arguments), tag)
    return obj


def _adder(cls: type, name: str) -> Any:
    return facade(cls, name, "RenderablesCollection", _add)


@strict_api
class RenderablesCollection:
    """The renderables of one scene (blendify's ``scene.renderables``). Each ``add_*`` takes its class's
    constructor arguments, then the pose (``rotation_mode``, ``rotation``, ``translation``) and ``tag``."""

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

    add_mesh = _adder(Mesh, "add_mesh")
    add_pointcloud = _adder(PointCloud, "add_pointcloud")
    add_cube_mesh = _adder(CubeMesh, "add_cube_mesh")
    add_circle_mesh = _adder(CircleMesh, "add_circle_mesh")
    add_cylinder_mesh = _adder(CylinderMesh, "add_cylinder_mesh")
    add_plane_mesh = _adder(PlaneMesh, "add_plane_mesh")
    add_sphere_nurbs = _adder(SphereNURBS, "add_sphere_nurbs")
    add_ellipsoid_nurbs = _adder(EllipsoidNURBS, "add_ellipsoid_nurbs")
    add_curve_nurbs = _adder(CurveBezier, "add_curve_nurbs")

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
