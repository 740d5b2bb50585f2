"""Materials: Blender's Principled BSDF parameter set (blendify's names and defaults) and friends.

The base colour of an object comes from its colour source (``colors=`` of ``add_*``), not from the
material, as in blendify. Colour parameters of materials (``emission_color``, ``coat_tint``, ``sheen_tint``,
``specular_tint``, ``wireframe_color``) are sRGB-encoded unless the material is created with
``color_space="linear"``; backends read linear values with :meth:`Material.linear`.

Attributes are readable and settable (validated on every assignment); each change bumps
``material.revision`` so backends know to update.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.colors import COLOR_SPACES, NormalMap, TextureMap, _to_linear
from blendify_core.ir.physics import material_lobes
from blendify_core.ir.validate import _describe, as_array, as_choice, as_float, reject_unknown, strict_arguments

__all__ = [
    "Material",
    "PrincipledBSDFMaterial",
    "DiffuseMaterial",
    "GlossyBSDFMaterial",
    "MetalMaterial",
    "PlasticMaterial",
    "PrincipledBSDFWireframeMaterial",
    "PlasticWireframeMaterial",
    "MetalWireframeMaterial",
    "material_from_dict",
]


@dataclass(frozen=True)
class _Param:
    name: str
    default: Any
    kind: str = "float"  # float | color | vec3 | texture | normal_map | choice
    min_value: float | None = 0.0
    max_value: float | None = 1.0
    choices: tuple[str, ...] = ()


def _principled_params() -> list[_Param]:
    inf = None
    return [
        _Param("alpha", 1.0),
        _Param("anisotropic", 0.0),
        _Param("anisotropic_rotation", 0.0),
        _Param("coat_ior", 1.5, min_value=1.0, max_value=4.0),
        _Param("coat_roughness", 0.0),
        _Param("coat_tint", (1.0, 1.0, 1.0, 1.0), "color"),
        _Param("coat_weight", 0.0),
        _Param("diffuse_roughness", 0.0),
        _Param("emission_color", (0.0, 0.0, 0.0, 0.0), "color"),
        _Param("emission_strength", 0.0, max_value=inf),
        _Param("ior", 1.45, min_value=1.0, max_value=1000.0),
        _Param("metallic", 0.0),
        _Param("roughness", 0.4),
        _Param("sheen_weight", 0.0),
        _Param("sheen_roughness", 0.5),
        _Param("sheen_tint", (0.5, 0.5, 0.5, 1.0), "color"),
        _Param("specular_ior", 0.3, max_value=inf),
        _Param("specular_tint", (0.0, 0.0, 0.0, 1.0), "color"),
        _Param("subsurface_anisotropy", 0.0, min_value=-1.0),
        _Param("subsurface_radius", (1.0, 0.2, 1.0), "vec3", max_value=inf),
        _Param("subsurface_scale", 0.05, max_value=inf),
        _Param("subsurface_weight", 0.0),
        _Param("thin_film_ior", 1.33, min_value=1.0, max_value=1000.0),
        _Param("thin_film_thickness", 0.0, max_value=100000.0),
        _Param("transmission_weight", 0.0),
        _Param("roughness_map", None, "texture"),
        _Param("metallic_map", None, "texture"),
        _Param("normal_map", None, "normal_map"),
    ]


class Material:
    """Base of all materials. Subclasses declare their parameters in ``_params``."""

    _params: tuple[_Param, ...] = ()
    kind = "material"

    def __init__(self, color_space: str = "srgb", **kwargs: Any):
        object.__setattr__(self, "_values", {})
        object.__setattr__(self, "revision", 0)
        object.__setattr__(self, "color_space", as_choice("color_space", color_space, COLOR_SPACES))
        names = {p.name for p in self._params}
        reject_unknown(type(self).__name__, kwargs, names)
        for p in self._params:
            self._set(p, kwargs.get(p.name, p.default))

    # -- parameter access ------------------------------------------------------------------------
    @classmethod
    def parameter_names(cls) -> tuple[str, ...]:
        return tuple(p.name for p in cls._params)

    def _param(self, name: str) -> _Param | None:
        for p in self._params:
            if p.name == name:
                return p
        return None

    def _set(self, p: _Param, value: Any) -> None:
        if p.kind == "float":
            v: Any = as_float(p.name, value, min_value=p.min_value, max_value=p.max_value)
        elif p.kind == "color":
            arr = as_array(p.name, value, ndim=1, min_value=0.0, max_value=1.0)
            if arr.shape[0] not in (3, 4):
                raise InvalidSceneError(f"{p.name}: expected 3 (RGB) or 4 (RGBA) values, got {arr.shape[0]}")
            v = tuple(float(x) for x in arr)
        elif p.kind == "vec3":
            v = tuple(float(x) for x in as_array(p.name, value, shape=(3,), min_value=p.min_value))
        elif p.kind == "texture":
            if value is not None and (not isinstance(value, TextureMap) or isinstance(value, NormalMap)):
                raise InvalidSceneError(f"{p.name}: expected a TextureMap or None, got {_describe(value)}")
            v = value
        elif p.kind == "normal_map":
            if value is not None and not isinstance(value, NormalMap):
                raise InvalidSceneError(f"{p.name}: expected a NormalMap or None, got {_describe(value)}")
            v = value
        elif p.kind == "choice":
            v = as_choice(p.name, value, p.choices)
        else:  # pragma: no cover - declaration error
            raise TypeError(p.kind)
        self._values[p.name] = v

    def __getattr__(self, name: str) -> Any:
        values = self.__dict__.get("_values")
        if values is not None and name in values:
            return values[name]
        raise AttributeError(f"{type(self).__name__} has no attribute {name!r}")

    def __setattr__(self, name: str, value: Any) -> None:
        p = self._param(name)
        if p is None:
            if name.startswith("_"):
                object.__setattr__(self, name, value)
                return
            raise InvalidSceneError(
                f"{type(self).__name__}: unknown parameter {name!r}; known: {list(self.parameter_names())}"
            )
        self._set(p, value)
        object.__setattr__(self, "revision", self.revision + 1)

    def get(self, name: str) -> Any:
        return self._values[name]

    def __copy__(self) -> Material:
        # parameters live in one dict: a shallow copy must not share it, or setting an attribute on the
        # copy would change the original
        new = type(self).__new__(type(self))
        new.__dict__.update(self.__dict__)
        new.__dict__["_values"] = dict(self._values)
        return new

    def linear(self, name: str) -> np.ndarray:
        """A colour parameter as linear RGBA (4,) float64 (alpha is 1 when only RGB was given)."""
        p = self._param(name)
        if p is None or p.kind != "color":
            raise InvalidSceneError(f"{name}: not a colour parameter of {type(self).__name__}")
        rgba = np.ones(4)
        c = self._values[name]
        rgba[: len(c)] = c
        return _to_linear(rgba, self.color_space)

    def parameters(self) -> dict[str, Any]:
        return dict(self._values)

    def copy(self, **changes: Any) -> Material:
        values = {k: v for k, v in self._values.items()}
        values.update(changes)
        return type(self)(color_space=self.color_space, **values)

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return self.color_space == other.color_space and self._values == other._values  # type: ignore[attr-defined]

    __hash__ = object.__hash__

    def __repr__(self) -> str:
        changed = {p.name: self._values[p.name] for p in self._params if self._values[p.name] != p.default}
        body = ", ".join(f"{k}={v!r}" for k, v in changed.items())
        return f"{type(self).__name__}({body})"

    # -- analysis helpers used by backends and the effect analysis -----------------------------
    @property
    def has_wireframe(self) -> bool:
        return "wireframe_thickness" in self._values

    @property
    def is_emissive(self) -> bool:
        v = self._values
        return float(v.get("emission_strength", 0.0)) > 0 and max(v.get("emission_color", (0, 0, 0))[:3]) > 0

    @property
    def is_diffuse_only(self) -> bool:
        """True when the material is an exact Lambertian reflector (no specular, metal, transmission, ...)."""
        return material_lobes(self).diffuse_only

    def to_dict(self, arrays: dict[str, np.ndarray], prefix: str) -> dict[str, Any]:
        params: dict[str, Any] = {}
        for p in self._params:
            v = self._values[p.name]
            if p.kind in ("texture", "normal_map"):
                params[p.name] = None if v is None else v.to_dict(arrays, f"{prefix}{p.name}.")
            else:
                params[p.name] = list(v) if isinstance(v, tuple) else v
        return {"kind": type(self).__name__, "color_space": self.color_space, "params": params}


class PrincipledBSDFMaterial(Material):
    """Blender's Principled BSDF. ``specular_ior`` is Blender's "Specular IOR Level" (0.5 = IOR unchanged,
    0 = no specular layer), as in blendify. Optional ``roughness_map``/``metallic_map`` (TextureMap) and
    ``normal_map`` (NormalMap) drive those inputs from textures through the mesh's UVs."""

    _params = tuple(_principled_params())
    kind = "principled"

    def __init__(
        self,
        alpha: float = 1.0,
        anisotropic: float = 0.0,
        anisotropic_rotation: float = 0.0,
        coat_ior: float = 1.5,
        coat_roughness: float = 0.0,
        coat_tint: Any = (1.0, 1.0, 1.0, 1.0),
        coat_weight: float = 0.0,
        diffuse_roughness: float = 0.0,
        emission_color: Any = (0.0, 0.0, 0.0, 0.0),
        emission_strength: float = 0.0,
        ior: float = 1.45,
        metallic: float = 0.0,
        roughness: float = 0.4,
        sheen_weight: float = 0.0,
        sheen_roughness: float = 0.5,
        sheen_tint: Any = (0.5, 0.5, 0.5, 1.0),
        specular_ior: float = 0.3,
        specular_tint: Any = (0.0, 0.0, 0.0, 1.0),
        subsurface_anisotropy: float = 0.0,
        subsurface_radius: Any = (1.0, 0.2, 1.0),
        subsurface_scale: float = 0.05,
        subsurface_weight: float = 0.0,
        thin_film_ior: float = 1.33,
        thin_film_thickness: float = 0.0,
        transmission_weight: float = 0.0,
        roughness_map: TextureMap | None = None,
        metallic_map: TextureMap | None = None,
        normal_map: NormalMap | None = None,
        color_space: str = "srgb",
        **kwargs: Any,
    ):
        reject_unknown(type(self).__name__, kwargs, self._extra_names())
        super().__init__(
            color_space=color_space,
            alpha=alpha,
            anisotropic=anisotropic,
            anisotropic_rotation=anisotropic_rotation,
            coat_ior=coat_ior,
            coat_roughness=coat_roughness,
            coat_tint=coat_tint,
            coat_weight=coat_weight,
            diffuse_roughness=diffuse_roughness,
            emission_color=emission_color,
            emission_strength=emission_strength,
            ior=ior,
            metallic=metallic,
            roughness=roughness,
            sheen_weight=sheen_weight,
            sheen_roughness=sheen_roughness,
            sheen_tint=sheen_tint,
            specular_ior=specular_ior,
            specular_tint=specular_tint,
            subsurface_anisotropy=subsurface_anisotropy,
            subsurface_radius=subsurface_radius,
            subsurface_scale=subsurface_scale,
            subsurface_weight=subsurface_weight,
            thin_film_ior=thin_film_ior,
            thin_film_thickness=thin_film_thickness,
            transmission_weight=transmission_weight,
            roughness_map=roughness_map,
            metallic_map=metallic_map,
            normal_map=normal_map,
            **kwargs,
        )

    @classmethod
    def _extra_names(cls) -> tuple[str, ...]:
        return tuple(p.name for p in cls._params[len(_principled_params()) :])


