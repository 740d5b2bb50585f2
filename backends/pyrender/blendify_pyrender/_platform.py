"""Headless OpenGL contexts for pyrender: platform choice (EGL or OSMesa) and one shared EGL display.

PyOpenGL binds its platform (``PYOPENGL_PLATFORM``) once, when ``OpenGL`` is first imported. This module
chooses the platform explicitly (an option of the backend), sets the environment variable only when the
user has not set it, before OpenGL is imported, and refuses clearly when OpenGL was already imported with
another platform.

Under EGL, ``eglTerminate`` ends the display for every context of the process (pyrender's
``OffscreenRenderer.delete`` calls it, which breaks every other live renderer). Contexts created here
share one reference-counted display per EGL device and terminate it only when the last one is released.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
import threading
from typing import Any

from blendify_core.errors import BackendUnavailableError, InvalidSceneError, RenderError

__all__ = ["PLATFORMS", "resolve_platform", "prepare_platform", "GLContext", "osmesa_available", "egl_available"]

PLATFORMS = ("egl", "osmesa")

_lock = threading.Lock()
# EGL display handle (int) -> number of live contexts using it
_display_refs: dict[int, int] = {}


def _library_loadable(name: str, versions: tuple[str, ...]) -> bool:
    """True when ``lib<name>.so`` (or a versioned file) can be opened, honouring LD_LIBRARY_PATH as
    PyOpenGL does (``ctypes.util.find_library`` alone ignores it)."""
    if ctypes.util.find_library(name) is not None:
        return True
    for suffix in ("",) + tuple("." + v for v in versions):
        try:
            ctypes.CDLL(f"lib{name}.so{suffix}")
            return True
        except OSError:
            continue
    return False


def egl_available() -> bool:
    """True when a libEGL can be loaded (no context is created)."""
    return _library_loadable("EGL", ("1",))


def osmesa_available() -> bool:
    """True when libOSMesa can be loaded (Debian: ``apt-get install libosmesa6``)."""
    return _library_loadable("OSMesa", ("8", "6"))


def _opengl_platform_in_use() -> str | None:
    """The platform PyOpenGL was loaded with ("egl", "osmesa", "glx", ...), or None if not loaded yet."""
    mod = sys.modules.get("OpenGL.platform")
    if mod is None:
        return None
    plat = getattr(mod, "PLATFORM", None)
    if plat is None:
        return None
    name = type(plat).__module__.rsplit(".", 1)[-1].lower()
    return name or None


def resolve_platform(platform: str | None) -> str:
    """Validate the ``platform`` option; None picks ``PYOPENGL_PLATFORM`` when set (egl/osmesa), else EGL
    when a libEGL exists, else OSMesa."""
    if platform is not None:
        if not isinstance(platform, str) or platform.lower() not in PLATFORMS:
            raise InvalidSceneError(f"platform: expected 'egl', 'osmesa' or None, got {platform!r}")
        return platform.lower()
    env = os.environ.get("PYOPENGL_PLATFORM", "").lower()
    if env in PLATFORMS:
        return env
    in_use = _opengl_platform_in_use()
    if in_use in PLATFORMS:
        return in_use  # type: ignore[return-value]
    if egl_available():
        return "egl"
    return "osmesa"


def prepare_platform(platform: str) -> None:
    """Make PyOpenGL use ``platform``: set ``PYOPENGL_PLATFORM`` if unset (before OpenGL is imported);
    raise BackendUnavailableError when that is impossible (another platform already loaded, library
    missing)."""
    env = os.environ.get("PYOPENGL_PLATFORM")
    in_use = _opengl_platform_in_use()
    if in_use is not None and in_use != platform:
        hint = f"create the backend with platform={in_use!r}, or " if in_use in PLATFORMS else ""
        raise BackendUnavailableError(
            f"pyrender: OpenGL was already imported in this process with the {in_use!r} platform, so the "
            f"{platform!r} platform cannot be used any more (PyOpenGL binds its platform at first import); "
            f"{hint}set PYOPENGL_PLATFORM={platform} before anything imports OpenGL (pyrender included)"
        )
    if env is not None and env.lower() != platform and in_use is None:
        raise BackendUnavailableError(
            f"pyrender: PYOPENGL_PLATFORM={env!r} is set in the environment but platform={platform!r} was "
            "requested; unset the variable or pass a matching platform option"
        )
    if platform == "osmesa" and not osmesa_available():
        raise BackendUnavailableError(
            "pyrender: platform 'osmesa' needs the OSMesa library (libOSMesa.so), which was not found; "
            "install it (Debian/Ubuntu: apt-get install libosmesa6) or use platform='egl'"
        )
    if platform == "egl" and not egl_available():
        raise BackendUnavailableError(
            "pyrender: platform 'egl' needs libEGL (Mesa: apt-get install libegl1 libgl1-mesa-dri), which "
            "was not found; install it or use platform='osmesa'"
        )
    if env is None and in_use is None:
        os.environ["PYOPENGL_PLATFORM"] = platform


def _display_key(display: Any) -> int:
    value = ctypes.cast(display, ctypes.c_void_p).value
    return int(value or 0)


class GLContext:
    """One OpenGL 4.1 core context on ``platform`` (rendering goes to framebuffer objects, so the
    context's own surface is never used). ``release()`` frees it; under EGL the display is terminated
    only when no other context of this module uses it."""

    def __init__(self, platform: str, device: int = 0) -> None:
        prepare_platform(platform)
        self.platform = platform
        self._impl: Any = None
        self._display_key: int | None = None
        try:
            if platform == "egl":
                self._init_egl(device)
            else:
                self._init_osmesa()
        except BackendUnavailableError:
            raise
        except Exception as exc:  # engine errors keep their message
            raise BackendUnavailableError(
                f"pyrender: cannot create an OpenGL context on {platform!r} ({type(exc).__name__}: {exc})"
            ) from exc

    # -- creation ----------------------------------------------------------------------------------
    def _init_egl(self, device: int) -> None:
        from pyrender.platforms import egl as pegl

        if not isinstance(device, int) or isinstance(device, bool) or device < 0:
            raise InvalidSceneError(f"device: expected a non-negative EGL device index, got {device!r}")
        impl = pegl.EGLPlatform(1, 1, device=pegl.get_device_by_index(device))
        with _lock:
            impl.init_context()  # eglInitialize on an initialised display is harmless
            key = _display_key(impl._egl_display)
            _display_refs[key] = _display_refs.get(key, 0) + 1
        self._impl, self._display_key = impl, key

    def _init_osmesa(self) -> None:
        from pyrender.platforms.osmesa import OSMesaPlatform

        impl = OSMesaPlatform(8, 8)
        impl.init_context()
        self._impl = impl

    # -- use ---------------------------------------------------------------------------------------
    @property
    def alive(self) -> bool:
        return self._impl is not None

    def make_current(self) -> None:
        if self._impl is None:
            raise RenderError("pyrender: the OpenGL context was released (the backend was closed)")
        try:
            self._impl.make_current()
        except Exception as exc:
            raise RenderError(
                f"pyrender: cannot make the {self.platform} context current ({type(exc).__name__}: {exc}); "
                "another library may have terminated the shared EGL display (pyrender.OffscreenRenderer.delete "
                "does)"
            ) from exc

    def release(self) -> None:
        """Destroy the context (idempotent)."""
        impl, self._impl = self._impl, None
        if impl is None:
            return
        if self.platform == "egl":
            from OpenGL import EGL

            with _lock:
                display = impl._egl_display
                if display is not None and impl._egl_context is not None:
                    EGL.eglMakeCurrent(display, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE, EGL.EGL_NO_CONTEXT)
                    EGL.eglDestroyContext(display, impl._egl_context)
                    impl._egl_context = None
                key = self._display_key
                if key is not None:
                    _display_refs[key] = _display_refs.get(key, 1) - 1
                    if _display_refs[key] <= 0:
                        _display_refs.pop(key, None)
                        if display is not None:
                            EGL.eglTerminate(display)
                impl._egl_display = None
        else:
            impl.delete_context()
