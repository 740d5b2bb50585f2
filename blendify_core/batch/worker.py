"""The code that runs one batch job in a worker (a pool process, a Ray task, a Dask/submitit task).

A job arrives as a plain dict of JSON-like values plus, at most, the bytes of a portable scene file:
no engine object ever crosses a process boundary. The worker loads the scene, renders it with
``bf.render`` (so the process-wide shared backend instance stays warm from job to job), writes the
outputs atomically and returns a small dict describing what happened.

Local pool workers are fresh interpreters started by ``blendify_core.batch`` as
``python -c BOOTSTRAP FD blendify-batch-worker``: :data:`BOOTSTRAP` (standard library only) opens the
connection on file descriptor (Windows: handle) FD, takes the parent's ``sys.path`` as the first message
and runs :func:`pool_main`. Unlike multiprocessing's "spawn", it never imports the parent's ``__main__``,
so a script without an ``if __name__ == "__main__":`` guard, ``python -``, ``python -c`` and notebooks
can all call ``render_many``.
"""

from __future__ import annotations

import os
import socket
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from blendify_core import registry as backend_mod
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.render import choose_backend, render
from blendify_core.pipeline.result import RenderResult
from blendify_core.registry import close_backends, shared_backend

if TYPE_CHECKING:  # annotations only: the parent process need not load multiprocessing
    from multiprocessing.connection import Connection

__all__ = [
    "run_job",
    "run_ray_job",
    "StartClock",
    "pool_main",
    "output_files",
    "save_outputs",
    "rss_mb",
    "BOOTSTRAP",
    "in_pool_worker",
]

#: what a local pool worker runs (``python -c BOOTSTRAP FD LABEL``). Standard library only until the
#: parent's ``sys.path`` is in place; an import error is sent to the parent (then the traceback goes to
#: stderr and the process exits with code 1), so the parent can say why the worker could not start.
BOOTSTRAP = """\
import signal, sys
signal.signal(signal.SIGINT, signal.SIG_IGN)
from multiprocessing import connection
conn = (connection.PipeConnection if sys.platform == "win32" else connection.Connection)(int(sys.argv[1]))
sys.path[:] = conn.recv()
try:
    from blendify_core.batch.worker import pool_main
except Exception as exc:
    conn.send(("error", f"{type(exc).__name__}: {exc}"))
    raise
pool_main(conn)
"""

_IN_POOL_WORKER = False


def in_pool_worker() -> bool:
    """True inside a local pool worker process (render_many refuses to start a pool from there)."""
    return _IN_POOL_WORKER


