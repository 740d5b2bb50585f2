"""What a render costs outside the engine on scenes of many objects (issue 20: the effect analysis must not
cost the time it saves): ``bf.analyse_effects``, ``Scene.bounds()`` and whole ``bf.render`` calls on scenes
of N small diffuse spheres plus N cubes under three point lights, N = 250, 1000, 2000.

Each measurement is the median of ``--reps`` runs in one process (the first run of a render is also
reported: it pays the engine's start and the scene's first translation). Renders: pyrender (``preview``,
a raster pass: whatever ``bf.render`` adds around it shows) and Cycles ``final`` (passes to its error target
with the effect pilots, 64x48).

Run: ``uv run --no-sync python benchmarks/bench_many_objects.py [--sizes 250,1000,2000] [--reps 3]
[--label after] [--out benchmarks/results/many_objects_after.json]``; ``--report before.json,after.json``
writes ``benchmarks/results/many_objects.md`` and ``.png`` from two runs (e.g. the commit before a change,
checked out in a worktree, and this one).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

import blendify_core as bf
from blendify_core.testing import look_at_camera

RESULTS = Path(__file__).parent / "results"


def scene(n: int) -> bf.Scene:
    """N spheres and N cubes (radius / edge 0.03) scattered in a unit ball, three point lights above."""
    s = bf.Scene()
    rng = np.random.default_rng(0)
    white = bf.UniformColors((0.7, 0.7, 0.7))
    for i in range(n):
        s.renderables.add_sphere_nurbs(0.03, bf.DiffuseMaterial(), white, translation=rng.normal(size=3), tag=f"s{i}")
        s.renderables.add_cube_mesh(0.03, bf.DiffuseMaterial(), white, translation=rng.normal(size=3), tag=f"c{i}")
    for i in range(3):
        s.lights.add_point(200.0, translation=(i - 1.0, -1.0, 4.0))
    look_at_camera(s, (64, 48), (0.0, -7.0, 3.0), (0, 0, 0), fov_x=np.deg2rad(45))
    return s


def timed(fn: Callable[[], Any], reps: int) -> tuple[float, float]:
    """(first run, median of the next ``reps``) in seconds."""
    times = []
    for _ in range(reps + 1):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return times[0], statistics.median(times[1:])


def measure_one(n: int, reps: int) -> dict[str, Any]:
    """One scene size: the four measurements."""
    s = scene(n)
    row: dict[str, Any] = {"objects": 2 * n}
    row["analyse_effects"] = timed(lambda: bf.analyse_effects(s), reps)
    row["bounds"] = timed(lambda: s.bounds(), reps)
    row["pyrender preview"] = timed(lambda: bf.render(s, backend="pyrender", quality="preview"), reps)
    row["cycles final"] = timed(
        lambda: bf.render(s, backend="cycles", quality="final", seed=1, threads=2), max(1, reps - 1)
    )
    print(row, flush=True)
    return row


def measure(sizes: list[int], reps: int) -> list[dict[str, Any]]:
    return [measure_one(n, reps) for n in sizes]


COLUMNS = ("analyse_effects", "bounds", "pyrender preview", "cycles final")


def write_report(runs: list[dict[str, Any]], out: Path) -> None:
    before, after = runs[0], runs[-1]
    lines = [
        "# Many objects: what a render costs outside the engine",
        "",
        f"Scenes: N diffuse spheres + N cubes (`benchmarks/bench_many_objects.py`), 3 point lights, 64x48. "
        f"Seconds, median of {after['info']['reps']} runs after a first one ({after['info']['reps'] - 1} for Cycles "
        f"`final`; the first run in brackets); "
        f"`{before['info']['label']}` = {before['info'].get('commit', '?')}, `{after['info']['label']}` = "
        f"{after['info'].get('commit', '?')}; load average {before['info']['load'][0]:.1f}-"
        f"{after['info']['load'][1]:.1f} on {after['info']['cpus']} cores. Run the script for the command.",
        "",
        "| objects | measurement | " + " | ".join(r["info"]["label"] for r in runs) + " | ratio |",
        "|---|---|" + "---|" * len(runs) + "---|",
    ]
    for rb, ra in zip(before["rows"], after["rows"], strict=True):
        for col in COLUMNS:
            cells = [f"{r[col][1]:.3f} ({r[col][0]:.2f})" for r in (rb, ra)]
            ratio = rb[col][1] / max(ra[col][1], 1e-9)
            lines.append(f"| {ra['objects']} | {col} | " + " | ".join(cells) + f" | {ratio:.1f}x |")
    lines += [
        "",
        "Before, every render asked each primitive for its world bounds by tessellating it (a sphere: 2145 "
        "vertices, 1 ms; a cube: its edge-split mesh), once for the scene's bounds and again in the effect "
        "analysis's light-inside test, and `final` ran that analysis again for each pilot round. "
        "After: spheres and ellipsoids give their own bounds, mesh primitives their corners, curves are "
        "tessellated once per geometry and rotation, the light-inside test runs only where it decides "
        "something, and a render analyses the scene once.",
        "",
    ]
    out.with_suffix(".md").write_text("\n".join(lines))
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is missing: no plot written")
        return
    fig, axes = plt.subplots(1, len(COLUMNS), figsize=(4 * len(COLUMNS), 3.4))
    for ax, col in zip(axes, COLUMNS, strict=True):
        for run, style in zip(runs, ("o-", "s-"), strict=False):
            xs = [r["objects"] for r in run["rows"]]
            ax.loglog(xs, [r[col][1] for r in run["rows"]], style, label=run["info"]["label"])
        ax.set_title(col, fontsize=9)
        ax.set_xlabel("objects")
    axes[0].set_ylabel("seconds (median)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out.with_suffix(".png"), dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", default="250,1000,2000")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--label", default="after")
    ap.add_argument("--commit", default="")
    ap.add_argument("--out", default=str(RESULTS / "many_objects_after.json"))
    ap.add_argument("--report", help="comma-separated json files (before first): write the .md and .png")
    args = ap.parse_args()
    if args.report:
        runs = [json.loads(Path(f).read_text()) for f in args.report.split(",")]
        write_report(runs, RESULTS / "many_objects")
        return
    load0 = os.getloadavg()[0]
    rows = measure([int(x) for x in args.sizes.split(",")], args.reps)
    info = {
        "label": args.label,
        "commit": args.commit,
        "reps": args.reps,
        "load": [load0, os.getloadavg()[0]],
        "cpus": os.cpu_count(),
        "machine": platform.platform(),
    }
    Path(args.out).write_text(json.dumps({"info": info, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
