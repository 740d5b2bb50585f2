"""blendify-core backend ``cycles``: Blender Cycles through the ``bpy`` wheel.

Importing this module does not import ``bpy``: the translator (:mod:`.translate`), the renderer
(:mod:`.engine`), the worker (:mod:`.worker`) and the .blend helpers (:mod:`.blendfile`) are imported
on first use.

Options (``bf.render(scene, backend="cycles", verbose=True)`` or ``CyclesBackend(...)``):

- ``verbose`` (False): print Blender's progress/log lines to stderr (always logged at DEBUG level on
  the ``blendify_blender`` logger).
- ``isolate`` (False): render in a persistent worker subprocess (the scene travels as a portable scene
  file); Blender keeps some memory it never frees, so long runs should use it.
- ``worker_max_renders`` (100): with ``isolate``, restart the worker after this many renders.
- ``device`` ("CPU"): "CPU" or "GPU" (GPU falls back to CPU with a logged reason when none is found).

Translation (details in :mod:`.translate`, :mod:`.materials`, :mod:`.engine`; formulas from
``shared/docs/CONVENTIONS.md``): meshes, colour attributes, UVs and texture pixels through bulk
``foreach_set``; point clouds as native Cycles points (vertex-only mesh + Geometry Nodes Mesh to Points +
Set Material, radius and colour as attributes); cubes/circles/cylinders/planes/spheres/ellipsoids from
the IR's shared tessellation (one mesh per shape, shared by identical primitives); curves as bevelled
POLY splines; one node-tree material per (object, slot) with the colour source feeding Base Color and the
``bf_albedo`` AOV; lights in the IR's (Blender's) units with soft falloff off and area ``normalize`` on,
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

import importlib.util
import logging
import time
from typing import Any

from blendify_core.errors import BackendUnavailableError, InvalidSceneError
from blendify_core.pipeline.backend import Backend
from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import RenderSettings
from blendify_core.registry import BackendStatus

__all__ = ["CyclesBackend"]

log = logging.getLogger("blendify_blender")


def _fix_bpy_tags() -> None:
    """Repair bpy's installed WHEEL tag (see ``_blendify_bpy_tags``, which ``_blendify_bpy_tags.pth`` also runs
    at interpreter start-up): otherwise uv reinstalls bpy on every ``uv run``, under running renders."""
    try:
        import _blendify_bpy_tags
    except ImportError:  # installed without the top-level helper (e.g. copied sources): nothing to do
        return
    _blendify_bpy_tags.fix()


_fix_bpy_tags()

_NOTES: dict[str, Capability] = {
    "primitive.sphere": Capability("exact", "the IR's shared tessellation (64x32 UV sphere, exact normals)"),
    "primitive.ellipsoid": Capability("exact", "the IR's shared tessellation (64x32, exact normals)"),
    "primitive.curve": Capability("exact", "Blender curve: POLY spline bevelled to the radius, filled caps"),
    "pointcloud": Capability("exact", "native Cycles points (Geometry Nodes Mesh to Points)"),
    "light.point.soft": Capability("exact", "sphere light, soft falloff off (matches a sphere emitter)"),
    "light.spot.blend": Capability("exact", "Blender's own smoothstep cone edge"),
    "camera.anisotropic": Capability("exact", "pixel aspect ratio"),
    "output.albedo": Capability("exact", "material colour input through a shader AOV"),
    "output.depth": Capability("exact", "Cycles Z pass (one sample per pixel, not anti-aliased)"),
    "output.instance": Capability("exact", "object index pass (not anti-aliased)"),
}


class CyclesBackend(Backend):
    """The reference path tracer: Blender Cycles (CPU, or GPU when asked and present)."""

    name = "cycles"
    engine = "bpy"
    qualities = ("final", "draft", "preview")
    path_tracer = True
    #: Blender renders at least 4x4 pixels; the core renders smaller images padded and crops them
    min_resolution = (4, 4)
    file_formats = ("blend",)

    def __init__(
        self,
        verbose: bool = False,
        isolate: bool = False,
        worker_max_renders: int = 100,
        device: str = "CPU",
        **options: Any,
    ) -> None:
        super().__init__(**options)
        if not isinstance(verbose, bool):
            raise InvalidSceneError(f"verbose: expected True or False, got {verbose!r}")
        if not isinstance(isolate, bool):
            raise InvalidSceneError(f"isolate: expected True or False, got {isolate!r}")
        if isinstance(worker_max_renders, bool) or not isinstance(worker_max_renders, int) or worker_max_renders < 1:
            raise InvalidSceneError(f"worker_max_renders: expected a positive integer, got {worker_max_renders!r}")
        if not isinstance(device, str) or device.upper() not in ("CPU", "GPU"):
            raise InvalidSceneError(f"device: expected 'CPU' or 'GPU', got {device!r}")
        self.verbose = verbose
        self.isolate = isolate
        self.worker_max_renders = worker_max_renders
        self.device = device.upper()
        self._translator: Any = None
        self._worker: Any = None

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
        return {name: _NOTES.get(name, Capability("exact")) for name in ALL_FEATURES}

    # -- .blend helpers (part B lives in blendfile.py) --------------------------------------------
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
    def export_blend(cls, scene: Any, path: Any, **kwargs: Any) -> Any:
        """Write a .blend file that renders ``scene`` in Blender (see :mod:`blendify_blender.blendfile`)."""
        from . import blendfile

        return blendfile.export_blend(scene, path, **kwargs)

    @classmethod
    def attach_blend(cls, scene: Any, path: Any, with_camera: bool = False, **kwargs: Any) -> Any:
        """Import a .blend file's content into ``scene`` (see :mod:`blendify_blender.blendfile`)."""
        from . import blendfile

        return blendfile.attach_blend(scene, path, with_camera=with_camera, **kwargs)

    # -- work --------------------------------------------------------------------------------------
    def _ensure_translator(self) -> Any:
        if self._translator is None:
            from . import _runtime
            from .translate import Translator

            _runtime.bpy_module()
            gpu = _enable_gpu if self.device == "GPU" else None
            self._translator = Translator(device=self.device, gpu_setup=gpu)
        return self._translator

    def _check_open(self) -> None:
        if self._closed:
            raise BackendUnavailableError(f"{self.name}: this backend instance was closed")

    def translate(self, scene: Any, settings: RenderSettings) -> Any:
        """Translate (or update) the scene in the bpy session; returns the BuiltScene."""
        self._check_open()
        from . import _runtime

        translator = self._ensure_translator()
        with _runtime.BPY_LOCK:
            with _runtime.capture_output("translate", self.verbose) as cap, _runtime.engine_errors("translating", cap):
                return translator.sync(scene, settings)

    def render(self, native: Any, settings: RenderSettings) -> RenderResult:
        """Render a BuiltScene returned by :meth:`translate`."""
        self._check_open()
        from . import _runtime
        from .engine import render_built

        with _runtime.BPY_LOCK:
            if native.generation != _runtime.generation():
                raise InvalidSceneError("native: this translated scene was reset since; translate the scene again")
            return render_built(native, settings, self.verbose)

    def render_scene(self, scene: Any, settings: RenderSettings) -> RenderResult:
        """Translate (incrementally) and render, holding the bpy lock for both; or hand the scene to the
        worker subprocess when ``isolate=True``."""
        self._check_open()
        if self.isolate:
            if self._worker is None:
                from .worker import WorkerClient

                self._worker = WorkerClient(
                    max_renders=self.worker_max_renders, verbose=self.verbose, device=self.device
                )
            return self._worker.render(scene, settings)
        from . import _runtime

        t0 = time.perf_counter()
        with _runtime.defer_keyboard_interrupt(), _runtime.BPY_LOCK:
            built = self.translate(scene, settings)
            t1 = time.perf_counter()
            result = self.render(built, settings)
        t2 = time.perf_counter()
        timings = result.meta.setdefault("timings", {})
        timings["translate"] = t1 - t0
        timings["render"] = t2 - t1
        result.meta["translation"] = dict(self._translator.last_stats)
        return result

    def clear(self) -> None:
        """Remove every datablock this backend created in the bpy session (keeps the backend usable)."""
        if self._translator is not None:
            from . import _runtime

            with _runtime.BPY_LOCK:
                self._translator.clear()

    def close(self) -> None:
        if self._closed:
            return
        try:
            self.clear()
            if self._worker is not None:
                self._worker.close()
                self._worker = None
        finally:
            self._translator = None
            super().close()


def _enable_gpu() -> str:
    """Enable the first available GPU compute backend; '' (CPU fallback, logged) when there is none."""
    from . import _runtime

    bpy = _runtime.bpy_module()
    try:
        prefs = bpy.context.preferences.addons["cycles"].preferences
    except Exception as exc:  # pragma: no cover - depends on the build
        log.warning("cycles: GPU requested but the Cycles preferences are unavailable (%s); using the CPU", exc)
        return ""
    for kind in ("OPTIX", "CUDA", "HIP", "METAL", "ONEAPI"):
        try:
            prefs.compute_device_type = kind
            prefs.get_devices()
        except Exception:
            continue
        devices = [d for d in prefs.devices if d.type == kind]
        if devices:
            for d in prefs.devices:
                d.use = d.type == kind
            return kind
    log.warning("cycles: GPU requested but no GPU compute device was found; rendering on the CPU")
    return ""
