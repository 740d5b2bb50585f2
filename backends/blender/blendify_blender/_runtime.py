"""Former name of :mod:`blendify_blender.session` (the bpy plumbing: lazy import, the lock, factory resets,
output capture, error wrapping). Kept so that code importing ``blendify_blender._runtime`` (the .blend
helpers, older tests and benchmarks) keeps working; new code imports :mod:`blendify_blender.session`."""

from __future__ import annotations

from blendify_blender.session import (
    BPY_LOCK,
    bpy_module,
    capture_output,
    datablock_counts,
    defer_keyboard_interrupt,
    engine_errors,
    factory_reset,
    generation,
    soft_reset,
)

__all__ = [
    "BPY_LOCK",
    "bpy_module",
    "factory_reset",
    "soft_reset",
    "generation",
    "capture_output",
    "engine_errors",
    "datablock_counts",
    "defer_keyboard_interrupt",
]
