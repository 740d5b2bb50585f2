"""The interactive loop: quick previews while the camera moves, then one final render of the chosen view."""

from __future__ import annotations

import numpy as np
from _common import out_dir, parser

import blendify_core as bf
from blendify_core.testing import bunny_scene


def main() -> None:
    args = parser(__doc__, samples=64).parse_args()
    out = out_dir(args)
    scene = bunny_scene(resolution=(args.size, args.size))
    cam = scene.camera
    times = []
    for angle in np.linspace(0, np.pi / 2, 8):
        pos = np.array([0.43 * np.sin(angle), -0.43 * np.cos(angle), 0.2])
        cam.set_position(rotation_mode="look_at", rotation=(0, 0, 0.07), translation=pos)
        preview = bf.render(scene, quality="preview", backend=args.backend if args.backend == "pyrender" else None)
        times.append(preview.meta["timings"]["total"])
    preview.save(out / "preview.png")
    final = bf.render(
        scene, quality="final", samples=args.samples, backend=args.backend if args.backend != "pyrender" else None
    )
    final.save(out / "final.png")
    print(
        f"previews ({preview.meta['backend']}): median {np.median(times) * 1000:.0f} ms/frame; "
        f"final ({final.meta['backend']}, {args.samples} spp): {final.meta['timings']['total']:.2f} s"
    )


if __name__ == "__main__":
    main()
