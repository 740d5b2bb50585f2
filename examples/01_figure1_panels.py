"""The blendify paper's Figure 1 panels on one mesh: colour, depth, albedo, rich materials, a point cloud
and advanced lighting (the Stanford bunny)."""

from __future__ import annotations

import numpy as np
from _common import data_file, out_dir, parser

import blendify_core as bf


def bunny(scene: bf.Scene, material, colors, **kwargs):
    mesh = scene.renderables.add_trimesh(
        data_file("bunny.ply"),
        material=material,
        colors=colors,
        smooth=True,
        rotation_mode="eulerXYZ",
        rotation=(90, 0, 0),
        **kwargs,
    )
    return mesh


def camera(scene: bf.Scene, size: int) -> None:
    scene.set_perspective_camera(
        (size, size),
        fov_x=np.deg2rad(30),
        rotation_mode="look_at",
        rotation=(-0.02, 0.0, 0.1),
        translation=(0.1, -0.45, 0.25),
    )


def main() -> None:
    args = parser(__doc__, size=256, samples=32).parse_args()
    out = out_dir(args)
    common = dict(backend=args.backend, samples=args.samples)

    scene = bf.Scene()
    camera(scene, args.size)
    bunny(scene, bf.PrincipledBSDFMaterial(roughness=0.5), bf.UniformColors((0.85, 0.6, 0.4)))
    scene.renderables.add_plane_mesh(
        2.0, bf.DiffuseMaterial(), bf.UniformColors((0.9, 0.9, 0.9)), translation=(0, 0, 0.033)
    )
    scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(35, 20, 0))
    scene.lights.set_background_light(0.3)
    result = bf.render(scene, outputs=("rgb", "depth", "albedo"), **common)
    result.save(out / "colour.png")
    result.save(out / "depth.png", output="depth")
    result.save(out / "albedo.png", output="albedo")
    print(f"colour/depth/albedo with {result.meta['backend']} in {result.meta['timings']['total']:.1f} s")

    for name, material in [
        ("metal", bf.MetalMaterial(roughness=0.3, metallic=1.0)),
        ("plastic", bf.PlasticMaterial()),
        ("wireframe", bf.PlasticWireframeMaterial(wireframe_thickness=0.0008)),
    ]:
        scene.renderables["Mesh_000"].update_material(material)
        bf.render(scene, **common).save(out / f"{name}.png")

    points = bf.Scene()
    camera(points, args.size)
    import trimesh

    verts = np.asarray(trimesh.load(data_file("bunny.ply"), process=False).vertices)
    colors = (verts - verts.min(0)) / np.ptp(verts, axis=0)
    points.renderables.add_pointcloud(
        verts,
        bf.DiffuseMaterial(),
        bf.VertexColors(colors),
        point_size=0.004,
        rotation_mode="eulerXYZ",
        rotation=(90, 0, 0),
    )
    points.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(35, 20, 0))
    points.lights.set_background_light(0.4)
    bf.render(points, **common).save(out / "pointcloud.png")

    lit = bf.Scene()
    camera(lit, args.size)
    bunny(lit, bf.PrincipledBSDFMaterial(roughness=0.4), bf.UniformColors((0.9, 0.9, 0.9)))
    lit.renderables.add_plane_mesh(
        2.0, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)), shadow_catcher=True, translation=(0, 0, 0.033)
    )
    lit.lights.add_spot(
        8.0,
        spot_size=np.deg2rad(40),
        rotation_mode="look_at",
        rotation=(0, 0, 0.08),
        translation=(-0.3, -0.3, 0.5),
        color=(1.0, 0.6, 0.3),
    )
    lit.lights.add_area(
        "square",
        0.2,
        strength=5.0,
        rotation_mode="look_at",
        rotation=(0, 0, 0.08),
        translation=(0.4, -0.2, 0.3),
        color=(0.3, 0.5, 1.0),
    )
    bf.render(lit, **common).save(out / "lighting.png")
    print(f"wrote 7 panels to {out}/")


if __name__ == "__main__":
    main()
