"""Camera trajectories: keypoints (position, rotation, time) refined into smooth per-frame poses.

Positions are interpolated with splines (scipy), rotations with quaternion slerp or squad on a
hemisphere-consistent quaternion sequence, so a camera never spins the long way round (a 180-degree
turn between two keypoints turns by 180 degrees, never 360).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from blendify_core.errors import InvalidSceneError
from blendify_core.errors import describe as _describe
from blendify_core.ir.transforms import Positionable, quaternion_from_rotation
from blendify_core.ir.validate import as_array, as_float, strict_api, strict_arguments

__all__ = ["Pose", "Trajectory", "apply_pose"]

POSITION_INTERPOLATIONS = ("linear", "quadratic", "cubic")
ROTATION_INTERPOLATIONS = ("slerp", "squad")


@strict_api
@dataclass(frozen=True)
class Pose:
    """One camera pose: ``position`` (3,), ``quaternion`` (4,) unit WXYZ, ``time`` (seconds).

    Also readable as a dict (``pose["position"]``), like blendify's refined trajectories."""

    position: np.ndarray
    quaternion: np.ndarray
    time: float

    def __getitem__(self, key: str) -> Any:
        if key not in ("position", "quaternion", "time"):
            raise KeyError(key)
        return getattr(self, key)

    def keys(self) -> tuple[str, ...]:
        return ("position", "quaternion", "time")

    def to_dict(self) -> dict[str, Any]:
        return {"position": self.position.tolist(), "quaternion": self.quaternion.tolist(), "time": self.time}


@strict_arguments
def apply_pose(camera: Positionable, pose: Pose | dict[str, Any]) -> None:
    """Move a camera (or any blendify positionable object) to ``pose``."""
    if not isinstance(camera, Positionable):
        raise InvalidSceneError(f"camera: expected a blendify camera or positionable object, got {_describe(camera)}")
    camera.set_position(rotation_mode="quaternionWXYZ", rotation=pose["quaternion"], translation=pose["position"])


# -------------------------------------------------------------------------------------------------
# quaternion helpers (WXYZ, vectorised over rows)
# -------------------------------------------------------------------------------------------------


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def _qconj(q: np.ndarray) -> np.ndarray:
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def _qlog(q: np.ndarray) -> np.ndarray:
    """Logarithm of unit quaternions -> pure quaternions (0, axis * half_angle)."""
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    ang = np.arctan2(s, q[..., :1])
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(s > 1e-12, ang / s, 1.0)
    return np.concatenate([np.zeros_like(q[..., :1]), v * f], axis=-1)


def _qexp(p: np.ndarray) -> np.ndarray:
    v = p[..., 1:]
    a = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(a > 1e-12, np.sin(a) / a, 1.0)
    return np.concatenate([np.cos(a), v * f], axis=-1)


