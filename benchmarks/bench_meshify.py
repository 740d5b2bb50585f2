"""Benchmark of the point-cloud utilities: meshify_pointcloud on the bunny scan and estimate_normals at scale.

Meshify: the vertices of ../shared/data/bunny.ply with synthetic sRGB colours (a smooth one and a
high-frequency one, both functions of position) are reconstructed into a textured mesh; the texture
colour error is measured at every input point (texture looked up bilinearly at the UV of the point's
closest surface point, compared with the point's colour, mean absolute error in 8-bit sRGB levels).
The "leave-one-out" row is the intrinsic limit of the colour signal at the scan's density: each point's
colour predicted from its 3 nearest OTHER points with the same inverse-distance weighting.

Normals: points sampled on a unit sphere, angular error against the true normals, wall time.

    uv run --no-sync python benchmarks/bench_meshify.py [--quick] [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path
from unittest import mock

import numpy as np

from blendify_core.testing import data_path
from blendify_core.utils import estimate_normals, normals_from_mesh
from blendify_core.utils.meshify import meshify_pointcloud, sample_texture
from blendify_core.utils.normals import closest_points_on_mesh


def bunny_points() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    import trimesh

    mesh = trimesh.load(data_path("bunny.ply"), process=False)
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.vertices), np.asarray(mesh.faces)


def synthetic_colours(p: np.ndarray, kind: str) -> np.ndarray:
    u = (p - p.min(0)) / np.ptp(p, axis=0)
    if kind == "smooth":
        return 0.5 + 0.5 * np.sin(np.stack([6 * u[:, 0], 5 * u[:, 1] + 1, 7 * u[:, 2] + 2], axis=1))
    # stripes about 12 point spacings wide (the bunny's median spacing is ~0.002 of its 0.155 size)
    return 0.5 + 0.5 * np.sin(np.stack([40 * u[:, 0], 45 * u[:, 1] + 1, 50 * u[:, 2] + 2], axis=1))


def texture_error(res, p: np.ndarray, cols: np.ndarray) -> tuple[float, float, float]:
    fid, bary, dist = closest_points_on_mesh(p, res.vertices, res.faces.astype(np.int64))
    uv = np.einsum("nk,nkc->nc", bary, res.faces_uv[fid].astype(np.float64))
    err = np.abs(sample_texture(res.texture, uv) - cols * 255.0)
    return float(err.mean()), float(np.percentile(err, 99)), float(np.sqrt(dist).mean())


def leave_one_out(p: np.ndarray, cols: np.ndarray) -> float:
    from scipy.spatial import cKDTree

    d, nn = cKDTree(p).query(p, k=4)
    d, nn = d[:, 1:], nn[:, 1:]
    w = 1.0 / np.maximum(d, 1e-12)
    w /= w.sum(1, keepdims=True)
    pred = np.einsum("nk,nkc->nc", w, cols[nn])
    return float(np.abs(np.round(pred * 255) - cols * 255).mean())


def bench_meshify(quick: bool) -> list[str]:
    p, _, _ = bunny_points()
    rows = [
        "| colours | method | target faces | faces | texture | sRGB MAE (levels) | p99 | mean dist to surface "
        "| normals s | reconstruct s | simplify s | texture s | total s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    meshify_pointcloud(p[:2000], synthetic_colours(p[:2000], "smooth"), target_faces=500)  # warm-up (imports)
    budgets = [None, 5000] if quick else [None, 10000, 2000]
    for kind in ("smooth", "stripes"):
        cols = synthetic_colours(p, kind)
        limit = leave_one_out(p, cols)
        rows.append(f"| {kind} | leave-one-out IDW (limit) | - | - | - | {limit:.2f} |" + " - |" * 7)
        for method in ("ball_pivoting", "poisson", "implicit", "implicit (no Open3D)"):
            for budget in budgets:
                if method == "implicit (no Open3D)":
                    with mock.patch.dict(sys.modules, {"open3d": None}):  # vertex clustering instead of quadric
                        res = meshify_pointcloud(p, cols, target_faces=budget, method="implicit")
                else:
                    res = meshify_pointcloud(p, cols, target_faces=budget, method=method)
                mae, p99, dist = texture_error(res, p, cols)
                t = res.timings
                rows.append(
                    f"| {kind} | {method} | {budget or 'all'} | {len(res.faces)} | {res.texture.shape[0]}^2 | "
                    f"{mae:.2f} | {p99:.1f} | {dist:.2e} | {t['normals']:.2f} | {t['reconstruct']:.2f} | "
                    f"{t['simplify']:.2f} | {t['texture']:.2f} | {t['total']:.2f} |"
                )
                print(rows[-1], flush=True)
    return rows


def bench_normals(quick: bool) -> list[str]:
    from blendify_core.geometry import icosphere

    rng = np.random.default_rng(0)
    rows = [
        "| points | k | orient | mean error (deg) | max error (deg) | time s |",
        "|---|---|---|---|---|---|",
    ]
    sizes = [100_000] if quick else [100_000, 1_000_000]
    for n in sizes:
        truth = rng.normal(size=(n, 3))
        truth /= np.linalg.norm(truth, axis=1, keepdims=True)
        for orient in (None, "propagate", "viewpoint"):
            t0 = time.perf_counter()
            est = estimate_normals(truth, k=16, orient=orient, viewpoint=(0, 0, 0) if orient == "viewpoint" else None)
            dt = time.perf_counter() - t0
            cos = np.sum(est * truth, axis=1)
            if orient is None:
                cos = np.abs(cos)  # unoriented
            if orient == "viewpoint":
                cos = -cos  # towards the centre = inwards
            err = np.degrees(np.arccos(np.clip(cos, -1, 1)))
            rows.append(f"| {n:,} | 16 | {orient} | {err.mean():.3f} | {err.max():.2f} | {dt:.2f} |")
            print(rows[-1], flush=True)
        mesh = icosphere(5)
        pts = truth * rng.uniform(0.98, 1.02, size=(n, 1))
        t0 = time.perf_counter()
        est = normals_from_mesh(pts, mesh.vertices, mesh.faces)
        dt = time.perf_counter() - t0
        err = np.degrees(np.arccos(np.clip(np.sum(est * truth, axis=1), -1, 1)))
        rows.append(
            f"| {n:,} | - | normals_from_mesh (icosphere 20k faces) | {err.mean():.3f} | {err.max():.2f} | {dt:.2f} |"
        )
        print(rows[-1], flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer configurations (for a smoke run)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args()
    import open3d

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    mesh_rows = bench_meshify(args.quick)
    normal_rows = bench_normals(args.quick)
    cpu = platform.processor() or platform.machine()
    import os

    text = [
        "# meshify_pointcloud and estimate_normals",
        "",
        f"Machine: {os.cpu_count()} CPU cores ({cpu}), Python {platform.python_version()}, numpy {np.__version__}, "
        f"Open3D {open3d.__version__}. Script: `benchmarks/bench_meshify.py`"
        + (" (--quick)" if args.quick else "")
        + f". Load average when the run ended: {os.getloadavg()[0]:.1f} (times are inflated when the machine "
        "is shared with other jobs).",
        "",
        "## Point cloud to textured mesh (bunny.ply, 8,171 points, synthetic sRGB colours)",
        "",
        "Texture colour error at the input points (bilinear lookup at the closest surface point), in 8-bit sRGB "
        "levels (0-255). 'texture' is the atlas side (8x8 texels per pair of triangles by default). Times in seconds "
        "on the machine above; the first call in a process also pays Open3D's import (~1 s, excluded by a warm-up). "
        "'implicit' = narrow-band signed distance + marching tetrahedra (numpy/scipy only), simplified with Open3D's "
        "quadric decimation; 'implicit (no Open3D)' = the same with vertex clustering, i.e. the path taken when "
        "Open3D is not installed.",
        "",
        *mesh_rows,
        "",
        "## Normals (points on a unit sphere)",
        "",
        "PCA on the 16 nearest neighbours; 'propagate' orients over a minimum spanning tree of the kNN graph "
        "(outwards), 'viewpoint' towards the centre; None = unoriented (error measured up to sign).",
        "",
        *normal_rows,
        "",
    ]
    name = "meshify_quick.md" if args.quick else "meshify.md"
    (out / name).write_text("\n".join(text))
    print(f"wrote {out / name}")


if __name__ == "__main__":
    main()
