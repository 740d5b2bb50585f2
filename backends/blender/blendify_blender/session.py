"""The bpy session: everything of the Cycles backend that lives across renders.

``bpy`` is one process-global Blender session, so everything that touches it must hold :data:`BPY_LOCK`
(a re-entrant lock: the translator and the .blend helpers call each other). This module holds

- the plumbing around it: the lazy import (:func:`bpy_module`), :func:`factory_reset` (which bumps
  :func:`generation`; cached translations compare it to know that their datablocks are gone), Blender's
  stdout noise (:func:`capture_output`), error wrapping (:func:`engine_errors`), Ctrl-C deferral and the
  GPU set-up (:func:`enable_gpu`);
- the translated scene kept between renders (:class:`BuiltScene`: every datablock created for one IR
  scene, by renderable) and :class:`CyclesSession`, which brings it in line with the IR scene using the
  core's change detection (:class:`~blendify_core.pipeline.changes.ChangeTracker`): a different IR scene
  (another renderables collection) resets bpy to factory settings; the same scene only gets what changed
  (new/removed/rebuilt renderables, moved objects get a new matrix, lights and world when they changed);
  the camera and the engine settings are applied every time (cheap). A camera or light change rebuilds
  no mesh.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import tempfile
import threading
import weakref
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from blendify_core.errors import BackendUnavailableError, BlendifyError, RenderError
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.changes import ChangeTracker
from blendify_core.pipeline.settings import RenderSettings
from blendify_core.pipeline.translator import TranslationContext

if TYPE_CHECKING:  # the translator imports this module; the session receives its class
    from blendify_blender.translate import CyclesTranslator

__all__ = [
    "BPY_LOCK",
    "BuiltScene",
    "CyclesSession",
    "TranslatedScene",
    "bpy_module",
    "capture_output",
    "datablock_counts",
    "defer_keyboard_interrupt",
    "enable_gpu",
    "list_gpu_devices",
    "GPU_TYPES",
    "engine_errors",
    "factory_reset",
    "generation",
    "soft_reset",
]

log = logging.getLogger("blendify_blender")

#: serialises every use of bpy across threads (bpy is not thread-safe and holds one global scene)
BPY_LOCK = threading.RLock()
_generation = 0
_bpy: Any = None


def bpy_module() -> Any:
    """Import ``bpy`` on first use (BackendUnavailableError with the reason if it cannot be imported)."""
    global _bpy
    if _bpy is None:
        try:
            import bpy
        except Exception as exc:  # ImportError, or a broken wheel raising anything
            raise BackendUnavailableError(f"cycles: cannot import bpy ({type(exc).__name__}: {exc})") from exc
        _bpy = bpy
    return _bpy


def generation() -> int:
    """Counter bumped by every :func:`factory_reset` (cached datablocks are invalid once it changes)."""
    return _generation


def factory_reset() -> None:
    """Reset bpy to an empty factory scene (no user preferences, no startup file, no objects).

    Also forces Python auto-execution off (the factory default) so nothing loaded later runs scripts.
    ``read_factory_settings`` crashes Blender when called from a thread other than the main one, so
    there the session is emptied through the data API instead (:func:`soft_reset`); every setting the
    backend relies on is set explicitly anyway."""
    global _generation
    bpy = bpy_module()
    with BPY_LOCK, capture_output("factory reset"):
        if threading.current_thread() is threading.main_thread():
            bpy.ops.wm.read_factory_settings(use_empty=True)
        else:
            soft_reset()
        _generation += 1
        with contextlib.suppress(Exception):
            bpy.context.preferences.filepaths.use_scripts_auto_execute = False
        if not hasattr(bpy.context.scene, "cycles"):
            # A reset re-registers Cycles every time (2000 resets in 10 fresh processes: never missing). It is
            # missing only when bpy's files were deleted under this process, i.e. bpy was reinstalled while it
            # ran (146 of 360 resets beside a reinstall loop; re-enabling the add-on rescued none of them).
            # uv did that on every `uv run` until _blendify_bpy_tags repaired bpy's installed WHEEL tag.
            raise RenderError(
                "cycles: the Cycles add-on is not registered after a factory reset: bpy's files changed under this "
                "process (was bpy reinstalled while it ran?)"
            )


#: the bpy.data collections the backend creates datablocks in (checked for leaks, emptied on reset)
_COLLECTIONS = (
    "objects",
    "meshes",
    "materials",
    "images",
    "lights",
    "cameras",
    "curves",
    "worlds",
    "node_groups",
    "pointclouds",
    "collections",
    "textures",
)
#: every collection a soft reset empties: the above plus what an attached .blend file may bring
_RESET_COLLECTIONS = (
    *_COLLECTIONS,
    "actions",
    "hair_curves",
    "grease_pencils",
    "volumes",
    "lattices",
    "metaballs",
    "fonts",
    "libraries",
)


def soft_reset() -> None:
    """Empty the bpy session through the data API (usable from any thread): every datablock of the
    common kinds and every scene but the current one are removed."""
    global _generation
    bpy = bpy_module()
    with BPY_LOCK:
        keep = bpy.context.scene
        ids = [s for s in bpy.data.scenes if s != keep]
        for name in _RESET_COLLECTIONS:
            coll = getattr(bpy.data, name, None)
            if coll is not None:
                ids.extend(coll)
        if ids:
            bpy.data.batch_remove(ids)
        keep.world = None
        keep.camera = None
        keep.compositing_node_group = None
        _generation += 1


class _Capture:
    """Blender's C-level stdout/stderr during one operation (see :func:`capture_output`)."""

    def __init__(self) -> None:
        self.text = ""

    @property
    def lines(self) -> list[str]:
        return [ln for ln in self.text.splitlines() if ln.strip()]

    def error_lines(self) -> list[str]:
        keys = ("error", "Error", "ERROR", "failed", "Failed", "cannot", "Cannot")
        return [ln.strip() for ln in self.lines if any(k in ln for k in keys)]


