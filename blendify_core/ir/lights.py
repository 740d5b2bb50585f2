"""Lights in Blender's units: point/spot/area power in watts, sun irradiance in W/m^2, background as
colour x strength (radiance), environment maps as an HDR image x strength.

Spot, sun and area lights emit along their local -Z axis (rotate them with any rotation mode, e.g.
``rotation_mode="look_at", rotation=target``). Colours are sRGB-encoded unless ``color_space="linear"``;
backends read ``linear_color``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.colors import COLOR_SPACES, _check_image, _to_linear, load_image
from blendify_core.ir.colorspace import srgb8_to_linear
from blendify_core.ir.transforms import Positionable, ValidatedParam, quaternion_from_rotation, quaternion_to_matrix
from blendify_core.ir.validate import (
    _describe,
    as_array,
    as_bool,
    as_choice,
    as_float,
    check_tag,
    frozen,
    raw_array,
    strict_arguments,
)


def _non_negative(obj: Any, name: str, value: Any) -> float:
    return as_float(name, value, min_value=0.0)


__all__ = [
    "Light",
    "PointLight",
    "SunLight",
    "SpotLight",
    "AreaLight",
    "SquareAreaLight",
    "CircleAreaLight",
    "RectangleAreaLight",
    "EllipseAreaLight",
    "BackgroundLight",
    "EnvironmentMap",
    "LightsCollection",
]


def _quaternion(name: str, value: Any) -> np.ndarray:
    return quaternion_from_rotation("quaternionWXYZ", value, name=name)


def _rgb(name: str, value: Any) -> tuple[float, float, float]:
    arr = as_array(name, value, ndim=1, min_value=0.0, max_value=1.0)
    if arr.shape[0] not in (3, 4):
        raise InvalidSceneError(f"{name}: expected 3 (RGB) values (a 4th, alpha, is ignored), got {arr.shape[0]}")
    return (float(arr[0]), float(arr[1]), float(arr[2]))


class Light(Positionable):
    """Base of positioned lights."""

    kind = "light"
    prefix = "Light"

    def __init__(
        self,
        strength: float,
        color: Any = (1.0, 1.0, 1.0),
        use_shadow: bool = True,
        color_space: str = "srgb",
        tag: str | None = None,
        **pose: Any,
    ):
        self._tag = tag or ""
        self._strength = as_float("strength", strength, min_value=0.0)
        self._color = _rgb("color", color)
        self._use_shadow = as_bool("use_shadow", use_shadow)
        self.color_space = as_choice("color_space", color_space, COLOR_SPACES)
        super().__init__(**pose)

    @property
    def strength(self) -> float:
        return self._strength

    @strength.setter
    def strength(self, value: float) -> None:
        self._strength = as_float("strength", value, min_value=0.0)
        self._bump("appearance")

    @property
    def color(self) -> tuple[float, float, float]:
        return self._color

    @color.setter
    def color(self, value: Any) -> None:
        self._color = _rgb("color", value)
        self._bump("appearance")

    @property
    def use_shadow(self) -> bool:
        return self._use_shadow

    @use_shadow.setter
    def use_shadow(self, value: bool) -> None:
        self._use_shadow = as_bool("use_shadow", value)
        self._bump("appearance")

    @property
    def linear_color(self) -> np.ndarray:
        """(3,) float64 linear RGB."""
        return _to_linear(np.array(self._color), self.color_space)

    @property
    def direction(self) -> np.ndarray:
        """(3,) unit world direction of emission (local -Z)."""
        return -self.rotation_matrix[:, 2]

    def _params(self) -> dict[str, Any]:
        return {
            "strength": self._strength,
            "color": list(self._color),
            "use_shadow": self._use_shadow,
            "color_space": self.color_space,
        }

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "tag": self.tag,
            "params": self._params(),
            "quaternion": self.quaternion.tolist(),
            "translation": self.translation.tolist(),
        }

    def __repr__(self) -> str:
        return f"{type(self).__name__}(tag={self.tag!r}, strength={self._strength:g})"


class PointLight(Light):
    """A point (spherical) light of power ``strength`` watts and radius ``shadow_soft_size`` metres."""

    kind = "point"
    prefix = "Point"
    shadow_soft_size = ValidatedParam(_non_negative, doc="Emitter radius in metres (soft shadows).")

    def __init__(
        self,
        strength: float = 100.0,
        shadow_soft_size: float = 0.25,
        color: Any = (1.0, 1.0, 1.0),
        use_shadow: bool = True,
        **kwargs: Any,
    ):
        self.shadow_soft_size = shadow_soft_size
        super().__init__(strength, color, use_shadow, **kwargs)

    def _params(self) -> dict[str, Any]:
        return {**super()._params(), "shadow_soft_size": self.shadow_soft_size}


class SunLight(Light):
    """A sun: irradiance ``strength`` W/m^2 on a surface facing it, ``angular_diameter`` radians."""

    kind = "sun"
    prefix = "Sun"
    angular_diameter = ValidatedParam(
        lambda obj, name, v: as_float(name, v, min_value=0.0, max_value=np.pi), doc="Angular diameter (radians)."
    )

    def __init__(
        self,
        strength: float = 10.0,
        angular_diameter: float = 0.00918043,
        color: Any = (1.0, 1.0, 1.0),
        use_shadow: bool = True,
        **kwargs: Any,
    ):
        self.angular_diameter = angular_diameter
        super().__init__(strength, color, use_shadow, **kwargs)

    def _params(self) -> dict[str, Any]:
        return {**super()._params(), "angular_diameter": self.angular_diameter}


class SpotLight(Light):
    """A spot light: ``strength`` W (as the point light it would be without the cone), full cone angle
    ``spot_size`` radians in [1 deg, 180 deg], edge ``spot_blend`` in [0, 1]."""

    kind = "spot"
    prefix = "Spot"
    spot_size = ValidatedParam(
        lambda obj, name, v: as_float(name, v, min_value=np.deg2rad(1.0), max_value=np.pi),
        doc="Full cone angle (radians, 1 to 180 degrees).",
    )
    spot_blend = ValidatedParam(
        lambda obj, name, v: as_float(name, v, min_value=0.0, max_value=1.0), doc="Soft cone edge, 0 to 1."
    )
    shadow_soft_size = ValidatedParam(_non_negative, doc="Emitter radius in metres (soft shadows).")

    def __init__(
        self,
        strength: float = 100.0,
        spot_size: float = np.pi / 4,
        spot_blend: float = 0.15,
        shadow_soft_size: float = 0.25,
        color: Any = (1.0, 1.0, 1.0),
        use_shadow: bool = True,
        **kwargs: Any,
    ):
        self.spot_size = spot_size
        self.spot_blend = spot_blend
        self.shadow_soft_size = shadow_soft_size
        super().__init__(strength, color, use_shadow, **kwargs)

    def _params(self) -> dict[str, Any]:
        return {
            **super()._params(),
            "spot_size": self.spot_size,
            "spot_blend": self.spot_blend,
            "shadow_soft_size": self.shadow_soft_size,
        }


class AreaLight(Light):
    """A one-sided area light emitting along local -Z with total power ``strength`` W (Blender's
    normalised area light). ``shape``: "square"/"circle" take a float ``size`` (edge / diameter),
    "rectangle"/"ellipse" a pair (size_x, size_y)."""

    kind = "area"
    prefix = "Area"
    SHAPES = ("square", "circle", "rectangle", "ellipse")

    def __init__(
        self,
        shape: str,
        size: Any,
        strength: float = 100.0,
        color: Any = (1.0, 1.0, 1.0),
        use_shadow: bool = True,
        **kwargs: Any,
    ):
        self._shape = as_choice("shape", shape, self.SHAPES)
        self.size = size
        super().__init__(strength, color, use_shadow, **kwargs)

    def _check_size(self, name: str, size: Any) -> tuple[float, float]:
        if self.shape in ("square", "circle"):
            if raw_array(name, size).ndim != 0:
                raise InvalidSceneError(f"{name}: a {self.shape} area light takes one number, got {_describe(size)}")
            s = as_float(name, size, min_value=0.0, exclusive_min=True)
            return (s, s)
        arr = as_array(name, size, shape=(2,), min_value=0.0)
        if np.any(arr <= 0):
            raise InvalidSceneError(f"{name}: expected two positive numbers, got {arr.tolist()}")
        return (float(arr[0]), float(arr[1]))

    size = ValidatedParam(
        lambda obj, name, v: obj._check_size(name, v),
        doc="(size_x, size_y) in metres; set a number for square/circle lights, a pair for rectangle/ellipse.",
    )

    @property
    def shape(self) -> str:
        """The outline: square, circle, rectangle or ellipse (fixed at creation)."""
        return self._shape

    @shape.setter
    def shape(self, value: Any) -> None:
        raise InvalidSceneError(f"shape: fixed at creation (got {value!r}); add a new area light instead")

    @property
    def area(self) -> float:
        a, b = self.size
        return a * b if self.shape in ("square", "rectangle") else np.pi * a * b / 4.0

    @property
    def radiance(self) -> np.ndarray:
        """(3,) linear emitted radiance P / (pi A) x colour (W / m^2 / sr)."""
        return self.linear_color * self.strength / (np.pi * self.area)

    def _params(self) -> dict[str, Any]:
        size: Any = self.size[0] if self.shape in ("square", "circle") else list(self.size)
        return {**super()._params(), "shape": self.shape, "size": size}


SquareAreaLight = CircleAreaLight = RectangleAreaLight = EllipseAreaLight = AreaLight


class BackgroundLight:
    """Uniform light from the whole sky: radiance = colour x strength (Blender's world Background)."""

    kind = "background"
    strength = ValidatedParam(_non_negative, doc="Strength (multiplies the colour).")
    color = ValidatedParam(lambda obj, name, v: _rgb(name, v), doc="RGB colour.")
    color_space = ValidatedParam(lambda obj, name, v: as_choice(name, v, COLOR_SPACES), doc="'srgb' or 'linear'.")

    def __init__(self, strength: float = 1.0, color: Any = (1.0, 1.0, 1.0), color_space: str = "srgb"):
        self.strength = as_float("strength", strength, min_value=0.0)
        self.color = _rgb("color", color)
        self.color_space = as_choice("color_space", color_space, COLOR_SPACES)

    @property
    def linear_color(self) -> np.ndarray:
        return _to_linear(np.array(self.color), self.color_space)

    @property
    def radiance(self) -> np.ndarray:
        return self.linear_color * self.strength

    def to_dict(self) -> dict[str, Any]:
        return {"strength": self.strength, "color": list(self.color), "color_space": self.color_space}


class EnvironmentMap:
    """Image-based lighting from an equirectangular (lat-long) image: a float HDR array (H, W, 3|4,
    linear, any non-negative value), a uint8 image (sRGB) or a file path (.exr, .hdr, .png, .jpg).

    Mapping: Blender's equirectangular convention, implemented once in :func:`equirect_uv` (world
    direction -> (u, v), u = 0.5 - atan2(d_y, d_x) / (2 pi), v = 0.5 + asin(d_z) / pi, v = 1 at the top
    row), applied after rotating the direction by the inverse of ``rotation`` (any rotation mode). Every
    backend must reproduce this mapping.
    """

    kind = "environment"
    strength = ValidatedParam(_non_negative, doc="Strength (multiplies the image).")
    quaternion = ValidatedParam(
        lambda obj, name, v: frozen(_quaternion(name, v)), doc="Rotation of the map (unit WXYZ quaternion)."
    )

    def __init__(
        self,
        image_or_path: Any,
        strength: float = 1.0,
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        color_space: str | None = None,
    ):
        self.path: str | None = None
        self._image: np.ndarray | None = None
        if isinstance(image_or_path, (str, os.PathLike)):
            p = Path(image_or_path).expanduser()
            if not p.is_file():
                raise InvalidSceneError(f"image_or_path: no such file {str(p)!r}")
            self.path = str(p.resolve())
        else:
            self._image = _check_image("image_or_path", image_or_path, max_value=None)
        self.strength = as_float("strength", strength, min_value=0.0)
        self.quaternion = frozen(quaternion_from_rotation(rotation_mode, rotation))
        if color_space is None:
            color_space = "linear" if (self._image is not None and self._image.dtype != np.uint8) else "srgb"
            if self.path and Path(self.path).suffix.lower() in (".exr", ".hdr"):
                color_space = "linear"
        self.color_space = as_choice("color_space", color_space, COLOR_SPACES)

    def image(self) -> np.ndarray:
        if self._image is None:
            self._image = frozen(load_image(str(self.path)))
        return self._image

    def linear_rgb_image(self) -> np.ndarray:
        """(H, W, 3) float32 linear radiance before ``strength``; row 0 = top (the sky)."""
        img = self.image()
        if img.shape[2] == 1:
            img = np.repeat(img, 3, axis=2)
        rgb = img[..., :3]
        if rgb.dtype == np.uint8:
            return srgb8_to_linear(rgb) if self.color_space == "srgb" else rgb.astype(np.float32) / 255.0
        out = rgb.astype(np.float32)
        return _to_linear(out, self.color_space).astype(np.float32) if self.color_space == "srgb" else out

    @property
    def rotation_matrix(self) -> np.ndarray:
        return quaternion_to_matrix(self.quaternion)

    def to_dict(self, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
        d: dict[str, Any] = {
            "strength": self.strength,
            "quaternion": self.quaternion.tolist(),
            "color_space": self.color_space,
            "path": self.path,
        }
        if self.path is None:
            arrays["environment.image"] = self.image()
            d["image"] = "environment.image"
        return d


def equirect_uv(directions: np.ndarray) -> np.ndarray:
    """Map world directions (..., 3) to equirectangular texture coordinates (..., 2), u right, v up."""
    d = np.asarray(directions, dtype=np.float64)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    u = 0.5 - np.arctan2(d[..., 1], d[..., 0]) / (2 * np.pi)
    v = 0.5 + np.arcsin(np.clip(d[..., 2], -1.0, 1.0)) / np.pi
    return np.stack([u % 1.0, v], axis=-1)


_LIGHT_CLASSES = {"point": PointLight, "sun": SunLight, "spot": SpotLight, "area": AreaLight}


class LightsCollection:
    """The lights of one scene: ``add_point``, ``add_sun``, ``add_spot``, ``add_area``,
    ``set_background_light``, ``set_environment_map``; ``[tag]``, ``remove``, iteration, ``len``."""

    def __init__(self) -> None:
        self._lights: dict[str, Light] = {}
        self._counters: dict[str, int] = {}
        self.background: BackgroundLight | None = None
        self.environment: EnvironmentMap | None = None
        self.revision = 0

    def _add(self, light: Light, tag: str | None) -> Light:
        if tag is None:
            n = self._counters.get(light.prefix, 0)
            while f"{light.prefix}_{n:03d}" in self._lights:
                n += 1
            self._counters[light.prefix] = n + 1
            tag = f"{light.prefix}_{n:03d}"
        else:
            check_tag("tag", tag)
            if tag in self._lights:
                raise InvalidSceneError(f"tag: a light tagged {tag!r} already exists in this scene")
        light._tag = tag
        self._lights[tag] = light
        self.revision += 1
        return light

    @strict_arguments
    def add_point(
        self,
        strength: float = 100.0,
        shadow_soft_size: float = 0.25,
        color: Any = (1.0, 1.0, 1.0),
        use_shadow: bool = True,
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        tag: str | None = None,
        color_space: str = "srgb",
    ) -> PointLight:
        light = PointLight(
            strength,
            shadow_soft_size,
            color,
            use_shadow,
            rotation_mode=rotation_mode,
            rotation=rotation,
            translation=translation,
            color_space=color_space,
        )
        return self._add(light, tag)  # type: ignore[return-value]

    @strict_arguments
    def add_sun(
        self,
        strength: float = 10.0,
        angular_diameter: float = 0.00918043,
        color: Any = (1.0, 1.0, 1.0),
        use_shadow: bool = True,
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        tag: str | None = None,
        color_space: str = "srgb",
    ) -> SunLight:
        light = SunLight(
            strength,
            angular_diameter,
            color,
            use_shadow,
            rotation_mode=rotation_mode,
            rotation=rotation,
            translation=translation,
            color_space=color_space,
        )
        return self._add(light, tag)  # type: ignore[return-value]

    @strict_arguments
    def add_spot(
        self,
        strength: float = 100.0,
        spot_size: float = np.pi / 4,
        spot_blend: float = 0.15,
        shadow_soft_size: float = 0.25,
        color: Any = (1.0, 1.0, 1.0),
        use_shadow: bool = True,
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        tag: str | None = None,
        color_space: str = "srgb",
    ) -> SpotLight:
        light = SpotLight(
            strength,
            spot_size,
            spot_blend,
            shadow_soft_size,
            color,
            use_shadow,
            rotation_mode=rotation_mode,
            rotation=rotation,
            translation=translation,
            color_space=color_space,
        )
        return self._add(light, tag)  # type: ignore[return-value]

    @strict_arguments
    def add_area(
        self,
        shape: str,
        size: Any,
        strength: float = 100.0,
        color: Any = (1.0, 1.0, 1.0),
        use_shadow: bool = True,
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        translation: Any = (0, 0, 0),
        tag: str | None = None,
        color_space: str = "srgb",
    ) -> AreaLight:
        light = AreaLight(
            shape,
            size,
            strength,
            color,
            use_shadow,
            rotation_mode=rotation_mode,
            rotation=rotation,
            translation=translation,
            color_space=color_space,
        )
        return self._add(light, tag)  # type: ignore[return-value]

    @strict_arguments
    def set_background_light(
        self, strength: float = 1.0, color: Any = (1.0, 1.0, 1.0), color_space: str = "srgb"
    ) -> BackgroundLight:
        self.background = BackgroundLight(strength, color, color_space)
        self.revision += 1
        return self.background

    def remove_background_light(self) -> None:
        self.background = None
        self.revision += 1

    @strict_arguments
    def set_environment_map(
        self,
        image_or_path: Any,
        strength: float = 1.0,
        rotation_mode: str = "quaternionWXYZ",
        rotation: Any = None,
        color_space: str | None = None,
    ) -> EnvironmentMap:
        self.environment = EnvironmentMap(image_or_path, strength, rotation_mode, rotation, color_space)
        self.revision += 1
        return self.environment

    def remove_environment_map(self) -> None:
        self.environment = None
        self.revision += 1

    # -- collection protocol -------------------------------------------------------------------
    def remove(self, obj_or_tag: Light | str) -> None:
        tag = obj_or_tag.tag if isinstance(obj_or_tag, Light) else obj_or_tag
        if not isinstance(tag, str) or tag not in self._lights:
            raise KeyError(f"no light tagged {tag!r} in this scene")
        del self._lights[tag]
        self.revision += 1

    def __getitem__(self, tag: str) -> Light:
        try:
            return self._lights[tag]
        except KeyError:
            raise KeyError(f"no light tagged {tag!r} in this scene; tags: {list(self._lights)}") from None

    def __delitem__(self, tag: str) -> None:
        self.remove(tag)

    def __contains__(self, tag: object) -> bool:
        return tag in self._lights

    def __iter__(self):  # type: ignore[no-untyped-def]
        return iter(list(self._lights.values()))

    def __len__(self) -> int:
        return len(self._lights)

    def keys(self) -> list[str]:
        return list(self._lights.keys())

    def values(self) -> list[Light]:
        return list(self._lights.values())

    def items(self) -> list[tuple[str, Light]]:
        return list(self._lights.items())

    def clear(self) -> None:
        self._lights.clear()
        self.background = None
        self.environment = None
        self.revision += 1


def light_from_dict(d: dict[str, Any]) -> Light:
    cls = _LIGHT_CLASSES.get(d.get("kind", ""))
    if cls is None:
        raise InvalidSceneError(f"scene file: unknown light kind {d.get('kind')!r}")
    light = cls(**d["params"], rotation=d["quaternion"], translation=d["translation"])
    light._tag = d["tag"]
    return light
