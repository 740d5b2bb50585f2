"""``isolate=True``: render in a persistent worker subprocess.

Blender keeps some memory it never frees, and a crash inside it would take the caller down; the worker
holds bpy instead. The scene travels as a portable scene file (``Scene.save`` / ``Scene.load``), the
result comes back as an ``.npz``; requests and replies are JSON lines on the worker's stdin and on a
duplicate of its original stdout (Blender's own stdout noise goes to a log file). The worker is
restarted after ``max_renders`` renders, after a crash, and after Ctrl-C (which kills it).

Run as ``python -m blendify_blender.worker`` (only the client does that).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np

from blendify_blender.blendfile.origins import export_origins, import_origins
from blendify_core.errors import BackendUnavailableError, BlendifyError, InvalidSceneError, RenderError
from blendify_core.ir.attachments import Attachment
from blendify_core.pipeline.result import RenderResult, _jsonable
from blendify_core.pipeline.settings import RenderSettings

__all__ = ["IsolatedScene", "WorkerClient", "main"]

_ARRAYS = ("rgba", "depth", "normal", "albedo", "instance")
_ERRORS = {
    "RenderError": RenderError,
    "InvalidSceneError": InvalidSceneError,
    "BackendUnavailableError": BackendUnavailableError,
}


def _settings_from_dict(d: dict[str, Any]) -> RenderSettings:
    d = dict(d)
    d["outputs"] = tuple(d["outputs"])
    return RenderSettings(**d)


def _save_result(result: RenderResult, path: str) -> None:
    arrays = {k: getattr(result, k) for k in _ARRAYS if getattr(result, k) is not None}
    arrays["instance_tags"] = np.array(result.instance_tags, dtype=str)
    arrays["meta"] = np.array(json.dumps(_jsonable(result.meta)))
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def _load_result(path: str) -> RenderResult:
    with np.load(path, allow_pickle=False) as z:
        result = RenderResult(**{k: np.array(z[k]) for k in _ARRAYS if k in z.files})
        result.instance_tags = [str(t) for t in z["instance_tags"]]
        result.meta = json.loads(str(z["meta"]))
    return result


@dataclass(frozen=True)
class IsolatedScene:
    """What ``CyclesBackend.translate`` returns with ``isolate=True``: the IR scene, which the worker process
    translates and renders (nothing touches bpy in this process)."""

    scene: Any


class WorkerClient:
    """Owns one worker process and a private temporary directory (removed by :meth:`close`)."""

    def __init__(self, max_renders: int = 100, verbose: bool = False, device: str = "CPU") -> None:
        self.max_renders = max_renders
        self.verbose = verbose
        self.device = device
        self._proc: subprocess.Popen[str] | None = None
        self._renders = 0
        self._dir = tempfile.mkdtemp(prefix="blendify_cycles_worker_")
        self._log_path = os.path.join(self._dir, "worker.log")
        self._lock = threading.Lock()
        self.restarts = 0

    # -- process management ------------------------------------------------------------------------
    def _start(self) -> subprocess.Popen[str]:
        # same interpreter and environment: blendify_core / blendify_blender import as they do here (the
        # parent's sys.path is not passed on: after importing bpy it holds Blender's script folders,
        # whose 'bpy' package would shadow the bpy module in the child)
        env = dict(os.environ)
        # verbose: the worker's Blender lines go straight to our stderr; otherwise to a log file
        log: Any = None if self.verbose else open(self._log_path, "ab")  # noqa: SIM115 - closed below
        try:
            proc = subprocess.Popen(
                [sys.executable, "-m", "blendify_blender.worker", "--device", self.device]
                + (["--verbose"] if self.verbose else []),
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=log,
                text=True,
                bufsize=1,
                env=env,
                start_new_session=True,  # a terminal Ctrl-C reaches the parent only; the parent kills us
            )
        finally:
            if log is not None:
                log.close()
        self._renders = 0
        self.restarts += 1
        return proc

    def _stop(self, kill: bool = False) -> None:
        proc, self._proc = self._proc, None
        if proc is None:
            return
        try:
            if not kill and proc.poll() is None and proc.stdin is not None:
                proc.stdin.write(json.dumps({"cmd": "close"}) + "\n")
                proc.stdin.flush()
                proc.wait(timeout=10)
        except (OSError, subprocess.TimeoutExpired, ValueError):
            pass
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for stream in (proc.stdin, proc.stdout):
            try:
                if stream is not None:
                    stream.close()
            except OSError:
                pass

    def _log_tail(self, n: int = 15) -> str:
        try:
            with open(self._log_path, encoding="utf-8", errors="replace") as f:
                lines = [ln.rstrip() for ln in f.readlines() if ln.strip()]
        except OSError:
            return ""
        return "\n".join(lines[-n:])

    @property
    def pid(self) -> int | None:
        return None if self._proc is None else self._proc.pid

    # -- rendering ---------------------------------------------------------------------------------
    def render(self, scene: Any, settings: RenderSettings) -> RenderResult:
        with self._lock:
            if self._proc is not None and (self._proc.poll() is not None or self._renders >= self.max_renders):
                self._stop()
            if self._proc is None:
                self._proc = self._start()
            scene_path = os.path.join(self._dir, "scene.npz")
            out_path = os.path.join(self._dir, "result.npz")
            for p in (scene_path, out_path):
                if os.path.exists(p):
                    os.remove(p)
            scene.save(scene_path, relative_paths=False)
            request = {
                "cmd": "render",
                "scene": scene_path,
                "settings": _jsonable(settings.to_dict()),
                "out": out_path,
                "attached_blends": list(scene.attached_blends),  # not in scene files
                "origins": export_origins(scene),  # what renders from the attached files (blendfile.origins)
            }
            proc = self._proc
            if proc.stdin is None or proc.stdout is None:  # started without pipes: cannot talk to it
                raise RenderError("cycles: the isolated render worker has no stdin/stdout pipe")
            try:
                proc.stdin.write(json.dumps(request) + "\n")
                proc.stdin.flush()
                line = proc.stdout.readline()
            except KeyboardInterrupt:
                self._stop(kill=True)  # the next render starts a fresh worker
                raise
            except (BrokenPipeError, OSError) as exc:
                self._stop(kill=True)
                raise RenderError(f"cycles worker: lost the worker process ({exc}); log:\n{self._log_tail()}") from exc
            if not line:
                code = proc.poll()
                self._stop(kill=True)
                raise RenderError(
                    f"cycles worker: the worker process died (exit code {code}); log:\n{self._log_tail()}"
                )
            self._renders += 1
            reply = json.loads(line)
            if not reply.get("ok"):
                cls = _ERRORS.get(reply.get("type", ""), RenderError)
                raise cls(reply.get("error", "cycles worker: unknown error"))
            result = _load_result(out_path)
            os.remove(out_path)
            os.remove(scene_path)
            result.meta["isolated"] = {"worker_pid": proc.pid, "renders_in_worker": self._renders}
            return result

    def close(self) -> None:
        with self._lock:
            self._stop()
            shutil.rmtree(self._dir, ignore_errors=True)

    def __del__(self) -> None:  # pragma: no cover - best effort at interpreter shutdown
        try:
            self._stop(kill=True)
            shutil.rmtree(self._dir, ignore_errors=True)
        except Exception:
            pass


def main(argv: list[str] | None = None) -> int:
    """Worker loop: one JSON request per stdin line, one JSON reply per line on the protocol pipe."""
    import argparse

    parser = argparse.ArgumentParser(prog="blendify_blender.worker")
    parser.add_argument("--device", default="CPU")
    parser.add_argument("--verbose", action="store_true")
    args = parser.parse_args(argv)
    proto = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)  # anything printed to stdout (Blender, Python) goes to the log, not the protocol
    sys.stdout = sys.stderr

    from blendify_core.ir.scene import Scene

    from . import CyclesBackend

    backend = CyclesBackend(device=args.device, verbose=args.verbose)
    for line in sys.stdin:
        if not line.strip():
            continue
        req = json.loads(line)
        if req.get("cmd") == "close":
            break
        reply: dict[str, Any]
        try:
            scene = Scene.load(req["scene"], allow_outside=True)
            scene.attachments = [Attachment("blend", p) for p in req.get("attached_blends", [])]
            import_origins(scene, req.get("origins", {}))
            settings = _settings_from_dict(req["settings"])
            # device=: decided here, where bpy runs (the parent of an isolated backend never imports it)
            choice = backend.device_choice()
            if choice is not None and choice.fallback and settings.strict:
                raise BackendUnavailableError(
                    f"cycles: device={choice.requested!r} is unavailable here ({choice.fallback}); "
                    f"strict=True refuses to render on {choice.used} instead"
                )
            result = backend.render_scene(scene, settings)
            if choice is not None:
                result.meta["device"] = choice.used
                if choice.fallback:
                    result.meta["device_fallback"] = choice.fallback  # type: ignore[typeddict-unknown-key]
            _save_result(result, req["out"])
            reply = {"ok": True}
        except BlendifyError as exc:
            reply = {"ok": False, "type": type(exc).__name__, "error": str(exc)}
        except Exception as exc:
            reply = {"ok": False, "type": "RenderError", "error": f"cycles worker: {type(exc).__name__}: {exc}"}
        proto.write(json.dumps(reply) + "\n")
        proto.flush()
    backend.close()
    proto.close()
    return 0


if __name__ == "__main__":
    main()
