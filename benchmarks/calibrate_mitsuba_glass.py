"""Calibrate the transmission scale of the Mitsuba backend's rough glass (``blendify_mitsuba.principled``,
``GLASS_T_SCALE``) with white-furnace renders.

A white glass sphere (Principled, transmission 1, base colour white, MULTI_GGX) under a uniform white
background: an energy-conserving BSDF shows 1 everywhere. Cycles' compensated glass shows about 0.98-1.0;
Mitsuba's single-scattering ``roughdielectric`` loses energy at every rough interaction (most inside, in
rough total internal reflection). Per roughness and IOR this finds (by bisection) the factor on the
transmittance with which Mitsuba's furnace mean equals Cycles'. Prints the table.

Run: ``nice -n 10 python benchmarks/calibrate_mitsuba_glass.py [--samples 256]``.
"""

from __future__ import annotations

import argparse

import numpy as np

import blendify_core as bf
from blendify_core.ir.colors import UniformColors
from blendify_core.ir.materials import PrincipledBSDFMaterial

ROUGH = (0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.0)
IOR = (1.2, 1.45, 1.9, 2.5)
SIZE = 32


def _inside() -> np.ndarray:
    c = (np.arange(SIZE) + 0.5) / SIZE * 2.2 - 1.1
    x, y = np.meshgrid(c, c)
    return np.asarray(x * x + y * y < 0.8)


def cycles_furnace(roughness: float, ior: float, samples: int) -> float:
    scene = bf.Scene()
    scene.set_orthographic_camera((SIZE, SIZE), ortho_scale=2.2, translation=(0, 0, 5.0), near=0.1, far=20)
    mat = PrincipledBSDFMaterial(roughness=roughness, ior=ior, transmission_weight=1.0, specular_tint=(1, 1, 1))
    scene.renderables.add_sphere_nurbs(1.0, mat, UniformColors((1, 1, 1), color_space="linear"), tag="s")
    scene.lights.set_background_light(1.0)
    img = bf.render(scene, "cycles", samples=samples, outputs=("rgb",), max_bounces=64).rgba[..., 0]
    return float(img[_inside()].mean())


def mitsuba_furnace(mi, roughness: float, ior: float, t_scale: float, samples: int) -> float:
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 65},
            "sensor": {
                "type": "orthographic",
                "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0])
                @ mi.ScalarTransform4f().scale([1.1, 1.1, 1]),
                "film": {"type": "hdrfilm", "width": SIZE, "height": SIZE, "rfilter": {"type": "box"}},
                "sampler": {"type": "independent", "sample_count": samples},
            },
            "s": {
                "type": "sphere",
                "bsdf": {
                    "type": "roughdielectric",
                    "distribution": "ggx",
                    "alpha": roughness * roughness,
                    "int_ior": ior,
                    "ext_ior": 1.0,
                    "specular_transmittance": t_scale,
                },
            },
            "env": {"type": "constant", "radiance": 1.0},
        }
    )
    img = np.array(mi.render(scene, seed=1))[..., 0]
    return float(img[_inside()].mean())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--samples", type=int, default=256)
    args = ap.parse_args()
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    print("ROUGH =", ROUGH, "IOR =", IOR)
    for r in ROUGH:
        row = []
        for ior in IOR:
            target = cycles_furnace(r, ior, args.samples)
            lo, hi = 1.0, 2.5
            for _ in range(7):
                mid = 0.5 * (lo + hi)
                if mitsuba_furnace(mi, r, ior, mid, args.samples) < target:
                    lo = mid
                else:
                    hi = mid
            row.append(round(0.5 * (lo + hi), 3))
            print(f"  r {r} ior {ior}: cycles furnace {target:.4f} -> scale {row[-1]}", flush=True)
        print(r, row, flush=True)


if __name__ == "__main__":
    main()
