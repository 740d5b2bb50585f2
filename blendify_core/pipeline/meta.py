"""``result.meta``: every key ``bf.render`` and the backends record, with its type and meaning.

:class:`RenderMeta` is the type of :attr:`RenderResult.meta <blendify_core.pipeline.result.RenderResult.meta>`.
At run time it is a plain ``dict`` (saved ``.npz`` files, JSON and user code keep working); the TypedDict
documents the keys and lets a type checker catch a misspelt one. Every key is optional for a backend; the
keys marked "(core)" are always present in a result returned by ``bf.render``.

Timings (``meta["timings"]``, seconds) are a plain ``dict[str, float]``: the common phases in
:data:`COMMON_TIMINGS` (meanings in :data:`TIMING_KEYS`) are always there (the core fills ``translate`` and
``render`` when a backend did not report them, see :func:`complete_timings`); a backend may add finer phases
of its own under other names (documented by that backend), which the core keeps but never reads.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypedDict

__all__ = [
    "RenderMeta",
    "Simulated",
    "AntiAliasingMeta",
    "IsolatedMeta",
    "COMMON_TIMINGS",
    "TIMING_KEYS",
    "META_KEYS",
    "complete_timings",
    "undocumented_keys",
]


class Simulated(TypedDict, total=False):
    """``meta["simulated"]``: what light transport was simulated and why."""

    #: False when only geometric outputs were requested (no lighting computed)
    lighting: bool
    #: "full" (``effects=False``) or the names of the effects :func:`analyse_effects` found
    effects: str | list[str]
    #: one sentence saying why
    why: str
    #: what the pilot of ``target_error`` found unnecessary and left out, with the numbers (e.g. indirect light)
    dropped: dict[str, str]


class AntiAliasingMeta(TypedDict):
    """``meta["antialiasing"]`` (pyrender): the anti-aliasing scheme used for the colour image."""

    #: "none", "coverage", "msaa" or "ssaa"
    mode: str
    #: MSAA samples (0 when not multisampled)
    msaa: int
    #: supersampling factor per axis (1 when not supersampled)
    supersample: int


class IsolatedMeta(TypedDict):
    """``meta["isolated"]`` (Cycles with ``isolate=True``): the worker process that rendered."""

    worker_pid: int
    renders_in_worker: int


class RenderMeta(TypedDict, total=False):
    """The keys of ``result.meta``. "(core)": written by ``bf.render`` for every backend; otherwise the
    backend named in brackets writes it."""

    # -- provenance (core) ----------------------------------------------------------------------------
    #: (core) name of the backend that rendered ("cycles", "mitsuba", "pyrender", ...)
    backend: str
    #: (core) version of the engine's distribution, None when unknown
    engine_version: str | None
    #: (core) the resolved :class:`RenderSettings` as a dict (``RenderSettings.to_dict()``)
    settings: dict[str, Any]
    #: (core) :meth:`Scene.fingerprint` of the rendered scene
    scene_fingerprint: str
    #: (core) samples per pixel rendered (with ``target_error``: the sum over all passes)
    samples: int
    #: (core, backends with ``device=``) what rendered: "CPU", "GPU (OPTIX: ...)", "CPU (llvm_ad_rgb)", ...
    device: str
    #: (core) True for Monte Carlo path tracers (``Backend.path_tracer``)
    path_tracer: bool
    #: (core) the backends skipped by the automatic choice, each "name: reason" (only when skipped)
    backend_fallback: list[str]

    # -- what was simulated (core) ---------------------------------------------------------------------
    #: (core) :meth:`Effects.to_dict` of :func:`analyse_effects`: each effect on/off plus ``reasons``
    effects: dict[str, bool | dict[str, str]]
    #: (core) what light transport was simulated and why
    simulated: Simulated
    #: (core) what makes a path tracer's picture converge to something other than the unbiased one (clamps,
    #: Filter Glossy, denoiser, adaptive stop, bounce limits; ``settings_bias``); empty for ``final``
    bias: list[str]
    #: (core) sorted notes on every feature the backend only approximates for this scene (also the biased
    #: settings it cannot apply, ``setting the engine cannot apply: ...``, and an attached file's ``IR parse of``)
    approximations: list[str]
    #: [cycles] settings of this engine's own that change the picture and no other engine applies (Cycles'
    #: ``cycles_settings``, e.g. "cycles.caustics_reflective=False (blendify: True)"); a crosscheck pair with
    #: an engine that lacks them is limited by the engine
    engine_only_settings: list[str]
    #: (core) warnings about the scene or the settings (clipping, precision, target_error on a raster backend)
    warnings: list[str]
    #: (core) world origin the scene was re-centred on before translation (far-from-origin scenes only)
    recentred_origin: list[float]
    #: [mitsuba, pyrender] IR objects that contribute nothing in this backend, each "Type: why" (sorted;
    #: only when some were ignored; Cycles lists them under ``translation["ignored"]``)
    ignored: list[str]

    # -- error estimate (core) -------------------------------------------------------------------------
    #: (core) estimated relative RMS error of the colour, None when not estimated
    estimated_error: float | None
    #: (core) how ``estimated_error`` was obtained, or why it was not
    estimated_error_kind: str
    #: (core, ``target_error``; ``bf.crosscheck`` of a path tracer) independent passes rendered
    passes: int
    #: (core, ``target_error`` only) 90 % interval of the true error: the jackknife spread over passes widened
    #: to the estimator's validated factor 1.5 (benchmarks/results/error_estimator.md)
    estimated_error_interval: list[float]
    #: (core, ``target_error`` only) the jackknife spread over passes alone (the variance of the estimate)
    estimated_error_jackknife: list[float]
    #: (core, ``target_error`` only) whether the estimate reached the target
    target_reached: bool
    #: (core, ``target_error`` only) why the passes stopped: "target reached", "time_limit", "pass cap",
    #: "sample cap"
    stopped: str
    #: (core, ``target_error`` with ``effects=True``) the pilot deciding whether direct light alone reaches the
    #: target sooner: ``dropped``, ``why``, ``indirect_error`` (relative RMS of the indirect light, 90 % upper
    #: bound; ``indirect_error_low`` the lower), ``passes`` (direct-light passes rendered), the samples each
    #: choice needs
    indirect_pilot: dict[str, Any]
    #: (core, ``target_error`` with ``effects=True``, scenes with caustics) the pilot deciding whether
    #: ``caustics=False`` reaches the target sooner: ``dropped``, ``why``, ``caustics_error`` (relative RMS of the
    #: light through glossy or refractive surfaces onto diffuse ones, 90 % upper bound; ``caustics_error_low``),
    #: ``passes``, ``sample_cost`` (a pilot sample's cost in full ones), ``cost_in_samples`` (the pilot's passes
    #: and their fixed costs in full samples), the samples each choice needs
    caustics_pilot: dict[str, Any]
    #: (``bf.crosscheck`` with ``repeats``) renders averaged into the colour image
    repeats: int

    # -- timings (core + backend) ----------------------------------------------------------------------
    #: seconds per phase: :data:`COMMON_TIMINGS` always, plus the backend's finer phases
    timings: dict[str, float]

    # -- Cycles ----------------------------------------------------------------------------------------
    #: [cycles] what the translation set on the Blender scene (samples, bounce limits, filter, device, ...)
    engine_settings: dict[str, Any]
    #: [cycles] the last lines of Blender's render log
    log_tail: list[str]
    #: [cycles] what the incremental translation did (objects created, updated, reused; seconds per step)
    translation: dict[str, Any]
    #: [cycles] the worker process of an isolated backend (``isolate=True``)
    isolated: IsolatedMeta

    # -- Mitsuba ---------------------------------------------------------------------------------------
    #: [mitsuba] the Mitsuba variant used (e.g. "llvm_ad_rgb", "scalar_rgb")
    variant: str
    #: [mitsuba] why that variant was chosen (e.g. the reason of a fallback to scalar_rgb)
    variant_reason: str
    #: [mitsuba] path of the libLLVM the variant uses, None when it needs none
    libllvm: str | None
    #: [mitsuba] integrator plugin ("path", "direct", ...)
    integrator: str
    #: [mitsuba] the integrator's max_depth
    max_depth: int
    #: [mitsuba] whether directly visible emitters are hidden
    hide_emitters: bool
    #: [mitsuba] samples per pixel requested
    spp: int
    #: [mitsuba] samples per pixel the sampler actually took
    rendered_spp: int
    #: [mitsuba] sampler plugin ("independent", "stratified", ...)
    sampler: str
    #: [mitsuba] seed given to the sampler
    seed: int
    #: [mitsuba] pixel filter used ("box" or "gaussian")
    pixel_filter: str
    #: [mitsuba] True when alpha was composited from a coverage pass (emissive surfaces over a sky)
    alpha_compositing: bool
    #: [mitsuba] True when the directly seen emission of the light shapes (point lights with a radius, area
    #: lights) was subtracted from the colour (scenes with emissive materials, where emitters stay visible)
    lights_removed: bool
    #: [mitsuba] True when shadow catchers were emulated by a second render
    shadow_catcher_emulated: bool
    #: [mitsuba] spheres rendered as analytic sphere shapes (not tessellated)
    analytic_spheres: int
    #: [mitsuba] settings Mitsuba could not honour (denoise, clamping, adaptive stop), said rather than dropped
    notes: list[str]
    #: [mitsuba] True when the translated scene was reused from the previous render
    translate_cached: bool

    # -- pyrender --------------------------------------------------------------------------------------
    #: [pyrender] OpenGL platform ("egl" or "osmesa")
    platform: str
    #: [pyrender] the OpenGL renderer string (GPU or software rasteriser)
    gl_renderer: str
    #: [pyrender] anti-aliasing of the colour image, None when no colour was rendered
    antialiasing: AntiAliasingMeta | None
    #: [pyrender] renderables rebuilt (not reused) for this frame
    rebuilt_renderables: int


#: the common phases of ``meta["timings"]`` (seconds): ``translate``, ``render`` and ``total`` are in every
#: result, ``read_back`` (a part of ``render``) when the backend measures it. A backend reports
#: ``translate``, ``render`` and ``read_back`` itself under these names (``Backend.render_scene`` does it for
#: backends that do not override it); the core reads no other name.
COMMON_TIMINGS: tuple[str, ...] = ("translate", "render", "read_back", "total")

#: every timing the core reads or writes, with its meaning
TIMING_KEYS: dict[str, str] = {
    "translate": "IR to the engine's native scene (incremental backends: only what changed)",
    "render": "the engine's rendering of every requested output, reading them back into numpy included",
    "read_back": "the part of render spent reading the engine's outputs back into numpy (when measured)",
    "total": "the whole bf.render call, checks and post-processing included (written by the core)",
    "distortion": "the core's lens-distortion remap (distorted cameras only, written by the core)",
}

#: every documented top-level key of ``result.meta``
META_KEYS: frozenset[str] = frozenset(RenderMeta.__optional_keys__ | RenderMeta.__required_keys__)


def complete_timings(timings: dict[str, float], call_seconds: float) -> None:
    """Make ``timings`` carry ``translate`` and ``render`` (in place): a phase the backend did not report
    is 0 for ``translate`` and the rest of the backend call (``call_seconds``) for ``render``. Only the
    documented common names are read; ``total`` is the caller's to add."""
    if "translate" not in timings:
        timings["translate"] = 0.0
    if "render" not in timings:
        timings["render"] = max(0.0, call_seconds - float(timings["translate"]))


def undocumented_keys(meta: Mapping[str, object]) -> list[str]:
    """Keys of ``meta`` that :class:`RenderMeta` does not document (sorted); a backend test can assert
    this is empty so every key a backend records is documented here."""
    return sorted(k for k in meta if k not in META_KEYS)
