"""Helpers of the pyrender backend tests (a uniquely named module: conftest names clash)."""

from __future__ import annotations

import numpy as np


def alpha_centroids(rgba: np.ndarray, pixels: np.ndarray, window: int = 7) -> np.ndarray:
    """Alpha-weighted centroids (OpenCV pixel coordinates) in a window around each expected pixel."""
    from blendify_core.evaluate.metrics import alpha_centroids as centroids
    from blendify_core.pipeline.result import RenderResult

    return centroids(RenderResult(rgba=rgba), pixels, window)
