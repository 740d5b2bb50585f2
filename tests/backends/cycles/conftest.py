"""Shared fixtures of the Cycles backend tests (skipped, with the reason printed, without bpy)."""

from __future__ import annotations

from typing import Any

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


@pytest.fixture(scope="session")
def bpy_script():
    """``bpy_script(code, *args)``: run a bpy script in a fresh interpreter (files written by Blender
    itself, Blender's own renders); returns the JSON object it printed last."""
    from blendify_blender.blendfile.reference import run_bpy_script

    def run(code: str, *args: str, timeout: float = 180.0) -> dict[str, Any]:
        try:
            return run_bpy_script(code, *args, timeout=timeout)
        except RuntimeError as exc:
            raise AssertionError(str(exc)) from None

    return run


@pytest.fixture(scope="session")
def blender_render():
    """``blender_render(blend, exr) -> (info, rgba)``: Blender's own render of a .blend (its settings), as
    a float32 (H, W, 4) array; ``info`` has the file's engine and samples
    (:func:`blendify_blender.blendfile.reference.blender_render`)."""
    from blendify_blender.blendfile.reference import blender_render as render

    return render
