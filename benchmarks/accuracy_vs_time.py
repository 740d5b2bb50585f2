"""The price of accuracy: error against a converged reference versus render time, per scene, backend and
quality preset (issue 7; re-run at realistic size for issue 20).

Scenes (``scenes(res)``): the six of issue 7 (a diffuse bunny under a sun, a glossy metal sphere, a glass
sphere with caustics, a point cloud, the textured fuze bottle, a lone sphere lit directly) and three realistic
ones from ``blendify_core.testing``: a textured scan on a table (``textured_scan_scene``), a closed
Cornell-style room lit by one area light, where indirect light dominates (``cornell_room_scene``), and a
scanned point cloud on a shadow catcher (``pointcloud_catcher_scene``).

Configurations: ``final`` with effect analysis swept over samples per pixel (one pass of N samples:
``samples=`` fixes the count), Cycles with Blender's default settings as shipped (OIDN denoiser, indirect
clamp 10, adaptive sampling) swept the same way, ``draft`` and ``preview`` (Cycles, denoised), Mitsuba
``final`` swept, pyrender ``preview``; and ``final`` as it is used, stopping at an error target (relative MSE
1e-3, i.e. ``target_error=sqrt(1e-3)``), with and without effect analysis, in Cycles and Mitsuba: its time,
samples and ``estimated_error`` against the true error.

Error = relative MSE over the premultiplied RGB pixel channels, mean((x - ref)^2 / (ref^2 + 0.01)) (the
estimator's floor, ``blendify_core.pipeline.render.relative_error_estimate``), against each engine's own
reference (full settings, ``--ref-spp`` samples as two independent halves, 1 px box filter), less the
reference's own noise (estimated from the difference of its halves; E[measured] = true + reference noise).
References are cached in ``benchmarks/.cache/accuracy_vs_time/`` (ignored by git) and so are finished scenes
(``--fresh`` starts over). The time at relMSE 1e-3 is interpolated log-log between the bracketing sweep
points; a sweep stops once it is well below the target. Each point is rendered once (the machine is shared:
compare ratios from one run; the load average is recorded). Every image uses the 1 px box filter.

Run: ``uv run --no-sync python benchmarks/accuracy_vs_time.py [--res 256] [--quick]`` (writes
benchmarks/results/accuracy_vs_time.{md,json,png} and accuracy_vs_time_{estimator,effects}.png; ``--quick``
writes into the cache folder instead).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import textwrap
import time
from pathlib import Path
from typing import Any

import numpy as np

import blendify_core as bf
from blendify_core.ir.colorspace import linear_to_srgb
from blendify_core.testing import (
    bunny_scene,
    cornell_room_scene,
    data_path,
    look_at_camera,
    pointcloud_catcher_scene,
    pointcloud_scene,
    textured_scan_scene,
)

RESULTS = Path(__file__).parent / "results"
CACHE = Path(__file__).parent / ".cache" / "accuracy_vs_time"
TARGET = 1e-3  # relative MSE
TARGET_RMS = math.sqrt(TARGET)  # the same target as final's relative RMS ``target_error``
THREADS = 2
#: a target render stops here at the latest (recorded; glass caustics would otherwise take hours) ...
TARGET_TIME_LIMIT = 300.0
#: ... and the glass sphere's sooner: caustics through glass need tens of thousands of samples
TARGET_TIME_LIMIT_GLASS = 45.0
#: each scene's reference uses --ref-spp times this (cheap, smooth scenes need fewer; the room, the glossy and
#: the glass sphere more: with 256 spp their references' noise was 1/4-2x the target)
REF_SPP_FACTOR = {
    "metal sphere (glossy)": 4.0,
    "glass sphere (caustics)": 4.0,
    "bunny (diffuse, sun)": 0.5,
    "textured mesh (fuze)": 0.5,
    "lone sphere (direct light only)": 0.5,
    "point cloud on a shadow catcher": 0.5,
    "Cornell room (indirect)": 2.0,
}


# -- scenes ------------------------------------------------------------------------------------------
def _floor(s: bf.Scene) -> None:
    s.renderables.add_plane_mesh(4.0, bf.DiffuseMaterial(), bf.UniformColors((0.6, 0.6, 0.6)), tag="floor")


def metal_scene(res: int) -> bf.Scene:
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(
        0.3, bf.MetalMaterial(roughness=0.25), bf.UniformColors((0.9, 0.7, 0.3)), translation=(0, 0, 0.3), tag="ball"
    )
    _floor(s)
    look_at_camera(s, (res, res), (1.2, -1.2, 0.9), (0, 0, 0.25), fov_x=np.deg2rad(40))
    s.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    s.lights.set_background_light(0.3)
    return s


def glass_scene(res: int) -> bf.Scene:
    s = bf.Scene()
    glass = bf.PrincipledBSDFMaterial(transmission_weight=1.0, roughness=0.0, ior=1.45)
    s.renderables.add_sphere_nurbs(0.3, glass, bf.UniformColors((1, 1, 1)), translation=(0, 0, 0.3), tag="glass")
    _floor(s)
    look_at_camera(s, (res, res), (1.2, -1.2, 0.9), (0, 0, 0.25), fov_x=np.deg2rad(40))
    s.lights.add_area(
        "square", 0.5, strength=60.0, rotation_mode="look_at", rotation=(0, 0, 0.3), translation=(0.4, 0.3, 1.5)
    )
    s.lights.set_background_light(0.2)
    return s


def lone_sphere_scene(res: int) -> bf.Scene:
    """One convex diffuse object under a sun and a sky: direct light is all there is (effects matter here)."""
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(0.3, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.5, 0.3)), tag="ball")
    look_at_camera(s, (res, res), (1.2, -1.2, 0.9), (0, 0, 0), fov_x=np.deg2rad(40))
    s.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    s.lights.set_background_light(0.3)
    return s


def fuze_scene(res: int) -> bf.Scene:
    s = bf.Scene()
    s.renderables.add_trimesh(str(data_path("fuze.obj")), tag="fuze")
    look_at_camera(s, (res, res), (0.3, -0.3, 0.22), (0, 0, 0.1), fov_x=np.deg2rad(40))
    s.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    s.lights.set_background_light(0.3)
    return s


def scenes(res: int) -> dict[str, tuple[bf.Scene, str]]:
    """name -> (scene, kind). The first six are issue 7's, the last three the realistic ones of issue 20."""
    return {
        "bunny (diffuse, sun)": (bunny_scene((res, res)), "diffuse"),
        "metal sphere (glossy)": (metal_scene(res), "glossy"),
        "glass sphere (caustics)": (glass_scene(res), "glass"),
        "point cloud": (pointcloud_scene(2000, (res, res)), "diffuse"),
        "textured mesh (fuze)": (fuze_scene(res), "textured"),
        "lone sphere (direct light only)": (lone_sphere_scene(res), "diffuse"),
        "textured scan on a table": (textured_scan_scene((res, res)), "realistic"),
        "Cornell room (indirect)": (cornell_room_scene((res, res)), "realistic"),
        "point cloud on a shadow catcher": (pointcloud_catcher_scene((res, res)), "realistic"),
    }


