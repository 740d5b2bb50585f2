"""Measure how far the backends agree on the canonical scenes and write docs/crosscheck.md.

Renders every scene of tests/crossbackend/xb_canonical.py with every available backend through
``bf.crosscheck`` (box filter, no denoiser, no clamping, seed 0), compares every pair at the tier
``choose_tier`` picks, and writes:

- docs/img/crosscheck_<scene>.png: the contact sheet (renders, depth, normals, albedo, ids, diff maps)
- docs/crosscheck.md: the tiers, the measured agreement table, marker-centroid errors, the noise-aware
  verdict and its calibration (copied from benchmarks/results/crosscheck_calibration.md, written by
  benchmarks/crosscheck_calibration.py), the third-party scenes (tests/third_party), the statistical
  (Z-test) checks, and which backends were unavailable.

Usage: ``uv run --no-sync python benchmarks/crosscheck_report.py [--scenes a,b] [--out docs]``
"""

from __future__ import annotations

import argparse
import datetime as dt
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np
from scipy.stats import norm

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "crossbackend"))
sys.path.insert(0, str(ROOT / "tests" / "third_party" / "scenes"))

from ports import PORTS  # noqa: E402
from test_xb_canonical import KNOWN  # noqa: E402
from test_xb_third_party import KNOWN_THIRD_PARTY  # noqa: E402
from xb_canonical import CANONICAL  # noqa: E402

import blendify_core as bf  # noqa: E402
from blendify_core.evaluate.metrics import alpha_centroids  # noqa: E402
from blendify_core.evaluate.stats import ReferenceEstimate  # noqa: E402
from blendify_core.evaluate.tiers import TIER_NOTES, TIERS  # noqa: E402
from blendify_core.testing import marker_scene, plane_scene  # noqa: E402

BACKENDS = ("cycles", "mitsuba", "pyrender")
COLUMNS = [
    ("rgb", "mean_rel_error_interior", "rgb rel (interior)"),
    ("rgb", "mean_rel_error", "rgb rel (all)"),
    ("rgb", "mean_ratio", "rgb ratio"),
    ("rgb", "ssim", "SSIM"),
    ("rgb", "noise_global_rel_diff", "noise: image rel"),
    ("rgb", "noise_tiles_rejected", "noise: tiles rej"),
    ("rgb", "flip", "FLIP"),
    ("depth", "rel_diff_q99", "depth q99"),
    ("mask", "n_disagree", "mask diff px"),
    ("mask", "n_disagree_interior", "interior"),
    ("normal", "angle_q99_deg", "normal q99 deg"),
    ("instance", "agreement", "id agree"),
    ("albedo", "mean_rel_error", "albedo rel"),
]


def fmt(v: float | None) -> str:
    if v is None:
        return "–"
    if isinstance(v, float) and math.isnan(v):
        return "n/a"
    if float(v).is_integer():
        return str(int(v))
    if abs(v) < 1e-3:
        return f"{v:.1e}"
    return f"{v:.4f}" if abs(v) < 10 else f"{v:.1f}"


def marker_centroids(status: dict) -> list[str]:
    """Alpha-weighted marker centroids vs the exact coverage centroid, per backend and camera."""
    from test_xb_markers import CASES, WINDOW, exact_centroids

    lines = [
        "| backend | camera | max error (px) | mean error (px) |",
        "|---|---|---|---|",
    ]
    for case, kw in CASES.items():
        scene, pixels = marker_scene(**kw)
        want = exact_centroids(scene, pixels)
        for b in BACKENDS:
            if not status[b].available:
                continue
            try:
                r = bf.render(scene, backend=b, samples=64, outputs=("rgb",), seed=0)
            except bf.UnsupportedFeatureError as exc:
                lines.append(f"| {b} | {case} | unsupported: {str(exc)[:80]} | |")
                continue
            err = np.linalg.norm(alpha_centroids(r, pixels, window=WINDOW) - want, axis=1)
            lines.append(f"| {b} | {case} | {err.max():.4f} | {err.mean():.4f} |")
    return lines


