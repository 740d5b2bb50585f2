"""The price before paying: ``bf.estimate_cost`` predicts a render's samples and time from a short pilot.

A path tracer's error falls as 1/sqrt(samples) and its time grows as a fixed cost per pass plus a cost per
sample. The pilot renders exactly the first passes ``final`` renders (``FIRST_PASSES`` independent passes of
the preset's samples: their spread is the render's own first estimate, with the same sampler at the same
sample count, so a quasi-Monte-Carlo sampler's faster convergence at higher counts is not extrapolated from
tiny passes) and one pass of ``LONG_PASS`` times the preset's samples. Their times separate the fixed cost
per pass, the cost per sample and what an engine pays the first time it renders a sample count (Mitsuba's
llvm variants compile a kernel: the first pass against its repeats; where it does, or where the long pass
costs more than ``LONG_PASS`` short ones, the long pass is rendered again, compiled, so its compilation does
not count as samples). The
prediction replays the schedule :func:`~blendify_core.pipeline.render.render_to_target` follows from there
(the same pass sizing), so predicted passes and samples are those the render takes if the error keeps
falling as 1/sqrt(samples). The pilot costs about twice the cheapest ``final`` render.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.scene import Scene
from blendify_core.ir.validate import as_float, strict_api, strict_arguments
from blendify_core.pipeline.backend import Backend
from blendify_core.pipeline.render import (
    FIRST_PASSES,
    MAX_PASSES,
    MAX_SAMPLES,
    _mean_mse,
    _next_pass_samples,
    error_dof,
    error_interval,
    expected_size_factor,
    few_terms_factor,
    pass_seed,
    pass_size_model,
    relative_error_estimate,
    render,
)
from blendify_core.pipeline.settings import FINAL_TARGET_ERROR, resolve_settings
from blendify_core.typing import FloatArray

__all__ = ["CostEstimate", "estimate_cost", "predict_schedule", "schedule"]

#: the pilot's last pass renders this many times the preset's pass samples: it fixes the cost per sample,
#: which 1- and 16-sample passes alone leave to timing noise on hard scenes
LONG_PASS = 4
#: timing noise allowed before a long pass dearer than LONG_PASS short ones counts as having compiled
LONG_PASS_SLACK = 1.25


@strict_api
@dataclass(frozen=True)
class CostEstimate:
    """What a render to ``target_error`` is predicted to cost (``seconds`` excludes the pilot itself)."""

    backend: str
    target_error: float
    samples: int
    passes: int
    seconds: float
    #: a 90 % range of ``seconds`` from the pilot's error interval (error ~ 1/sqrt(samples))
    seconds_range: tuple[float, float]
    pilot_samples: int
    pilot_seconds: float
    pilot_error: float
    seconds_per_sample: float
    seconds_per_pass: float
    #: "noise" for a path tracer; "bias" for a raster backend (one render; its error is not noise)
    kind: str
    reaches_target: bool
    #: an engine's extra cost the first time it renders a sample count (Mitsuba's llvm variants compile)
    seconds_per_new_size: float = 0.0
    #: what one ``bf.render`` call costs outside the engine's passes (checks, the scene's fingerprint, the
    #: result's assembly); the render is one call, so this is counted once
    seconds_per_call: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def __str__(self) -> str:
        if self.kind == "bias":
            return f"{self.backend}: one render, about {self.seconds:.2f} s (raster: its error is bias, not noise)"
        lo, hi = self.seconds_range
        cap = "" if self.reaches_target else " (the pass/sample cap stops it first)"
        return (
            f"{self.backend}: about {self.samples} samples in {self.passes} passes, {self.seconds:.1f} s "
            f"(90 %: {lo:.1f}-{hi:.1f} s) to reach a relative RMS error of {self.target_error:g}{cap}; "
            f"pilot: {self.pilot_samples} samples, error {self.pilot_error:.3g}, {self.pilot_seconds:.1f} s"
        )


def schedule(
    error_at: float,
    samples_at: int,
    target: float,
    base: int,
    pixels: float = float("inf"),
    size_model: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[list[int], bool]:
    """The pass sizes ``render_to_target`` renders if the error is ``error_at`` at ``samples_at`` samples and
    falls as 1/sqrt(samples), and whether it reaches ``target`` before the caps. ``pixels``: how many pixels
    carry the error (:func:`error_dof` per pass), which the render's stopping rule trusts by
    (:func:`few_terms_factor`). ``size_model``: (the pilot's fitted pooled variances, its passes' samples)
    (:func:`~blendify_core.pipeline.render.pass_size_model`, ``error_at`` then without the factor it carries):
    the estimate of passes of different sizes falls as that model says, with the factor the render's estimate
    carries (:func:`~blendify_core.pipeline.render.expected_size_factor`)."""
    counts = [base] * FIRST_PASSES
    at = None if size_model is None else _mean_mse(size_model[0], np.asarray(size_model[1], dtype=np.float64))[1]
    while True:
        total = sum(counts)
        if size_model is None or not at:
            mse_ratio = samples_at / total
        else:
            n = np.asarray(counts, dtype=np.float64)
            mse_ratio = _mean_mse(size_model[0], n)[1] / at * expected_size_factor(size_model[0], n)
        estimate = error_at * np.sqrt(mse_ratio) * few_terms_factor((len(counts) - 1) * pixels)
        if estimate <= target:
            return counts, True
        if len(counts) >= MAX_PASSES or total >= MAX_SAMPLES:
            return counts, False
        counts.append(_next_pass_samples(total, float(estimate), target, base))


def predict_schedule(*args: Any, **kwargs: Any) -> tuple[int, int, bool]:
    """Passes and total samples of :func:`schedule` (the same arguments), and whether it reaches ``target``."""
    counts, reached = schedule(*args, **kwargs)
    return len(counts), sum(counts), reached


@strict_arguments
def estimate_cost(
    scene: Scene,
    backend: str | Backend | None = None,
    target_error: float | None = None,
    quality: str = "final",
    seed: int = 0,
    **kwargs: Any,
) -> CostEstimate:
    """Predict the samples and seconds a render of ``scene`` to ``target_error`` (default: the quality
    preset's target, else :data:`FINAL_TARGET_ERROR`) takes, from a pilot at the scene's own resolution: the
    render's own first passes and one longer pass (see the module's documentation).
    ``kwargs`` are passed to :func:`bf.render` (settings overrides and backend options)."""
    if not isinstance(scene, Scene):
        raise InvalidSceneError(f"scene: expected a blendify_core.Scene, got {type(scene).__name__}")
    for bad in ("samples", "target_error", "denoise", "time_limit"):
        if bad in kwargs:
            raise InvalidSceneError(f"estimate_cost: {bad!r} is chosen by the pilot; do not pass it")
    preset = resolve_settings(quality)
    if target_error is None:
        target = preset.target_error if preset.target_error is not None else FINAL_TARGET_ERROR
    else:
        target = as_float("target_error", target_error, min_value=0.0, exclusive_min=True)
    base = preset.samples

    outside: list[float] = []  # each pilot call's seconds outside the engine's part

    def one(samples: int, index: int) -> tuple[FloatArray | None, float, Any]:
        t0 = time.perf_counter()
        r = render(scene, backend=backend, quality=quality, samples=samples, seed=pass_seed(seed, index), **kwargs)
        wall = time.perf_counter() - t0
        # the engine's part ("render": set-up + rendering + read-back): a pass of the real render repeats that,
        # not the pilot's per-call checks or a re-translation for a new sample count; those the real render
        # pays once (``seconds_per_call``)
        seconds = float(r.meta.get("timings", {}).get("render", wall))
        outside.append(max(wall - seconds, 0.0))
        return (None if r.rgba is None else r.rgba[..., :3].astype(np.float64)), seconds, r

    t_start = time.perf_counter()
    _, _, warm = one(1, 0)  # translation and engine start-up: paid once by the real render too
    name = str(warm.meta.get("backend"))
    if not warm.meta.get("path_tracer"):
        _, seconds, _ = one(1, 0)
        seconds += outside[-1]  # the one call's own checks
        return CostEstimate(name, target, 1, 1, seconds, (seconds, seconds), 0, time.perf_counter() - t_start,
                            0.0, 0.0, seconds, "bias", True, seconds_per_call=outside[-1])  # fmt: skip
    # the render's own first passes (the first of a sample count pays an engine's compilation for it, e.g.
    # Mitsuba's llvm variants: the difference to the repeats), then one pass of a new, larger count
    firsts = [one(base, i) for i in range(FIRST_PASSES)]
    long_rgb, t_long, _ = one(LONG_PASS * base, FIRST_PASSES)
    t_rep = float(np.median([t for _, t, _ in firsts[1:]]))
    per_size = max(firsts[0][1] - t_rep, 0.0)
    colours = [c for c, _, _ in firsts] + [long_rgb]
    counts = [float(base)] * FIRST_PASSES + [float(LONG_PASS * base)]
    if per_size > t_rep or t_long > LONG_PASS * t_rep * LONG_PASS_SLACK:
        # the engine compiled for the new sample count: the long pass's compilation (not the same as the first
        # pass's) hides its cost per sample, so it is timed again, compiled (Mitsuba's llvm variants: 48x48
        # bunny, 0.0056 s per sample from the compiling pass against 0.0017 rendered). A long pass dearer than
        # LONG_PASS short ones has paid a one-time cost too (its fixed part is paid once, not LONG_PASS
        # times), also where the first pass's size was compiled by an earlier render in the process and so
        # showed none: a 64x64 bunny after a sample sweep was predicted 1.45 s for a 0.19 s render
        long_again, t_again, _ = one(LONG_PASS * base, FIRST_PASSES + 1)
        colours.append(long_again)
        counts.append(float(LONG_PASS * base))
        per_size = max(per_size, t_long - t_again)
        t_long = t_again
        per_sample = max((t_long - t_rep) / ((LONG_PASS - 1) * base), 0.0)
    else:
        per_sample = max((t_long - per_size - t_rep) / ((LONG_PASS - 1) * base), 0.0)
    per_pass = max(t_rep - base * per_sample, 0.0)
    if any(c is None for c in colours):
        raise InvalidSceneError("estimate_cost: the error is estimated on colour; the render has no 'rgb' output")
    stack = np.stack(colours)  # type: ignore[arg-type]
    counts_arr = np.array(counts)
    pilot_error = relative_error_estimate(stack, counts_arr)
    pixels = error_dof(stack, counts_arr) / (len(counts_arr) - 1)  # the pixels that carry the error
    lo_err, hi_err = error_interval(stack, counts_arr)
    pilot_n = int(counts_arr.sum())
    # the first call translated the scene, which the real render finds done: the repeats' median
    per_call = float(np.median(outside[1:]))
    compiled = {base, LONG_PASS * base}  # sizes this process's engine has seen now

    # where the pilot's passes of two sizes show a stratified sampler's faster fall, the render's will too
    coef, carried = pass_size_model(stack, counts_arr)
    size_model = None if coef is None else (coef, counts_arr)
    unscaled = 1.0 if coef is None else 1.0 / np.sqrt(carried)  # the schedule starts from the 1/n estimate

    def seconds_for(err: float) -> float:
        sizes, _ = schedule(err * unscaled, pilot_n, target, base, pixels, size_model)
        return per_call + len(sizes) * per_pass + sum(sizes) * per_sample + len(set(sizes) - compiled) * per_size

    passes, samples, reached = predict_schedule(pilot_error * unscaled, pilot_n, target, base, pixels, size_model)
    seconds = seconds_for(pilot_error)
    hi_err = hi_err if np.isfinite(hi_err) else pilot_error * 2
    # the seconds are not monotonic in the error (whole passes: a larger error can mean fewer, larger passes)
    bounds = (seconds_for(lo_err), seconds, seconds_for(hi_err))
    return CostEstimate(
        backend=name,
        target_error=target,
        samples=samples,
        passes=passes,
        seconds=seconds,
        seconds_range=(min(bounds), max(bounds)),
        pilot_samples=pilot_n,
        pilot_seconds=time.perf_counter() - t_start,
        pilot_error=pilot_error,
        seconds_per_sample=per_sample,
        seconds_per_pass=per_pass,
        kind="noise",
        reaches_target=reached,
        seconds_per_new_size=per_size,
        seconds_per_call=per_call,
    )
