"""Materials side by side (plastic, metal, wireframe, glossy) standing on a shadow catcher, composited
over a white background as a figure would be."""

from __future__ import annotations

import numpy as np
from _common import out_dir, parser

import blendify_core as bf
from blendify_core.ir.geometry import torus


def main() -> None:
    args = parser(__doc__).parse_args()
    out = out_dir(args)
    scene = bf.Scene()
    t = torus(0.3, 0.12, 64, 32)
    materials = [
        bf.PlasticMaterial(),
        bf.MetalMaterial(roughness=0.25, metallic=1.0),
        bf.PlasticWireframeMaterial(wireframe_thickness=0.003),
        bf.GlossyBSDFMaterial(roughness=0.15),
    ]
    colours = [(0.8, 0.2, 0.2), (0.9, 0.75, 0.4), (0.3, 0.6, 0.9), (0.6, 0.9, 0.6)]
    for i, (m, c) in enumerate(zip(materials, colours)):
        scene.renderables.add_mesh(
            t.vertices,
            t.faces,
            m,
            bf.UniformColors(c),
            smooth=True,
            rotation_mode="eulerXYZ",
            rotation=(60, 0, 0),
            translation=(i * 0.9 - 1.35, 0, 0.3),
        )
    scene.renderables.add_plane_mesh(10, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)), shadow_catcher=True)
    scene.set_perspective_camera(
        (args.size * 2, args.size),
        fov_x=np.deg2rad(45),
        rotation_mode="look_at",
        rotation=(0, 0, 0.25),
        translation=(0, -3.5, 1.6),
    )
    scene.lights.add_point(60.0, shadow_soft_size=0.2, translation=(-1.5, -1.5, 2.5))
    scene.lights.add_spot(
        120.0, spot_size=np.deg2rad(60), rotation_mode="look_at", rotation=(0, 0, 0), translation=(2, -2, 3)
    )
    scene.lights.set_background_light(0.2)
    result = bf.render(scene, backend=args.backend, samples=args.samples)
    result.save(out / "materials.png")
    rgba = result.to_srgb8().astype(np.float32) / 255
    over_white = rgba[..., :3] * rgba[..., 3:] + (1 - rgba[..., 3:])
    from PIL import Image

    Image.fromarray(np.round(over_white * 255).astype(np.uint8)).save(out / "materials_on_white.png")
    print(
        f"{result.meta['backend']}: {result.meta['timings']['total']:.2f} s; approximations: "
        f"{result.meta['approximations'] or 'none'}"
    )


if __name__ == "__main__":
    main()
