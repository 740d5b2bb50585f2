"""blendify-core backend ``cycles``: Blender Cycles through the ``bpy`` wheel.

Importing this module does not import ``bpy`` (it is imported on first use). Where things live:

- :mod:`.translate`: :class:`~blendify_blender.translate.CyclesTranslator`, one handler per IR type (a
  sphere is translated by ``CyclesTranslator.sphere``), each declaring the capabilities it implements;
  ``build_scene`` (used by the .blend export); :mod:`.materials`: the node trees its material handlers build;
- :mod:`.capabilities`: the capability table (what the translator declares);
- :mod:`.session`: the bpy session (lazy import, the lock, factory resets, output capture) and the
  translated scene kept between renders, updated from the core's change detection;
- :mod:`.render`: rendering a translated scene into a RenderResult (the passes);
- :mod:`.worker`: ``isolate=True`` (a worker process); :mod:`.blendfile`: .blend export and attach.

Options (``bf.render(scene, backend="cycles", verbose=True)`` or ``CyclesBackend(...)``):

- ``verbose`` (False): print Blender's progress/log lines to stderr (always logged at DEBUG level on
  the ``blendify_blender`` logger).
- ``isolate`` (False): render in a persistent worker subprocess (the scene travels as a portable scene
  file); Blender keeps some memory it never frees, so long runs should use it.
- ``worker_max_renders`` (100): with ``isolate``, restart the worker after this many renders.
- ``device`` ("cpu"): "cpu", "gpu" (the first Cycles compute type with a device: OPTIX, CUDA, HIP, METAL,
  ONEAPI) or one of those types by name. Without such a device ``bf.render`` warns and renders on the CPU,
  or raises ``BackendUnavailableError`` with ``strict=True``; ``result.meta["device"]`` says what ran.
- ``cycles_settings`` (None): Cycles scene properties set after blendify's own settings, for rendering an
  attached .blend with the file's settings (``attach_blend(..., render_settings=True).cycles_settings``:
  volume bounces, caustics, light threshold and tree, adaptive threshold, film exposure); the keys are
  those of :data:`blendify_blender.blendfile.settings.CYCLES_KEYS`.

Translation (details in :mod:`.translate`, :mod:`.materials`, :mod:`.render`; formulas from
``shared/docs/CONVENTIONS.md``): meshes, colour attributes, UVs and texture pixels through bulk
``foreach_set``; point clouds as native Cycles points (vertex-only mesh + Geometry Nodes Mesh to Points +
Set Material, radius and colour as attributes); cubes/circles/cylinders/planes/spheres/ellipsoids from
the IR's shared tessellation (one mesh per shape, shared by identical primitives); curves as the IR's
tube mesh; one node-tree material per (object, slot) with the colour source feeding Base Color and the
``bf_albedo`` AOV, the shading normal feeding the ``bf_normal`` AOV (the normal output);
lights in the IR's (Blender's) units with soft falloff off and area ``normalize`` on,
invisible to camera rays; the world = background light + environment texture (nothing else);
perspective cameras with ``HORIZONTAL`` sensor fit, lens from fx, principal point through the shift,
fx != fy through the pixel aspect; orthographic cameras. Every Cycles setting is explicit (see
``result.meta["engine_settings"]``); with ``settings.effects`` the per-type bounce limits and caustics
follow :func:`blendify_core.analyse_effects`. A new scene starts from a factory reset; the same scene is
updated incrementally (camera, lights and moved objects never rebuild meshes). Objects of attached .blend
files that the IR cannot represent (hair, volumes, ...) are appended (safely) and rendered as they are.

Outputs come from per-pass single-layer EXR files (a compositor File Output node; the multilayer writer
fails with non-square pixels) in a private temporary directory removed after reading. Ctrl-C during an
in-process render is honoured when Cycles finishes the frame (Cycles cannot be cancelled from the bpy
module); with ``isolate=True`` it is immediate (the worker is killed and restarted on the next render).

Environment: bpy 5.0.1's installed ``WHEEL`` file carries the wrong tag (cp39 for a cp311 wheel), which made
uv reinstall bpy on every ``uv run``, under running renders. This distribution also installs the top-level
module ``_blendify_bpy_tags`` and ``_blendify_bpy_tags.pth`` (hatch ``force-include``: present in the wheel
and in the editable install alike); the .pth repairs the tag when an interpreter starts, and importing this
package does it again. Details and measurements in that module's docstring.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import logging
from typing import Any

from blendify_core.errors import BackendUnavailableError, InvalidSceneError, warn_at_caller
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.backend import Backend, DeviceChoice, parse_device
from blendify_core.pipeline.capabilities import Capability
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import RenderSettings
from blendify_core.registry import BackendStatus

from . import capabilities as _capabilities
from . import session as _session
from .render import render_built
from .session import (
    BPY_LOCK,
    GPU_TYPES,
    CyclesSession,
    TranslatedScene,
    bpy_module,
    defer_keyboard_interrupt,
    enable_gpu,
)
from .translate import CyclesTranslator, apply_cycles_settings, check_cycles_settings
from .worker import IsolatedScene, WorkerClient

__all__ = ["CyclesBackend"]

log = logging.getLogger("blendify_blender")
# a library logs, the application decides where to: no "No handlers could be found" output by default
log.addHandler(logging.NullHandler())


def _fix_bpy_tags() -> None:
    """Repair bpy's installed WHEEL tag (see ``_blendify_bpy_tags``, which ``_blendify_bpy_tags.pth`` also runs
    at interpreter start-up): otherwise uv reinstalls bpy on every ``uv run``, under running renders."""
    try:
        import _blendify_bpy_tags
    except ImportError:  # installed without the top-level helper (e.g. copied sources): nothing to do
        return
    _blendify_bpy_tags.fix()


_fix_bpy_tags()


def _choose_device(requested: str) -> DeviceChoice:
    """The device for ``device=requested``, from the GPU list Cycles reports here."""
    if requested == "cpu":
        return DeviceChoice("cpu", "CPU", None, ("CPU",))
    devices = _session.list_gpu_devices()
    found = ("CPU", *(f"GPU {kind}: {name}" for kind, name in devices))
    kinds = [k for k in GPU_TYPES if any(kind == k for kind, _ in devices)]
    wanted = kinds if requested == "gpu" else [k for k in kinds if k == requested]
    if wanted:
        names = ", ".join(name for kind, name in devices if kind == wanted[0])
        return DeviceChoice(requested, f"GPU ({wanted[0]}: {names})", None, found)
    if not devices:
        why = f"Cycles found no GPU compute device (looked for {', '.join(GPU_TYPES)})"
    else:
        why = f"Cycles found no {requested} device (found: {', '.join(found[1:])})"
    return DeviceChoice(requested, "CPU", why, found)


#: the fixed time of one render call (a pass of ``final``: scene update, film, EXR read-back) in pixel-samples:
#: measured on a warm backend as (time of 1 spp) less 1/32 of (33 spp - 1 spp), plastic ball and cube under a sky
#: and the floating bunny at 32 and 96 px: 25-38 ms per call against 0.57-1.7 us per pixel-sample on one thread
#: (1.6e4-6.6e4; about twice that on two threads); the lowest, so a pilot is never refused for a cost it does not
#: have
PASS_OVERHEAD = 1.6e4


class CyclesBackend(Backend):
    """The reference path tracer: Blender Cycles (CPU, or GPU when asked and present)."""

    name = "cycles"
    engine = "bpy"
    qualities = ("final", "draft", "preview")
    path_tracer = True
    #: the geometric outputs come from the first sample, which Cycles fixes at the pixel centre and colour skips: a
    #: render asking for both renders twice (:func:`blendify_blender.render.render_built`)
    geometry_pins_first_sample = True
    #: Blender renders at least 4x4 pixels; the core renders smaller images padded and crops them
    min_resolution = (4, 4)
    file_formats = ("blend",)
    # measured with bpy 5.0.1 (tests/robustness/test_hard_cases_round2.py): a sphere 4.5e13 m away renders,
    # 4.5e14 m away nothing; two coincident quads render black (each shadows the other)
    numeric_limits = {"max_distance": 1e14, "coincident_faces": 1.0}
    translator_class = CyclesTranslator

    def __init__(
        self,
        verbose: bool = False,
        isolate: bool = False,
        worker_max_renders: int = 100,
        device: str = "cpu",
        cycles_settings: dict[str, Any] | None = None,
        **options: Any,
    ) -> None:
        super().__init__(**options)
        if not isinstance(verbose, bool):
            raise InvalidSceneError(f"verbose: expected True or False, got {verbose!r}")
        if not isinstance(isolate, bool):
            raise InvalidSceneError(f"isolate: expected True or False, got {isolate!r}")
        if isinstance(worker_max_renders, bool) or not isinstance(worker_max_renders, int) or worker_max_renders < 1:
            raise InvalidSceneError(f"worker_max_renders: expected a positive integer, got {worker_max_renders!r}")
        #: "cpu", "gpu" (the first of GPU_TYPES with a device) or a Cycles compute type ("OPTIX", "CUDA", ...)
        self.device = parse_device(device, GPU_TYPES)
        self.verbose = verbose
        self.isolate = isolate
        self.worker_max_renders = worker_max_renders
        self._device_choice: DeviceChoice | None = None
        self._gpu_type = ""
        self.cycles_settings = check_cycles_settings(cycles_settings)
        if self.cycles_settings and isolate:
            raise InvalidSceneError("cycles_settings: not available with isolate=True (the worker uses its own)")
        self._session: CyclesSession | None = None
        self._worker: WorkerClient | None = None

    # -- discovery ---------------------------------------------------------------------------------
    @classmethod
    def probe(cls) -> BackendStatus:
        """Cheap: checks that ``bpy`` and ``OpenEXR`` are installed, without importing bpy."""
        try:
            if importlib.util.find_spec("bpy") is None:
                return BackendStatus(False, "the 'bpy' package is not installed (pip install bpy==5.0.1)", None)
            if importlib.util.find_spec("OpenEXR") is None:
                return BackendStatus(False, "the 'openexr' package is not installed (pip install openexr)", None)
        except (ImportError, ValueError) as exc:
            return BackendStatus(False, f"cannot look up bpy: {exc}", None)
        return BackendStatus(True, None, cls.engine_version())

    @classmethod
    def capabilities(cls) -> dict[str, Capability]:
        return _capabilities.capabilities()

    # -- .blend helpers (in blendfile/) ------------------------------------------------------
    @classmethod
    def export_file(cls, scene: Any, file_format: str, path: Any, **kwargs: Any) -> Any:
        if file_format != "blend":
            return super().export_file(scene, file_format, path, **kwargs)
        return cls.export_blend(scene, path, **kwargs)

    @classmethod
    def attach_file(cls, scene: Any, file_format: str, path: Any, **kwargs: Any) -> Any:
        if file_format != "blend":
            return super().attach_file(scene, file_format, path, **kwargs)
        return cls.attach_blend(scene, path, **kwargs)

    @classmethod
    def info_details(cls) -> list[str]:
        """Lines for ``blendify info``: the devices Cycles finds here."""
        found = _choose_device("gpu").found
        if len(found) > 1:
            return [f"devices: {', '.join(found)}"]
        return [f"devices: CPU; GPU: none (Cycles looked for {', '.join(GPU_TYPES)})"]

    def pass_overhead(self, settings: RenderSettings) -> float:
        """One render call's fixed time in pixel-samples (:data:`PASS_OVERHEAD`)."""
        return PASS_OVERHEAD

    def device_choice(self) -> DeviceChoice | None:
        """What this backend renders on: the CPU for ``device="cpu"``; otherwise the GPU devices Cycles finds
        (:func:`blendify_blender.session.list_gpu_devices`, enumerated once per backend), or the CPU with
        the reason. With ``isolate=True`` the worker decides (None here: no bpy in this process)."""
        if self.isolate and self.device != "cpu":
            return None
        if self._device_choice is None:
            self._device_choice = _choose_device(self.device)
            used = self._device_choice.used
            self._gpu_type = used[5 : used.index(":")] if used.startswith("GPU (") else ""
        return self._device_choice

    @classmethod
    def export_blend(cls, scene: Any, path: Any, **kwargs: Any) -> Any:
        """Write a .blend file that renders ``scene`` in Blender (see :mod:`blendify_blender.export`)."""
        from .export import export_blend

        return export_blend(scene, path, **kwargs)

    @classmethod
    def attach_blend(cls, scene: Any, path: Any, with_camera: bool = False, **kwargs: Any) -> Any:
        """Import a .blend file's content into ``scene`` (see :mod:`blendify_blender.blendfile`)."""
        from .blendfile import attach_blend

        return attach_blend(scene, path, with_camera=with_camera, **kwargs)

    # -- work --------------------------------------------------------------------------------------
    def _ensure_session(self) -> CyclesSession:
        if self._session is None:
            bpy_module()
            self.device_choice()
            kind = self._gpu_type
            gpu = functools.partial(enable_gpu, kind) if kind else None
            self._session = CyclesSession(CyclesTranslator, device="GPU" if kind else "CPU", gpu_setup=gpu)
        return self._session

    def _check_open(self) -> None:
        if self._closed:
            raise BackendUnavailableError(f"{self.name}: this backend instance was closed")

    def scene_lock(self) -> contextlib.AbstractContextManager[object]:
        """bpy holds one scene per process: no other thread translates between this translation and its
        render (the lock is re-entrant; an isolated backend renders in its worker and needs none)."""
        return contextlib.nullcontext() if self.isolate else BPY_LOCK

    def translate(self, scene: Scene, settings: RenderSettings) -> TranslatedScene | IsolatedScene:
        """Translate (or update) the scene in the bpy session. With ``isolate=True`` nothing is translated
        here: the scene is checked and handed to :meth:`render`, which sends it to the worker process."""
        self._check_open()
        if self.isolate:
            CyclesTranslator.check_scene(scene)
            return IsolatedScene(scene)
        session = self._ensure_session()
        with defer_keyboard_interrupt():
            return session.translate(scene, settings, self.verbose)

    def render(self, native: TranslatedScene | IsolatedScene, settings: RenderSettings) -> RenderResult:
        """Render what :meth:`translate` returned (translated again first when another translation ran in
        between, e.g. in another thread: the lock is held from there to the end of the render)."""
        self._check_open()
        if isinstance(native, IsolatedScene):
            if self._worker is None:
                self._worker = WorkerClient(
                    max_renders=self.worker_max_renders, verbose=self.verbose, device=self.device
                )
            result = self._worker.render(native.scene, settings)
            fallback = result.meta.pop("device_fallback", None)  # type: ignore[misc]
            if fallback:  # the worker chose the device (strict=True already refused there)
                used = result.meta.get("device")
                note = f"cycles: device={self.device!r} is unavailable here ({fallback}); rendering on {used}"
                warn_at_caller(note)
                result.meta.setdefault("warnings", []).append(note)
            return result
        if not isinstance(native, TranslatedScene):
            raise InvalidSceneError(
                f"native: expected what CyclesBackend.translate returned, got {type(native).__name__}"
            )
        session = self._ensure_session()
        with defer_keyboard_interrupt(), BPY_LOCK:
            built = session.current(native, self.verbose)
            if self.cycles_settings:
                apply_cycles_settings(built, self.cycles_settings)
            result = render_built(built, settings, self.verbose)
        if self.cycles_settings:  # what no other engine applies: a crosscheck pair is limited by the engine
            from .blendfile.settings import cycles_changes

            only = cycles_changes(self.cycles_settings, settings.max_bounces)
            if only:
                result.meta["engine_only_settings"] = [f"cycles.{x}" for x in only]
        return result

    def clear(self) -> None:
        """Remove every datablock this backend created in the bpy session (keeps the backend usable)."""
        if self._session is not None:
            self._session.clear()

    def close(self) -> None:
        if self._closed:
            return
        try:
            self.clear()
            if self._worker is not None:
                self._worker.close()
                self._worker = None
        finally:
            self._session = None
            super().close()