_verbose_default = False


@contextlib.contextmanager
def capture_output(what: str, verbose: bool | None = None) -> Iterator[_Capture]:
    """Redirect file descriptors 1 and 2 (Blender prints from C) to a temporary file while the block
    runs; the lines go to the ``blendify_blender`` logger (DEBUG), and to stderr when ``verbose``.

    Restores the descriptors whatever happens (KeyboardInterrupt included). Nested use is a no-op."""
    cap = _Capture()
    if getattr(_local, "depth", 0) > 0:
        _local.depth += 1
        try:
            yield cap
        finally:
            _local.depth -= 1
        return
    verbose = _verbose_default if verbose is None else verbose
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except Exception:  # closed or replaced streams: nothing to flush
        pass
    tmp = tempfile.TemporaryFile(mode="w+b")
    saved: list[tuple[int, int]] = []
    try:
        for fd in (1, 2):
            try:
                saved.append((fd, os.dup(fd)))
            except OSError:
                continue
            os.dup2(tmp.fileno(), fd)
    except OSError:  # pragma: no cover - unusual descriptor setups: run without capture
        pass
    _local.depth = 1
    try:
        yield cap
    finally:
        _local.depth = 0
        for fd, copy in saved:
            with contextlib.suppress(OSError):
                os.dup2(copy, fd)
            with contextlib.suppress(OSError):
                os.close(copy)
        with contextlib.suppress(Exception):
            tmp.seek(0)
            cap.text = tmp.read().decode("utf-8", "replace")
        tmp.close()
        for line in cap.lines:
            log.debug("blender[%s]: %s", what, line)
            if verbose:
                sys.stderr.write(f"[blender] {line}\n")


_local = threading.local()


@contextlib.contextmanager
def engine_errors(what: str, capture: _Capture | None = None) -> Iterator[None]:
    """Turn any non-blendify exception raised inside bpy into :class:`RenderError` carrying Blender's
    own message (and the error lines it printed)."""
    try:
        yield
    except BlendifyError:
        raise
    except (KeyboardInterrupt, SystemExit, GeneratorExit):
        raise
    except Exception as exc:
        msg = str(exc).strip() or type(exc).__name__
        extra = [ln for ln in (capture.error_lines() if capture else []) if ln not in msg]
        if extra:
            msg += " | " + " | ".join(extra[-5:])
        raise RenderError(f"cycles: {what} failed: {msg}") from exc


