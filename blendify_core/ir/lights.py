"""Lights in Blender's units: point/spot/area power in watts, sun irradiance in W/m^2, background as
colour x strength (radiance), environment maps as an HDR image x strength.

Every parameter is declared once, below, as a :class:`~blendify_core.ir.params.Param`; constructors,
``inspect.signature``, attribute validation, scene files, the ``add_*`` methods of
:class:`LightsCollection` and ``docs/parameters.md`` come from these declarations.

Spot, sun and area lights emit along their local -Z axis (rotate them with any rotation mode, e.g.
``rotation_mode="look_at", rotation=target``). Colours are sRGB-encoded unless ``color_space="linear"``;
backends read ``linear_color``.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.errors import describe as _describe
from blendify_core.ir.colors import COLOR_SPACES, _check_image, _to_linear, load_image
from blendify_core.ir.colorspace import srgb8_to_linear
from blendify_core.ir.facade import facade
from blendify_core.ir.params import (
    POSE,
    REQUIRED,
    ROTATION,
    ROTATION_MODE,
    TAG,
    Declared,
    Param,
    Signature,
    emission_param,
    encode_params,
)
from blendify_core.ir.transforms import Positionable, ValidatedParam, quaternion_from_rotation, quaternion_to_matrix
from blendify_core.ir.validate import as_array, as_choice, as_float, check_tag, frozen, raw_array, strict_api
from blendify_core.typing import AnyArray

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
    "equirect_uv",
]

# -- the declarations ---------------------------------------------------------------------------------

COLOR_SPACE = Param(
    "color_space", "srgb", "choice", choices=COLOR_SPACES, doc="Encoding of ``color``: 'srgb' or 'linear'"
)
COLOR = Param(
    "color",
    (1.0, 1.0, 1.0),
    "color",
    0.0,
    1.0,
    channels=(3,),
    doc="Colour of the light, RGB (sRGB unless color_space='linear'; a light has no alpha)",
)
#: blendify's set_background_light took RGBA: an opaque 4th value (1) is accepted and dropped, any other raises
BACKGROUND_COLOR = replace(
    COLOR, channels=(3, 4), opaque_alpha=True, doc="Colour of the background, RGB (sRGB unless color_space='linear')"
)
USE_SHADOW = Param("use_shadow", True, "bool", doc="Whether the light casts shadows")
POWER = emission_param("strength", 100.0, "Emitted power", unit="W")
SHADOW_SOFT_SIZE = Param(
    "shadow_soft_size", 0.25, "float", 0.0, None, unit="m", doc="Emitter radius (soft shadows; 0 = a point)"
)
_LIGHT_TAIL = (COLOR_SPACE, TAG, *POSE)  # inputs every positioned light takes by keyword


def _area_size(obj: Any, name: str, value: Any) -> tuple[float, float]:
    shape = obj._values["shape"]
    if shape in ("square", "circle"):
        if raw_array(name, value).ndim != 0:
            raise InvalidSceneError(f"{name}: a {shape} area light takes one number, got {_describe(value)}")
        s = as_float(name, value, min_value=0.0, exclusive_min=True)
        return (s, s)
    arr = as_array(name, value, shape=(2,), min_value=0.0)
    if np.any(arr <= 0):
        raise InvalidSceneError(f"{name}: expected two positive numbers, got {arr.tolist()}")
    return (float(arr[0]), float(arr[1]))


def _area_size_json(obj: Any, value: tuple[float, float]) -> Any:
    return value[0] if obj._values["shape"] in ("square", "circle") else list(value)


def _auto_color_space(obj: Any, name: str, value: Any) -> str:
    if value is not None:
        return as_choice(name, value, COLOR_SPACES)
    image = obj.__dict__.get("_image")
    if image is not None:
        return "srgb" if image.dtype == np.uint8 else "linear"
    return "linear" if Path(str(obj.path)).suffix.lower() in (".exr", ".hdr") else "srgb"


def _image_or_path(obj: Any, name: str, value: Any) -> Any:
    return value  # checked by EnvironmentMap._setup (a path or an image array)


# -- positioned lights ------------------------------------------------------------------------------------


class Light(Positionable, Declared):
    """Base of positioned lights."""

    _declared: tuple[Param, ...] = (
        emission_param("strength", REQUIRED, "Power", unit="W or W/m^2"),
        COLOR,
        USE_SHADOW,
        *_LIGHT_TAIL,
    )
    _signature = Signature(("strength", "color", "use_shadow", "color_space", "tag"), "pose")
    kind = "light"
    prefix = "Light"
    strength: float
    color: tuple[float, float, float]
    use_shadow: bool
    color_space: str

    def _setup(self, inputs: dict[str, Any]) -> None:
        self._tag = inputs["tag"] or ""
        self._init_values(inputs)
        Positionable.__init__(self, inputs["rotation_mode"], inputs["rotation"], inputs["translation"])

    def _param_changed(self, param: Param) -> None:
        self._bump(param.group)

    @property
    def linear_color(self) -> AnyArray:
        """(3,) float64 linear RGB."""
        return _to_linear(np.array(self.color), self.color_space)

    @property
    def direction(self) -> AnyArray:
        """(3,) unit world direction of emission (local -Z)."""
        return -self.rotation_matrix[:, 2]

    def _params(self) -> dict[str, Any]:
        """Every parameter as JSON (the scene file's ``params``)."""
        return encode_params(self, {})

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "tag": self.tag,
            "params": self._params(),
            "quaternion": self.quaternion.tolist(),
            "translation": self.translation.tolist(),
        }

    def __repr__(self) -> str:
        return f"{type(self).__name__}(tag={self.tag!r}, strength={self.strength:g})"