def statistical_checks(status: dict) -> list[str]:
    """Z-tests on real renders: each path tracer against its own K-render reference (must pass), and the
    two path tracers against each other (two-sample test)."""
    lines = []
    k, spp = 8, 16
    refs = {}
    for b in ("cycles", "mitsuba"):
        if not status[b].available:
            lines.append(f"- {b}: unavailable ({status[b].reason})")
            continue
        for light in ("area", "background"):
            scene = plane_scene(light)
            t0 = time.perf_counter()
            ref = ReferenceEstimate.from_images(
                [bf.render(scene, backend=b, samples=spp, seed=100 + i).rgb for i in range(k)], spp
            )
            refs[(b, light)] = ref
            test = bf.render(scene, backend=b, samples=spp, seed=999).rgb
            z = ref.z_test(test)
            biased = ref.z_test(test * 1.02)
            lines.append(
                f"- {b}, plane under {light} light, {k} x {spp} spp reference ({time.perf_counter() - t0:.1f} s): "
                f"a new seed **{'passes' if z.passed else 'FAILS'}** "
                f"({z.accept_fraction:.2%} pixel-channels accept, global p = {z.global_p:.2g}); "
                f"the same image x 1.02 **{'passes' if biased.passed else 'fails'}** "
                f"(global p = {biased.global_p:.2g}, {biased.n_tile_reject}/{biased.n_tiles} tiles reject)"
            )
    for light in ("area", "background"):
        if ("cycles", light) in refs and ("mitsuba", light) in refs:
            z = refs[("cycles", light)].compare(refs[("mitsuba", light)])
            lines.append(
                f"- Cycles vs Mitsuba (two-sample Welch test of two {k} x {spp} spp estimates), plane under {light} "
                f"light: **{'consistent' if z.passed else 'DIFFERENT'}** ({z.n_reject} pixel-channels reject, "
                f"{z.n_tile_reject} tiles reject, global p = {z.global_p:.2g}); reasons: {'; '.join(z.reasons) or '-'}"
            )
    return lines


STAT_SCENES = (
    "plane_point",
    "plane_area",
    "plane_background",
    "textured_quad",
    "markers",
    "faces_material",
    "fuze",
    "bunny",
    "primitives",
)


def statistical_crosscheck(status: dict, repeats: int = 4, spp: int = 64) -> list[str]:
    """``bf.crosscheck(repeats=...)`` between the two path tracers: are their expected images equal?"""
    if not (status["cycles"].available and status["mitsuba"].available):
        return ["Needs Cycles and Mitsuba (unavailable here)."]
    lines = [
        "| scene | verdict | pixel-channels rejecting | tiles rejecting | global z | colour ratio | time (s) |",
        "|---|---|---|---|---|---|---|",
    ]
    for name in STAT_SCENES:
        build = CANONICAL[name][0]
        t0 = time.perf_counter()
        rep = bf.crosscheck(build(), backends=("cycles", "mitsuba"), samples=spp, repeats=repeats, outputs=("rgb",))
        z = rep.ztests[("cycles", "mitsuba")]
        ratio = rep.pairs[("cycles", "mitsuba")].metrics["rgb"]["mean_ratio"]
        gz = float(norm.isf(max(z.global_p, 1e-300) / 2))
        lines.append(
            f"| {name} | {'consistent' if z.passed else '**different**'} | {z.n_reject} / {z.n_tests} | "
            f"{z.n_tile_reject} / {z.n_tiles} | {gz:.1f} | {ratio:.4f} | {time.perf_counter() - t0:.1f} |"
        )
    return lines


