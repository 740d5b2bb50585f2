"""``bf.render``: one call from a scene to a :class:`RenderResult` with any backend."""

from __future__ import annotations

import dataclasses
import logging
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from blendify_core.errors import (
    BackendUnavailableError,
    InvalidSceneError,
    RenderError,
    UnsupportedFeatureError,
    warn_at_caller,
)
from blendify_core.ir.cameras import Camera, OrthographicCamera, PerspectiveCamera
from blendify_core.ir.renderables import PointCloud
from blendify_core.ir.scene import Scene
from blendify_core.ir.validate import strict_arguments
from blendify_core.pipeline.backend import Backend, DeviceChoice
from blendify_core.pipeline.capabilities import scene_features
from blendify_core.pipeline.compat import map_legacy_keywords
from blendify_core.pipeline.distortion import margin_camera, remap_result
from blendify_core.pipeline.effects import Effects, analyse_effects
from blendify_core.pipeline.meta import RenderMeta, Simulated, complete_timings
from blendify_core.pipeline.recentre import Bounds, _scene_scale, needs_recentring, recentred_view
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import (
    ENGINE_LIMIT_PREFIX,
    RenderSettings,
    engine_limits,
    resolve_settings,
    settings_bias,
)
from blendify_core.pipeline.translator import check_handlers
from blendify_core.registry import available_backends, shared_backend
from blendify_core.typing import Float64Array, FloatArray

__all__ = ["render", "check_capabilities", "choose_backend"]

log = logging.getLogger("blendify_core")

# backend=None: the preference order per quality mode
_PREFERENCE = {
    "preview": ("pyrender", "cycles", "mitsuba"),
    "draft": ("cycles", "mitsuba", "pyrender"),
    "final": ("cycles", "mitsuba", "pyrender"),
}
_SETTING_NAMES = {f.name for f in dataclasses.fields(RenderSettings)} - {"extra"}


def choose_backend(quality: str) -> tuple[str, list[str]]:
    """The best available backend for ``quality`` and the reasons the better ones were skipped."""
    status = available_backends()
    skipped: list[str] = []
    order = list(_PREFERENCE.get(quality, _PREFERENCE["final"]))
    order += [n for n in sorted(status) if n not in order]
    for name in order:
        st = status.get(name)
        if st is None:
            continue
        if st.available:
            return name, skipped
        skipped.append(f"{name}: {st.reason}")
    raise BackendUnavailableError("no backend is available: " + "; ".join(skipped or ["none registered"]))


def check_capabilities(backend: Backend, scene: Scene, settings: RenderSettings) -> list[str]:
    """Check the scene's features against the backend's capability table; return the approximations."""
    if backend.translator_class is not None:
        check_handlers(backend.translator_class, scene)
    caps = backend.capabilities()
    approximations: list[str] = []
    for feature, where in scene_features(scene, settings.outputs).items():
        cap = caps.get(feature)
        if cap is None or cap.level == "unsupported":
            note = f" ({cap.note})" if cap is not None and cap.note else ""
            raise UnsupportedFeatureError(
                f"backend {backend.name!r} cannot render {feature} used by {where}{note}",
                feature=feature,
                backend=backend.name,
            )
        if cap.level == "approximate":
            text = f"{feature}: {cap.note}" if cap.note else feature
            if settings.strict:
                raise _strict_refusal(backend, f"only approximates {feature} used by {where} ({cap.note})", feature)
            approximations.append(text)
    for a in scene.attachments:  # a file this backend does not read: it renders the file's IR parse
        limits = a.ir_limits() if a.format not in backend.file_formats else []
        if limits and settings.strict:
            what = f"{len(limits)} item(s) ({'; '.join(a.approximations[:3])}...)"
            raise _strict_refusal(
                backend, f"renders the IR parse of {a.path!r}, which approximates {what}", "attachment"
            )
        approximations.extend(limits)
    unapplied = engine_limits(settings, backend.unapplied_settings)
    if unapplied and settings.strict:
        what = "; ".join(x[len(ENGINE_LIMIT_PREFIX) :] for x in unapplied)
        raise _strict_refusal(backend, f"cannot apply the render settings {what}", "settings")
    approximations.extend(unapplied)
    return approximations


def _strict_refusal(backend: Backend, what: str, feature: str) -> UnsupportedFeatureError:
    """The error of ``strict=True`` for an approximation: backend ``what``."""
    return UnsupportedFeatureError(
        f"backend {backend.name!r} {what}; strict=True forbids approximations", feature=feature, backend=backend.name
    )


_OUTPUT_FIELDS: dict[str, tuple[str, tuple[int, ...], type[np.generic]]] = {
    "rgb": ("rgba", (4,), np.float32),
    "depth": ("depth", (), np.float32),
    "normal": ("normal", (3,), np.float32),
    "albedo": ("albedo", (3,), np.float32),
    "instance": ("instance", (), np.int32),
}
_ARRAYS = ("rgba", "depth", "normal", "albedo", "instance")


@dataclass(frozen=True)
class _ViewPlan:
    """What the backend renders and how its result becomes the requested picture."""

    #: the camera the result is for (``resolution_percentage`` applied)
    out_cam: Camera
    #: the camera the backend renders (a distortion margin, padding up to the engine's minimum size)
    render_cam: Camera
    #: the scene handed to the backend (``render_cam``; re-centred when far from the origin)
    view: Scene
    #: where each output pixel samples the undistorted render (distorted cameras only)
    src: Float64Array | None
    #: (height, width) to crop a padded render to
    crop: tuple[int, int] | None
    #: the world origin of a re-centred view
    origin: Float64Array | None


@dataclass(frozen=True)
class _Preflight:
    """What bf.render learnt before calling the backend (recorded in ``meta``)."""

    approximations: list[str]
    effects: Effects
    fallback_notes: list[str]
    #: warnings already issued that also go to ``meta["warnings"]``
    warnings: list[str] = field(default_factory=list)
    #: what the backend renders on (backends with a ``device=`` option)
    device: DeviceChoice | None = None


def _padded_camera(cam: Camera, width: int, height: int) -> Camera:
    """A copy of ``cam`` with a larger image whose extra pixels extend right and down (same intrinsics)."""
    padded = cam.copy()
    padded._resolution = (width, height)
    if isinstance(cam, OrthographicCamera) and isinstance(padded, OrthographicCamera):
        padded._ortho_scale = cam.pixel_size * width  # same pixel size over the wider image
    return padded


def _check_outputs(result: object, settings: RenderSettings, cam: Camera, backend_name: str) -> RenderResult:
    """Hold a backend to the RenderResult contract: every requested output present with the camera's
    shape (cast to the canonical dtype), every other output None."""
    if not isinstance(result, RenderResult):
        raise RenderError(f"backend {backend_name!r} returned {type(result).__name__}, not a RenderResult")
    shape = (cam.height, cam.width)
    for output, (attr, channels, dtype) in _OUTPUT_FIELDS.items():
        data = getattr(result, attr)
        if output not in settings.outputs:
            setattr(result, attr, None)
            continue
        if data is None:
            raise RenderError(f"backend {backend_name!r} returned no {output!r} output although it was requested")
        data = np.asarray(data)
        if data.shape != shape + channels:
            raise RenderError(
                f"backend {backend_name!r} returned the {output!r} output with shape {data.shape}, "
                f"expected {shape + channels}"
            )
        setattr(result, attr, data if data.dtype == dtype else data.astype(dtype))
    return result