class PointLight(Light):
    """A point (spherical) light of power ``strength`` watts and radius ``shadow_soft_size`` metres."""

    _declared = (POWER, SHADOW_SOFT_SIZE, COLOR, USE_SHADOW, *_LIGHT_TAIL)
    _signature = Signature(("strength", "shadow_soft_size", "color", "use_shadow"), "kwargs")
    kind = "point"
    prefix = "Point"
    shadow_soft_size: float


class SunLight(Light):
    """A sun: irradiance ``strength`` W/m^2 on a surface facing it, ``angular_diameter`` radians."""

    _declared = (
        emission_param("strength", 10.0, "Irradiance on a surface facing the sun", unit="W/m^2"),
        Param("angular_diameter", 0.00918043, "float", 0.0, np.pi, unit="rad", doc="Angular diameter of the disc"),
        COLOR,
        USE_SHADOW,
        *_LIGHT_TAIL,
    )
    _signature = Signature(("strength", "angular_diameter", "color", "use_shadow"), "kwargs")
    kind = "sun"
    prefix = "Sun"
    angular_diameter: float


class SpotLight(Light):
    """A spot light: ``strength`` W (as the point light it would be without the cone), full cone angle
    ``spot_size`` radians in [1 deg, 180 deg], edge ``spot_blend`` in [0, 1]."""

    _declared = (
        POWER,
        Param(
            "spot_size",
            np.pi / 4,
            "float",
            float(np.deg2rad(1.0)),
            np.pi,
            unit="rad",
            doc="Full cone angle (1 to 180 degrees)",
        ),
        Param("spot_blend", 0.15, "float", 0.0, 1.0, doc="Softness of the cone's edge"),
        SHADOW_SOFT_SIZE,
        COLOR,
        USE_SHADOW,
        *_LIGHT_TAIL,
    )
    _signature = Signature(("strength", "spot_size", "spot_blend", "shadow_soft_size", "color", "use_shadow"), "kwargs")
    kind = "spot"
    prefix = "Spot"
    spot_size: float
    spot_blend: float
    shadow_soft_size: float