def datablock_counts() -> dict[str, int]:
    """Number of datablocks per bpy.data collection (to check that nothing leaks)."""
    bpy = bpy_module()
    return {name: len(getattr(bpy.data, name)) for name in (*_COLLECTIONS, "scenes")}


@contextlib.contextmanager
def defer_keyboard_interrupt() -> Iterator[None]:
    """Hold Ctrl-C (SIGINT) until the block is done, then raise KeyboardInterrupt.

    Cycles cannot be cancelled from the bpy module: a render runs to its end anyway. Deferring the
    interrupt to the end of the block keeps file descriptors, the temporary directory, the lock and the
    translation cache consistent, so the backend stays usable. Only the main thread receives signals;
    elsewhere this is a no-op. (With ``isolate=True`` Ctrl-C is immediate: the worker is killed.)"""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []

    def _handler(signum: int, frame: Any) -> None:
        received.append(signum)
        log.warning("cycles: Ctrl-C received; stopping after the current render step")

    try:
        old = signal.signal(signal.SIGINT, _handler)
    except (ValueError, OSError):  # pragma: no cover - not the main interpreter
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
        if received:
            if callable(old) and old is not signal.default_int_handler:
                old(signal.SIGINT, None)
            else:
                raise KeyboardInterrupt


#: Cycles' GPU compute backends, preferred first (``device="gpu"`` takes the first with a device)
GPU_TYPES = ("OPTIX", "CUDA", "HIP", "METAL", "ONEAPI")


def _cycles_prefs() -> Any:
    return bpy_module().context.preferences.addons["cycles"].preferences


def list_gpu_devices() -> list[tuple[str, str]]:
    """(compute type, device name) of every GPU device Cycles finds here, in :data:`GPU_TYPES` order.

    The one place devices are enumerated: ``CyclesBackend.device_choice`` and ``blendify info`` call it
    through this module, so a test can replace it with a faked list."""
    try:
        prefs = _cycles_prefs()
    except Exception as exc:  # noqa: BLE001 - depends on the build
        log.debug("cycles: the Cycles preferences are unavailable (%s): no GPU", exc)
        return []
    found: list[tuple[str, str]] = []
    with capture_output("list GPU devices"):  # Cycles prints a line per missing driver library
        for kind in GPU_TYPES:
            try:
                prefs.compute_device_type = kind
                prefs.get_devices()
            except Exception:  # noqa: BLE001 - a compute type this build does not have
                continue
            found += [(kind, str(d.name)) for d in prefs.devices if d.type == kind]
    return found


def enable_gpu(kind: str) -> str:
    """Enable Cycles' ``kind`` devices (called after every factory reset, which forgets the preferences);
    returns ``kind``, or '' (CPU, logged) when Blender refuses it."""
    try:
        prefs = _cycles_prefs()
        prefs.compute_device_type = kind
        prefs.get_devices()
        for d in prefs.devices:
            d.use = d.type == kind
    except Exception as exc:  # noqa: BLE001 - reported, rendered on the CPU
        log.warning("cycles: enabling %s devices failed (%s); rendering on the CPU", kind, exc)
        return ""
    return kind


# ---------------------------------------------------------------------------------------------------
# the translated scene: datablock bookkeeping
# ---------------------------------------------------------------------------------------------------


@dataclass
class _Entry:
    """The datablocks of one renderable (or of the lights / world / camera)."""

    objects: list[Any] = field(default_factory=list)
    data: list[tuple[str, Any]] = field(default_factory=list)  # (bpy.data collection name, ID)
    offset: np.ndarray | None = None  # object-space centre folded into the object matrix
    timings: dict[str, float] = field(default_factory=dict)  # seconds per build step (benchmarks)
    ids: list[Any] = field(default_factory=list)  # any other datablocks (removed with batch_remove)

    def add(self, collection: str, block: Any) -> Any:
        self.data.append((collection, block))
        return block

    def remove(self) -> None:
        bpy = bpy_module()
        for obj in self.objects:
            try:
                bpy.data.objects.remove(obj, do_unlink=True)
            except ReferenceError:
                pass
        for coll, block in reversed(self.data):
            try:
                getattr(bpy.data, coll).remove(block, do_unlink=True)
            except (ReferenceError, RuntimeError):
                pass
        alive = []
        for block in self.ids:
            try:
                _ = block.name
                alive.append(block)
            except ReferenceError:
                pass
        if alive:
            bpy.data.batch_remove(alive)
        self.objects.clear()
        self.data.clear()
        self.ids.clear()


