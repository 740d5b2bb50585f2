"""Benchmark of the point-cloud utilities: meshify_pointcloud on the bunny scan and estimate_normals at scale.

Meshify: the vertices of tests/data/bunny.ply with synthetic sRGB colours (a smooth one and a
high-frequency one, both functions of position) are reconstructed into a textured mesh; the texture
colour error is measured at the input points (reproduction) and, for a mesh built from 90% of the
points, at the 10% held out (prediction), texture looked up bilinearly at the UV of the point's closest
surface point, mean absolute error in 8-bit sRGB levels. Results: results/meshify.md.

Normals: points sampled on a unit sphere, angular error against the true normals, wall time.
Results: results/meshify_normals.md.

    uv run --no-sync python benchmarks/bench_meshify.py [--quick] [--part all|meshify|normals]
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

try:
    import open3d

    _HAVE_O3D, _O3D_VERSION = True, open3d.__version__
except ImportError:  # meshify_pointcloud(method="implicit") still runs
    _HAVE_O3D, _O3D_VERSION = False, "not installed (implicit method only)"


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


def idw_predict(train: np.ndarray, cols: np.ndarray, query: np.ndarray, exclude_self: bool) -> np.ndarray:
    from scipy.spatial import cKDTree

    k = 4 if exclude_self else 3
    d, nn = cKDTree(train).query(query, k=k)
    if exclude_self:
        d, nn = d[:, 1:], nn[:, 1:]
    w = 1.0 / np.maximum(d, 1e-12)
    w /= w.sum(1, keepdims=True)
    return np.einsum("nk,nkc->nc", w, cols[nn])


def _run(method: str, p: np.ndarray, cols: np.ndarray, budget: int | None):
    if method == "implicit (no Open3D)":
        with mock.patch.dict(sys.modules, {"open3d": None}):  # vertex clustering instead of quadric
            return meshify_pointcloud(p, cols, target_faces=budget, method="implicit")
    return meshify_pointcloud(p, cols, target_faces=budget, method=method)


def bench_meshify(quick: bool) -> list[str]:
    p, _, _ = bunny_points()
    rng = np.random.default_rng(1)
    held = np.zeros(len(p), dtype=bool)
    held[rng.choice(len(p), size=len(p) // 10, replace=False)] = True
    rows = [
        "| colours | method | target faces | faces | texture | MAE at the points | p99 | MAE held-out 10% "
        "| mean dist to surface | normals s | reconstruct s | simplify s | texture s | total s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    warm = "ball_pivoting" if _HAVE_O3D else "implicit"
    meshify_pointcloud(p[:2000], synthetic_colours(p[:2000], "smooth"), target_faces=500, method=warm)  # warm-up
    budgets = [None, 5000] if quick else [None, 10000, 2000]
    methods = ("ball_pivoting", "poisson", "implicit", "implicit (no Open3D)") if _HAVE_O3D else ("implicit",)
    for kind in ("smooth", "stripes"):
        cols = synthetic_colours(p, kind)
        loo = np.abs(np.round(idw_predict(p, cols, p, True) * 255) - cols * 255).mean()
        ho = np.abs(np.round(idw_predict(p[~held], cols[~held], p[held], False) * 255) - cols[held] * 255).mean()
        rows.append(
            f"| {kind} | IDW of the 3 nearest other points (limit) | - | - | - | {loo:.2f} | - | {ho:.2f} |"
            + " - |" * 6
        )
        for method in methods:
            for budget in budgets:
                res = _run(method, p, cols, budget)
                mae, p99, dist = texture_error(res, p, cols)
                res_h = _run(method, p[~held], cols[~held], budget)
                mae_h, _, _ = texture_error(res_h, p[held], cols[held])
                t = res.timings
                rows.append(
                    f"| {kind} | {method} | {budget or 'all'} | {len(res.faces)} | {res.texture.shape[0]}^2 | "
                    f"{mae:.2f} | {p99:.1f} | {mae_h:.2f} | {dist:.2e} | {t['normals']:.2f} | {t['reconstruct']:.2f} | "
                    f"{t['simplify']:.2f} | {t['texture']:.2f} | {t['total']:.2f} |"
                )
                print(rows[-1], flush=True)
    return rows


def bench_normals(quick: bool) -> list[str]:
    from blendify_core.ir.geometry import icosphere

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


def render_figure(out: Path) -> Path:
    """Points vs the meshes of each method, rendered with the first available backend (a visual check that
    the FacesUV + TextureColors mesh renders like the points)."""
    import blendify_core as bf
    from blendify_core.utils import add_meshified, contact_sheet

    status = bf.available_backends()
    name = next(n for n in ("pyrender", "cycles", "mitsuba") if n in status and status[n].available)
    p, _, _ = bunny_points()
    cols = synthetic_colours(p, "stripes")
    lo, hi = p.min(0), p.max(0)
    centre = (lo + hi) / 2

    def base() -> bf.Scene:
        scene = bf.Scene()
        scene.set_perspective_camera(
            (240, 240),
            fov_x=np.deg2rad(35),
            rotation_mode="look_at",
            rotation=centre,
            translation=centre + np.array([0.0, 0.05, 0.35]),
        )
        scene.lights.add_sun(strength=3.0, rotation_mode="eulerXYZ", rotation=(-10, 10, 0))
        return scene

    images, labels = [], []
    scene = base()
    scene.renderables.add_pointcloud(p, bf.DiffuseMaterial(), bf.VertexColors(cols), point_size=0.003)
    images.append(bf.render(scene, backend=name, quality="preview"))
    labels.append(f"{len(p)} points")
    for method in ("ball_pivoting", "poisson", "implicit"):
        res = meshify_pointcloud(p, cols, method=method, target_faces=10000)
        scene = base()
        add_meshified(scene, res)
        images.append(bf.render(scene, backend=name, quality="preview"))
        labels.append(f"{method}, {len(res.faces)} faces")
    from PIL import Image

    path = out / "meshify_bunny.png"
    Image.fromarray(contact_sheet(images, labels, ncols=4)).save(path)
    print(f"wrote {path} ({name})")
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer configurations (for a smoke run)")
    ap.add_argument("--part", choices=("all", "meshify", "normals", "render"), default="all")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args()
    import os

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    suffix = "_quick" if args.quick else ""
    machine = (
        f"Machine: {os.cpu_count()} CPU cores ({platform.processor() or platform.machine()}), Python "
        f"{platform.python_version()}, numpy {np.__version__}, Open3D {_O3D_VERSION}. Script: "
        f"`benchmarks/bench_meshify.py{' --quick' if args.quick else ''}`. Load average when the run ended: "
        "{load:.1f} (times are inflated when the machine is shared with other jobs)."
    )
    if args.part in ("all", "meshify"):
        rows = bench_meshify(args.quick)
        text = [
            "# meshify_pointcloud: point cloud to textured mesh",
            "",
            machine.format(load=os.getloadavg()[0]),
            "",
            "Input: the 8,171 vertices of bunny.ply with synthetic sRGB colours that are functions of position: "
            "'smooth' (a few periods across the model) and 'stripes' (periods of about 12 point spacings). Colour "
            "errors are mean absolute differences in 8-bit sRGB levels (0-255), looked up bilinearly in the texture "
            "at the UV of each point's closest surface point. 'MAE at the points': the mesh built from all points, "
            "measured at those points (reproduction). 'MAE held-out 10%': the mesh built from 90% of the points, "
            "measured at the other 10% (prediction); the first row of each block is the limit of that prediction "
            "for the colour signal at this density (inverse-distance weighting of the 3 nearest other points, "
            "what the texture does per texel). 'texture' is the atlas side (8x8 texels per pair of triangles). "
            "Times (seconds) are for the all-points run; Open3D's import is excluded by a warm-up. 'implicit' = "
            "narrow-band signed distance + marching tetrahedra (numpy/scipy only) simplified with Open3D's quadric "
            "decimation; 'implicit (no Open3D)' = the same with vertex clustering: the path taken without Open3D.",
            "",
            *rows,
            "",
        ]
        (out / f"meshify{suffix}.md").write_text("\n".join(text))
        print(f"wrote {out / f'meshify{suffix}.md'}")
    if args.part in ("all", "normals"):
        rows = bench_normals(args.quick)
        text = [
            "# estimate_normals and normals_from_mesh",
            "",
            machine.format(load=os.getloadavg()[0]),
            "",
            "Points on a unit sphere. PCA on the 16 nearest neighbours; 'propagate' orients over a minimum spanning "
            "tree of the kNN graph (outwards), 'viewpoint' towards the centre; None = unoriented (error measured up "
            "to sign). normals_from_mesh: points within 2% of an icosphere (20,480 faces), interpolated normals.",
            "",
            *rows,
            "",
        ]
        (out / f"meshify_normals{suffix}.md").write_text("\n".join(text))
        print(f"wrote {out / f'meshify_normals{suffix}.md'}")
    if args.part in ("all", "render"):
        render_figure(out)


if __name__ == "__main__":
    main()