class AreaLight(Light):
    """A one-sided area light emitting along local -Z with total power ``strength`` W (Blender's
    normalised area light). ``shape``: "square"/"circle" take a float ``size`` (edge / diameter; Blender's
    "disk" is accepted for "circle", the capability key is ``light.area.disk``),
    "rectangle"/"ellipse" a pair (size_x, size_y)."""

    SHAPES = ("square", "circle", "rectangle", "ellipse")
    _declared = (
        Param(
            "shape",
            REQUIRED,
            "choice",
            choices=SHAPES,
            aliases=(("disk", "circle"),),
            fixed=True,
            doc="Outline of the emitter (Blender's name 'disk' is accepted for 'circle')",
        ),
        Param(
            "size",
            REQUIRED,
            "custom",
            unit="m",
            check_fn=_area_size,
            encode_fn=_area_size_json,
            type_text="float (square, circle) or (x, y) (rectangle, ellipse)",
            doc="Edge or diameter; a pair for rectangle / ellipse (read back as (size_x, size_y))",
        ),
        POWER,
        COLOR,
        USE_SHADOW,
        *_LIGHT_TAIL,
    )
    _signature = Signature(("shape", "size", "strength", "color", "use_shadow"), "kwargs")
    kind = "area"
    prefix = "Area"
    shape: str
    size: tuple[float, float]

    @property
    def area(self) -> float:
        a, b = self.size
        return a * b if self.shape in ("square", "rectangle") else float(np.pi * a * b / 4.0)

    @property
    def radiance(self) -> AnyArray:
        """(3,) linear emitted radiance P / (pi A) x colour (W / m^2 / sr)."""
        return self.linear_color * self.strength / (np.pi * self.area)


SquareAreaLight = CircleAreaLight = RectangleAreaLight = EllipseAreaLight = AreaLight


# -- world lights ---------------------------------------------------------------------------------------


class BackgroundLight(Declared):
    """Uniform light from the whole sky: radiance = colour x strength (Blender's world Background)."""

    _declared = (
        emission_param("strength", 1.0, "Multiplies the colour (radiance = color x strength)"),
        BACKGROUND_COLOR,
        COLOR_SPACE,
    )
    _signature = Signature(None, None)
    kind = "background"
    strength: float
    color: tuple[float, float, float]
    color_space: str

    @property
    def linear_color(self) -> AnyArray:
        return _to_linear(np.array(self.color), self.color_space)

    @property
    def radiance(self) -> AnyArray:
        return self.linear_color * self.strength

    def to_dict(self) -> dict[str, Any]:
        return encode_params(self, {})


class EnvironmentMap(Declared):
    """Image-based lighting from an equirectangular (lat-long) image: a float HDR array (H, W, 3|4,
    linear, any non-negative value), a uint8 image (sRGB) or a file path (.exr, .hdr, .png, .jpg).

    Mapping: Blender's equirectangular convention, implemented once in :func:`equirect_uv` (world
    direction -> (u, v), u = 0.5 - atan2(d_y, d_x) / (2 pi), v = 0.5 + asin(d_z) / pi, v = 1 at the top
    row), applied after rotating the direction by the inverse of ``rotation`` (any rotation mode). Every
    backend must reproduce this mapping.
    """

    _declared = (
        Param(
            "image_or_path",
            REQUIRED,
            "custom",
            stored=False,
            check_fn=_image_or_path,
            type_text="(H, W, 3|4) array or a path",
            doc="The equirectangular image: float HDR (linear), uint8 (sRGB) or an image file",
        ),
        emission_param("strength", 1.0, "Multiplies the image"),
        ROTATION_MODE,
        ROTATION,
        Param(
            "color_space",
            None,
            "custom",
            annotation="str | None",
            check_fn=_auto_color_space,
            type_text='"srgb" / "linear" or None',
            doc="Encoding of the image; None: linear for float images and .exr/.hdr files, sRGB otherwise",
        ),
    )
    _signature = Signature(None, None)
    kind = "environment"
    strength: float
    color_space: str
    quaternion = ValidatedParam(
        lambda obj, name, v: frozen(quaternion_from_rotation("quaternionWXYZ", v, name=name)),
        doc="Rotation of the map (unit WXYZ quaternion).",
    )

    def _setup(self, inputs: dict[str, Any]) -> None:
        image_or_path = inputs["image_or_path"]
        self.path: str | None = None
        self._image: AnyArray | None = None
        if isinstance(image_or_path, (str, os.PathLike)):
            p = Path(image_or_path).expanduser()
            if not p.is_file():
                raise InvalidSceneError(f"image_or_path: no such file {str(p)!r}")
            self.path = str(p.resolve())
        else:
            self._image = _check_image("image_or_path", image_or_path, max_value=None)
        self._init_values(inputs)
        self.quaternion = frozen(quaternion_from_rotation(inputs["rotation_mode"], inputs["rotation"]))

    def image(self) -> AnyArray:
        if self._image is None:
            self._image = frozen(load_image(str(self.path)))
        return self._image

    def linear_rgb_image(self) -> AnyArray:
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
    def rotation_matrix(self) -> AnyArray:
        return quaternion_to_matrix(self.quaternion)

    def to_dict(self, arrays: dict[str, AnyArray]) -> dict[str, Any]:
        d: dict[str, Any] = {
            **encode_params(self, arrays),
            "quaternion": self.quaternion.tolist(),
            "path": self.path,
        }
        if self.path is None:
            arrays["environment.image"] = self.image()
            d["image"] = "environment.image"
        return d


