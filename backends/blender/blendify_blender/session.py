"""Process-level plumbing around ``bpy``: lazy import, the render lock, factory resets, Blender's stdout
noise and error wrapping.

``bpy`` is one process-global Blender session, so everything that touches it must hold :data:`BPY_LOCK`
(a re-entrant lock: the translator and the .blend helpers call each other). :func:`factory_reset` bumps
:data:`GENERATION`; cached translations compare it to know that their datablocks are gone.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import tempfile
import threading
from collections.abc import Iterator
from typing import Any

from blendify_core.errors import BackendUnavailableError, BlendifyError, RenderError

__all__ = [
    "BPY_LOCK",
    "bpy_module",
    "factory_reset",
    "generation",
    "capture_output",
    "engine_errors",
    "datablock_counts",
    "defer_keyboard_interrupt",
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
