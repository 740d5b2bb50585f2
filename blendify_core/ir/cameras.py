"""Cameras. Pose: Blender/OpenGL camera frame (looks along local -Z, +Y up); identity rotation looks
down world -Z. Intrinsics: OpenCV style, in pixels, pixel centres at integer coordinates
(pixel (0, 0) covers [-0.5, 0.5]^2); ``cx, cy`` default to the image centre ((W-1)/2, (H-1)/2).

OpenCV extrinsics (``x_cam = R @ x_world + t``, +Z forward, +Y down) are an input and output format:
``Scene.set_camera_from_opencv`` and :meth:`Camera.opencv_extrinsics`.

Lens distortion (OpenCV k1, k2, p1, p2[, k3]) is part of the camera; the core renders an undistorted
image with a margin and remaps it, once, for every backend.
"""

from __future__ import annotations

import copy
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from blendify_core.errors import InvalidSceneError
from blendify_core.errors import describe as _describe
from blendify_core.ir.transforms import Positionable, ValidatedParam, _orthonormalise, matrix_to_quaternion
from blendify_core.ir.validate import as_array, as_float, as_int, raw_array
from blendify_core.typing import Float64Array, IntArray

__all__ = ["Camera", "PerspectiveCamera", "OrthographicCamera", "CV_FROM_BLENDER"]

_C = TypeVar("_C", bound="Camera")

CV_FROM_BLENDER = np.diag([1.0, -1.0, -1.0])
"""Camera-frame change between Blender/OpenGL (-Z forward, +Y up) and OpenCV (+Z forward, +Y down)."""


def _resolution(value: ArrayLike) -> tuple[int, int]:
    arr = raw_array("resolution", value)
    if arr.shape != (2,):
        raise InvalidSceneError(f"resolution: expected (width, height), got {_describe(value)}")
    w = as_int("resolution (width)", arr[0].item() if hasattr(arr[0], "item") else arr[0], min_value=1, max_value=65536)
    h = as_int(
        "resolution (height)", arr[1].item() if hasattr(arr[1], "item") else arr[1], min_value=1, max_value=65536
    )
    return w, h


