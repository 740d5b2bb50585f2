"""The name-keyed, lazily importing backend registry (the bottom layer: it imports no IR and no engine).

Backends register through the entry-point group ``blendify.backends``
(``cycles = "blendify_blender:CyclesBackend"``), so a third party can add one without touching this
repository; :func:`register_backend` adds one at run time (tests use it for fakes). Nothing is imported
when the registry is read: a backend module is imported on first use, and its engine only when a
backend instance needs it.

Backends may also declare the file formats they can export a scene to and attach to a scene
(``file_formats = ("blend",)`` on the class): :func:`backend_for_format` finds the backend that handles
one, so the IR reaches format-specific code (``scene.export_blend``) without knowing any backend.
Formats the core writes itself, without an engine (glTF, the HTML viewer), are named here as
``"module:function"`` and imported on first use, the same way: :func:`exporter_for_format` finds either.
"""

from __future__ import annotations

import importlib
import threading
from dataclasses import dataclass
from importlib import metadata
from typing import Any

from blendify_core.errors import BackendUnavailableError, InvalidSceneError, UnsupportedFeatureError, strict_arguments

__all__ = [
    "BackendStatus",
    "ENTRY_POINT_GROUP",
    "available_backends",
    "backend_for_format",
    "backend_names",
    "core_tool",
    "exporter_for_format",
    "close_backends",
    "get_backend",
    "get_backend_class",
    "register_backend",
    "shared_backend",
    "unregister_backend",
]

ENTRY_POINT_GROUP = "blendify.backends"


@dataclass(frozen=True)
class BackendStatus:
    """Whether a backend can be used here, and if not, why."""

    available: bool
    reason: str | None = None
    version: str | None = None


# ---------------------------------------------------------------------------------------------------

_registered: dict[str, Any] = {}  # name -> class or "module:Class"
_lock = threading.Lock()


@strict_arguments
def register_backend(name: str, target: type | str) -> None:
    """Register a backend class (or a "module:Class" path) under ``name`` at run time."""
    if not isinstance(name, str) or not name:
        raise InvalidSceneError(f"name: expected a non-empty backend name, got {name!r}")
    _registered[name] = target


@strict_arguments
def unregister_backend(name: str) -> None:
    _registered.pop(name, None)


def _entry_points() -> dict[str, Any]:
    found: dict[str, Any] = {}
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        found.setdefault(ep.name, ep.value)
    found.update(_registered)
    return found


@strict_arguments
def backend_names() -> list[str]:
    """Names of every registered backend (available or not), without importing any of them."""
    return sorted(_entry_points())


@strict_arguments
def get_backend_class(name: str) -> Any:
    """Import and return the class of backend ``name`` (raises BackendUnavailableError with the reason)."""
    points = _entry_points()
    if name not in points:
        raise InvalidSceneError(f"backend: unknown backend {name!r}; registered backends: {sorted(points)}")
    target = points[name]
    if isinstance(target, type):
        return target
    module_name, _, attr = str(target).partition(":")
    try:
        module = importlib.import_module(module_name)
        cls = getattr(module, attr)
    except Exception as exc:  # an import error of a third-party backend must not take the registry down
        raise BackendUnavailableError(
            f"backend {name!r}: cannot import {target} ({type(exc).__name__}: {exc})"
        ) from exc
    if not (isinstance(cls, type) and getattr(cls, "_is_blendify_backend", False)):
        raise BackendUnavailableError(f"backend {name!r}: {target} is not a blendify_core.Backend subclass")
    return cls


@strict_arguments
def available_backends() -> dict[str, BackendStatus]:
    """Every registered backend with its status: available, why not, engine version."""
    out: dict[str, BackendStatus] = {}
    for name in backend_names():
        try:
            cls = get_backend_class(name)
            out[name] = cls.probe()
        except BackendUnavailableError as exc:
            out[name] = BackendStatus(False, str(exc), None)
    return out


@strict_arguments
def get_backend(name: str, **options: Any) -> Any:
    """A new instance of backend ``name`` with ``options`` (close it when done, or use ``with``)."""
    cls = get_backend_class(name)
    status = cls.probe()
    if not status.available:
        raise BackendUnavailableError(f"backend {name!r} is not available: {status.reason}")
    return cls(**options)


_shared: dict[Any, Any] = {}


def shared_backend(name: str, **options: Any) -> Any:
    """The process-wide default instance of ``name`` with ``options`` (reused across ``bf.render`` calls
    so contexts and translated scenes stay warm)."""
    try:
        key: Any = (name, tuple(sorted(options.items())))
        hash(key)
    except TypeError:  # unhashable option values (lists, dicts): key them by their repr
        key = (name, repr(sorted(options.items(), key=lambda kv: kv[0])))
    with _lock:
        inst = _shared.get(key)
        if inst is None or inst._closed:
            inst = get_backend(name, **options)
            _shared[key] = inst
        return inst


@strict_arguments
def close_backends() -> None:
    """Close every shared backend instance created by ``bf.render``."""
    with _lock:
        items = list(_shared.values())
        _shared.clear()
    for inst in items:
        inst.close()


@strict_arguments
def backend_for_format(file_format: str) -> Any:
    """The class of the first available backend (by name) that declares ``file_format`` in its
    ``file_formats``; raises UnsupportedFeatureError naming the format and what was tried."""
    tried = []
    for name in backend_names():
        try:
            cls = get_backend_class(name)
        except BackendUnavailableError as exc:
            tried.append(f"{name}: {exc}")
            continue
        if file_format not in getattr(cls, "file_formats", ()):
            continue
        status = cls.probe()
        if status.available:
            return cls
        tried.append(f"{name}: {status.reason}")
    raise UnsupportedFeatureError(
        f"no available backend handles .{file_format} files" + (f" ({'; '.join(tried)})" if tried else ""),
        feature=f"file.{file_format}",
    )


#: what the core writes without an engine ("module:function", imported on first use); suffix -> format in
#: :data:`FORMAT_SUFFIXES`
_CORE_TOOLS = {
    "glb": "blendify_core.export.gltf:export_gltf",
    "gltf": "blendify_core.export.gltf:export_gltf",
    "html": "blendify_core.export.html:export_html",
    "show": "blendify_core.export.viewer:show",
}
#: file-name suffix -> format name (``scene.export`` picks the format from the suffix)
FORMAT_SUFFIXES = {".glb": "glb", ".gltf": "gltf", ".html": "html", ".blend": "blend", ".xml": "mitsuba"}


@strict_arguments
def core_tool(name: str) -> Any:
    """The core function registered as ``name`` (``"glb"``, ``"html"``, ``"show"``, ...), imported now."""
    target = _CORE_TOOLS.get(name)
    if target is None:
        raise InvalidSceneError(f"name: unknown core tool {name!r}; known: {sorted(_CORE_TOOLS)}")
    module_name, _, attr = target.partition(":")
    return getattr(importlib.import_module(module_name), attr)


@strict_arguments
def exporter_for_format(file_format: str) -> Any:
    """A function ``(scene, path, **kwargs)`` writing ``file_format``: the core's own exporter (glTF,
    HTML) or, for engine formats (``blend``, ``mitsuba``), the ``export_file`` of the first available
    backend declaring it (UnsupportedFeatureError naming the format and what was tried otherwise)."""
    if file_format in _CORE_TOOLS and file_format != "show":
        return core_tool(file_format)
    cls = backend_for_format(file_format)

    def export(scene: Any, path: Any, **kwargs: Any) -> Any:
        return cls.export_file(scene, file_format, path, **kwargs)

    return export