class DiffuseMaterial(PrincipledBSDFMaterial):
    """An exact Lambertian reflector: Principled with no specular layer (renders identically in every
    path tracer; the reference material of cross-renderer tests)."""

    def __init__(self, **kwargs: Any):
        kwargs.setdefault("roughness", 1.0)
        kwargs.setdefault("specular_ior", 0.0)
        super().__init__(**kwargs)


class MetalMaterial(PrincipledBSDFMaterial):
    """Principled preset for metals (blendify's defaults: roughness 0.55, metallic 0.9)."""

    def __init__(
        self,
        roughness: float = 0.55,
        metallic: float = 0.9,
        coat_ior: float = 1.5,
        specular_ior: float = 0.5,
        coat_roughness: float = 0.0,
        **kwargs: Any,
    ):
        super().__init__(
            roughness=roughness,
            metallic=metallic,
            coat_ior=coat_ior,
            specular_ior=specular_ior,
            coat_roughness=coat_roughness,
            **kwargs,
        )


class PlasticMaterial(PrincipledBSDFMaterial):
    """Principled preset for plastics (blendify's defaults: roughness 0.3, IOR 1.45)."""

    def __init__(
        self,
        roughness: float = 0.3,
        ior: float = 1.45,
        coat_ior: float = 1.5,
        specular_ior: float = 0.5,
        coat_roughness: float = 0.0,
        **kwargs: Any,
    ):
        super().__init__(
            roughness=roughness,
            ior=ior,
            coat_ior=coat_ior,
            specular_ior=specular_ior,
            coat_roughness=coat_roughness,
            **kwargs,
        )


