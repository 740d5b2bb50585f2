"""Render settings: quality presets plus explicit overrides, resolved into a frozen dataclass."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, TypedDict

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.validate import as_bool, as_choice, as_float, as_int

__all__ = ["RenderSettings", "QUALITIES", "OUTPUTS", "resolve_settings"]

QUALITIES = ("preview", "draft", "final")
OUTPUTS = ("rgb", "depth", "normal", "albedo", "instance")


# Presets are backend-independent. A path tracer asked for a preview renders few samples, denoised.
# "final" = unbiased path tracing (no denoiser, no clamp, no adaptive stop) at a fixed 256 samples per pixel:
# its accuracy is stated by measurement (benchmarks/results/accuracy_vs_time.md: relative MSE against a
# converged reference), not estimated per render; pass ``target_error=`` for a per-render estimate and a
# guaranteed bound (independent passes until the estimated relative RMS error is below it).
class _Preset(TypedDict):
    samples: int
    denoise: bool
    max_bounces: int


_PRESETS: dict[str, _Preset] = {
    "preview": {"samples": 8, "denoise": True, "max_bounces": 4},
    "draft": {"samples": 32, "denoise": True, "max_bounces": 8},
    "final": {"samples": 256, "denoise": False, "max_bounces": 12},
}


@dataclass(frozen=True)
class RenderSettings:
    """Everything that decides how a scene is rendered (recorded in ``result.meta["settings"]``).

    ``samples``: samples per pixel (path tracers) or supersampling/anti-aliasing level hint (raster).
    ``pixel_filter``: "box" (1 px, the default: comparable across engines) or "gaussian" (1.5 px).
    ``clamp_direct`` / ``clamp_indirect``: 0 = off (unbiased). ``adaptive``: adaptive sampling on/off.
    ``effects``: True = simulate only what the scene needs (effect analysis); False = full settings.
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
    clamp_direct: float = 0.0
    clamp_indirect: float = 0.0
    adaptive: bool = False
    transparent_background: bool = True
    effects: bool = True
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
    pixel_filter: str = "box",
    clamp_direct: float = 0.0,
    clamp_indirect: float = 0.0,
    adaptive: bool = False,
    transparent_background: bool = True,
    effects: bool = True,
    strict: bool = False,
) -> RenderSettings:
    """Resolve a quality preset and explicit overrides into :class:`RenderSettings` (validated)."""
    q = as_choice("quality", quality, QUALITIES)
    preset = _PRESETS[q]
    s = preset["samples"] if samples is None else as_int("samples", samples, min_value=1, max_value=1 << 24)
    if threads is not None:
        threads = as_int("threads", threads, min_value=1, max_value=4096)
    return RenderSettings(
        quality=q,
        samples=s,
        seed=as_int("seed", seed, min_value=0, max_value=2**31 - 1),
        threads=threads,
        outputs=_outputs(outputs),
        denoise=preset["denoise"] if denoise is None else as_bool("denoise", denoise),
        max_bounces=preset["max_bounces"]
        if max_bounces is None
        else as_int("max_bounces", max_bounces, min_value=0, max_value=1024),
        time_limit=None
        if time_limit is None
        else as_float("time_limit", time_limit, min_value=0.0, exclusive_min=True),
        target_error=None
        if target_error is None
        else as_float("target_error", target_error, min_value=0.0, exclusive_min=True),
        pixel_filter=as_choice("pixel_filter", pixel_filter, ("box", "gaussian")),
        clamp_direct=as_float("clamp_direct", clamp_direct, min_value=0.0),
        clamp_indirect=as_float("clamp_indirect", clamp_indirect, min_value=0.0),
        adaptive=as_bool("adaptive", adaptive),
        transparent_background=as_bool("transparent_background", transparent_background),
        effects=as_bool("effects", effects),
        strict=as_bool("strict", strict),
    )
