"""OpenCV lens distortion, applied once by the core for every backend: render a pinhole image with a
margin that covers every distorted pixel's ray, then remap it."""

from __future__ import annotations

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.cameras import PerspectiveCamera
from blendify_core.pipeline.result import RenderResult
from blendify_core.typing import AnyArray, Float64Array

__all__ = ["undistort_points", "distort_points", "margin_camera", "remap_result"]

MAX_GROWTH = 3.0


def distort_points(xy: Float64Array, d: Float64Array) -> Float64Array:
    """Apply OpenCV distortion (k1, k2, p1, p2, k3) to normalised image coordinates (N, 2)."""
    k1, k2, p1, p2, k3 = d
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([xd, yd], axis=1)


def undistort_points(xy_d: Float64Array, d: Float64Array, iterations: int = 30) -> Float64Array:
    """Invert :func:`distort_points` by fixed-point iteration (as OpenCV's undistortPoints)."""
    k1, k2, p1, p2, k3 = d
    x, y = xy_d[:, 0].copy(), xy_d[:, 1].copy()
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
        radial = np.where(np.abs(radial) < 1e-6, 1e-6, radial)
        dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        x = (xy_d[:, 0] - dx) / radial
        y = (xy_d[:, 1] - dy) / radial
    return np.stack([x, y], axis=1)


def _source_coords(cam: PerspectiveCamera, d: Float64Array) -> Float64Array:
    """Undistorted normalised coordinates seen by every output pixel (H*W, 2)."""
    vv, uu = np.mgrid[0 : cam.height, 0 : cam.width]
    xy_d = np.stack([(uu.ravel() - cam.cx) / cam.fx, (vv.ravel() - cam.cy) / cam.fy], axis=1)
    with np.errstate(all="ignore"):
        xy = undistort_points(xy_d, d)
        back = distort_points(xy, d)
    # the fixed-point inversion diverges (NaN) or settles on a wrong point where the model folds over
    err_px = float(np.max(np.abs(back - xy_d)) * max(cam.fx, cam.fy)) if np.all(np.isfinite(back)) else np.inf
    if not err_px < 0.01:
        raise InvalidSceneError(
            "distortion: the OpenCV model with these coefficients cannot be inverted over the whole image "
            f"(it folds over or diverges; residual {err_px:.3g} px); check the signs and units of (k1, k2, p1, p2, k3)"
        )
    return xy


def margin_camera(cam: PerspectiveCamera) -> tuple[PerspectiveCamera, Float64Array]:
    """A pinhole camera (same pose and focal lengths) whose image covers every ray of the distorted
    camera, and the (H*W, 2) pixel coordinates in it that each output pixel samples."""
    if cam.distortion is None:
        raise InvalidSceneError("camera.distortion: margin_camera needs a camera with lens distortion")
    xy = _source_coords(cam, cam.distortion)
    u = xy[:, 0] * cam.fx
    v = xy[:, 1] * cam.fy
    pad = 2.0
    umin, umax = float(u.min()) - pad, float(u.max()) + pad
    vmin, vmax = float(v.min()) - pad, float(v.max()) + pad
    limit_w, limit_h = MAX_GROWTH * cam.width, MAX_GROWTH * cam.height
    if umax - umin > limit_w or vmax - vmin > limit_h:
        raise InvalidSceneError(
            "distortion: these coefficients bend rays so far that the undistorted image would be more than "
            f"{MAX_GROWTH:g}x the output size; check the signs and units of (k1, k2, p1, p2, k3)"
        )
    w = int(np.ceil(umax - umin)) + 1
    h = int(np.ceil(vmax - vmin)) + 1
    cx, cy = -umin, -vmin
    k = np.array([[cam.fx, 0, cx], [0, cam.fy, cy], [0, 0, 1.0]])
    render_cam = PerspectiveCamera(
        (w, h), K=k, near=cam.near, far=cam.far, tag=cam.tag, rotation=cam.quaternion, translation=cam.translation
    )
    src = np.stack([u + cx, v + cy], axis=1)
    return render_cam, src


def _bilinear(img: AnyArray, src: Float64Array, shape: tuple[int, int]) -> AnyArray:
    h, w = img.shape[:2]
    x = np.clip(src[:, 0], 0, w - 1)
    y = np.clip(src[:, 1], 0, h - 1)
    x0 = np.floor(x).astype(int)
    y0 = np.floor(y).astype(int)
    x1 = np.minimum(x0 + 1, w - 1)
    y1 = np.minimum(y0 + 1, h - 1)
    fx = (x - x0)[:, None] if img.ndim == 3 else (x - x0)
    fy = (y - y0)[:, None] if img.ndim == 3 else (y - y0)
    out: AnyArray = (
        img[y0, x0] * (1 - fx) * (1 - fy)
        + img[y0, x1] * fx * (1 - fy)
        + img[y1, x0] * (1 - fx) * fy
        + img[y1, x1] * fx * fy
    )
    return out.reshape(shape + img.shape[2:]).astype(img.dtype)


def _nearest(img: AnyArray, src: Float64Array, shape: tuple[int, int]) -> AnyArray:
    h, w = img.shape[:2]
    x = np.clip(np.round(src[:, 0]).astype(int), 0, w - 1)
    y = np.clip(np.round(src[:, 1]).astype(int), 0, h - 1)
    picked: AnyArray = img[y, x]
    return picked.reshape(shape + img.shape[2:])


def remap_result(
    result: RenderResult, src: Float64Array, out_cam: PerspectiveCamera, render_cam: PerspectiveCamera
) -> RenderResult:
    """Resample every output of a pinhole render into the distorted image (in place)."""
    shape = (out_cam.height, out_cam.width)
    if result.rgba is not None:
        result.rgba = _bilinear(result.rgba, src, shape)
    if result.albedo is not None:
        result.albedo = _bilinear(result.albedo, src, shape)
    if result.normal is not None:
        n = _bilinear(result.normal, src, shape)
        ln = np.linalg.norm(n, axis=-1, keepdims=True)
        result.normal = np.divide(n, ln, out=np.zeros_like(n), where=ln > 1e-6).astype(np.float32)
    if result.depth is not None:
        result.depth = _nearest(result.depth, src, shape)
    if result.instance is not None:
        result.instance = _nearest(result.instance, src, shape)
    return result
