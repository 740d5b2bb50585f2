"""Tolerance tiers: which thresholds a pair of results must meet, chosen by the backends and the scene.

Two path tracers on Lambertian materials under delta lights are held tightest; area and sky light add
Monte-Carlo noise; non-Lambertian materials and a rasteriser get looser, measured tiers. Every number
cites its measurement (see the comments next to :data:`TIERS`).
"""

from __future__ import annotations

from collections.abc import Mapping

from blendify_core.errors import BackendUnavailableError, InvalidSceneError
from blendify_core.evaluate.metrics import COMPARED_OUTPUTS, _backend_of
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.capabilities import scene_features
from blendify_core.pipeline.result import RenderResult
from blendify_core.registry import get_backend_class

__all__ = ["TIERS", "NOISE_MARGINS", "TIER_NOTES", "choose_tier", "is_path_tracer"]

# ---------------------------------------------------------------------------------------------------
# Tolerance tiers: output -> metric -> threshold (upper bound, or lower bound for HIGHER_IS_BETTER).
# Every number cites the measurement behind it. "CONV" = docs/conventions.md, section "Measurements behind
# the tolerance tiers" (made with the same engine versions); "XC" = benchmarks/crosscheck_report.py, whose
# measured table is in docs/crosscheck.md (re-run it after changing a backend, then revisit the numbers).
# ---------------------------------------------------------------------------------------------------
_GEOMETRY: dict[str, dict[str, float]] = {
    # CONV §11: depth <= 1e-3 relative with identical tessellation and the Mitsuba near-clip correction.
    # The q99 (not the max): silhouette pixels whose centre ray grazes an edge may hit different surfaces.
    # XC: Cycles/pyrender vs the analytic ray cast of tessellated marker spheres 6.7e-4 / 9.8e-4 (sagitta of
    # the 64x32 UV sphere); tilted plane 5e-6; every mesh scene <= 8e-5.
    "depth": {"rel_diff_q99": 1e-3},
    # CONV §13: pyrender/OSMesa and Cycles matched an exact ray cast pixel for pixel on the marker scene.
    # XC: every pair on every mesh scene has 0 interior disagreements; the only edge disagreements are
    # pixel centres within 0.004 px of a silhouette (tessellation), <= 3 px per scene.
    # (IoU is reported but not thresholded: one edge pixel moves the IoU of a 30-pixel marker by 3 %.)
    "mask": {"n_disagree_interior": 0, "edge_disagree_fraction": 0.05},
    # interior pixels only (no silhouette/crease: see interior_mask). XC: Mitsuba vs pyrender <= 2e-4 deg
    # (both pixel-centre); Cycles' normal pass is averaged over the pixel: 2.0 deg (bunny) / 2.1 deg
    # (orthographic bunny) at q99 on a curved dense mesh. A flipped/mirrored normal shows as ~180 deg.
    "normal": {"angle_q99_deg": 3.0, "flipped_fraction": 0.01},
    # XC: >= 0.9999 on every scene (one pixel on an instance border of the orthographic bunny)
    "instance": {"agreement": 0.999},
}

