"""Helpers of the pyrender backend tests (a uniquely named module: conftest names clash)."""

from __future__ import annotations

import numpy as np


def alpha_centroids(rgba: np.ndarray, pixels: np.ndarray, window: int = 7) -> np.ndarray:
    """Alpha-weighted centroids (OpenCV pixel coordinates) in a window around each expected pixel."""
    a = rgba[..., 3]
    h, w = a.shape
    out = []
    for u, v in pixels:
        u0, v0 = int(round(u)), int(round(v))
        ys, xs = np.mgrid[max(v0 - window, 0) : min(v0 + window + 1, h), max(u0 - window, 0) : min(u0 + window + 1, w)]
        wgt = a[ys, xs]
        out.append([(wgt * xs).sum() / wgt.sum(), (wgt * ys).sum() / wgt.sum()])
    return np.array(out)
