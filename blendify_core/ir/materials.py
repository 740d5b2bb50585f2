"""Materials: Blender's Principled BSDF parameter set (blendify's names and defaults) and friends.

Every parameter is declared once, below, as a :class:`~blendify_core.ir.params.Param` (kind, default,
valid range, unit, doc and Blender's clamp range where it has one); the constructors, their
``inspect.signature``, attribute validation, scene files and ``docs/parameters.md`` all come from these
declarations. Presets (MetalMaterial, PlasticMaterial, DiffuseMaterial, ...) declare only the defaults
they change.

The base colour of an object comes from its colour source (``colors=`` of ``add_*``), not from the
material, as in blendify. Colour parameters of materials (``emission_color``, ``coat_tint``, ``sheen_tint``,
``specular_tint``, ``wireframe_color``) are sRGB-encoded unless the material is created with
``color_space="linear"``; backends read linear values with :meth:`Material.linear`.

Attributes are readable and settable (validated on every assignment); each change bumps
``material.revision`` so backends know to update.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.errors import describe as _describe
from blendify_core.ir.colors import COLOR_SPACES, _to_linear
from blendify_core.ir.params import Clamp, Declared, Param, Signature, emission_param, encode_params
from blendify_core.ir.physics import material_lobes
from blendify_core.typing import AnyArray

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
    "check_material",
]


def _factor(name: str, default: float, doc: str, **kw: Any) -> Param:
    """A [0, 1] factor (Blender's FACTOR sockets)."""
    return Param(name, default, "float", 0.0, 1.0, doc=doc, **kw)


def _colour(name: str, default: tuple[float, ...], doc: str) -> Param:
    return Param(name, default, "color", 0.0, 1.0, doc=doc + " (sRGB unless color_space='linear')")


#: the colour encoding of a material's colour parameters; a constructor input, not a parameter
MATERIAL_COLOR_SPACE = Param(
    "color_space",
    "srgb",
    "choice",
    choices=COLOR_SPACES,
    stored=False,
    doc="Encoding of the material's colour parameters: 'srgb' or 'linear' (fixed at creation)",
)
ROUGHNESS = _factor("roughness", 0.4, "Perceptual roughness of the specular lobes (GGX alpha = roughness^2)")
ALPHA = _factor("alpha", 1.0, "Opacity: 1 opaque, 0 invisible (Blender's Transparent BSDF mix)")

# Blender clamps (measured with bpy 5.0.1: renders of the clamped value and of the clamp target are
# pixel-identical; Cycles' closure setup: coat IOR max(ior, 1), subsurface anisotropy clamp(a, 0, 0.9)).
COAT_IOR_CLAMP = Clamp(0.0, 1.0, 1.0, high_open=True)
SUBSURFACE_ANISOTROPY_CLAMPS = (Clamp(-1.0, 0.0, 0.0, high_open=True), Clamp(0.9, 1.0, 0.9, low_open=True))

PRINCIPLED: tuple[Param, ...] = (
    ALPHA,
    _factor("anisotropic", 0.0, "Anisotropy of the specular highlight (0 = isotropic)"),
    Param("anisotropic_rotation", 0.0, "float", 0.0, 1.0, unit="turns", doc="Rotation of the anisotropy direction"),
    Param(
        "coat_ior",
        1.5,
        "float",
        1.0,
        4.0,
        doc="Index of refraction of the clear coat (blendify's 0 and other values below 1 render as 1)",
        clamps=(COAT_IOR_CLAMP,),
    ),
    _factor("coat_roughness", 0.0, "Roughness of the clear coat"),
    _colour("coat_tint", (1.0, 1.0, 1.0, 1.0), "Colour absorbed by the clear coat"),
    _factor("coat_weight", 0.0, "Strength of the clear coat layer"),
    _factor("diffuse_roughness", 0.0, "Oren-Nayar roughness of the diffuse lobe (0 = Lambertian)"),
    _colour("emission_color", (0.0, 0.0, 0.0, 0.0), "Emitted colour"),
    emission_param(
        "emission_strength", 0.0, "Emitted radiance = emission_color x emission_strength", unit="W/(m^2 sr)"
    ),
    Param("ior", 1.45, "float", 1.0, 1000.0, doc="Index of refraction of the dielectric (specular and transmission)"),
    _factor("metallic", 0.0, "Blend from dielectric (0) to metal (1)"),
    ROUGHNESS,
    _factor("sheen_weight", 0.0, "Strength of the sheen layer"),
    _factor("sheen_roughness", 0.5, "Roughness of the sheen layer"),
    _colour("sheen_tint", (0.5, 0.5, 0.5, 1.0), "Colour of the sheen"),
    Param(
        "specular_ior",
        0.3,
        "float",
        0.0,
        None,
        doc="Blender's 'Specular IOR Level': 0.5 keeps the IOR, 0 removes the specular layer",
    ),
    _colour("specular_tint", (0.0, 0.0, 0.0, 1.0), "Tint of the dielectric specular reflection"),
    Param(
        "subsurface_anisotropy",
        0.0,
        "float",
        0.0,
        0.9,
        doc="Forward scattering of the subsurface medium (Blender renders negative values as 0, above 0.9 as 0.9)",
        clamps=SUBSURFACE_ANISOTROPY_CLAMPS,
    ),
    Param(
        "subsurface_radius",
        (1.0, 0.2, 1.0),
        "vec3",
        0.0,
        None,
        unit="m (x subsurface_scale)",
        doc="Mean free path per RGB channel",
    ),
    Param("subsurface_scale", 0.05, "float", 0.0, None, unit="m", doc="Scale of subsurface_radius"),
    _factor("subsurface_weight", 0.0, "Blend from diffuse to subsurface scattering"),
    Param("thin_film_ior", 1.33, "float", 1.0, 1000.0, doc="Index of refraction of the thin film"),
    Param("thin_film_thickness", 0.0, "float", 0.0, 100000.0, unit="nm", doc="Thickness of the thin film (0 = none)"),
    _factor("transmission_weight", 0.0, "Blend to glass-like transmission"),
    Param("roughness_map", None, "texture", nullable=True, doc="Texture driving roughness through the mesh's UVs"),
    Param("metallic_map", None, "texture", nullable=True, doc="Texture driving metallic through the mesh's UVs"),
    Param("normal_map", None, "normal_map", nullable=True, doc="Tangent-space normal map (OpenGL convention)"),
    Param(
        "distribution",
        "MULTI_GGX",
        "choice",
        choices=("GGX", "MULTI_GGX"),
        doc="Microfacet distribution of the specular, metallic and transmission lobes: 'MULTI_GGX' (Blender's "
        "default, GGX with the energy lost to single scattering restored) or 'GGX' (single scattering)",
    ),
)

WIREFRAME: tuple[Param, ...] = (
    Param("wireframe_thickness", 0.01, "float", 0.0, None, unit="m", doc="Width of the drawn edges in world units"),
    _colour("wireframe_color", (0.0, 0.0, 0.0, 1.0), "Colour of the drawn edges"),
)

GLOSSY: tuple[Param, ...] = (
    ROUGHNESS,
    Param(
        "distribution",
        "GGX",
        "choice",
        choices=("GGX", "BECKMANN", "ASHIKHMIN_SHIRLEY", "MULTI_GGX"),
        doc="Microfacet distribution",
    ),
    ALPHA,
)

# presets: the defaults they change and the parameters their signatures list (blendify's)
_METAL = {"roughness": 0.55, "metallic": 0.9, "specular_ior": 0.5}
_PLASTIC = {"roughness": 0.3, "specular_ior": 0.5}
_METAL_NAMES = ("roughness", "metallic", "coat_ior", "specular_ior", "coat_roughness")
_PLASTIC_NAMES = ("roughness", "ior", "coat_ior", "specular_ior", "coat_roughness")
_WIRE_NAMES = tuple(p.name for p in WIREFRAME)


class Material(Declared):
    """Base of all materials. Subclasses declare their parameters in ``_declared`` (``_params`` lists the
    stored ones, in declaration order) and presets their changed defaults in ``_preset``."""

    _declared: tuple[Param, ...] = (MATERIAL_COLOR_SPACE,)
    _signature = Signature(None, "kwargs")
    _params: tuple[Param, ...] = ()
    kind = "material"
    color_space: str
    revision: int

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls._params = cls._stored

    def _setup(self, inputs: dict[str, Any]) -> None:
        object.__setattr__(self, "revision", 0)
        object.__setattr__(self, "color_space", MATERIAL_COLOR_SPACE.check(inputs["color_space"]))
        self._init_values(inputs)

    def _param_changed(self, param: Param) -> None:
        object.__setattr__(self, "revision", self.revision + 1)

    def __setattr__(self, name: str, value: Any) -> None:
        if name.startswith("_"):
            object.__setattr__(self, name, value)
            return
        p = self._param_index.get(name)
        if p is None or not p.stored:
            raise InvalidSceneError(
                f"{type(self).__name__}: unknown parameter {name!r}; known: {list(self.parameter_names())}"
            )
        self._set_param(p, value)

    def get(self, name: str) -> Any:
        return self._values[name]

    def linear(self, name: str) -> AnyArray:
        """A colour parameter as linear RGBA (4,) float64 (alpha is 1 when only RGB was given)."""
        p = self._param_index.get(name)
        if p is None or p.kind != "color":
            raise InvalidSceneError(f"{name}: not a colour parameter of {type(self).__name__}")
        rgba = np.ones(4)
        c = self._values[name]
        rgba[: len(c)] = c
        return _to_linear(rgba, self.color_space)

    def copy(self, **changes: Any) -> Material:
        values = {k: v for k, v in self._values.items() if k not in self._fixed_params}
        values.update(changes)
        cls: Any = type(self)
        new: Material = cls(color_space=self.color_space, **values)
        return new

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return self.color_space == other.color_space and self._values == other._values

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
        if "emission_strength" not in v:
            return False
        return float(v["emission_strength"]) > 0 and max(v["emission_color"][:3]) > 0

    @property
    def is_diffuse_only(self) -> bool:
        """True when the material is an exact Lambertian reflector (no specular, metal, transmission, ...)."""
        return material_lobes(self).diffuse_only

    def to_dict(self, arrays: dict[str, AnyArray], prefix: str) -> dict[str, Any]:
        """The scene-file form: ``{"kind", "color_space", "params"}`` (params walk the declaration)."""
        params = encode_params(self, arrays, prefix)
        return {"kind": type(self).__name__, "color_space": self.color_space, "params": params}


class PrincipledBSDFMaterial(Material):
    """Blender's Principled BSDF. ``specular_ior`` is Blender's "Specular IOR Level" (0.5 = IOR unchanged,
    0 = no specular layer), as in blendify. Optional ``roughness_map``/``metallic_map`` (TextureMap) and
    ``normal_map`` (NormalMap) drive those inputs from textures through the mesh's UVs. ``distribution``
    is the node's microfacet distribution ("MULTI_GGX", Blender's default, or "GGX"); what every
    parameter means is written down in docs/conventions.md ("Materials")."""

    _declared = PRINCIPLED + (MATERIAL_COLOR_SPACE,)
    kind = "principled"


class DiffuseMaterial(PrincipledBSDFMaterial):
    """An exact Lambertian reflector: Principled with no specular layer (renders identically in every
    path tracer; the reference material of cross-renderer tests)."""

    _preset = {"roughness": 1.0, "specular_ior": 0.0}
    _signature = Signature((), "kwargs")
    #: what keeps it an exact Lambertian reflector; metallic, roughness, coat, ... raise
    _settable = ("alpha", "emission_color", "emission_strength", "normal_map")


class MetalMaterial(PrincipledBSDFMaterial):
    """Principled preset for metals (blendify's defaults: roughness 0.55, metallic 0.9)."""

    _preset = _METAL
    _signature = Signature(_METAL_NAMES, "kwargs")


class PlasticMaterial(PrincipledBSDFMaterial):
    """Principled preset for plastics (blendify's defaults: roughness 0.3, IOR 1.45)."""

    _preset = _PLASTIC
    _signature = Signature(_PLASTIC_NAMES, "kwargs")


class PrincipledBSDFWireframeMaterial(PrincipledBSDFMaterial):
    """Principled surface with the mesh edges drawn over it: ``wireframe_thickness`` in world units,
    ``wireframe_color`` (sRGB by default). The edges are the triangle edges of the mesh."""

    _declared = PRINCIPLED + WIREFRAME + (MATERIAL_COLOR_SPACE,)
    _signature = Signature(_WIRE_NAMES, "kwargs")


class PlasticWireframeMaterial(PrincipledBSDFWireframeMaterial):
    """PlasticMaterial's defaults with the mesh edges drawn over it."""

    _preset = _PLASTIC
    _signature = Signature(_PLASTIC_NAMES + _WIRE_NAMES, "kwargs")


class MetalWireframeMaterial(PrincipledBSDFWireframeMaterial):
    """MetalMaterial's defaults with the mesh edges drawn over it."""

    _preset = _METAL
    _signature = Signature(_METAL_NAMES + _WIRE_NAMES, "kwargs")


class GlossyBSDFMaterial(Material):
    """Blender's Glossy BSDF: a pure specular reflector tinted by the object's colour.
    ``distribution``: "GGX", "BECKMANN", "ASHIKHMIN_SHIRLEY" or "MULTI_GGX"."""

    _declared = GLOSSY + (MATERIAL_COLOR_SPACE,)
    _signature = Signature(None, None)
    kind = "glossy"


def check_material(name: str, value: Any) -> Material:
    if not isinstance(value, Material):
        raise InvalidSceneError(f"{name}: expected a Material (e.g. PrincipledBSDFMaterial()), got {_describe(value)}")
    return value
