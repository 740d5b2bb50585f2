"""``bf.crosscheck``: render one scene with every available backend at comparable settings (box filter, no
denoiser, no clamping unless asked for, fixed seed) and compare every pair at the tier that fits the pair and the scene.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.errors import (
    BackendUnavailableError,
    BlendifyError,
    InvalidSceneError,
    RenderError,
    UnsupportedFeatureError,
    exit_code,
    exit_code_epilog,
)
from blendify_core.evaluate.compare import compare
from blendify_core.evaluate.noise import DEFAULT_PASSES, combine_passes, pass_samples
from blendify_core.evaluate.progress import progress_bar
from blendify_core.evaluate.report import CompareReport, CrosscheckReport
from blendify_core.evaluate.stats import ReferenceEstimate
from blendify_core.evaluate.tiers import TIERS, _delta_lights, choose_tier, is_path_tracer
from blendify_core.ir.attachments import IR_LIMIT_PREFIX
from blendify_core.ir.scene import Scene
from blendify_core.ir.validate import strict_arguments
from blendify_core.pipeline.render import render
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import ENGINE_LIMIT_PREFIX, ENGINE_ONLY_PREFIX, _outputs
from blendify_core.registry import available_backends, backend_names

__all__ = ["crosscheck", "crosscheck_main"]


@strict_arguments
def crosscheck(
    scene: Scene,
    backends: Sequence[str] = ("cycles", "mitsuba", "pyrender"),
    outputs: Sequence[str] = ("rgb", "depth", "normal", "albedo", "instance"),
    samples: int | None = 256,
    tier: str | Mapping[str, Mapping[str, float]] | None = None,
    seed: int = 0,
    backend_options: Mapping[str, Mapping[str, Any]] | None = None,
    scene_name: str = "scene",
    repeats: int = 1,
    progress: bool | None = None,
    passes: int = DEFAULT_PASSES,
    **settings: Any,
) -> CrosscheckReport:
    """Render ``scene`` with each of ``backends`` and compare every pair.

    Comparable settings are forced: box pixel filter, no denoiser, no adaptive sampling, seed ``seed``,
    ``samples`` samples per pixel; no clamping and no Filter Glossy unless asked for; ``settings`` may
    override other RenderSettings fields (e.g. ``max_bounces``, the per-kind bounce limits). A biased setting
    (clamp, Filter Glossy, per-kind bounce limits) one engine applies and the other cannot makes that pair
    limited by the engine (``report.limited``, with the settings): neither passed nor failed; an attached
    file's IR parse does the same for what it could not carry (limited by the IR).
    ``backend_options``: per-backend options (``{"mitsuba": {"variant": ...}}``).
    ``tier``: None = per pair by :func:`choose_tier` (path tracer pair on delta lights and diffuse
    materials -> "pathtracer_delta", other path tracer pairs -> "pathtracer", with a rasteriser ->
    "raster"), or a tier name / dict for every pair. Unavailable backends are skipped with their reason;
    outputs a backend does not support are dropped for that backend (noted in ``report.notes``); a
    backend whose render raises is reported in ``report.errors`` (and the report does not pass).
    Pairs (a, b) follow the order of ``backends``; the later backend is the reference b.

    ``passes`` (default 4): each path tracer splits its ``samples`` into ``passes`` independent passes
    (seeds ``seed``, ``seed + 1``, ...; about the cost of one render); its colour is their mean and
    ``result.rgb_var`` the variance of that mean, so every path-tracer pair gets the noise-aware colour
    verdict (:mod:`blendify_core.evaluate.noise`: passes when the engines agree within noise up to a small
    margin, fails on a bias) instead of fixed colour tolerances. ``passes=1``: one render, fixed tolerances.

    ``repeats`` (>= 2; instead of ``passes``): each path tracer renders the scene ``repeats`` times with seeds ``seed``,
    ``seed + 1``, ...; its colour becomes the mean of the renders (geometry from the first), its mean and
    variance estimate go to ``report.estimates``, and every path-tracer pair also gets a two-sample
    statistical test (:meth:`ReferenceEstimate.compare`) in ``report.ztests``, which must pass too: are
    the two engines' expected images equal, given their noise?

    ``progress``: a progress bar over the renders (None: only on a terminal or in a notebook; see
    :mod:`blendify_core.evaluate.progress`).
    """
    backends, outs = _checked_arguments(scene, backends, outputs, settings, repeats)
    if not isinstance(passes, (int, np.integer)) or passes < 1:
        raise InvalidSceneError(f"passes: expected a positive integer, got {passes!r}")
    renders = _Renders(scene, samples, seed, repeats, settings, dict(backend_options or {}), passes=int(passes))
    status = available_backends()
    usable = []
    for name in backends:
        st = status.get(name)
        if st is None:
            renders.skipped[name] = f"not registered (registered: {sorted(status)})"
        elif not st.available:
            renders.skipped[name] = st.reason or "unavailable"
        else:
            usable.append(name)
    renders.bar = progress_bar(sum(renders.planned(n) for n in usable), "crosscheck", progress)
    try:
        for name in usable:
            renders.render(name, list(outs))
    finally:
        renders.bar.close()
    names = list(renders.results)
    n_pt = sum(is_path_tracer(n) for n in names)
    if (
        n_pt >= 1
        and passes < 2
        and samples is not None
        and samples * max(repeats, 1) < 128
        and not _delta_lights(scene)
    ):
        renders.notes.append(
            f"samples={samples}: the colour tiers for area/sky light were measured at 256 spp; at fewer samples "
            "Monte-Carlo noise alone may fail them (use more samples, or repeats=k for the statistical test)"
        )
    pairs = _compare_pairs(scene, renders.results, tier)
    limited = _limited(renders.results, pairs)
    limited_reports = {k: pairs.pop(k) for k in limited}
    estimates = renders.estimates
    ztests = {(a, b): estimates[a].compare(estimates[b]) for (a, b) in pairs if a in estimates and b in estimates}
    used_settings: dict[str, Any] = {"samples": samples, "seed": seed, **FIXED_SETTINGS, **settings}
    if repeats > 1:
        used_settings["repeats"] = repeats
    elif passes > 1:
        used_settings["passes"] = passes
    return CrosscheckReport(
        results=renders.results,
        pairs=pairs,
        skipped=renders.skipped,
        errors=renders.errors,
        notes=renders.notes,
        settings=used_settings,
        scene_name=scene_name,
        estimates=estimates,
        ztests=ztests,
        limited=limited,
        limited_reports=limited_reports,
    )


def _limited(results: Mapping[str, RenderResult], pairs: Mapping[tuple[str, str], Any]) -> dict[Any, list[str]]:
    """Pairs limited by the IR or by the engine, with what makes them differ rather than the engines' light
    transport: the ``meta["approximations"]`` lines only one side lists among

    - ``IR parse of ...``: one side renders an attached file itself, the other its IR parse, which could
      not carry these items;
    - ``setting the engine cannot apply: ...``: a biased render setting (clamp, Filter Glossy, per-kind bounce
      limits) one side applies and the other engine cannot (``Backend.unapplied_settings``);
    - ``setting only one engine applies: <backend>: ...``: a setting of one engine's own (its
      ``meta["engine_only_settings"]``: Cycles' ``cycles_settings`` such as caustics off or film exposure)."""

    def limits(name: str) -> set[str]:
        meta = results[name].meta if isinstance(results[name].meta, dict) else {}
        approx = meta.get("approximations", [])
        only = [f"{ENGINE_ONLY_PREFIX}{name}: {x}" for x in meta.get("engine_only_settings", [])]
        return {a for a in approx if isinstance(a, str) and a.startswith(_LIMIT_PREFIXES)} | set(only)

    out = {}
    for a, b in pairs:
        differ = limits(a) ^ limits(b)
        if differ:
            out[(a, b)] = sorted(differ)
    return out


