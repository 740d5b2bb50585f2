"""blendify-core backend ``mitsuba``: the IR rendered by Mitsuba 3, the independent cross-check of Cycles.

The engine is imported lazily (on the first translate/render), never at module import time, so the
registry and :meth:`MitsubaBackend.probe` stay cheap. The variant is chosen by
:mod:`blendify_mitsuba._variant` (JIT variants are probed in a subprocess first: an unsuitable libLLVM
aborts the process that uses it).
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
import math
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from blendify_core.errors import BlendifyError, InvalidSceneError, RenderError
from blendify_core.pipeline.backend import Backend
from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import RenderSettings
from blendify_core.registry import BackendStatus

__all__ = ["MitsubaBackend", "MitsubaNative", "DEFAULT_MAX_ANALYTIC_SPHERES"]

log = logging.getLogger("blendify_mitsuba")

#: point clouds up to this many points become analytic spheres, larger ones one merged icosphere mesh.
#: Measured (benchmarks/results/mitsuba_pointcloud_*.md): in scalar_rgb analytic spheres load and render
#: faster than the merged mesh up to ~100k points (load_dict of the 1.6M-triangle mesh of 20k icospheres
#: takes ~7 s); in the JIT variants one BSDF per sphere makes rendering slow (20k spheres: 22 s vs 1.2 s),
#: the merged mesh wins from ~1000 points on.
DEFAULT_MAX_ANALYTIC_SPHERES = {"scalar": 100_000, "jit": 500}

# mi.set_variant is process-global: every use of the engine holds this lock and sets its variant
_ENGINE_LOCK = threading.RLock()

E, A, U = "exact", "approximate", "unsupported"
_CAPS: dict[str, tuple[str, str]] = {
    "mesh": (E, ""),
    "mesh.vertex_colors": (E, "mesh attribute 'vertex_color' (linear, interpolated like Cycles)"),
    "mesh.texture": (
        E,
        "in-memory bitmap, v -> 1 - v; 8-bit sRGB textures with linear interpolation are upsampled in encoded "
        "space (Cycles interpolates before decoding), up to 1M texels",
    ),
    "mesh.file_texture": (E, "read by Mitsuba (8-bit PNG/JPEG, nearest or linear data) or through the IR"),
    "mesh.faces_material": (E, "one Mitsuba mesh per material slot"),
    "mesh.smooth": (E, "vertex normals"),
    "pointcloud": (
        E,
        "analytic spheres up to max_analytic_spheres points, beyond that the IR's merged icosphere mesh",
    ),
    "pointcloud.vertex_colors": (E, ""),
    "pointcloud.emission": (A, "area emitter on the spheres, front (outer) side only"),
    "primitive.cube": (E, "IR tessellation"),
    "primitive.circle": (E, "IR tessellation"),
    "primitive.cylinder": (E, "IR tessellation"),
    "primitive.plane": (E, "IR tessellation"),
    "primitive.sphere": (E, "analytic sphere"),
    "primitive.ellipsoid": (E, "IR tessellation"),
    "primitive.curve": (E, "IR tessellation (tube along the polyline)"),
    "shadow_catcher": (
        A,
        "emulated from two renders (with and without the other objects): where a pixel centre sees the catcher, "
        "black with alpha = 1 - shadowed/unshadowed luminance; catcher edges against objects keep the plane's "
        "colour; the catcher also reflects light onto objects",
    ),
    "object.no_shadow": (U, "Mitsuba has no per-object shadow visibility"),
    "material.principled": (
        A,
        "Mitsuba 'principled' (Disney diffuse with retro-reflection, Schlick Fresnel, no diffuse/specular "
        "energy coupling; eta from IOR and Specular IOR Level, alpha = roughness^2). Measured on a red sphere "
        "under a sun vs Cycles: red channel +6-7 %, dark channels (specular) +40-65 %; roughplastic was not "
        "closer",
    ),
    "material.diffuse_only": (E, "Lambertian 'diffuse' (matches Cycles within 0.1 %)"),
    "material.metallic": (A, "Mitsuba 'principled' metallic (measured 1.008 x Cycles on a sphere)"),
    "material.glossy": (A, "roughconductor with a perfect-mirror Fresnel tinted by the colour"),
    "material.transmission": (A, "principled spec_trans (one-sided, thin-surface differences)"),
    "material.coat": (A, "principled clearcoat (different lobe from Blender's coat)"),
    "material.sheen": (A, "principled sheen (different lobe)"),
    "material.subsurface": (U, "Mitsuba has no subsurface scattering in the principled BSDF"),
    "material.emission": (
        A,
        "area emitter on the surface: emits from the front side only; with a background/environment light "
        "the coverage alpha is composited from two extra one-bounce passes",
    ),
    "material.alpha": (E, "mask BSDF with the material x colour alpha"),
    "material.wireframe": (
        A,
        "triangle edges as square tubes of side wireframe_thickness (world units) with the surface's BSDF in "
        "the wireframe colour: geometry instead of Blender's Wireframe shader (protrudes by half the "
        "thickness, casts shadows, also draws the diagonals of triangulated quads)",
    ),
    "material.roughness_map": (A, "raw bitmap driving principled roughness (the principled BSDF's differences)"),
    "material.metallic_map": (A, "raw bitmap driving principled metallic (the principled BSDF's differences)"),
    "material.normal_map": (
        A,
        "Mitsuba 'normalmap' (frame dp/du, n x dp/du; strength baked into the map); not compared with Cycles yet",
    ),
    "light.point": (E, "point, intensity = P / (4 pi)"),
    "light.point.soft": (
        A,
        "point lights: a sphere emitter of radiance P / (4 pi^2 r^2) (Blender's sphere light with soft falloff "
        "off); spot lights: delta (radius ignored). The light's null surface also blocks other lights' shadow rays",
    ),
    "light.sun": (E, "directional, irradiance = strength"),
    "light.sun.soft": (A, "delta directional light (angular diameter ignored: hard shadows)"),
    "light.spot": (E, "spot, intensity = P / (4 pi), cutoff = spot_size / 2"),
    "light.spot.blend": (A, "Mitsuba's falloff is linear in angle, Blender's a smoothstep"),
    "light.area": (
        E,
        "rectangle with radiance P / (pi A), one-sided, hidden from the camera (visible from its emitting "
        "side only in scenes with emissive materials)",
    ),
    "light.area.disk": (E, "disk with radiance P / (pi A), one-sided, hidden from the camera as light.area"),
    "light.no_shadow": (U, "Mitsuba lights always cast shadows"),
    "light.background": (E, "constant emitter"),
    "light.environment": (E, "envmap rotated to Blender's equirectangular mapping"),
    "camera.perspective": (E, "perspective sensor with principal-point offsets"),
    "camera.orthographic": (E, "orthographic sensor, principal point by translating the camera"),
    "camera.anisotropic": (
        A,
        "fx != fy: colour rendered by a square-pixel camera (columns supersampled k <= 4 times, rows at "
        "k fx/fy per pixel, same samples per target pixel) and box-resampled with exact row overlaps (only "
        "boundary rows split); depth/normal/albedo/instance exact (cast through the target pixel centres)",
    ),
    "output.rgb": (E, ""),
    "output.depth": (E, "planar z from pixel-centre ray casts"),
    "output.normal": (E, "world shading normal (facing the camera) from pixel-centre ray casts"),
    "output.albedo": (E, "the material colour input at the pixel centre"),
    "output.instance": (E, "renderable index from pixel-centre ray casts"),
}


@dataclass
class MitsubaNative:
    """A translated scene: the loaded Mitsuba scene(s), the dictionary and what each shape stands for."""

    variant: str
    scene: Any
    scene_dict: dict[str, Any]
    shapes: dict[str, Any]
    camera: Any
    spp: int = 1  # samples per rendered pixel (differs from settings.samples for fx != fy)
    aniso: Any = None  # the square-pixel plan for fx != fy (see _aniso)
    coverage_scene: Any = None  # shapes only: coverage alpha (when compositing)
    sky_scene: Any = None  # background/environment only: what the sky adds behind partial pixels
    catcher_scene: Any = None  # shadow catchers alone (unshadowed radiance)
    catchers: list[int] = field(default_factory=list)  # renderable indices of the shadow catchers
    integrator: dict[str, Any] = field(default_factory=dict)
    effects: Any = None
    n_analytic_spheres: int = 0


def _sampler_count(native: Any) -> int:
    """Samples per pixel the loaded sensor really takes (stratified samplers round the request up)."""
    try:
        return int(native.scene.sensors()[0].sampler().sample_count())
    except Exception:  # a scene without a sensor (never built by this backend): report the plan
        return int(native.spp)


class MitsubaBackend(Backend):
    """Mitsuba 3 backend.

    Options: ``variant`` (None = the fastest variant that passes a subprocess probe, else
    ``scalar_rgb``; or a variant name such as "scalar_rgb", "llvm_ad_rgb"; an unusable JIT variant falls
    back to ``scalar_rgb`` with the reason in ``result.meta["variant_reason"]``) and
    ``max_analytic_spheres`` (point clouds up to this size are analytic spheres, larger ones the IR's merged
    icosphere mesh; None = the measured default of the variant, see DEFAULT_MAX_ANALYTIC_SPHERES).
    """

    path_tracer = True  # target_error: independent passes until the estimated error is reached
    name = "mitsuba"
    engine = "mitsuba"
    qualities = ("final", "draft", "preview")

    SAMPLERS = ("independent", "stratified", "multijitter", "ldsampler", "orthogonal")

    def __init__(
        self,
        variant: str | None = None,
        max_analytic_spheres: int | None = None,
        sampler: str = "independent",
        **options: Any,
    ) -> None:
        super().__init__(**options)
        if sampler not in self.SAMPLERS:
            raise InvalidSceneError(f"sampler: expected one of {list(self.SAMPLERS)}, got {sampler!r}")
        self.sampler = sampler
        from ._variant import KNOWN_VARIANTS

        if variant is not None and (not isinstance(variant, str) or variant not in KNOWN_VARIANTS):
            raise InvalidSceneError(
                f"variant: expected None or one of {list(KNOWN_VARIANTS)} (RGB variants), got {variant!r}"
            )
        if max_analytic_spheres is not None and (
            isinstance(max_analytic_spheres, bool)
            or not isinstance(max_analytic_spheres, (int, np.integer))
            or max_analytic_spheres < 0
        ):
            raise InvalidSceneError(
                f"max_analytic_spheres: expected None or an integer >= 0, got {max_analytic_spheres!r}"
            )
        self.requested_variant = variant
        self._max_analytic_spheres = None if max_analytic_spheres is None else int(max_analytic_spheres)
        self._choice: Any = None
        self._cache: tuple[Any, MitsubaNative] | None = None  # (key, native) of the last translation

    # -- discovery -------------------------------------------------------------------------------
    @classmethod
    def probe(cls) -> BackendStatus:
        if importlib.util.find_spec("mitsuba") is None or importlib.util.find_spec("drjit") is None:
            return BackendStatus(False, "the 'mitsuba' package is not installed (pip install mitsuba)", None)
        return BackendStatus(True, None, cls.engine_version())

    @classmethod
    def info_details(cls) -> list[str]:
        """Lines for ``blendify info``: the variant a default ``MitsubaBackend()`` uses here and why, one line
        per variant probe (the probes run now when the probe cache has no result for them)."""
        from ._variant import describe

        return describe(None)

    @classmethod
    def capabilities(cls) -> dict[str, Capability]:
        caps = {name: Capability(*_CAPS[name]) for name in ALL_FEATURES if name in _CAPS}
        for name in ALL_FEATURES:
            caps.setdefault(name, Capability(U, "not declared by the mitsuba backend"))
        return caps

    # -- engine ----------------------------------------------------------------------------------
    @property
    def variant_choice(self) -> Any:
        """The resolved :class:`~blendify_mitsuba._variant.VariantChoice` (probes on first use)."""
        if self._choice is None:
            from ._variant import choose_variant

            self._choice = choose_variant(self.requested_variant)
        return self._choice

    @property
    def variant(self) -> str:
        return self.variant_choice.variant

    @property
    def max_analytic_spheres(self) -> int:
        """Point clouds up to this size become analytic spheres (default depends on the variant)."""
        if self._max_analytic_spheres is not None:
            return self._max_analytic_spheres
        return DEFAULT_MAX_ANALYTIC_SPHERES["scalar" if self.variant.startswith("scalar") else "jit"]

    def _set_variant(self) -> Any:
        variant = self.variant  # resolve (and probe) before the first import of mitsuba/drjit
        from ._variant import before_engine_import, quiet_engine_import

        before_engine_import()
        with quiet_engine_import(variant):
            import mitsuba as mi

        if mi.variant() != variant:
            try:
                mi.set_variant(variant)
            except Exception as exc:  # e.g. a variant missing from this build
                raise RenderError(f"mitsuba: cannot set variant {variant!r}: {exc}") from exc
        return mi

    @contextlib.contextmanager
    def _engine(self) -> Iterator[Any]:
        """Hold the engine lock with this backend's variant set; the previous variant (another backend's or
        the user's own ``mi.set_variant``) is restored afterwards."""
        with _ENGINE_LOCK:
            import sys

            previous = sys.modules["mitsuba"].variant() if "mitsuba" in sys.modules else None
            mi = self._set_variant()
            try:
                yield mi
            finally:
                if previous is not None and previous != mi.variant():
                    mi.set_variant(previous)

    # -- work --------------------------------------------------------------------------------------
    def integrator_for(self, scene: Any, settings: RenderSettings) -> tuple[dict[str, Any], Any]:
        """The integrator dictionary: ``path`` with max_depth = max_bounces + 2, or max_depth 2 (direct
        light only; 3 when a camera ray may have to pass through an area light's null surface) when
        ``settings.effects`` and the effect analysis finds no indirect light."""
        from blendify_core.ir.lights import AreaLight, PointLight
        from blendify_core.pipeline.effects import analyse_effects

        effects = analyse_effects(scene)
        # hide_emitters gives a coverage alpha under a sky and hides area lights from the camera (as in
        # Cycles), but in Mitsuba 3.9 it also skips emissive *surfaces* along camera rays: with emissive
        # materials the alpha is recovered by compositing instead (see translate)
        hide = bool(settings.transparent_background) and not effects.emission
        max_depth = settings.max_bounces + 2
        if settings.effects and not (
            effects.indirect_diffuse or effects.glossy or effects.transmission or effects.caustics
        ):
            has_area = any(
                light.strength > 0
                and (isinstance(light, AreaLight) or (type(light) is PointLight and light.shadow_soft_size > 0))
                for light in scene.lights
            )
            max_depth = min(max_depth, 3 if has_area else 2)
        return {"type": "path", "max_depth": int(max_depth), "hide_emitters": hide}, effects

    def translate(self, scene: Any, settings: RenderSettings) -> MitsubaNative:
        from blendify_core.ir.scene import Scene

        if not isinstance(scene, Scene):
            raise InvalidSceneError(f"scene: expected a blendify_core.Scene, got {type(scene).__name__}")
        cam = scene.camera
        if cam is None:
            raise InvalidSceneError("scene.camera: the scene has no camera")
        plan = None
        render_cam, spp = cam, int(settings.samples)
        if cam.kind == "perspective" and not math.isclose(cam.fx, cam.fy, rel_tol=1e-9):
            from ._aniso import plan_square_pixels

            plan = plan_square_pixels(cam, spp)  # non-square pixels: a resampled square-pixel render
            render_cam, spp = plan.camera, plan.spp
        integrator, effects = self.integrator_for(scene, settings)
        with self._engine() as mi:
            from ._translate import translate_scene

            film = {
                "type": "hdrfilm",
                "width": int(render_cam.width),
                "height": int(render_cam.height),
                "pixel_format": "rgba",
                "rfilter": {"type": "box"} if settings.pixel_filter == "box" else {"type": "gaussian"},
            }
            sampler = {"type": self.sampler, "sample_count": spp}
            try:
                composite = bool(settings.transparent_background) and effects.emission
                tr = translate_scene(scene, film, sampler, integrator, self.max_analytic_spheres, render_cam, composite)
            except BlendifyError:
                raise
            except Exception as exc:
                raise RenderError(f"mitsuba: translating the scene failed: {type(exc).__name__}: {exc}") from exc
            try:
                mi_scene = mi.load_dict(tr.scene_dict)
                cov_scene = sky_scene = catcher_scene = None
                if tr.catcher_dict is not None:
                    catcher_scene = mi.load_dict(tr.catcher_dict)
                if tr.coverage_dict is not None and tr.background_dict is not None:
                    cov_scene = mi.load_dict(tr.coverage_dict)
                    sky_scene = mi.load_dict(tr.background_dict)
            except Exception as exc:
                raise RenderError(f"mitsuba: mi.load_dict failed: {exc}") from exc
        return MitsubaNative(
            variant=self.variant,
            scene=mi_scene,
            scene_dict=tr.scene_dict,
            shapes=tr.shapes,
            camera=cam,
            spp=spp,
            aniso=plan,
            coverage_scene=cov_scene,
            sky_scene=sky_scene,
            catcher_scene=catcher_scene,
            catchers=tr.catchers,
            integrator=integrator,
            effects=effects,
            n_analytic_spheres=tr.n_analytic_spheres,
        )

    def render_scene(self, scene: Any, settings: RenderSettings) -> RenderResult:
        """Translate (unless the same scene content and translation settings were just translated) and
        render. The cache key is the scene's content fingerprint, so any change re-translates."""
        from blendify_core.errors import BackendUnavailableError

        if self._closed:
            raise BackendUnavailableError(f"{self.name}: this backend instance was closed")
        t0 = time.perf_counter()
        key = (
            scene.fingerprint(),
            settings.samples,
            settings.pixel_filter,
            settings.max_bounces,
            settings.effects,
            settings.transparent_background,
            self.variant,
        )
        cached = self._cache is not None and self._cache[0] == key
        native = self._cache[1] if cached else self.translate(scene, settings)
        self._cache = (key, native)
        t1 = time.perf_counter()
        result = self.render(native, settings)
        t2 = time.perf_counter()
        result.meta["translate_cached"] = cached
        timings = result.meta.setdefault("timings", {})
        timings.setdefault("translate", t1 - t0)
        timings.setdefault("render", t2 - t1)
        return result

    def close(self) -> None:
        self._cache = None
        super().close()

    def _catch_shadows(self, native: MitsubaNative, rgba: np.ndarray, settings: RenderSettings) -> np.ndarray:
        """Shadow-catcher emulation: where a pixel centre sees a catcher, the pixel becomes black with
        alpha = (1 - shadowed / unshadowed radiance) x coverage; the unshadowed radiance comes from a
        render of the catchers alone (same seed and samples)."""
        from ._render import cast_outputs, render_rgba

        free = render_rgba(native.catcher_scene, native.spp, settings.seed)
        cam = native.camera if native.aniso is None else native.aniso.camera
        inst = cast_outputs(native.scene, cam, native.shapes, ("instance",), not native.variant.startswith("scalar"))
        mask = np.isin(inst["instance"], native.catchers)
        lum = np.array([0.2126, 0.7152, 0.0722], np.float32)
        shadowed = rgba[..., :3] @ lum
        unshadowed = free[..., :3] @ lum
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(unshadowed > 1e-8, shadowed / unshadowed, 1.0)
        out = rgba.copy()
        out[mask, :3] = 0.0
        out[mask, 3] = np.clip(1.0 - ratio[mask], 0.0, 1.0) * free[mask, 3]
        return out

    def render(self, native: MitsubaNative, settings: RenderSettings) -> RenderResult:
        if not isinstance(native, MitsubaNative):
            raise InvalidSceneError(f"native: expected a MitsubaNative from translate(), got {type(native).__name__}")
        timings: dict[str, float] = {}
        out: dict[str, Any] = {}
        with self._engine():
            if settings.threads is not None:
                import drjit as dr

                dr.set_thread_count(int(settings.threads))
            from ._render import cast_outputs, render_rgba

            try:
                if settings.wants("rgb"):
                    t0 = time.perf_counter()
                    rgba = render_rgba(native.scene, native.spp, settings.seed)
                    if native.coverage_scene is not None:
                        # emissive surfaces + a sky: rendered with the sky visible; the coverage alpha comes
                        # from a one-bounce pass of the shapes, the sky behind partly covered pixels is removed
                        alpha = render_rgba(native.coverage_scene, native.spp, settings.seed)[..., 3]
                        sky = render_rgba(native.sky_scene, native.spp, settings.seed)[..., :3]
                        rgba[..., :3] -= (1.0 - alpha)[..., None] * sky
                        rgba[..., :3] = np.maximum(rgba[..., :3], 0.0)
                        rgba[..., 3] = alpha
                    if native.catcher_scene is not None:
                        rgba = self._catch_shadows(native, rgba, settings)
                    if native.aniso is not None:
                        from ._aniso import resample_rows

                        cam = native.camera
                        rgba = resample_rows(rgba, cam.width, cam.height, native.aniso.k, native.aniso.row_scale)
                    if not settings.transparent_background:
                        rgba[..., 3] = 1.0
                    out["rgba"] = rgba
                    timings["render_rgb"] = time.perf_counter() - t0
                geo = tuple(o for o in ("depth", "normal", "albedo", "instance") if settings.wants(o))
                geo = tuple(o for o in geo if o not in out)
                if geo:
                    t0 = time.perf_counter()
                    out.update(
                        cast_outputs(
                            native.scene,
                            native.camera,
                            native.shapes,
                            geo,
                            vectorised=not native.variant.startswith("scalar"),
                        )
                    )
                    timings["ray_cast"] = time.perf_counter() - t0
            except BlendifyError:
                raise
            except Exception as exc:
                raise RenderError(f"mitsuba: rendering failed: {type(exc).__name__}: {exc}") from exc
        choice = self.variant_choice
        meta = {
            "backend": self.name,
            "engine_version": self.engine_version(),
            "variant": native.variant,
            "variant_reason": choice.reason,
            "libllvm": choice.libllvm,
            "integrator": native.integrator["type"],
            "max_depth": native.integrator["max_depth"],
            "hide_emitters": native.integrator["hide_emitters"],
            "spp": settings.samples,
            "rendered_spp": _sampler_count(native),
            "samples": settings.samples,
            "sampler": self.sampler,
            "seed": settings.seed,
            "pixel_filter": settings.pixel_filter,
            "alpha_compositing": native.coverage_scene is not None,
            "shadow_catcher_emulated": native.catcher_scene is not None,
            "analytic_spheres": native.n_analytic_spheres,
            "timings": timings,
        }
        if native.effects is not None:
            meta["effects"] = native.effects.to_dict()
        if settings.denoise:
            meta.setdefault("notes", []).append("denoise requested: Mitsuba's CPU build has no denoiser (not applied)")
        if settings.adaptive or settings.time_limit or settings.target_error:
            meta.setdefault("notes", []).append(
                "adaptive / time_limit / target_error are not supported by Mitsuba: fixed spp rendered"
            )
        if settings.clamp_direct or settings.clamp_indirect:
            meta.setdefault("notes", []).append("sample clamping is not supported by Mitsuba (unclamped)")
        return RenderResult(
            rgba=out.get("rgba"),
            depth=out.get("depth"),
            normal=out.get("normal"),
            albedo=out.get("albedo"),
            instance=out.get("instance"),
            instance_tags=[],
            meta=meta,
        )
