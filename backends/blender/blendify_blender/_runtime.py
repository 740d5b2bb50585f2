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

    Also forces Python auto-execution off (the factory default) so nothing loaded later runs scripts."""
    global _generation
    bpy = bpy_module()
    with BPY_LOCK, capture_output("factory reset"):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        _generation += 1
        with contextlib.suppress(Exception):
            bpy.context.preferences.filepaths.use_scripts_auto_execute = False
        if not hasattr(bpy.context.scene, "cycles"):
            # seen once: the Cycles add-on not re-registered after the reset; register it again
            import addon_utils

            log.warning("cycles: the Cycles add-on was not registered after a factory reset; enabling it")
            addon_utils.enable("cycles", default_set=True)
            if not hasattr(bpy.context.scene, "cycles"):
                raise RenderError("cycles: the Cycles add-on is not available in this bpy session")


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
    "scenes",
)


def datablock_counts() -> dict[str, int]:
    """Number of datablocks per bpy.data collection (to check that nothing leaks)."""
    bpy = bpy_module()
    return {name: len(getattr(bpy.data, name)) for name in _COLLECTIONS}
