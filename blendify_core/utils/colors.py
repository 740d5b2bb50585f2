"""Camera-dependent point-cloud colours: grey out (or hide) the points that face away from the camera."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from blendify_core.errors import InvalidSceneError
from blendify_core.errors import describe as _describe
from blendify_core.ir.cameras import Camera, PerspectiveCamera
from blendify_core.ir.validate import as_array, strict_arguments

__all__ = ["approximate_colors_from_camera"]


def _rgba_rows(name: str, colors: Any, n: int) -> np.ndarray:
    """(n, 4) float64 from (n, 3|4) or (3|4,) colours, float in [0, 1] or uint8 0-255."""
    raw = np.asarray(colors) if not isinstance(colors, (str, bytes)) else None
    if raw is None or raw.dtype.kind not in "uif" or raw.ndim not in (1, 2) or raw.shape[-1] not in (3, 4):
        raise InvalidSceneError(
            f"{name}: expected colours of shape (N, 3|4) or (3|4,), float in [0, 1] or uint8, got {_describe(colors)}"
        )
    if raw.ndim == 2 and raw.shape[0] != n:
        raise InvalidSceneError(f"{name}: expected {n} rows (one per normal), got {_describe(raw)}")
    if raw.dtype.kind in "iu":
        if raw.size and (raw.min() < 0 or raw.max() > 255):
            raise InvalidSceneError(f"{name}: integer colours must be 0-255")
        c = raw.astype(np.float64) / 255.0
    else:
        c = as_array(name, raw, dtype=np.float64, min_value=0.0, max_value=1.0)
    if c.shape[-1] == 3:
        c = np.concatenate([c, np.ones(c.shape[:-1] + (1,))], axis=-1)
    return np.broadcast_to(c, (n, 4))


@strict_arguments
def approximate_colors_from_camera(
    camera: Camera | ArrayLike,
    normals: ArrayLike,
    colors: ArrayLike,
    back_color: ArrayLike = (0.6, 0.6, 0.6),
    points: ArrayLike | None = None,
) -> np.ndarray:
    """Per-point RGBA colours (N, 4) float32: ``colors`` where a point faces the camera, ``back_color``
    where its normal points away from the camera (``normal . view_direction > 0``).

    ``camera``: a blendify camera (``scene.camera``) or a (3,) view direction (blendify's
    ``camera.get_camera_viewdir()``). For a perspective camera and given ``points`` (N, 3, world), each
    point's own view direction (point - camera position) is used, which is right near the image borders
    and for wide fields of view; otherwise the camera's optical axis is used for every point (blendify's
    behaviour, exact for orthographic cameras). ``back_color``: RGB, or RGBA with alpha < 1 to make
    back-facing points transparent (with alpha 0 they disappear; blendify's "hide"). ``colors``: (N, 3|4)
    or one (3|4,) colour, float in [0, 1] or uint8. Values are passed through unchanged (no colour-space
    conversion), so pass sRGB colours to an sRGB VertexColors.
    """
    n = as_array("normals", normals, dtype=np.float64, ndim=2)
    if n.shape[1] != 3:
        raise InvalidSceneError(f"normals: expected shape (N, 3), got {_describe(n)}")
    count = len(n)
    if isinstance(camera, Camera):
        axis = camera.viewdir
        if points is not None and isinstance(camera, PerspectiveCamera):
            p = as_array("points", points, dtype=np.float64, shape=(count, 3))
            view = p - camera.translation
        else:
            if points is not None:
                as_array("points", points, dtype=np.float64, shape=(count, 3))
            view = np.broadcast_to(axis, (count, 3))
    else:
        if points is not None:
            raise InvalidSceneError(
                "points: per-point view directions need a camera object (its position), not a view direction"
            )
        axis = as_array("camera", camera, dtype=np.float64, shape=(3,))
        if not np.linalg.norm(axis) > 0:
            raise InvalidSceneError("camera: the view direction must be a non-zero vector")
        view = np.broadcast_to(axis, (count, 3))
    front = _rgba_rows("colors", colors, count)
    back = _rgba_rows("back_color", back_color, 1)[0]
    facing_away = np.einsum("ij,ij->i", n, view) > 0
    out = np.array(front, dtype=np.float32)
    out[facing_away] = back.astype(np.float32)
    return out
