"""Large point clouds in Mitsuba 3.9: the representations one could use, measured (issue 17).

Scene: ``testing.pointcloud_scene(n)`` (points on a unit sphere, point_size 0.03 -> radius 0.015, per-point
colours, sun + background), 128x128, 16 spp. Each case runs in its own process, ``--rounds`` times, the cases
interleaved (paired under the machine's changing load): ``first`` = seconds from the scene to the first image
(importing the engine, translation, ``mi.load_dict`` and render), ``warm`` = a second render of the same scene
in the same process (the backends reuse their translation), ``RSS`` = the process's peak resident memory.
For the backend, ``first`` is split into its phases (import + variant, translation, ``mi.load_dict`` =
Embree's BVH build, ``mi.render``). ``mis-hits`` = the share of 4,000 rays from the camera, aimed within 1.2
radii of random points, whose hit/miss differs from the exact ray-sphere answer (float64), and ``t err`` the
share of agreeing hits whose distance is off by more than 5 % of the radius: the geometric accuracy.

Representations: ``mesh`` (before issue 17, for clouds beyond ``max_analytic_spheres``: the IR's merged
icosphere mesh, 80 triangles per point; run up to ``--mesh-max`` points, else its rows are carried over from
the previous results: at 1M in scalar_rgb it took 198 s and ~11 GB), ``before`` (the capsule curves as first
built for issue 17: a spacer segment of radius 0 per point, so Embree's BVH holds 2N segments), ``backend``
(what ``bf.render(..., "mitsuba")`` does now: one ``linearcurve`` shape of capsules whose spacers are one
shared segment Embree leaves out, :mod:`blendify_mitsuba.points`), ``ellipsoids`` (Mitsuba's ``ellipsoids``
shape: one shape, analytic, but see its mis-hits), ``cycles`` (the Cycles backend: the goal is <= 3x its
first render and <= 2 GB).

Run: ``uv run --no-sync python benchmarks/bench_mitsuba_pointcloud_options.py [--sizes 100000 1000000]``;
writes ``benchmarks/results/mitsuba_pointcloud_options.{md,json,png}``. ``llvm_ad_rgb`` needs a libLLVM >= 16
(the ``mitsuba-llvm`` extra); without one its cases fail and say so.
"""

from __future__ import annotations

import argparse
import contextlib
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


def _curves_before(centres: np.ndarray, radii: np.ndarray, bsdf: Any, length: float = 1e-2) -> Any:
    """The capsule layout first built for issue 17 (kept here for the before/after rows): three control
    points per point, the capsule from the centre 1 % of the radius along z, then a spacer segment of radius
    0 per point (2N segments in Embree's BVH)."""
    from blendify_mitsuba.points import curve_shape

    n = len(centres)
    r = np.asarray(radii, dtype=np.float64) / np.sqrt(1.0 + 1e-2 / 2.0)
    cp = np.empty((n, 3, 4), np.float32)
    cp[:, :, :3] = np.asarray(centres, dtype=np.float64)[:, None, :]
    cp[:, 1:, 2] += (r * 1e-2)[:, None]
    cp[:, :2, 3] = r[:, None]
    cp[:, 2, 3] = 0.0
    base = np.arange(n, dtype=np.uint32) * 3
    return curve_shape(cp.reshape(-1, 4), np.stack([base, base + 1], axis=1), bsdf)


def _timed(module: Any, name: str, phases: dict[str, float]) -> None:
    """Wrap ``module.name`` so that its calls add their seconds to ``phases[name]``."""
    original = getattr(module, name)

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        import drjit as dr

        t0 = time.perf_counter()
        try:
            out = original(*args, **kwargs)
            dr.eval(out)  # the JIT variants evaluate lazily: count the kernels here, not where they are read
            dr.sync_thread()
            return out
        finally:
            phases[name] = phases.get(name, 0.0) + time.perf_counter() - t0

    setattr(module, name, wrapper)


