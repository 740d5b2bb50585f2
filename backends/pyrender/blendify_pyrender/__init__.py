"""blendify-core backend ``pyrender``: interactive-speed previews framed exactly like the final render.

Importing this package does not import pyrender or OpenGL: the OpenGL platform is chosen when the first
frame is rendered (see :mod:`blendify_pyrender._platform`), so ``probe()`` and the registry stay cheap.

Usage::

    import blendify_core as bf
    result = bf.render(scene, backend="pyrender", quality="preview", outputs=("rgb", "depth"))

    with PyrenderBackend(platform="egl") as be:       # a session: the scene is translated once
        for pose in poses:
            scene.camera.set_position(...)              # only the camera moves
            frame = bf.render(scene, backend=be, quality="preview")

Options: ``platform`` ("egl", "osmesa" or None = ``PYOPENGL_PLATFORM`` if set, else EGL when present,
else OSMesa), ``msaa`` (MSAA samples of the anti-aliased colour pass, default 4; 0 = none),
``supersample`` (render the colour pass at k times the resolution and box-filter it; default 1 with
MSAA, 2 where the platform has no MSAA), ``device`` (EGL device index).

Anti-aliasing follows ``settings.samples``: 1 = a plain frame (no MSAA, no supersampling); more = the
anti-aliased colour pass. Depth, normal, albedo and instance always come from a separate pass without
MSAA (one sample at each pixel centre).
"""

from __future__ import annotations

import importlib.util
import threading
from typing import Any

from blendify_core.backend import Backend, BackendStatus
from blendify_core.errors import BackendUnavailableError, InvalidSceneError
from blendify_core.features import Capability
from blendify_core.result import RenderResult
from blendify_core.settings import RenderSettings

from ._capabilities import capability_table

__all__ = ["PyrenderBackend"]


def _as_int_option(name: str, value: Any, min_value: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < min_value:
        raise InvalidSceneError(f"{name}: expected an integer >= {min_value}, got {value!r}")
    return int(value)


class PyrenderBackend(Backend):
    """Rasterised previews with pyrender (OpenGL through EGL or OSMesa, CPU Mesa works)."""

    name = "pyrender"
    engine = "pyrender"
    qualities = ("preview",)

    def __init__(
        self,
        platform: str | None = None,
        msaa: int = 4,
        supersample: int | None = None,
        device: int = 0,
        **options: Any,
    ) -> None:
        super().__init__(**options)
        from ._platform import resolve_platform

        self.platform = resolve_platform(platform)
        self.msaa = _as_int_option("msaa", msaa, 0)
        self.supersample = None if supersample is None else _as_int_option("supersample", supersample, 1)
        if self.supersample is not None and self.supersample > 8:
            raise InvalidSceneError(f"supersample: expected 1..8, got {supersample}")
        self.device = _as_int_option("device", device, 0)
        self._engine: Any = None
        self._lock = threading.RLock()

    # -- discovery ---------------------------------------------------------------------------------
    @classmethod
    def probe(cls) -> BackendStatus:
        """Available when pyrender and PyOpenGL are installed (no OpenGL context is created here)."""
        for module in ("pyrender", "OpenGL"):
            if importlib.util.find_spec(module) is None:
                return BackendStatus(False, f"the {module!r} package is not installed", cls.engine_version())
        return BackendStatus(True, None, cls.engine_version())

    @classmethod
    def capabilities(cls) -> dict[str, Capability]:
        return capability_table()

    # -- engine ------------------------------------------------------------------------------------
    @property
    def engine_instance(self) -> Any:
        """The live :class:`~blendify_pyrender._engine.Engine` (created on first use)."""
        if self._closed:
            raise BackendUnavailableError(f"{self.name}: this backend instance was closed")
        if self._engine is None:
            from ._engine import Engine

            self._engine = Engine(self.platform, self.device)
        return self._engine

    def _aa(self, settings: RenderSettings) -> tuple[int, int]:
        """(MSAA samples, supersampling factor) for ``settings``."""
        if settings.samples <= 1:
            return 0, 1
        eng = self.engine_instance
        msaa = self.msaa if eng.msaa_supported else 0
        if self.supersample is not None:
            return msaa, self.supersample
        return msaa, (1 if msaa > 0 else 2)

    # -- Backend API -------------------------------------------------------------------------------
    def translate(self, scene: Any, settings: RenderSettings) -> Any:
        """Update the cached pyrender scene from ``scene`` (only what changed) and return the frame."""
        if scene.camera is None:
            raise InvalidSceneError("scene.camera: the scene has no camera")
        with self._lock:
            return self.engine_instance.sync(scene)

    def render(self, native: Any, settings: RenderSettings) -> RenderResult:
        with self._lock:
            msaa, ss = self._aa(settings)
            return self.engine_instance.render(native, settings, msaa, ss)

    def close(self) -> None:
        with self._lock:
            eng, self._engine = self._engine, None
            if eng is not None:
                eng.close()
        super().close()

    def __del__(self) -> None:
        try:
            if getattr(self, "_engine", None) is not None:
                self.close()
        except Exception:
            pass
