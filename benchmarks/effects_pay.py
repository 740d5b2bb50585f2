"""Effects that pay (issue 20, item 3): equal-error time of effect-aware settings (``effects=True``) versus full
settings (``effects=False``), per scene and path tracer.

Each render is blendify's ``final``: independent passes until the estimated relative RMS error is <= the
target (``bf.FINAL_TARGET_ERROR``), so both sides stop at the same error and the time is the equal-error time.
Runs are paired: each repetition renders the effect-aware and the full settings back to back (the order
alternates between repetitions, both sides use the same seed) and the ratio full/effect-aware is taken within
the pair; the table gives the median of the ratios, with their range. The machine may be shared: the load
average is recorded; the ratios, not the absolute times, are the result.

The scenes do not call for some effect: a Lambertian scene (no glossy, transmission, caustics or transparency),
lights that cast no shadows, an object floating in the dark (direct light only), a glossy scene whose indirect
light is below the target, and geometric outputs only. A scene that calls for every effect (a glass sphere on a
floor) shows that nothing is dropped where everything is needed.

Run: ``wtpy benchmarks/effects_pay.py [--quick] [--reps N]`` (writes benchmarks/results/effects_pay.{md,json,png}).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from accuracy_vs_time import glass_scene  # a glass sphere on a floor: calls for every effect (nothing to drop)

import blendify_core as bf
from blendify_core.testing import look_at_camera

RESULTS = Path(__file__).parent / "results"
THREADS = 2


# -- scenes ------------------------------------------------------------------------------------------
def _floor(s: bf.Scene) -> None:
    s.renderables.add_plane_mesh(4.0, bf.DiffuseMaterial(), bf.UniformColors((0.6, 0.6, 0.6)), tag="floor")


def _camera(s: bf.Scene, res: int) -> None:
    look_at_camera(s, (res, res), (1.2, -1.2, 0.9), (0, 0, 0.25), fov_x=np.deg2rad(40))


def _ball_and_box(s: bf.Scene, res: int) -> None:
    s.renderables.add_sphere_nurbs(
        0.3, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.5, 0.3)), translation=(0, 0, 0.3), tag="ball"
    )
    s.renderables.add_cube_mesh(
        0.3, bf.DiffuseMaterial(), bf.UniformColors((0.3, 0.6, 0.8)), translation=(0.45, 0.35, 0.15), tag="box"
    )
    _floor(s)
    _camera(s, res)


def lambert_scene(res: int) -> bf.Scene:
    """Diffuse sphere and cube on a diffuse floor under a sun and a sky: indirect diffuse light and shadows,
    but no glossy, transmission, caustics or transparency."""
    s = bf.Scene()
    _ball_and_box(s, res)
    s.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    s.lights.set_background_light(0.3)
    return s


def no_shadow_scene(res: int) -> bf.Scene:
    """The Lambertian scene lit by a point light and a sun that cast no shadows (no sky)."""
    s = bf.Scene()
    _ball_and_box(s, res)
    s.lights.add_sun(2.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0), use_shadow=False)
    s.lights.add_point(30.0, translation=(-0.8, -0.5, 1.5), use_shadow=False)
    return s


def floating_scene(res: int) -> bf.Scene:
    """One diffuse sphere floating in the dark under a sun: direct light only (no indirect, no sky)."""
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(
        0.3, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.5, 0.3)), translation=(0, 0, 0.3), tag="ball"
    )
    _camera(s, res)
    s.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    return s


def dark_floor_scene(res: int) -> bf.Scene:
    """A diffuse ball on a near-black floor (5 %) under a large area light: every bounce hits something, but the
    indirect light is far below the target (the ``target_error`` pilot measures it and drops it)."""
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(
        0.3, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.5, 0.3)), translation=(0, 0, 0.3), tag="ball"
    )
    s.renderables.add_plane_mesh(4.0, bf.DiffuseMaterial(), bf.UniformColors((0.05, 0.05, 0.05)), tag="floor")
    _camera(s, res)
    s.lights.add_area(
        "square", 3.0, strength=100.0, rotation_mode="look_at", rotation=(0, 0, 0.3), translation=(0.3, -0.6, 1.2)
    )
    return s


def floating_bunny_scene(res: int) -> bf.Scene:
    """The bunny (glossy principled, concave) floating in the dark under an area light: it lights itself a
    little (indirect), no floor, no sky."""
    s = bf.testing.bunny_scene((res, res), plane=False, light="area")
    return s


SCENES: dict[str, tuple[Callable[[int], bf.Scene], tuple[str, ...]]] = {
    "lambert": (lambert_scene, ("rgb",)),
    "no_shadow": (no_shadow_scene, ("rgb",)),
    "floating": (floating_scene, ("rgb",)),
    "floating_bunny": (floating_bunny_scene, ("rgb",)),
    "dark_floor": (dark_floor_scene, ("rgb",)),
    "glass": (glass_scene, ("rgb",)),
    "depth_normal": (lambert_scene, ("depth", "normal")),
}


# -- measurement -------------------------------------------------------------------------------------
def _one(scene: bf.Scene, backend: str, effects: bool, seed: int, outputs: tuple[str, ...]) -> dict[str, Any]:
    t0 = time.perf_counter()
    res = bf.render(
        scene, backend=backend, quality="final", effects=effects, seed=seed, threads=THREADS, outputs=outputs
    )
    dt = time.perf_counter() - t0
    meta = res.meta
    return {
        "time": dt,
        "samples": meta.get("samples"),
        "estimated_error": meta.get("estimated_error"),
        "simulated": meta.get("simulated"),
        "engine_settings": {k: v for k, v in (meta.get("engine_settings") or {}).items() if not isinstance(v, dict)},
        "integrator": meta.get("integrator"),
        "max_depth": meta.get("max_depth"),
        "indirect_pilot": meta.get("indirect_pilot"),
        "rgba": None if res.rgba is None else res.rgba,
    }


def _rel_diff(a: np.ndarray | None, b: np.ndarray | None) -> float | None:
    if a is None or b is None:
        return None
    x, y = a[..., :3].astype(np.float64), b[..., :3].astype(np.float64)
    return float(np.sqrt(np.mean((x - y) ** 2 / ((0.5 * (x + y)) ** 2 + 0.01))))


def measure(name: str, backend: str, res: int, reps: int) -> dict[str, Any]:
    make, outputs = SCENES[name]
    scene = make(res)
    _one(scene, backend, True, 99, outputs)  # warm-up (engine start, caches)
    pairs = []
    for r in range(reps):
        order = (True, False) if r % 2 == 0 else (False, True)
        runs = {eff: _one(scene, backend, eff, 1000 + r, outputs) for eff in order}
        e, f = runs[True], runs[False]
        pairs.append(
            {
                "t_eff": e["time"],
                "t_full": f["time"],
                "ratio": f["time"] / e["time"],
                "spp_eff": e["samples"],
                "spp_full": f["samples"],
                "err_eff": e["estimated_error"],
                "err_full": f["estimated_error"],
                "rel_rms_diff": _rel_diff(e["rgba"], f["rgba"]),
            }
        )
        print(
            f"  {backend:8s} {name:15s} rep {r}: eff {e['time']:.2f} s ({e['samples']} spp) "
            f"full {f['time']:.2f} s ({f['samples']} spp) ratio {f['time'] / e['time']:.2f}",
            flush=True,
        )
    ratios = np.array([p["ratio"] for p in pairs])
    last_e = {k: v for k, v in e.items() if k != "rgba"}
    last_f = {k: v for k, v in f.items() if k != "rgba"}
    return {
        "scene": name,
        "backend": backend,
        "outputs": list(outputs),
        "pairs": pairs,
        "ratio_median": float(np.median(ratios)),
        "ratio_min": float(ratios.min()),
        "ratio_max": float(ratios.max()),
        "t_eff_median": float(np.median([p["t_eff"] for p in pairs])),
        "t_full_median": float(np.median([p["t_full"] for p in pairs])),
        "effect_aware": last_e,
        "full": last_f,
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--backends", default="cycles,mitsuba")
    ap.add_argument("--out", default=str(RESULTS / "effects_pay"))
    args = ap.parse_args()
    res = 64 if args.quick else args.res
    reps = 3 if args.quick else args.reps
    rows = []
    load0 = os.getloadavg()[0]
    for backend in args.backends.split(","):
        for name in args.scenes.split(","):
            rows.append(measure(name, backend, res, reps))
    load1 = os.getloadavg()[0]
    out = Path(args.out)
    info = {"res": res, "reps": reps, "load": [load0, load1], "machine": platform.platform(), "cpus": os.cpu_count()}
    out.with_suffix(".json").write_text(json.dumps({"info": info, "rows": rows}, indent=1, default=str))
    print(json.dumps([(r["backend"], r["scene"], round(r["ratio_median"], 2)) for r in rows]))


if __name__ == "__main__":
    main()