_LIMIT_PREFIXES = (IR_LIMIT_PREFIX, ENGINE_LIMIT_PREFIX)


#: settings crosscheck fixes so that the backends' images are comparable
FIXED_SETTINGS: dict[str, Any] = {
    "pixel_filter": "box",
    "pixel_filter_width": 1.0,
    "denoise": False,
    "clamp_direct": 0.0,
    "clamp_indirect": 0.0,
    "filter_glossy": 0.0,
    "adaptive": False,
}
#: biased settings a crosscheck may be asked for (e.g. an attached .blend's own ``render_settings``): an engine
#: that cannot apply one (``Backend.unapplied_settings``) makes its pairs with an engine that can limited by
#: the engine (``report.limited``), neither passed nor failed
BIASED_SETTINGS = ("clamp_direct", "clamp_indirect", "filter_glossy")


def _checked_arguments(
    scene: object,
    backends: Sequence[str] | str,
    outputs: Sequence[str] | str,
    settings: Mapping[str, object],
    repeats: object,
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The backends and the validated outputs; errors for a bad scene, backend list, setting or repeats."""
    if not isinstance(scene, Scene):
        raise InvalidSceneError(f"scene: expected a blendify_core.Scene, got {type(scene).__name__}")
    if isinstance(backends, str):
        backends = (backends,)
    if not backends or len(set(backends)) != len(backends):
        raise InvalidSceneError(f"backends: expected a non-empty sequence of distinct names, got {backends!r}")
    forbidden = (set(FIXED_SETTINGS) - set(BIASED_SETTINGS)) & set(settings)
    if forbidden:
        raise InvalidSceneError(
            f"crosscheck: {sorted(forbidden)} are fixed by crosscheck (1 px box filter, no denoiser or adaptive "
            "sampling)"
        )
    outs = _outputs(outputs if isinstance(outputs, str) else tuple(outputs))  # bad names: error up front
    if not isinstance(repeats, (int, np.integer)) or repeats < 1:
        raise InvalidSceneError(f"repeats: expected a positive integer, got {repeats!r}")
    return tuple(backends), outs


@dataclass
class _Renders:
    """Renders every backend at the comparable settings; what each rendered, skipped or failed at."""

    scene: Scene
    samples: int | None
    seed: int
    repeats: int
    settings: dict[str, Any]
    backend_options: dict[str, Mapping[str, Any]]
    results: dict[str, RenderResult] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    errors: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    estimates: dict[str, ReferenceEstimate] = field(default_factory=dict)
    passes: int = DEFAULT_PASSES
    bar: Any = None  # the progress bar (crosscheck sets it)
    done: int = 0  # renders made

    def planned(self, name: str) -> int:
        """How many renders backend ``name`` is planned to make."""
        return self.renders_of(name)

    def renders_of(self, name: str) -> int:
        """Renders of backend ``name``: ``repeats`` or ``passes`` for a path tracer, else 1."""
        if not is_path_tracer(name):
            return 1
        return self.repeats if self.repeats > 1 else self.passes

    def samples_of(self, name: str) -> int | None:
        """Samples per render of backend ``name`` (``samples`` split over the passes of a path tracer)."""
        if self.repeats > 1 or not is_path_tracer(name):
            return self.samples
        return pass_samples(self.samples, self.passes)

    def _render(self, name: str, seed: int, outputs: tuple[str, ...]) -> RenderResult:
        if self.bar is not None:
            self.bar.set_postfix_str(f"{name} seed {seed}")
        result = render(
            self.scene,
            backend=name,
            samples=self.samples_of(name),
            seed=seed,
            outputs=outputs,
            **{**FIXED_SETTINGS, **self.settings},
            **dict(self.backend_options.get(name, {})),
        )
        self.done += 1
        if self.bar is not None:
            self.bar.update(1)
        return result

    def render(self, name: str, outs: list[str]) -> None:
        """Render with backend ``name``, dropping outputs it does not support (noted) and, for a path
        tracer with ``repeats`` > 1, averaging the colour of the repeats."""
        before = self.done
        try:
            self._render_all(name, outs)
        finally:
            if self.bar is not None:  # a skipped or failed backend: its planned renders count as done
                self.bar.update(max(self.planned(name) - (self.done - before), 0))

    def _render_all(self, name: str, outs: list[str]) -> None:
        while True:
            try:
                self.results[name] = result = self._render(name, self.seed, tuple(outs))
                k = self.renders_of(name)
                if k > 1 and result.rgba is not None:
                    extra = [self._render(name, self.seed + i, ("rgb",)) for i in range(1, k)]
                    if self.repeats > 1:
                        self.estimates[name] = _repeats_estimate(result, extra, self.samples)
                    combine_passes(result, extra)
                return
            except UnsupportedFeatureError as exc:
                feat = getattr(exc, "feature", None) or ""
                if feat.startswith("output.") and feat[7:] in outs and len(outs) > 1:
                    outs.remove(feat[7:])
                    self.notes.append(f"{name}: output {feat[7:]!r} unsupported, not compared ({exc})")
                    continue
                self.skipped[name] = f"unsupported: {exc}"
                return
            except BackendUnavailableError as exc:
                self.skipped[name] = str(exc)
                return
            except (RenderError, InvalidSceneError) as exc:
                self.errors[name] = f"{type(exc).__name__}: {exc}"
                return


def _compare_pairs(
    scene: Scene, results: dict[str, RenderResult], tier: str | Mapping[str, Mapping[str, float]] | None
) -> dict[tuple[str, str], CompareReport]:
    """Every pair (a, b) in the order of ``results``; b is the reference."""
    pairs: dict[tuple[str, str], CompareReport] = {}
    names = list(results)
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            a, b = names[i], names[j]
            t = tier if tier is not None else choose_tier(a, b, scene)
            pairs[(a, b)] = compare(results[a], results[b], tier=t, names=(a, b))
    return pairs


def _repeats_estimate(first: RenderResult, extra: list[RenderResult], samples: int | None) -> ReferenceEstimate:
    """The ReferenceEstimate of the colour of all repeats (``first`` records their number)."""
    stack = [r.rgba for r in [first, *extra] if r.rgba is not None]
    est = ReferenceEstimate.from_images([x[..., :3] for x in stack], int(samples or 1))
    first.meta["repeats"] = len(stack)
    return est


def crosscheck_main(
    argv: Sequence[str] | None = None, parser_class: type[argparse.ArgumentParser] = argparse.ArgumentParser
) -> int:
    """``blendify crosscheck SCENE [-o FOLDER] [--backends ...] [--samples N] ...``: render a scene file
    with every available backend, write the contact sheet and the markdown report into FOLDER. Returns
    0 when every pair passed, 1 when one failed (or fewer than two backends could render), 2 on bad
    usage or a missing scene file, 3 when a backend asked for is unavailable (the ``blendify`` exit codes,
    :data:`blendify_core.errors.EXIT_CODES`)."""
    p = parser_class(
        prog="blendify crosscheck",
        description="Render a scene file with several backends and compare them pairwise.",
        epilog=exit_code_epilog(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("scene", help="scene file written by Scene.save (.npz)")
    p.add_argument("-o", "--output", default="crosscheck_out", help="folder for the sheet and report")
    p.add_argument(
        "--backends",
        default="cycles,mitsuba,pyrender",
        help=f"comma-separated backend names from: {', '.join(backend_names())}",
    )
    p.add_argument("--outputs", default="rgb,depth,normal,albedo,instance", help="comma-separated outputs")
    p.add_argument("--samples", type=int, default=256, help="samples per pixel (default 256)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--tier", default=None, help=f"tier for every pair (default: per pair); one of {sorted(TIERS)}")
    p.add_argument("--max-bounces", type=int, default=None)
    p.add_argument(
        "--repeats",
        type=int,
        default=1,
        help="render each path tracer N times (seeds seed..seed+N-1) and add a statistical test per pair",
    )
    p.add_argument(
        "--passes",
        type=int,
        default=DEFAULT_PASSES,
        help=f"split each path tracer's samples into N independent passes for the noise-aware verdict "
        f"(default {DEFAULT_PASSES}; 1 = fixed tolerances)",
    )
    try:
        args = p.parse_args(list(argv) if argv is not None else None)
    except SystemExit as exc:  # argparse exits on --help / errors; turn that into a return code
        return int(exc.code or 0)
    try:
        scene = Scene.load(args.scene)
        extra = {} if args.max_bounces is None else {"max_bounces": args.max_bounces}
        t0 = time.perf_counter()
        report = crosscheck(
            scene,
            backends=tuple(b.strip() for b in args.backends.split(",") if b.strip()),
            outputs=tuple(o.strip() for o in args.outputs.split(",") if o.strip()),
            samples=args.samples,
            seed=args.seed,
            tier=args.tier,
            scene_name=Path(args.scene).name,
            repeats=args.repeats,
            passes=args.passes,
            **extra,
        )
        folder = report.save(args.output)
    except (BlendifyError, OSError) as exc:
        sys.stderr.write(f"blendify crosscheck: error: {exc}\n")
        return exit_code(exc)
    sys.stdout.write(f"{report!r}\n")
    if not report.pairs:
        sys.stderr.write(
            "blendify crosscheck: fewer than two backends rendered the scene, nothing was compared "
            f"(skipped: {report.skipped or 'none'}; errors: {report.errors or 'none'})\n"
        )
    elapsed = time.perf_counter() - t0
    sys.stdout.write(f"wrote {folder / 'crosscheck.png'} and {folder / 'crosscheck.md'} ({elapsed:.1f} s)\n")
    return 0 if report.passed and report.pairs else 1
