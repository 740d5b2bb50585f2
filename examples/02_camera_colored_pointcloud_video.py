"""A camera-coloured point cloud orbit video: the bunny's points, normals estimated from the points,
front-facing points coloured, back-facing ones grey, re-coloured for every frame of an orbit."""

from __future__ import annotations

import numpy as np
import trimesh
from _common import data_file, out_dir, parser

import blendify_core as bf
from blendify_core.utils import Trajectory, approximate_colors_from_camera, estimate_normals


def main() -> None:
    p = parser(__doc__, size=192, samples=16)
    p.add_argument("--frames", type=int, default=24, help="number of frames (the orbit is one turn)")
    args = p.parse_args()
    out = out_dir(args)
    points = np.asarray(trimesh.load(data_file("bunny.ply"), process=False).vertices)
    points = points[:, [0, 2, 1]] * np.array([1, -1, 1])  # +Y up -> +Z up
    points -= points.mean(axis=0)
    normals = estimate_normals(points, k=16, orient="viewpoint", viewpoint=points.mean(axis=0) + [0, 0, 10])
    base = (points - points.min(0)) / np.ptp(points, axis=0)

    scene = bf.Scene()
    cloud = scene.renderables.add_pointcloud(points, bf.DiffuseMaterial(), bf.VertexColors(base), point_size=0.004)
    scene.set_perspective_camera((args.size, args.size), fov_x=np.deg2rad(35))
    scene.lights.add_sun(2.5, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    scene.lights.set_background_light(0.6)

    def recolour(scene: bf.Scene, frame: int) -> None:
        rgba = approximate_colors_from_camera(scene.camera, normals, base, back_color=(0.6, 0.6, 0.6), points=points)
        cloud.update_colors(bf.VertexColors(rgba[:, :3]))

    fps = 12.0
    orbit = Trajectory.orbit(center=(0, 0, 0), radius=0.35, height=0.12, duration=args.frames / fps)
    report = bf.render_frames(
        scene,
        orbit,
        backend=args.backend,
        samples=args.samples,
        fps=fps,
        frames_dir=out / "orbit_frames",
        video_path=out / "orbit.mp4",
        on_frame=recolour,
        progress=False,
    )
    print(f"{report}")


if __name__ == "__main__":
    main()
