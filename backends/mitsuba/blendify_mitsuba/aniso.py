"""Non-square pixels (fx != fy) for Mitsuba's square-pixel perspective sensor.

The colour image is rendered by a square-pixel camera with the same pose and horizontal focal length
scaled by ``k`` (columns supersampled ``k`` times), whose rows sample the target's vertical field of
view at ``k * fx / fy`` rows per target row; it is then box-downsampled: columns by exactly ``k``, rows
by their exact overlap with each target row (only the two boundary rows of a target pixel are split,
assuming a uniform radiance inside them). Geometric outputs never need this: they are cast through the
target camera's own pixel centres. Pure numpy; no engine import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from blendify_core.ir.cameras import PerspectiveCamera

__all__ = ["SquarePixelPlan", "plan_square_pixels", "resample_rows"]


@dataclass(frozen=True)
class SquarePixelPlan:
    """The square-pixel render camera, its supersampling ``k``, the row scale and samples per pixel."""

    camera: PerspectiveCamera
    k: int
    row_scale: float  # rendered rows per target row (k * fx / fy)
    spp: int


def plan_square_pixels(camera: PerspectiveCamera, spp: int, max_k: int = 4) -> SquarePixelPlan:
    """A square-pixel camera covering exactly the image of ``camera`` (fx != fy)."""
    s = camera.fx / camera.fy
    k = int(max(1, min(max_k, math.floor(math.sqrt(max(spp, 1) / s)))))
    row_scale = k * s
    w_r = camera.width * k
    h_r = int(math.ceil(camera.height * row_scale - 1e-9))
    f_r = camera.fx * k
    cxp_r = (camera.cx + 0.5) * k
    cyp_r = (camera.cy + 0.5) * row_scale
    kmat = np.array([[f_r, 0.0, cxp_r - 0.5], [0.0, f_r, cyp_r - 0.5], [0.0, 0.0, 1.0]])
    render_cam = PerspectiveCamera(
        (w_r, h_r),
        K=kmat,
        near=camera.near,
        far=camera.far,
        tag=camera.tag,
        rotation_mode="quaternionWXYZ",
        rotation=camera.quaternion,
        translation=camera.translation,
    )
    pixels = k * k * s  # rendered pixels per target pixel
    return SquarePixelPlan(render_cam, k, row_scale, max(1, int(math.ceil(spp / pixels))))


def resample_rows(img: np.ndarray, width: int, height: int, k: int, row_scale: float) -> np.ndarray:
    """Box-downsample a square-pixel render (H_r, W*k, C) to the target (H, W, C)."""
    h_r, w_r = img.shape[:2]
    cols = img.reshape(h_r, width, k, -1).mean(axis=2)
    # weights[v, j] = overlap of target row v ([v, v+1] * row_scale) with rendered row j ([j, j+1])
    lo = np.arange(height)[:, None] * row_scale
    hi = lo + row_scale
    j = np.arange(h_r)[None, :]
    w = np.clip(np.minimum(hi, j + 1) - np.maximum(lo, j), 0.0, None) / row_scale
    return np.einsum("vj,jwc->vwc", w, cols).astype(img.dtype)