@strict_arguments
def render(
    scene: Scene,
    backend: str | Backend | None = None,
    quality: str = "final",
    samples: int | None = None,
    seed: int = 0,
    outputs: str | Sequence[str] = ("rgb",),
    threads: int | None = None,
    strict: bool = False,
    **kwargs: Any,
) -> RenderResult:
    """Render ``scene`` and return a :class:`RenderResult`.

    ``backend``: a name ("cycles", "mitsuba", "pyrender"), a backend instance, or None for the best
    available one for ``quality`` ("preview" -> pyrender; "draft"/"final" -> cycles), falling back to the
    next available backend with a logged reason. Keyword arguments that name a :class:`RenderSettings`
    field (``denoise``, ``max_bounces``, ``time_limit``, ``target_error``, ``pixel_filter``, ...) override
    the quality preset; all others are backend options (e.g. ``platform="egl"``, ``variant="scalar_rgb"``).
    ``result.meta`` holds the keys documented in :class:`~blendify_core.pipeline.meta.RenderMeta`.
    """
    t_start = time.perf_counter()
    if not isinstance(scene, Scene):
        raise InvalidSceneError(f"scene: expected a blendify_core.Scene, got {type(scene).__name__}")
    outputs, kwargs = map_legacy_keywords(outputs, kwargs)
    setting_kwargs = {k: v for k, v in kwargs.items() if k in _SETTING_NAMES}
    options = {k: v for k, v in kwargs.items() if k not in _SETTING_NAMES}
    settings = resolve_settings(
        quality=quality, samples=samples, seed=seed, outputs=outputs, threads=threads, strict=strict, **setting_kwargs
    )
    if scene.camera is None:
        raise InvalidSceneError(
            "scene.camera: the scene has no camera; call scene.set_perspective_camera(...) "
            "or scene.set_orthographic_camera(...) first"
        )
    inst, fallback_notes = _backend_instance(backend, settings.quality, options)
    bounds = scene.bounds()  # once per render: the clip, precision and re-centring checks share it
    preflight = _preflight(scene, inst, settings, bounds, fallback_notes)
    plan = _plan_view(scene, scene.camera, inst, bounds)
    precision_warning = _precision_check(scene, bounds)
    if precision_warning:
        warnings.warn(precision_warning, stacklevel=2)
        preflight.warnings.append(precision_warning)

    t_call = time.perf_counter()
    result = _call_backend(inst, plan.view, settings)
    _finish_outputs(result, settings, plan, inst.name)
    _record_meta(result, scene, inst, settings, preflight, plan)
    complete_timings(result.meta.setdefault("timings", {}), time.perf_counter() - t_call)
    result.meta["timings"]["total"] = time.perf_counter() - t_start
    return result


def _backend_instance(
    backend: str | Backend | None, quality: str, options: dict[str, Any]
) -> tuple[Backend, list[str]]:
    """The backend instance to render with, and the reasons better backends were skipped (``backend=None``)."""
    if isinstance(backend, Backend):
        if options:
            raise InvalidSceneError(
                f"render: backend options {sorted(options)} cannot be applied to an existing "
                "backend instance; pass them when creating it"
            )
        return backend, []
    fallback_notes: list[str] = []
    if backend is None:
        name, fallback_notes = choose_backend(quality)
        for note in fallback_notes:
            log.info("blendify: skipped backend %s", note)
    elif isinstance(backend, str):
        name = backend
    else:
        raise InvalidSceneError(f"backend: expected a backend name or instance, got {type(backend).__name__}")
    inst = shared_backend(name, **options)
    if not isinstance(inst, Backend):
        raise BackendUnavailableError(f"backend {name!r}: the registry returned {type(inst).__name__}, not a Backend")
    return inst, fallback_notes


def _preflight(
    scene: Scene, inst: Backend, settings: RenderSettings, bounds: Bounds | None, fallback_notes: list[str]
) -> _Preflight:
    """Warn about a black or empty picture, check the backend can render the scene, analyse its effects."""
    if (
        "rgb" in settings.outputs
        and not len(scene.lights)
        and scene.lights.background is None
        and scene.lights.environment is None
        and not any(m.is_emissive for r in scene.renderables for m in r.materials)
    ):
        warnings.warn(
            "scene has no lights, no background and no emissive material: the colour image will be black", stacklevel=3
        )
    recorded = []
    clip_warning = _clip_check(scene, bounds)
    if clip_warning:
        warnings.warn(clip_warning, stacklevel=3)
        recorded.append(clip_warning)
    for note in numeric_limit_warnings(scene, inst, bounds):
        warnings.warn(note, stacklevel=3)
        recorded.append(note)
    approximations = check_capabilities(inst, scene, settings)
    device = inst.device_choice()
    if device is not None and device.fallback:
        if settings.strict:
            raise BackendUnavailableError(
                f"{inst.name}: {device.option}={device.requested!r} is unavailable here ({device.fallback}); "
                f"strict=True refuses to render on {device.used} instead"
            )
        note = (
            f"{inst.name}: {device.option}={device.requested!r} is unavailable here ({device.fallback}); "
            f"rendering on {device.used}"
        )
        warn_at_caller(note)
        recorded.append(note)
    return _Preflight(approximations, analyse_effects(scene), fallback_notes, recorded, device)


def _plan_view(scene: Scene, cam: Camera, inst: Backend, bounds: Bounds | None) -> _ViewPlan:
    """The camera and scene view the backend renders: resolution percentage, a margin for lens
    distortion, padding to the engine's minimum image size, re-centring of far scenes."""
    out_cam = cam._scaled(cam.resolution_percentage / 100.0) if cam.resolution_percentage != 100 else cam
    render_cam: Camera = out_cam
    src = None
    if isinstance(out_cam, PerspectiveCamera) and out_cam.distortion is not None:
        render_cam, src = margin_camera(out_cam)
    crop = None
    min_w, min_h = inst.min_resolution
    if render_cam.width < min_w or render_cam.height < min_h:
        # engines with a minimum image size render a larger image with the same pixels at the top left
        crop = (render_cam.height, render_cam.width)
        render_cam = _padded_camera(render_cam, max(render_cam.width, min_w), max(render_cam.height, min_h))
    view = scene if render_cam is cam else scene.with_camera(render_cam)
    origin = None
    if needs_recentring(view, bounds):
        view, origin = recentred_view(view, bounds)
    return _ViewPlan(out_cam, render_cam, view, src, crop, origin)


def _call_backend(inst: Backend, view: Scene, settings: RenderSettings) -> RenderResult:
    """One render of ``view``, or independent passes until ``target_error`` for a path tracer."""
    if settings.target_error is not None and inst.path_tracer:
        return render_to_target(inst, view, settings)
    result = inst.render_scene(view, settings)
    if settings.target_error is not None and isinstance(result, RenderResult):
        result.meta.setdefault("warnings", []).append(
            f"target_error: backend {inst.name!r} is not a path tracer; rendered once (its error is bias, not noise)"
        )
    return result


def _finish_outputs(result: RenderResult, settings: RenderSettings, plan: _ViewPlan, backend_name: str) -> None:
    """Check the backend's outputs, crop a padded render, remap a distorted camera's outputs."""
    _check_outputs(result, settings, plan.render_cam, backend_name)
    if plan.crop is not None:
        height, width = plan.crop
        for attr in _ARRAYS:
            data = getattr(result, attr)
            if data is not None:
                setattr(result, attr, np.ascontiguousarray(data[:height, :width]))
    # a distorted camera is perspective, and so is its margin camera (padded or not)
    if (
        plan.src is not None
        and isinstance(plan.out_cam, PerspectiveCamera)
        and isinstance(plan.render_cam, PerspectiveCamera)
    ):
        t0 = time.perf_counter()
        remap_result(result, plan.src, plan.out_cam, plan.render_cam)
        result.meta.setdefault("timings", {})["distortion"] = time.perf_counter() - t0