def run_case(kind: str, n: int, variant: str, accuracy: bool) -> dict[str, Any]:
    """One case in this process: first-render time (and its phases), warm render, peak RSS, mean, accuracy."""
    import resource

    t0 = time.perf_counter()
    scene, centres, r, cam = _points(n)
    colors = np.asarray(scene.renderables["points"].colors_list[0].linear_rgba[:, :3], dtype=np.float32)
    n = len(centres)
    t_scene = time.perf_counter() - t0
    phases: dict[str, float] = {}
    t0 = time.perf_counter()
    native_scene = None
    warm: float | None = None
    if kind == "cycles":
        import blendify_core as bf

        img = bf.render(scene, "cycles", samples=SPP).rgba
        first = time.perf_counter() - t0
        t1 = time.perf_counter()
        bf.render(scene, "cycles", samples=SPP)
        warm = time.perf_counter() - t1
    elif kind in ("backend", "mesh", "before"):
        from blendify_mitsuba import MitsubaBackend
        from blendify_mitsuba import translate as mtr

        import blendify_core as bf

        opts: dict[str, Any] = {"variant": variant}  # backend: the default analytic-sphere limit
        if kind != "backend":
            opts["max_analytic_spheres"] = 0
        if kind == "mesh":  # the representation before issue 17: the IR's merged icosphere mesh
            mtr.curves_fit = lambda *a: "benchmark: the merged mesh"  # type: ignore[assignment]
        elif kind == "before":
            mtr.curve_points = _curves_before  # type: ignore[assignment]
        b = MitsubaBackend(**opts)
        mi = b.session.set_variant()  # import + variant (the first render would do it)
        phases["import"] = time.perf_counter() - t0
        _timed(mi, "load_dict", phases)
        _timed(mi, "render", phases)
        img = bf.render(scene, b, samples=SPP).rgba
        first = time.perf_counter() - t0
        phases["translate"] = first - sum(phases.values())
        t1 = time.perf_counter()
        bf.render(scene, b, samples=SPP)
        warm = time.perf_counter() - t1
        native_scene = b.session.native.scene if b.session.native is not None else None
    else:
        import mitsuba as mi

        mi.set_variant(variant)
        d = _base_dict(mi, scene)
        d["points"] = {
            "type": "ellipsoids",
            "centers": mi.TensorXf(centres.astype(np.float32)),
            "scales": mi.TensorXf(np.full((n, 3), r, np.float32)),
            "quaternions": mi.TensorXf(np.tile(np.array([0, 0, 0, 1], np.float32), (n, 1))),
            "extent": 1.0,
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": colors.mean(axis=0).tolist()}},
        }
        native_scene = mi.load_dict(d)
        img = np.array(mi.render(native_scene, spp=SPP))
        first = time.perf_counter() - t0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    out = {
        "kind": kind,
        "n": n,
        "variant": variant if kind != "cycles" else "-",
        "first": first,
        "warm": warm,
        "phases": phases,
        "scene_build": t_scene,
        "rss_gb": rss,
        "mean": float(np.asarray(img)[..., :3].mean()),
    }
    if native_scene is not None and accuracy:
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


