"""Shared fixtures of the Cycles backend tests (skipped, with the reason printed, without bpy)."""

from __future__ import annotations

import numpy as np
import pytest
from blendify_blender import CyclesBackend

_status = CyclesBackend.probe()
if not _status.available:  # pragma: no cover - depends on the machine
    print(f"skipping the Cycles tests: {_status.reason}")
    pytest.skip(f"cycles backend unavailable: {_status.reason}", allow_module_level=True)


@pytest.fixture(scope="session")
def cycles():
    """One in-process Cycles backend for the whole session."""
    with CyclesBackend() as b:
        yield b


@pytest.fixture
def bpy(cycles):
    from blendify_blender import _runtime

    return _runtime.bpy_module()


def alpha_centroids(rgba: np.ndarray, pixels: np.ndarray, window: int = 6) -> np.ndarray:
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
