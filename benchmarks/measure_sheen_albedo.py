"""Cycles' sheen albedo per viewing cosine and sheen roughness, measured (for the Mitsuba backend's
Principled mapping, ``blendify_mitsuba.principled.SHEEN_MEASURED``).

A sheen-only Principled sphere (black base colour, no specular layer, sheen weight 1, white tint) under a
uniform white background, seen by an orthographic camera: a pixel's value is the sheen's directional albedo
for the viewing cosine of that pixel (the sphere's normal there). Prints the table.

Run: ``nice -n 10 python benchmarks/measure_sheen_albedo.py [--samples 1024]``.
"""

from __future__ import annotations

import argparse

import numpy as np

import blendify_core as bf
from blendify_core.ir.colors import UniformColors
from blendify_core.ir.materials import PrincipledBSDFMaterial

MU = (0.1, 0.2, 0.3, 0.5, 0.7, 0.9, 1.0)
ROUGH = (0.0, 0.25, 0.5, 0.75, 1.0)


def measure(roughness: float, samples: int, size: int = 96) -> np.ndarray:
    scene = bf.Scene()
    scene.set_orthographic_camera((size, size), ortho_scale=2.2, translation=(0, 0, 5.0), near=0.1, far=20)
    mat = PrincipledBSDFMaterial(
        specular_ior=0.0, sheen_weight=1.0, sheen_roughness=roughness, sheen_tint=(1.0, 1.0, 1.0), roughness=0.5
    )
    scene.renderables.add_sphere_nurbs(1.0, mat, UniformColors((0.0, 0.0, 0.0)), tag="s")
    scene.lights.set_background_light(1.0)
    img = bf.render(scene, "cycles", samples=samples, outputs=("rgb",), max_bounces=1).rgba[..., 0]
    c = (np.arange(size) + 0.5) / size * 2.2 - 1.1
    x, y = np.meshgrid(c, c)
    r2 = x * x + y * y
    mu = np.sqrt(np.clip(1.0 - r2, 0.0, 1.0))
    inside = r2 < 0.995
    out = []
    for m in MU:
        sel = inside & (np.abs(mu - m) < 0.04)
        out.append(float(img[sel].mean()))
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--samples", type=int, default=1024)
    args = ap.parse_args()
    print("MU =", MU)
    for r in ROUGH:
        print(r, np.round(measure(r, args.samples), 4).tolist(), flush=True)


if __name__ == "__main__":
    main()