def _median(rows: list[dict[str, Any]], key: str) -> float | None:
    vals = [r[key] for r in rows if r.get(key) is not None]
    return float(np.median(vals)) if vals else None


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[100000, 1000000])
    ap.add_argument("--case", nargs=4, default=None, help=argparse.SUPPRESS)  # kind n variant accuracy (child)
    ap.add_argument("--mesh-max", type=int, default=0, help="largest n for the merged mesh (slow)")
    ap.add_argument("--rounds", type=int, default=3, help="fresh processes per case (interleaved)")
    ap.add_argument("--variants", nargs="+", default=["scalar_rgb", "llvm_ad_rgb"])
    args = ap.parse_args()
    if args.case is not None:
        kind, n, variant, acc = args.case
        print("CASE" + json.dumps(run_case(kind, int(n), variant, acc == "1")), flush=True)
        return
    load0 = os.getloadavg()[0]
    cases: list[tuple[str, int, str]] = []
    for n in args.sizes:
        cases.append(("cycles", n, "-"))
        for v in args.variants:
            if n <= args.mesh_max:
                cases.append(("mesh", n, v))
            cases += [("before", n, v), ("backend", n, v), ("ellipsoids", n, v)]
    runs: dict[tuple[str, int, str], list[dict[str, Any]]] = {c: [] for c in cases}
    for rnd in range(args.rounds):
        for kind, n, v in cases:
            rounds = 1 if kind == "mesh" else args.rounds
            if rnd >= rounds:
                continue
            acc = "1" if rnd == 0 and kind != "cycles" else "0"
            cmd = [sys.executable, __file__, "--case", kind, str(n), v, acc]
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
            line = [x for x in proc.stdout.splitlines() if x.startswith("CASE")]
            row = (
                json.loads(line[-1][4:]) if line else {"kind": kind, "n": n, "variant": v, "error": proc.stderr[-300:]}
            )
            runs[(kind, n, v)].append(row)
            print(rnd, row, flush=True)
    rows: list[dict[str, Any]] = []
    for rs in runs.values():
        ok = [r for r in rs if "error" not in r]
        if not ok:
            rows.append(rs[-1])
            continue
        row = dict(ok[0])
        row["runs"] = len(ok)
        for key in ("first", "warm", "rss_gb"):
            row[key] = _median(ok, key)
        row["first_all"] = [r["first"] for r in ok]
        row["warm_all"] = [r["warm"] for r in ok if r.get("warm") is not None]
        row["phases"] = {k: float(np.median([r["phases"][k] for r in ok])) for k in ok[0].get("phases", {})}
        rows.append(row)
    if args.mesh_max < min(args.sizes):  # carry the slow mesh rows over from the previous results
        with contextlib.suppress(OSError, ValueError):
            old = json.loads((RESULTS / "mitsuba_pointcloud_options.json").read_text())
            rows = [dict(r, carried=True) for r in old if r.get("kind") == "mesh"] + rows
    write(rows, (load0, os.getloadavg()[0]), args.rounds)


