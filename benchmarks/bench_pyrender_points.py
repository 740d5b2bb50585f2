"""Coloured point clouds in the pyrender backend: build and warm-frame times per sphere tessellation.

Compares, at 512x512, merged per-point spheres with per-vertex colours (icosphere-1, icosphere-0,
octahedron: what the backend's level of detail chooses between) against pyrender's instancing
(``Primitive(poses=...)``, one icosphere-1 drawn N times: fast to build but pyrender has no per-instance
colour, so it cannot show per-point colours). Each variant runs in a fresh process; "build" = translation
+ upload + first frame (the OpenGL context is created before timing), "warm" = median of 5 frames with
the camera orbiting.

Run: ``uv run --no-sync python benchmarks/bench_pyrender_points.py``; writes
``benchmarks/results/pyrender_points.md`` and ``pyrender_points.png``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
RES = (512, 512)
N_WARM = 5
VARIANTS = ("icosphere-1", "icosphere-0", "octahedron", "GL points", "instanced icosphere-1 (no colours)")
#: (variant, minimum size) combinations not attempted: too much memory / minutes per frame on 2 cores
SKIP = {
    ("icosphere-1", 1_000_000): "80M triangles, 1.7 GB of vertex data",
    ("icosphere-0", 1_000_000): "20M triangles",
    ("instanced icosphere-1 (no colours)", 1_000_000): "measured in an earlier run: build 40.8 s, warm 25.6 s",
}
SIZES = (100_000, 1_000_000)


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


def child(variant: str, n: int) -> dict:
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    sys.path.insert(0, str(HERE))
    from bench_pyrender import orbit
    from blendify_pyrender import PyrenderBackend

    import blendify_core as bf

    scene = build_scene(n)
    be = PyrenderBackend(platform="egl")
    from blendify_core import testing

    bf.render(testing.depth_plane_scene(), backend=be, samples=1)  # context + shaders outside the timing
    if variant.startswith("instanced"):
        return instanced(be, scene, n)
    from blendify_pyrender import translate as tr

    lod = {
        "icosphere-1": tr.PointLOD("icosphere-1", 1, False),
        "icosphere-0": tr.PointLOD("icosphere-0", 0, True),
        "octahedron": tr.PointLOD("octahedron", -1, True),
        "GL points": tr.PointLOD("GL points", -2, True),
    }[variant]
    tr.point_lod = lambda _n: lod  # force the tessellation under test
    t0 = time.perf_counter()
    bf.render(scene, backend=be, quality="preview", samples=1)
    build = time.perf_counter() - t0
    warm = []
    for i in range(N_WARM):
        orbit(scene, i)
        t = time.perf_counter()
        bf.render(scene, backend=be, quality="preview", samples=1)
        warm.append(time.perf_counter() - t)
    be.close()
    return {"build": build, "warm": float(np.median(warm))}


def instanced(be, scene, n: int) -> dict:  # type: ignore[no-untyped-def]
    """pyrender instancing of one icosphere-1 through the backend's renderer (same passes, no colours)."""
    import pyrender
    from bench_pyrender import orbit

    from blendify_core.ir.geometry import icosphere

    eng = be.engine_instance
    pts = scene.renderables["points"]
    t0 = time.perf_counter()
    s = icosphere(1)
    r = pts.radii()
    poses = np.tile(np.eye(4, dtype=np.float32), (n, 1, 1))
    poses[:, 0, 0] = poses[:, 1, 1] = poses[:, 2, 2] = r
    poses[:, :3, 3] = pts.vertices
    prim = pyrender.Primitive(
        positions=s.vertices.astype(np.float32),
        normals=s.normals.astype(np.float32),
        indices=s.faces.astype(np.uint32),
        poses=poses,
        material=pyrender.MetallicRoughnessMaterial(baseColorFactor=[0.5, 0.5, 0.5, 1.0], metallicFactor=0.0),
    )
    prim.albedo_factor = np.array([0.5, 0.5, 0.5, 1.0])
    scene.renderables.remove("points")
    from blendify_core import render

    eng.pscene.add(pyrender.Mesh([prim]))
    render(scene, backend=be, quality="preview", samples=1)
    build = time.perf_counter() - t0
    warm = []
    for i in range(N_WARM):
        orbit(scene, i)
        t = time.perf_counter()
        render(scene, backend=be, quality="preview", samples=1)
        warm.append(time.perf_counter() - t)
    return {"build": build, "warm": float(np.median(warm))}


