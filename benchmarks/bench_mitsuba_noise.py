"""Equal-sample noise: Mitsuba vs Cycles, per scene and light type, before -> after issue 17's fixes.

Noise = the per-pixel standard deviation over ``--seeds`` renders with different seeds (same scene, same
samples), averaged over the image and divided by the image mean (linear premultiplied RGB). Scenes: a
diffuse sphere on a plane lit by (a) a sun, (b) a sun + background 0.3, (c) an area light, (d) an
environment map (a sky gradient with a small bright sun patch), and every scene of
``benchmarks/accuracy_vs_time.py``.

Mitsuba configurations: ``before`` = the ``independent`` sampler and the uniform background sampled as
often as any other emitter (the defaults before issue 17: ``translate.BACKGROUND_SAMPLING_WEIGHT`` set back
to 1 here), ``after`` = the defaults (``multijitter``, background weight 1e-3); each in ``scalar_rgb`` and,
where its libLLVM works, ``llvm_ad_rgb``. ``time`` = median seconds per render (translation cached, the
first render of each configuration not counted); ``equal-error time`` = time x (noise / Cycles' noise)^2,
the time to reach Cycles' noise at this spp if the error falls as 1/sqrt(spp) (conservative for the
stratified ``multijitter``, whose error falls faster).

Run: ``uv run --no-sync python benchmarks/bench_mitsuba_noise.py [--spp 16 --seeds 6 --res 96]``; writes
``benchmarks/results/mitsuba_noise.{md,json,png}`` (``--tag _256 --res 256 --only bunny``:
``mitsuba_noise_256.*``, the larger images where the per-render overheads matter less).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

import blendify_core as bf
from blendify_core import testing

RESULTS = Path(__file__).resolve().parent / "results"
sys.path.insert(0, str(Path(__file__).resolve().parent))


def sky(h: int = 64, w: int = 128) -> np.ndarray:
    """An equirectangular sky: a blue gradient, a darker lower half and a small bright patch (a sun)."""
    v = (np.arange(h) + 0.5) / h
    img = np.zeros((h, w, 3), np.float32)
    img[:] = (0.2 + 0.6 * (1 - v))[:, None, None] * np.array([0.5, 0.7, 1.0], np.float32)
    img[v > 0.5] *= 0.3
    cy, cx = int(h * 0.25), int(w * 0.3)
    img[cy - 2 : cy + 2, cx - 3 : cx + 3] = 50.0
    return img


def sphere_scene(light: str, res: tuple[int, int]) -> bf.Scene:
    """A diffuse sphere on a diffuse plane lit by ``light``: sun, sun_bg, area or env."""
    s = bf.Scene()
    s.renderables.add_plane_mesh(6.0, bf.DiffuseMaterial(), bf.UniformColors((0.6, 0.6, 0.6)), tag="ground")
    s.renderables.add_sphere_nurbs(
        0.5, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.4, 0.2)), translation=(0, 0, 0.5), tag="ball"
    )
    testing.look_at_camera(s, res, (2.2, -2.6, 1.8), (0, 0, 0.4))
    if light in ("sun", "sun_bg"):
        s.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    if light == "sun_bg":
        s.lights.set_background_light(0.3)
    if light == "area":
        s.lights.add_area(
            "square", 0.8, strength=60.0, rotation_mode="look_at", rotation=(0, 0, 0.5), translation=(0.8, -0.6, 2.0)
        )
    if light == "env":
        s.lights.set_environment_map(sky(), strength=1.0)
    return s


def all_scenes(res: int) -> dict[str, bf.Scene]:
    from accuracy_vs_time import scenes as accuracy_scenes

    out = {f"sphere on plane: {k}": sphere_scene(k, (res, res * 3 // 4)) for k in ("sun", "sun_bg", "area", "env")}
    for name, (scene, _kind) in accuracy_scenes(res).items():
        out[name] = scene
    return out


def measure(scene: bf.Scene, backend: Any, spp: int, seeds: int) -> dict[str, float]:
    imgs, times = [], []
    for seed in range(seeds + 1):
        t0 = time.perf_counter()
        r = bf.render(scene, backend, samples=spp, seed=seed, max_bounces=12, denoise=False, pixel_filter="box")
        times.append(time.perf_counter() - t0)
        if seed > 0:  # the first render (translation, JIT compilation) is not counted
            imgs.append(r.rgba[..., :3].astype(np.float64))
    a = np.stack(imgs)
    mean = float(a.mean())
    return {"noise": float(a.std(0, ddof=1).mean() / mean), "time": statistics.median(times[1:]), "mean": mean}


def configs(variants: list[str]) -> list[tuple[str, str, dict[str, Any], bool]]:
    out: list[tuple[str, str, dict[str, Any], bool]] = [("cycles", "cycles", {}, False)]
    for v in variants:
        out.append((f"mitsuba {v} before", "mitsuba", {"variant": v, "sampler": "independent"}, True))
        out.append((f"mitsuba {v} after", "mitsuba", {"variant": v}, False))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--res", type=int, default=96)
    ap.add_argument("--only", default=None, help="a substring of the scene names to run")
    ap.add_argument("--tag", default="", help="suffix of the result files (mitsuba_noise<tag>.md)")
    args = ap.parse_args()
    from blendify_mitsuba import MitsubaBackend
    from blendify_mitsuba import translate as mtr

    from blendify_core.registry import get_backend

    variants = ["scalar_rgb"]
    with MitsubaBackend(variant="llvm_ad_rgb") as probe:
        if probe.variant == "llvm_ad_rgb":
            variants.append("llvm_ad_rgb")
    load0 = os.getloadavg()[0]
    scenes = {k: v for k, v in all_scenes(args.res).items() if args.only is None or args.only in k}
    rows: list[dict[str, Any]] = []
    for label, name, options, before in configs(variants):
        backend = get_backend(name, **options) if name == "cycles" else MitsubaBackend(**options)
        saved = mtr.BACKGROUND_SAMPLING_WEIGHT
        mtr.BACKGROUND_SAMPLING_WEIGHT = 1.0 if before else saved
        try:
            for sname, scene in scenes.items():
                m = measure(scene, backend, args.spp, args.seeds)
                rows.append({"scene": sname, "config": label, **m})
                print(f"{sname:40s} {label:28s} noise {m['noise']:.4f} time {m['time']:.3f} s", flush=True)
        finally:
            mtr.BACKGROUND_SAMPLING_WEIGHT = saved
            if name != "cycles":
                backend.close()
    load1 = os.getloadavg()[0]
    write(rows, args, variants, (load0, load1))


def write(rows: list[dict[str, Any]], args: Any, variants: list[str], load: tuple[float, float]) -> None:
    RESULTS.mkdir(exist_ok=True)
    name = f"mitsuba_noise{args.tag}"
    (RESULTS / f"{name}.json").write_text(json.dumps({"args": vars(args), "rows": rows}, indent=1))
    by = {(r["scene"], r["config"]): r for r in rows}
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    cfgs = list(dict.fromkeys(r["config"] for r in rows))
    lines = [
        "# Mitsuba vs Cycles: equal-sample noise, before -> after issue 17",
        "",
        f"{args.spp} spp, {args.seeds} seeds per configuration, {args.res} px wide, max_bounces 12, box filter, no "
        "denoiser. noise = per-pixel std over the seeds / image mean (linear RGB); `x Cycles` = noise / Cycles' "
        "noise (goal: <= 2); `eq-err time` = seconds per render x (noise / Cycles' noise)^2 (time to Cycles' noise "
        "if error ~ 1/sqrt(spp)). `before` = `independent` sampler, uniform background sampled like any emitter; "
        "`after` = the defaults (`multijitter`, background light-sampling weight 1e-3). "
        f"Machine: {platform.machine()}, 2 cores shared with other jobs (load average {load[0]:.1f} at the start, "
        f"{load[1]:.1f} at the end): times are indicative (llvm_ad_rgb renders of 96 px took 0.07-0.13 s "
        f"on a quieter machine). mitsuba {metadata.version('mitsuba')}, bpy "
        f"{metadata.version('bpy')}. Script: `benchmarks/bench_mitsuba_noise.py`.",
        "",
        "| scene | " + " | ".join(cfgs) + " |",
        "|---|" + "---|" * len(cfgs),
    ]
    for s in scenes:
        cyc = by.get((s, "cycles"))
        cells = []
        for c in cfgs:
            r = by.get((s, c))
            if r is None:
                cells.append("-")
            elif c == "cycles" or cyc is None:
                cells.append(f"{r['noise']:.4f} ({r['time']:.2f} s)")
            else:
                ratio = r["noise"] / cyc["noise"]
                eq = r["time"] * ratio**2
                cells.append(f"{r['noise']:.4f}: {ratio:.2f}x Cycles, eq-err time {eq:.2f} s")
        lines.append(f"| {s} | " + " | ".join(cells) + " |")
    lines += ["", f"Plot: `{name}.png` (noise relative to Cycles per scene and configuration; log scale)."]
    (RESULTS / f"{name}.md").write_text("\n".join(lines) + "\n")
    plot(by, scenes, cfgs, name)


def plot(by: dict[tuple[str, str], dict[str, Any]], scenes: list[str], cfgs: list[str], name: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    others = [c for c in cfgs if c != "cycles"]
    fig, ax = plt.subplots(figsize=(11, 5))
    width = 0.8 / max(1, len(others))
    x = np.arange(len(scenes))
    for i, c in enumerate(others):
        vals = [
            by[(s, c)]["noise"] / by[(s, "cycles")]["noise"] if (s, c) in by and (s, "cycles") in by else np.nan
            for s in scenes
        ]
        ax.bar(x + i * width, vals, width, label=c)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.axhline(2.0, color="r", lw=0.8, ls="--", label="goal (2x Cycles)")
    ax.set_yscale("log")
    ax.set_xticks(x + width * (len(others) - 1) / 2)
    ax.set_xticklabels(scenes, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("per-pixel noise / Cycles' (equal spp)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / f"{name}.png", dpi=110)


if __name__ == "__main__":
    main()
