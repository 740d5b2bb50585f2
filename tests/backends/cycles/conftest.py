"""Shared fixtures of the Cycles backend tests (skipped, with the reason printed, without bpy)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
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


def _run_bpy_script(code: str, *args: str, timeout: float = 180.0) -> dict[str, Any]:
    """Run ``code`` with bpy in a fresh interpreter; returns the JSON object printed on its last line."""
    proc = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=dict(os.environ),
    )
    if proc.returncode != 0:
        raise AssertionError(f"bpy script failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    return json.loads(lines[-1]) if lines else {}


@pytest.fixture(scope="session")
def bpy_script():
    """``bpy_script(code, *args)``: run a bpy script in a fresh interpreter (files written by Blender
    itself, Blender's own renders); returns the JSON object it printed last."""
    return _run_bpy_script


#: Blender renders a .blend file itself (opened as the main file, its own settings), to an EXR
RENDER_BLEND = """
import bpy, sys, json
import numpy as np
import OpenEXR
path, out = sys.argv[1:3]
bpy.ops.wm.open_mainfile(filepath=path)
sc = bpy.context.scene
sc.render.image_settings.media_type = "IMAGE"
sc.render.image_settings.file_format = "OPEN_EXR"
sc.render.image_settings.color_depth = "32"
sc.render.use_compositing = False
sc.render.filepath = out
bpy.ops.render.render(write_still=True)
with OpenEXR.File(out) as f:
    ch = f.channels()
    rgba = np.asarray(ch["RGBA"].pixels, dtype=np.float32)
np.save(out + ".npy", rgba)
print(json.dumps({"engine": sc.render.engine, "samples": sc.cycles.samples}))
"""


@pytest.fixture(scope="session")
def blender_render():
    """``blender_render(blend, exr) -> (info, rgba)``: Blender's own render of a .blend (its settings), as
    a float32 (H, W, 4) array; ``info`` has the file's engine and samples."""

    def run(blend: Any, exr: Any) -> tuple[dict[str, Any], Any]:
        import numpy as np

        info = _run_bpy_script(RENDER_BLEND, str(blend), str(exr))
        return info, np.load(f"{exr}.npy")

    return run