# -- configurations ----------------------------------------------------------------------------------
# name -> (backend, settings overrides, kind): kind 'sweep' = swept over samples per pixel (one pass each),
# 'fixed' = the preset's own samples, 'target' = final stopping at relative MSE TARGET
FINAL = "final, effects (cycles)"
DEFAULTS = "Blender defaults (denoise, clamp 10, adaptive)"
MITSUBA = "final, effects (mitsuba)"
CONFIGS: dict[str, tuple[str, dict[str, Any], str]] = {
    FINAL: ("cycles", {"quality": "final", "effects": True}, "sweep"),
    DEFAULTS: ("cycles", {"effects": False, "denoise": True, "clamp_indirect": 10.0, "adaptive": True}, "sweep"),
    "draft (cycles)": ("cycles", {"quality": "draft"}, "fixed"),
    "preview (cycles)": ("cycles", {"quality": "preview"}, "fixed"),
    MITSUBA: ("mitsuba", {"quality": "final", "effects": True}, "sweep"),
    "preview (pyrender)": ("pyrender", {"quality": "preview"}, "fixed"),
    "final to target, effects (cycles)": ("cycles", {"quality": "final", "effects": True}, "target"),
    "final to target, full settings (cycles)": ("cycles", {"quality": "final", "effects": False}, "target"),
    "final to target, effects (mitsuba)": ("mitsuba", {"quality": "final", "effects": True}, "target"),
    "final to target, full settings (mitsuba)": ("mitsuba", {"quality": "final", "effects": False}, "target"),
}
#: the sweep stops once the error is below TARGET / SWEEP_MARGIN (more samples only lower it further)
SWEEP_MARGIN = 3.0


def rel_mse(x: np.ndarray, ref: np.ndarray) -> float:
    a, b = x[..., :3].astype(np.float64), ref[..., :3].astype(np.float64)
    return float(np.mean((a - b) ** 2 / (b * b + 1e-2)))


def alpha_mse(x: np.ndarray, ref: np.ndarray) -> float:
    """Mean squared alpha difference (a shadow catcher's shadow lives in alpha only)."""
    return float(np.mean((x[..., 3].astype(np.float64) - ref[..., 3].astype(np.float64)) ** 2))


def ssim(x: np.ndarray, ref: np.ndarray) -> float:
    from skimage.metrics import structural_similarity

    def srgb(im: np.ndarray) -> np.ndarray:
        return linear_to_srgb(np.clip(im[..., :3], 0, 1).astype(np.float32))

    return float(structural_similarity(srgb(x), srgb(ref), channel_axis=-1, data_range=1.0))


def timed(scene: bf.Scene, backend: str, **kw: Any) -> tuple[np.ndarray, float, dict[str, Any]]:
    t0 = time.perf_counter()
    r = bf.render(scene, backend=backend, threads=THREADS, **kw)
    return r.rgba, time.perf_counter() - t0, r.meta


def reference(scene: bf.Scene, backend: str, spp: int) -> dict[str, Any]:
    """The engine's converged reference: two independent halves of ``spp`` // 2 samples (full settings, seeds
    4242 / 4243), their mean, and the mean's own relative MSE estimated from their difference
    (E[(a - b)^2] / 4 = the variance of the mean). Cached by scene fingerprint, engine and samples."""
    key = f"{scene.fingerprint()[:20]}_{backend}_{spp}"
    path = CACHE / f"ref_{key}.npz"
    if path.is_file():
        z = np.load(path)
        return {"rgba": z["rgba"], "noise": float(z["noise"]), "seconds": float(z["seconds"]), "cached": True}
    halves, secs = [], 0.0
    for seed in (4242, 4243):
        img, t, _ = timed(scene, backend, quality="final", samples=spp // 2, effects=False, seed=seed)
        halves.append(img.astype(np.float64))
        secs += t
    ref = (halves[0] + halves[1]) / 2
    d = halves[0][..., :3] - halves[1][..., :3]
    noise = float(np.mean(d * d / 4 / (ref[..., :3] ** 2 + 1e-2)))
    CACHE.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, rgba=ref.astype(np.float32), noise=noise, seconds=secs)
    return {"rgba": ref.astype(np.float32), "noise": noise, "seconds": secs, "cached": False}


