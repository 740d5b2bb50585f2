"""sRGB <-> linear conversions (IEC 61966-2-1 piecewise curve, the "Standard" view transform)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from blendify_core.typing import FloatArray, UInt8Array


def srgb_to_linear(values: ArrayLike) -> FloatArray:
    """Decode sRGB-encoded values in [0, 1] to linear (float64 for scalars, input float dtype otherwise)."""
    v = np.asarray(values, dtype=np.float64 if np.ndim(values) == 0 else None)
    if v.dtype.kind != "f":
        v = v.astype(np.float32)
    out: FloatArray = np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4).astype(v.dtype)
    return out


def linear_to_srgb(values: ArrayLike) -> FloatArray:
    """Encode linear values with the sRGB curve; values are clipped to [0, 1] first."""
    v = np.asarray(values, dtype=np.float64 if np.ndim(values) == 0 else None)
    if v.dtype.kind != "f":
        v = v.astype(np.float32)
    v = np.clip(v, 0.0, 1.0)
    out: FloatArray = np.where(v <= 0.0031308, v * 12.92, 1.055 * np.power(v, 1.0 / 2.4) - 0.055).astype(v.dtype)
    return out


def srgb8_to_linear(values: ArrayLike) -> NDArray[np.float32]:
    """Decode uint8 sRGB to linear float32 through a 256-entry table (exact and fast)."""
    table = srgb_to_linear(np.arange(256, dtype=np.float64) / 255.0).astype(np.float32)
    out: NDArray[np.float32] = table[np.asarray(values, dtype=np.uint8)]
    return out


def linear_to_srgb8(values: ArrayLike) -> UInt8Array:
    """Encode linear float values to uint8 sRGB with round-to-nearest."""
    out: UInt8Array = np.round(linear_to_srgb(np.asarray(values, dtype=np.float32)) * 255.0).astype(np.uint8)
    return out
