"""Shared fixtures of the Cycles backend tests (skipped, with the reason printed, without bpy)."""

from __future__ import annotations

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
    from blendify_blender import session

    return session.bpy_module()