@dataclass
class BuiltScene:
    """The bpy scene built for one IR scene, with every datablock created for it."""

    bscene: Any
    entries: dict[int, _Entry] = field(default_factory=dict)  # renderable uid -> entry
    lights: _Entry = field(default_factory=_Entry)
    world: _Entry = field(default_factory=_Entry)
    camera: _Entry = field(default_factory=_Entry)
    compositor: _Entry = field(default_factory=_Entry)
    attached: _Entry = field(default_factory=_Entry)
    #: primitive meshes shared by every primitive of the same shape (materials linked per object)
    shared: _Entry = field(default_factory=_Entry)
    shared_meshes: dict[tuple[Any, ...], tuple[Any, np.ndarray | None]] = field(default_factory=dict)
    #: materials with a uniform colour, shared by every object using the same (material, colour)
    shared_materials: dict[tuple[Any, ...], tuple[Any, Any]] = field(default_factory=dict)
    generation: int = -1
    engine_settings: dict[str, Any] = field(default_factory=dict)
    instance_tags: list[str] = field(default_factory=list)
    #: what the last translation did (``result.meta["translation"]``)
    stats: dict[str, Any] = field(default_factory=dict)
    #: attached .blend files linked into the scene (blendfile.linking.FileContent), the uids of the IR
    #: lights and the (path, scene) of the world rendered from them
    file_contents: list[Any] = field(default_factory=list)
    file_lights: frozenset[int] = frozenset()
    file_world: tuple[str, str] | None = None

    @property
    def camera_object(self) -> Any:
        return self.camera.objects[0] if self.camera.objects else None

    def all_entries(self) -> list[_Entry]:
        return [
            *self.entries.values(),
            self.lights,
            self.world,
            self.camera,
            self.compositor,
            self.attached,
            self.shared,
        ]

    def remove(self) -> None:
        """Delete every datablock this scene created (objects first)."""
        for e in self.all_entries():
            e.remove()
        self.entries.clear()
        self.shared_meshes.clear()
        self.shared_materials.clear()


# ---------------------------------------------------------------------------------------------------
# the session: one cached translation, updated from the core's change detection
# ---------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TranslatedScene:
    """What :meth:`CyclesSession.translate` returns (the backend's native scene): the built bpy scene and
    what it was translated from. Rendering it translates ``scene`` again when another translation ran in
    between (another thread's, a .blend export's, a reset), so a render always shows its own scene."""

    built: BuiltScene
    scene: Scene
    settings: RenderSettings
    token: int


def _world_extra(scene: Scene) -> tuple[Any, ...]:
    """What the core's ``world_state`` does not follow (yet) and the world depends on: the environment map's
    rotation and colour space, and the lights collection's revision (a new environment map may get the
    ``id`` of the one it replaces)."""
    env = scene.lights.environment
    return (scene.lights.revision, None if env is None else (tuple(env.quaternion), env.color_space))


