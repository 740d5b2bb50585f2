"""The base of every renderable: material(s), colour source(s), shadows, pose and revisions.

All renderables are positionable (any rotation mode), carry a material (or a list of materials with
``faces_material``) and a colour source, and are two-sided in every backend. Geometry is stored in
OBJECT space, float64 (backends re-centre in float64 before handing float32 to an engine).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.errors import describe as _describe
from blendify_core.ir.colors import Colors, UniformColors
from blendify_core.ir.geometry import TriMesh
from blendify_core.ir.materials import Material, check_material
from blendify_core.ir.transforms import Positionable
from blendify_core.ir.validate import as_bool
from blendify_core.typing import AnyArray

__all__ = ["Renderable"]


def _column_bounds(v: AnyArray) -> tuple[AnyArray, AnyArray]:
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

    def world_bounds(self) -> tuple[AnyArray, AnyArray]:
        """Axis-aligned bounds (min, max) in world space: the tessellation's, rotated. The rotated bounds are
        kept per geometry revision and rotation (a translation only shifts them), so a render's several
        checks tessellate each primitive once (the scene's bounds for 2000 spheres and 2000 cubes: 3.2 s
        each time before, 0.03 s)."""
        key = self.revision("geometry")
        rotation = self.quaternion
        kept = self.__dict__.get("_rotated_bounds")
        if kept is None or kept[0] != key or not np.array_equal(kept[1], rotation):
            vertices = self._bounds_vertices()
            if len(vertices) == 0:
                lo = hi = np.zeros(3)
            else:
                v = vertices @ self.rotation_matrix.T
                lo, hi = v.min(axis=0), v.max(axis=0)
            kept = (key, rotation, lo, hi)
            self.__dict__["_rotated_bounds"] = kept  # replaced, never changed: a view's copy keeps the original's
        return kept[2] + self.translation, kept[3] + self.translation

    def _bounds_vertices(self) -> AnyArray:
        """Object-space vertices whose bounds are the object's (the tessellation's)."""
        return self.to_mesh().vertices

    def _base_dict(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
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
