"""The scene camera of a .blend -> IR camera (``with_camera=True``).

Resolution and percentage, lens / sensor / sensor fit / pixel aspect -> K, the principal point from
``shift_x`` / ``shift_y`` with the correct sign (blendify 2.1 mirrored it), clipping, orthographic
cameras. Panoramic cameras, depth of field and render borders are not parsed (noted).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from blendify_blender.blendfile.common import Notes, matrix_array, rotation_only, saved_tag

__all__ = ["blender_camera_intrinsics", "camera_spec"]


def blender_camera_intrinsics(
    cam: Any, width: int, height: int, pixel_aspect_x: float = 1.0, pixel_aspect_y: float = 1.0
) -> dict[str, Any]:
    """OpenCV intrinsics of a Blender camera datablock at ``width`` x ``height`` pixels.

    Follows Blender's view-plane computation: the fitted sensor dimension spans ``viewfac`` pixels
    (``W`` for horizontal fit, ``H * ycor`` for vertical, ``ycor = pixel_aspect_y / pixel_aspect_x``),
    ``shift`` is in units of ``viewfac`` and +shift_y moves the view UP. Pixel centres are at integers:
    ``cx = W/2 - shift_x * viewfac - 0.5``, ``cy = H/2 + shift_y * viewfac / ycor - 0.5``,
    ``fx = lens * viewfac / sensor``, ``fy = fx / ycor``. Orthographic: ``ortho_scale`` (IR: visible
    width) = Blender ortho_scale * W / viewfac. Returns a dict with fx, fy, cx, cy, ortho_scale, type.
    """
    w, h = float(width), float(height)
    ycor = float(pixel_aspect_y) / float(pixel_aspect_x)
    fit = cam.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if pixel_aspect_x * w >= pixel_aspect_y * h else "VERTICAL"
        sensor = cam.sensor_width
    elif fit == "HORIZONTAL":
        sensor = cam.sensor_width
    else:
        sensor = cam.sensor_height
    viewfac = w if fit == "HORIZONTAL" else ycor * h
    cx = w / 2.0 - cam.shift_x * viewfac - 0.5
    cy = h / 2.0 + cam.shift_y * viewfac / ycor - 0.5
    out: dict[str, Any] = {"type": cam.type, "cx": cx, "cy": cy, "ycor": ycor}
    if cam.type == "ORTHO":
        out["ortho_scale"] = cam.ortho_scale * w / viewfac
    else:
        fx = cam.lens * viewfac / sensor
        out["fx"] = fx
        out["fy"] = fx / ycor
    return out


def camera_spec(sc: Any, obj_eval: Any, notes: Notes) -> tuple[str, dict[str, Any]] | None:
    """("persp" | "ortho", keywords of ``set_perspective_camera`` / ``set_orthographic_camera``) of the
    evaluated camera object ``obj_eval`` rendering scene ``sc``, or None (noted)."""
    cam = obj_eval.data
    where = f"camera {obj_eval.name!r}"
    rd = sc.render
    w, h, pct = int(rd.resolution_x), int(rd.resolution_y), int(rd.resolution_percentage)
    if cam.type not in ("PERSP", "ORTHO"):
        notes.add(f"{where}: {cam.type.lower()} camera not supported, no camera imported")
        return None
    if cam.dof.use_dof:
        notes.add(f"{where}: depth of field not parsed")
    if rd.use_border:
        notes.add(f"{where}: render border not parsed")
    intr = blender_camera_intrinsics(cam, w, h, rd.pixel_aspect_x, rd.pixel_aspect_y)
    r, t = rotation_only(matrix_array(obj_eval.matrix_world))
    pose = {"rotation_mode": "rotmat", "rotation": r, "translation": t}
    common = {
        "near": float(cam.clip_start),
        "far": float(max(cam.clip_end, cam.clip_start * (1 + 1e-6))),
        "resolution_percentage": pct,
        "tag": saved_tag(obj_eval) or obj_eval.name.strip() or "camera",
    }
    if cam.type == "ORTHO":
        if abs(intr["ycor"] - 1.0) > 1e-9:
            notes.add(f"{where}: orthographic camera with non-square pixels read with square pixels")
        spec = {"resolution": (w, h), "ortho_scale": intr["ortho_scale"], "center": (intr["cx"], intr["cy"])}
        return "ortho", {**spec, **common, **pose}
    k = np.array([[intr["fx"], 0.0, intr["cx"]], [0.0, intr["fy"], intr["cy"]], [0.0, 0.0, 1.0]])
    return "persp", {"resolution": (w, h), "K": k, **common, **pose}