def rss_mb() -> float | None:
    """Resident set size of this process in MiB (Linux /proc; peak RSS elsewhere), None if unknown."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    try:
        import resource
        import sys

        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        return peak / (1024.0 * 1024.0) if sys.platform == "darwin" else peak / 1024.0
    except (ImportError, OSError):
        return None


def output_files(output: str, outputs: tuple[str, ...] | list[str]) -> list[str]:
    """The files a job writes: ``output`` itself and, for images (.png/.exr), one ``<stem>.<name><suffix>``
    per extra requested output (a ``.npz`` output holds every requested output in one file)."""
    p = Path(output)
    if p.suffix.lower() == ".npz":
        return [str(p)]
    primary = "rgb" if "rgb" in outputs else outputs[0]
    files = [str(p)]
    files += [str(p.with_name(f"{p.stem}.{name}{p.suffix}")) for name in outputs if name != primary]
    return files


def save_outputs(result: RenderResult, output: str, outputs: tuple[str, ...]) -> list[str]:
    """Write ``result`` as a batch job does (see :func:`output_files`); the files written."""
    files = output_files(output, outputs)
    if Path(output).suffix.lower() == ".npz":
        result.save(output)
        return files
    primary = "rgb" if "rgb" in outputs else outputs[0]
    names = [primary] + [n for n in outputs if n != primary]
    for name, path in zip(names, files):
        result.save(path, output=name)
    return files


def _load_scene(payload: dict[str, Any]) -> Scene:
    data = payload.get("scene_bytes")
    if data is None:
        return Scene.load(payload["scene_path"], allow_outside=bool(payload.get("allow_outside")))
    import tempfile

    fd, tmp = tempfile.mkstemp(prefix="blendify-job-", suffix=".npz")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        # written by render_many with absolute texture paths: reading them is intended
        return Scene.load(tmp, allow_outside=True)
    finally:
        os.unlink(tmp)


def _register(registrations: dict[str, str] | None) -> None:
    if not registrations:
        return
    for name, target in registrations.items():
        if name not in backend_mod._entry_points():
            backend_mod.register_backend(name, target)


def _drop_blender_script_paths() -> None:
    """A parent process that imported ``bpy`` hands Blender's script folders on ``sys.path`` to the
    children it spawns; there the pure-Python ``bpy`` package in ``bpy/<version>/scripts/modules``
    shadows the ``bpy`` extension module ("No module named '_bpy'"). Drop them before ``bpy`` is
    imported here (importing it adds them back in the right order)."""
    if "bpy" in sys.modules:
        return
    keep = []
    for entry in sys.path:
        norm = entry.replace("\\", "/") + "/"
        if "/scripts/" in norm and ("/bpy/" in norm or "/blender/" in norm.lower()):
            continue
        keep.append(entry)
    sys.path[:] = keep


def run_job(payload: dict[str, Any], on_start: Callable[[], None] | None = None) -> dict[str, Any]:
    """Render one job described by ``payload`` (built by ``blendify_core.batch.run``) and write its outputs.

    Never raises for a failed render: returns ``{"status": "failed", "reason": ...}``. A render that ends
    after ``payload["timeout"]`` seconds is reported as a timeout and its outputs are NOT written, so an
    abandoned job can never write behind the manifest's back.
    """
    t0 = time.perf_counter()
    info: dict[str, Any] = {"index": payload.get("index"), "pid": os.getpid(), "host": socket.gethostname()}
    try:
        _drop_blender_script_paths()
        _register(payload.get("registrations"))
        scene = _load_scene(payload)
        settings = dict(payload.get("settings") or {})
        options = dict(payload.get("options") or {})
        name = payload.get("backend")
        if name is None:
            name, _ = choose_backend(settings.get("quality", "final"))
        shared_backend(name, **options)  # warm up (engine import, context) before the clock starts
        if on_start is not None:
            on_start()
        timeout = payload.get("timeout")
        t_start = time.perf_counter()
        result = render(scene, backend=name, **settings, **options)
        elapsed = time.perf_counter() - t_start
        if timeout is not None and elapsed > float(timeout):
            info.update(
                status="failed",
                reason=f"timeout: the render took {elapsed:.1f} s > {float(timeout):g} s (outputs not written)",
            )
        else:
            outputs = tuple(result.meta.get("settings", {}).get("outputs") or settings.get("outputs") or ("rgb",))
            info.update(status="done", files=save_outputs(result, payload["output"], outputs))
        info["backend"] = result.meta.get("backend", name)
        info["render_seconds"] = elapsed
    except Exception as exc:  # reported per job; the worker and the run go on
        msg = str(exc).strip().splitlines()
        info.update(status="failed", reason=f"{type(exc).__name__}: {msg[0] if msg else ''}".rstrip(": "))
    info["seconds"] = time.perf_counter() - t0
    info["rss_mb"] = rss_mb()
    return info


class StartClock:
    """Where Ray tasks record when their render starts (used as a zero-CPU Ray actor), so the driver
    can time jobs out from the real start rather than from submission."""

    def __init__(self) -> None:
        self._starts: dict[int, float] = {}

    def started(self, index: int) -> None:
        self._starts[index] = time.time()

    def starts(self) -> dict[int, float]:
        return dict(self._starts)


def run_ray_job(payload: dict[str, Any], clock: Any = None) -> dict[str, Any]:
    """:func:`run_job` for a Ray task: reports the render's start to the driver's :class:`StartClock`."""
    index = payload.get("index")
    on_start = None if clock is None else (lambda: clock.started.remote(index))
    return run_job(payload, on_start=on_start)


def pool_main(conn: Connection) -> None:
    """Main loop of a local pool worker process: receive a job dict, send ``("start", index)`` when the
    render starts and ``("result", index, info)`` when it ends; ``None`` (or the parent going away) ends
    the loop. Ctrl-C is left to the parent, which stops the workers itself."""
    import signal

    global _IN_POOL_WORKER
    _IN_POOL_WORKER = True
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        conn.send(("ready", os.getpid(), rss_mb()))
        while True:
            try:
                payload = conn.recv()
            except (EOFError, OSError):
                break
            if payload is None:
                break
            index = payload.get("index")

            def started(index: object = index) -> None:
                conn.send(("start", index))

            info = run_job(payload, on_start=started)
            try:
                conn.send(("result", index, info))
            except (BrokenPipeError, OSError):
                break
    finally:
        try:
            close_backends()
        finally:
            conn.close()
