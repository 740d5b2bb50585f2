"""Cost of Mitsuba's integrator for lights that cast no shadow (``blendify_mitsuba.integrator``).

The scene is ``testing.occluder_scene`` (a plane, a cube between it and one light) per light type. Three
renders per variant: Mitsuba's ``path`` with the light casting shadows, ``blendify_path`` forced onto the
same scene (the integrator's own overhead: same work), and ``blendify_path`` with ``use_shadow=False``
(what bf.render does); the last also against Cycles (ratio of image sums). JIT variants are measured only
where the variant module chooses one (a libLLVM it accepts).

Run: ``nice -n 10 python benchmarks/bench_mitsuba_no_shadow.py``. Writes
``benchmarks/results/mitsuba_no_shadow.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from importlib import metadata
from pathlib import Path

import numpy as np
from blendify_mitsuba import MitsubaBackend
from blendify_mitsuba.integrator import register
from blendify_mitsuba.translate import MitsubaTranslator

import blendify_core as bf
from blendify_core import testing
from blendify_core.pipeline.settings import resolve_settings

RESULTS = Path(__file__).resolve().parent / "results"
LIGHTS = ("point", "sun", "spot", "area", "area_disk")


def _timed(fn, repeats: int = 3):  # type: ignore[no-untyped-def]
    """The result of ``fn`` and its fastest time over ``repeats`` calls (the machine is shared)."""
    best = float("inf")
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return out, best


def measure(variant: str, light: str, res: int, spp: int) -> dict[str, float]:
    with MitsubaBackend(variant=variant) as b:
        with b.session.engine() as mi:
            shadowed = testing.occluder_scene(light, True, (res, res))
            settings = resolve_settings(samples=spp, pixel_filter="box")
            tr = MitsubaTranslator(settings, max_analytic_spheres=b.session.max_analytic_spheres).translate(shadowed)
            scene = mi.load_dict(tr.scene_dict)
            np.array(mi.render(scene, spp=spp, seed=1))  # warm-up (JIT compilation, BVH)
            _, t_path = _timed(lambda: np.array(mi.render(scene, spp=spp, seed=0)))
            d = dict(tr.scene_dict)
            d["integrator"] = {**tr.integrator, "type": register(), "no_shadow": ""}
            forced = mi.load_dict(d)
            np.array(mi.render(forced, spp=spp, seed=1))
            _, t_forced = _timed(lambda: np.array(mi.render(forced, spp=spp, seed=0)))
        free = testing.occluder_scene(light, False, (res, res))
        bf.render(free, backend=b, samples=spp, pixel_filter="box", seed=1)  # warm-up
        r, t_free = _timed(lambda: bf.render(free, backend=b, samples=spp, pixel_filter="box"))
    c = bf.render(free, backend="cycles", samples=spp, pixel_filter="box", denoise=False)
    return {
        "path": t_path,
        "forced": t_forced,
        "bf_render": t_free,
        "ratio": float(r.rgba[..., :3].sum() / c.rgba[..., :3].sum()),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--samples", type=int, default=64)
    args = ap.parse_args()
    variants = ["scalar_rgb"]
    jit = MitsubaBackend().session.variant
    notes = []
    if jit.startswith("llvm"):
        variants.append(jit)
    else:
        notes.append(f"No JIT variant measured: the variant module chose {jit} here (no libLLVM it accepts).")
    rows = []
    for variant in variants:
        for light in LIGHTS:
            m = measure(variant, light, args.resolution, args.samples)
            rows.append((variant, light, m))
            print(variant, light, m, flush=True)
    lines = [
        "# Mitsuba: lights that cast no shadow (integrator `blendify_path`)",
        "",
        f"Scene: `testing.occluder_scene(light)` (Lambertian plane, cube between it and the light), "
        f"{args.resolution}x{args.resolution}, {args.samples} spp, box filter. mitsuba {metadata.version('mitsuba')}, "
        f"bpy {metadata.version('bpy')}, {platform.machine()}, {os.cpu_count()} cores shared with other jobs "
        "(timings under load, fastest of 3 after a warm-up render: compare the ratios, not the seconds).",
        "",
        "`path`: Mitsuba's integrator, light casting shadows. `blendify_path (forced)`: the Python integrator on "
        "the same scene (its overhead for the same work). `bf.render, use_shadow=False`: end to end, "
        "translation and geometric outputs included. Mitsuba / Cycles: image sums, use_shadow=False.",
        "",
        "| variant | light | path (s) | blendify_path forced (s) | slowdown | bf.render use_shadow=False (s) "
        "| Mitsuba / Cycles |",
        "|---|---|---|---|---|---|---|",
    ]
    for variant, light, m in rows:
        lines.append(
            f"| {variant} | {light} | {m['path']:.3f} | {m['forced']:.3f} | {m['forced'] / m['path']:.1f}x "
            f"| {m['bf_render']:.3f} | {m['ratio']:.4f} |"
        )
    lines += [""] + notes + [""] if notes else [""]
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "mitsuba_no_shadow.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
