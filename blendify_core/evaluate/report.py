"""Reports of comparisons: :class:`CompareReport` (one pair) and :class:`CrosscheckReport` (every pair of
backends), with summaries, contact sheets and saving.
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.evaluate.noise import NoiseTest
from blendify_core.evaluate.stats import ReferenceEstimate, ZTestResult
from blendify_core.io.output import atomic_write, ensure_folder
from blendify_core.ir.colorspace import linear_to_srgb
from blendify_core.ir.validate import strict_api
from blendify_core.pipeline.result import RenderResult, depth_to_image, instance_to_image
from blendify_core.pipeline.settings import ENGINE_LIMIT_PREFIX, ENGINE_ONLY_PREFIX

__all__ = ["CompareReport", "CrosscheckReport"]


# ---------------------------------------------------------------------------------------------------
# the report
# ---------------------------------------------------------------------------------------------------
def _fmt(v: float) -> str:
    if isinstance(v, float) and math.isnan(v):
        return "nan"
    if isinstance(v, float) and math.isinf(v):
        return "inf"
    if float(v).is_integer() and abs(v) < 1e9:
        return str(int(v))
    return f"{v:.4g}"


@strict_api
@dataclass
class CompareReport:
    """Result of :func:`compare` (``b`` is the reference).

    ``metrics``: output -> metric -> float; ``tier``: the tier's name; ``thresholds``: output -> metric ->
    threshold actually applied; ``passed``; ``failures``: readable strings; ``checks``: every applied
    check as (output, metric, value, op, threshold, ok); ``diff_images``: output -> (H, W, 3) uint8 heat
    map; ``legends``: output -> what the colours mean; ``names``: labels of a and b.
    """

    metrics: dict[str, dict[str, float]]
    tier: str
    thresholds: dict[str, dict[str, float]]
    passed: bool
    failures: list[str]
    checks: list[tuple[str, str, float, str, float, bool]]
    diff_images: dict[str, np.ndarray] = field(repr=False)
    legends: dict[str, str] = field(default_factory=dict, repr=False)
    names: tuple[str, str] = ("a", "b")
    notes: list[str] = field(default_factory=list)
    #: the compared results (a, b), kept so :meth:`save` can write them next to the diff maps
    results: tuple[RenderResult, RenderResult] | None = field(default=None, repr=False, compare=False)
    #: the noise-aware colour test (both results carried ``rgb_var``), else None
    noise: NoiseTest | None = field(default=None, repr=False, compare=False)

    def summary(self) -> str:
        """Markdown: verdict, failures, and a table of every metric with its threshold."""
        a, b = self.names
        lines = [
            f"### {a} vs {b} (reference): {'PASS' if self.passed else 'FAIL'} at tier `{self.tier}`",
            "",
        ]
        for f in self.failures:
            lines.append(f"- FAIL: {f}")
        for n in self.notes:
            lines.append(f"- note: {n}")
        if self.failures or self.notes:
            lines.append("")
        lines += ["| output | metric | value | threshold |", "|---|---|---|---|"]
        limits = {(o, k): (op, t, ok) for o, k, _, op, t, ok in self.checks}
        for out, ms in self.metrics.items():
            for k, v in ms.items():
                lim = limits.get((out, k))
                th = "" if lim is None else f"{lim[0]} {_fmt(lim[1])}{'' if lim[2] else ' **FAIL**'}"
                lines.append(f"| {out} | {k} | {_fmt(v)} | {th} |")
        return "\n".join(lines) + "\n"

    def save(self, folder: str | os.PathLike[str]) -> Path:
        """Write ``diff_<output>.png`` for every output, the compared images (``a_<output>.png`` and
        ``b_<output>.png``, 8-bit previews), ``report.md`` and ``metrics.json`` into ``folder`` (created if
        needed); returns the folder. Each file is written atomically with the usual file mode; a file that
        cannot be written raises :class:`~blendify_core.errors.OutputError` naming it."""
        from PIL import Image

        out = ensure_folder(folder, arg="folder")
        for name, img in self.diff_images.items():
            atomic_write(
                out / f"diff_{name}.png",
                lambda tmp, img=img: Image.fromarray(img).save(tmp, format="PNG"),
                arg="folder",
            )
        if self.results is not None:
            for label, r in zip(("a", "b"), self.results):
                for o in self.diff_images:
                    if (
                        o in ("rgb", "depth", "normal", "albedo", "instance")
                        and getattr(r, "rgba" if o == "rgb" else o) is not None
                    ):
                        r.save(out / f"{label}_{o}.png", output=o)
        legend = "\n".join(f"- `diff_{k}.png`: {v}" for k, v in self.legends.items())
        _write_text(out / "report.md", self.summary() + "\nDiff images:\n\n" + legend + "\n")
        _write_text(
            out / "metrics.json",
            json.dumps(
                {"tier": self.tier, "passed": self.passed, "failures": self.failures, "metrics": _json(self.metrics)},
                indent=1,
            ),
        )
        return out

    def contact_sheet(self, tile: int = 160) -> np.ndarray:
        """(H, W, 3) uint8 labelled sheet: one column per compared output; a row for each compared result
        (when the report keeps them) and a row of heat maps, each marked ok/FAIL against the tier."""
        rows: list[tuple[str, list[tuple[str, np.ndarray]]]] = []
        if self.results is not None:
            for label, r in zip(self.names, self.results):
                row = [(o, img) for o in self.diff_images if (img := _output_tile(r, o)) is not None]
                rows.append((label, row))
        diffs = [(f"{o} diff: {'ok' if _output_ok(self, o) else 'FAIL'}", img) for o, img in self.diff_images.items()]
        rows.append((f"{self.tier}\n{'PASS' if self.passed else 'FAIL'}", diffs))
        return _draw_sheet(rows, tile)

    def _repr_png_(self) -> bytes:
        """The contact sheet (notebooks show it when they cannot show HTML)."""
        return _png(self.contact_sheet())

    def _repr_html_(self) -> str:
        """The verdict, failures, notes, the metric table and the contact sheet (shown by notebooks)."""
        a, b = self.names
        colour = _GREEN if self.passed else _RED
        parts = [
            f"<div><b>{html.escape(a)} vs {html.escape(b)} (reference): "
            f'<span style="color:{colour}">{"PASS" if self.passed else "FAIL"}</span></b> at tier '
            f"<code>{html.escape(self.tier)}</code></div>",
            _html_list([f"FAIL: {f}" for f in self.failures] + [f"note: {n}" for n in self.notes]),
            _metric_table(self),
            _html_image(self.contact_sheet()),
        ]
        return "<div>" + "".join(parts) + "</div>"

    def __repr__(self) -> str:
        head = f"CompareReport({self.names[0]} vs {self.names[1]}: {'PASS' if self.passed else 'FAIL'}"
        text = f"{head} at tier {self.tier!r}; " + _key_metrics(self)
        if self.failures:
            text += "; failures: " + "; ".join(self.failures)
        return text + ")"


def _json(metrics: Mapping[str, Mapping[str, float]]) -> dict[str, dict[str, Any]]:
    return {
        o: {k: (v if isinstance(v, float) and math.isfinite(v) else str(v)) for k, v in ms.items()}
        for o, ms in metrics.items()
    }


# ---------------------------------------------------------------------------------------------------
# crosscheck
# ---------------------------------------------------------------------------------------------------
def _limited_heading(items: Sequence[str]) -> str:
    """The summary heading of a limited pair: by the IR, by the engine, or both."""
    engine = any(x.startswith((ENGINE_LIMIT_PREFIX, ENGINE_ONLY_PREFIX)) for x in items)
    ir = any(not x.startswith((ENGINE_LIMIT_PREFIX, ENGINE_ONLY_PREFIX)) for x in items)
    if engine and not ir:
        return "LIMITED BY THE ENGINE (not judged); render settings only one engine applies:"
    if engine:
        return (
            "LIMITED BY THE IR AND THE ENGINE (not judged); what the IR parse could not carry and the render "
            "settings only one engine applies:"
        )
    return "LIMITED BY THE IR (not judged); the IR parse could not carry:"


@strict_api
@dataclass
class CrosscheckReport:
    """Result of :func:`crosscheck`: ``results`` backend -> RenderResult, ``pairs`` (a, b) ->
    CompareReport (b is the reference), ``skipped`` backend -> reason, ``errors`` backend -> message of
    a failed render, ``notes`` free-form remarks (outputs dropped because a backend lacks them, ...)."""

    results: dict[str, RenderResult]
    pairs: dict[tuple[str, str], CompareReport]
    skipped: dict[str, str]
    errors: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    settings: dict[str, Any] = field(default_factory=dict)
    scene_name: str = "scene"
    #: backend -> ReferenceEstimate of its colour (``crosscheck(repeats=k)``, path tracers only)
    estimates: dict[str, ReferenceEstimate] = field(default_factory=dict, repr=False)
    #: (a, b) -> ZTestResult of the two-sample test between two path tracers' estimates
    ztests: dict[tuple[str, str], ZTestResult] = field(default_factory=dict)
    #: pairs limited by the IR or by the engine -> what makes them differ: the items the IR parse of an
    #: attached file could not carry (one side renders the file itself, the other its parse; lines starting
    #: ``IR parse of``) and the biased render settings one side applies and the other engine cannot (lines
    #: starting ``setting the engine cannot apply:``); neither passed nor failed (their comparisons in
    #: ``limited_reports``)
    limited: dict[tuple[str, str], list[str]] = field(default_factory=dict)
    limited_reports: dict[tuple[str, str], CompareReport] = field(default_factory=dict, repr=False)

    @property
    def passed(self) -> bool:
        """Every pair passed its tier (and its statistical test, with ``repeats``), no available backend
        failed to render, and at least one pair was compared (nothing compared proves nothing)."""
        return (
            not self.errors
            and bool(self.pairs)
            and all(r.passed for r in self.pairs.values())
            and all(z.passed for k, z in self.ztests.items() if k not in self.limited)
        )

    def summary(self) -> str:
        """Markdown report: settings, per-backend timings, skipped backends, pair verdicts and metrics."""
        lines = [f"## Crosscheck of {self.scene_name}: {'PASS' if self.passed else 'FAIL'}", ""]
        if self.settings:
            lines.append("Settings: " + ", ".join(f"`{k}={v}`" for k, v in self.settings.items()))
            lines.append("")
        lines += ["| backend | status | render time (s) |", "|---|---|---|"]
        for name, r in self.results.items():
            t = r.meta.get("timings", {}) if isinstance(r.meta, dict) else {}
            total = sum(v for v in t.values() if isinstance(v, (int, float)))
            lines.append(f"| {name} | rendered | {total:.2f} |")
        for name, why in self.skipped.items():
            lines.append(f"| {name} | skipped: {why} | |")
        for name, why in self.errors.items():
            lines.append(f"| {name} | ERROR: {why} | |")
        lines.append("")
        for n in self.notes:
            lines.append(f"- {n}")
        if self.notes:
            lines.append("")
        for (a, b), z in self.ztests.items():
            verdict = "consistent" if z.passed else "DIFFERENT"
            lines.append(
                f"- statistical test {a} vs {b} ({self.settings.get('repeats')} renders each): **{verdict}**; "
                f"{z.n_reject} pixel-channels and {z.n_tile_reject}/{z.n_tiles} tiles reject, "
                f"global p = {z.global_p:.3g}" + (f" ({'; '.join(z.reasons)})" if z.reasons else "")
            )
        if self.ztests:
            lines.append("")
        for rep in self.pairs.values():
            lines.append(rep.summary())
        for (a, b), items in self.limited.items():
            lines.append(f"### {a} vs {b}: {_limited_heading(items)}")
            lines += [f"- {x}" for x in items] + [""]
        return "\n".join(lines)

    def __repr__(self) -> str:
        pairs = ", ".join(
            [f"{a}/{b}: {'PASS' if r.passed else 'FAIL'}" for (a, b), r in self.pairs.items()]
            + [f"{a}/{b}: LIMITED" for (a, b) in self.limited]
        )
        skipped = ", ".join(self.skipped) or "none"
        return f"CrosscheckReport({self.scene_name}: {pairs or 'no pairs'}; skipped: {skipped})"

    def contact_sheet(self, tile: int = 160) -> np.ndarray:
        """(H, W, 3) uint8 labelled sheet: one row per backend (colour over a checkerboard, depth, normal,
        albedo, instance ids) and one row per pair (the heat maps of every compared output, each tile
        marked ok/FAIL against the pair's tier). Tiles are scaled (nearest) to ``tile`` px wide."""
        rows: list[tuple[str, list[tuple[str, np.ndarray]]]] = []
        for name, r in self.results.items():
            row = [
                (o, img)
                for o in ("rgb", "depth", "normal", "albedo", "instance")
                if (img := _output_tile(r, o)) is not None
            ]
            rows.append((name, row))
        for (a, b), rep in self.pairs.items():
            row = [
                (f"{out} diff: {'ok' if _output_ok(rep, out) else 'FAIL'}", img) for out, img in rep.diff_images.items()
            ]
            verdict = "PASS" if rep.passed else "FAIL"
            rows.append((f"{a}\nvs {b}\n{rep.tier}\n{verdict}", row))
        return _draw_sheet(rows, tile)

    def _repr_png_(self) -> bytes:
        """The contact sheet (notebooks show it when they cannot show HTML)."""
        return _png(self.contact_sheet())

    def _repr_html_(self) -> str:
        """The verdict, a table of the backends (rendered, skipped, failed), a table of the pairs' verdicts
        with their key metrics, the notes and the contact sheet (shown by notebooks)."""
        colour = _GREEN if self.passed else _RED
        parts = [
            f"<div><b>Crosscheck of {html.escape(self.scene_name)}: "
            f'<span style="color:{colour}">{"PASS" if self.passed else "FAIL"}</span></b></div>'
        ]
        if self.settings:
            parts.append(
                "<div>Settings: "
                + ", ".join(f"<code>{html.escape(f'{k}={v}')}</code>" for k, v in self.settings.items())
                + "</div>"
            )
        backends = [("backend", "status", "render time (s)")]
        for name, r in self.results.items():
            t = r.meta.get("timings", {}) if isinstance(r.meta, dict) else {}
            backends.append((name, "rendered", f"{sum(v for v in t.values() if isinstance(v, (int, float))):.2f}"))
        backends += [(name, f"skipped: {why}", "") for name, why in self.skipped.items()]
        backends += [(name, f"ERROR: {why}", "") for name, why in self.errors.items()]
        parts.append(_html_table(backends))
        if self.pairs:
            verdicts = [("a", "b (reference)", "tier", "verdict", "key metrics", "failures")]
            for (a, b), rep in self.pairs.items():
                z = self.ztests.get((a, b))
                fails = list(rep.failures) + ([] if z is None or z.passed else ["statistical test: DIFFERENT"])
                verdicts.append(
                    (
                        a,
                        b,
                        rep.tier,
                        "PASS" if rep.passed and (z is None or z.passed) else "FAIL",
                        _key_metrics(rep),
                        "; ".join(fails),
                    )
                )
            parts.append(_html_table(verdicts, verdict_column=3))
        parts.append(_html_list(self.notes))
        parts.append(_html_image(self.contact_sheet()))
        return "<div>" + "".join(parts) + "</div>"

    def save(self, folder: str | os.PathLike[str], name: str = "crosscheck") -> Path:
        """Write ``<name>.png`` (contact sheet), ``<name>.md`` (report) and per-pair diff folders, each file
        atomically with the usual file mode (:class:`~blendify_core.errors.OutputError` when one cannot be
        written)."""
        from PIL import Image

        out = ensure_folder(folder, arg="folder")
        sheet = self.contact_sheet()
        atomic_write(out / f"{name}.png", lambda tmp: Image.fromarray(sheet).save(tmp, format="PNG"), arg="name")
        _write_text(out / f"{name}.md", f"![contact sheet]({name}.png)\n\n" + self.summary(), arg="name")
        for (a, b), rep in self.pairs.items():
            rep.save(out / f"{a}_vs_{b}")
        return out


def _write_text(path: Path, text: str, arg: str = "folder") -> None:
    """A report file, atomically (UTF-8)."""

    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)

    atomic_write(path, write, arg=arg)