def main() -> None:
    RESULTS.mkdir(parents=True, exist_ok=True)
    rows = []
    for n in SIZES:
        for variant in VARIANTS:
            if (variant, n) in SKIP:
                rows.append((n, variant, None))
                continue
            for attempt in range(3):  # the checkout is shared with other jobs: retry a transient failure
                p = subprocess.run(
                    [sys.executable, __file__, "--child", variant, str(n)], capture_output=True, text=True, timeout=3600
                )
                line = [x for x in p.stdout.splitlines() if x.startswith("RESULT ")]
                if p.returncode == 0 and line:
                    break
                print(f"{variant} {n}: attempt {attempt + 1} failed:\n{p.stderr[-2000:]}", flush=True)
                time.sleep(30)
            else:
                raise SystemExit(f"{variant} {n} failed")
            r = json.loads(line[0][7:])
            rows.append((n, variant, r))
            print(f"{n:>9d} {variant:40s} build {r['build']:.2f} s  warm {r['warm'] * 1000:.0f} ms", flush=True)
    write_report(rows)


def write_report(rows: list) -> None:
    lines = [
        "# pyrender backend: coloured point clouds at 512x512",
        "",
        f"Machine: {os.cpu_count()} CPU cores, Mesa llvmpipe through EGL (shared with other jobs: +-30%). Generated by "
        f"`benchmarks/bench_pyrender_points.py` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. Points on "
        "a shell, diameter 0.01, per-point colours, sun (with shadows) + background, plain frames "
        "(samples=1; the default coverage anti-aliasing adds one cheap coverage pass).",
        "",
        "| points | tessellation | triangles | build + first frame (s) | warm frame (ms) |",
        "|---:|---|---:|---:|---:|",
    ]
    tris = {
        "icosphere-1": 80,
        "icosphere-0": 20,
        "octahedron": 8,
        "GL points": 0,
        "instanced icosphere-1 (no colours)": 80,
    }
    for n, variant, r in rows:
        if r is None:
            lines.append(f"| {n:,} | {variant} | {tris[variant] * n:,} | not attempted ({SKIP[(variant, n)]}) | |")
        else:
            lines.append(f"| {n:,} | {variant} | {tris[variant] * n:,} | {r['build']:.2f} | {r['warm'] * 1000:.0f} |")
    lines += [
        "",
        "Choice (``blendify_pyrender.translate.point_lod``): merged spheres with per-vertex colours, because "
        "pyrender's instancing has no per-instance colour (it would need one draw per colour); icosphere-1 "
        "(the shared tessellation) up to 20,000 points, icosphere-0 up to 50,000, octahedra up to 100,000, "
        "beyond that GL points (one square sprite per point, the projected diameter at the cloud's centre, "
        "shaded facing the camera; 0 triangles in the table), of which a random subset of about 8 points per "
        "covered pixel is drawn when the cloud is denser on screen (never fewer than 100,000; at 1M points "
        "in this view about 250k are drawn). The coarser levels are listed in "
        "``result.meta['approximations']``. llvmpipe's cost is roughly per primitive, so triangles per point "
        "decide the frame time.",
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
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, key, title in ((axes[0], "build", "build + first frame (s)"), (axes[1], "warm", "warm frame (s)")):
        for variant in VARIANTS:
            pts = [(n, r[key]) for n, v, r in rows if v == variant and r is not None]
            if pts:
                ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=variant)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("points")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / "pyrender_points.png", dpi=110)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        print("RESULT " + json.dumps(child(sys.argv[2], int(sys.argv[3]))), flush=True)
    else:
        main()
