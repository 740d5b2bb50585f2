"""``bf.compare``: compare two renders, treating the second as the reference.

``compare(a, b)`` returns a :class:`~blendify_core.evaluate.report.CompareReport`: per-output metrics
(:mod:`.metrics`), a verdict against a named tolerance tier (:mod:`.tiers`), human-readable failures and a
heat-map diff image per output. Statistical (noise-aware) comparison of path-traced images lives in
:mod:`.stats`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.evaluate.metrics import (
    _COUNT_KEYS,
    _INSTALL_HINT,
    _INTERIOR_METRICS,
    _MISSING_METRICS,
    COMPARED_OUTPUTS,
    HIGHER_IS_BETTER,
    _albedo_metrics,
    _backend_of,
    _depth_metrics,
    _instance_metrics,
    _mask_metrics,
    _normal_metrics,
    _rgb_metrics,
    hit_mask,
    interior_mask,
)
from blendify_core.evaluate.report import CompareReport, _fmt
from blendify_core.evaluate.tiers import _resolve_tier
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.result import RenderResult
from blendify_core.typing import AnyArray, BoolArray

__all__ = ["compare"]


def _check_shapes(a: RenderResult, b: RenderResult) -> None:
    ra, rb = a.resolution, b.resolution
    if ra is None or rb is None:
        raise InvalidSceneError("compare: both results need at least one output")
    if ra != rb:
        raise InvalidSceneError(f"compare: resolutions differ ({ra} vs {rb}); render both at the same resolution")


def compare(
    a: RenderResult,
    b: RenderResult,
    tier: str | Mapping[str, Mapping[str, float]] | None = "auto",
    outputs: Iterable[str] | None = None,
    names: tuple[str, str] | None = None,
    scene: Scene | None = None,
) -> CompareReport:
    """Compare render ``a`` with reference ``b``; see the module docstring for the metrics.

    ``tier``: a name from :data:`TIERS`, "auto" (from ``meta["backend"]`` of both results:
    :func:`choose_tier`; pass the rendered ``scene`` so it can tell delta lights and non-Lambertian
    materials apart) or a dict output -> metric -> threshold. ``names``: labels for the report.
    ``outputs``: the outputs to compare (from "rgb", "depth", "mask", "normal", "albedo", "instance");
    default: every output present in both ("mask" whenever a hit mask can be derived from both).
    Requesting an output one of the results lacks raises :class:`InvalidSceneError`.
    """
    if not isinstance(a, RenderResult) or not isinstance(b, RenderResult):
        raise InvalidSceneError(f"compare: expected two RenderResult, got {type(a).__name__} and {type(b).__name__}")
    _check_shapes(a, b)
    tier_name, thresholds = _resolve_tier(tier, a, b, scene)
    ma, mb = hit_mask(a), hit_mask(b)
    wanted = _wanted_outputs(a, b, ma, mb, outputs)
    metrics, diffs, legends = _measure(a, b, ma, mb, wanted)
    verdict = _Verdict(tier_name)
    for out, ms in thresholds.items():
        if out not in metrics:
            if outputs is not None and out in wanted:
                verdict.notes.append(f"{out}: not compared")
            continue
        for metric, limit in ms.items():
            verdict.check(out, metric, metrics[out], limit)
    if "rgb" in metrics:
        missing = sorted(m for m in ("ssim", "flip") if m in _MISSING_METRICS and math.isnan(metrics["rgb"][m]))
        if missing:
            verdict.notes.append(f"rgb: {', '.join(missing)} not computed: {_INSTALL_HINT}")
    return CompareReport(
        metrics=metrics,
        tier=tier_name,
        thresholds=verdict.applied,
        passed=not verdict.failures,
        failures=verdict.failures,
        checks=verdict.checks,
        diff_images=diffs,
        legends=legends,
        names=_labels(a, b, names),
        notes=verdict.notes,
        results=(a, b),
    )


_ATTR = {"rgb": "rgba", "depth": "depth", "normal": "normal", "albedo": "albedo", "instance": "instance"}


def _has(r: RenderResult, out: str, m: BoolArray | None) -> bool:
    return m is not None if out == "mask" else getattr(r, _ATTR[out]) is not None


def _wanted_outputs(
    a: RenderResult, b: RenderResult, ma: BoolArray | None, mb: BoolArray | None, outputs: Iterable[str] | None
) -> list[str]:
    """The outputs to compare: the requested ones (each present in both), or every one present in both."""
    if outputs is None:
        wanted = [o for o in COMPARED_OUTPUTS if _has(a, o, ma) and _has(b, o, mb)]
    else:
        if isinstance(outputs, str):
            outputs = (outputs,)
        wanted = []
        for name in outputs:
            o = "rgb" if name == "rgba" else name
            if o not in COMPARED_OUTPUTS:
                raise InvalidSceneError(f"outputs: unknown output {o!r}; expected names from {list(COMPARED_OUTPUTS)}")
            for label, r, m in (("a", a, ma), ("b", b, mb)):
                if not _has(r, o, m):
                    raise InvalidSceneError(f"outputs: result {label} has no {o!r} output")
            if o not in wanted:
                wanted.append(o)
    if not wanted:
        raise InvalidSceneError("compare: the two results have no output in common")
    return wanted


def _measure(
    a: RenderResult, b: RenderResult, ma: BoolArray | None, mb: BoolArray | None, wanted: list[str]
) -> tuple[dict[str, dict[str, float]], dict[str, AnyArray], dict[str, str]]:
    """Metrics, heat-map diff image and its legend per output."""
    both = (ma & mb) if (ma is not None and mb is not None) else None
    if both is None:
        width, height = a.resolution or (0, 0)
        both = np.ones((height, width), dtype=bool)
    interior = interior_mask(a, b)
    _MISSING_METRICS.clear()
    metrics: dict[str, dict[str, float]] = {}
    diffs: dict[str, AnyArray] = {}
    legends: dict[str, str] = {}
    for o in wanted:
        if o == "rgb":
            res = _rgb_metrics(a, b, interior)
        elif o == "depth":
            res = _depth_metrics(a, b)
        elif o == "mask":
            res = _mask_metrics(ma, mb)  # type: ignore[arg-type]
        elif o == "normal":
            res = _normal_metrics(a, b, both, interior)
        elif o == "instance":
            res = _instance_metrics(a, b)
        else:
            res = _albedo_metrics(a, b, both, interior)
        metrics[o], diffs[o], legends[o] = res
    return metrics, diffs, legends


class _Verdict:
    """Metric checks against a tier's thresholds: the checks made, the thresholds applied, failures, notes."""

    def __init__(self, tier_name: str) -> None:
        self.tier_name = tier_name
        self.failures: list[str] = []
        self.notes: list[str] = []
        self.checks: list[tuple[str, str, float, str, float, bool]] = []
        self.applied: dict[str, dict[str, float]] = {}

    def check(self, out: str, metric: str, measured: dict[str, float], limit: float) -> None:
        if metric not in measured:
            raise InvalidSceneError(f"tier: unknown metric {out}.{metric}; known: {sorted(measured)}")
        value = measured[metric]
        if math.isnan(value):
            count_key = "n_interior" if metric in _INTERIOR_METRICS[out] else _COUNT_KEYS.get(out, "")
            if measured.get(count_key, 1.0) == 0:
                what = (
                    "interior pixels (objects of 1-2 px, e.g. small points)"
                    if count_key == "n_interior"
                    else ("pixels covered by both")
                )
                self.notes.append(f"{out}.{metric}: not checked, no {what}")
                return
        higher = metric in HIGHER_IS_BETTER
        op = ">=" if higher else "<="
        ok = (value >= limit) if higher else (value <= limit)
        if isinstance(value, float) and math.isnan(value):
            ok = False
        self.checks.append((out, metric, value, op, limit, bool(ok)))
        self.applied.setdefault(out, {})[metric] = limit
        if not ok:
            hint = f"; {_INSTALL_HINT}" if out == "rgb" and metric in _MISSING_METRICS else ""
            self.failures.append(
                f"{out}.{metric} = {_fmt(value)}, expected {op} {_fmt(limit)} (tier {self.tier_name!r}){hint}"
            )


def _labels(a: RenderResult, b: RenderResult, names: tuple[str, str] | None) -> tuple[str, str]:
    la = names[0] if names else (_backend_of(a) or "a")
    lb = names[1] if names else (_backend_of(b) or "b")
    if la == lb and names is None:
        la, lb = f"{la} (a)", f"{lb} (b)"
    return la, lb
