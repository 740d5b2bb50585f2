"""Research utilities: point-cloud normals and camera colouring, camera trajectories, point cloud to
textured mesh, figure helpers, and rendering frame sequences / videos.

Importing this package loads numpy and scipy only; optional libraries (Open3D, imageio, Pillow, tqdm)
are imported by the functions that need them.
"""

from __future__ import annotations

from .animation import FramesReport, render_frames, write_video
from .colors import approximate_colors_from_camera
from .image import blend_with_background, contact_sheet, crop_to_content, to_display_uint8
from .meshify import MeshifyResult, add_meshified, meshify_pointcloud
from .normals import estimate_normals, normals_from_mesh, orient_normals
from .trajectory import Pose, Trajectory, apply_pose

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
