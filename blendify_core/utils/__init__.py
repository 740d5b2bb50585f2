"""Research utilities: point-cloud normals and camera colouring, camera trajectories, point cloud to
textured mesh, figure helpers, and rendering frame sequences / videos.

Importing this package loads numpy and scipy only; optional libraries (Open3D, imageio, Pillow, tqdm)
are imported by the functions that need them.
"""

from __future__ import annotations

from blendify_core.utils.animation import FramesReport, render_frames, write_video
from blendify_core.utils.colors import approximate_colors_from_camera
from blendify_core.utils.image import blend_with_background, contact_sheet, crop_to_content, to_display_uint8
from blendify_core.utils.meshify import MeshifyResult, add_meshified, meshify_pointcloud
from blendify_core.utils.normals import estimate_normals, normals_from_mesh, orient_normals
from blendify_core.utils.trajectory import Pose, Trajectory, apply_pose

__all__ = [
    "estimate_normals",
    "normals_from_mesh",
    "orient_normals",
    "approximate_colors_from_camera",
    "Trajectory",
    "Pose",
    "apply_pose",
    "meshify_pointcloud",
    "add_meshified",
    "MeshifyResult",
    "render_frames",
    "write_video",
    "FramesReport",
    "blend_with_background",
    "contact_sheet",
    "crop_to_content",
    "to_display_uint8",
]