def _record_meta(
    result: RenderResult, scene: Scene, inst: Backend, settings: RenderSettings, pre: _Preflight, plan: _ViewPlan
) -> None:
    """The core's keys of ``result.meta`` (see :class:`RenderMeta`); a backend's own values are kept
    where it set them (``backend``, ``engine_version``, ``effects``, ``samples``)."""
    meta = result.meta
    meta.setdefault("backend", inst.name)
    meta.setdefault("engine_version", inst.engine_version())
    meta["settings"] = settings.to_dict()
    meta.setdefault("effects", pre.effects.to_dict())
    meta["simulated"] = _simulated(settings, pre.effects, meta.get("indirect_pilot"), meta.get("caustics_pilot"))
    meta.setdefault("bias", settings_bias(settings) if inst.path_tracer else [])
    meta["approximations"] = sorted(set(pre.approximations) | set(meta.get("approximations", [])))
    if pre.fallback_notes:
        meta["backend_fallback"] = pre.fallback_notes
    meta.setdefault("samples", settings.samples)
    if pre.device is not None:
        meta.setdefault("device", pre.device.used)
    if plan.origin is not None:
        meta["recentred_origin"] = [float(x) for x in plan.origin]
    if pre.warnings:
        meta.setdefault("warnings", []).extend(pre.warnings)
    meta["scene_fingerprint"] = scene.fingerprint()
    if not result.instance_tags:
        result.instance_tags = [r.tag for r in scene.renderables]
    meta["path_tracer"] = bool(inst.path_tracer)
    _error_meta(meta, settings, meta["path_tracer"])


def _simulated(
    settings: RenderSettings,
    effects: Effects,
    pilot: dict[str, Any] | None = None,
    caustics_pilot: dict[str, Any] | None = None,
) -> Simulated:
    """What light transport was simulated and why (``meta["simulated"]``)."""
    if "rgb" not in settings.outputs:
        return {"lighting": False, "why": "only geometric outputs requested: no lighting needed"}
    if not settings.effects:
        return {"lighting": True, "effects": "full", "why": "effects=False: full settings requested"}
    on = [f for f, v in effects.to_dict().items() if f != "reasons" and v]
    sim: Simulated = {
        "lighting": True,
        "effects": on,
        "why": "effects=True: only what analyse_effects found is simulated",
    }
    if pilot is not None and pilot.get("dropped"):
        sim["effects"] = [f for f in on if f not in ("indirect_diffuse", "caustics")]
        sim["dropped"] = {"indirect light": str(pilot["why"])}
    elif caustics_pilot is not None and caustics_pilot.get("dropped"):
        sim["effects"] = [f for f in on if f != "caustics"]
        sim["dropped"] = {"caustics": str(caustics_pilot["why"])}
    elif not settings.caustics and "caustics" in on:
        sim["effects"] = [f for f in on if f != "caustics"]
        sim["dropped"] = {"caustics": "caustics=False requested"}
    return sim


def _error_meta(meta: RenderMeta, settings: RenderSettings, path_tracer: bool) -> None:
    """Every result says whether its error was estimated (``estimated_error`` is None when not)."""
    if meta.get("estimated_error") is not None:
        return
    meta["estimated_error"] = None
    if "rgb" not in settings.outputs:
        why = "not estimated: no colour output"
    elif path_tracer and settings.denoise:
        why = "not estimated: denoised (a denoiser's error is bias, not noise)"
    elif path_tracer:
        why = (
            f"not estimated: a fixed {settings.samples} samples in one pass (leave samples unset under 'final', "
            "or pass target_error=, for an estimate from independent passes)"
        )
    else:
        why = "not estimated: raster backend (deterministic: its error is bias, not noise)"
    meta["estimated_error_kind"] = why


def numeric_limit_warnings(scene: Scene, inst: Backend, bounds: Bounds | None) -> list[str]:
    """Warnings, each naming the backend and the cause, for a scene beyond where the backend's arithmetic
    renders right (its measured ``numeric_limits``): geometry too far from the camera, a clip range it
    cannot represent, faces of objects at the same place."""
    limits, cam = type(inst).numeric_limits, scene.camera
    out: list[str] = []
    if cam is None:
        return out
    name = inst.name
    if "max_distance" in limits and bounds is not None:
        lo, hi = bounds
        far = float(np.max(np.abs(np.stack([lo, hi]) - cam.translation)))
        if far > limits["max_distance"]:
            out.append(
                f"{name}: geometry {far:.3g} m from the camera is beyond what {name} renders right "
                f"({limits['max_distance']:g} m; its float32 arithmetic renders nothing there): scale the scene "
                "down (the camera's near/far with it)"
            )
    if "max_clip_ratio" in limits and cam.far / cam.near > limits["max_clip_ratio"]:
        out.append(
            f"{name}: camera far / near = {cam.far / cam.near:.3g} is beyond what {name}'s depth buffer resolves "
            f"({limits['max_clip_ratio']:g}; objects disappear): raise `near` or lower `far`"
        )
    if "min_near" in limits and cam.near < limits["min_near"]:
        out.append(
            f"{name}: camera near = {cam.near:g} m is below what {name} represents ({limits['min_near']:g} m; "
            "the image comes out empty): raise `near`"
        )
    if limits.get("coincident_faces"):
        pairs = coincident_faces(scene)
        if pairs:
            shown = ", ".join(f"{a!r} and {b!r}" if a != b else f"{a!r} (with itself)" for a, b in pairs[:5])
            out.append(
                f"{name}: faces at the same place in {shown}: {name} renders coincident faces dark (each "
                "shadows the other), not just z-fighting; remove the duplicate or offset one object"
            )
    return out


#: above this many triangles in a scene, coincident faces are not looked for (the check would cost seconds)
COINCIDENT_MAX_TRIANGLES = 2_000_000


def coincident_faces(scene: Scene) -> list[tuple[str, str]]:
    """Pairs of renderable tags (a tag twice: within one object) that have a triangle at exactly the same
    place in world space (vertices equal to 1e-9 of the scene's size, in any order)."""
    parts, owners, total = [], [], 0
    for i, r in enumerate(scene.renderables):
        if isinstance(r, PointCloud):
            continue
        m = r.to_mesh()
        total += len(m.faces)
        if total > COINCIDENT_MAX_TRIANGLES:
            return []
        if len(m.faces) == 0:
            continue
        mw = r.matrix_world
        v = m.vertices @ mw[:3, :3].T + mw[:3, 3]
        parts.append(v[m.faces])
        owners.append(np.full(len(m.faces), i))
    if not parts:
        return []
    tris = np.concatenate(parts)
    owner = np.concatenate(owners)
    eps = 1e-9 * max(1.0, float(np.abs(tris).max()))
    q = np.round(tris / eps).astype(np.int64)
    h = q @ np.array([73856093, 19349663, 83492791], dtype=np.int64)
    q = np.take_along_axis(q, np.argsort(h, axis=1)[..., None], axis=1).reshape(len(q), 9)
    _, inverse, counts = np.unique(q, axis=0, return_inverse=True, return_counts=True)
    dup = counts[inverse.reshape(-1)] > 1
    if not dup.any():
        return []
    tags = [r.tag for r in scene.renderables]
    pairs: set[tuple[str, str]] = set()
    groups: dict[int, list[int]] = {}
    for g, o in zip(inverse.reshape(-1)[dup].tolist(), owner[dup].tolist()):
        groups.setdefault(g, []).append(o)
    for members in groups.values():
        a, b = sorted(members)[:2]
        pairs.add((tags[a], tags[b]))
    return sorted(pairs)


def _clip_check(scene: Scene, bounds: Bounds | None) -> str | None:
    """A warning when the scene's geometry (``bounds``) lies entirely outside the camera's [near, far]."""
    cam = scene.camera
    if cam is None or bounds is None:
        return None
    lo, hi = bounds
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    depth = cam.world_to_camera_cv(corners)[:, 2]
    if depth.max() < cam.near:
        return (
            f"camera.near: every object is nearer than the near clip ({cam.near:g}; nearest depth "
            f"{depth.min():.3g}): the image will be empty; lower `near`"
        )
    if depth.min() > cam.far:
        return (
            f"camera.far: every object is beyond the far clip ({cam.far:g}; nearest depth {depth.min():.3g}): "
            "the image will be empty; raise `far`"
        )
    return None


