"""The backend protocol: translate the IR to a native scene, render it to a RenderResult.

Backends are found by name through :mod:`blendify_core.registry`.
"""

from __future__ import annotations

import abc
import contextlib
import dataclasses
import inspect
import logging
import os
import time
from dataclasses import dataclass
from importlib import metadata
from typing import Any, ClassVar

from blendify_core.errors import BackendUnavailableError, InvalidSceneError, UnsupportedFeatureError
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability
from blendify_core.pipeline.compat import suggest
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import RenderSettings
from blendify_core.pipeline.translator import Translator
from blendify_core.registry import BackendStatus

__all__ = ["Backend", "Capability", "DeviceChoice", "parse_device"]

log = logging.getLogger("blendify_core")


@dataclass(frozen=True)
class DeviceChoice:
    """What a backend renders on (``Backend.device_choice``): ``requested`` ("cpu", "gpu" or an engine
    device), ``used`` (``result.meta["device"]``), ``fallback``: why the request could not be honoured
    (None when it was). ``bf.render`` refuses a fallback under ``strict=True`` (BackendUnavailableError),
    otherwise warns."""

    requested: str
    used: str
    fallback: str | None = None
    #: the devices found (``blendify info``), e.g. ["CPU", "GPU OPTIX: NVIDIA ..."]
    found: tuple[str, ...] = ()
    #: the option the request came from ("device", or Mitsuba's "variant")
    option: str = "device"


