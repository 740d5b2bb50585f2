"""Helpers of the cross-backend suite (imported by conftest.py, the tests and the benchmark)."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest

import blendify_core as bf

BACKENDS = ("cycles", "mitsuba", "pyrender")
PAIRS = tuple(itertools.combinations(BACKENDS, 2))
PATH_TRACERS = ("cycles", "mitsuba")

_status: dict[str, Any] | None = None


def backend_status() -> dict[str, Any]:
    global _status
    if _status is None:
        _status = bf.available_backends()
    return _status


def require(name: str) -> None:
    """Skip (printing the reason) when backend ``name`` cannot run here."""
    st = backend_status().get(name)
    if st is None:
        reason = f"backend {name!r} is not registered"
    elif not st.available:
        reason = f"backend {name!r} unavailable: {st.reason}"
    else:
        return
    print(f"SKIP: {reason}")
    pytest.skip(reason)


def inside(result: bf.RenderResult, margin: int = 2) -> np.ndarray:
    """(H, W) bool: hit pixels at least ``margin`` pixels inside their instance's silhouette (every pixel
    within ``margin`` (Chebyshev) has the same instance id)."""
    inst = result.instance
    h, w = inst.shape
    pad = np.pad(inst, margin, mode="constant", constant_values=-1)
    ok = inst >= 0
    for dy in range(-margin, margin + 1):
        for dx in range(-margin, margin + 1):
            ok &= pad[margin + dy : margin + dy + h, margin + dx : margin + dx + w] == inst
    return ok


def geometry_agreement(a: bf.RenderResult, b: bf.RenderResult, margin: int = 2) -> dict[str, float]:
    """Depth (relative) and normal (degrees) differences at pixel centres >= ``margin`` px inside every
    silhouette of both results (same instance in both): q50 / q99 / max, and the pixel count."""
    mask = inside(a, margin) & inside(b, margin) & (a.instance == b.instance)
    da, db = a.depth[mask].astype(np.float64), b.depth[mask].astype(np.float64)
    rel = np.abs(da - db) / np.abs(da)
    na, nb = a.normal[mask].astype(np.float64), b.normal[mask].astype(np.float64)
    cos = np.sum(na * nb, axis=1) / (np.linalg.norm(na, axis=1) * np.linalg.norm(nb, axis=1))
    ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    out = {"pixels": float(mask.sum())}
    for name, x in (("depth_rel", rel), ("normal_deg", ang)):
        q = np.quantile(x, [0.5, 0.99]) if x.size else [np.nan, np.nan]
        out |= {f"{name}_q50": float(q[0]), f"{name}_q99": float(q[1]), f"{name}_max": float(x.max(initial=0))}
    return out