def time_at(points: list[tuple[float, float]], target: float, extrapolate: bool = False) -> tuple[float | None, str]:
    """(time, how) at which the sweep (time, relMSE) reaches ``target``: interpolated log-log between the
    bracketing points; when even the most samples stay above it, 'not reached', or with ``extrapolate`` (an
    unbiased render, whose relative MSE falls as 1/samples while its time grows as samples) the last point's
    time scaled by its error over the target, 'extrapolated'."""
    pts = sorted(points)
    if pts[0][1] <= target:
        return pts[0][0], "first point already below"
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        if e0 > target >= e1:
            f = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0))), "interpolated"
    if extrapolate and len(pts) >= 2 and pts[-1][1] < pts[-2][1]:
        return pts[-1][0] * pts[-1][1] / target, "extrapolated"
    return None, "not reached"


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name.lower()).strip("_")


def _config_order(flip: bool) -> list[str]:
    """The configurations in order; with ``flip`` each engine's full-settings target render comes before its
    effect-aware one (alternated between scenes so neither side always runs second, on warmer caches)."""
    names = list(CONFIGS)
    if flip:
        for engine in ("cycles", "mitsuba"):
            i = names.index(f"final to target, effects ({engine})")
            j = names.index(f"final to target, full settings ({engine})")
            names[i], names[j] = names[j], names[i]
    return names