class Camera(Positionable):
    """Base of cameras: resolution, principal point, clipping, distortion and the pose."""

    kind = "camera"
    cx = ValidatedParam(lambda obj, name, v: as_float(name, v), doc="Principal point x (OpenCV pixels).")
    cy = ValidatedParam(lambda obj, name, v: as_float(name, v), doc="Principal point y (OpenCV pixels).")

    def __init__(
        self,
        resolution: ArrayLike,
        near: float = 0.1,
        far: float = 100.0,
        center: ArrayLike | None = None,
        distortion: ArrayLike | None = None,
        tag: str = "camera",
        resolution_percentage: int = 100,
        **pose: Any,
    ):
        self._tag = tag
        self._resolution = _resolution(resolution)
        w, h = self._resolution
        self._near = as_float("near", near, min_value=0.0, exclusive_min=True)
        self._far = as_float("far", far, min_value=self._near, exclusive_min=True)
        self.resolution_percentage = resolution_percentage
        if center is None:
            self.cx, self.cy = (w - 1) / 2.0, (h - 1) / 2.0
        else:
            c = as_array("center", center, shape=(2,))
            self.cx, self.cy = float(c[0]), float(c[1])
        self.distortion = None if distortion is None else self._check_distortion(distortion)
        super().__init__(**pose)

    @staticmethod
    def _check_distortion(value: ArrayLike) -> Float64Array | None:
        d = as_array("distortion", value, ndim=1)
        if d.shape[0] not in (4, 5):
            raise InvalidSceneError(f"distortion: expected OpenCV (k1, k2, p1, p2[, k3]), got {d.shape[0]} values")
        out = np.zeros(5)
        out[: d.shape[0]] = d
        if not np.any(out):
            return None
        return out

    @property
    def resolution(self) -> IntArray:
        """(2,) int: (width, height) in pixels."""
        return np.array(self._resolution)

    @property
    def width(self) -> int:
        return self._resolution[0]

    @property
    def height(self) -> int:
        return self._resolution[1]

    @property
    def center(self) -> Float64Array:
        """Principal point (cx, cy) in OpenCV pixel coordinates (settable)."""
        return np.array([self.cx, self.cy])

    @center.setter
    def center(self, value: ArrayLike) -> None:
        c = as_array("center", value, shape=(2,))
        self.cx, self.cy = float(c[0]), float(c[1])

    @property
    def near(self) -> float:
        """Near clip distance (world units, settable; must stay below ``far``)."""
        return self._near

    @near.setter
    def near(self, value: float) -> None:
        self._near = as_float("near", value, min_value=0.0, max_value=self._far, exclusive_min=True, exclusive_max=True)

    @property
    def far(self) -> float:
        """Far clip distance (world units, settable; must stay above ``near``)."""
        return self._far

    @far.setter
    def far(self, value: float) -> None:
        self._far = as_float("far", value, min_value=self._near, exclusive_min=True)

    @property
    def resolution_percentage(self) -> int:
        """Render at this percentage of ``resolution`` (1-10000, settable)."""
        return self._resolution_percentage

    @resolution_percentage.setter
    def resolution_percentage(self, value: int) -> None:
        self._resolution_percentage = as_int("resolution_percentage", value, min_value=1, max_value=10000)

    @property
    def viewdir(self) -> Float64Array:
        """(3,) unit world direction the camera looks along (local -Z)."""
        return -self.rotation_matrix[:, 2]

    def get_camera_viewdir(self) -> Float64Array:
        """blendify's name for :attr:`viewdir`."""
        return self.viewdir

    def opencv_extrinsics(self) -> tuple[Float64Array, Float64Array]:
        """(R, t) with ``x_cam = R @ x_world + t`` in the OpenCV camera frame (+Z forward, +Y down)."""
        rb = self.rotation_matrix
        r = CV_FROM_BLENDER @ rb.T
        t = -r @ self.translation
        return r, t

    def world_to_camera_cv(self, points: ArrayLike) -> Float64Array:
        """World points (N, 3) in the OpenCV camera frame (+Z forward, +Y down)."""
        r, t = self.opencv_extrinsics()
        x: Float64Array = np.asarray(points, dtype=np.float64) @ r.T + t
        return x

    def copy(self: _C) -> _C:
        c = copy.copy(self)
        c._revisions = dict(self._revisions)
        return c

    def _scaled(self: _C, factor: float) -> _C:
        """A copy with the resolution multiplied by ``factor`` (resolution_percentage)."""
        c = self.copy()
        w, h = self._resolution
        nw, nh = max(1, round(w * factor)), max(1, round(h * factor))
        sx, sy = nw / w, nh / h
        c._resolution = (nw, nh)
        c.cx = (self.cx + 0.5) * sx - 0.5
        c.cy = (self.cy + 0.5) * sy - 0.5
        c.resolution_percentage = 100
        c._scale_intrinsics(sx, sy)
        return c

    def _scale_intrinsics(self, sx: float, sy: float) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def project(self, points: ArrayLike) -> tuple[Float64Array, Float64Array]:  # pragma: no cover - overridden
        raise NotImplementedError

    def pixel_rays(self, pixels: ArrayLike | None = None) -> tuple[Float64Array, Float64Array]:  # pragma: no cover
        raise NotImplementedError

    def _base_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "tag": self.tag,
            "resolution": list(self._resolution),
            "near": self.near,
            "far": self.far,
            "center": [self.cx, self.cy],
            "distortion": None if self.distortion is None else self.distortion.tolist(),
            "resolution_percentage": self.resolution_percentage,
            "quaternion": self.quaternion.tolist(),
            "translation": self.translation.tolist(),
        }


