"""The backend protocol and the name-keyed, lazily importing backend registry.

Backends register through the entry-point group ``blendify.backends``
(``cycles = "blendify_blender:CyclesBackend"``), so a third party can add one without touching this
repository; :func:`register_backend` adds one at run time (tests use it for fakes). Nothing is imported
when the registry is read: a backend module is imported on first use, and its engine only when a
backend instance needs it.
"""

from __future__ import annotations

import abc
import importlib
import logging
import threading
import time
from dataclasses import dataclass
from importlib import metadata
from typing import Any, ClassVar

from blendify_core.errors import BackendUnavailableError, InvalidSceneError
from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import RenderSettings

__all__ = [
    "Backend",
    "BackendStatus",
    "Capability",
    "available_backends",
    "backend_names",
    "get_backend",
    "get_backend_class",
    "register_backend",
    "ENTRY_POINT_GROUP",
]

log = logging.getLogger("blendify_core")
ENTRY_POINT_GROUP = "blendify.backends"


@dataclass(frozen=True)
class BackendStatus:
    """Whether a backend can be used here, and if not, why."""

    available: bool
    reason: str | None = None
    version: str | None = None


class Backend(abc.ABC):
    """Base of every backend: translate the IR to a native scene, render it to a :class:`RenderResult`.

    Subclasses set ``name`` and ``engine`` (the distribution whose version is reported), implement
    :meth:`probe`, :meth:`capabilities`, :meth:`translate` and :meth:`render`, and accept their options
    as keyword arguments of ``__init__`` (unknown ones must raise ``InvalidSceneError``).
    """

    name: ClassVar[str] = "base"
    engine: ClassVar[str | None] = None
    #: quality modes this backend serves well, best first (used by the automatic choice)
    qualities: ClassVar[tuple[str, ...]] = ("preview", "draft", "final")
    #: True for Monte Carlo renderers: ``target_error`` renders independent passes until the estimated
    #: error is low enough (see ``blendify_core.pipeline.render.render_to_target``)
    path_tracer: ClassVar[bool] = False
    #: the smallest image the engine renders; the core pads smaller cameras and crops the result
    min_resolution: ClassVar[tuple[int, int]] = (1, 1)

    def __init__(self, **options: Any) -> None:
        if options:
            raise InvalidSceneError(f"{type(self).__name__}: unknown option(s) {sorted(options)}")
        self._closed = False

    # -- discovery ---------------------------------------------------------------------------------
    @classmethod
    def probe(cls) -> BackendStatus:
        """Cheap check that the engine can be used (must never crash the process)."""
        import importlib.util

        if cls.engine is None:
            return BackendStatus(True)
        module = cls.engine_module()
        if importlib.util.find_spec(module) is None:
            return BackendStatus(False, f"the '{cls.engine}' package is not installed", None)
        return BackendStatus(True, None, cls.engine_version())

    @classmethod
    def engine_module(cls) -> str:
        return (cls.engine or "").replace("-", "_")

    @classmethod
    def engine_version(cls) -> str | None:
        if cls.engine is None:
            return None
        try:
            return metadata.version(cls.engine)
        except metadata.PackageNotFoundError:
            return None

    @classmethod
    def capabilities(cls) -> dict[str, Capability]:
        """Feature name -> Capability for every name in ``blendify_core.pipeline.capabilities.ALL_FEATURES``."""
        return {name: Capability("unsupported", "not declared") for name in ALL_FEATURES}

    # -- work ---------------------------------------------------------------------------------------
    @abc.abstractmethod
    def translate(self, scene: Any, settings: RenderSettings) -> Any:
        """Build (or update) the engine's native scene from the IR."""

    @abc.abstractmethod
    def render(self, native: Any, settings: RenderSettings) -> RenderResult:
        """Render a native scene built by :meth:`translate`."""

    def render_scene(self, scene: Any, settings: RenderSettings) -> RenderResult:
        """Translate and render; records ``meta["timings"]`` (seconds) for both phases."""
        if self._closed:
            raise BackendUnavailableError(f"{self.name}: this backend instance was closed")
        t0 = time.perf_counter()
        native = self.translate(scene, settings)
        t1 = time.perf_counter()
        result = self.render(native, settings)
        t2 = time.perf_counter()
        timings = result.meta.setdefault("timings", {})
        timings.setdefault("translate", t1 - t0)
        timings.setdefault("render", t2 - t1)
        return result

    def close(self) -> None:
        """Release engine resources (contexts, datablocks). Idempotent."""
        self._closed = True

    def __enter__(self) -> Backend:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# ---------------------------------------------------------------------------------------------------
# registry
# ---------------------------------------------------------------------------------------------------

_registered: dict[str, Any] = {}  # name -> class or "module:Class"
_lock = threading.Lock()


def register_backend(name: str, target: type[Backend] | str) -> None:
    """Register a backend class (or a "module:Class" path) under ``name`` at run time."""
    if not isinstance(name, str) or not name:
        raise InvalidSceneError(f"name: expected a non-empty backend name, got {name!r}")
    _registered[name] = target


def unregister_backend(name: str) -> None:
    _registered.pop(name, None)


def _entry_points() -> dict[str, Any]:
    found: dict[str, Any] = {}
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        found.setdefault(ep.name, ep.value)
    found.update(_registered)
    return found


def backend_names() -> list[str]:
    """Names of every registered backend (available or not), without importing any of them."""
    return sorted(_entry_points())


def get_backend_class(name: str) -> type[Backend]:
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
    if not (isinstance(cls, type) and issubclass(cls, Backend)):
        raise BackendUnavailableError(f"backend {name!r}: {target} is not a blendify_core.Backend subclass")
    return cls


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


def get_backend(name: str, **options: Any) -> Backend:
    """A new instance of backend ``name`` with ``options`` (close it when done, or use ``with``)."""
    cls = get_backend_class(name)
    status = cls.probe()
    if not status.available:
        raise BackendUnavailableError(f"backend {name!r} is not available: {status.reason}")
    return cls(**options)


_shared: dict[tuple[str, tuple[tuple[str, Any], ...]], Backend] = {}


def shared_backend(name: str, **options: Any) -> Backend:
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


def close_backends() -> None:
    """Close every shared backend instance created by ``bf.render``."""
    with _lock:
        items = list(_shared.values())
        _shared.clear()
    for inst in items:
        inst.close()
