"""Light-unit check: a Lambertian plane (rho = 0.5) under each light type (``testing.plane_scene``),
Mitsuba / Cycles and both against the analytic radiance, over the inner 3/4 of the image.

Run: ``uv run --no-sync python benchmarks/bench_mitsuba_light_units.py``. Writes
``benchmarks/results/mitsuba_light_units.md`` and ``.png``.
"""

from __future__ import annotations

import argparse
import platform
from importlib import metadata
from pathlib import Path

import numpy as np

import blendify_core as bf
from blendify_core import testing

RESULTS = Path(__file__).resolve().parent / "results"
LIGHTS = ("point", "sun", "spot", "area", "area_disk", "background")


def analytic(scene, light: str) -> np.ndarray:
    """Radiance (H, W) of the rho = 0.5 Lambertian plane z = 0 at the pixel centres."""
    cam = scene.camera
    o, d = cam.pixel_rays()
    p = o - d * (o[:, 2:3] / d[:, 2:3])
    lights = list(scene.lights)
    if light == "sun":
        e = lights[0].strength * max(0.0, -lights[0].direction[2]) * np.ones(len(p))
    elif light in ("point", "spot"):
        v = lights[0].translation - p
        dist = np.linalg.norm(v, axis=1)
        e = lights[0].strength / (4 * np.pi) * (v[:, 2] / dist) / dist**2
    elif light in ("area", "area_disk"):
        s = lights[0]
        n = 300
        g = (np.arange(n) + 0.5) / n - 0.5
        gx, gy = np.meshgrid(g * s.size[0], g * s.size[1])
        pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
        da = s.size[0] * s.size[1] / n**2
        if light == "area_disk":
            keep = (pts[:, 0] / (s.size[0] / 2)) ** 2 + (pts[:, 1] / (s.size[1] / 2)) ** 2 <= 1
            pts = pts[keep] * np.sqrt(np.pi / 4 * s.size[0] * s.size[1] / (keep.sum() * da))
        q = np.concatenate([pts, np.zeros((len(pts), 1))], axis=1) + s.translation
        e = np.zeros(len(p))
        for chunk in np.array_split(np.arange(len(p)), 64):
            v = q[None] - p[chunk, None]
            r2 = (v**2).sum(-1)
            cos = v[..., 2] / np.sqrt(r2)
            e[chunk] = (s.radiance[0] * cos * cos / r2).sum(1) * da
    elif light == "background":
        e = np.pi * np.ones(len(p))
    else:
        raise ValueError(light)
    return (0.5 / np.pi * e).reshape(cam.height, cam.width)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--resolution", type=int, default=64)
    args = ap.parse_args()
    res = (args.resolution, args.resolution)
    k = args.resolution // 8
    inner = (slice(k, -k), slice(k, -k))
    rows = []
    profiles = {}
    cycles_note = ""
    for light in LIGHTS:
        scene = testing.plane_scene(light, resolution=res)
        exp = analytic(scene, light)
        m = bf.render(scene, backend="mitsuba", variant="scalar_rgb", samples=args.samples).rgba[..., 0]
        try:
            c = bf.render(scene, backend="cycles", samples=args.samples).rgba[..., 0]
        except Exception as exc:  # noqa: BLE001 - reported in the table
            c = None
            cycles_note = f"Cycles unavailable: {type(exc).__name__}: {exc}"
        mi_c = float(m[inner].sum() / c[inner].sum()) if c is not None else float("nan")
        per_pixel = np.abs(m[inner] / c[inner] - 1) if c is not None else np.full(1, np.nan)
        rows.append(
            (
                light,
                mi_c,
                float(np.median(per_pixel)),
                float(m[inner].sum() / exp[inner].sum()),
                float(c[inner].sum() / exp[inner].sum()) if c is not None else float("nan"),
            )
        )
        profiles[light] = (
            m[args.resolution // 2],
            None if c is None else c[args.resolution // 2],
            exp[args.resolution // 2],
        )
        print(rows[-1], flush=True)
    RESULTS.mkdir(parents=True, exist_ok=True)
    lines = [
        "# Light units: Mitsuba vs Cycles vs analytic",
        "",
        f"Scene: `blendify_core.testing.plane_scene(light)`: Lambertian plane rho = 0.5 (linear), orthographic "
        f"camera looking down, {res[0]}x{res[1]}, {args.samples} spp, box filter; ratios of sums over the inner "
        f"3/4 of the image. mitsuba {metadata.version('mitsuba')} (scalar_rgb), bpy {_v('bpy')}, "
        f"{platform.machine()}.",
        "",
        "Conversions (blendify_mitsuba): point I = P/(4 pi); spot I = P/(4 pi), cutoff = spot_size/2; sun "
        "irradiance = strength; area radiance = P/(pi A) on a one-sided rectangle/disk (flip_normals, null "
        "BSDF); background = constant radiance colour x strength.",
        "",
        "| light | Mitsuba / Cycles | median per-pixel abs(Mitsuba/Cycles - 1) | Mitsuba / analytic "
        "| Cycles / analytic |",
        "|---|---|---|---|---|",
    ]
    for light, mc, med, ma, ca in rows:
        lines.append(f"| {light} | {mc:.4f} | {med:.4f} | {ma:.4f} | {ca:.4f} |")
    if cycles_note:
        lines += ["", cycles_note]
    lines += ["", "Profiles through the image centre: `mitsuba_light_units.png`.", ""]
    (RESULTS / "mitsuba_light_units.md").write_text("\n".join(lines))
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is missing: no plot written")
        return
    fig, axes = plt.subplots(2, 3, figsize=(11, 6))
    for ax, light in zip(axes.ravel(), LIGHTS, strict=True):
        m_row, c_row, e_row = profiles[light]
        ax.plot(e_row, "k-", label="analytic")
        if c_row is not None:
            ax.plot(c_row, "b.", label="Cycles")
        ax.plot(m_row, "r+", label="Mitsuba")
        ax.set_title(light)
        ax.set_xlabel("pixel column (centre row)")
    axes[0, 0].legend()
    fig.suptitle("Radiance of a rho=0.5 Lambertian plane under each light type")
    fig.tight_layout()
    fig.savefig(RESULTS / "mitsuba_light_units.png", dpi=90)


def _v(name: str) -> str:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "?"


if __name__ == "__main__":
    main()