class CyclesSession:
    """Keeps one translated scene in the bpy session and updates it from the core's :class:`SceneChanges`.

    A different IR scene (another renderables collection) resets bpy to factory settings and removes
    everything; the same scene only gets what changed (see the module docstring). Call with
    :data:`BPY_LOCK` held (the public methods take it)."""

    def __init__(self, translator_class: type[CyclesTranslator], device: str = "CPU", gpu_setup: Any = None) -> None:
        self.translator_class = translator_class
        self.built: BuiltScene | None = None
        self.tracker = ChangeTracker()
        self._scene_ref: Any = None
        self._world_extra: Any = None
        self._token = 0
        self.device = device
        #: called after every factory reset when device == "GPU" (the reset forgets the preferences);
        #: returns the compute device type enabled, or "" to fall back to the CPU
        self.gpu_setup = gpu_setup
        self.compute_device_type = ""
        self.last_stats: dict[str, Any] = {}

    # -- state -----------------------------------------------------------------------------------------
    def _same_scene(self, scene: Scene) -> bool:
        if self.built is None or self._scene_ref is None or self.built.generation != generation():
            return False
        if self._scene_ref() is not scene.renderables:
            return False
        if not self._alive():
            # someone else reset or replaced the bpy session: the cached datablocks are gone
            self._forget()
            return False
        return True

    def _alive(self) -> bool:
        """Whether the cached datablocks still exist (cheap spot check)."""
        built = self.built
        if built is None:
            return False
        try:
            if bpy_module().context.scene != built.bscene:
                return False
            for entry in [built.camera, *list(built.entries.values())[:1]]:
                for obj in entry.objects:
                    _ = obj.name
        except ReferenceError:
            return False
        return True

    def _forget(self) -> None:
        self.built = None
        self._scene_ref = None
        self._world_extra = None
        self.tracker.reset()
        self._token += 1

    def clear(self) -> None:
        """Remove every datablock of the cached scene (the bpy session is left empty, not reset)."""
        with BPY_LOCK:
            if self.built is not None and self.built.generation == generation() and self._alive():
                self.built.remove()
                bpy = bpy_module()
                for img in list(bpy.data.images):  # created by our renders ("Render Result", "Viewer Node")
                    if img.type in ("RENDER_RESULT", "COMPOSITING"):
                        bpy.data.images.remove(img)
                try:
                    bpy.data.orphans_purge(do_recursive=True)
                except Exception:  # pragma: no cover - best effort
                    pass
            self._forget()

    # -- translation -----------------------------------------------------------------------------------
    def translate(self, scene: Scene, settings: RenderSettings, verbose: bool = False) -> TranslatedScene:
        """Bring the bpy scene in line with ``scene`` and ``settings``."""
        with BPY_LOCK:
            with capture_output("translate", verbose) as cap, engine_errors("translating", cap):
                built = self.sync(scene, settings)
            return TranslatedScene(built, scene, settings, self._token)

    def current(self, native: TranslatedScene, verbose: bool = False) -> BuiltScene:
        """The BuiltScene of ``native``, translated again if anything else was translated since. Hold
        :data:`BPY_LOCK` from this call to the end of the render."""
        if native.token != self._token or native.built is not self.built or native.built.generation != generation():
            log.debug("cycles: the bpy scene changed since this scene was translated; translating it again")
            native = self.translate(native.scene, native.settings, verbose)
        return native.built

    def sync(self, scene: Scene, settings: RenderSettings) -> BuiltScene:
        """Translate what changed since the last call (everything for a new scene); returns the BuiltScene."""
        translator_class = self.translator_class
        translator_class.check_scene(scene)
        bpy = bpy_module()
        new_scene = not self._same_scene(scene)
        if new_scene:
            self.clear()
            factory_reset()
            if self.device == "GPU" and self.gpu_setup is not None:
                self.compute_device_type = self.gpu_setup()
            self.built = BuiltScene(bscene=bpy.context.scene, generation=generation())
            self._scene_ref = weakref.ref(scene.renderables)
        built = self.built
        if built is None:  # set just above for a new scene; an internal invariant
            raise RenderError("cycles: the translated scene is missing (internal error)")
        changes = self.tracker.update(scene)
        world_extra = _world_extra(scene)
        if world_extra != self._world_extra and not changes.world:
            changes = replace(changes, world=True)
        device = "GPU" if (self.device == "GPU" and self.compute_device_type) else "CPU"
        translator = translator_class(built, settings, device=device, compute_device_type=self.compute_device_type)
        ctx = TranslationContext()
        try:
            stats = translator.translate(scene, changes, ctx)
        except BaseException:
            # a half-updated scene (error or Ctrl-C) is never reused
            self.clear()
            raise
        self._world_extra = world_extra
        self._token += 1
        stats["new_scene"] = new_scene
        built.stats = stats
        self.last_stats = stats
        return built