def _per_sample_variance(passes: FloatArray, n: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The sample-weighted mean of passes (K, H, W, C) with n_i samples each, and the per-sample variance
    sum(n_i (x_i - mean)^2) / (K - 1) of each pixel-channel."""
    k = passes.shape[0]
    w = (n / n.sum()).reshape((k,) + (1,) * (passes.ndim - 1))
    mean = (passes * w).sum(axis=0)
    var_one = (n.reshape(w.shape) * (passes - mean) ** 2).sum(axis=0) / (k - 1)
    return mean, var_one


def _relative_divisor(passes: FloatArray, n: FloatArray, mean: FloatArray) -> FloatArray:
    """The divisor m^2 + 0.01 of the relative error of each pixel-channel of the passes' (K, H, W, C) mean.

    The pixel's own mean is correlated with its noise: a pass with a bright outlier raises the divisor along
    with the error it adds (the estimate was 0.6-0.7x the truth on a glossy metal sphere). m is the median of
    the mean over the pixel's 3x3 neighbourhood (edges repeated), which such an outlier does not raise, kept
    between the pixel's mean without its brightest pass (so a feature a pixel wide, bright in every pass,
    keeps its value) and the pixel's mean (so a dark pixel beside a bright edge keeps its own). Arrays of
    other shapes use the mean itself."""
    if mean.ndim != 3 or min(mean.shape[:2]) < 3 or passes.shape[0] < 2:
        return mean * mean + 1e-2
    h, w = mean.shape[:2]
    pad = np.pad(mean, ((1, 1), (1, 1), (0, 0)), mode="edge")
    med = np.median(np.stack([pad[dy : dy + h, dx : dx + w] for dy in range(3) for dx in range(3)]), axis=0)
    top = np.argmax(passes, axis=0)[None]
    n_top = n[top[0]]
    weighted = (passes * n.reshape((-1,) + (1,) * (passes.ndim - 1))).sum(axis=0)
    without = (weighted - n_top * np.take_along_axis(passes, top, axis=0)[0]) / (n.sum() - n_top)
    m: FloatArray = np.clip(med, without, mean)
    return m * m + 1e-2


def relative_error_estimate(passes: FloatArray, samples: FloatArray | None = None) -> float:
    """Estimated relative RMS error of the sample-weighted mean of independent passes (K, H, W, C), K >= 2.

    With ``samples`` n_i per pass (default: equal), the per pixel-channel variance of one sample is
    estimated as sum(n_i (x_i - mean)^2) / (K - 1) and the variance of the mean is that / sum(n_i). The
    result is the RMS over pixel-channels of sqrt(var / (m^2 + 0.01)) (Mitsuba's relative-MSE floor), with m
    an estimate of the pixel's value that a bright outlier does not raise (:func:`_relative_divisor`): its
    square is the relative MSE."""
    return float(np.sqrt(_relative_terms(passes, samples).mean()))


#: what every error statistic of a set of passes starts from (:func:`_error_parts`): the samples per pass, the
#: per-sample variance, the relative divisor and :func:`_pass_size_factor`
_ErrorParts = tuple[FloatArray, FloatArray, FloatArray, float]


def _error_parts(passes: FloatArray, samples: FloatArray | None = None) -> _ErrorParts:
    """:data:`_ErrorParts` of passes (K, H, W, C), computed once for the estimate, its bound and its interval."""
    n = np.ones(passes.shape[0]) if samples is None else np.asarray(samples, dtype=np.float64)
    mean, var_one = _per_sample_variance(passes, n)
    divisor = _relative_divisor(passes, n, mean)
    return n, var_one, divisor, _pass_size_factor(passes, n, mean, divisor, var_one / n.sum() / divisor)


def _relative_terms(
    passes: FloatArray, samples: FloatArray | None = None, parts: _ErrorParts | None = None
) -> FloatArray:
    """Each pixel-channel's relative MSE of the passes' mean (:func:`relative_error_estimate` is the root of
    their mean; :func:`error_dof` counts the pixels that carry them), times :func:`_pass_size_factor`."""
    n, var_one, divisor, factor = parts if parts is not None else _error_parts(passes, samples)
    terms: FloatArray = var_one / n.sum() / divisor * factor
    return terms


#: the faster rate of :func:`_pass_size_factor`'s model: the variance of a stratified (scrambled Sobol) pass
#: at a silhouette or shadow edge falls as samples^-1.5 (a discontinuity in the pixel's two dimensions)
STRATIFIED_RATE = 1.5
#: :func:`_pass_size_factor` is fitted only where the estimate's degrees of freedom (:func:`error_dof`) and
#: each pass's pixels that carry its deviation from the mean (their participation ratio) are at least this
#: many: each pass's pooled spread is then known to about 10 %, and no few bright pixels decide it
SIZE_FIT_PIXELS = 200.0
#: ... and lowers the estimated relative MSE at most this much (the estimate at most 3.2x)
SIZE_FIT_FLOOR = 0.1
#: the model's rates: independent samples (1) and a stratified pass at an edge (:data:`STRATIFIED_RATE`)
_RATES = (1.0, STRATIFIED_RATE)


def _deviation_rates(n: FloatArray) -> FloatArray:
    """(K, 2): E[squared deviation of pass i from the weighted mean] per unit of each model term
    (:data:`_RATES`): its own variance less twice its share of the mean's, plus the mean's."""
    w = n / n.sum()
    return np.stack([n**-a * (1.0 - 2.0 * w) + (w * w * n**-a).sum() for a in _RATES], axis=1)


def _size_model(d2: FloatArray, n: FloatArray) -> FloatArray | None:
    """The coefficients (a, b) >= 0 of the passes' pooled relative variances a / n + b / n^STRATIFIED_RATE,
    fitted to their pooled squared deviations ``d2`` from the sample-weighted mean; None where the sizes
    cannot tell them apart (fewer than 3 passes, all of one size)."""
    k = len(n)
    if k < 3 or np.ptp(n) == 0 or not np.all(d2 > 0):
        return None
    rows = _deviation_rates(n) / d2[:, None]  # relative misfit: each pass counts alike
    coef, *_ = np.linalg.lstsq(rows, np.ones(k), rcond=None)
    if coef.min() < 0:  # non-negative: the better of the two rates alone
        fits = [np.linalg.lstsq(rows[:, j : j + 1], np.ones(k), rcond=None) for j in range(2)]
        j = int(np.argmin([float(f[1][0]) if len(f[1]) else np.inf for f in fits]))
        coef = np.zeros(2)
        coef[j] = max(float(fits[j][0][0]), 0.0)
    return None if coef.sum() <= 0 else np.asarray(coef, dtype=np.float64)


def _mean_mse(coef: FloatArray, n: FloatArray) -> tuple[float, float]:
    """Under the model ``coef``: (the relative MSE of the passes' mean, what the 1/samples estimate expects
    for it)."""
    w = n / n.sum()
    true_mse = float(sum(c * (w * w * n**-a).sum() for c, a in zip(coef, _RATES)))
    assumed = float((coef * (n[:, None] * _deviation_rates(n)).sum(axis=0)).sum() / (len(n) - 1) / n.sum())
    return true_mse, assumed


def _size_factor_of_gram(gram: FloatArray, n: FloatArray) -> float:
    """:func:`_pass_size_factor` from the pooled products of the passes' deviations from their mean."""
    k = len(n)
    d2 = np.diag(gram).copy()
    factors = []
    keep = np.ones(k, dtype=bool)
    for i in range(-1, k):
        if i < 0:
            sub, sizes = d2, n
        else:  # the deviations from the mean without pass i: d_j + c d_i, c = n_i / (N - n_i)
            c = n[i] / (n.sum() - n[i])
            keep[i] = False
            sub, sizes = (d2 + 2.0 * c * gram[:, i] + c * c * d2[i])[keep], n[keep]
            keep[i] = True
        coef = _size_model(sub, sizes)
        if coef is None:
            return 1.0  # one pass decides the fit alone
        true_mse, assumed = _mean_mse(coef, n)  # the model fitted without pass i, for all the passes
        factors.append(true_mse / assumed)
    return float(np.clip(np.median(factors), SIZE_FIT_FLOOR, 1.0))


def expected_size_factor(coef: FloatArray, n: FloatArray) -> float:
    """The :func:`_pass_size_factor` that passes of ``n`` samples give on average where their pooled relative
    variances are ``coef`` (:func:`_size_model`): ``bf.estimate_cost`` replays the render's schedule with it."""
    n = np.asarray(n, dtype=np.float64)
    if len(n) < 4 or np.ptp(n) == 0:
        return 1.0
    w = n / n.sum()
    var = sum(c * n**-a for c, a in zip(coef, _RATES))
    mean_var = float((w * w * var).sum())
    gram = np.diag(var) - (w * var)[:, None] - (w * var)[None, :] + mean_var
    return _size_factor_of_gram(gram, n)


def _pass_size_factor(
    passes: FloatArray, n: FloatArray, mean: FloatArray, divisor: FloatArray, terms: FloatArray
) -> float:
    """How much smaller the relative MSE of the passes' mean is than its 1/samples estimate (<= 1).

    The estimate assumes each pass's variance falls as 1/samples, as for independent random samples. A
    stratified sampler beats that where the pixel's own two dimensions decide the value (silhouettes, shadow
    edges): measured in Cycles at 48x48, samples x relative variance fell from 0.104 at 16 spp to 0.046 at 64
    and 0.025 at 256 on a point cloud (0.0076 -> 0.0037 on the bunny). Since ``final``'s later passes are
    larger, the passes of the first size then make the estimate too high (1.6-1.75x the true error on the
    point cloud and the primitives). Where the passes have different sizes, their pooled squared deviations
    from the mean are fitted with variances a / n + b / n^:data:`STRATIFIED_RATE` (a, b >= 0) and the estimate
    scaled by the fitted model's ratio of the mean's variance to what the 1/n estimate expects. The factor is
    the median of the fits on all passes and on all but each one (their largest was 2.3x too high on two
    large passes of a stratified stand-in: the fit without one of them has little to go on), 1 unless every
    such fit can tell the sizes apart (at least two passes of sizes other than the first), not below
    :data:`SIZE_FIT_FLOOR`, and 1 where fewer than :data:`SIZE_FIT_PIXELS` pixels carry the passes' deviations
    (few pixels, or a pass with a rare bright path: that pass would decide the fit). Equal passes: exactly 1."""
    flat = _fit_deviations(passes, n, mean, divisor, terms)
    return 1.0 if flat is None else _size_factor_of_gram(flat @ flat.T / flat.shape[1], n)


def _fit_deviations(
    passes: FloatArray, n: FloatArray, mean: FloatArray, divisor: FloatArray, terms: FloatArray
) -> FloatArray | None:
    """(K, pixel-channels): each pass's relative deviation from the mean, where :func:`_pass_size_factor` may
    fit them (passes of different sizes, enough pixels carry them); None otherwise."""
    k = len(n)
    if k < 4 or np.ptp(n) == 0 or _dof_of_terms(terms, k) < SIZE_FIT_PIXELS:
        return None
    x = (passes - mean) / np.sqrt(divisor)
    t = (x * x).reshape(k, -1, x.shape[-1]).sum(axis=-1) if x.ndim >= 3 else (x * x).reshape(k, -1)
    if float(((t.sum(axis=1) ** 2) / np.maximum((t * t).sum(axis=1), 1e-300)).min()) < SIZE_FIT_PIXELS:
        return None  # a pass whose deviation few pixels carry (a rare bright path) would decide the fit
    flat: FloatArray = x.reshape(k, -1)
    return flat


def pass_size_model(passes: FloatArray, samples: FloatArray) -> tuple[FloatArray | None, float]:
    """The passes' fitted pooled relative variances (a, b) of :func:`_pass_size_factor`'s model (None where
    it is not fitted) and the factor their estimate carries: ``bf.estimate_cost`` replays the render's
    schedule with them (:func:`expected_size_factor`)."""
    n = np.asarray(samples, dtype=np.float64)
    mean, var_one = _per_sample_variance(passes, n)
    divisor = _relative_divisor(passes, n, mean)
    flat = _fit_deviations(passes, n, mean, divisor, var_one / n.sum() / divisor)
    if flat is None:
        return None, 1.0
    gram = flat @ flat.T / flat.shape[1]
    return _size_model(np.diag(gram).copy(), n), _size_factor_of_gram(gram, n)


def _dof_of_terms(terms: FloatArray, k: int) -> float:
    """:func:`error_dof` of ``k`` passes from their :func:`_relative_terms`."""
    t = terms.reshape(-1, terms.shape[-1]).sum(axis=-1) if terms.ndim >= 2 else terms.ravel()
    total = float(t.sum())
    if total <= 0.0:
        return float("inf")  # no pixel varies between the passes: nothing to be unsure about
    return (k - 1) * total * total / float((t * t).sum())


def _estimate_and_trusted(
    passes: FloatArray, samples: FloatArray, parts: _ErrorParts | None = None
) -> tuple[float, float]:
    """:func:`relative_error_estimate` and the bound ``final`` stops on (times :func:`few_terms_factor`),
    from one computation of the terms (``parts``: :func:`_error_parts`, when the caller has them)."""
    terms = _relative_terms(passes, samples, parts)
    estimate = float(np.sqrt(terms.mean()))
    return estimate, estimate * few_terms_factor(_dof_of_terms(terms, passes.shape[0]))


def error_dof(passes: FloatArray, samples: FloatArray | None = None) -> float:
    """The degrees of freedom of :func:`relative_error_estimate`: (K - 1) per independent pixel, times the
    pixels that carry the error (the participation ratio (sum t)^2 / sum t^2 of the pixels' relative-MSE terms
    t, channels summed: one noisy pixel counts once; equally noisy pixels count 1 / (1 + 2 / (C (K - 1))) each,
    C channels, as their estimated terms scatter: on the safe side)."""
    return _dof_of_terms(_relative_terms(passes, samples), passes.shape[0])


def few_terms_factor(dof: float, z: float = 1.645) -> float:
    """How much larger the true relative RMS error may be than its estimate at ``dof`` degrees of freedom
    (:func:`error_dof`), one-sided 95 %: sqrt(dof / chi2 quantile(0.05, dof)), the quantile by the
    Wilson-Hilferty approximation (within 4 % of the exact one at 3 dof). 1.008 at 20 000 dof (a 256 px image);
    3.0 at 3 (one noisy pixel after 4 passes). Measured on a 1x1 render of a sphere in Mitsuba, 16 seeds, target
    0.01: without it 6 stopped above 0.015 (median true error 0.0073 at 229 samples), with it none (0.0011 at
    1282 samples)."""
    if not np.isfinite(dof):
        return 1.0
    c = 2.0 / (9.0 * dof)
    q = dof * (1.0 - c - z * np.sqrt(c)) ** 3
    if 1.0 - c - z * np.sqrt(c) <= 0.0 or q <= 0.0:
        return float("inf")
    return float(np.sqrt(dof / q))


def error_interval(
    passes: FloatArray, samples: FloatArray | None = None, z: float = 1.645, parts: _ErrorParts | None = None
) -> tuple[float, float]:
    """A two-sided 90 % (``z`` = 1.645) confidence interval of :func:`relative_error_estimate`, by the
    jackknife over passes: each pass left out in turn re-estimates the per-sample variance (the full
    mean's sample count kept), so a pass with a rare bright path widens the interval. K >= 3 passes."""
    k = passes.shape[0]
    if k < 3:
        return 0.0, float("inf")
    n, var_one, divisor, factor = parts if parts is not None else _error_parts(passes, samples)
    denom = n.sum() * divisor
    full = float((var_one / denom).mean()) * factor  # the size factor as the estimate carries it
    loo = np.empty(k)
    for i in range(k):
        keep = np.arange(k) != i
        _, var_i = _per_sample_variance(passes[keep], n[keep])
        loo[i] = float((var_i / denom).mean()) * factor
    sd = float(np.sqrt((k - 1) / k * ((loo - loo.mean()) ** 2).sum()))
    return float(np.sqrt(max(full - z * sd, 0.0))), float(np.sqrt(full + z * sd))


#: the estimate's validated accuracy: against converged references the true error was within this factor of
#: the estimate in 47 of 48 renders (benchmarks/results/error_estimator.md: 12 scenes, Cycles and Mitsuba)
ESTIMATE_FACTOR = 1.5


def confidence_interval(estimate: float, jackknife: tuple[float, float], bias: float = 0.0) -> tuple[float, float]:
    """The 90 % interval of an error estimate: the jackknife's spread over passes (the variance of the
    estimate; :func:`error_interval`), widened to at least ``ESTIMATE_FACTOR`` either side (what the
    estimator's validation against converged references found: the spread alone covered the truth in only
    28 of 48 renders (18 of 48 before the fit to passes of different sizes), because a sampler's correlations
    and heavy tails bias the estimate slightly).
    ``bias``: an error known to be added in quadrature (left-out light)."""
    low, high = (float(np.hypot(v, bias)) for v in jackknife)
    return min(low, estimate / ESTIMATE_FACTOR), max(high, estimate * ESTIMATE_FACTOR)


MAX_PASSES = 24
MAX_SAMPLES = 1 << 16
#: passes rendered before the first estimate (the estimate needs independent passes; 4 keep its spread small)
FIRST_PASSES = 4


def _rendered_samples(result: RenderResult, asked: int) -> int:
    """The samples a pass really took (an engine's stratified sampler may round the request up: Mitsuba
    reports ``rendered_spp``), which weigh the passes' mean."""
    rendered = result.meta.get("rendered_spp")
    return int(rendered) if isinstance(rendered, (int, np.integer)) and rendered > 0 else asked


def pass_seed(seed: int, index: int) -> int:
    """The seed of independent pass ``index`` (pass 0 uses ``seed`` itself)."""
    return (seed + 7919 * index) % (2**31 - 1)


def _next_pass_samples(total: int, estimate: float, target: float, base: int) -> int:
    """Samples of the next pass: about half of what the estimate says is still needed (error ~
    1/sqrt(samples)), rounded down to ``base`` times a power of two, so the target is approached in a few
    passes without overshooting by much, and a render repeats few distinct pass sizes (an engine that compiles
    per sample count, like Mitsuba's llvm variants, then reuses its kernels)."""
    needed = total * (estimate / target) ** 2 * 1.1 - total
    if not np.isfinite(needed):  # an estimate not to be trusted at all: as many as the cap allows
        return int(max(MAX_SAMPLES - total, 1))
    half = max(float(np.ceil(needed / 2)), float(base))
    n = base * 2 ** int(np.floor(np.log2(half / base)))
    return int(np.clip(n, 1, max(MAX_SAMPLES - total, 1)))


def _samples_that_fit(remaining: float, pass_seconds: list[tuple[float, int]]) -> int:
    """How many samples a pass can take in ``remaining`` seconds, at the rate of the passes so far (their
    seconds over their samples: the fixed cost per pass counted as if per sample, so a long pass is
    estimated on the safe side). Passes grow as the target nears, so checking the limit only between
    passes overran it: a glass sphere at 256x256 with ``time_limit=45`` stopped after 68.6 s (its fifth
    pass, 1024 samples, took 60 s); a pass sized to all the time left still ran to 72-76 s when the machine
    slowed down mid-pass."""
    seconds = sum(t for t, _ in pass_seconds)
    samples = sum(n for _, n in pass_seconds)
    if remaining <= 0:
        return 0
    if seconds <= 0:
        return MAX_SAMPLES
    return int(min(remaining * samples / seconds, MAX_SAMPLES))


def _add_timings(total: dict[str, float], more: dict[str, float]) -> None:
    """Sum a later pass's engine timings into the first pass's (translation is paid once)."""
    for key, value in more.items():
        if key != "translate" and isinstance(value, (int, float)):
            total[key] = total.get(key, 0.0) + float(value)


#: a pilot (:data:`PILOTS`) renders this many passes without its effect (same seeds and samples as the first
#: full passes: the same first samples, so their difference is mostly the effect's light; measured: half the
#: samples loosened the estimate's upper bound 3.5x on a ball over a dark floor)
PILOT_PASSES = 2
#: ... and up to this many (one more per round, paired with the next full pass) while its 90 % interval still
#: straddles the threshold: an engine whose same-seed passes share fewer random numbers leaves a noisier
#: difference. Measured on a dark ball over a 3 % floor (16 spp, true indirect light 0.0016): rel. RMS of
#: full - direct per pass 0.001 in Cycles (2 passes decide), 0.025 in Mitsuba ``scalar_rgb`` (its samplers'
#: jitter comes from one random stream per pixel, so a longer path shifts the next sample's numbers; its
#: ``llvm_ad_rgb`` gives each sample its own stream and decides with 2): upper bound 0.0081 with 2 passes,
#: 0.0031 with 3, 0.0014 with 4. (Mitsuba's ``ldsampler`` shares the numbers, 0.0011, but has 1.0-1.5x the
#: noise of the default ``multijitter`` on every benchmark scene: not worth it for a pilot.)
PILOT_MAX_PASSES = FIRST_PASSES
#: ... and only when the full passes still need this many times the pilots' samples, weighed by their cost
#: (they cost <= 1/16 of them;
#: measured at 4x: 10-15 % slower on a floating bunny, whose indirect light it rightly kept; Mitsuba also
#: loads the direct-light scene once more)
PILOT_MIN_GAIN = 16.0
#: direct light (or the render without caustics) may need this many times the full settings' samples, weighed by
#: their cost. 1: a direct sample is barely cheaper (Russian
#: roulette already ends the paths that carry little), and without the indirect light the relative noise of dark
#: pixels is higher (measured on a ball over a 5 % floor: 1.1x the samples, 0.85x the speed with a slack of 1.25)
DIRECT_SAMPLES_SLACK = 1.0
#: indirect light or caustics may be left out when their estimated relative RMS (90 % upper bound) is <= this x
#: target
INDIRECT_SHARE = 0.5


def _indirect_bounds(colours: list[FloatArray], direct: list[FloatArray]) -> tuple[float, float]:
    """The 90 % upper and lower bounds of the indirect light's relative RMS from the direct-light passes
    ``direct`` and the full passes of the same seeds (``colours[: len(direct)]``): the squared mean of their
    difference less its noise (the variance of the mean between the pairs), averaged over pixel-channels."""
    k = len(direct)
    diff = np.stack(colours[:k]) - np.stack(direct)
    dbar = diff.mean(axis=0)
    var_mean = ((diff - dbar) ** 2).sum(axis=0) / (k - 1) / k
    ref = np.stack(colours).mean(axis=0)
    term = (dbar * dbar - var_mean) / (ref * ref + 1e-2)
    half = 1.645 * float(term.std()) / np.sqrt(term.size)
    mean = float(term.mean())
    return float(np.sqrt(max(mean + half, 0.0))), float(np.sqrt(max(mean - half, 0.0)))


#: what each pilot of ``render_to_target`` leaves out: the settings it renders instead and its name in meta
#: (``meta["<kind>_pilot"]``, ``"<kind>_error"``)
#: (in the order tried: caustics first, as the noisiest light; measured on a plastic ball and cube under a sun,
#: Cycles at 64 px: 25152 samples with caustics, 96 without)
PILOTS: dict[str, dict[str, Any]] = {
    "caustics": {"changes": {"caustics": False}, "label": "caustics"},
    "indirect": {"changes": {"max_bounces": 0}, "label": "indirect light"},
}


#: what a pass's meta says about how the engine ran it (a pilot's drop changes it for the passes that follow)
ENGINE_META_KEYS = ("integrator", "max_depth", "engine_settings")


def _pilot_applies(kind: str, settings: RenderSettings, eff: Effects) -> str | None:
    """Why pilot ``kind`` is not tried on a scene with effects ``eff`` (None: it is)."""
    if not settings.effects:
        return "not tried: effects=False"
    if kind == "indirect":
        if settings.max_bounces == 0:
            return "not tried: no bounces anyway"
        if eff.transmission:
            return "not tried: light passes through a transmissive material (needs bounces)"
        if not (eff.indirect_diffuse or eff.glossy or eff.caustics):
            return "not tried: the effect analysis already renders direct light only"
        return None
    if not settings.caustics or settings.max_bounces == 0:
        return "not tried: caustics off or no bounces anyway"
    if not eff.caustics:
        return "not tried: the effect analysis already found no caustics"
    if eff.transmission:
        return "not tried: light passes through a transmissive material (refraction lights what is behind it)"
    return None


def _effect_pilot(
    kind: str,
    inst: Backend,
    scene: Scene,
    settings: RenderSettings,
    pass_settings: RenderSettings,
    colours: list[FloatArray],
    counts: list[int],
    estimate: float,
    spent: float = 0.0,
    eff: Effects | None = None,
) -> dict[str, Any]:
    """Decide from pixels whether the settings without one effect (:data:`PILOTS`: ``indirect`` = direct
    light alone, ``max_bounces=0``; ``caustics`` = ``caustics=False``) reach ``settings.target_error`` sooner.

    Renders ``PILOT_PASSES`` passes with the pilot's settings and the seeds and samples of the first full passes
    (the same first samples: the difference is mostly the light left out), estimates the relative RMS of that
    light (full - pilot; its squared mean less its noise, 90 % interval over pixel-channels) and the samples the
    pilot's settings need for the rest of the error budget. While the interval straddles the threshold, one more
    pass is paired with the next full pass, up to ``PILOT_MAX_PASSES`` and as long as the pilot costs at most
    1/``PILOT_MIN_GAIN`` of the full passes' samples (with ``spent``, the samples earlier pilots of this render
    cost, weighed by their cost). The effect is left out when its light is <= ``INDIRECT_SHARE``
    x target and the pilot's settings need at most ``DIRECT_SAMPLES_SLACK`` x the full settings' samples, each
    sample weighed by its cost (:meth:`Backend.pilot_sample_cost`: e.g. Mitsuba renders caustics=False with a
    Python integrator). ``eff``: the scene's :func:`analyse_effects` when the caller has it (analysed here
    otherwise). Stopping depends only on pixels, so a seed still gives the same picture. Returns the
    decision and its numbers (``meta["<kind>_pilot"]``); with ``dropped`` also the passes to continue from."""
    spec = PILOTS[kind]
    target = float(settings.target_error or 0.0)
    base = settings.samples
    total = sum(counts)
    need_full = total * (estimate / target) ** 2 * 1.1 - total
    out: dict[str, Any] = {"dropped": False}
    skip = _pilot_applies(kind, settings, eff if eff is not None else analyse_effects(scene))
    if skip is not None:
        out["why"] = skip
        return out
    pilot_spp = base
    pilot_settings = pass_settings.replace(**spec["changes"])
    cost = float(inst.pilot_sample_cost(pilot_settings))
    # a pilot pass's fixed cost in samples of this image, and the first one's for switching to its settings
    pixels = max(1, colours[0].shape[0] * colours[0].shape[1])
    call = float(inst.pass_overhead(pilot_settings)) / pixels
    switch_overhead = getattr(inst, "switch_overhead", None)  # (a stand-in engine may have pass_overhead only)
    switch = float(switch_overhead(pilot_settings)) / pixels if switch_overhead is not None else call

    def pilot_cost(k: int) -> float:
        return k * (cost * pilot_spp + call) + switch

    if need_full < PILOT_MIN_GAIN * (spent + pilot_cost(PILOT_PASSES)):
        out["retry"] = True  # tried again after the next pass, if the estimate grows
        out["why"] = f"not tried: the full passes need only {need_full:.0f} more samples"
        notes = [f"a pilot sample costs {cost:g} full ones"] if cost != 1 else []
        if call > 0:
            notes.append(f"a pass's fixed cost is {call:.3g} samples of this image")
        if switch > call:
            notes.append(f"switching to the pilot's settings {switch:.3g}")
        if notes:
            out["why"] += f" ({'; '.join(notes)})"
        return out
    passes: list[FloatArray] = []
    alphas: list[FloatArray] = []
    timings: dict[str, float] = {}
    threshold = INDIRECT_SHARE * target
    max_passes = min(PILOT_MAX_PASSES, len(colours))
    while True:
        i = len(passes)
        r = inst.render_scene(scene, pilot_settings.replace(seed=pass_seed(settings.seed, i), samples=pilot_spp))
        if r.rgba is None:
            raise RenderError(f"backend {inst.name!r} returned no 'rgb' output for the {spec['label']} pilot")
        passes.append(r.rgba[..., :3].astype(np.float64))
        alphas.append(r.rgba[..., 3:4].astype(np.float64))
        _add_timings(timings, r.meta.get("timings", {}))
        engine_meta = r.meta
        k = len(passes)
        if k < PILOT_PASSES:
            continue
        bias, low = _indirect_bounds(colours, passes)
        undecided = low <= threshold < bias
        if not undecided or k >= max_passes or need_full < PILOT_MIN_GAIN * (spent + pilot_cost(k + 1)):
            break
    counts_p = [pilot_spp] * k
    est_p = relative_error_estimate(np.stack(passes), np.array(counts_p, dtype=np.float64))
    out.update(
        {f"{kind}_error": bias, f"{kind}_error_low": low},
        passes=k,
        full_samples_needed=int(total + need_full),
        sample_cost=cost,
        cost_in_samples=pilot_cost(k),
        timings=timings,
    )
    if bias > threshold:
        out["why"] = f"kept: {spec['label']} {bias:.3g} relative RMS > {INDIRECT_SHARE:g} x target {target:g}"
        return out
    noise_target = float(np.sqrt(target**2 - bias**2))
    need = k * pilot_spp * (est_p / noise_target) ** 2 * 1.1
    out["pilot_samples_needed"] = int(need)
    if kind == "indirect":
        out["direct_samples_needed"] = int(need)
    costed = f" (each {cost:g}x the cost of a full one)" if cost != 1 else ""
    if need * cost > DIRECT_SAMPLES_SLACK * (total + need_full):
        out["why"] = (
            f"kept: without {spec['label']} the render needs {need:.0f} samples{costed}, the full passes "
            f"{total + need_full:.0f}"
        )
        return out
    changes = ", ".join(f"{k_}={v}" for k_, v in spec["changes"].items())
    out.update(
        dropped=True,
        why=(
            f"{spec['label']} dropped ({changes}): estimated at {bias:.3g} relative RMS (90 % upper bound) "
            f"<= {INDIRECT_SHARE:g} x target {target:g}; without it ~{need:.0f} samples{costed}, "
            f"the full settings ~{total + need_full:.0f}"
        ),
        colours=passes,
        alphas=alphas,
        counts=counts_p,
        engine_meta=engine_meta,
    )
    return out


def render_to_target(inst: Backend, scene: Scene, settings: RenderSettings) -> RenderResult:
    """Render independent passes (different seeds) until the estimated relative RMS error of their
    sample-weighted mean is <= ``settings.target_error``, the ``time_limit`` is reached, or the pass or
    sample cap is hit.

    The first 4 passes use ``settings.samples`` each; later passes are sized from the current estimate
    (error falls as 1/sqrt(samples)). Stopping depends only on the passes' pixels, so a seed gives the same
    picture every time. Geometric outputs come from the first pass, or from a render of their own where the
    backend's :attr:`~blendify_core.pipeline.backend.Backend.geometry_pins_first_sample` says they need a sample
    its colour must not take. ``meta`` records the estimate with its 90 % interval, the passes, the total
    samples, whether the target was reached and why the passes stopped."""
    t0 = time.perf_counter()
    if settings.target_error is None:
        raise InvalidSceneError("target_error: render_to_target needs settings.target_error (a positive number)")
    target = float(settings.target_error)
    base = settings.samples
    pass_settings = settings.replace(target_error=None, time_limit=None, denoise=False)
    geometric = tuple(o for o in settings.outputs if o != "rgb")
    geometry: RenderResult | None = None
    if geometric and "rgb" in settings.outputs and getattr(inst, "geometry_pins_first_sample", False):
        # the geometric outputs once, apart (the engine would render them apart with every pass)
        geometry = inst.render_scene(scene, pass_settings.replace(outputs=geometric))
        pass_settings = pass_settings.replace(outputs=("rgb",))
    first = inst.render_scene(scene, pass_settings)
    if geometry is not None:
        for attr in geometric:
            setattr(first, attr, getattr(geometry, attr))
        first.instance_tags = list(geometry.instance_tags) or first.instance_tags
        _add_timings(first.meta.setdefault("timings", {}), geometry.meta.get("timings", {}))
    if first.rgba is None:
        return first
    colours = [first.rgba[..., :3].astype(np.float64)]
    alphas = [first.rgba[..., 3:4].astype(np.float64)]
    counts = [_rendered_samples(first, base)]
    estimate = trusted = float("inf")
    stopped = "pass cap"
    noise_target, bias = target, 0.0
    pilots: dict[str, dict[str, Any]] = {}
    # the pilots not decided yet; one whose gain is too small yet is tried again after each pass (an estimate
    # may grow as rare bright samples turn up: a plastic ball under a sun, Cycles at 64 px, needed 355 more
    # samples after 4 passes, 2880 in all)
    pending, spent = list(PILOTS), 0.0
    pass_seconds: list[tuple[float, int]] = []  # (seconds, samples) of the passes after the first
    engine_meta: Mapping[str, Any] | None = None  # how the picture's passes were rendered, once a pilot dropped
    eff: Effects | None = None  # the scene's effects, analysed once for all the pilots' rounds
    while True:
        if len(colours) >= FIRST_PASSES:
            # the estimate, and the one trusted for stopping: its 95 % upper bound where few pixels carry the error
            estimate, trusted = _estimate_and_trusted(np.stack(colours), np.array(counts))
            if pending and estimate > noise_target:
                eff = eff if eff is not None else analyse_effects(scene)
                for kind in list(pending):  # caustics first; if kept, direct light alone
                    pilot = pilots[kind] = _effect_pilot(
                        kind, inst, scene, settings, pass_settings, colours, counts, estimate, spent, eff
                    )
                    if pilot.pop("retry", False):
                        continue
                    pending.remove(kind)
                    spent += pilot.get("cost_in_samples", 0.0)
                    if "timings" in pilot:
                        _add_timings(first.meta.setdefault("timings", {}), pilot.pop("timings"))
                    if pilot.get("dropped"):
                        colours, alphas, counts = pilot.pop("colours"), pilot.pop("alphas"), pilot.pop("counts")
                        engine_meta = pilot.pop("engine_meta")
                        pass_settings = pass_settings.replace(**PILOTS[kind]["changes"])
                        bias = float(pilot[f"{kind}_error"])
                        noise_target = float(np.sqrt(target**2 - bias**2))
                        estimate, trusted = _estimate_and_trusted(np.stack(colours), np.array(counts))
                        pending.clear()
                        break
            if trusted <= noise_target:
                stopped = "target reached"
                break
        if len(colours) >= MAX_PASSES or sum(counts) >= MAX_SAMPLES:
            stopped = "pass cap" if len(colours) >= MAX_PASSES else "sample cap"
            break
        if settings.time_limit is not None and time.perf_counter() - t0 >= settings.time_limit:
            stopped = "time_limit"
            break
        n = base if len(colours) < FIRST_PASSES else _next_pass_samples(sum(counts), trusted, noise_target, base)
        if settings.time_limit is not None and pass_seconds:
            fits = _samples_that_fit(settings.time_limit - (time.perf_counter() - t0), pass_seconds)
            if fits < min(n, base):  # not even a first-size pass fits: stop rather than overrun the limit
                stopped = "time_limit"
                break
            if n > fits:
                # a pass that would not fit is cut to half of what does, so the limit is approached in halving
                # steps: a machine that slows down mid-pass (other jobs) overruns it by that half's slowdown, not
                # the whole rest's. A pass that fits is left as it is: a render that ends before its limit
                # gives the same pixels as without one
                n = max(fits // 2, min(n, base))
        t_pass = time.perf_counter()
        r = inst.render_scene(
            scene, pass_settings.replace(seed=pass_seed(settings.seed, len(colours)), samples=max(1, n))
        )
        pass_seconds.append((time.perf_counter() - t_pass, max(1, n)))
        if r.rgba is None:
            raise RenderError(f"backend {inst.name!r} returned no 'rgb' output for pass {len(colours) + 1}")
        colours.append(r.rgba[..., :3].astype(np.float64))
        alphas.append(r.rgba[..., 3:4].astype(np.float64))
        counts.append(_rendered_samples(r, max(1, n)))
        _add_timings(first.meta.setdefault("timings", {}), r.meta.get("timings", {}))
        if engine_meta is not None:
            engine_meta = r.meta
    n_arr = np.array(counts, dtype=np.float64)
    w = (n_arr / n_arr.sum()).reshape(-1, 1, 1, 1)
    stack = np.stack(colours)
    parts = _error_parts(stack, n_arr) if len(colours) >= 2 else None  # once for the estimate, bound, interval
    if parts is not None:
        noise, trusted = _estimate_and_trusted(stack, n_arr, parts)
        estimate = float(np.hypot(noise, bias))
    rgb = (stack * w).sum(axis=0)
    alpha = (np.stack(alphas) * w).sum(axis=0)
    first.rgba = np.concatenate([rgb, alpha], axis=-1).astype(np.float32)
    if parts is not None:  # the variance of the weighted mean (the noise-aware comparison uses it)
        first.rgb_var = (parts[1] / n_arr.sum()).astype(np.float32)
    meta = first.meta
    if engine_meta is not None:  # the picture comes from passes without the dropped effect: say how they ran
        for key in ENGINE_META_KEYS:
            if key in engine_meta:
                meta[key] = engine_meta[key]  # type: ignore[literal-required]
    meta["passes"] = len(colours)
    meta["samples"] = int(n_arr.sum())
    meta["estimated_error"] = estimate
    meta["estimated_error_kind"] = (
        "relative RMS error (its square is the relative MSE), from the variance between independent passes"
    )
    spread = error_interval(stack, n_arr, parts=parts)
    meta["estimated_error_jackknife"] = [float(np.hypot(v, bias)) for v in spread]
    low, high = confidence_interval(estimate, spread, bias)
    if len(colours) >= 2:  # where few pixels carry the error, at least the bound the stopping rule trusted
        high = max(high, float(np.hypot(trusted, bias)))
    meta["estimated_error_interval"] = [low, high]
    meta["target_reached"] = bool(estimate <= target)
    meta["stopped"] = stopped
    for kind, pilot in pilots.items():
        meta[f"{kind}_pilot"] = pilot  # type: ignore[literal-required]
        if pilot.get("dropped"):
            meta["estimated_error_kind"] += (
                f"; plus the {PILOTS[kind]['label']} left out (estimated from the pilot, added in quadrature)"
            )
    if not meta["target_reached"]:
        meta.setdefault("warnings", []).append(
            f"target_error: stopped at the {stopped} with an estimated error of {estimate:.3g} "
            f"(target {target:g}) after {len(colours)} passes, {int(n_arr.sum())} samples"
        )
    meta.setdefault("timings", {})["render"] = time.perf_counter() - t0
    return first


#: float64 keeps ~16 digits: beyond this ratio of coordinate magnitude to scene size, even the IR's own
#: numbers cannot place the objects to 1e-3 of their size (re-centring cannot recover lost digits)
PRECISION_RATIO = 1e12


def _precision_check(scene: Scene, bounds: Bounds | None) -> str | None:
    """A warning when coordinates are so large relative to the scene's size that float64 itself loses it."""
    if bounds is None:
        return None
    magnitude, size = _scene_scale(scene, bounds)
    if magnitude > PRECISION_RATIO * size:
        return (
            f"scene: coordinates of magnitude {magnitude:.3g} for a scene {size:.3g} across exceed float64 "
            "precision (about 16 digits): objects may collapse or vanish; move the scene nearer the origin "
            "or scale it"
        )
    return None