TIERS: dict[str, dict[str, dict[str, float]]] = {
    # Two results of the same deterministic computation (golden tests of a raster backend, unit tests).
    "identical": {
        "rgb": {"max_rel_error": 1e-6, "alpha_mean_abs_error": 1e-6},
        "depth": {"rel_diff_max": 1e-6},
        "mask": {"n_disagree": 0},
        "normal": {"angle_max_deg_all": 1e-2},
        "instance": {"agreement": 1.0},
        "albedo": {"max_rel_error_all": 1e-6},
    },
    # Geometric outputs only (colour unchecked): camera, depth, masks, normals, instance ids.
    "geometry": dict(_GEOMETRY),
    # Cycles vs Mitsuba, Lambertian materials lit by delta lights only (point/spot without radius, sun
    # without angle). CONV §11: mean rel <= 0.5 % (noise-free cases 0.03 %); CONV §13 planes 1.0005/0.9995.
    # XC: planes 2e-7 (sun) / 9e-4 (point, spot at 16 spp: pixel-footprint sampling), per-face-material
    # scene 1.5e-3 interior, ratio 0.9996. Albedo is noise-free: XC <= 2e-6.
    "pathtracer_delta": {
        **_GEOMETRY,
        "rgb": {"mean_rel_error_interior": 0.005, "ratio_error": 0.005},
        "albedo": {"mean_rel_error": 0.01},
    },
    # Cycles vs Mitsuba, Lambertian materials with area lights or a background/environment light.
    # CONV §11: area/world lights mean rel <= 2 % at 256 spp (Monte-Carlo noise dominates). XC at 256 spp:
    # area 0.72 %, disk 0.62 %, background 1.27 % (Mitsuba's env noise; Cycles is noise-free there),
    # textured quad 1.28 %; ratios within 0.9998-1.0001.
    "pathtracer": {
        **_GEOMETRY,
        "rgb": {"mean_rel_error_interior": 0.02, "ratio_error": 0.01},
        "albedo": {"mean_rel_error": 0.01},
    },
    # Cycles vs Mitsuba with non-Lambertian materials (Principled with a specular layer, plastic, metal,
    # glossy, emission, ...): the engines' BSDFs differ. CONV §6.2: plastic sum ratio 0.935, mean |rel|
    # 7.3 %; metal 1.008 / 1.5 %. XC: bunny (Principled, roughness 0.6) 5.4 % / ratio 0.981, orthographic
    # bunny 5.8 %, primitives (plastic + metal) 5.5 % / 0.993.
    "pathtracer_material": {
        **_GEOMETRY,
        "rgb": {"mean_rel_error_interior": 0.08, "ratio_error": 0.08},
        "albedo": {"mean_rel_error": 0.01},
    },
    # pyrender vs a path tracer, Lambertian materials. pyrender keeps an F0 = 0.04 GGX lobe (CONV §6.1: +-1 %
    # on grey, but +0.01 absolute on every channel, i.e. >100 % relative on dark channels of saturated
    # colours), has no GI and shadow-mapped shadows: per-channel relative error is meaningless there
    # (XC: 28 % on the per-face-material scene whose images look alike). The tier therefore bounds the
    # overall brightness (ratio) and the perceptual error (FLIP on sRGB). XC: ratio error <= 0.02 on the
    # planes, 0.05 fuze, 0.085 point cloud (pyrender's coarser point spheres); FLIP <= 0.044 on the planes,
    # <= 0.067 on every other Lambertian scene. An area light (pyrender: a spot light) gives ratio 1.45.
    # Geometry keeps the tight tier (CONV §13; XC pixel-exact except pyrender's level-of-detail points).
    # Albedo: pyrender samples minified textures through mipmaps, the path tracers per sample / at the
    # pixel centre: XC 4.6 % (Cycles) and 5.0 % (Mitsuba) on fuze.obj.
    "raster": {
        **_GEOMETRY,
        "rgb": {"ratio_error": 0.10, "flip": 0.08},
        "albedo": {"mean_rel_error": 0.08},
    },
    # pyrender vs a path tracer with non-Lambertian materials. CONV §6.2: pyrender/Mitsuba plastic 0.911,
    # 9.6 %. XC: FLIP 0.058-0.108 (bunny, orthographic bunny, primitives), ratio error <= 0.017.
    "raster_material": {
        **_GEOMETRY,
        "rgb": {"ratio_error": 0.10, "flip": 0.12},
        "albedo": {"mean_rel_error": 0.08},
    },
}

#: tier -> (margin_global, margin_tile) of the noise-aware colour verdict (:mod:`.noise`), used instead of
#: the tier's fixed colour thresholds when both results carry their noise (``rgb_var``, from independent
#: passes). The margins are the *practical* agreement asked of two path tracers beyond their noise:
#: whole-image brightness within 0.25 % (XC: Cycles vs Mitsuba image sums agree within 2e-4 on the
#: planes and area lights, 4e-4 on the per-face-material scene; a 1 % bias must fail), a tile within 2 %
#: (leaves room for sub-pixel geometry differences at silhouettes; a 0.5 px shift moves an 8x8 tile with
#: a high-contrast edge by ~6 %). Non-Lambertian materials: the engines' BSDFs differ (CONV §6.2), so the
#: margins follow the fixed tier (8 % there).
NOISE_MARGINS: dict[str, tuple[float, float]] = {
    "pathtracer_delta": (0.0025, 0.02),
    "pathtracer": (0.0025, 0.02),
    "pathtracer_material": (0.03, 0.08),
}

