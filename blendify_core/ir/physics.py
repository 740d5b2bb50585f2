"""Shared physics of the IR: what a light's power and a material's parameters mean, computed once.

Every backend converts the IR with these functions instead of its own copy of the formulas, and the
effect analysis and the capability check classify materials with :func:`material_lobes`.

Light units are Blender's (docs/conventions.md, "Lights"): point and spot power ``P`` in watts spread
over the whole sphere (intensity ``P / 4 pi`` W/sr, no cosine factor in the spot cone), area power over
a Lambertian emitter (radiance ``P / (pi A)``), a point light of radius ``r`` as a sphere emitter of radiance
``P / (4 pi^2 r^2)`` (Blender's sphere light with soft falloff off), sun irradiance in W/m^2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from blendify_core.typing import Float64Array

__all__ = [
    "MaterialLobes",
    "area_radiance",
    "blend_normal_map",
    "material_lobes",
    "point_intensity",
    "sphere_light_radiance",
    "spot_cone",
    "spot_falloff",
]


def point_intensity(power: float) -> float:
    """Radiant intensity (W/sr) of a point or spot light of ``power`` watts (Blender: P / 4 pi)."""
    return float(power) / (4.0 * math.pi)


def sphere_light_radiance(power: float, radius: float) -> float:
    """Radiance of the surface of a spherical light of ``power`` watts and ``radius`` (P / (4 pi^2 r^2))."""
    return float(power) / (4.0 * math.pi**2 * float(radius) ** 2)


def area_radiance(power: float, area: float) -> float:
    """Radiance of a one-sided Lambertian emitter of ``power`` watts and ``area`` m^2 (P / (pi A))."""
    return float(power) / (math.pi * float(area))


def spot_cone(spot_size: float, spot_blend: float) -> tuple[float, float]:
    """Half-angle of the cone and half-angle inside which a spot is at full intensity, in radians, from
    Blender's full ``spot_size`` (radians) and ``spot_blend`` (0..1): the blend band starts where
    cos(angle) = blend + (1 - blend) cos(spot_size / 2)."""
    half = 0.5 * float(spot_size)
    blend = float(spot_blend)
    inner = math.acos(min(1.0, blend + (1.0 - blend) * math.cos(half)))
    return half, inner


def spot_falloff(cos_angle: ArrayLike, spot_size: float, spot_blend: float) -> Float64Array:
    """Blender's spot attenuation at directions whose angle to the axis has cosine ``cos_angle``: 0 outside
    the cone, 1 inside the full-intensity cone of :func:`spot_cone`, a smoothstep in cos(angle) over the blend
    band between (no cosine factor)."""
    half, inner = spot_cone(spot_size, spot_blend)
    c = np.asarray(cos_angle, dtype=np.float64)
    lo, hi = math.cos(half), math.cos(inner)
    if hi - lo <= 0.0:
        out: Float64Array = (c > lo).astype(np.float64)
        return out
    t = np.clip((c - lo) / (hi - lo), 0.0, 1.0)
    out = t * t * (3.0 - 2.0 * t)
    return out


def blend_normal_map(normals: ArrayLike, strength: float) -> Float64Array:
    """Tangent-space normals (..., 3) with Blender's normal-map ``strength`` applied:
    n' = normalize(N + s (n - N)) with N = (0, 0, 1). Strength 0 gives the flat normal, 1 the map."""
    n = np.asarray(normals, dtype=np.float64)
    s = float(strength)
    out: Float64Array = np.stack([s * n[..., 0], s * n[..., 1], 1.0 + s * (n[..., 2] - 1.0)], axis=-1)
    out /= np.maximum(np.linalg.norm(out, axis=-1, keepdims=True), 1e-12)
    return out


@dataclass(frozen=True)
class MaterialLobes:
    """Which scattering lobes a material has (the one classification the effect analysis, the capability
    check and the backends use).

    ``diffuse``: a diffuse base (not fully metallic, not fully transmissive, not a Glossy BSDF), Lambertian
    unless ``rough_diffuse`` (Principled ``diffuse_roughness`` > 0); ``specular``: any glossy reflection
    (dielectric specular layer, metal, coat, sheen, Glossy BSDF)."""

    diffuse: bool
    rough_diffuse: bool
    specular: bool
    metallic: bool
    transmission: bool
    coat: bool
    sheen: bool
    subsurface: bool
    emission: bool
    alpha: bool
    roughness: float

    @property
    def diffuse_only(self) -> bool:
        """An exact Lambertian reflector and nothing else."""
        return self.diffuse and not (
            self.rough_diffuse
            or self.specular
            or self.metallic
            or self.transmission
            or self.coat
            or self.sheen
            or self.subsurface
        )


def material_lobes(material: Any) -> MaterialLobes:
    """The lobes of an IR material (the Principled family or the Glossy BSDF). A lobe whose parameter the
    material does not declare (a Glossy BSDF has no ``metallic``) is absent; every declared value is read
    as the material's attribute (its default is the declaration's, nowhere else)."""
    declared = set(material.parameter_names())

    def weight(name: str) -> float:
        """The lobe's weight, 0 when the material has no such lobe."""
        return float(getattr(material, name)) if name in declared else 0.0

    glossy = material.kind == "glossy"
    metallic_value = weight("metallic")
    metallic = metallic_value > 0 or ("metallic_map" in declared and material.metallic_map is not None)
    coat = weight("coat_weight") > 0
    sheen = weight("sheen_weight") > 0
    transmission = weight("transmission_weight")
    alpha = float(material.alpha) if "alpha" in declared else 1.0
    return MaterialLobes(
        diffuse=not glossy and metallic_value < 1.0 and transmission < 1.0,
        rough_diffuse=weight("diffuse_roughness") > 0,
        specular=glossy or weight("specular_ior") > 0 or metallic or coat or sheen,
        metallic=metallic,
        transmission=transmission > 0,
        coat=coat,
        sheen=sheen,
        subsurface=weight("subsurface_weight") > 0,
        emission=bool(material.is_emissive),
        alpha=alpha < 1.0,
        roughness=float(material.roughness),
    )
