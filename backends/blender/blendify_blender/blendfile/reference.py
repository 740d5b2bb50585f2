"""Blender's own render of a .blend file, for the tests and benchmarks that hold blendify to it.

Each step runs in a fresh interpreter with bpy (``sys.executable -c``): nothing of the calling session is
shared, and the file is opened as Blender's main file, as a user would. :func:`prepare_blend` writes a copy
set up for a comparison (Cycles, the resolution, the samples, seed 0, no denoiser, no adaptive sampling, the
Standard view; a camera looking at the objects when the file has none; everything else as the file has it);
:func:`blender_render` renders a file with its own settings into a float32 (H, W, 4) array.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["blender_render", "prepare_blend", "run_bpy_script"]

_PREPARE = """
import bpy, sys, json, math
from mathutils import Vector
src, out, w, h, spp = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
bpy.ops.wm.open_mainfile(filepath=src)
sc = bpy.context.scene
r, cy = sc.render, sc.cycles
engine = r.engine
r.engine = "CYCLES"
r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100
r.pixel_aspect_x = r.pixel_aspect_y = 1.0
cy.device = "CPU"; cy.samples = spp; cy.seed = 0; cy.use_animated_seed = False
cy.use_denoising = False; cy.use_adaptive_sampling = False; cy.time_limit = 0.0
sc.view_settings.view_transform = "Standard"; sc.view_settings.look = "None"
sc.view_settings.exposure = 0.0; sc.view_settings.gamma = 1.0
added_camera = False
if sc.camera is None:
    pts = [ob.matrix_world @ Vector(c) for ob in sc.objects if ob.type == "MESH" and not ob.hide_render
           for c in ob.bound_box]
    lo = Vector((min(p.x for p in pts), min(p.y for p in pts), min(p.z for p in pts)))
    hi = Vector((max(p.x for p in pts), max(p.y for p in pts), max(p.z for p in pts)))
    centre, radius = (lo + hi) / 2, max((hi - lo).length / 2, 1e-3)
    cam = bpy.data.objects.new("blendify_camera", bpy.data.cameras.new("blendify_camera"))
    cam.data.lens, cam.data.sensor_fit = 35.0, "HORIZONTAL"
    direction = Vector((0.6, -1.0, 0.5)).normalized()
    cam.location = centre + direction * radius * 2.0
    cam.rotation_euler = (-direction).to_track_quat("-Z", "Y").to_euler()
    sc.collection.objects.link(cam)
    sc.camera = cam
    added_camera = True
bpy.ops.wm.save_as_mainfile(filepath=out, relative_remap=True, copy=True)
print(json.dumps({"engine": engine, "added_camera": added_camera}))
"""

_RENDER = """
import bpy, sys, json
import numpy as np
import OpenEXR
path, out, seed = sys.argv[1], sys.argv[2], sys.argv[3]
bpy.ops.wm.open_mainfile(filepath=path)
sc = bpy.context.scene
if seed:
    sc.cycles.seed = int(seed)
# the samples blendify's colour renders take: past Cycles' first sample, which sits at the pixel centre whatever
# the seed
from blendify_blender.render import set_sample_window
cy = sc.cycles
n = int(cy.sample_subset_length) if cy.use_sample_subset else int(cy.samples)
set_sample_window(cy, n)
sc.render.image_settings.media_type = "IMAGE"
sc.render.image_settings.file_format = "OPEN_EXR"
sc.render.image_settings.color_depth = "32"
sc.render.use_compositing = False
sc.render.filepath = out
bpy.ops.render.render(write_still=True)
with OpenEXR.File(out) as f:
    rgba = np.asarray(f.channels()["RGBA"].pixels, dtype=np.float32)
np.save(out + ".npy", rgba)
pct = sc.render.resolution_percentage / 100.0
print(json.dumps({"engine": sc.render.engine, "samples": n,
                  "width": int(sc.render.resolution_x * pct), "height": int(sc.render.resolution_y * pct)}))
"""


def run_bpy_script(code: str, *args: str, timeout: float = 900.0) -> dict[str, Any]:
    """Run ``code`` with bpy in a fresh interpreter; returns the JSON object it printed last (RuntimeError
    with the script's output when it fails)."""
    proc = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code), *args], capture_output=True, text=True, timeout=timeout
    )
    if proc.returncode != 0:
        raise RuntimeError(f"bpy script failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    return json.loads(lines[-1]) if lines else {}


def prepare_blend(src: str | Path, out: str | Path, size: tuple[int, int], samples: int) -> dict[str, Any]:
    """Write ``out``: ``src`` set up for a comparison (see the module); returns {"engine": the file's render
    engine, "added_camera": bool}."""
    w, h = size
    return run_bpy_script(_PREPARE, str(src), str(out), str(w), str(h), str(samples))


def blender_render(path: str | Path, exr: str | Path, seed: int | None = None) -> tuple[dict[str, Any], np.ndarray]:
    """Blender's render of ``path`` with the file's own settings (``seed`` overrides its seed) over the samples
    blendify's colour renders take (past Cycles' fixed first sample), written to ``exr``; returns ({"engine",
    "samples"} of the file, float32 (H, W, 4) linear RGBA)."""
    info = run_bpy_script(_RENDER, str(path), str(exr), "" if seed is None else str(seed))
    rgba = np.load(f"{exr}.npy")
    return info, rgba.reshape(int(info["height"]), int(info["width"]), 4)