def _fmt(x: float | None, digits: int = 2) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def write(rows: list[dict[str, Any]], load: tuple[float, float], rounds: int) -> None:
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "mitsuba_pointcloud_options.json").write_text(json.dumps(rows, indent=1))
    stamp = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    lines = [
        "# Large point clouds in Mitsuba 3.9.1: representations measured",
        "",
        f"`testing.pointcloud_scene(n)` (radius 0.015), {RES[0]}x{RES[1]}, {SPP} spp. Every case in a fresh "
        f"process, {rounds} rounds with the cases interleaved (medians; the range over the rounds in brackets). "
        "first = scene -> first image (s), engine import included; warm = the same scene rendered again in that "
        "process; RSS = peak resident memory; mis-hits = share of 4,000 camera rays aimed near points whose "
        "hit/miss differs from the exact spheres; t err = share of hits more than 5 % of the radius off. "
        f"Machine: {platform.machine()}, 2 cores shared with other jobs (load average {load[0]:.1f} -> "
        f"{load[1]:.1f}): compare rows of one run, not with other runs. mitsuba {metadata.version('mitsuba')}, "
        f"{stamp}. Script: `benchmarks/bench_mitsuba_pointcloud_options.py`.",
        "",
        "| n | representation | variant | first (s) | warm (s) | RSS (GB) | mean | mis-hits | t err > 5 % r |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['n']} | {r['kind']} | {r['variant']} | failed: {r['error'][-80:]!r} | | | | | |")
            continue
        acc = (f"{100 * r['mis_hits']:.2f} %", f"{100 * r['t_err_5pct']:.2f} %") if "mis_hits" in r else ("-", "-")
        span = r.get("first_all") or [r["first"]]
        first = f"{r['first']:.2f}" + (f" [{min(span):.1f}-{max(span):.1f}]" if len(span) > 1 else "")
        kind = r["kind"] + (" (previous run)" if r.get("carried") else "")
        lines.append(
            f"| {r['n']} | {kind} | {r['variant']} | {first} | {_fmt(r.get('warm'))} | {r['rss_gb']:.2f} | "
            f"{r['mean']:.4f} | {acc[0]} | {acc[1]} |"
        )
    phased = [r for r in rows if r.get("phases") and "error" not in r and not r.get("carried")]
    if phased:
        lines += [
            "",
            "Where the first render's time goes (medians, s): import = importing Mitsuba and setting the variant; "
            "translate = the IR -> dictionaries and shapes (the capsules' buffers are set in memory: no curve "
            "file); load_dict = `mi.load_dict` (Embree's BVH build); render = `mi.render`.",
            "",
            "| n | representation | variant | import | translate | load_dict | render | first |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for r in phased:
            ph = r["phases"]
            lines.append(
                f"| {r['n']} | {r['kind']} | {r['variant']} | {_fmt(ph.get('import'))} | "
                f"{_fmt(ph.get('translate'))} | {_fmt(ph.get('load_dict'))} | {_fmt(ph.get('render'))} | "
                f"{r['first']:.2f} |"
            )
    lines += [
        "",
        "Before this run's change, for comparison (previous run, load average 14-20, so slower throughout): "
        "the backend's first render at 1,000,000 points took 22.3 s (scalar_rgb) and 25.0 s (llvm_ad_rgb) "
        "against Cycles' 17.6 s, and at 100,000 points in scalar_rgb, then analytic spheres (the old "
        "limit of 100,000), 65.5 s against Cycles' 17.7 s; the `before` rows above are that capsule layout "
        "measured in this run. In the JIT variant the first process on a machine also compiles the kernels "
        "(Dr.Jit caches them on disk): the round ranges' upper ends.",
        "",
        "Against the goal (<= 3x Cycles, <= 2 GB), per size and variant:",
        "",
    ]
    for n in sorted({r["n"] for r in rows}):
        cyc = next((r for r in rows if r["n"] == n and r["kind"] == "cycles" and "error" not in r), None)
        for r in rows:
            if r["n"] != n or r["kind"] != "backend" or "error" in r or cyc is None:
                continue
            lines.append(
                f"- {n:,} points, {r['variant']}: first {r['first']:.2f} s = {r['first'] / cyc['first']:.2f}x "
                f"Cycles' first ({cyc['first']:.2f} s) and {r['first'] / cyc['warm']:.2f}x Cycles' warm "
                f"({cyc['warm']:.2f} s); warm {r['warm']:.2f} s = {r['warm'] / cyc['warm']:.2f}x Cycles' warm; "
                f"peak RSS {r['rss_gb']:.2f} GB."
            )
    lines += [
        "",
        "The goal is judged against Cycles' first render in a fresh process: the issue asks for the *first* render "
        "with translation included, and only a fresh process gives both engines the same start (each pays its "
        "engine import: Blender's bpy for Cycles, Mitsuba and its variant here). The warm columns compare the "
        "engines once both are loaded (second render in the same process); Mitsuba's first render against "
        "Cycles' warm render is the strictest reading and is listed too. Not run here (too slow / too big for "
        "this machine's shared memory): the merged mesh at 1,000,000 points, measured before issue 17 in "
        "scalar_rgb at 198 s and ~11 GB for the first render. `ellipsoids` hits spheres of this size at the wrong "
        "distance (Mitsuba 3.9.1: its intersection starts the quadratic from a point off the closest approach by "
        "the factor 1/scale, so small spheres lose single precision; correct at radius 1, all wrong at radius "
        "0.015 seen from 4 units, also when instanced at scale 0.015), so its time is no option. "
        "Plot: `mitsuba_pointcloud_options.png`.",
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
        ok = [r for r in ok if r.get(key) is not None]
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
    fig.suptitle(
        "Mitsuba point clouds: mesh = before issue 17, before = first capsule layout, backend = now", fontsize=10
    )
    fig.tight_layout()
    fig.savefig(RESULTS / "mitsuba_pointcloud_options.png", dpi=110)


if __name__ == "__main__":
    main()
