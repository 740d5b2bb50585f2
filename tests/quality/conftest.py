"""Fixtures of the quality tests: skip (with the printed reason) when a backend is unavailable."""

from __future__ import annotations

import pytest

from blendify_core.registry import available_backends


def _need(name: str) -> str:
    st = available_backends().get(name)
    if st is None or not st.available:
        reason = f"backend {name!r} unavailable: {st.reason if st else 'not registered'}"
        print(reason)
        pytest.skip(reason)
    return name


@pytest.fixture
def cycles() -> str:
    return _need("cycles")


@pytest.fixture
def mitsuba() -> str:
    return _need("mitsuba")


@pytest.fixture
def pyrender() -> str:
    return _need("pyrender")
