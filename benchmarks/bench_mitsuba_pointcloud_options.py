"""Large point clouds in Mitsuba 3.9: the representations one could use, measured (issue 17).

Scene: ``testing.pointcloud_scene(n)`` (points on a unit sphere, point_size 0.03 -> radius 0.015, per-point
colours, sun + background), 128x128, 16 spp. Each case runs in its own process: ``first`` = seconds from the
scene to the first image (translation, ``mi.load_dict`` and render), ``RSS`` = the process's peak resident
memory. ``mis-hits`` = the share of 4,000 rays from the camera, aimed within 1.2 radii of random points,
whose hit/miss differs from the exact ray-sphere answer (float64), and ``t err`` the share of agreeing hits
whose distance is off by more than 5 % of the radius: the geometric accuracy of the representation.

Representations: ``mesh`` (before issue 17, for clouds beyond ``max_analytic_spheres``: the IR's merged
icosphere mesh, 80 triangles per point; run up to ``--mesh-max`` points: at 1M in scalar_rgb it took 198 s
and ~11 GB), ``backend`` (what ``bf.render(..., "mitsuba")`` does now: in scalar_rgb analytic spheres up
to 100,000 points, beyond that, and in llvm_ad_rgb beyond 500, one ``linearcurve`` shape of sphere-capped
capsules, :mod:`blendify_mitsuba.points`), ``ellipsoids`` (Mitsuba's ``ellipsoids`` shape: one shape,
analytic, but see its mis-hits), ``cycles`` (the Cycles backend, for the time budget: the goal is <= 3x
its first render and <= 2 GB).

Run: ``uv run --no-sync python benchmarks/bench_mitsuba_pointcloud_options.py [--sizes 100000 1000000]``;
writes ``benchmarks/results/mitsuba_pointcloud_options.{md,json}``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"
RES = (128, 128)
SPP = 16


def _points(n: int) -> tuple[Any, np.ndarray, float, np.ndarray]:
    from blendify_core import testing

    scene = testing.pointcloud_scene(n, RES)
    pc = scene.renderables["points"]
    centres = np.asarray(pc.vertices, dtype=np.float64)
    return scene, centres, float(pc.radii()[0]), np.asarray(scene.camera.translation, dtype=np.float64)


def _base_dict(mi: Any, scene: Any) -> dict[str, Any]:
    """Camera, lights and integrator of ``scene`` as the backend translates them (without the renderables)."""
    from blendify_mitsuba.translate import MitsubaContext, MitsubaTranslator

    from blendify_core.pipeline.settings import resolve_settings

    tr = MitsubaTranslator(resolve_settings(samples=SPP))
    ctx = MitsubaContext(scene=scene)
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 14, "hide_emitters": True},
        "sensor": tr.sensor(ctx),
    }
    d.update(tr.emitters(ctx))
    return d


def run_case(kind: str, n: int, variant: str) -> dict[str, Any]:
    """One case in this process: first-render time, peak RSS, mean/coverage, ray accuracy."""
    import resource

    t0 = time.perf_counter()
    scene, centres, r, cam = _points(n)
    colors = np.asarray(scene.renderables["points"].colors_list[0].linear_rgba[:, :3], dtype=np.float32)
    n = len(centres)
    t_scene = time.perf_counter() - t0
    t0 = time.perf_counter()
    native_scene = None
    if kind == "cycles":
        import blendify_core as bf

        img = bf.render(scene, "cycles", samples=SPP).rgba
    elif kind in ("backend", "mesh"):
        from blendify_mitsuba import MitsubaBackend
        from blendify_mitsuba import translate as mtr

        import blendify_core as bf

        opts: dict[str, Any] = {"variant": variant}
        if kind == "mesh":  # the representation before issue 17: the IR's merged icosphere mesh
            opts["max_analytic_spheres"] = 0
            mtr.curves_fit = lambda *a: "benchmark: the merged mesh"  # type: ignore[assignment]
        b = MitsubaBackend(**opts)
        img = bf.render(scene, b, samples=SPP).rgba
        native_scene = b.session._native.scene if b.session._native is not None else None
    else:
        import mitsuba as mi

        mi.set_variant(variant)
        d = _base_dict(mi, scene)
        if kind == "ellipsoids":
            d["points"] = {
                "type": "ellipsoids",
                "centers": mi.TensorXf(centres.astype(np.float32)),
                "scales": mi.TensorXf(np.full((n, 3), r, np.float32)),
                "quaternions": mi.TensorXf(np.tile(np.array([0, 0, 0, 1], np.float32), (n, 1))),
                "extent": 1.0,
                "bsdf": {"type": "diffuse"},
            }
        else:
            from blendify_mitsuba.points import curve_points, point_bitmap

            bsdf = {"type": "diffuse", "reflectance": mi.load_dict(point_bitmap(colors))}
            d["points"] = curve_points(centres, np.full(n, r), bsdf)
        native_scene = mi.load_dict(d)
        img = np.array(mi.render(native_scene, spp=SPP))
    first = time.perf_counter() - t0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    out = {
        "kind": kind,
        "n": n,
        "variant": variant if kind != "cycles" else "-",
        "first": first,
        "scene_build": t_scene,
        "rss_gb": rss,
        "mean": float(np.asarray(img)[..., :3].mean()),
    }
    if native_scene is not None:
        out.update(_accuracy(native_scene, centres, r, cam))
    return out


def _accuracy(scene: Any, centres: np.ndarray, r: float, cam: np.ndarray, rays: int = 4000) -> dict[str, float]:
    """Mis-hit share and distance errors of camera rays against the exact spheres (vectorised in numpy)."""
    import drjit as dr
    import mitsuba as mi
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(1)
    tgt = centres[rng.integers(0, len(centres), rays)] + rng.normal(size=(rays, 3)) * r * 0.7
    d = tgt - cam
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    # exact: candidate spheres near each ray (the k nearest centres to points sampled along the ray's end)
    tree = cKDTree(centres)
    exact_t = np.full(rays, np.inf)
    dist_to_tgt = np.linalg.norm(tgt - cam, axis=1)
    for s in np.linspace(-2.5, 2.5, 72):  # sample the ray around its target (the points lie on the unit sphere)
        p = cam + d * (dist_to_tgt + s * 1.0)[:, None]
        near = tree.query_ball_point(p, r * 1.0 + 0.04)
        for i, cand in enumerate(near):
            if not cand:
                continue
            oc = cam - centres[cand]
            b = oc @ d[i]
            c = (oc**2).sum(1) - r * r
            disc = b * b - c
            ok = disc >= 0
            if ok.any():
                t = -b[ok] - np.sqrt(disc[ok])
                t = t[t > 0]
                if len(t):
                    exact_t[i] = min(exact_t[i], float(t.min()))
    if dr.is_jit_v(mi.Float):
        ray = mi.Ray3f(
            mi.Point3f(*[mi.Float(np.full(rays, c)) for c in cam]), mi.Vector3f(*[mi.Float(d[:, j]) for j in range(3)])
        )
        si = scene.ray_intersect(ray)
        got_t = np.where(np.array(si.is_valid()), np.array(si.t), np.inf)
    else:
        got_t = np.full(rays, np.inf)
        for i in range(rays):
            si = scene.ray_intersect(mi.Ray3f(cam.tolist(), d[i].tolist()))
            if si.is_valid():
                got_t[i] = float(si.t)
    hit_e, hit_g = np.isfinite(exact_t), np.isfinite(got_t)
    both = hit_e & hit_g
    return {
        "mis_hits": float((hit_e != hit_g).mean()),
        "t_err_5pct": float((np.abs(got_t[both] - exact_t[both]) > 0.05 * r).mean()) if both.any() else 0.0,
        "exact_hits": float(hit_e.mean()),
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[100000, 1000000])
    ap.add_argument("--case", nargs=3, default=None, help=argparse.SUPPRESS)  # kind n variant (child)
    ap.add_argument("--mesh-max", type=int, default=100000, help="largest n for the merged mesh (slow)")
    args = ap.parse_args()
    if args.case is not None:
        print("CASE" + json.dumps(run_case(args.case[0], int(args.case[1]), args.case[2])), flush=True)
        return
    variants = ["scalar_rgb", "llvm_ad_rgb"]
    rows: list[dict[str, Any]] = []
    load0 = os.getloadavg()[0]
    for n in args.sizes:
        cases = [("cycles", "-")]
        for v in variants:
            if n <= args.mesh_max:
                cases.append(("mesh", v))
            cases += [("backend", v), ("ellipsoids", v)]
        for kind, v in cases:
            cmd = [sys.executable, __file__, "--case", kind, str(n), v]
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
            line = [x for x in proc.stdout.splitlines() if x.startswith("CASE")]
            row = (
                json.loads(line[-1][4:]) if line else {"kind": kind, "n": n, "variant": v, "error": proc.stderr[-300:]}
            )
            rows.append(row)
            print(row, flush=True)
    write(rows, (load0, os.getloadavg()[0]))


def write(rows: list[dict[str, Any]], load: tuple[float, float]) -> None:
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "mitsuba_pointcloud_options.json").write_text(json.dumps(rows, indent=1))
    lines = [
        "# Large point clouds in Mitsuba 3.9.1: representations measured",
        "",
        f"`testing.pointcloud_scene(n)` (radius 0.015), {RES[0]}x{RES[1]}, {SPP} spp; one process per case. "
        "first = scene -> first image (s); RSS = peak resident memory; mis-hits = share of 4,000 camera rays "
        "aimed near points whose hit/miss differs from the exact spheres; t err = share of hits more than 5 % of "
        f"the radius off. Machine: {platform.machine()}, 2 cores shared with other jobs (load average "
        f"{load[0]:.1f} -> {load[1]:.1f}): times are indicative. mitsuba {metadata.version('mitsuba')}. "
        "Script: `benchmarks/bench_mitsuba_pointcloud_options.py`.",
        "",
        "| n | representation | variant | first (s) | RSS (GB) | mean | mis-hits | t err > 5 % r |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['n']} | {r['kind']} | {r['variant']} | failed: {r['error'][-80:]!r} | | | | |")
            continue
        acc = (f"{100 * r['mis_hits']:.2f} %", f"{100 * r['t_err_5pct']:.2f} %") if "mis_hits" in r else ("-", "-")
        lines.append(
            f"| {r['n']} | {r['kind']} | {r['variant']} | {r['first']:.2f} | {r['rss_gb']:.2f} | {r['mean']:.4f} | "
            f"{acc[0]} | {acc[1]} |"
        )
    lines += [
        "",
        "Not run here (too slow / too big for this machine's shared memory): the merged mesh at 1,000,000 points, "
        "measured before issue 17 in scalar_rgb at 198 s and ~11 GB for the first render. Goal: <= 3x Cycles' "
        "first render and <= 2 GB. `ellipsoids` hits spheres of this size at the wrong distance (Mitsuba 3.9.1), "
        "so its time is no option. Plot: `mitsuba_pointcloud_options.png`.",
    ]
    (RESULTS / "mitsuba_pointcloud_options.md").write_text("\n".join(lines) + "\n")
    plot(rows)


def plot(rows: list[dict[str, Any]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if "error" not in r]
    sizes = sorted({r["n"] for r in ok})
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    for ax, key, label in ((axes[0], "first", "first render (s)"), (axes[1], "rss_gb", "peak RSS (GB)")):
        names = list(dict.fromkeys(f"{r['kind']} {r['variant']}".replace(" -", "") for r in ok))
        width = 0.8 / len(names)
        for i, name in enumerate(names):
            vals = [
                next((r[key] for r in ok if r["n"] == n and f"{r['kind']} {r['variant']}".replace(" -", "") == name), 0)
                for n in sizes
            ]
            ax.bar(np.arange(len(sizes)) + i * width, vals, width, label=name)
        ax.set_xticks(np.arange(len(sizes)) + 0.4 - width / 2)
        ax.set_xticklabels([f"{n:,} points" for n in sizes])
        ax.set_yscale("log")
        ax.set_ylabel(label)
    axes[1].axhline(2.0, color="r", ls="--", lw=0.8)
    axes[0].legend(fontsize=7)
    fig.suptitle("Mitsuba point clouds: mesh = before issue 17, backend = now (capsule curves beyond the limit)")
    fig.tight_layout()
    fig.savefig(RESULTS / "mitsuba_pointcloud_options.png", dpi=110)


if __name__ == "__main__":
    main()