def _slerp(q0: np.ndarray, q1: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Row-wise slerp along the SHORTER arc (q1 is flipped when q0 . q1 < 0)."""
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)
    dot = np.abs(dot)
    u = u[..., None]
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_t = np.sin(theta)
    small = sin_t < 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        w0 = np.where(small, 1.0 - u, np.sin((1.0 - u) * theta) / sin_t)
        w1 = np.where(small, u, np.sin(u * theta) / sin_t)
    out = w0 * q0 + w1 * q1
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def _hemisphere_align(q: np.ndarray) -> np.ndarray:
    """Flip signs so consecutive quaternions have a non-negative dot product (no long-way spins)."""
    out = np.array(q, dtype=np.float64)
    for i in range(1, len(out)):
        if np.dot(out[i - 1], out[i]) < 0:
            out[i] = -out[i]
    return out


def _canonical(q: np.ndarray) -> np.ndarray:
    return np.where(q[..., :1] < 0, -q, q)


# -------------------------------------------------------------------------------------------------


@strict_api
class Trajectory:
    """A camera path: keypoints (position, rotation, time), kept sorted by time.

    >>> traj = Trajectory()
    >>> traj.add_keypoint((0, -5, 1), rotation=(0, 0, 0), time=0.0, rotation_mode="look_at")
    >>> traj.add_keypoint((5, 0, 1), rotation=(0, 0, 0), time=2.0, rotation_mode="look_at")
    >>> poses = traj.refine(1 / 30)  # 61 poses, cubic positions, squad rotations

    A keypoint added at the time of an existing one REPLACES it (the last one wins; blendify kept the
    first and ignored the new one silently). Note the argument order: position first, then rotation
    (blendify 2.1: ``add_keypoint(quaternion, position, time)``).
    """

    def __init__(self, keypoints: Sequence[Any] | None = None) -> None:
        self._times = np.zeros(0)
        self._positions = np.zeros((0, 3))
        self._quaternions = np.zeros((0, 4))
        if keypoints is not None:
            for kp in keypoints:
                if isinstance(kp, dict):
                    self.add_keypoint(
                        kp["position"],
                        kp.get("rotation", kp.get("quaternion")),
                        kp.get("time"),
                        kp.get("rotation_mode", "quaternionWXYZ"),
                    )
                else:
                    self.add_keypoint(*kp)

    # -- keypoints ---------------------------------------------------------------------------------
    def add_keypoint(
        self,
        position: ArrayLike,
        rotation: ArrayLike | None = None,
        time: float | None = None,
        rotation_mode: str = "quaternionWXYZ",
    ) -> None:
        """Add a keypoint. ``rotation`` in any blendify rotation mode (``quaternionWXYZ``, ``quaternionXYZW``,
        ``rotvec``, ``rotmat``, ``eulerXYZ``..., ``look_at`` with a target point); None = identity
        (looking down world -Z). ``time`` in seconds; None = one second after the last keypoint (0 for the
        first). A keypoint at the time of an existing one replaces it."""
        pos = as_array("position", position, shape=(3,))
        q = quaternion_from_rotation(rotation_mode, rotation, pos)
        if time is None:
            t = float(self._times[-1] + 1.0) if len(self._times) else 0.0
        else:
            t = as_float("time", time)
        same = np.abs(self._times - t) <= 1e-9 * max(1.0, abs(t))
        if same.any():
            i = int(np.flatnonzero(same)[0])
            self._positions[i] = pos
            self._quaternions[i] = q
            return
        i = int(np.searchsorted(self._times, t))
        self._times = np.insert(self._times, i, t)
        self._positions = np.insert(self._positions, i, pos, axis=0)
        self._quaternions = np.insert(self._quaternions, i, q, axis=0)

    def remove_keypoint(self, index: int) -> None:
        if not -len(self) <= index < len(self):
            raise InvalidSceneError(f"index: expected a keypoint index in [0, {len(self)}), got {index}")
        self._times = np.delete(self._times, index)
        self._positions = np.delete(self._positions, index, axis=0)
        self._quaternions = np.delete(self._quaternions, index, axis=0)

    @property
    def times(self) -> np.ndarray:
        return self._times.copy()

    @property
    def positions(self) -> np.ndarray:
        return self._positions.copy()

    @property
    def quaternions(self) -> np.ndarray:
        return self._quaternions.copy()

    @property
    def duration(self) -> float:
        return float(self._times[-1] - self._times[0]) if len(self._times) else 0.0

    def __len__(self) -> int:
        return len(self._times)

    def __iter__(self) -> Iterator[Pose]:
        for i in range(len(self)):
            yield self[i]

    def __getitem__(self, index: int) -> Pose:
        return Pose(self._positions[index].copy(), self._quaternions[index].copy(), float(self._times[index]))

    def __repr__(self) -> str:
        return f"Trajectory({len(self)} keypoints, {self.duration:g} s)"

    @staticmethod
    def apply(camera: Positionable, pose: Pose | dict[str, Any]) -> None:
        """Move ``camera`` to ``pose`` (see :func:`apply_pose`)."""
        apply_pose(camera, pose)

    # -- (de)serialisation -------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """Plain-Python description (JSON-serialisable); :meth:`from_dict` reads it back."""
        return {"keypoints": [p.to_dict() for p in self]}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Trajectory:
        if not isinstance(data, dict) or not isinstance(data.get("keypoints"), list):
            raise InvalidSceneError(f"data: expected {{'keypoints': [...]}}, got {_describe(data)}")
        traj = cls()
        for i, kp in enumerate(data["keypoints"]):
            if not isinstance(kp, dict) or not {"position", "quaternion", "time"} <= set(kp):
                raise InvalidSceneError(f"data['keypoints'][{i}]: expected position, quaternion and time, got {kp!r}")
            traj.add_keypoint(kp["position"], kp["quaternion"], kp["time"])
        return traj

    # -- builders --------------------------------------------------------------------------------
    @classmethod
    def orbit(
        cls,
        center: ArrayLike = (0.0, 0.0, 0.0),
        radius: float = 3.0,
        height: float = 1.0,
        duration: float = 4.0,
        n_keypoints: int = 8,
        start_angle_deg: float = -90.0,
        turns: float = 1.0,
    ) -> Trajectory:
        """A circular path around ``center`` (counter-clockwise seen from +Z) at ``height`` above it,
        always looking at ``center``; ``n_keypoints`` keypoints per turn, refined smoothly."""
        c = as_array("center", center, shape=(3,))
        r = as_float("radius", radius, min_value=0.0, exclusive_min=True)
        h = as_float("height", height)
        d = as_float("duration", duration, min_value=0.0, exclusive_min=True)
        if isinstance(n_keypoints, bool) or not isinstance(n_keypoints, (int, np.integer)) or n_keypoints < 3:
            raise InvalidSceneError(f"n_keypoints: expected an integer >= 3, got {n_keypoints!r}")
        tu = as_float("turns", turns, min_value=0.0, exclusive_min=True)
        count = max(2, int(np.ceil(n_keypoints * tu)) + 1)
        traj = cls()
        for i, s in enumerate(np.linspace(0.0, 1.0, count)):
            a = np.deg2rad(start_angle_deg) + 2 * np.pi * tu * s
            pos = c + np.array([r * np.cos(a), r * np.sin(a), h])
            traj.add_keypoint(pos, c, d * s if i < count - 1 else d, rotation_mode="look_at")
        return traj

    # -- sampling ----------------------------------------------------------------------------------
    def sample(
        self,
        times: ArrayLike,
        interpolation: str = "cubic",
        rotation_interpolation: str | None = None,
        smoothness: float = 0.0,
    ) -> list[Pose]:
        """Poses at arbitrary ``times`` (clamped to the keypoint range); see :meth:`refine`."""
        if len(self) == 0:
            raise InvalidSceneError("trajectory: no keypoints; call add_keypoint() first")
        t = as_array("times", np.atleast_1d(times), ndim=1)
        if t.size > 1 and np.any(np.diff(t) < 0):
            raise InvalidSceneError("times: expected non-decreasing times")
        pos_mode, rot_mode = _modes(interpolation, rotation_interpolation)
        s = as_float("smoothness", smoothness, min_value=0.0)
        tc = np.clip(t, self._times[0], self._times[-1])
        positions = self._interp_positions(tc, pos_mode)
        quats = self._interp_rotations(tc, rot_mode)
        if s > 0 and len(t) > 1:
            from scipy.ndimage import gaussian_filter1d

            positions = gaussian_filter1d(positions, s, axis=0, mode="nearest")
            aligned = _hemisphere_align(quats)
            quats = gaussian_filter1d(aligned, s, axis=0, mode="nearest")
            quats /= np.linalg.norm(quats, axis=1, keepdims=True)
        quats = _canonical(quats)
        return [Pose(positions[i].copy(), quats[i].copy(), float(t[i])) for i in range(len(t))]

    def refine(
        self,
        time_step: float = 1.0 / 30.0,
        interpolation: str = "cubic",
        smoothness: float = 0.0,
        rotation_interpolation: str | None = None,
    ) -> list[Pose]:
        """Per-frame poses every ``time_step`` seconds from the first keypoint to the last (included
        when it falls on the grid).

        ``interpolation`` (positions): ``"linear"``, ``"quadratic"`` or ``"cubic"`` (not-a-knot cubic
        spline through the keypoints; with 2 keypoints every mode is linear, with 3 a quadratic/cubic
        spline is a parabola). ``"slerp"`` / ``"squad"`` are shorthands for linear+slerp / cubic+squad.
        ``rotation_interpolation``: ``"slerp"`` (piecewise geodesic) or ``"squad"`` (smooth spherical
        spline); default slerp for linear positions, squad otherwise. ``smoothness``: Gaussian sigma in
        FRAMES applied to positions and rotations after interpolation (0 = none; blendify's default
        was 5, which does not pass through the keypoints).
        Robust to 2 keypoints (and 1: a constant pose), repeated times and 180-degree turns."""
        step = as_float("time_step", time_step, min_value=0.0, exclusive_min=True)
        if len(self) == 0:
            raise InvalidSceneError("trajectory: no keypoints; call add_keypoint() first")
        span = self.duration
        n = int(np.floor(span / step + 1e-9)) + 1
        times = self._times[0] + np.arange(n) * step
        return self.sample(times, interpolation, rotation_interpolation, smoothness)

    # -- internals -------------------------------------------------------------------------------
    def _interp_positions(self, t: np.ndarray, mode: str) -> np.ndarray:
        kt, kp = self._times, self._positions
        if len(kt) == 1:
            return np.repeat(kp, len(t), axis=0)
        if mode == "linear" or len(kt) == 2:
            return np.stack([np.interp(t, kt, kp[:, c]) for c in range(3)], axis=1)
        from scipy.interpolate import CubicSpline, make_interp_spline

        if mode == "quadratic":
            return make_interp_spline(kt, kp, k=2, axis=0)(t)
        return CubicSpline(kt, kp, axis=0, bc_type="not-a-knot")(t)

    def _interp_rotations(self, t: np.ndarray, mode: str) -> np.ndarray:
        kt = self._times
        q = _hemisphere_align(self._quaternions)
        if len(kt) == 1:
            return np.repeat(q, len(t), axis=0)
        seg = np.clip(np.searchsorted(kt, t, side="right") - 1, 0, len(kt) - 2)
        u = np.clip((t - kt[seg]) / (kt[seg + 1] - kt[seg]), 0.0, 1.0)
        q0, q1 = q[seg], q[seg + 1]
        if mode == "slerp" or len(kt) == 2:
            return _slerp(q0, q1, u)
        # squad control points s_i = q_i exp(-(log(q_i^-1 q_{i+1}) + log(q_i^-1 q_{i-1})) / 4)
        inner = np.array(q)
        qi = q[1:-1]
        inv = _qconj(qi)
        tangent = _qlog(_qmul(inv, q[2:])) + _qlog(_qmul(inv, q[:-2]))
        inner[1:-1] = _qmul(qi, _qexp(-0.25 * tangent))
        inner = inner / np.linalg.norm(inner, axis=1, keepdims=True)
        s0, s1 = inner[seg], inner[seg + 1]
        a = _slerp(q0, q1, u)
        b = _slerp_raw(s0, s1, u)  # no shorter-arc flip: s_i follow the aligned q_i continuously
        return _slerp_raw(a, b, 2.0 * u * (1.0 - u))


def _slerp_raw(q0: np.ndarray, q1: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Slerp WITHOUT the shorter-arc flip (squad's inner interpolation must not flip)."""
    dot = np.clip(np.sum(q0 * q1, axis=-1, keepdims=True), -1.0, 1.0)
    theta = np.arccos(dot)
    sin_t = np.sin(theta)
    u = u[..., None]
    small = np.abs(sin_t) < 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        w0 = np.where(small, 1.0 - u, np.sin((1.0 - u) * theta) / sin_t)
        w1 = np.where(small, u, np.sin(u * theta) / sin_t)
    out = w0 * q0 + w1 * q1
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def _modes(interpolation: str, rotation_interpolation: str | None) -> tuple[str, str]:
    if interpolation == "slerp":
        pos, rot = "linear", "slerp"
    elif interpolation == "squad":
        pos, rot = "cubic", "squad"
    elif interpolation in POSITION_INTERPOLATIONS:
        pos, rot = interpolation, ("slerp" if interpolation == "linear" else "squad")
    else:
        raise InvalidSceneError(
            f"interpolation: expected one of {list(POSITION_INTERPOLATIONS) + list(ROTATION_INTERPOLATIONS)}, "
            f"got {interpolation!r}"
        )
    if rotation_interpolation is not None:
        if rotation_interpolation not in ROTATION_INTERPOLATIONS:
            raise InvalidSceneError(
                f"rotation_interpolation: expected one of {list(ROTATION_INTERPOLATIONS)}, "
                f"got {rotation_interpolation!r}"
            )
        rot = rotation_interpolation
    return pos, rot
