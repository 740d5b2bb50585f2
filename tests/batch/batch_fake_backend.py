"""A fake backend for the batch tests, importable by spawned workers as ``batch_fake_backend:FakeBackend``.

Each instance is told what to do through backend options (so one batch mixes behaviours per job):
``action`` = "ok" | "sleep" | "raise" | "abort" | "kill" | "segfault" | "raise_if_exists" | "check_sys_path",
``seconds`` (sleep), ``path`` (raise_if_exists), ``log`` (append "<pid> <scene tag>" per render, so
tests can count how often each job was rendered), ``leak_mb`` (keep that much memory per render).
"""

from __future__ import annotations

import os
import signal
import sys
import time
from typing import Any

import numpy as np

from blendify_core.errors import RenderError
from blendify_core.pipeline.backend import Backend
from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability
from blendify_core.pipeline.result import RenderResult

_LEAK: list[bytearray] = []


class FakeBackend(Backend):
    name = "batchfake"
    engine = None

    def __init__(
        self,
        action: str = "ok",
        seconds: float = 0.0,
        path: str | None = None,
        log: str | None = None,
        leak_mb: float = 0.0,
    ) -> None:
        super().__init__()
        self.action, self.seconds, self.path, self.log, self.leak_mb = action, seconds, path, log, leak_mb

    @classmethod
    def capabilities(cls) -> dict[str, Capability]:
        return {name: Capability("exact") for name in ALL_FEATURES}

    def translate(self, scene: Any, settings: Any) -> Any:
        return scene

    def render(self, native: Any, settings: Any) -> RenderResult:
        tags = [r.tag for r in native.renderables]
        tag = tags[0] if tags else "-"
        if self.log:
            with open(self.log, "a", encoding="utf-8") as f:
                f.write(f"{os.getpid()} {tag} {settings.threads}\n")
        if self.leak_mb:
            _LEAK.append(bytearray(os.urandom(1024)) * int(self.leak_mb * 1024))
        if self.action == "sleep":
            time.sleep(self.seconds)
        elif self.action == "raise":
            raise RenderError("fake engine failure: out of fake memory")
        elif self.action == "raise_if_exists" and self.path and os.path.exists(self.path):
            raise RenderError(f"fake engine failure: {self.path} exists")
        elif self.action == "check_sys_path":
            shadows = [p for p in sys.path if "/scripts/" in p.replace("\\", "/") + "/" and "/bpy/" in p]
            if shadows:
                raise RenderError(f"Blender script folders on sys.path: {shadows}")
        elif self.action == "abort":
            os.abort()
        elif self.action == "kill":
            os.kill(os.getpid(), signal.SIGKILL)
        elif self.action == "segfault":
            import ctypes

            ctypes.string_at(0)
        w, h = native.camera.resolution
        seed = sum(tag.encode()) % 200
        rgba = np.zeros((h, w, 4), dtype=np.float32)
        rgba[..., 0] = seed / 255.0
        rgba[..., 3] = 1.0
        depth = np.full((h, w), 2.0, dtype=np.float32) if settings.wants("depth") else None
        return RenderResult(rgba=rgba, depth=depth, meta={"backend": self.name})


FAKE = "batchfake"
TARGET = "batch_fake_backend:FakeBackend"


def tiny_scene(tag: str, resolution: tuple[int, int] = (16, 12)) -> Any:
    """A one-plane scene whose renderable tag names the job (the fake colours the frame from it)."""
    from blendify_core.ir.colors import UniformColors
    from blendify_core.ir.materials import DiffuseMaterial
    from blendify_core.ir.scene import Scene

    scene = Scene()
    scene.set_orthographic_camera(resolution, ortho_scale=2.0, translation=(0, 0, 5.0), near=0.1, far=20)
    scene.renderables.add_plane_mesh(4.0, DiffuseMaterial(), UniformColors((0.5, 0.5, 0.5)), tag=tag)
    scene.lights.add_sun(strength=3.0)
    return scene


def expected_red(tag: str) -> int:
    """The 8-bit sRGB red value the fake writes for ``tag``."""
    from blendify_core.ir.colorspace import linear_to_srgb

    return int(np.round(linear_to_srgb(np.float32((sum(tag.encode()) % 200) / 255.0)) * 255))
