"""Helpers of the cross-backend suite (imported by conftest.py, the tests and the benchmark)."""

from __future__ import annotations

import itertools
from typing import Any

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