_WIRE = (
    _Param("wireframe_thickness", 0.01, min_value=0.0, max_value=None),
    _Param("wireframe_color", (0.0, 0.0, 0.0, 1.0), "color"),
)


class PrincipledBSDFWireframeMaterial(PrincipledBSDFMaterial):
    """Principled surface with the mesh edges drawn over it: ``wireframe_thickness`` in world units,
    ``wireframe_color`` (sRGB by default). The edges are the triangle edges of the mesh."""

    _params = PrincipledBSDFMaterial._params + _WIRE
    kind = "principled"

    def __init__(self, wireframe_thickness: float = 0.01, wireframe_color: Any = (0.0, 0.0, 0.0, 1.0), **kwargs: Any):
        super().__init__(wireframe_thickness=wireframe_thickness, wireframe_color=wireframe_color, **kwargs)


class PlasticWireframeMaterial(PrincipledBSDFWireframeMaterial):
    def __init__(
        self,
        roughness: float = 0.3,
        ior: float = 1.45,
        coat_ior: float = 1.5,
        specular_ior: float = 0.5,
        coat_roughness: float = 0.0,
        wireframe_thickness: float = 0.01,
        wireframe_color: Any = (0.0, 0.0, 0.0, 1.0),
        **kwargs: Any,
    ):
        super().__init__(
            roughness=roughness,
            ior=ior,
            coat_ior=coat_ior,
            specular_ior=specular_ior,
            coat_roughness=coat_roughness,
            wireframe_thickness=wireframe_thickness,
            wireframe_color=wireframe_color,
            **kwargs,
        )