def _output_ok(rep: CompareReport, out: str) -> bool:
    return all(ok for o, _, _, _, _, ok in rep.checks if o == out)


def _over_checker(r: RenderResult) -> np.ndarray:
    """sRGB of a premultiplied render over a light checkerboard (so transparency is visible)."""
    rgba = r.rgba.astype(np.float64)  # type: ignore[union-attr]
    h, w = rgba.shape[:2]
    cb = ((np.indices((h, w)) // 4).sum(axis=0) % 2) * 0.15 + 0.6
    lin = rgba[..., :3] + (1 - rgba[..., 3:4]) * cb[..., None] ** 2.2
    return np.round(linear_to_srgb(lin) * 255).astype(np.uint8)


_GREEN, _RED = "#067d17", "#b00020"
#: the metric shown for each output in one-line summaries
_KEY_METRICS = (
    ("rgb", "mean_rel_error"),
    ("rgb", "noise_global_rel_diff"),
    ("rgb", "noise_tiles_rejected"),
    ("depth", "rel_diff_q99"),
    ("mask", "iou"),
    ("normal", "angle_q99_deg"),
    ("instance", "agreement"),
    ("albedo", "mean_rel_error"),
)


def _key_metrics(rep: CompareReport) -> str:
    """``rgb.mean_rel_error=0.01, depth.rel_diff_q99=2e-05, ...`` for the outputs the report measured."""
    return ", ".join(
        f"{out}.{metric}={_fmt(rep.metrics[out][metric])}"
        for out, metric in _KEY_METRICS
        if metric in rep.metrics.get(out, {}) and not math.isnan(rep.metrics[out][metric])
    )


def _output_tile(r: RenderResult, output: str) -> np.ndarray | None:
    """(H, W, 3) uint8 view of one output of a result (None when the result has no such output)."""
    if output == "rgb":
        return None if r.rgba is None else _over_checker(r)
    if output == "mask":
        m = r.mask
        return None if m is None else np.repeat((m.astype(np.uint8) * 255)[..., None], 3, axis=-1)
    data = getattr(r, output, None) if output in ("depth", "normal", "albedo", "instance") else None
    if data is None:
        return None
    if output == "depth":
        return np.repeat(depth_to_image(data)[..., None], 3, axis=-1)
    if output == "normal":
        return np.round(np.clip(data * 0.5 + 0.5, 0, 1) * 255).astype(np.uint8)
    if output == "albedo":
        return np.round(np.clip(linear_to_srgb(data), 0, 1) * 255).astype(np.uint8)
    return instance_to_image(data)


def _draw_sheet(rows: list[tuple[str, list[tuple[str, np.ndarray]]]], tile: int) -> np.ndarray:
    """Rows of labelled tiles (scaled, nearest, to ``tile`` px wide) under a row heading each."""
    from PIL import Image, ImageDraw

    if not any(row for _, row in rows):
        return np.zeros((32, 32, 3), dtype=np.uint8)
    h0, w0 = next(img for _, row in rows for _, img in row).shape[:2]
    tw = max(int(tile), 16)
    th = max(int(round(h0 * tw / max(w0, 1))), 1)
    label_h, pad, head_w = 14, 4, 110
    ncols = max(len(row) for _, row in rows)
    width = head_w + ncols * (tw + pad) + pad
    height = len(rows) * (th + label_h + pad) + pad
    sheet = Image.new("RGB", (width, height), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for ri, (head, row) in enumerate(rows):
        y = pad + ri * (th + label_h + pad)
        colour = (180, 0, 0) if head.endswith("FAIL") else (0, 0, 0)
        draw.multiline_text((pad, y + label_h), head, fill=colour, spacing=2)
        for ci, (label, img) in enumerate(row):
            x = head_w + ci * (tw + pad)
            im = Image.fromarray(np.ascontiguousarray(img[..., :3])).resize((tw, th), Image.Resampling.NEAREST)
            sheet.paste(im, (x, y + label_h))
            draw.text((x + 1, y + 1), label, fill=(180, 0, 0) if label.endswith("FAIL") else (0, 0, 0))
    return np.asarray(sheet)


def _png(image: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG")
    return buf.getvalue()


def _html_image(image: np.ndarray) -> str:
    data = base64.b64encode(_png(image)).decode("ascii")
    return f'<img src="data:image/png;base64,{data}" style="max-width:100%;image-rendering:pixelated"/>'


def _html_list(items: list[str]) -> str:
    if not items:
        return ""
    return "<ul>" + "".join(f"<li>{html.escape(i)}</li>" for i in items) + "</ul>"


def _html_table(rows: Sequence[tuple[str, ...]], verdict_column: int | None = None) -> str:
    """The first row is the header; cells are escaped; the verdict column is coloured PASS/FAIL."""
    head, *body = rows
    out = ["<table><thead><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr></thead><tbody>"]
    for row in body:
        cells = []
        for i, cell in enumerate(row):
            style = ""
            if i == verdict_column:
                style = f' style="color:{_GREEN if cell == "PASS" else _RED};font-weight:bold"'
            cells.append(f"<td{style}>{html.escape(str(cell))}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    return "".join(out) + "</tbody></table>"


def _metric_table(rep: CompareReport) -> str:
    """Every metric with the threshold applied to it (failed checks in red)."""
    limits = {(o, k): (op, t, ok) for o, k, _, op, t, ok in rep.checks}
    out = ["<table><thead><tr><th>output</th><th>metric</th><th>value</th><th>threshold</th></tr></thead><tbody>"]
    for o, ms in rep.metrics.items():
        for k, v in ms.items():
            lim = limits.get((o, k))
            th = "" if lim is None else f"{lim[0]} {_fmt(lim[1])}"
            style = "" if lim is None or lim[2] else f' style="color:{_RED};font-weight:bold"'
            out.append(
                f"<tr{style}><td>{html.escape(o)}</td><td>{html.escape(k)}</td><td>{_fmt(v)}</td>"
                f"<td>{html.escape(th)}</td></tr>"
            )
    return "".join(out) + "</tbody></table>"
