"""Point clouds in Mitsuba: analytic spheres (one shape + BSDF per point) versus what the backend uses beyond
``max_analytic_spheres`` (one ``linearcurve`` shape whose segments end in each point's exact sphere,
:mod:`blendify_mitsuba.points`, for opaque clouds), load (translate + load_dict) and render times against the
number of points. Chooses ``DEFAULT_MAX_ANALYTIC_SPHERES``. One warm-up render first, so that importing Mitsuba is
not counted.

Run: ``uv run --no-sync python benchmarks/bench_mitsuba_pointcloud.py [--variant llvm_ad_rgb --analytic-max 5000]``.
Writes ``benchmarks/results/mitsuba_pointcloud_<variant>.md`` and ``.png``.
"""

from __future__ import annotations

import argparse
import os
import time
from importlib import metadata
from pathlib import Path

import numpy as np

from blendify_core import testing
from blendify_core.pipeline.settings import resolve_settings

try:
    from blendify_mitsuba import DEFAULT_MAX_ANALYTIC_OPAQUE, DEFAULT_MAX_ANALYTIC_SPHERES
except ImportError:  # the table's note only
    DEFAULT_MAX_ANALYTIC_OPAQUE, DEFAULT_MAX_ANALYTIC_SPHERES = 0, {}

RESULTS = Path(__file__).resolve().parent / "results"


def run(n: int, analytic: bool, variant: str, settings) -> tuple[str, float, float, float]:
    """(representation used, load s, render s, coverage)."""
    from blendify_mitsuba import MitsubaBackend

    scene = testing.pointcloud_scene(n=n, resolution=(128, 128), point_size=min(0.03, 2.0 / np.sqrt(n)))
    with MitsubaBackend(variant=variant, max_analytic_spheres=n if analytic else 0) as b:
        t0 = time.perf_counter()
        native = b.translate(scene, settings)
        t1 = time.perf_counter()
        res = b.render(native, settings)
        t2 = time.perf_counter()
        keys = list(native.shapes)
    kind = "analytic spheres" if keys[0].endswith("_p0000000") else "curve spheres"
    kind = "merged icospheres" if keys[0].endswith("_mesh") else kind
    return kind, t1 - t0, t2 - t1, float(res.rgba[..., 3].mean())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", default="200,500,1000,5000,20000,100000")
    ap.add_argument("--analytic-max", type=int, default=100000, help="largest n rendered as analytic spheres")
    ap.add_argument("--variant", default="scalar_rgb")
    args = ap.parse_args()
    sizes = [int(x) for x in args.sizes.split(",")]
    settings = resolve_settings(samples=16, outputs=("rgb",))
    rows = []
    run(100, True, args.variant, settings)  # warm-up: import and JIT set-up
    for n in sizes:
        for analytic in (True, False):
            if analytic and n > args.analytic_max:
                continue
            kind, tr, rd, cov = run(n, analytic, args.variant, settings)
            rows.append((n, kind, tr, rd, cov))
            print(rows[-1], flush=True)
    RESULTS.mkdir(parents=True, exist_ok=True)
    stamp = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    lines = [
        "# Mitsuba point clouds: analytic spheres vs one curve shape of spheres",
        "",
        f"Scene: `testing.pointcloud_scene(n)` (points on a unit sphere, per-point colours, sun + background), "
        f"128x128, 16 spp, variant {args.variant}, mitsuba {metadata.version('mitsuba')}, 2 cores shared with "
        f"other jobs (load average {os.getloadavg()[0]:.1f} at the end), {stamp}. "
        "`load` = translate + `mi.load_dict` (one sphere shape and BSDF per point vs one `linearcurve` "
        "shape of exact spheres with a per-point colour bitmap); one warm-up render before, so no import is counted.",
        "",
        "| points | representation | load (s) | render (s) | total (s) | coverage |",
        "|---|---|---|---|---|---|",
    ]
    for n, kind, tr, rd, cov in rows:
        lines.append(f"| {n} | {kind} | {tr:.2f} | {rd:.2f} | {tr + rd:.2f} | {cov:.4f} |")
    lines += [
        "",
        "Both are within the path tracers' exactness bounds (depth q99 <= 1e-4 relative, normals q99 <= 0.5 "
        "deg; `tests/backends/mitsuba/test_mitsuba_render.py::test_curve_points_have_the_spheres_depth_and_normals`"
        "), so clouds that can be curves leave the analytic spheres where the curves become faster in total "
        f"(`blendify_mitsuba.DEFAULT_MAX_ANALYTIC_OPAQUE`: {DEFAULT_MAX_ANALYTIC_OPAQUE}; the others at "
        f"`DEFAULT_MAX_ANALYTIC_SPHERES`: {DEFAULT_MAX_ANALYTIC_SPHERES}). The merged icosphere "
        "mesh (emissive or partly transparent clouds, and points smaller than 5e-5 of their distance to the camera) "
        "is measured in `mitsuba_pointcloud_options.md`.",
        "",
    ]
    (RESULTS / f"mitsuba_pointcloud_{args.variant}.md").write_text("\n".join(lines))
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is missing: no plot written")
        return
    fig, ax = plt.subplots(figsize=(6, 4))
    for kind, style in (("analytic spheres", "o-"), ("curve spheres", "s-"), ("merged icospheres", "^-")):
        xs = [r[0] for r in rows if r[1] == kind]
        if not xs:
            continue
        ax.loglog(xs, [r[2] + r[3] for r in rows if r[1] == kind], style, label=f"{kind}: load + render")
        ax.loglog(xs, [r[2] for r in rows if r[1] == kind], style, alpha=0.4, label=f"{kind}: load")
    ax.set_xlabel("points")
    ax.set_ylabel("seconds")
    ax.set_title(f"Mitsuba point clouds ({args.variant}, 128x128, 16 spp)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / f"mitsuba_pointcloud_{args.variant}.png", dpi=100)


if __name__ == "__main__":
    main()
