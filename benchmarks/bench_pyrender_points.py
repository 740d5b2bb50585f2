"""Coloured point clouds in the pyrender backend: build and warm-frame times of the backend's own drawing,
one code version against another.

At 512x512, clouds of 2k to 1M points on a shell (diameter 0.01, per-point colours, sun with shadows +
background). Each (version, size) runs in a fresh process; "build" = translation + upload + first frame
(the OpenGL context and shaders are created before timing), "warm" = median of 5 frames with the camera
orbiting, as plain frames (``samples=1``) and as the default preview (coverage anti-aliasing on llvmpipe).
A version is a label and the checkout whose packages are imported: ``--label after`` (this checkout) or
``--label before --checkout DIR`` (e.g. ``git archive <rev> | tar -x -C DIR``). Each label's rows are kept in
``results/pyrender_points_<label>.json``; the table compares the labels present.

Run: ``nice python benchmarks/bench_pyrender_points.py --label after``; writes
``benchmarks/results/pyrender_points.md`` and ``pyrender_points.png``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results"
RES = (512, 512)
N_WARM = 5
SIZES = (2_000, 30_000, 100_000, 150_000, 1_000_000)
LABELS = ("before", "after")
#: what each version drew (by the backend's level of detail in "before")
DRAWN = {
    "before": {
        2_000: "icosphere-1 (80 triangles)",
        30_000: "icosphere-0 (20 triangles)",
        100_000: "octahedra (8 triangles)",
        150_000: "orthographic GL point sprites",
        1_000_000: "orthographic GL point sprites",
    },
    "after": {n: "exact spheres (quads, 2 triangles)" for n in SIZES},
}


def build_scene(n: int):  # type: ignore[no-untyped-def]
    from blendify_core import DiffuseMaterial, Scene, VertexColors, testing

    rng = np.random.default_rng(0)
    p = rng.normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    p *= rng.uniform(0.8, 1.0, size=(n, 1))
    scene = Scene()
    scene.renderables.add_pointcloud(
        p, DiffuseMaterial(), VertexColors((p * 0.5 + 0.5).astype(np.float32)), point_size=0.01, tag="points"
    )
    testing.look_at_camera(scene, RES, (2.5, -2.5, 2.0), fov_x=np.deg2rad(40))
    scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    scene.lights.set_background_light(0.3)
    return scene


def child(n: int) -> dict:
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    sys.path.insert(0, str(HERE))
    from bench_pyrender import orbit
    from blendify_pyrender import PyrenderBackend

    import blendify_core as bf
    from blendify_core import testing

    scene = build_scene(n)
    be = PyrenderBackend(platform="egl")
    bf.render(testing.depth_plane_scene(), backend=be, samples=1)  # context + shaders outside the timing
    t0 = time.perf_counter()
    bf.render(scene, backend=be, quality="preview", samples=1)
    build = time.perf_counter() - t0
    out = {"build": build}
    for key, kwargs in (("warm", {"samples": 1}), ("preview", {})):
        times = []
        for i in range(N_WARM):
            orbit(scene, i)
            t = time.perf_counter()
            bf.render(scene, backend=be, quality="preview", **kwargs)
            times.append(time.perf_counter() - t)
        out[key] = float(np.median(times))
    be.close()
    return out


def _pythonpath(checkout: Path) -> str:
    parts = [
        checkout,
        checkout / "backends" / "blender",
        checkout / "backends" / "mitsuba",
        checkout / "backends" / "pyrender",
    ]
    return os.pathsep.join(str(p) for p in parts)


def measure(label: str, checkout: Path, sizes: tuple[int, ...]) -> None:
    env = dict(os.environ, PYTHONPATH=_pythonpath(checkout))
    rows = []
    for n in sizes:
        for attempt in range(3):  # the machine is shared with other jobs: retry a transient failure
            p = subprocess.run(
                [sys.executable, __file__, "--child", str(n)], capture_output=True, text=True, timeout=3600, env=env
            )
            line = [x for x in p.stdout.splitlines() if x.startswith("RESULT ")]
            if p.returncode == 0 and line:
                break
            print(f"{label} {n}: attempt {attempt + 1} failed:\n{p.stderr[-2000:]}", flush=True)
            time.sleep(30)
        else:
            raise SystemExit(f"{label} {n} failed")
        r = json.loads(line[0][7:])
        rows.append({"points": n, **r})
        print(
            f"{label} {n:>9d} build {r['build']:.2f} s  warm {r['warm'] * 1000:.0f} ms  "
            f"preview {r['preview'] * 1000:.0f} ms",
            flush=True,
        )
    load = os.getloadavg()[0]
    data = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "load_1min": load, "rows": rows}
    (RESULTS / f"pyrender_points_{label}.json").write_text(json.dumps(data, indent=1) + "\n")


def write_report() -> None:
    runs = {t: json.loads(p.read_text()) for t in LABELS if (p := RESULTS / f"pyrender_points_{t}.json").exists()}
    if not runs:
        return
    lines = [
        "# pyrender backend: coloured point clouds at 512x512",
        "",
        f"Machine: {os.cpu_count()} CPU cores, Mesa llvmpipe through EGL, shared with other jobs (+-30%; 1-minute "
        "load average at the end of each run: "
        + ", ".join(f"{t} {r['load_1min']:.1f} ({r['date']})" for t, r in runs.items())
        + "). Generated by `benchmarks/bench_pyrender_points.py`. Points on a shell, diameter 0.01, per-point "
        "colours, sun (with shadows) + background. Build = translation + upload + first frame; plain = warm frame "
        "with samples=1; preview = warm frame of the default preview (coverage anti-aliasing); medians of 5 frames "
        "with the camera orbiting.",
        "",
        "| points | version | drawn as | build + first frame (s) | plain frame (ms) | preview frame (ms) |",
        "|---:|---|---|---:|---:|---:|",
    ]
    for n in SIZES:
        for t, run in runs.items():
            r = next((x for x in run["rows"] if x["points"] == n), None)
            if r is not None:
                lines.append(
                    f"| {n:,} | {t} | {DRAWN[t][n]} | {r['build']:.2f} | {r['warm'] * 1000:.0f} | "
                    f"{r['preview'] * 1000:.0f} |"
                )
    if len(runs) == 2:
        lines += [
            "",
            "| points | preview after / before | plain after / before | build after / before |",
            "|---:|---:|---:|---:|",
        ]
        before = {x["points"]: x for x in runs["before"]["rows"]}
        for x in runs["after"]["rows"]:
            b = before.get(x["points"])
            if b is not None:
                lines.append(
                    f"| {x['points']:,} | {x['preview'] / b['preview']:.2f} | {x['warm'] / b['warm']:.2f} | "
                    f"{x['build'] / b['build']:.2f} |"
                )
    lines += [
        "",
        "Before: the level of detail chose merged icospheres (subdivision 1 up to 20k points, 0 up to 50k), "
        "octahedra up to 100k and orthographic point sprites beyond. After: every cloud is one quad per point "
        "that the shaders spread over the sphere's projected box and intersect exactly per pixel centre "
        "(`blendify_pyrender.translate.pointcloud`). In both, the colour pass of a cloud denser than about 8 "
        "points per covered pixel draws a random subset (never fewer than 100,000 points); after, the G-buffer "
        "and the shadow maps draw every point.",
        "",
        "![point cloud timings](pyrender_points.png)",
        "",
    ]
    (RESULTS / "pyrender_points.md").write_text("\n".join(lines))
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no plot written")
        return
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    for ax, key, title in (
        (axes[0], "build", "build + first frame (s)"),
        (axes[1], "warm", "plain frame (s)"),
        (axes[2], "preview", "preview frame (s)"),
    ):
        for t, run in runs.items():
            ax.plot([x["points"] for x in run["rows"]], [x[key] for x in run["rows"]], "o-", label=t)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("points")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / "pyrender_points.png", dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--label", choices=LABELS, default="after")
    ap.add_argument("--checkout", type=Path, default=ROOT, help="the checkout whose packages are measured")
    ap.add_argument("--sizes", default=",".join(str(n) for n in SIZES))
    ap.add_argument("--table", action="store_true", help="only rewrite the table and plot from the JSON files")
    args = ap.parse_args()
    RESULTS.mkdir(parents=True, exist_ok=True)
    if not args.table:
        measure(args.label, args.checkout.resolve(), tuple(int(x) for x in args.sizes.split(",")))
    write_report()


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        print("RESULT " + json.dumps(child(int(sys.argv[2]))), flush=True)
    else:
        main()