class PerspectiveCamera(Camera):
    """A pinhole camera. Give exactly one of ``focal_dist`` (pixels, fx = fy), ``fov_x`` / ``fov_y``
    (full angles, radians) or ``K`` (3x3, fx != fy allowed; its principal point is used unless ``center``
    is given)."""

    kind = "perspective"
    fx = ValidatedParam(
        lambda obj, name, v: as_float(name, v, min_value=0.0, exclusive_min=True), doc="Focal length x (pixels)."
    )
    fy = ValidatedParam(
        lambda obj, name, v: as_float(name, v, min_value=0.0, exclusive_min=True), doc="Focal length y (pixels)."
    )

    def __init__(
        self,
        resolution: ArrayLike,
        focal_dist: float | None = None,
        fov_x: float | None = None,
        fov_y: float | None = None,
        center: ArrayLike | None = None,
        K: ArrayLike | None = None,
        near: float = 0.1,
        far: float = 100.0,
        distortion: ArrayLike | None = None,
        tag: str = "camera",
        resolution_percentage: int = 100,
        **pose: Any,
    ):
        given = [
            n for n, v in (("focal_dist", focal_dist), ("fov_x", fov_x), ("fov_y", fov_y), ("K", K)) if v is not None
        ]
        if len(given) != 1:
            raise InvalidSceneError(
                "set_perspective_camera: expected exactly one of focal_dist, fov_x, fov_y or K, got "
                + (", ".join(given) if given else "none")
            )
        w, h = _resolution(resolution)
        if K is not None:
            k = as_array("K", K, shape=(3, 3))
            if abs(k[0, 1]) > 1e-12 or abs(k[1, 0]) > 1e-12 or abs(k[2, 0]) > 0 or abs(k[2, 1]) > 0 or k[2, 2] != 1:
                raise InvalidSceneError(
                    f"K: expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), got {k.tolist()}"
                )
            fx, fy = float(k[0, 0]), float(k[1, 1])
            if center is None:
                center = (k[0, 2], k[1, 2])
        elif focal_dist is not None:
            fx = fy = as_float("focal_dist", focal_dist, min_value=0.0, exclusive_min=True)
        elif fov_x is not None:
            a = as_float(
                "fov_x", fov_x, min_value=0.0, max_value=np.pi, exclusive_min=True, exclusive_max=True, unit="rad"
            )
            fx = fy = w / (2.0 * np.tan(a / 2.0))
        else:
            a = as_float(
                "fov_y", fov_y, min_value=0.0, max_value=np.pi, exclusive_min=True, exclusive_max=True, unit="rad"
            )
            fx = fy = h / (2.0 * np.tan(a / 2.0))
        if not (fx > 0 and fy > 0 and np.isfinite(fx) and np.isfinite(fy)):
            raise InvalidSceneError(f"K: expected positive finite focal lengths, got fx={fx}, fy={fy}")
        self.fx, self.fy = float(fx), float(fy)
        super().__init__(resolution, near, far, center, distortion, tag, resolution_percentage, **pose)

    @property
    def K(self) -> Float64Array:  # noqa: N802 - the standard name
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def focal_dist(self) -> float:
        """Focal length in pixels (fx; equals fy unless the pixels are non-square). Setting it sets
        fx = fy (square pixels)."""
        return self.fx

    @focal_dist.setter
    def focal_dist(self, value: float) -> None:
        self.fx = self.fy = as_float("focal_dist", value, min_value=0.0, exclusive_min=True)

    @property
    def fov_x(self) -> float:
        """Full horizontal field of view (radians). Setting it sets fx = fy (square pixels)."""
        return 2.0 * float(np.arctan(self.width / (2.0 * self.fx)))

    @fov_x.setter
    def fov_x(self, value: float) -> None:
        a = as_float("fov_x", value, min_value=0.0, max_value=np.pi, exclusive_min=True, exclusive_max=True, unit="rad")
        self.fx = self.fy = self.width / (2.0 * float(np.tan(a / 2.0)))

    @property
    def fov_y(self) -> float:
        """Full vertical field of view (radians). Setting it sets fx = fy (square pixels)."""
        return 2.0 * float(np.arctan(self.height / (2.0 * self.fy)))

    @fov_y.setter
    def fov_y(self, value: float) -> None:
        a = as_float("fov_y", value, min_value=0.0, max_value=np.pi, exclusive_min=True, exclusive_max=True, unit="rad")
        self.fx = self.fy = self.height / (2.0 * float(np.tan(a / 2.0)))

    def _scale_intrinsics(self, sx: float, sy: float) -> None:
        self.fx *= sx
        self.fy *= sy

    def project(self, points: ArrayLike) -> tuple[Float64Array, Float64Array]:
        """Project world points: (N, 2) OpenCV pixel coordinates and (N,) planar depth (ignores distortion)."""
        x = self.world_to_camera_cv(points)
        z = x[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = self.fx * x[:, 0] / z + self.cx
            v = self.fy * x[:, 1] / z + self.cy
        return np.stack([u, v], axis=1), z

    def pixel_rays(self, pixels: ArrayLike | None = None) -> tuple[Float64Array, Float64Array]:
        """World-space rays through pixel centres: origins (N, 3) and unit directions (N, 3).

        ``pixels`` is (N, 2) OpenCV (u, v); by default every pixel in row-major order (v outer)."""
        if pixels is None:
            vv, uu = np.mgrid[0 : self.height, 0 : self.width]
            pixels = np.stack([uu.ravel(), vv.ravel()], axis=1).astype(np.float64)
        pixels = np.asarray(pixels, dtype=np.float64)
        d_cv = np.stack(
            [(pixels[:, 0] - self.cx) / self.fx, (pixels[:, 1] - self.cy) / self.fy, np.ones(len(pixels))], axis=1
        )
        r, _ = self.opencv_extrinsics()
        d = d_cv @ r  # R^T applied to row vectors
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return np.broadcast_to(self.translation, d.shape).copy(), d

    def to_dict(self) -> dict[str, Any]:
        return {**self._base_dict(), "fx": self.fx, "fy": self.fy}


class OrthographicCamera(Camera):
    """An orthographic camera seeing ``ortho_scale`` world units across the image width (square pixels)."""

    kind = "orthographic"

    def __init__(
        self,
        resolution: ArrayLike,
        ortho_scale: float = 1.0,
        near: float = 0.1,
        far: float = 100.0,
        center: ArrayLike | None = None,
        distortion: ArrayLike | None = None,
        tag: str = "camera",
        resolution_percentage: int = 100,
        **pose: Any,
    ):
        self.ortho_scale = ortho_scale
        if distortion is not None:
            raise InvalidSceneError("distortion: lens distortion applies to perspective cameras only")
        super().__init__(resolution, near, far, center, None, tag, resolution_percentage, **pose)

    @property
    def ortho_scale(self) -> float:
        """Visible width in world units (settable)."""
        return self._ortho_scale

    @ortho_scale.setter
    def ortho_scale(self, value: float) -> None:
        self._ortho_scale = as_float("ortho_scale", value, min_value=0.0, exclusive_min=True)

    @property
    def pixel_size(self) -> float:
        """World units per pixel."""
        return self.ortho_scale / self.width

    def _scale_intrinsics(self, sx: float, sy: float) -> None:
        pass  # same visible width at any resolution

    def project(self, points: ArrayLike) -> tuple[Float64Array, Float64Array]:
        x = self.world_to_camera_cv(points)
        s = self.pixel_size
        return np.stack([x[:, 0] / s + self.cx, x[:, 1] / s + self.cy], axis=1), x[:, 2]

    def pixel_rays(self, pixels: ArrayLike | None = None) -> tuple[Float64Array, Float64Array]:
        if pixels is None:
            vv, uu = np.mgrid[0 : self.height, 0 : self.width]
            pixels = np.stack([uu.ravel(), vv.ravel()], axis=1).astype(np.float64)
        pixels = np.asarray(pixels, dtype=np.float64)
        s = self.pixel_size
        o_cv = np.stack([(pixels[:, 0] - self.cx) * s, (pixels[:, 1] - self.cy) * s, np.zeros(len(pixels))], axis=1)
        r, t = self.opencv_extrinsics()
        origins = (o_cv - t) @ r
        d = np.broadcast_to(self.viewdir, origins.shape).copy()
        return origins, d

    def to_dict(self) -> dict[str, Any]:
        return {**self._base_dict(), "ortho_scale": self.ortho_scale}


def camera_from_opencv(
    K: ArrayLike,
    R: ArrayLike,
    t: ArrayLike,
    resolution: ArrayLike,
    distortion: ArrayLike | None = None,
    near: float = 0.1,  # noqa: N803
    far: float = 100.0,
) -> PerspectiveCamera:
    """A perspective camera from OpenCV intrinsics and extrinsics (``x_cam = R @ x_world + t``)."""
    r = _orthonormalise("R", as_array("R", R, shape=(3, 3)))
    tv = as_array("t", t, shape=(3,))
    rb = r.T @ CV_FROM_BLENDER
    position = -r.T @ tv
    return PerspectiveCamera(
        resolution,
        K=K,
        near=near,
        far=far,
        distortion=distortion,
        rotation_mode="quaternionWXYZ",
        rotation=matrix_to_quaternion(rb),
        translation=position,
    )


def camera_from_dict(d: dict[str, Any]) -> Camera:
    common = dict(
        near=d["near"],
        far=d["far"],
        center=d["center"],
        tag=d["tag"],
        resolution_percentage=d.get("resolution_percentage", 100),
        rotation=d["quaternion"],
        translation=d["translation"],
    )
    if d["kind"] == "perspective":
        k = np.array([[d["fx"], 0, d["center"][0]], [0, d["fy"], d["center"][1]], [0, 0, 1]])
        return PerspectiveCamera(d["resolution"], K=k, distortion=d["distortion"], **common)
    if d["kind"] == "orthographic":
        return OrthographicCamera(d["resolution"], ortho_scale=d["ortho_scale"], **common)
    raise InvalidSceneError(f"scene file: unknown camera kind {d['kind']!r}")
