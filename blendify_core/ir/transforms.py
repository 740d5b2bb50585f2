"""Rotation modes, look-at frames and the :class:`Positionable` base of cameras, lights and renderables.

Rotation modes (blendify's vocabulary; all resolve to a unit quaternion in WXYZ order):

===================  ==========================================================================
``quaternionWXYZ``   4 numbers (w, x, y, z); normalised (a zero quaternion is an error)
``quaternionXYZW``   4 numbers (x, y, z, w)
``rotvec``           axis * angle (radians), 3 numbers
``rotmat``           3x3 matrix; re-orthonormalised (polar decomposition) when slightly off,
                     rejected when it is not close to a proper rotation (reflection, scale, singular)
``euler<order>``     e.g. ``eulerXYZ`` / ``eulerxyz``: angles in DEGREES; upper-case axes are intrinsic,
                     lower-case extrinsic (scipy's convention); 1 to 3 axes
``look_at``          a target point, a positionable object (its translation), or ``(target, roll_deg)``.
                     The object's local -Z points at the target and local +Y is as close to world +Z as
                     possible; when the view direction is parallel to the Z axis, world +Y is used instead
                     (looking straight down or straight up: image up = +Y, as blendify). A position equal
                     to the target gives the identity rotation.
===================  ==========================================================================
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import Any, Generic, TypeVar, overload

import numpy as np
from numpy.typing import ArrayLike

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.validate import as_array, as_float, frozen, strict_api
from blendify_core.typing import Float64Array

__all__ = [
    "ROTATION_MODES",
    "Positionable",
    "quaternion_from_rotation",
    "quaternion_to_matrix",
    "matrix_to_quaternion",
    "look_at_rotation",
    "compose_matrix",
]

ROTATION_MODES = ("quaternionWXYZ", "quaternionXYZW", "rotvec", "rotmat", "euler<order>", "look_at")

_uid_counter = itertools.count(1)
_T = TypeVar("_T")


def quaternion_to_matrix(q: ArrayLike) -> Float64Array:
    """3x3 rotation matrix of a unit WXYZ quaternion (float64)."""
    w, x, y, z = (float(v) for v in np.asarray(q, dtype=np.float64))
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ],
        dtype=np.float64,
    )


def matrix_to_quaternion(m: ArrayLike) -> Float64Array:
    """Unit WXYZ quaternion (w >= 0) of a proper rotation matrix (Shepperd's method, float64)."""
    m = np.asarray(m, dtype=np.float64)
    q: Float64Array
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = np.array([0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s])
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = np.array([(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s])
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = np.array([(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s])
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = np.array([(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s])
    q /= np.linalg.norm(q)
    if q[0] < 0:
        q = -q
    return q


def _orthonormalise(name: str, m: Float64Array) -> Float64Array:
    u, s, vt = np.linalg.svd(m)
    det = np.linalg.det(m)
    if not np.isfinite(det) or det <= 0:
        raise InvalidSceneError(
            f"{name}: expected a proper rotation matrix (determinant +1), got determinant {det:.3g} "
            "(a reflection or a singular matrix)"
        )
    if np.max(np.abs(s - 1.0)) > 1e-2:
        raise InvalidSceneError(
            f"{name}: expected an orthonormal rotation matrix, got singular values {np.round(s, 4).tolist()} "
            "(scale and shear belong in the geometry, not in the rotation)"
        )
    rotation: Float64Array = u @ vt
    return rotation


def look_at_rotation(position: ArrayLike, target: ArrayLike, roll_deg: float = 0.0) -> Float64Array:
    """Rotation matrix whose local -Z looks from ``position`` at ``target`` (see module docs)."""
    pos, tgt = np.asarray(position, dtype=np.float64), np.asarray(target, dtype=np.float64)
    forward = pos - tgt
    norm = np.linalg.norm(forward)
    scale = max(float(np.linalg.norm(pos)), float(np.linalg.norm(tgt)), 1.0)
    if norm <= 1e-12 * scale:
        base = np.eye(3)
    else:
        z = forward / norm
        up = np.array([0.0, 0.0, 1.0])
        if abs(z[2]) > 1.0 - 1e-12:
            up = np.array([0.0, 1.0, 0.0])
        x = np.cross(up, z)
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        base = np.stack([x, y, z], axis=1)
    if roll_deg:
        a = np.deg2rad(roll_deg)
        c, s = np.cos(a), np.sin(a)
        base = base @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return base


#: the largest angle (radians for rotvec, degrees for Euler) a rotation may be given with: beyond it the
#: spacing of float64 values exceeds 1e-7 of a turn and the rotation is lost to rounding (1e300 rad
#: made a NaN quaternion)
MAX_ANGLE = 1e9


def _check_angles(name: str, angles: Any, unit: str) -> None:
    peak = float(np.max(np.abs(angles))) if np.size(angles) else 0.0
    if peak > MAX_ANGLE:
        raise InvalidSceneError(
            f"{name}: expected angles within +-{MAX_ANGLE:g} {unit}, got {peak:g} (the rotation of so large an "
            "angle is lost to float64 rounding; reduce it modulo a full turn)"
        )


def quaternion_from_rotation(
    rotation_mode: str, rotation: Any, position: Float64Array | None = None, *, name: str = "rotation"
) -> Float64Array:
    """Resolve any rotation mode to a unit WXYZ quaternion (float64, w >= 0)."""
    if not isinstance(rotation_mode, str):
        raise InvalidSceneError(f"rotation_mode: expected a string such as 'quaternionWXYZ', got {rotation_mode!r}")
    if rotation is None:
        return np.array([1.0, 0.0, 0.0, 0.0])
    mode = rotation_mode
    if mode in ("quaternionWXYZ", "quaternionXYZW"):
        q = as_array(name, rotation, shape=(4,))
        if mode == "quaternionXYZW":
            q = np.array([q[3], q[0], q[1], q[2]])
        n = np.linalg.norm(q)
        if not np.isfinite(n):  # |q|^2 overflows float64 (|q| > ~1e154): scale first, only the direction counts
            q = np.asarray(q, dtype=np.float64) / np.abs(q).max()
            n = np.linalg.norm(q)
        if n < 1e-12:
            raise InvalidSceneError(f"{name}: expected a non-zero quaternion, got {np.asarray(q).tolist()}")
        q = np.array(q, dtype=np.float64)
        if abs(n - 1.0) > 4 * np.finfo(np.float64).eps:  # keep unit quaternions bit-exact (file round trips)
            q /= n
        return -q if q[0] < 0 else q
    if mode == "rotvec":
        from scipy.spatial.transform import Rotation

        v = as_array(name, rotation, shape=(3,))
        _check_angles(name, v, "rad")
        return matrix_to_quaternion(Rotation.from_rotvec(np.array(v)).as_matrix())  # scipy rejects read-only
    if mode == "rotmat":
        m = as_array(name, rotation, shape=(3, 3))
        return matrix_to_quaternion(_orthonormalise(name, m))
    if mode.lower().startswith("euler"):
        from scipy.spatial.transform import Rotation

        seq = mode[5:]
        if not (1 <= len(seq) <= 3) or not (seq.isupper() or seq.islower()) or set(seq.lower()) - set("xyz"):
            raise InvalidSceneError(
                f"rotation_mode: expected 'euler' followed by 1-3 axes all upper-case (intrinsic) or all "
                f"lower-case (extrinsic), e.g. 'eulerXYZ', got {rotation_mode!r}"
            )
        angles = as_array(name, np.atleast_1d(rotation), shape=(len(seq),))
        _check_angles(name, angles, "degrees")
        m = Rotation.from_euler(seq, np.array(angles), degrees=True).as_matrix()
        return matrix_to_quaternion(m)
    if mode in ("look_at", "lookat"):
        roll = 0.0
        target = rotation
        if isinstance(rotation, tuple) and len(rotation) == 2 and not np.isscalar(rotation[0]):
            target, roll = rotation
            roll = as_float(f"{name} (roll)", roll)
        if isinstance(target, Positionable):
            target = target.translation
        target = as_array(f"{name} (look_at target)", target, shape=(3,))
        pos = np.zeros(3) if position is None else position
        return matrix_to_quaternion(look_at_rotation(pos, target, roll))
    raise InvalidSceneError(
        f"rotation_mode: unknown rotation mode {rotation_mode!r}; expected one of "
        "'quaternionWXYZ', 'quaternionXYZW', 'rotvec', 'rotmat', 'euler<order>' (e.g. 'eulerXYZ'), 'look_at'"
    )


class ValidatedParam(Generic[_T]):
    """A settable parameter of a positionable object: every assignment is checked with
    ``check(obj, name, value)`` and, once the object exists, bumps its ``kind`` revision so backends
    that cache by revision see the change."""

    def __init__(self, check: Callable[[Any, str, Any], _T], kind: str = "appearance", doc: str | None = None):
        self.check = check
        self.kind = kind
        self.__doc__ = doc

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name
        self.attr = "_" + name

    @overload
    def __get__(self, obj: None, owner: type | None = None) -> ValidatedParam[_T]: ...

    @overload
    def __get__(self, obj: object, owner: type | None = None) -> _T: ...

    def __get__(self, obj: object | None, owner: type | None = None) -> ValidatedParam[_T] | _T:
        if obj is None:
            return self
        value: _T = obj.__dict__[self.attr]
        return value

    def __set__(self, obj: Any, value: object) -> None:
        obj.__dict__[self.attr] = self.check(obj, self.name, value)
        if "_revisions" in obj.__dict__:
            obj._bump(self.kind)


def compose_matrix(quaternion: ArrayLike, translation: ArrayLike) -> Float64Array:
    m = np.eye(4)
    m[:3, :3] = quaternion_to_matrix(quaternion)
    m[:3, 3] = translation
    return m


class Positionable:
    """Something with a pose: a rotation (any rotation mode) and a translation, in world coordinates.

    Every IR object keeps revision counters (``revision("transform")``, ``"geometry"``, ``"appearance"``)
    so backends can update only what changed between renders.
    """

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        strict_api(cls)  # every renderable, light and camera: unknown keywords raise naming them

    def __init__(self, rotation_mode: str = "quaternionWXYZ", rotation: Any = None, translation: Any = (0, 0, 0)):
        self.uid = next(_uid_counter)
        self._revisions = {"transform": 0, "geometry": 0, "appearance": 0}
        self._translation = frozen(np.zeros(3))
        self._quaternion = frozen(np.array([1.0, 0.0, 0.0, 0.0]))
        self.set_position(rotation_mode=rotation_mode, rotation=rotation, translation=translation)

    # -- name --------------------------------------------------------------------------------------
    @property
    def tag(self) -> str:
        """The object's name in its scene (read-only, as in blendify: collections are keyed by it)."""
        return str(self.__dict__.get("_tag", ""))

    @tag.setter
    def tag(self, value: Any) -> None:
        raise InvalidSceneError(
            f"tag: read-only (got {value!r}); pass tag=... to add_*, or remove the object and add it again"
        )

    # -- revisions -------------------------------------------------------------------------------
    def revision(self, kind: str) -> int:
        """How many times this object's ``kind`` ("transform", "geometry", "appearance") has changed."""
        return self._revisions[kind]

    def _bump(self, kind: str) -> None:
        self._revisions[kind] += 1

    # -- pose ------------------------------------------------------------------------------------
    def set_position(
        self, rotation_mode: str = "quaternionWXYZ", rotation: Any = None, translation: Any = None
    ) -> None:
        """Set the pose. The translation is applied first (it matters for ``look_at``)."""
        if translation is not None:
            t = as_array("translation", translation, shape=(3,))
        else:
            t = self._translation
        q = quaternion_from_rotation(rotation_mode, rotation, t)
        self._translation = frozen(np.array(t, dtype=np.float64))
        self._quaternion = frozen(q)
        self._bump("transform")

    @property
    def translation(self) -> Float64Array:
        """(3,) float64 world position."""
        return self._translation

    @translation.setter
    def translation(self, value: Any) -> None:
        self._translation = as_array("translation", value, shape=(3,))
        self._bump("transform")

    @property
    def quaternion(self) -> Float64Array:
        """(4,) float64 unit quaternion, WXYZ, w >= 0."""
        return self._quaternion

    @quaternion.setter
    def quaternion(self, value: Any) -> None:
        self._quaternion = frozen(quaternion_from_rotation("quaternionWXYZ", value, name="quaternion"))
        self._bump("transform")

    @property
    def rotation_matrix(self) -> Float64Array:
        return quaternion_to_matrix(self._quaternion)

    @property
    def matrix_world(self) -> Float64Array:
        """(4, 4) float64 object-to-world transform."""
        return compose_matrix(self._quaternion, self._translation)


strict_api(Positionable)