def equirect_uv(directions: AnyArray) -> AnyArray:
    """Map world directions (..., 3) to equirectangular texture coordinates (..., 2), u right, v up."""
    d = np.asarray(directions, dtype=np.float64)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    u = 0.5 - np.arctan2(d[..., 1], d[..., 0]) / (2 * np.pi)
    v = 0.5 + np.arcsin(np.clip(d[..., 2], -1.0, 1.0)) / np.pi
    return np.stack([u % 1.0, v], axis=-1)


# -- the collection -------------------------------------------------------------------------------------


def _add_light(lights: LightsCollection, cls: type, arguments: dict[str, Any]) -> Light:
    tag = arguments.pop("tag")
    return lights._add(cls(**arguments), tag)


def _set_background(lights: LightsCollection, cls: type, arguments: dict[str, Any]) -> BackgroundLight:
    lights.background = BackgroundLight(**arguments)
    lights.revision += 1
    return lights.background


def _set_environment(lights: LightsCollection, cls: type, arguments: dict[str, Any]) -> EnvironmentMap:
    lights.environment = EnvironmentMap(**arguments)
    lights.revision += 1
    return lights.environment


@strict_api
class LightsCollection:
    """The lights of one scene: ``add_point``, ``add_sun``, ``add_spot``, ``add_area``,
    ``set_background_light``, ``set_environment_map``; ``[tag]``, ``remove``, iteration, ``len``.
    Each ``add_*`` takes its light's parameters (docs/parameters.md), the pose, ``tag`` and ``color_space``."""

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

    add_point = facade(PointLight, "add_point", "LightsCollection", _add_light, trailing=(COLOR_SPACE,))
    add_sun = facade(SunLight, "add_sun", "LightsCollection", _add_light, trailing=(COLOR_SPACE,))
    add_spot = facade(SpotLight, "add_spot", "LightsCollection", _add_light, trailing=(COLOR_SPACE,))
    add_area = facade(AreaLight, "add_area", "LightsCollection", _add_light, trailing=(COLOR_SPACE,))
    set_background_light = facade(
        BackgroundLight,
        "set_background_light",
        "LightsCollection",
        _set_background,
        pose=False,
        doc="Set the uniform background light (replacing any) and return it.",
    )
    set_environment_map = facade(
        EnvironmentMap,
        "set_environment_map",
        "LightsCollection",
        _set_environment,
        pose=False,
        doc="Set the environment map (replacing any) and return it.",
    )

    def remove_background_light(self) -> None:
        self.background = None
        self.revision += 1

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