def third_party(out: Path) -> list[str]:
    """Every port of tests/third_party/scenes through ``bf.crosscheck`` (64 spp as 4 passes per path tracer):
    the Cycles/Mitsuba noise-aware verdict and pyrender's SSIM against Cycles."""
    from PIL import Image

    lines = [
        "| scene | licence | Cycles vs Mitsuba | image rel diff | tiles beyond margin | other failures | "
        "pyrender vs Cycles SSIM | time (s) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, port in PORTS.items():
        t0 = time.perf_counter()
        rep = bf.crosscheck(
            port.build(),
            backends=BACKENDS,
            samples=64,
            outputs=("rgb", "depth", "normal", "instance"),
            backend_options={"mitsuba": {"variant": "scalar_rgb"}},
            scene_name=name,
            progress=False,
        )
        elapsed = time.perf_counter() - t0
        print(f"{name}: {elapsed:.1f} s {rep!r}")
        Image.fromarray(rep.contact_sheet(tile=96)).save(out / "img" / f"crosscheck_tp_{name}.png")
        pm = rep.pairs.get(("cycles", "mitsuba"))
        pp = rep.pairs.get(("cycles", "pyrender"))
        ssim = fmt(pp.metrics["rgb"].get("ssim")) if pp is not None else "–"
        if pm is None or pm.noise is None:
            lines.append(f"| {name} | {port.licence} | not compared | | | | {ssim} | {elapsed:.1f} |")
            continue
        other = [f.split(" (tier")[0] for f in pm.failures if not f.startswith("rgb.noise")]
        verdict = "pass" if pm.passed else "FAIL" + (" (known)" if name in KNOWN_THIRD_PARTY else "")
        rel = fmt(pm.metrics["rgb"]["noise_global_rel_diff"])
        lines.append(
            f"| [{name}](img/crosscheck_tp_{name}.png) | {port.licence} | {verdict} (`{pm.tier}`) | {rel} | "
            f"{pm.noise.n_tile_reject} / {pm.noise.n_tiles} | {'; '.join(other) or '-'} | {ssim} | {elapsed:.1f} |"
        )
    return lines


def calibration() -> list[str]:
    """The calibration table and plot written by benchmarks/crosscheck_calibration.py (not re-run here)."""
    md = ROOT / "benchmarks" / "results" / "crosscheck_calibration.md"
    if not md.exists():
        return ["Not measured yet: run `benchmarks/crosscheck_calibration.py`."]
    body = [ln for ln in md.read_text().splitlines()[1:] if not ln.startswith("![")]
    body = [ln.replace("## ", "### ") for ln in body]
    return [*body, "", "![calibration](../benchmarks/results/crosscheck_calibration.png)"]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", default="", help="comma-separated subset of " + ",".join(CANONICAL))
    p.add_argument("--out", default=str(ROOT / "docs"), help="docs folder (img/ is created inside)")
    p.add_argument("--no-stats", action="store_true", help="skip the Z-test section")
    args = p.parse_args(argv)
    names = [n for n in args.scenes.split(",") if n] or list(CANONICAL)
    unknown = sorted(set(names) - set(CANONICAL))
    if unknown:
        p.error(f"unknown scenes {unknown}")
    out = Path(args.out)
    (out / "img").mkdir(parents=True, exist_ok=True)
    status = bf.available_backends()
    for b in BACKENDS:
        if b not in status:
            status[b] = bf.BackendStatus(False, "not registered")
    from PIL import Image

    rows = []
    sections = []
    counts = {"pairs": 0, "pass": 0, "known": 0, "unexpected": 0}
    unexpected: list[str] = []
    t_all = time.perf_counter()
    variants: set[str] = set()  # the Mitsuba variant(s) the canonical scenes rendered with (the default)
    for name in names:
        build, spp, note = CANONICAL[name]
        scene = build()
        t0 = time.perf_counter()
        rep = bf.crosscheck(scene, backends=BACKENDS, samples=spp, scene_name=name)
        elapsed = time.perf_counter() - t0
        if "mitsuba" in rep.results:
            variants.add(str(rep.results["mitsuba"].meta.get("variant")))
        print(f"{name}: {elapsed:.1f} s {rep!r}")
        Image.fromarray(rep.contact_sheet(tile=96)).save(out / "img" / f"crosscheck_{name}.png")
        for (a, b), cr in rep.pairs.items():
            cells = [cr.metrics.get(o, {}).get(m) for o, m, _ in COLUMNS]
            verdict = "pass" if cr.passed else "FAIL: " + "; ".join(f.split(" (tier")[0] for f in cr.failures)
            counts["pairs"] += 1
            if cr.passed:
                counts["pass"] += 1
            elif (name, a) in KNOWN or (name, b) in KNOWN:
                counts["known"] += 1
                verdict += " (known)"
            else:
                counts["unexpected"] += 1
                unexpected.append(f"{name}: {a} / {b}")
            values = " | ".join(fmt(c) for c in cells)
            rows.append(f"| {name} | {a} / {b} | `{cr.tier}` | {values} | {verdict} |")
        sec = [f"### {name}", "", f"{note}; {spp} spp; {elapsed:.1f} s for all backends.", ""]
        for b_, why in rep.skipped.items():
            sec.append(f"- {b_} skipped: {why}")
        for b_, why in rep.errors.items():
            sec.append(f"- {b_} ERROR: {why}")
        for n in rep.notes:
            sec.append(f"- {n}")
        approx = {b_: [x.split(":")[0] for x in r.meta.get("approximations", [])] for b_, r in rep.results.items()}
        for b_, ap in approx.items():
            if ap:
                sec.append(f"- {b_} approximates: {', '.join(ap)}")
        sec += ["", f"![{name}](img/crosscheck_{name}.png)", ""]
        sections.append("\n".join(sec))

    tiers = ["| tier | output | thresholds |", "|---|---|---|"]
    for tname, spec in TIERS.items():
        for o, ms in spec.items():
            hb = {"ssim", "psnr", "iou", "agreement"}
            th = ", ".join(f"{m} {'>=' if m in hb else '<='} {fmt(float(v))}" for m, v in ms.items())
            tiers.append(f"| `{tname}` | {o} | {th} |")

    versions = ", ".join(
        f"{b} {status[b].version}" if status[b].available else f"{b}: unavailable ({status[b].reason})"
        for b in BACKENDS
    )
    head = " | ".join(label for _, _, label in COLUMNS)
    doc = [
        "# Cross-backend agreement",
        "",
        "Generated by `benchmarks/crosscheck_report.py` "
        f"({dt.datetime.now(dt.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}, {platform.machine()}, "
        f"Python {platform.python_version()}; {versions}; Mitsuba variant of the canonical scenes: "
        f"{', '.join(sorted(variants)) or 'none'}, the default here). Re-run it after changing a backend.",
        "",
        "Every canonical scene (`tests/crossbackend/xb_canonical.py`, the scenes the cross-backend tests use) is "
        "rendered by every available backend with `bf.crosscheck`: box pixel filter, no denoiser, no clamping, "
        "no adaptive sampling, seed 0. Each pair (a, b) is compared with `bf.compare(a, b)` (b is the reference) "
        "at the tier `choose_tier` picks: `pathtracer_delta` for Cycles/Mitsuba on Lambertian scenes lit by delta "
        "lights, `pathtracer` for Lambertian scenes with area/sky light, `pathtracer_material` for non-Lambertian "
        "materials, `raster`/`raster_material` when pyrender is involved.",
        "",
        "How to read the table: *rgb rel* is the mean of |a − r| / max(|r|, 0.02) over colour channels "
        "(Mitsuba's error with its floor); *(interior)* restricts it to pixels whose 3×3 neighbourhood is one "
        "surface (no silhouette, no border between objects, no crease), where colour averaged over the pixel and "
        "a pixel-centre pass (every engine's geometric outputs) are comparable; *rgb ratio* = sum(a) / sum(r) (a units "
        "check); *depth q99* the 99th percentile of the relative depth difference where both hit; *mask diff px* "
        "pixels hit by one backend only (*interior*: not explained by a ≤1 px silhouette move); *normal q99* "
        "angular error on interior pixels; *id agree* the instance agreement where both hit; *albedo rel* the "
        "interior relative albedo error.",
        "",
        "## Measured agreement",
        "",
        f"**{counts['pass']} of {counts['pairs']} pairs pass their tier; {counts['known']} fail for a known, "
        f"documented reason (below, under Known differences); {counts['unexpected']} fail unexpectedly"
        + (f": {', '.join(unexpected)}" if unexpected else "")
        + ".**",
        "",
        f"| scene | pair | tier | {head} | verdict |",
        "|" + "---|" * (len(COLUMNS) + 4),
        *rows,
        "",
        "## Marker centroids (camera self-test)",
        "",
        "Alpha-weighted centroid of each marker vs the centroid of its exact box-filtered coverage "
        "(16×16 ray cast per pixel), 64 spp, 64×48, markers of ~3 px radius (target ≤ 0.05 px).",
        "",
        *marker_centroids(status),
        "",
    ]
    doc += [
        "## The noise-aware colour verdict",
        "",
        "`bf.crosscheck` renders each path tracer's samples as 4 independent passes (seeds `seed`..`seed + 3`, "
        "about the cost of one render) and keeps the variance of the mean colour (`result.rgb_var`). A pair of "
        "path tracers is then judged by `blendify_core/evaluate/noise.py` instead of fixed colour tolerances: for "
        "every 8×8 tile and for the whole image, per channel, the summed difference of the two means is tested "
        "against its standard error (Student t with Welch–Satterthwaite degrees of freedom, Šidák-corrected over "
        "the tiles, alpha = 0.01 split between tiles and image) beyond a practical margin — 0.25 % for the whole "
        "image and 2 % for a tile (`NOISE_MARGINS`: 3 % / 8 % for non-Lambertian materials, whose BSDFs differ "
        "between the engines). *noise: image rel* is the largest per-channel relative difference of the image "
        "sums, *noise: tiles rej* the tiles that differ beyond their margin and noise. `bf.compare(a, b)` does the "
        "same whenever both results carry `rgb_var` (`blendify_core.evaluate.noise.render_passes`); `passes=1` "
        "gives the fixed tiers back.",
        "",
        "### Calibration",
        "",
        *calibration(),
        "",
        "## Third-party scenes",
        "",
        "Ports of public example scenes (`tests/third_party/scenes/ports.py`; sources and licences in "
        "`tests/third_party/SOURCES.md`), 64 spp as 4 passes per path tracer, Mitsuba `scalar_rgb`. Nobody "
        "here designed them: they show where the engines still differ on scenes other people build. Known "
        "differences (xfail in `tests/crossbackend/test_xb_third_party.py`):",
        "",
        *[f"- **{n}**: {why}" for n, why in KNOWN_THIRD_PARTY.items()],
        "",
        *third_party(out),
        "",
        "Public `.blend` files that cannot be committed (licence unknown) are read from "
        "`$BLENDIFY_THIRD_PARTY_DIR` (`scenes/blendify/cornell_box.blend`, `scenes/blendify/light_box.blend`; "
        "see SOURCES.md) by `test_xb_third_party.py`, which skips them with the reason when absent.",
        "",
    ]
    if not args.no_stats:
        doc += [
            "## Statistical test on real renders",
            "",
            "`blendify_core.evaluate.stats`: per-pixel Z-test (Šidák-corrected, t distribution for a K-render "
            "reference) plus tile and whole-image aggregates. A correct render passes against its own reference; a 2 % "
            "bias fails.",
            "",
            *statistical_checks(status),
            "",
            "### Cycles vs Mitsuba, statistically (`bf.crosscheck(scene, repeats=4, samples=64)`)",
            "",
            "Each path tracer renders the scene 4 times (seeds 0-3); the two-sample test asks whether the two "
            "engines' expected images are equal given their noise (|global z| of the whole-image mean per "
            "channel, the largest; Šidák-corrected per-pixel and 8×8-tile tests). Lambertian scenes must come "
            "out consistent; the test flags the documented material (Principled/plastic BSDF) and fuze "
            "(normals/texture) differences at a level no fixed tolerance could separate from noise.",
            "",
            *statistical_crosscheck(status),
            "",
        ]
    doc += [
        "## Known differences",
        "",
        "Understood disagreements (the pairs are `xfail` in `tests/crossbackend/test_xb_canonical.py`, so a fix "
        "shows up as XPASS):",
        "",
        *[f"- **{scene}**, pairs with **{backend}**: {why}" for (scene, backend), why in KNOWN.items()],
        "",
        "## Using it",
        "",
        "```python",
        "import blendify_core as bf",
        "a = bf.render(scene, backend='cycles', outputs=('rgb', 'depth', 'normal', 'instance'))",
        "b = bf.render(scene, backend='mitsuba', outputs=('rgb', 'depth', 'normal', 'instance'))",
        "rep = bf.compare(a, b)            # tier 'auto' from meta['backend'], or tier='pathtracer_delta', ...",
        "rep.metrics['rgb']['mean_rel_error'], rep.metrics['depth']['rel_diff_q99'], rep.metrics['mask']['iou']",
        "rep.passed, rep.failures; rep.save('out/')   # diff_<output>.png heat maps + report.md + metrics.json",
        "",
        "xc = bf.crosscheck(scene, samples=256)      # every backend; path tracers as 4 passes of 64 spp",
        "xc.pairs[('cycles', 'mitsuba')], xc.skipped; xc.save('out/')   # contact sheet + markdown report",
        "xc.pairs[('cycles', 'mitsuba')].noise      # the noise-aware verdict: .passed, .reasons, .global_rel_diff",
        "",
        "from blendify_core.evaluate.noise import render_passes",
        "a = render_passes(scene, 'cycles', samples=256)   # colour = mean of 4 passes, a.rgb_var its variance",
        "b = render_passes(scene, 'mitsuba', samples=256)",
        "bf.compare(a, b, scene=scene).passed        # agree within noise, fail on a bias",
        "",
        "from blendify_core.evaluate.stats import estimate_reference",
        "ref = estimate_reference(scene, k=8, samples=16, backend='mitsuba')  # mean + variance from 8 seeds",
        "ref.z_test(bf.render(scene, backend='mitsuba', samples=16, seed=99).rgb).passed",
        "```",
        "",
        "In a notebook a CompareReport and a CrosscheckReport display themselves: verdict, metric (or verdict) "
        "table and contact sheet (`_repr_html_`, `_repr_png_`). `bf.crosscheck` and `estimate_reference` show a "
        "progress bar over their renders on a terminal or in a notebook (`progress=False` turns it off, "
        "`progress=True` forces it; `TQDM_DISABLE=1` turns every bar off).",
        "",
        "Command line: `blendify crosscheck scene.npz -o out/ [--backends cycles,mitsuba] [--samples 256] "
        "[--passes 4]` "
        "(exit code 0 when every pair passes, 1 otherwise).",
        "",
        "Pairs that cannot be judged are reported apart (`xc.limited`: pair -> the list; their comparisons in "
        "`xc.limited_reports`), neither passed nor failed: **limited by the IR** when one backend renders an "
        "attached `.blend` itself and the other its IR parse (what the parse could not carry, `IR parse of ...`), "
        "**limited by the engine** when a render setting is applied by one engine only: a biased setting the other "
        "cannot apply (`bf.crosscheck(scene, clamp_indirect=10, filter_glossy=1, diffuse_bounces=4)`: Mitsuba has "
        "no clamp, no Filter Glossy and one depth for every kind of bounce, pyrender traces no paths; "
        "`Backend.unapplied_settings`, listed as `setting the engine cannot apply: ...` in its "
        "`meta[\"approximations\"]`) or a setting of one engine's own (Cycles' `cycles_settings`, "
        '`meta["engine_only_settings"]`).',
        "",
    ]
    notes = [f"- `{t}`: {why}" for t, why in TIER_NOTES.items()]
    doc += [
        "## Tolerance tiers (`blendify_core.evaluate.tiers.TIERS`)",
        "",
        "CONV = `docs/conventions.md`, section *Measurements behind the tolerance tiers* (sections 5, 6, 11, 13, "
        "made with the same engine versions); "
        "'measured' = this report. The per-number comments are next to `TIERS` in `blendify_core/evaluate/tiers.py`.",
        "",
        *notes,
        "",
        *tiers,
        "",
        "## Scenes",
        "",
        *sections,
    ]
    doc.append(f"\nTotal time: {time.perf_counter() - t_all:.0f} s.\n")
    (out / "crosscheck.md").write_text("\n".join(doc))
    print(f"wrote {out / 'crosscheck.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
