"""Render settings: quality presets plus explicit overrides, resolved into a frozen dataclass."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, TypedDict

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.validate import as_bool, as_choice, as_float, as_int, strict_api, strict_arguments

__all__ = [
    "RenderSettings",
    "QUALITIES",
    "OUTPUTS",
    "PIXEL_FILTERS",
    "FINAL_TARGET_ERROR",
    "resolve_settings",
    "settings_bias",
    "ENGINE_LIMIT_PREFIX",
    "ENGINE_ONLY_PREFIX",
    "BIAS_KEYS",
    "engine_limits",
]

QUALITIES = ("preview", "draft", "final", "blendify")
OUTPUTS = ("rgb", "depth", "normal", "albedo", "instance")
#: pixel reconstruction filters and their default widths (pixels)
PIXEL_FILTERS = {"box": 1.0, "gaussian": 1.5, "blackman_harris": 1.5}


# Presets are backend-independent. A path tracer asked for a preview renders few samples, denoised.
# "final" = unbiased path tracing (no denoiser, no clamp, no adaptive stop) that targets an error, not a
# sample count: a path tracer renders independent passes (``samples`` each at first) until the estimated
# relative RMS error of their mean is <= FINAL_TARGET_ERROR (relative MSE 1e-4), and reports the estimate
# with a confidence interval. An explicit ``samples=`` without ``target_error=`` renders exactly that many
# samples in one pass (no estimate); a raster backend renders once.
#
# "blendify" = the picture blendify 2.1 users had: Blender's own Cycles defaults as blendify 2.1 left them
# (128 samples, adaptive sampling with noise threshold 0.01, indirect light clamped at 10, Filter Glossy 1,
# bounces 12 / diffuse 4 / glossy 4 / transmission 12 / transparent 8, Blackman-Harris 1.5 px pixel filter;
# no denoiser, which blendify's render left off unless use_denoiser=True). Biased: meta["bias"] says how.
FINAL_TARGET_ERROR = 0.01


class _Preset(TypedDict, total=False):
    samples: int
    target_error: float
    denoise: bool
    max_bounces: int
    diffuse_bounces: int
    glossy_bounces: int
    transmission_bounces: int
    transparent_bounces: int
    pixel_filter: str
    clamp_indirect: float
    filter_glossy: float
    adaptive: bool


_PRESETS: dict[str, _Preset] = {
    "preview": {"samples": 8, "denoise": True, "max_bounces": 4},
    "draft": {"samples": 32, "denoise": True, "max_bounces": 8},
    "final": {"samples": 16, "denoise": False, "max_bounces": 12, "target_error": FINAL_TARGET_ERROR},
    "blendify": {
        "samples": 128,
        "denoise": False,
        "max_bounces": 12,
        "diffuse_bounces": 4,
        "glossy_bounces": 4,
        "transmission_bounces": 12,
        "transparent_bounces": 8,
        "pixel_filter": "blackman_harris",
        "clamp_indirect": 10.0,
        "filter_glossy": 1.0,
        "adaptive": True,
    },
}


@strict_api
@dataclass(frozen=True)
class RenderSettings:
    """Everything that decides how a scene is rendered (recorded in ``result.meta["settings"]``).

    ``samples``: samples per pixel (path tracers) or supersampling/anti-aliasing level hint (raster); with
    ``target_error`` the samples of each of the first independent passes (later passes are sized from the
    estimate).
    ``target_error``: render passes until the estimated relative RMS error is at most this (``final``'s
    preset: 0.01 unless ``samples=`` is given); ``time_limit`` stops earlier (recorded in meta).
    ``pixel_filter``: "box" (1 px, the default: comparable across engines), "gaussian" (1.5 px) or
    "blackman_harris" (1.5 px, Blender's default); ``pixel_filter_width`` overrides the width (pixels).
    ``clamp_direct`` / ``clamp_indirect``: 0 = off (unbiased). ``adaptive``: adaptive sampling on/off.
    ``filter_glossy``: Blender's Filter Glossy (blurs glossy reflections seen after a diffuse or rough
    bounce; 0 = off, unbiased). ``diffuse_bounces`` / ``glossy_bounces`` / ``transmission_bounces`` /
    ``transparent_bounces``: per-kind limits (None = ``max_bounces``; the transparent default: 8 or more).
    ``effects``: True = simulate only what the scene needs (effect analysis); False = full settings.
    ``caustics``: False leaves out light that reaches a diffuse surface through a glossy or refractive one
    (Cycles' caustics switches; Mitsuba's ``blendify_path`` integrator): biased, far less noisy; ``final``'s
    pilot chooses it where it estimates that light below half the target.
    """

    quality: str = "final"
    samples: int = 256
    seed: int = 0
    threads: int | None = None
    outputs: tuple[str, ...] = ("rgb",)
    denoise: bool = False
    max_bounces: int = 12
    time_limit: float | None = None
    target_error: float | None = None
    pixel_filter: str = "box"
    pixel_filter_width: float = 1.0
    clamp_direct: float = 0.0
    clamp_indirect: float = 0.0
    filter_glossy: float = 0.0
    adaptive: bool = False
    diffuse_bounces: int | None = None
    glossy_bounces: int | None = None
    transmission_bounces: int | None = None
    transparent_bounces: int | None = None
    transparent_background: bool = True
    effects: bool = True
    caustics: bool = True
    strict: bool = False
    extra: dict[str, object] = field(default_factory=dict, compare=False)

    def replace(self, **changes: Any) -> RenderSettings:
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["outputs"] = list(self.outputs)
        return d

    def wants(self, output: str) -> bool:
        return output in self.outputs

    def bounces(self, kind: str) -> int:
        """The bounce limit of ``kind`` ("diffuse", "glossy", "transmission", "transparent")."""
        value = getattr(self, f"{kind}_bounces")
        if value is not None:
            return int(value)
        return max(self.max_bounces, 8) if kind == "transparent" else self.max_bounces


#: the start of every ``meta["approximations"]`` line naming a biased setting the engine cannot apply
#: (:func:`engine_limits`); a crosscheck pair where one side applies it reports the pair as limited by the engine
ENGINE_LIMIT_PREFIX = "setting the engine cannot apply: "
#: the start of a crosscheck's limited-pair line for a setting only one engine of the pair applies (its
#: ``meta["engine_only_settings"]``, e.g. Cycles' ``cycles_settings`` from an attached .blend)
ENGINE_ONLY_PREFIX = "setting only one engine applies: "
#: the keys of :func:`settings_bias`'s items (what ``Backend.unapplied_settings`` names)
BIAS_KEYS = (
    "denoise",
    "clamp_direct",
    "clamp_indirect",
    "filter_glossy",
    "adaptive",
    "time_limit",
    "bounce_limits",
    "caustics",
)


def _bias_items(settings: RenderSettings) -> list[tuple[str, str]]:
    """(key of :data:`BIAS_KEYS`, description) of each biased setting of ``settings``."""
    out = []
    if settings.denoise:
        out.append(("denoise", "denoise: the denoiser smooths noise and fine detail"))
    if settings.clamp_direct:
        out.append(
            (
                "clamp_direct",
                f"clamp_direct={settings.clamp_direct:g}: direct light samples brighter than this are clamped",
            )
        )
    if settings.clamp_indirect:
        out.append(
            (
                "clamp_indirect",
                f"clamp_indirect={settings.clamp_indirect:g}: indirect light samples brighter than this are "
                "clamped (fewer fireflies, darker caustics and highlights)",
            )
        )
    if settings.filter_glossy:
        out.append(
            (
                "filter_glossy",
                f"filter_glossy={settings.filter_glossy:g}: glossy reflections after a diffuse or rough bounce "
                "are blurred (fewer fireflies, softer caustics)",
            )
        )
    if settings.adaptive:
        out.append(("adaptive", "adaptive: pixels stop sampling at a noise threshold (0.01), not at the sample count"))
    if settings.time_limit:
        out.append(("time_limit", f"time_limit={settings.time_limit:g}: sampling stops at the time limit"))
    if not settings.caustics:
        out.append(
            (
                "caustics",
                "caustics=False: light reaching a diffuse surface through a glossy or refractive one is left out",
            )
        )
    capped = [
        f"{kind} {settings.bounces(kind)}"
        for kind in ("diffuse", "glossy", "transmission")
        if settings.bounces(kind) < settings.max_bounces
    ]
    if capped:
        out.append(
            (
                "bounce_limits",
                "bounce limits below max_bounces (" + ", ".join(capped) + "): light of longer paths is missing",
            )
        )
    return out


def settings_bias(settings: RenderSettings, only: Sequence[str] | None = None) -> list[str]:
    """What makes a render with ``settings`` converge to something other than the unbiased picture
    (``result.meta["bias"]``; empty for ``final``); ``only``: just these keys of :data:`BIAS_KEYS` (what an
    engine applies)."""
    return [line for key, line in _bias_items(settings) if only is None or key in only]


def engine_limits(settings: RenderSettings, unapplied: Sequence[str]) -> list[str]:
    """The biased settings of ``settings`` an engine cannot apply (``unapplied``: keys of :data:`BIAS_KEYS`,
    ``Backend.unapplied_settings``), as ``meta["approximations"]`` lines starting with
    :data:`ENGINE_LIMIT_PREFIX` (the same text for every engine, so a crosscheck can tell which pairs differ)."""
    return [ENGINE_LIMIT_PREFIX + line for key, line in _bias_items(settings) if key in unapplied]


def _outputs(value: object) -> tuple[str, ...]:
    if isinstance(value, str):
        value = (value,)
    if not isinstance(value, (tuple, list)) or not value:
        raise InvalidSceneError(f"outputs: expected a non-empty tuple of names from {list(OUTPUTS)}, got {value!r}")
    out = []
    for v in value:
        name = "rgb" if v == "rgba" else v
        if name not in OUTPUTS:
            raise InvalidSceneError(f"outputs: unknown output {v!r}; expected names from {list(OUTPUTS)}")
        if name not in out:
            out.append(name)
    return tuple(out)


@strict_arguments
def resolve_settings(
    quality: str = "final",
    samples: int | None = None,
    seed: int = 0,
    threads: int | None = None,
    outputs: str | Sequence[str] = ("rgb",),
    denoise: bool | None = None,
    max_bounces: int | None = None,
    time_limit: float | None = None,
    target_error: float | None = None,
    pixel_filter: str | None = None,
    pixel_filter_width: float | None = None,
    clamp_direct: float = 0.0,
    clamp_indirect: float | None = None,
    filter_glossy: float | None = None,
    adaptive: bool | None = None,
    transparent_background: bool = True,
    effects: bool = True,
    caustics: bool = True,
    strict: bool = False,
    diffuse_bounces: int | None = None,
    glossy_bounces: int | None = None,
    transmission_bounces: int | None = None,
    transparent_bounces: int | None = None,
) -> RenderSettings:
    """Resolve a quality preset and explicit overrides into :class:`RenderSettings` (validated). An
    argument left at None takes the preset's value (or the :class:`RenderSettings` default)."""
    q = as_choice("quality", quality, QUALITIES)
    preset = _PRESETS[q]
    defaults: dict[str, Any] = dict(preset)
    pf_value = defaults.get("pixel_filter", "box") if pixel_filter is None else pixel_filter
    pf = as_choice("pixel_filter", pf_value, tuple(PIXEL_FILTERS))
    if pixel_filter_width is None:
        width = PIXEL_FILTERS[pf]
    else:
        width = as_float("pixel_filter_width", pixel_filter_width, min_value=0.01, max_value=10.0)

    def per_kind(kind: str, value: int | None) -> int | None:
        value = defaults.get(kind) if value is None else value
        return None if value is None else as_int(kind, value, min_value=0, max_value=1024)

    s = preset["samples"] if samples is None else as_int("samples", samples, min_value=1, max_value=1 << 24)
    dn = preset["denoise"] if denoise is None else as_bool("denoise", denoise)
    if target_error is None and samples is None and not dn:
        # the preset's error target applies unless the user fixed the sample count or asked for a denoised
        # picture (denoised passes are not independent estimates)
        target_error = defaults.get("target_error")
    if threads is not None:
        threads = as_int("threads", threads, min_value=1, max_value=4096)
    return RenderSettings(
        quality=q,
        samples=s,
        seed=as_int("seed", seed, min_value=0, max_value=2**31 - 1),
        threads=threads,
        outputs=_outputs(outputs),
        denoise=dn,
        max_bounces=preset["max_bounces"]
        if max_bounces is None
        else as_int("max_bounces", max_bounces, min_value=0, max_value=1024),
        time_limit=None
        if time_limit is None
        else as_float("time_limit", time_limit, min_value=0.0, exclusive_min=True),
        target_error=None
        if target_error is None
        else as_float("target_error", target_error, min_value=0.0, exclusive_min=True),
        pixel_filter=pf,
        pixel_filter_width=width,
        clamp_direct=as_float("clamp_direct", clamp_direct, min_value=0.0),
        clamp_indirect=as_float(
            "clamp_indirect",
            defaults.get("clamp_indirect", 0.0) if clamp_indirect is None else clamp_indirect,
            min_value=0.0,
        ),
        filter_glossy=as_float(
            "filter_glossy",
            defaults.get("filter_glossy", 0.0) if filter_glossy is None else filter_glossy,
            min_value=0.0,
            max_value=10.0,
        ),
        adaptive=as_bool("adaptive", defaults.get("adaptive", False) if adaptive is None else adaptive),
        transparent_background=as_bool("transparent_background", transparent_background),
        effects=as_bool("effects", effects),
        caustics=as_bool("caustics", caustics),
        strict=as_bool("strict", strict),
        diffuse_bounces=per_kind("diffuse_bounces", diffuse_bounces),
        glossy_bounces=per_kind("glossy_bounces", glossy_bounces),
        transmission_bounces=per_kind("transmission_bounces", transmission_bounces),
        transparent_bounces=per_kind("transparent_bounces", transparent_bounces),
    )
