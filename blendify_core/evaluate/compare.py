"""``bf.compare``: compare two renders, treating the second as the reference.

``compare(a, b)`` returns a :class:`~blendify_core.evaluate.report.CompareReport`: per-output metrics
(:mod:`.metrics`), a verdict against a named tolerance tier (:mod:`.tiers`), human-readable failures and a
heat-map diff image per output. When both results carry the noise of their colour (``rgb_var``, measured
from independent passes: ``bf.crosscheck`` and :func:`~blendify_core.evaluate.noise.render_passes` keep
it), the colour verdict of the path-tracer tiers is the noise-aware test of :mod:`.noise` (agree within
noise up to a small margin, fail on a bias) instead of fixed tolerances. Per-pixel statistical tests
against a reference live in :mod:`.stats`.
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
from blendify_core.evaluate.noise import NoiseTest, noise_test
from blendify_core.evaluate.report import CompareReport, _fmt
from blendify_core.evaluate.tiers import NOISE_MARGINS, _resolve_tier
from blendify_core.ir.scene import Scene
from blendify_core.ir.validate import as_bool, strict_arguments
from blendify_core.pipeline.result import RenderResult
from blendify_core.typing import AnyArray, BoolArray

__all__ = ["compare"]


def _check_shapes(a: RenderResult, b: RenderResult) -> None:
    ra, rb = a.resolution, b.resolution
    if ra is None or rb is None:
        raise InvalidSceneError("compare: both results need at least one output")
    if ra != rb:
        raise InvalidSceneError(f"compare: resolutions differ ({ra} vs {rb}); render both at the same resolution")


@strict_arguments
def compare(
    a: RenderResult,
    b: RenderResult,
    tier: str | Mapping[str, Mapping[str, float]] | None = "auto",
    outputs: Iterable[str] | None = None,
    names: tuple[str, str] | None = None,
    scene: Scene | None = None,
    noise: bool | None = None,
) -> CompareReport:
    """Compare render ``a`` with reference ``b``; see the module docstring for the metrics.

    ``tier``: a name from :data:`TIERS`, "auto" (from ``meta["backend"]`` of both results:
    :func:`choose_tier`; pass the rendered ``scene`` so it can tell delta lights and non-Lambertian
    materials apart) or a dict output -> metric -> threshold. ``names``: labels for the report.
    ``outputs``: the outputs to compare (from "rgb", "depth", "mask", "normal", "albedo", "instance");
    default: every output present in both ("mask" whenever a hit mask can be derived from both).
    Requesting an output one of the results lacks raises :class:`InvalidSceneError`.

    ``noise``: None (default) = the noise-aware colour verdict whenever both results carry ``rgb_var``
    and the tier is a path-tracer tier (margins :data:`~blendify_core.evaluate.tiers.NOISE_MARGINS`);
    True = require it (an error when a result has no ``rgb_var``); False = the tier's fixed thresholds.
    The test's outcome is ``report.noise``; its checks appear as ``rgb.noise_tiles_rejected`` (<= 0) and
    ``rgb.noise_global_excess`` (<= its critical value).
    """
    if not isinstance(a, RenderResult) or not isinstance(b, RenderResult):
        raise InvalidSceneError(f"compare: expected two RenderResult, got {type(a).__name__} and {type(b).__name__}")
    _check_shapes(a, b)
    tier_name, thresholds = _resolve_tier(tier, a, b, scene)
    ma, mb = hit_mask(a), hit_mask(b)
    wanted = _wanted_outputs(a, b, ma, mb, outputs)
    depth_limits = thresholds.get("depth", {})
    tie_tol = depth_limits.get("rel_diff_q99", depth_limits.get("rel_diff_max"))
    metrics, diffs, legends = _measure(a, b, ma, mb, wanted, None if tie_tol is None else float(tie_tol))
    nt = _noise_verdict(a, b, tier_name, noise) if "rgb" in wanted else None
    if nt is not None:
        metrics["rgb"]["noise_tiles_rejected"] = float(nt.n_tile_reject)
        metrics["rgb"]["noise_global_excess"] = nt.global_excess
        metrics["rgb"]["noise_global_rel_diff"] = float(np.max(np.abs(nt.global_rel_diff)))
        thresholds = {**thresholds, "rgb": {"noise_tiles_rejected": 0.0, "noise_global_excess": nt.global_crit}}
        if nt.n_tile_reject and "rgb" in diffs:
            diffs["rgb"] = _frame_tiles(diffs["rgb"], nt)
            legends["rgb"] = legends.get("rgb", "") + "; magenta frames: tiles that differ beyond their noise"
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
        notes=verdict.notes
        + ([f"rgb: noise-aware verdict: {'; '.join(nt.reasons) or 'agree within noise'}"] if nt else []),
        results=(a, b),
        noise=nt,
    )


def _frame_tiles(image: AnyArray, nt: NoiseTest) -> AnyArray:
    """A copy of the (H, W, 3) uint8 heat map with a magenta frame around every tile the noise test rejected."""
    out = np.array(image, copy=True)
    h, w = out.shape[:2]
    t = nt.tile
    for ty, tx in zip(*np.nonzero(nt.tile_reject), strict=True):
        y0, x0 = ty * t, tx * t
        y1, x1 = min(y0 + t, h) - 1, min(x0 + t, w) - 1
        for ys, xs in (
            (slice(y0, y1 + 1), x0),
            (slice(y0, y1 + 1), x1),
            (y0, slice(x0, x1 + 1)),
            (y1, slice(x0, x1 + 1)),
        ):
            out[ys, xs] = (255, 0, 255)
    return out


def _noise_verdict(a: RenderResult, b: RenderResult, tier_name: str, noise: bool | None) -> NoiseTest | None:
    """The noise-aware colour test, when asked for (``noise``) or possible (both results carry ``rgb_var``
    and the tier is a path-tracer tier)."""
    if noise is not None and not as_bool("noise", noise):
        return None
    have = a.rgb_var is not None and b.rgb_var is not None and a.rgba is not None and b.rgba is not None
    if noise is None and not (have and tier_name in NOISE_MARGINS):
        return None
    if not have:
        raise InvalidSceneError(
            "noise=True: both results need the colour and its noise (rgb_var, from independent passes: "
            "bf.crosscheck or blendify_core.evaluate.noise.render_passes)"
        )
    margin_global, margin_tile = NOISE_MARGINS.get(tier_name, NOISE_MARGINS["pathtracer"])
    dofs = []
    for label, r in (("a", a), ("b", b)):
        k = r.meta.get("passes") if isinstance(r.meta, dict) else None
        if not isinstance(k, (int, np.integer)) or k < 2:
            raise InvalidSceneError(
                f"result {label}: rgb_var needs meta['passes'] (the number of independent passes, >= 2), got {k!r}"
            )
        dofs.append(float(k - 1))
    if a.rgba is None or b.rgba is None or a.rgb_var is None or b.rgb_var is None:  # checked above (types)
        raise InvalidSceneError("noise: both results need the colour and its noise (rgb_var)")
    return noise_test(
        a.rgba[..., :3],
        a.rgb_var,
        dofs[0],
        b.rgba[..., :3],
        b.rgb_var,
        dofs[1],
        margin_global=margin_global,
        margin_tile=margin_tile,
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
    a: RenderResult,
    b: RenderResult,
    ma: BoolArray | None,
    mb: BoolArray | None,
    wanted: list[str],
    depth_tol: float | None = None,
) -> tuple[dict[str, dict[str, float]], dict[str, AnyArray], dict[str, str]]:
    """Metrics, heat-map diff image and its legend per output (``depth_tol``: the tier's relative depth
    threshold, within which two different instance ids at one pixel are a tie)."""
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
            res = _instance_metrics(a, b, depth_tol)
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
