"""Batch rendering benchmarks (issue 10).

- ``throughput``: frames per minute of 100 small frames (64x48, a new random mesh each frame on the
  primitives scene) through ``bf.render_many`` with 1 and 2 local pool workers.
- ``memory``: RSS of one pool worker after each of 500 jobs (a new random mesh each job), without
  recycling and with ``recycle_after=N``; used to choose ``DEFAULT_RECYCLE_AFTER``.

Writes benchmarks/results/batch_<kind>_<backend>.{json,md,png}. The machine's load average is
recorded before and after each run (this machine is shared; read the numbers with it).

    uv run --no-sync python benchmarks/bench_batch.py throughput --backend mitsuba
    uv run --no-sync python benchmarks/bench_batch.py memory --backend mitsuba --jobs 500 --recycle 100
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

import blendify_core as bf
from blendify_core.ir.colors import UniformColors
from blendify_core.ir.materials import PrincipledBSDFMaterial
from blendify_core.testing import primitives_scene

RESULTS = Path(__file__).resolve().parent / "results"


def bench_scene(i: int, resolution: tuple[int, int] = (64, 48), n_points: int = 400) -> bf.Scene:
    """The primitives scene plus a random convex mesh (about 2 * n_points triangles) unique to job ``i``."""
    from scipy.spatial import ConvexHull

    rng = np.random.default_rng(i)
    scene = primitives_scene(resolution)
    pts = rng.normal(size=(n_points, 3))
    pts /= np.linalg.norm(pts, axis=1, keepdims=True)
    pts *= rng.uniform(0.8, 1.2, size=(n_points, 1)) * 0.35
    hull = ConvexHull(pts)
    faces = hull.simplices.astype(np.int32)
    # orient outwards
    centre = pts.mean(axis=0)
    v = pts[faces]
    normal = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    flip = np.einsum("ij,ij->i", normal, v.mean(axis=1) - centre) < 0
    faces[flip] = faces[flip][:, ::-1]
    colour = tuple(float(c) for c in rng.uniform(0.2, 0.9, 3))
    scene.renderables.add_mesh(
        pts, faces, PrincipledBSDFMaterial(), UniformColors(colour), translation=(0.5, -1.0, 0.4), tag=f"blob{i}"
    )
    return scene


def _machine() -> dict[str, Any]:
    return {
        "platform": platform.platform(),
        "python": platform.python_version(),
        "cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
    }


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def choose_backend(requested: str | None) -> str:
    if requested:
        return requested
    status = bf.available_backends()
    for name in ("cycles", "mitsuba", "pyrender"):
        if name in status and status[name].available:
            return name
    raise SystemExit("no backend available")


def _loop(paths: list[Path], out: Path, backend: str, samples: int) -> tuple[int, list[float]]:
    """The reference: bf.render in a plain loop in this process (no pool, no manifest)."""
    times = []
    for i, p in enumerate(paths):
        t = time.perf_counter()
        bf.render(bf.Scene.load(p), backend=backend, samples=samples).save(out / f"f{i}.png")
        times.append(time.perf_counter() - t)
    return len(paths), times


def run_throughput(
    backend: str,
    frames: int,
    samples: int,
    configs: list[tuple[str, int]],
    repeat: int = 1,
    resolution: tuple[int, int] = (64, 48),
) -> dict[str, Any]:
    scenes_dir = Path(tempfile.mkdtemp(prefix="bench-batch-scenes-"))
    paths = []
    for i in range(frames):
        p = scenes_dir / f"s{i}.npz"
        bench_scene(i, resolution).save(p)
        paths.append(p)
    cores = _machine()["cores"]
    runs = []
    for round_ in range(repeat):  # rounds interleave the configurations, so load changes hit them all
        for executor, workers in configs:
            out = Path(tempfile.mkdtemp(prefix="bench-batch-out-"))
            jobs = [bf.RenderJob(p, out / f"f{i}.png", backend=backend, samples=samples) for i, p in enumerate(paths)]
            if executor == "ray":
                os.environ.setdefault("RAY_ENABLE_UV_RUN_RUNTIME_ENV", "0")
                import ray

                if not ray.is_initialized():  # started outside the timing, as on a real cluster
                    ray.init(num_cpus=cores, include_dashboard=False, log_to_driver=False)
            load_before = _load()
            t0 = time.perf_counter()
            if executor == "loop":
                done, per_job = _loop(paths, out, backend, samples)
                failed, first_failure = 0, None
            else:
                report = bf.render_many(jobs, executor=executor, workers=workers, progress=False)
                done, failed = report.counts["done"], report.counts["failed"]
                per_job = [j.seconds for j in report if j.seconds is not None]
                first_failure = report.failed[0].reason if report.failed else None
            wall = time.perf_counter() - t0
            row = {
                "executor": executor,
                "workers": workers,
                "threads_per_job": max(1, cores // workers),
                "frames": frames,
                "done": done,
                "failed": failed,
                "wall_s": wall,
                "frames_per_min": 60.0 * done / wall,
                "median_job_s": float(np.median(per_job)) if per_job else None,
                "load_before": load_before,
                "load_after": _load(),
                "first_failure": first_failure,
                "round": round_,
            }
            print(json.dumps(row))
            runs.append(row)
    return {
        "kind": "throughput",
        "backend": backend,
        "samples": samples,
        "resolution": list(resolution),
        "machine": _machine(),
        "runs": runs,
    }


def run_memory(backend: str, jobs_n: int, samples: int, recycle_list: list[int | None]) -> dict[str, Any]:
    runs = []
    for recycle in recycle_list:
        out = Path(tempfile.mkdtemp(prefix="bench-batch-mem-"))
        jobs = [
            bf.RenderJob(bench_scene(i), out / f"f{i}.png", backend=backend, samples=samples) for i in range(jobs_n)
        ]
        load_before = _load()
        t0 = time.perf_counter()
        report = bf.render_many(jobs, workers=1, recycle_after=recycle, progress=False, manifest=False)
        wall = time.perf_counter() - t0
        rss = [j.rss_mb for j in report]
        workers = [j.worker for j in report]
        row = {
            "recycle_after": recycle,
            "jobs": jobs_n,
            "done": report.counts["done"],
            "failed": report.counts["failed"],
            "wall_s": wall,
            "frames_per_min": 60.0 * report.counts["done"] / wall,
            "rss_mb": rss,
            "seconds": [j.seconds for j in report],
            "worker": workers,
            "load_before": load_before,
            "load_after": _load(),
            "first_failure": report.failed[0].reason if report.failed else None,
        }
        valid = [r for r in rss if r is not None]
        print(
            json.dumps(
                {k: v for k, v in row.items() if k not in ("rss_mb", "worker", "seconds")}
                | {"rss_first": valid[:1], "rss_last": valid[-1:], "rss_max": max(valid) if valid else None}
            )
        )
        runs.append(row)
    return {"kind": "memory", "backend": backend, "samples": samples, "machine": _machine(), "runs": runs}


def _slope(rss: list[float | None], start: int) -> float | None:
    y = np.array([r for r in rss[start:] if r is not None], dtype=float)
    if len(y) < 10:
        return None
    x = np.arange(len(y), dtype=float)
    return float(np.polyfit(x, y, 1)[0])


def _aggregate(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (executor, workers): the median run by frames/min, with the range over the rounds."""
    groups: dict[tuple[str, int], list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r.get("executor", "local"), r["workers"]), []).append(r)
    out = []
    for group in groups.values():
        ordered = sorted(group, key=lambda r: r["frames_per_min"])
        med = dict(ordered[len(ordered) // 2])
        fpm = [r["frames_per_min"] for r in group]
        med["all_fpm"] = fpm
        med["fpm_range"] = f"{min(fpm):.0f}-{max(fpm):.0f}, n={len(fpm)}"
        out.append(med)
    return out


def write_throughput(data: dict[str, Any]) -> None:
    res = tuple(data.get("resolution", (64, 48)))
    size = f"{res[0]}x{res[1]}"
    name = f"batch_throughput_{data['backend']}" + ("" if res == (64, 48) else f"_{size}")
    (RESULTS / f"{name}.json").write_text(json.dumps(data, indent=1))
    m = data["machine"]
    lines = [
        f"# Batch throughput: {data['backend']}, {data['runs'][0]['frames']} frames of {size}, "
        f"{data['samples']} samples",
        "",
        f"`bf.render_many` with the local process pool (scene files on disk, PNG outputs, JSON-lines manifest), "
        f"{m['cores']} cores, {m['platform']}, Python {m['python']}. Each frame is the primitives scene plus a "
        "random convex mesh unique to the frame. Wall time includes starting the workers and the engine.",
        "",
        "| executor | workers | threads/job | done | failed | wall (s) | frames/min (range) | median job (s) | "
        "load avg before -> after |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    runs = _aggregate(data["runs"])
    for r in runs:
        lines.append(
            f"| {r.get('executor', 'local')} | {r['workers']} | {r['threads_per_job']} | {r['done']} | "
            f"{r['failed']} | {r['wall_s']:.1f} | "
            f"**{r['frames_per_min']:.1f}** ({r['fpm_range']}) | {r['median_job_s']:.3f} | "
            f"{r['load_before']} -> {r['load_after']} |"
        )
    local = {r["workers"]: r for r in runs if r.get("executor", "local") == "local"}
    if 1 in local and 2 in local and local[1]["frames_per_min"] > 0:
        speedup = local[2]["frames_per_min"] / local[1]["frames_per_min"]
        lines += ["", f"Local pool, 2 vs 1 worker: {speedup:.2f}x."]
    lines += [
        "",
        "`loop` is the reference: `bf.render` + `result.save` in a plain loop in one process (engine threads = "
        "default). For `ray`, Ray was started before the timing (as on a running cluster); `median job` is "
        "the worker-side time of one job (scene load, render, PNG write).",
    ]
    lines += [
        "",
        "The load average is the machine's (1, 5, 15 min); other work was running on this shared machine, "
        "so absolute numbers are pessimistic and the 1-vs-2 comparison is only indicative.",
        "",
    ]
    (RESULTS / f"{name}.md").write_text("\n".join(lines))
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is missing: no plot written")
        return
    fig, ax = plt.subplots(figsize=(4.5, 3.2))
    labels = [f"{r.get('executor', 'local')}\n{r['workers']} worker(s)" for r in runs]
    heights = [r["frames_per_min"] for r in runs]
    ax.bar(labels, heights, color="#4477aa")
    for k, r in enumerate(runs):
        ax.plot([k] * len(r["all_fpm"]), r["all_fpm"], "k.", ms=4)
    ax.set_ylabel("frames per minute")
    ax.set_title(f"render_many throughput ({data['backend']})")
    fig.tight_layout()
    fig.savefig(RESULTS / f"{name}.png", dpi=120)
    plt.close(fig)


def write_memory(data: dict[str, Any]) -> None:
    name = f"batch_memory_{data['backend']}"
    (RESULTS / f"{name}.json").write_text(json.dumps(data))
    m = data["machine"]
    lines = [
        f"# Worker memory over {data['runs'][0]['jobs']} jobs: {data['backend']}, 64x48, {data['samples']} samples",
        "",
        f"One local pool worker renders every job (a new random mesh on the primitives scene each time); its RSS is "
        f"read from /proc after each job. {m['cores']} cores, {m['platform']}.",
        "",
        "| recycle_after | done | failed | wall (s) | frames/min | RSS after job 1 (MiB) | RSS max (MiB) | "
        "RSS last (MiB) | growth (MiB/job, after job 20, one process) | workers used | median job s, jobs 2-100 | "
        "median job s, jobs 401-500 | first job of a fresh worker (s, mean) | load avg before -> after |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for r in data["runs"]:
        rss = r["rss_mb"]
        valid = [x for x in rss if x is not None]
        first_worker = next((w for w, x in zip(r["worker"], rss) if x is not None), None)
        own = [x for x, w in zip(rss, r["worker"]) if w == first_worker]
        slope = _slope(own, 20)
        secs = r.get("seconds") or [None] * len(rss)
        early = [x for x in secs[1:100] if x is not None]
        late = [x for x in secs[400:500] if x is not None]
        firsts = [x for k, x in enumerate(secs) if x is not None and (k == 0 or r["worker"][k] != r["worker"][k - 1])]

        def med(v: list[float]) -> str:
            return f"{np.median(v):.3f}" if v else "n/a"

        timing = f"{med(early)} | {med(late)} | {f'{np.mean(firsts):.2f}' if firsts else 'n/a'}"
        lines.append(
            f"| {r['recycle_after'] or 'never'} | {r['done']} | {r['failed']} | {r['wall_s']:.1f} | "
            f"{r['frames_per_min']:.1f} | {valid[0]:.0f} | {max(valid):.0f} | {valid[-1]:.0f} | "
            f"{'n/a' if slope is None else f'{slope:.3f}'} | {len(set(r['worker']) - {None})} | {timing} | "
            f"{r['load_before']} -> {r['load_after']} |"
        )
    lines.append("")
    (RESULTS / f"{name}.md").write_text("\n".join(lines))
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is missing: no plot written")
        return
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 3.6))
    for r in data["runs"]:
        label = f"recycle_after={r['recycle_after']}" if r["recycle_after"] else "no recycling"
        ax.plot(np.arange(1, len(r["rss_mb"]) + 1), [np.nan if x is None else x for x in r["rss_mb"]], label=label)
        if r.get("seconds"):
            t = np.array([np.nan if x is None else x for x in r["seconds"]], dtype=float)
            k = 25
            smooth = [np.nanmedian(t[max(0, i - k) : i + 1]) for i in range(len(t))]
            ax2.plot(np.arange(1, len(t) + 1), smooth, label=label)
    ax2.set_xlabel("job")
    ax2.set_ylabel("job time (s, running median of 25)")
    ax2.set_title("worker-side job time")
    ax2.legend()
    ax.set_xlabel("job")
    ax.set_ylabel("worker RSS after the job (MiB)")
    ax.set_title(f"pool worker memory ({data['backend']})")
    ax.legend()
    fig.tight_layout()
    fig.savefig(RESULTS / f"{name}.png", dpi=120)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("kind", choices=("throughput", "memory"))
    parser.add_argument("--backend", default=None, help="default: cycles, else mitsuba, else pyrender")
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--jobs", type=int, default=500)
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--repeat", type=int, default=3, help="rounds of the throughput configurations")
    parser.add_argument("--resolution", default="64x48", help="frame size of the throughput runs, WxH")
    parser.add_argument(
        "--configs", default="loop:1,local:1,local:2,ray:2", help="executor:workers list (loop = plain bf.render loop)"
    )
    parser.add_argument("--recycle", type=int, default=100, help="recycle_after of the recycling run")
    parser.add_argument("--rewrite", action="store_true", help="rewrite the table and plot from the saved JSON")
    args = parser.parse_args()
    RESULTS.mkdir(parents=True, exist_ok=True)
    backend = choose_backend(args.backend)
    if args.rewrite:
        suffix = "" if args.kind == "memory" or args.resolution == "64x48" else f"_{args.resolution}"
        data = json.loads((RESULTS / f"batch_{args.kind}_{backend}{suffix}.json").read_text())
        (write_throughput if args.kind == "throughput" else write_memory)(data)
        return
    if args.kind == "throughput":
        configs = [(c.split(":")[0], int(c.split(":")[1])) for c in args.configs.split(",")]
        res = tuple(int(v) for v in args.resolution.lower().split("x"))
        data = run_throughput(backend, args.frames, args.samples, configs, args.repeat, res)  # type: ignore[arg-type]
        write_throughput(data)
    else:
        data = run_memory(backend, args.jobs, args.samples, [None, args.recycle])
        write_memory(data)


if __name__ == "__main__":
    main()
