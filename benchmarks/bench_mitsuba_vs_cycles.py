"""Equal-sample render times: Mitsuba 3 (scalar_rgb and llvm_ad_rgb when usable) versus Cycles on the
same scenes (testing.bunny_scene on a plane, sun and area light, 256x256, 64 spp, box filter).

Run: ``uv run --no-sync python benchmarks/bench_mitsuba_vs_cycles.py [--repeats 3]``. Writes
``benchmarks/results/mitsuba_vs_cycles.md`` and ``.png``.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from importlib import metadata
from pathlib import Path

import numpy as np

from blendify_core import testing
from blendify_core.pipeline.settings import resolve_settings

RESULTS = Path(__file__).resolve().parent / "results"


def _time_mitsuba(scene, variant: str, settings, repeats: int) -> dict:
    from blendify_mitsuba import MitsubaBackend

    with MitsubaBackend(variant=variant) as backend:
        t0 = time.perf_counter()
        _ = backend.variant_choice  # probe (subprocess) outside the timings
        probe = time.perf_counter() - t0
        if backend.variant != variant:
            return {"skipped": backend.variant_choice.reason}
        first = None
        translate, render = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            native = backend.translate(scene, settings)
            t1 = time.perf_counter()
            res = backend.render(native, settings)
            t2 = time.perf_counter()
            if first is None:
                first = (t1 - t0) + (t2 - t1)
            translate.append(t1 - t0)
            render.append(t2 - t1)
        return {
            "probe": probe,
            "first": first,
            "translate": min(translate),
            "render": min(render),
            "mean": float(res.rgba[..., :3].mean()),
            "image": res.rgba,
        }


def _time_cycles(scene, settings, repeats: int) -> dict:
    from blendify_core.registry import get_backend

    try:
        backend = get_backend("cycles")
    except Exception as exc:  # noqa: BLE001 - reported in the table
        return {"skipped": f"{type(exc).__name__}: {exc}"}
    with backend:
        first = None
        translate, render = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            native = backend.translate(scene, settings)
            t1 = time.perf_counter()
            res = backend.render(native, settings)
            t2 = time.perf_counter()
            if first is None:
                first = t2 - t0
            translate.append(t1 - t0)
            render.append(t2 - t1)
    return {
        "first": first,
        "translate": min(translate),
        "render": min(render),
        "mean": float(res.rgba[..., :3].mean()),
        "image": res.rgba,
    }


_LOAD = os.getloadavg()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--resolution", type=int, default=256)
    ap.add_argument("--samples", type=int, default=64)
    args = ap.parse_args()
    res = (args.resolution, args.resolution)
    settings = resolve_settings(samples=args.samples, outputs=("rgb",), max_bounces=12)
    rows = []
    for light in ("sun", "area"):
        scene = testing.bunny_scene(res, light=light)
        engines = {
            "cycles": _time_cycles(scene, settings, args.repeats),
            "mitsuba scalar_rgb": _time_mitsuba(scene, "scalar_rgb", settings, args.repeats),
            "mitsuba llvm_ad_rgb": _time_mitsuba(scene, "llvm_ad_rgb", settings, args.repeats),
        }
        ref = engines["cycles"].get("mean")
        for name, r in engines.items():
            rows.append((light, name, r, ref))
            print(light, name, {k: v for k, v in r.items() if k != "image"}, flush=True)
        _save_images(light, engines)
    _write(rows, args, res)


def _save_images(light: str, engines: dict) -> None:
    from PIL import Image

    from blendify_core.ir.colorspace import linear_to_srgb

    tiles = [r["image"] for r in engines.values() if "image" in r]
    if not tiles:
        return
    row = np.concatenate(tiles, axis=1)
    rgb = np.clip(linear_to_srgb(np.clip(row[..., :3], 0, None)), 0, 1)
    alpha = np.clip(row[..., 3:4], 0, 1)
    out = np.round((rgb * alpha + (1 - alpha)) * 255).astype(np.uint8)  # over white
    Image.fromarray(out).save(RESULTS / f"mitsuba_vs_cycles_{light}.png")


def _total(rows, light: str, name: str) -> float:
    for li, n, r, _ in rows:
        if li == light and n == name and "render" in r:
            return r["translate"] + r["render"]
    return 0.0


def _version(name: str) -> str:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "?"


def _write(rows, args, res) -> None:
    RESULTS.mkdir(parents=True, exist_ok=True)
    lines = [
        "# Mitsuba 3 vs Cycles: equal-sample render times",
        "",
        f"Scene: `blendify_core.testing.bunny_scene` (bunny with vertex colours, Principled roughness 0.6, on a "
        f"diffuse plane, background 0.2), {res[0]}x{res[1]}, {args.samples} spp, box filter, max_bounces 12 "
        "(Mitsuba path max_depth 14), denoiser/adaptive off. "
        f"Machine: {platform.machine()}, {os.cpu_count()} cores, no GPU, shared with other jobs (load average "
        f"{_LOAD[0]:.1f} at the start, {os.getloadavg()[0]:.1f} at the end); best of {args.repeats}. "
        f"mitsuba {metadata.version('mitsuba')}, bpy {_version('bpy')}.",
        "",
        "`first` = first translate + render in the process (llvm: includes JIT compilation; the variant probe "
        "subprocess is listed separately), `translate`/`render` = best warm times (seconds). `mean/cycles` = "
        "mean linear RGB relative to Cycles (same scene, different BSDF implementations for the bunny's "
        "Principled material: see the capability notes).",
        "",
        "| light | engine | probe (s) | first (s) | translate (s) | render (s) | translate+render (s) | "
        "vs Cycles | mean/cycles |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    cyc = {r[0]: _total(rows, r[0], "cycles") for r in rows if r[1] == "cycles"}
    for light, name, r, ref in rows:
        if "skipped" in r:
            lines.append(f"| {light} | {name} | - | - | - | - | - | - | skipped: {r['skipped'][:160]} |")
            continue
        total = r["translate"] + r["render"]
        speed = f"{total / cyc[light]:.2f}x" if cyc.get(light) else "-"
        ratio = f"{r['mean'] / ref:.3f}" if ref else "-"
        probe = f"{r['probe']:.2f}" if "probe" in r else "-"
        lines.append(
            f"| {light} | {name} | {probe} | {r['first']:.2f} | {r['translate']:.3f} | {r['render']:.2f} | "
            f"{total:.2f} | {speed} | {ratio} |"
        )
    lines += [
        "",
        "Images (Cycles, Mitsuba scalar, Mitsuba llvm; over white): `mitsuba_vs_cycles_sun.png`, "
        "`mitsuba_vs_cycles_area.png`; plot: `mitsuba_vs_cycles.png`.",
        "",
    ]
    (RESULTS / "mitsuba_vs_cycles.md").write_text("\n".join(lines))
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is missing: no plot written")
        return
    fig, ax = plt.subplots(figsize=(7, 3.5))
    names = [n for n in ("cycles", "mitsuba scalar_rgb", "mitsuba llvm_ad_rgb")]
    lights = ["sun", "area"]
    width = 0.25
    for i, name in enumerate(names):
        vals = [
            next((r["render"] for li, n, r, _ in rows if li == light and n == name and "render" in r), 0)
            for light in lights
        ]
        ax.bar(np.arange(len(lights)) + (i - 1) * width, vals, width, label=name)
    ax.set_xticks(np.arange(len(lights)), [f"bunny, {light} light" for light in lights])
    ax.set_ylabel(f"translate + render (s), {args.samples} spp")
    ax.set_title(f"Equal-sample render time, {res[0]}x{res[1]} (warm, best of runs)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(RESULTS / "mitsuba_vs_cycles.png", dpi=100)


if __name__ == "__main__":
    main()