#: one line per tier: what it is for and the measurement behind its numbers (docs/crosscheck.md prints it)
TIER_NOTES: dict[str, str] = {
    "identical": "same deterministic computation twice (same backend, same seed): bit-level agreement.",
    "geometry": "depth q99 <= 1e-3 (CONV §11; measured <= 9.8e-4 on tessellated spheres, 5e-6 on a plane), "
    "no interior mask disagreement (measured 0 on every mesh scene), normals q99 <= 3 deg on interior pixels "
    "(every engine's from the pixel-centre ray: Mitsuba/pyrender 2e-4 deg, Cycles/Mitsuba 0.010 deg on the bunny; "
    "2.1 deg while Cycles averaged its normal pass over the pixel), ids >= 0.999.",
    "pathtracer_delta": "Cycles vs Mitsuba, Lambertian, delta lights: colour <= 0.5 % interior mean rel and "
    "ratio within 0.5 % (CONV §11; measured 2e-7 sun plane, 9e-4 point/spot plane, 1.5e-3 per-face scene).",
    "pathtracer": "Cycles vs Mitsuba, Lambertian, area/sky light: <= 2 % at 256 spp (CONV §11; measured 0.6-1.3 %"
    ", ratio within 2e-4); below ~128 spp noise alone may fail it: use repeats (statistical test).",
    "pathtracer_material": "Cycles vs Mitsuba with Principled/plastic/metal: <= 8 % and ratio within 8 % "
    "(CONV §6.2 plastic 7.3 % / 0.935; measured bunny 5.4 % / 0.981, primitives 5.5 % / 0.993).",
    "raster": "pyrender vs a path tracer, Lambertian: brightness ratio within 10 % and FLIP <= 0.08 (per-channel "
    "relative error is meaningless with pyrender's F0 = 0.04 lobe on dark channels; measured ratio <= 1.02 on "
    "planes, FLIP <= 0.067); geometry as tight as the geometry tier; albedo <= 8 % (mipmapped textures: "
    "measured 4.6-5.0 % on fuze.obj).",
    "raster_material": "pyrender vs a path tracer with non-Lambertian materials: ratio within 10 %, FLIP <= 0.12 "
    "(CONV §6.2 plastic 0.911 / 9.6 %; measured FLIP 0.058-0.108).",
}


def is_path_tracer(backend: str | RenderResult | None) -> bool:
    """Whether a backend (by name: its class's ``path_tracer``), or the backend that made a result (its
    ``meta["path_tracer"]``, recorded by ``bf.render``), is a path tracer."""
    if isinstance(backend, RenderResult):
        flag = backend.meta.get("path_tracer") if isinstance(backend.meta, dict) else None
        if flag is not None:
            return bool(flag)
        backend = _backend_of(backend)
    if backend is None:
        return False
    try:
        return bool(getattr(get_backend_class(backend), "path_tracer", False))
    except (BackendUnavailableError, InvalidSceneError):
        return False


def choose_tier(
    backend_a: str | RenderResult | None, backend_b: str | RenderResult | None, scene: Scene | None = None
) -> str:
    """The tier for a backend pair and (optionally) the scene.

    Two path tracers: "pathtracer_delta" (Lambertian materials, delta lights only), "pathtracer"
    (Lambertian, any light) or "pathtracer_material" (any non-Lambertian material). With a rasteriser:
    "raster" or "raster_material". Without a scene the Lambertian tiers are assumed ("pathtracer" /
    "raster"). Unknown backends (None) count as path tracers."""
    pt_a = backend_a is None or is_path_tracer(backend_a)
    pt_b = backend_b is None or is_path_tracer(backend_b)
    material = scene is not None and _non_lambertian(scene)
    if not (pt_a and pt_b):
        return "raster_material" if material else "raster"
    if material:
        return "pathtracer_material"
    if scene is not None and _delta_lights(scene):
        return "pathtracer_delta"
    return "pathtracer"


_NON_DELTA: tuple[str, ...] = ("light.point.soft", "light.sun.soft", "light.area", "light.area.disk")
_NON_DELTA += ("light.background", "light.environment")
_NON_DIFFUSE = (
    "material.principled",
    "material.metallic",
    "material.glossy",
    "material.transmission",
    "material.coat",
    "material.sheen",
    "material.subsurface",
    "material.emission",
    "material.alpha",
    "material.wireframe",
    "material.roughness_map",
    "material.metallic_map",
    "material.normal_map",
    "pointcloud.emission",
)


def _delta_lights(scene: Scene) -> bool:
    used = scene_features(scene, ("rgb",))
    return not any(f in used for f in _NON_DELTA)


def _non_lambertian(scene: Scene) -> bool:
    used = scene_features(scene, ("rgb",))
    return any(f in used for f in _NON_DIFFUSE)


def _resolve_tier(
    tier: str | Mapping[str, Mapping[str, float]] | None, a: RenderResult, b: RenderResult, scene: Scene | None = None
) -> tuple[str, dict[str, dict[str, float]]]:
    if tier is None or tier == "auto":
        name = choose_tier(a, b, scene)
        return name, TIERS[name]
    if isinstance(tier, str):
        if tier not in TIERS:
            raise InvalidSceneError(f"tier: unknown tier {tier!r}; expected one of {sorted(TIERS)}, 'auto' or a dict")
        return tier, TIERS[tier]
    if isinstance(tier, Mapping):
        th: dict[str, dict[str, float]] = {}
        for out, ms in tier.items():
            if out not in COMPARED_OUTPUTS or not isinstance(ms, Mapping):
                raise InvalidSceneError(
                    f"tier: expected a dict output -> {{metric: threshold}} with outputs from "
                    f"{list(COMPARED_OUTPUTS)}, got key {out!r} -> {ms!r}"
                )
            th[out] = {str(k): float(v) for k, v in ms.items()}
        return "custom", th
    raise InvalidSceneError(f"tier: expected a tier name from {sorted(TIERS)}, 'auto' or a dict, got {tier!r}")
