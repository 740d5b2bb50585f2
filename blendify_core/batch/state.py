"""The bookkeeping of one :func:`~blendify_core.batch.run.render_many` run, shared by every executor:
building a job's payload for a worker, finishing jobs (manifest record, progress bar, status).
"""

from __future__ import annotations

import datetime
import os
import shutil
import socket
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol

from blendify_core import registry as backend_mod
from blendify_core.batch.jobs import STATUSES, JobStatus, RenderJob
from blendify_core.batch.manifest import Manifest

__all__ = ["BatchRun", "ProgressBar", "STARTUP_TIMEOUT", "cpu_count"]

#: a worker that received a job but did not start rendering within this many seconds is given up on
STARTUP_TIMEOUT = 300.0


class ProgressBar(Protocol):
    """What the run needs of a progress bar (a tqdm bar)."""

    def update(self, n: int = 1) -> object: ...

    def set_postfix(self, ordered_dict: Mapping[str, object] | None = None, refresh: bool = True) -> None: ...

    def close(self) -> None: ...


def cpu_count() -> int:
    """The cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


class BatchRun:
    """State shared by the executors: payload building, finishing jobs (manifest + progress + report)."""

    def __init__(
        self,
        jobs: list[RenderJob],
        keys: dict[int, str],
        fingerprints: dict[int, str],
        manifest: Manifest | None,
        bar: ProgressBar | None,
        timeout: float | None,
    ) -> None:
        self.jobs = jobs
        self.keys = keys
        self.fingerprints = fingerprints
        self.manifest = manifest
        self.bar = bar
        self.timeout = timeout
        self.statuses: dict[int, JobStatus] = {}
        self.counts = dict.fromkeys(STATUSES, 0)
        self.tmpdir: str | None = None
        self.registrations = _registrations()

    # payloads ------------------------------------------------------------------------------------
    def payload(self, index: int, threads: int | None, scene_as: str) -> dict[str, Any]:
        job = self.jobs[index]
        settings = dict(job.setting_kwargs)
        if threads is not None and settings.get("threads") is None:
            settings["threads"] = threads
        p: dict[str, Any] = {
            "index": index,
            "output": job.output,
            "backend": job.backend,
            "settings": settings,
            "options": dict(job.options),
            "timeout": self.timeout,
            "registrations": self.registrations,
            "allow_outside": job.allow_outside,
        }
        if job.scene is None:
            p["scene_path"] = job.scene_path
            return p
        if self.tmpdir is None:
            self.tmpdir = tempfile.mkdtemp(prefix="blendify-batch-")
        path = os.path.join(self.tmpdir, f"job{index}.npz")
        job.scene.save(path, relative_paths=False)
        if scene_as == "bytes":
            with open(path, "rb") as f:
                p["scene_bytes"] = f.read()
            os.unlink(path)
        else:
            p["scene_path"] = path
            p["allow_outside"] = True  # a file we wrote with absolute texture paths
        return p

    def release(self, index: int) -> None:
        if self.tmpdir is not None:
            path = os.path.join(self.tmpdir, f"job{index}.npz")
            if os.path.exists(path):
                os.unlink(path)

    # finishing -----------------------------------------------------------------------------------
    def finish(self, index: int, info: dict[str, Any]) -> None:
        if index in self.statuses:
            return
        job = self.jobs[index]
        status = info.get("status", "failed")
        if status not in ("done", "failed"):
            status, info = "failed", {**info, "reason": f"unexpected worker answer {status!r}"}
        reason = None if status == "done" else str(info.get("reason") or "unknown failure")
        files = list(info.get("files") or []) if status == "done" else []
        if status == "failed":
            _remove_partial(job.files())
        worker = None
        if info.get("pid") is not None:
            worker = f"{info.get('host') or socket.gethostname()}:{info['pid']}"
        st = JobStatus(
            index=index,
            output=job.output,
            status=status,
            reason=reason,
            key=self.keys.get(index),
            backend=info.get("backend") or job.backend,
            seconds=info.get("seconds"),
            worker=worker,
            rss_mb=info.get("rss_mb"),
            files=files,
        )
        self.statuses[index] = st
        self.release(index)
        if self.manifest is not None and st.key is not None:
            self.manifest.add(
                {
                    "key": st.key,
                    "status": status,
                    "reason": reason,
                    "output": job.output,
                    "files": files,
                    "scene": job.scene_path,
                    "fingerprint": self.fingerprints.get(index),
                    "backend": st.backend,
                    "settings": job.setting_kwargs,
                    "options": job.options,
                    "seconds": st.seconds,
                    "render_seconds": info.get("render_seconds"),
                    "worker": worker,
                    "rss_mb": st.rss_mb,
                    "time": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                }
            )
        self.tick(status)

    def skip(self, index: int, record: dict[str, Any]) -> None:
        job = self.jobs[index]
        self.statuses[index] = JobStatus(
            index=index,
            output=job.output,
            status="skipped",
            key=self.keys.get(index),
            backend=record.get("backend"),
            files=list(record.get("files") or []),
        )
        self.tick("skipped")

    def tick(self, status: str) -> None:
        self.counts[status] += 1
        if self.bar is not None:
            self.bar.update(1)
            self.bar.set_postfix(self.counts, refresh=False)

    def cleanup(self) -> None:
        if self.tmpdir is not None:
            shutil.rmtree(self.tmpdir, ignore_errors=True)
            self.tmpdir = None


def _registrations() -> dict[str, str]:
    """Backends registered at run time in this process, as "module:Class" strings a worker can import."""
    out = {}
    for name, target in backend_mod._registered.items():
        if isinstance(target, str):
            out[name] = target
        elif isinstance(target, type) and target.__module__ != "__main__" and "<locals>" not in target.__qualname__:
            out[name] = f"{target.__module__}:{target.__qualname__}"
    return out


def _remove_partial(files: list[str]) -> None:
    """Remove temporary files a killed worker left behind (``atomic_write`` names them ``.<name>.*``)."""
    for f in files:
        p = Path(f)
        if not p.parent.is_dir():
            continue
        for tmp in p.parent.glob(f".{p.name}.*{p.suffix}"):
            try:
                tmp.unlink()
            except OSError:
                pass