def parse_device(value: object, explicit: tuple[str, ...]) -> str:
    """``device=``: "cpu", "gpu" (any case) or one of ``explicit`` (the engine's own device names, matched
    case-insensitively and returned as declared)."""
    if isinstance(value, str):
        low = value.lower()
        if low in ("cpu", "gpu"):
            return low
        for name in explicit:
            if name.lower() == low:
                return name
    raise InvalidSceneError(f"device: expected 'cpu', 'gpu' or one of {list(explicit)}, got {value!r}")


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
    #: True where the engine's geometric outputs (depth, normal, albedo, instance) need a sample its colour must not
    #: take (Cycles writes depth and object index from a first sample fixed at the pixel centre, so it renders them
    #: beside colour with a render of their own): ``target_error`` then asks for them once, apart, and renders its
    #: colour passes alone
    geometry_pins_first_sample: ClassVar[bool] = False
    #: the smallest image the engine renders; the core pads smaller cameras and crops the result
    min_resolution: ClassVar[tuple[int, int]] = (1, 1)
    #: where the engine's arithmetic stops rendering right (measured; the core warns, naming the backend, when a
    #: scene crosses one; :data:`NUMERIC_LIMITS` lists the keys): ``max_distance`` (m of geometry from the
    #: camera), ``max_clip_ratio`` (far / near), ``min_near`` (m), ``coincident_faces`` (1: faces of two
    #: objects at the same place render wrong, not just z-fighting)
    numeric_limits: ClassVar[dict[str, float]] = {}
    #: file formats (suffix without the dot) this backend can export a scene to and attach to a scene
    #: (:meth:`export_file`, :meth:`attach_file`); found by :func:`blendify_core.registry.backend_for_format`
    file_formats: ClassVar[tuple[str, ...]] = ()
    #: biased render settings this engine cannot apply (keys of
    #: :data:`blendify_core.pipeline.settings.BIAS_KEYS` that change the converged picture: clamps, Filter
    #: Glossy, per-kind bounce limits): a render asking for one lists it in ``meta["approximations"]``
    #: (``strict=True`` refuses), and a crosscheck pair whose other side applies it is limited by the engine
    unapplied_settings: ClassVar[tuple[str, ...]] = ()
    #: marks backend classes for the registry (which cannot import this module)
    _is_blendify_backend: ClassVar[bool] = True
    #: the backend's translator (one handler per IR type); the core refuses an IR object whose exact type
    #: has no handler there before calling the backend. None: the backend checks types itself.
    translator_class: ClassVar[type[Translator] | None] = None

    def __init__(self, **options: Any) -> None:
        if options:
            raise InvalidSceneError(
                f"{type(self).__name__}: unknown option(s) {sorted(options)}"
                + "".join(suggest(name, self.option_names()) for name in sorted(options))
            )
        self._closed = False

    @classmethod
    def option_names(cls) -> list[str]:
        """The keyword options this backend's constructor takes, and the render settings' names (the
        candidates of "did you mean" for an unknown option)."""
        names = {f.name for f in dataclasses.fields(RenderSettings)} | {"quality", "backend"}
        for klass in cls.__mro__:
            init = klass.__dict__.get("__init__")
            if init is not None:
                params = inspect.signature(init).parameters.values()
                names |= {p.name for p in params if p.kind is p.KEYWORD_ONLY or p.kind is p.POSITIONAL_OR_KEYWORD}
        return sorted(names - {"self", "extra"})

    def pilot_sample_cost(self, settings: RenderSettings) -> float:
        """The time of one sample with ``settings`` (a pilot's: e.g. ``caustics=False``) relative to one with
        the full settings, as measured for this engine; ``final``'s pilots weigh the samples of each choice by
        it (a fixed number, not a timing, so a seed still gives the same picture). 1.0: no dearer."""
        return 1.0

    def pass_overhead(self, settings: RenderSettings) -> float:
        """The fixed time of one more render call with ``settings`` (scene update, film, read-back), in
        pixel-samples of the full settings, as measured for this engine: ``final``'s pilots count it for each
        of their passes, so that on a small or cheap image a pilot is tried only where its saving exceeds its
        calls (a fixed number, not a timing, so a seed still gives the same picture). 0.0: negligible."""
        return 0.0

    def switch_overhead(self, settings: RenderSettings) -> float:
        """The extra time of the first render call with ``settings`` after calls with others (a pilot's
        settings: the engine translates or loads the scene for them), in pixel-samples of the full settings,
        as measured for this engine; ``final``'s pilots count it once. Default: one more
        :meth:`pass_overhead`."""
        return self.pass_overhead(settings)

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
    def translate(self, scene: Scene, settings: RenderSettings) -> Any:
        """Build (or update) the engine's native scene from the IR (its type is the backend's own)."""

    @abc.abstractmethod
    def render(self, native: Any, settings: RenderSettings) -> RenderResult:
        """Render a native scene built by :meth:`translate`. ``result.meta`` holds keys documented in
        :class:`~blendify_core.pipeline.meta.RenderMeta`; timings under the common names of
        :data:`~blendify_core.pipeline.meta.COMMON_TIMINGS` (``render``, ``read_back``) plus any finer
        phases of the backend's own."""

    def device_choice(self) -> DeviceChoice | None:
        """The device this backend renders on (None: the backend has no ``device=`` option)."""
        return None

    def scene_lock(self) -> contextlib.AbstractContextManager[object]:
        """A lock held from translation to the end of the render (default: none). A backend whose engine
        holds one global scene (bpy) returns its re-entrant lock, so no other thread translates in between."""
        return contextlib.nullcontext()

    def render_scene(self, scene: Scene, settings: RenderSettings) -> RenderResult:
        """Translate and render under :meth:`scene_lock` (the one entry point: backends do not override it);
        records ``meta["timings"]["translate"]`` and ``["render"]`` (seconds) unless :meth:`render`
        reported them."""
        if self._closed:
            raise BackendUnavailableError(f"{self.name}: this backend instance was closed")
        with self.scene_lock():
            t0 = time.perf_counter()
            native = self.translate(scene, settings)
            t1 = time.perf_counter()
            result = self.render(native, settings)
            t2 = time.perf_counter()
        timings = result.meta.setdefault("timings", {})
        timings.setdefault("translate", t1 - t0)
        timings.setdefault("render", t2 - t1)
        return result

    @classmethod
    def export_file(cls, scene: Scene, file_format: str, path: str | os.PathLike[str], **kwargs: Any) -> object:
        """Write ``scene`` as a ``file_format`` file (only for formats in :attr:`file_formats`)."""
        raise UnsupportedFeatureError(
            f"backend {cls.name!r} cannot export .{file_format} files", feature=f"file.{file_format}", backend=cls.name
        )

    @classmethod
    def attach_file(cls, scene: Scene, file_format: str, path: str | os.PathLike[str], **kwargs: Any) -> object:
        """Import a ``file_format`` file into ``scene`` (only for formats in :attr:`file_formats`)."""
        raise UnsupportedFeatureError(
            f"backend {cls.name!r} cannot attach .{file_format} files", feature=f"file.{file_format}", backend=cls.name
        )

    def close(self) -> None:
        """Release engine resources (contexts, datablocks). Idempotent."""
        self._closed = True

    def __enter__(self) -> Backend:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
