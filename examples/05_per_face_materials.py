"""Per-face materials: one mesh, three material slots chosen by `faces_material`."""

from __future__ import annotations

import numpy as np
from _common import out_dir, parser

import blendify_core as bf
from blendify_core.ir.geometry import torus


def main() -> None:
    args = parser(__doc__).parse_args()
    out = out_dir(args)
    t = torus(0.5, 0.22, 96, 48)
    centres = t.vertices[t.faces].mean(axis=1)
    slot = np.where(centres[:, 2] > 0.05, 1, 0)  # icing on top
    slot[(centres[:, 2] > 0.05) & (np.sin(40 * np.arctan2(centres[:, 1], centres[:, 0])) > 0.95)] = 2  # sprinkles
    scene = bf.Scene()
    scene.renderables.add_mesh(
        t.vertices,
        t.faces,
        material=[bf.PrincipledBSDFMaterial(roughness=0.7), bf.PlasticMaterial(roughness=0.2), bf.DiffuseMaterial()],
        colors=[
            bf.UniformColors((0.8, 0.55, 0.3)),
            bf.UniformColors((0.95, 0.5, 0.65)),
            bf.UniformColors((0.2, 0.4, 0.95)),
        ],
        faces_material=slot,
        smooth=True,
    )
    scene.set_perspective_camera(
        (args.size, args.size),
        fov_x=np.deg2rad(40),
        rotation_mode="look_at",
        rotation=(0, 0, 0),
        translation=(0, -1.6, 1.3),
    )
    scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    scene.lights.set_background_light(0.4)
    result = bf.render(scene, backend=args.backend, samples=args.samples, outputs=("rgb", "instance"))
    result.save(out / "per_face_materials.png")
    print(f"{result.meta['backend']}: {result.meta['timings']['total']:.2f} s -> {out}/per_face_materials.png")


if __name__ == "__main__":
    main()
