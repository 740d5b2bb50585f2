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
    attr = {"rgb": "rgba", "depth": "depth", "normal": "normal", "albedo": "albedo", "instance": "instance"}
    ma, mb = hit_mask(a), hit_mask(b)

    def has(r: RenderResult, out: str, m: np.ndarray | None) -> bool:
        return m is not None if out == "mask" else getattr(r, attr[out]) is not None

    if outputs is None:
        wanted = [o for o in COMPARED_OUTPUTS if has(a, o, ma) and has(b, o, mb)]
    else:
        if isinstance(outputs, str):
            outputs = (outputs,)
        wanted = []
        for o in outputs:
            o = "rgb" if o == "rgba" else o
            if o not in COMPARED_OUTPUTS:
                raise InvalidSceneError(f"outputs: unknown output {o!r}; expected names from {list(COMPARED_OUTPUTS)}")
            for label, r, m in (("a", a, ma), ("b", b, mb)):
                if not has(r, o, m):
                    raise InvalidSceneError(f"outputs: result {label} has no {o!r} output")
            if o not in wanted:
                wanted.append(o)
    if not wanted:
        raise InvalidSceneError("compare: the two results have no output in common")

    both = (ma & mb) if (ma is not None and mb is not None) else None
    if both is None:
        both = np.ones(a.resolution[::-1], dtype=bool)  # type: ignore[index]
    interior = interior_mask(a, b)
    _MISSING_METRICS.clear()
    metrics: dict[str, dict[str, float]] = {}
    diffs: dict[str, np.ndarray] = {}
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

    failures: list[str] = []
    notes: list[str] = []
    checks: list[tuple[str, str, float, str, float, bool]] = []
    applied: dict[str, dict[str, float]] = {}
    for out, ms in thresholds.items():
        if out not in metrics:
            if outputs is not None and out in wanted:
                notes.append(f"{out}: not compared")
            continue
        for metric, limit in ms.items():
            if metric not in metrics[out]:
                raise InvalidSceneError(f"tier: unknown metric {out}.{metric}; known: {sorted(metrics[out])}")
            value = metrics[out][metric]
            if math.isnan(value):
                count_key = "n_interior" if metric in _INTERIOR_METRICS[out] else _COUNT_KEYS.get(out, "")
                if metrics[out].get(count_key, 1.0) == 0:
                    what = (
                        "interior pixels (objects of 1-2 px, e.g. small points)"
                        if count_key == "n_interior"
                        else ("pixels covered by both")
                    )
                    notes.append(f"{out}.{metric}: not checked, no {what}")
                    continue
            higher = metric in HIGHER_IS_BETTER
            op = ">=" if higher else "<="
            ok = (value >= limit) if higher else (value <= limit)
            if isinstance(value, float) and math.isnan(value):
                ok = False
            checks.append((out, metric, value, op, limit, bool(ok)))
            applied.setdefault(out, {})[metric] = limit
            if not ok:
                hint = f"; {_INSTALL_HINT}" if out == "rgb" and metric in _MISSING_METRICS else ""
                failures.append(
                    f"{out}.{metric} = {_fmt(value)}, expected {op} {_fmt(limit)} (tier {tier_name!r}){hint}"
                )
    if "rgb" in metrics:
        missing = sorted(m for m in ("ssim", "flip") if m in _MISSING_METRICS and math.isnan(metrics["rgb"][m]))
        if missing:
            notes.append(f"rgb: {', '.join(missing)} not computed: {_INSTALL_HINT}")
    la = names[0] if names else (_backend_of(a) or "a")
    lb = names[1] if names else (_backend_of(b) or "b")
    if la == lb and names is None:
        la, lb = f"{la} (a)", f"{lb} (b)"
    return CompareReport(
        metrics=metrics,
        tier=tier_name,
        thresholds=applied,
        passed=not failures,
        failures=failures,
        checks=checks,
        diff_images=diffs,
        legends=legends,
        names=(la, lb),
        notes=notes,
        results=(a, b),
    )
