"""Research utilities: point-cloud normals and camera colouring, camera trajectories, point cloud to
textured mesh, figure helpers, and rendering frame sequences / videos.

Importing this package loads numpy and scipy only; optional libraries (Open3D, imageio, Pillow, tqdm)
are imported by the functions that need them.
"""

from __future__ import annotations

from .image import blend_with_background, contact_sheet, crop_to_content, to_display_uint8
from .normals import estimate_normals, normals_from_mesh, orient_normals

__all__ = [
    "estimate_normals",
    "normals_from_mesh",
    "orient_normals",
    "blend_with_background",
    "contact_sheet",
    "crop_to_content",
    "to_display_uint8",
]
