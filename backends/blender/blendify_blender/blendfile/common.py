"""Small pieces shared by the .blend parser modules: the notes of what could not be parsed, the custom
property holding IR tags, and matrix / colour conversions from Blender values to IR values."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = [
    "TAG_PROPERTY",
    "Notes",
    "decompose",
    "is_identity",
    "matrix_array",
    "rgb01",
    "rotation_only",
    "saved_tag",
]

#: custom property holding the IR tag on objects written by :func:`blendify_blender.export.export_blend`
TAG_PROPERTY = "blendify_tag"


class Notes(list):  # type: ignore[type-arg]
    """What could not be (fully) parsed, in order of discovery: the lines of the one BlendAttachWarning."""

    def add(self, msg: str) -> None:
        """Add ``msg`` unless it is already there."""
        if msg not in self:
            self.append(msg)


def saved_tag(obj: Any) -> str | None:
    """The IR tag stored by ``export_blend`` on an object (custom property), or None."""
    orig = getattr(obj, "original", None) or obj
    tag = orig.get(TAG_PROPERTY)
    return tag.strip() if isinstance(tag, str) and tag.strip() else None


def matrix_array(m: Any) -> np.ndarray:
    """A Blender matrix as a float64 array."""
    return np.array([list(row) for row in m], dtype=np.float64)


def decompose(m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """4x4 -> (R proper rotation, S = R^T A (scale/shear, may contain a reflection), t)."""
    a = m[:3, :3]
    u, _s, vt = np.linalg.svd(a)
    r = u @ vt
    if np.linalg.det(r) < 0:
        r = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    s = r.T @ a
    return r, s, m[:3, 3].copy()


def rotation_only(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """4x4 -> (R proper rotation, t): the scale and shear are dropped."""
    r, _s, t = decompose(m)
    return r, t


def is_identity(s: np.ndarray, tol: float = 1e-7) -> bool:
    return bool(np.max(np.abs(s - np.eye(3))) <= tol)


def rgb01(rgb: Any) -> tuple[np.ndarray, float]:
    """Split a linear RGB (may exceed 1; negative values are clipped) into a [0, 1] colour and a
    multiplier (the IR keeps colours in [0, 1] and intensities in strengths)."""
    c = np.clip(np.asarray(rgb, dtype=np.float64)[:3], 0.0, None)
    peak = float(c.max()) if c.size else 0.0
    if peak > 1.0:
        return c / peak, peak
    return c, 1.0