class MetalWireframeMaterial(PrincipledBSDFWireframeMaterial):
    def __init__(
        self,
        roughness: float = 0.55,
        metallic: float = 0.9,
        coat_ior: float = 1.5,
        specular_ior: float = 0.5,
        coat_roughness: float = 0.0,
        wireframe_thickness: float = 0.01,
        wireframe_color: Any = (0.0, 0.0, 0.0, 1.0),
        **kwargs: Any,
    ):
        super().__init__(
            roughness=roughness,
            metallic=metallic,
            coat_ior=coat_ior,
            specular_ior=specular_ior,
            coat_roughness=coat_roughness,
            wireframe_thickness=wireframe_thickness,
            wireframe_color=wireframe_color,
            **kwargs,
        )


class GlossyBSDFMaterial(Material):
    """Blender's Glossy BSDF: a pure specular reflector tinted by the object's colour.
    ``distribution``: "GGX", "BECKMANN", "ASHIKHMIN_SHIRLEY" or "MULTI_GGX"."""

    _params = (
        _Param("roughness", 0.4),
        _Param("distribution", "GGX", "choice", choices=("GGX", "BECKMANN", "ASHIKHMIN_SHIRLEY", "MULTI_GGX")),
        _Param("alpha", 1.0),
    )
    kind = "glossy"

    @strict_arguments
    def __init__(
        self, roughness: float = 0.4, distribution: str = "GGX", alpha: float = 1.0, color_space: str = "srgb"
    ):
        super().__init__(color_space=color_space, roughness=roughness, distribution=distribution, alpha=alpha)


_MATERIAL_CLASSES = {
    cls.__name__: cls
    for cls in (
        PrincipledBSDFMaterial,
        DiffuseMaterial,
        GlossyBSDFMaterial,
        MetalMaterial,
        PlasticMaterial,
        PrincipledBSDFWireframeMaterial,
        PlasticWireframeMaterial,
        MetalWireframeMaterial,
    )
}


def check_material(name: str, value: Any) -> Material:
    if not isinstance(value, Material):
        raise InvalidSceneError(f"{name}: expected a Material (e.g. PrincipledBSDFMaterial()), got {_describe(value)}")
    return value


def material_from_dict(d: dict[str, Any], arrays: dict[str, np.ndarray], base_dir: str | None) -> Material:
    cls = _MATERIAL_CLASSES.get(d.get("kind", ""))
    if cls is None:
        raise InvalidSceneError(f"scene file: unknown material kind {d.get('kind')!r}")
    params = dict(d["params"])
    for key in ("roughness_map", "metallic_map", "normal_map"):
        t = params.get(key)
        if t is not None:
            src = arrays[t["image"]] if t.get("image") else _resolve(t["path"], base_dir)
            params[key] = (
                NormalMap(src, strength=t["strength"])
                if t["kind"] == "normal_map"
                else TextureMap(src, channel=t["channel"])
            )
    mat = Material.__new__(cls)
    Material.__init__(mat, color_space=d["color_space"], **params)
    return mat


def _resolve(path: str, base_dir: str | None) -> str:
    import os

    if base_dir is not None and not os.path.isabs(path):
        return os.path.join(base_dir, path)
    return path
