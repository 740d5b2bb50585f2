"""blendify-core backend ``pyrender``: interactive-speed previews framed exactly like the final render.

Importing this package does not import pyrender or OpenGL: the OpenGL platform is chosen when the first
frame is rendered (see :mod:`blendify_pyrender._platform`), so ``probe()`` and the registry stay cheap.

Where things live: ``translate.py`` (PyrenderTranslator: one handler per IR type, the capabilities declared
beside each), ``capabilities.py`` (the table, from the translator), ``session.py`` (the GL context, the
cached pyrender scene and the core's change tracker), ``render.py`` (the frame passes, anti-aliasing and
the shadow-catcher composite), ``_platform.py`` (EGL/OSMesa choice, one shared EGL display).

Usage::

    import blendify_core as bf
    result = bf.render(scene, backend="pyrender", quality="preview", outputs=("rgb", "depth"))

    with PyrenderBackend(platform="egl") as be:       # a session: the scene is translated once
        for pose in poses:
            scene.camera.set_position(...)              # only the camera moves
            frame = bf.render(scene, backend=be, quality="preview")

Options: ``platform`` ("egl", "osmesa" or None = ``PYOPENGL_PLATFORM`` if set, else EGL when present,
else OSMesa), ``antialias`` ("auto", "coverage", "msaa", "ssaa"), ``msaa`` (samples of multisampled
passes, default 4; 0 = none), ``supersample`` (factor for "ssaa", and for the coverage pass where the
platform has no MSAA; default 2), ``device`` (EGL device index; "gpu" = 0, as ``bf.render(device="gpu")``
and blendify 2.1's ``use_gpu=True`` give).

Anti-aliasing follows ``settings.samples``: 1 = a plain frame (one sample per pixel, binary alpha); more
= the ``antialias`` scheme:

- "msaa": the lit pass multisampled (best; cheap on GPUs, but Mesa's llvmpipe shades every sample, so
  it costs 2.5-4x a plain frame on a CPU);
- "coverage": the lit pass once per pixel plus a coverage pass with a trivial shader at 3x the
  resolution (9 samples per pixel);
  silhouettes against the (transparent) background get exact coverage alpha and the colour of the
  covered neighbours; edges between two objects stay aliased (about 1.2x a plain frame);
- "ssaa": the lit pass at ``supersample`` times the resolution, box-filtered (k^2 x the cost);
- "auto": "coverage" on software rasterisers (llvmpipe, softpipe, swrast), else "msaa".

Depth, normal, albedo and instance always come from a separate pass without MSAA (one sample at each
pixel centre).
"""

from __future__ import annotations

import importlib.util
import logging
import threading
from typing import Any

from blendify_core.errors import BackendUnavailableError, InvalidSceneError
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.backend import Backend
from blendify_core.pipeline.capabilities import Capability
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import RenderSettings
from blendify_core.registry import BackendStatus

from .capabilities import capability_table
from .translate import PyrenderTranslator

# a library logs, the application decides where to: no "No handlers could be found" output by default
logging.getLogger("blendify_pyrender").addHandler(logging.NullHandler())

__all__ = ["PyrenderBackend", "ANTIALIAS_MODES"]

ANTIALIAS_MODES = ("auto", "coverage", "msaa", "ssaa")


def _as_int_option(name: str, value: Any, min_value: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < min_value:
        raise InvalidSceneError(f"{name}: expected an integer >= {min_value}, got {value!r}")
    return int(value)


class PyrenderBackend(Backend):
    """Rasterised previews with pyrender (OpenGL through EGL or OSMesa, CPU Mesa works)."""

    name = "pyrender"
    engine = "pyrender"
    qualities = ("preview",)
    translator_class = PyrenderTranslator
    # measured (tests/robustness/test_hard_cases_round2.py): far / near = 1e8 renders, 1e9 loses the sphere
    numeric_limits = {"max_clip_ratio": 1e8}
    #: a rasteriser traces no paths: nothing to clamp, blur or cut at a bounce limit
    unapplied_settings = ("clamp_direct", "clamp_indirect", "filter_glossy", "bounce_limits")

    def __init__(
        self,
        platform: str | None = None,
        antialias: str = "auto",
        msaa: int = 4,
        supersample: int = 2,
        device: int | str = 0,
        **options: Any,
    ) -> None:
        super().__init__(**options)
        from ._platform import resolve_platform

        self.platform = resolve_platform(platform)
        self.msaa = _as_int_option("msaa", msaa, 0)
        if antialias not in ANTIALIAS_MODES:
            raise InvalidSceneError(f"antialias: expected one of {list(ANTIALIAS_MODES)}, got {antialias!r}")
        self.antialias = antialias
        self.supersample = _as_int_option("supersample", supersample, 1)
        if self.supersample > 8:
            raise InvalidSceneError(f"supersample: expected 1..8, got {supersample}")
        if isinstance(device, str) and device.lower() == "gpu":
            device = 0  # bf.render's device="gpu" (and blendify 2.1's use_gpu=True): the first EGL device
        elif isinstance(device, str) and device.lower() == "cpu":
            raise InvalidSceneError(
                "device: pyrender renders with OpenGL; for software rendering on the CPU pass platform='osmesa'"
            )
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
        """The live :class:`~blendify_pyrender.session.Engine` (created on first use)."""
        if self._closed:
            raise BackendUnavailableError(f"{self.name}: this backend instance was closed")
        if self._engine is None:
            from .session import Engine

            self._engine = Engine(self.platform, self.device)
        return self._engine

    def antialiasing(self, settings: RenderSettings) -> Any:
        """The :class:`~blendify_pyrender.render.AntiAliasing` used for ``settings``."""
        eng = self.engine_instance  # render.py imports OpenGL: only once the platform is chosen
        from .render import COVERAGE_SUPERSAMPLE, AntiAliasing

        if settings.samples <= 1:
            return AntiAliasing("none")
        msaa = min(self.msaa, eng.renderer.max_samples) if eng.msaa_supported else 0
        mode = self.antialias
        if mode == "auto":
            mode = "coverage" if eng.software else "msaa"
        if mode == "msaa" and msaa == 0:
            mode = "ssaa"
        if mode == "coverage":
            return AntiAliasing("coverage", 0, COVERAGE_SUPERSAMPLE)
        if mode == "ssaa":
            return AntiAliasing("ssaa", 0, self.supersample)
        return AntiAliasing("msaa", msaa, 1)

    @classmethod
    def show_scene(cls, scene: Scene, **viewer_kwargs: Any) -> Any:
        """Open pyrender's interactive Viewer on ``scene`` (see :mod:`blendify_pyrender.viewer`)."""
        from .viewer import show_scene

        return show_scene(scene, **viewer_kwargs)

    # -- Backend API -------------------------------------------------------------------------------
    def translate(self, scene: Scene, settings: RenderSettings) -> Any:
        """Update the cached pyrender scene from ``scene`` (only what changed) and return the frame
        (:class:`~blendify_pyrender.session.Frame`)."""
        if scene.camera is None:
            raise InvalidSceneError("scene.camera: the scene has no camera")
        with self._lock:
            return self.engine_instance.sync(scene)

    def render(self, native: Any, settings: RenderSettings) -> RenderResult:
        """Render a frame returned by :meth:`translate` (:func:`blendify_pyrender.render.render_frame`)."""
        with self._lock:
            eng = self.engine_instance
            from .render import render_frame

            return render_frame(eng, native, settings, self.antialiasing(settings))

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