def measure_scene(
    sname: str,
    scene: bf.Scene,
    kind: str,
    ref_spp: int,
    sweep: tuple[int, ...],
    sweep_defaults: tuple[int, ...],
    flip: bool = False,
    configs: list[str] | None = None,
) -> dict[str, Any]:
    """Every configuration on one scene (or only ``configs``): the references, the sweeps, the presets and the
    target renders."""
    names = [c for c in _config_order(flip) if configs is None or c in configs]
    for b in dict.fromkeys(CONFIGS[c][0] for c in names):  # warm-up (engine import, first-frame setup)
        bf.render(scene, backend=b, samples=1, threads=THREADS)
    if MITSUBA in names:
        # Mitsuba's llvm variants compile a kernel the first time they render a sample count (about 1 s): a
        # sweep point would time that compilation as well as its samples, where a final render repeats its
        # pass sizes. Each swept count is rendered once first (a no-op for scalar_rgb)
        for spp in sweep:
            bf.render(scene, backend="mitsuba", quality="final", effects=True, samples=spp, seed=3, threads=THREADS)
    ref_spp = 2 * round(ref_spp * REF_SPP_FACTOR.get(sname, 1.0) / 2)
    refs = {b: reference(scene, b, ref_spp) for b in ("cycles", "mitsuba")}
    ref_c, ref_m = refs["cycles"]["rgba"], refs["mitsuba"]["rgba"]
    info = {
        "cycles_seconds": refs["cycles"]["seconds"],
        "mitsuba_seconds": refs["mitsuba"]["seconds"],
        "cycles_noise_relmse": refs["cycles"]["noise"],
        "mitsuba_noise_relmse": refs["mitsuba"]["noise"],
        "cycles_vs_mitsuba_relmse": rel_mse(ref_m, ref_c),
        "resolution": [int(v) for v in scene.camera.resolution],
        "spp": ref_spp,
        "load_average": list(os.getloadavg()),
    }
    print(
        f"{sname}: references {info['cycles_seconds']:.1f} s / {info['mitsuba_seconds']:.1f} s "
        f"(noise {info['cycles_noise_relmse']:.1e} / {info['mitsuba_noise_relmse']:.1e}), "
        f"Mitsuba vs Cycles relMSE {info['cycles_vs_mitsuba_relmse']:.2e}",
        flush=True,
    )
    rows: list[dict[str, Any]] = []
    warmed: set[str] = set()
    for cname in names:
        backend, kw, ckind = CONFIGS[cname]
        if ckind == "target" and backend not in warmed:
            # one 16-spp pass with each setting first: Mitsuba's llvm variant compiles per setting and
            # sample count, and the effect-aware setting's kernels are already warm from its sweep
            for eff in (True, False):
                bf.render(scene, backend=backend, quality="final", samples=16, effects=eff, seed=1, threads=THREADS)
            warmed.add(backend)
        own = refs["mitsuba" if backend == "mitsuba" else "cycles"]
        levels: tuple[Any, ...] = (None,)
        if ckind == "sweep":
            levels = sweep_defaults if cname == DEFAULTS else sweep
        prev = math.inf
        for spp in levels:
            extra: dict[str, Any] = {"samples": spp} if spp is not None else {}
            est = None
            if ckind == "target":
                limit = TARGET_TIME_LIMIT_GLASS if kind == "glass" else TARGET_TIME_LIMIT
                extra = {"target_error": TARGET_RMS, "time_limit": limit}
                # the price before paying, as a user asks for it: a pilot (its own seed), then the render
                est = bf.estimate_cost(
                    scene, backend=backend, target_error=TARGET_RMS, seed=20_000, threads=THREADS, **kw
                )
            img, secs, meta = timed(scene, backend, seed=7, **kw, **extra)
            raw = rel_mse(img, own["rgba"])
            row: dict[str, Any] = {
                "scene": sname,
                "kind": kind,
                "config": cname,
                "config_kind": ckind,
                "backend": backend,
                "samples": meta.get("samples"),
                "seconds": secs,
                "relmse_raw": raw,
                "relmse": max(raw - own["noise"], 1e-9),
                "relmse_cycles_ref": rel_mse(img, ref_c),
                "ssim_cycles_ref": ssim(img, ref_c),
                "alpha_mse": alpha_mse(img, own["rgba"]),
            }
            if ckind == "target":
                assert est is not None
                pilot = meta.get("indirect_pilot") or {}
                row.update(
                    estimated_error=meta.get("estimated_error"),
                    estimated_error_interval=meta.get("estimated_error_interval"),
                    true_error=math.sqrt(row["relmse"]),
                    passes=meta.get("passes"),
                    stopped=meta.get("stopped"),
                    target_reached=meta.get("target_reached"),
                    indirect_dropped=bool(pilot.get("dropped")),
                    indirect_why=pilot.get("why"),
                    caustics_dropped=bool((meta.get("caustics_pilot") or {}).get("dropped")),
                    predicted_samples=est.samples,
                    predicted_passes=est.passes,
                    predicted_seconds=est.seconds,
                    predicted_seconds_range=list(est.seconds_range),
                    predicted_reaches_target=est.reaches_target,
                    pilot_seconds=est.pilot_seconds,
                    pilot_error=est.pilot_error,
                )
            if backend == "cycles":
                es = meta["engine_settings"]
                row["bounces"] = {k: es[k] for k in ("diffuse_bounces", "glossy_bounces", "transmission_bounces")}
            elif backend == "mitsuba":
                row["max_depth"] = meta.get("max_depth")
                row["variant"] = meta.get("variant")
            rows.append(row)
            extra_txt = (
                f" est={row['estimated_error']:.4f} true={row['true_error']:.4f} passes={row['passes']}"
                f" {row['stopped']}{' (indirect dropped)' if row['indirect_dropped'] else ''}"
                if ckind == "target"
                else ""
            )
            print(
                f"  {cname:48s} spp={row['samples']!s:>5} {secs:7.2f} s  relMSE={row['relmse']:.2e}"
                f" (raw {raw:.2e})  SSIM={row['ssim_cycles_ref']:.3f}{extra_txt}",
                flush=True,
            )
            if ckind == "sweep":
                stalled = cname == DEFAULTS and row["relmse"] > 0.8 * prev  # the denoiser's bias floor
                if row["relmse"] < TARGET / SWEEP_MARGIN or stalled:
                    break
                prev = row["relmse"]
    info["load_average_end"] = list(os.getloadavg())
    return {"reference": info, "rows": rows}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="tiny run (64 px, small references) to test the script")
    ap.add_argument("--res", type=int, default=256)
    ap.add_argument("--ref-spp", type=int, default=256, help="samples of each reference (two halves)")
    ap.add_argument("--fresh", action="store_true", help="measure every scene again (references stay cached)")
    ap.add_argument(
        "--configs",
        nargs="*",
        default=None,
        help="re-measure only these configurations on every (cached) scene, keeping the other rows",
    )
    ap.add_argument(
        "--only", nargs="*", default=None, help="scene names to measure (default: all; others come from the cache)"
    )
    args = ap.parse_args(argv)
    res, ref_spp = (64, 64) if args.quick else (args.res, args.ref_spp)
    sweep = (1, 4, 16) if args.quick else (1, 4, 16, 64)
    sweep_defaults = (1, 4, 16) if args.quick else (1, 4, 16, 64)
    load_start = os.getloadavg()
    t_run = time.perf_counter()
    per_scene: dict[str, Any] = {}
    for index, (sname, (scene, kind)) in enumerate(scenes(res).items()):
        done = CACHE / f"scene_{res}_{ref_spp}_{_slug(sname)}.json"
        if args.only and sname not in args.only:
            if done.is_file():  # measured before: kept in the results
                per_scene[sname] = json.loads(done.read_text())
            continue
        if done.is_file() and args.configs:
            per_scene[sname] = json.loads(done.read_text())
            new = measure_scene(sname, scene, kind, ref_spp, sweep, sweep_defaults, configs=args.configs)
            kept = [r for r in per_scene[sname]["rows"] if r["config"] not in args.configs]
            per_scene[sname]["rows"] = kept + new["rows"]
            per_scene[sname].setdefault("remeasured", {}).update(
                {c: {"load_average": new["reference"]["load_average"]} for c in args.configs}
            )
            done.write_text(json.dumps(per_scene[sname], indent=1, default=float))
            continue
        if done.is_file() and not args.fresh:
            per_scene[sname] = json.loads(done.read_text())
            print(f"{sname}: measured before (cached in {done.name})")
            continue
        t0 = time.perf_counter()
        per_scene[sname] = measure_scene(sname, scene, kind, ref_spp, sweep, sweep_defaults, flip=index % 2 == 1)
        per_scene[sname]["seconds"] = time.perf_counter() - t0
        CACHE.mkdir(parents=True, exist_ok=True)
        done.write_text(json.dumps(per_scene[sname], indent=1, default=float))
    load_end = os.getloadavg()
    rows = [r for v in per_scene.values() for r in v["rows"]]
    out: dict[str, Any] = {
        "machine": {
            "cpu_count": os.cpu_count(),
            "threads": THREADS,
            "platform": platform.platform(),
            "load_average_start": load_start,
            "load_average_end": load_end,
        },
        "reference_spp": ref_spp,
        "resolution": res,
        "sweep_spp": list(sweep),
        "sweep_spp_defaults": list(sweep_defaults),
        "target_relmse": TARGET,
        "target_time_limit": TARGET_TIME_LIMIT,
        "target_time_limit_glass": TARGET_TIME_LIMIT_GLASS,
        "references": {k: v["reference"] for k, v in per_scene.items()},
        "scene_seconds": {k: v.get("seconds") for k, v in per_scene.items()},
        "remeasured": {k: v["remeasured"] for k, v in per_scene.items() if v.get("remeasured")},
        "rows": rows,
        "summary": summarise(rows),
        "total_seconds": time.perf_counter() - t_run,
        "measured_seconds": sum(float(v.get("seconds") or 0.0) for v in per_scene.values()),
    }
    dest = CACHE if args.quick else RESULTS
    dest.mkdir(parents=True, exist_ok=True)
    before_path = RESULTS / "accuracy_vs_time_96px.json"
    before = json.loads(before_path.read_text()) if before_path.is_file() else None
    (dest / "accuracy_vs_time.json").write_text(json.dumps(out, indent=1, default=float))
    plot(rows, dest / "accuracy_vs_time.png")
    plot_estimator(rows, dest / "accuracy_vs_time_estimator.png")
    plot_effects(out["summary"], dest / "accuracy_vs_time_effects.png")
    (dest / "accuracy_vs_time.md").write_text(markdown(out, before))
    print(f"done in {out['total_seconds']:.0f} s; load {load_start} -> {load_end}; wrote {dest}")
    return 0


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per scene: time at relMSE 1e-3 per swept configuration, the speed-up of ``final`` over Blender's
    defaults, the target renders (effect-aware vs full, estimated vs true error) and the preview SSIMs."""
    out: dict[str, Any] = {}
    for sname in dict.fromkeys(r["scene"] for r in rows):
        sr = [r for r in rows if r["scene"] == sname]
        at: dict[str, Any] = {}
        for cname in dict.fromkeys(r["config"] for r in sr if r["config_kind"] == "sweep"):
            pts = [(r["seconds"], r["relmse"]) for r in sr if r["config"] == cname]
            t, how = time_at(pts, TARGET, extrapolate=cname != DEFAULTS)
            at[cname] = {"seconds": t, "how": how, "min_relmse": min(e for _, e in pts)}
        ours, base = at[FINAL]["seconds"], at[DEFAULTS]["seconds"]
        speedup = None if ours is None else (math.inf if base is None else base / ours)
        targets = {r["config"]: r for r in sr if r["config_kind"] == "target"}
        effects: dict[str, Any] = {}
        for engine in ("cycles", "mitsuba"):
            e = targets.get(f"final to target, effects ({engine})")
            f = targets.get(f"final to target, full settings ({engine})")
            if e and f:
                effects[engine] = {
                    "full_over_effects_seconds": f["seconds"] / e["seconds"],
                    "full_over_effects_samples": (f["samples"] or 0) / max(e["samples"] or 1, 1),
                    "indirect_dropped": e["indirect_dropped"],
                    "why": e["indirect_why"],
                }
        previews = {r["config"]: r["ssim_cycles_ref"] for r in sr if r["config"].startswith("preview")}
        out[sname] = {
            "kind": sr[0]["kind"],
            "time_at_target": at,
            "speedup_vs_defaults": speedup,
            "effects": effects,
            "preview_ssim": previews,
        }
    return out


def _f(v: Any, fmt: str = ".3g") -> str:
    return "-" if v is None else format(v, fmt)


def _x(v: float | None) -> str:
    if v is None:
        return "- (final not reached)"
    return "inf (defaults never reach it)" if math.isinf(v) else f"{v:.2f}x"


#: issue 7's scene names in the 96 px run -> this run's
_BEFORE_NAMES = {"final, effects (blendify)": FINAL, "mitsuba final, effects": MITSUBA}


def _before_at(before: dict[str, Any] | None, sname: str, cname: str) -> dict[str, Any] | None:
    if not before or sname not in before.get("summary", {}):
        return None
    at = before["summary"][sname]["time_at_target"]
    for old, new in _BEFORE_NAMES.items():
        if new == cname and old in at:
            return dict(at[old])
    return dict(at[cname]) if cname in at else None


def _before_speedup(before: dict[str, Any] | None, sname: str) -> float | None:
    if not before or sname not in before.get("summary", {}):
        return None
    return dict(before["summary"][sname]["speedup_vs"]).get(DEFAULTS)


def _time_cell(a: dict[str, Any] | None) -> str:
    if a is None:
        return "n/a"
    if a["seconds"] is None:
        return f"- (min {a['min_relmse']:.1e})"
    return _f(a["seconds"]) + (" (extrapolated)" if a["how"] == "extrapolated" else "")


def _ratio_ok(a: float | None, b: float | None) -> bool:
    return bool(a and b) and 1 / 1.5 <= a / b <= 1.5  # type: ignore[operator]


def cost_section(trows: list[dict[str, Any]]) -> list[str]:
    """The table of ``bf.estimate_cost``'s predictions against the target renders that followed them."""
    rows = [r for r in trows if r.get("predicted_samples") is not None]
    if not rows:
        return []
    lines = [
        "",
        "## `bf.estimate_cost` before each target render",
        "",
        "Each target render above was preceded by `bf.estimate_cost(scene, backend, target_error=..., seed=20000)` "
        "with the same settings (its pilot uses its own seed), the order a user follows: the prediction, then the "
        "render, in the same process. Predicted seconds exclude the pilot (its own column). Renders stopped by "
        "their time limit are shown but not counted (their samples are the limit's, not the target's).",
        "",
        "| scene | configuration | predicted spp | spp | ratio | predicted s (90 % range) | seconds | ratio "
        "| pilot s | effect dropped by the render's pilot |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lo, hi = r["predicted_seconds_range"]
        dropped = [k for k in ("indirect", "caustics") if r.get(f"{k}_dropped")]
        lines.append(
            f"| {r['scene']} | {r['config'].removeprefix('final to target, ')} | {r['predicted_samples']} "
            f"| {r['samples']} | {r['predicted_samples'] / r['samples']:.2f} | {r['predicted_seconds']:.2f} "
            f"({lo:.2f}-{hi:.2f}) | {r['seconds']:.2f} | {r['predicted_seconds'] / r['seconds']:.2f} "
            f"| {r['pilot_seconds']:.1f} | {', '.join(dropped) or '-'} |"
        )
    counted = [r for r in rows if r["target_reached"]]

    def tally(key: str, engine: str) -> str:
        sel = [r for r in counted if r["backend"] == engine]
        return f"{sum(1 for r in sel if _ratio_ok(r[f'predicted_{key}'], r[key]))}/{len(sel)}"

    lines += [
        "",
        f"Within 1.5x, renders that reached the target: samples Cycles {tally('samples', 'cycles')}, Mitsuba "
        f"{tally('samples', 'mitsuba')}; seconds Cycles {tally('seconds', 'cycles')}, Mitsuba "
        f"{tally('seconds', 'mitsuba')}.",
    ]
    return lines


def markdown(out: dict[str, Any], before: dict[str, Any] | None = None) -> str:
    m = out["machine"]
    res = out["resolution"]
    loads = [v for ri in out["references"].values() for v in (ri["load_average"][0], ri["load_average_end"][0])]
    lines = [
        f"# Accuracy versus time at {res}x{res} (issues 7 and 20)",
        "",
        "Generated by `benchmarks/accuracy_vs_time.py` (scenes: `scenes()` there; the three realistic ones are "
        "`textured_scan_scene`, `cornell_room_scene` and `pointcloud_catcher_scene` in `blendify_core.testing`). "
        f"{m['cpu_count']} cores shared with other jobs, {m['threads']} render threads, {m['platform']}; load "
        f"average (1 min) {min(loads):.1f}-{max(loads):.1f} while the scenes were measured (per scene below): "
        "times are wall-clock under that load, one render per point, so compare ratios within a scene. "
        f"Measuring took {out['measured_seconds']:.0f} s. Mitsuba variant: "
        f"{', '.join(sorted({str(r['variant']) for r in out['rows'] if r.get('variant')})) or 'not recorded'}.",
        "",
        f"References: each engine's own, full settings (`effects=False`, 12 bounces), {out['reference_spp']} spp "
        "(times the scene's factor: the table's spp) as two halves with seeds 4242/4243, 1 px box filter. "
        "Error = relative MSE over premultiplied RGB, "
        "mean((x-ref)^2/(ref^2+0.01)), less the reference's own noise (estimated from its halves). Sweeps: "
        f"{out['sweep_spp']} spp for `final` (Blender defaults: {out['sweep_spp_defaults']}), each stopping once "
        f"below 1/{SWEEP_MARGIN:g} of the target (the defaults also once the denoiser's bias floor stalls them); "
        "Mitsuba renders each swept count once before its sweep (its llvm variants compile a kernel per new "
        "count, which a final render's repeated passes pay once). "
        "'Blender defaults' = OIDN denoiser on, indirect clamp 10, adaptive sampling (threshold 0.01), "
        "12 bounces; the filter stays the 1 px box. "
        f"The 'before' columns are the 96x96 run of issue 7 ([accuracy_vs_time_96px.md](accuracy_vs_time_96px.md)).",
        "",
        "| scene | load (1 min) | ref spp | Cycles ref s | Mitsuba ref s | ref noise relMSE Cycles / Mitsuba "
        "| relMSE Mitsuba ref vs Cycles ref |",
        "|---|---|---|---|---|---|---|",
    ]
    for s, ri in out["references"].items():
        lines.append(
            f"| {s} | {ri['load_average'][0]:.1f} | {ri['spp']} | {ri['cycles_seconds']:.1f} "
            f"| {ri['mitsuba_seconds']:.1f} "
            f"| {ri['cycles_noise_relmse']:.1e} / {ri['mitsuba_noise_relmse']:.1e} "
            f"| {ri['cycles_vs_mitsuba_relmse']:.2e} |"
        )
    summ = out["summary"]
    lines += [
        "",
        "## Time to reach relMSE 1e-3 (seconds; '-' = not reached within the sweep, with its lowest error)",
        "",
        "'extrapolated': an unbiased sweep still above the target at its last point, whose time is scaled by "
        "its error over the target (relative MSE ~ 1/samples, time ~ samples).",
        "",
        "| scene | final (Cycles) | Blender defaults | Mitsuba final | speed-up of final vs Blender defaults "
        "| before (96x96): final / defaults / Mitsuba | before speed-up |",
        "|---|---|---|---|---|---|---|",
    ]
    for s, sm in summ.items():
        at = sm["time_at_target"]
        b = [_time_cell(_before_at(before, s, c)) for c in (FINAL, DEFAULTS, MITSUBA)]
        in_before = s in (before or {}).get("summary", {})
        bs = _x(_before_speedup(before, s)) if in_before else "n/a"
        lines.append(
            f"| {s} | {_time_cell(at.get(FINAL))} | {_time_cell(at.get(DEFAULTS))} | {_time_cell(at.get(MITSUBA))} "
            f"| {_x(sm['speedup_vs_defaults'])} | {' / '.join(b)} | {bs} |"
        )
    trows = [r for r in out["rows"] if r["config_kind"] == "target"]
    lines += [
        "",
        f"## `final` stopping at its error target (relative RMS {TARGET_RMS:.4f} = relMSE 1e-3; time limit "
        f"{out['target_time_limit']:g} s, glass {out['target_time_limit_glass']:g} s)",
        "",
        "Estimated = `meta['estimated_error']` with its 90 % interval; true = the relative RMS difference to the "
        "reference less the reference's noise. Within 1.5x: estimated / true in [1/1.5, 1.5].",
        "",
        "| scene | configuration | spp | passes | seconds | estimated | 90 % interval | true | est/true "
        "| interval covers | stopped | indirect light dropped |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in trows:
        est, true = r["estimated_error"], r["true_error"]
        lo, hi = r["estimated_error_interval"] or (math.nan, math.nan)
        ratio = est / true if est and true else math.nan
        lines.append(
            f"| {r['scene']} | {r['config'].removeprefix('final to target, ')} | {r['samples']} | {r['passes']} "
            f"| {r['seconds']:.1f} | {_f(est, '.4f')} | {lo:.4f}-{hi:.4f} | {true:.4f} | {ratio:.2f} "
            f"| {'yes' if lo <= true <= hi else 'no'} | {r['stopped']} | {'yes' if r['indirect_dropped'] else 'no'} |"
        )

    def within(r: dict[str, Any]) -> bool:
        return bool(r["estimated_error"]) and 1 / 1.5 <= r["estimated_error"] / r["true_error"] <= 1.5

    def covers(r: dict[str, Any]) -> bool:
        lo, hi = r["estimated_error_interval"] or (math.inf, -math.inf)
        return bool(lo <= r["true_error"] <= hi)

    refs = out["references"]
    clean = [r for r in trows if refs[r["scene"]][f"{r['backend']}_noise_relmse"] <= TARGET / 4 and r["target_reached"]]

    def count(rs: list[dict[str, Any]], test: Any, engine: str | None = None) -> str:
        sel = [r for r in rs if engine is None or r["backend"] == engine]
        return f"{sum(1 for r in sel if test(r))}/{len(sel)}"

    lines += [
        "",
        f"Estimate within 1.5x of the true error: {count(trows, within)} renders (Cycles "
        f"{count(trows, within, 'cycles')}, Mitsuba {count(trows, within, 'mitsuba')}); 90 % interval covers the "
        f"true error: {count(trows, covers)}. Counting only renders that reached the target and whose reference "
        f"noise is <= 1/4 of the target: within 1.5x {count(clean, within)} (Cycles {count(clean, within, 'cycles')}, "
        f"Mitsuba {count(clean, within, 'mitsuba')}), covered {count(clean, covers)}. "
        "Plot: [accuracy_vs_time_estimator.png](accuracy_vs_time_estimator.png).",
        *cost_section(trows),
        "",
        "## Effect-aware vs full settings (the target renders above, paired in one run)",
        "",
        "| scene | Cycles: time full / effect-aware | samples full / effect-aware | Mitsuba: time | samples "
        "| indirect-light pilot (Cycles, effect-aware) |",
        "|---|---|---|---|---|---|",
    ]
    for s, sm in summ.items():
        ec, em = sm["effects"].get("cycles"), sm["effects"].get("mitsuba")

        def cell(e: dict[str, Any] | None, k: str) -> str:
            return "-" if e is None else f"{e[k]:.2f}"

        why = (ec or {}).get("why") or "-"
        lines.append(
            f"| {s} | {cell(ec, 'full_over_effects_seconds')} | {cell(ec, 'full_over_effects_samples')} "
            f"| {cell(em, 'full_over_effects_seconds')} | {cell(em, 'full_over_effects_samples')} | {why} |"
        )
    lines += [
        "",
        "Where the samples are equal, the two settings took the same light paths (a bounce type no material has is "
        "never taken): their time ratio is the timing noise of a loaded machine, one pair per scene. "
        "Plot: [accuracy_vs_time_effects.png](accuracy_vs_time_effects.png).",
        "",
        "## Preview quality (SSIM against the converged Cycles reference, sRGB)",
        "",
    ]
    pnames = list(next(iter(summ.values()))["preview_ssim"])
    lines.append("| scene | " + " | ".join(pnames) + " | before (96x96) |")
    lines.append("|---" * (len(pnames) + 2) + "|")
    for s, sm in summ.items():
        old = (before or {}).get("summary", {}).get(s, {}).get("preview_ssim")
        olds = " / ".join(f"{v:.3f}" for v in old.values()) if old else "n/a"
        lines.append(f"| {s} | " + " | ".join(f"{v:.3f}" for v in sm["preview_ssim"].values()) + f" | {olds} |")
    again = sorted({c for v in out.get("remeasured", {}).values() for c in v})
    if again:
        loads = [x["load_average"][0] for v in out["remeasured"].values() for x in v.values()]
        lines += [
            "",
            f"Re-measured later against the same cached references (`--configs`): {', '.join(again)} "
            f"(load average {min(loads):.1f}-{max(loads):.1f}).",
        ]
    lines += [
        "",
        "## Every measurement",
        "",
        "| scene | config | spp | seconds | relMSE (less ref noise) | raw relMSE | relMSE vs Cycles ref "
        "| SSIM vs Cycles ref | alpha MSE | bounces d/g/t or max_depth |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in out["rows"]:
        b = r.get("bounces")
        bs = "/".join(str(v) for v in b.values()) if b else str(r.get("max_depth", "-"))
        lines.append(
            f"| {r['scene']} | {r['config']} | {r['samples']} | {r['seconds']:.2f} | {r['relmse']:.2e} "
            f"| {r['relmse_raw']:.2e} | {r['relmse_cycles_ref']:.2e} | {r['ssim_cycles_ref']:.3f} "
            f"| {r['alpha_mse']:.1e} | {bs} |"
        )
    lines += ["", "![error vs time](accuracy_vs_time.png)", ""]
    return "\n".join(lines)


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    """Error vs time, one panel per scene, one line per backend and preset; target renders as stars."""
    plt = _plt()
    names = list(dict.fromkeys(r["scene"] for r in rows))
    cols = 3
    nrows = math.ceil(len(names) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.6 * nrows), squeeze=False)
    cfgs = list(dict.fromkeys(r["config"] for r in rows))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, s in enumerate(names):
        ax = axes[k // cols][k % cols]
        for i, c in enumerate(cfgs):
            pts = [r for r in rows if r["scene"] == s and r["config"] == c]
            if not pts:
                continue
            x = [r["seconds"] for r in pts]
            y = [max(r["relmse"], 1e-7) for r in pts]
            style = {"sweep": "-o", "fixed": "s", "target": "*"}[pts[0]["config_kind"]]
            ax.loglog(x, y, style, color=colours[i % len(colours)], label=c, ms=7 if style == "*" else 4)
        ax.axhline(TARGET, color="k", ls=":", lw=1)
        ax.xaxis.set_minor_formatter(plt.NullFormatter())
        ax.set_title(s, fontsize=9)
        ax.set_xlabel("render time (s)")
        ax.grid(True, which="both", alpha=0.3)
        if k % cols == 0:
            ax.set_ylabel("relative MSE vs converged reference")
    for k in range(len(names), nrows * cols):
        axes[k // cols][k % cols].axis("off")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=7, loc="lower center", ncol=4)
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_estimator(rows: list[dict[str, Any]], path: Path) -> None:
    """Estimated against true relative RMS error of the target renders, with the 1.5x band."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.2, 4.8))
    trows = [r for r in rows if r["config_kind"] == "target" and r["estimated_error"]]
    for engine, colour in (("cycles", "C0"), ("mitsuba", "C1")):
        for full, marker in ((False, "o"), (True, "s")):
            pts = [r for r in trows if r["backend"] == engine and ("full settings" in r["config"]) == full]
            if not pts:
                continue
            t = np.array([r["true_error"] for r in pts])
            e = np.array([r["estimated_error"] for r in pts])
            lo = np.array([r["estimated_error_interval"][0] for r in pts])
            hi = np.array([r["estimated_error_interval"][1] for r in pts])
            ax.errorbar(
                t,
                e,
                yerr=[e - lo, hi - e],
                fmt=marker,
                color=colour,
                ms=5,
                capsize=2,
                alpha=0.8,
                label=f"{engine}, {'full settings' if full else 'effect-aware'}",
            )
    vals = [v for r in trows for v in (r["true_error"], r["estimated_error"])]
    if vals:
        a, b = min(vals) / 2, max(vals) * 2
        g = np.array([a, b])
        ax.loglog(g, g, "k-", lw=1)
        ax.loglog(g, g * 1.5, "k:", lw=1)
        ax.loglog(g, g / 1.5, "k:", lw=1, label="1.5x")
        ax.axvline(TARGET_RMS, color="grey", lw=0.8, ls="--")
    ax.set_xlabel("true relative RMS error (vs reference, less its noise)")
    ax.set_ylabel("estimated_error (90 % interval)")
    ax.set_title("final at relative RMS 0.0316: estimated vs true", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_effects(summary: dict[str, Any], path: Path) -> None:
    """Time (and samples) of full settings over effect-aware ones at the error target, per scene and engine."""
    plt = _plt()
    names = list(summary)
    fig, ax = plt.subplots(figsize=(9, 4.6))
    x = np.arange(len(names))
    for j, engine in enumerate(("cycles", "mitsuba")):
        t = [summary[s]["effects"].get(engine, {}).get("full_over_effects_seconds", np.nan) for s in names]
        n = [summary[s]["effects"].get(engine, {}).get("full_over_effects_samples", np.nan) for s in names]
        ax.bar(x + (j - 0.5) * 0.38, t, 0.36, color=f"C{j}", label=f"{engine}: time full / effect-aware")
        ax.plot(x + (j - 0.5) * 0.38, n, "k_", ms=14, mew=2, label="samples full / effect-aware" if j else None)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.axhline(1.5, color="grey", lw=0.8, ls=":")
    ax.set_xticks(x, [textwrap.fill(s, 14) for s in names], fontsize=7)
    ax.set_ylabel("full / effect-aware at relMSE 1e-3")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
