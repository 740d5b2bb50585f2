"""Batch and distributed rendering with resume: :func:`render_many`, :class:`RenderJob`, :class:`BatchReport`.

Jobs travel to workers as portable scene files (``Scene.save``) or the path of one, plus JSON-like
settings; engine objects are never pickled. Each worker process keeps ``bf.render``'s shared backend
instance warm from job to job and writes its outputs atomically. A manifest next to the outputs records
every finished job under a key (scene fingerprint + backend + settings + output path), so running the
same batch again skips what is done and retries what failed.
"""

from __future__ import annotations

import dataclasses
import datetime
import hashlib
import json
import logging
import os
import re
import shutil
import socket
import sys
import tempfile
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from blendify_core import registry as backend_mod
from blendify_core.batch import worker as _worker
from blendify_core.batch.worker import output_files
from blendify_core.errors import BlendifyError, InvalidSceneError
from blendify_core.io.output import atomic_write
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.settings import RenderSettings, resolve_settings

__all__ = ["RenderJob", "JobStatus", "BatchReport", "render_many", "DEFAULT_RECYCLE_AFTER", "MANIFEST_NAME"]

#: jobs a local pool worker renders before it is replaced by a fresh process (engines leak memory).
#: Measured (benchmarks/results/batch.md): Mitsuba 3.9 grows ~0.37 MiB per small job, Cycles ~0.01;
#: a restart costs ~1.5-3 s (process + engine start). 250 bounds the Mitsuba growth to ~100 MiB with a
#: restart overhead under ~8% for 0.1 s frames and under 1% for 1 s frames; use ``recycle_above_mb``
#: as the safety net for scenes that leak more.
DEFAULT_RECYCLE_AFTER = 250
#: default manifest file name, written in the common folder of the outputs
MANIFEST_NAME = "blendify_manifest.jsonl"
#: a pool worker that received a job but did not start rendering within this many seconds is killed
STARTUP_TIMEOUT = 300.0

_SETTING_NAMES = {f.name for f in dataclasses.fields(RenderSettings)} - {"extra"}
_OUTPUT_SUFFIXES = (".png", ".exr", ".npz")
_STATUSES = ("done", "skipped", "failed")
log = logging.getLogger("blendify_core")


def _cpu_count() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


# ---------------------------------------------------------------------------------------------------
# jobs
# ---------------------------------------------------------------------------------------------------


class RenderJob:
    """One frame to render: a scene (a :class:`Scene` or the path of a scene file) and where to write it.

    ``output``: ``.png`` / ``.exr`` (one file per requested output: ``out.png``, ``out.depth.png``, ...)
    or ``.npz`` (every output in one file). ``backend``: a backend name, or None for the best available
    one. ``render_kwargs`` are exactly those of :func:`blendify_core.pipeline.render` (``quality``, ``samples``,
    ``seed``, ``outputs``, ``threads``, ... and backend options); they are validated here. Backend options
    must be JSON values because they travel to the workers and into the manifest. ``allow_outside``
    applies to scene files whose textures live outside the file's folder.
    """

    def __init__(
        self,
        scene_or_path: Any,
        output: str | os.PathLike[str],
        backend: str | None = None,
        *,
        allow_outside: bool = False,
        **render_kwargs: Any,
    ) -> None:
        if isinstance(scene_or_path, Scene):
            self.scene: Scene | None = scene_or_path
            self.scene_path: str | None = None
        elif isinstance(scene_or_path, (str, os.PathLike)):
            path = os.fspath(scene_or_path)
            if Path(path).suffix.lower() != ".npz":
                raise InvalidSceneError(f"scene_or_path: expected a scene file ending in .npz, got {path!r}")
            self.scene, self.scene_path = None, os.path.abspath(path)
        else:
            raise InvalidSceneError(
                f"scene_or_path: expected a blendify_core.Scene or the path of a scene file (.npz), "
                f"got {type(scene_or_path).__name__}"
            )
        if not isinstance(output, (str, os.PathLike)):
            raise InvalidSceneError(f"output: expected a file path, got {type(output).__name__}")
        out = os.path.abspath(os.fspath(output))
        if Path(out).suffix.lower() not in _OUTPUT_SUFFIXES:
            raise InvalidSceneError(f"output: expected a .png, .exr or .npz file name, got {os.fspath(output)!r}")
        self.output = out
        if backend is not None and not (isinstance(backend, str) and backend):
            raise InvalidSceneError(
                f"backend: expected a backend name or None (a backend instance cannot travel to a worker), "
                f"got {backend!r}"
            )
        self.backend = backend
        self.allow_outside = bool(allow_outside)
        for reserved in ("scene", "output"):
            if reserved in render_kwargs:
                raise InvalidSceneError(f"{reserved}: given twice to RenderJob")
        self.setting_kwargs = {k: v for k, v in render_kwargs.items() if k in _SETTING_NAMES}
        self.options = {k: v for k, v in render_kwargs.items() if k not in _SETTING_NAMES}
        if "outputs" in self.setting_kwargs and not isinstance(self.setting_kwargs["outputs"], str):
            self.setting_kwargs["outputs"] = list(self.setting_kwargs["outputs"])
        self.settings = resolve_settings(**self.setting_kwargs)  # validates every setting now
        try:
            json.dumps(self.options)
        except (TypeError, ValueError) as exc:
            raise InvalidSceneError(
                f"render_kwargs: backend options of a batch job must be JSON values ({exc}); got {self.options!r}"
            ) from None

    @property
    def render_kwargs(self) -> dict[str, Any]:
        return {**self.setting_kwargs, **self.options}

    def files(self) -> list[str]:
        """Every file this job writes."""
        return output_files(self.output, self.settings.outputs)

    @classmethod
    def from_dict(cls, d: dict[str, Any], base: str | os.PathLike[str] | None = None) -> RenderJob:
        """A job from a JSON object ``{"scene": "a.npz", "output": "a.png", "backend": ..., **render_kwargs}``;
        relative paths resolve against ``base`` (the folder of the JSON-lines file)."""
        if not isinstance(d, dict):
            raise InvalidSceneError(f"job: expected a JSON object, got {type(d).__name__}")
        d = dict(d)
        for required in ("scene", "output"):
            if required not in d:
                raise InvalidSceneError(f"job: missing {required!r} in {d!r}")
        scene, output = d.pop("scene"), d.pop("output")
        if not isinstance(scene, str) or not isinstance(output, str):
            raise InvalidSceneError(f"job: 'scene' and 'output' must be path strings, got {scene!r}, {output!r}")
        if base is not None:
            scene = os.path.join(os.fspath(base), scene)
            output = os.path.join(os.fspath(base), output)
        return cls(scene, output, **d)

    def __repr__(self) -> str:
        src = self.scene_path if self.scene is None else "<Scene>"
        return f"RenderJob({src}, {self.output!r}, backend={self.backend!r}, {self.render_kwargs!r})"


def read_jobs(path: str | os.PathLike[str]) -> list[RenderJob]:
    """Read a JSON-lines file of jobs (one JSON object per line, ``#`` comments and blank lines ignored)."""
    p = Path(path)
    if not p.is_file():
        raise InvalidSceneError(f"jobs: no such file {str(path)!r}")
    jobs = []
    for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        try:
            d = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InvalidSceneError(f"jobs: {str(path)!r} line {n} is not valid JSON ({exc})") from None
        try:
            jobs.append(RenderJob.from_dict(d, base=p.resolve().parent))
        except InvalidSceneError as exc:
            raise InvalidSceneError(f"jobs: {str(path)!r} line {n}: {exc}") from None
    return jobs


def _job_key(fingerprint: str, job: RenderJob) -> str:
    settings = job.settings.to_dict()
    for name in ("threads", "extra"):  # how many threads render a frame does not change the frame
        settings.pop(name, None)
    blob = json.dumps(
        {
            "fingerprint": fingerprint,
            "backend": job.backend or "auto",
            "settings": settings,
            "options": job.options,
            "output": job.output,
        },
        sort_keys=True,
    )
    return hashlib.sha256(blob.encode("utf-8")).hexdigest()


# ---------------------------------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------------------------------


@dataclass
class JobStatus:
    """What happened to one job: ``status`` is "done", "skipped" (already in the manifest, files present)
    or "failed" (``reason`` says why: an engine error, "timeout: ...", "worker crashed: ...")."""

    index: int
    output: str
    status: str
    reason: str | None = None
    key: str | None = None
    backend: str | None = None
    seconds: float | None = None
    worker: str | None = None
    rss_mb: float | None = None
    files: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclass
class BatchReport:
    """One :class:`JobStatus` per job, in job order, plus the run's context."""

    jobs: list[JobStatus]
    executor: str
    workers: int
    wall_time: float
    manifest: str | None = None

    @property
    def counts(self) -> dict[str, int]:
        out = dict.fromkeys(_STATUSES, 0)
        for j in self.jobs:
            out[j.status] += 1
        return out

    @property
    def done(self) -> list[JobStatus]:
        return [j for j in self.jobs if j.status == "done"]

    @property
    def skipped(self) -> list[JobStatus]:
        return [j for j in self.jobs if j.status == "skipped"]

    @property
    def failed(self) -> list[JobStatus]:
        return [j for j in self.jobs if j.status == "failed"]

    @property
    def ok(self) -> bool:
        """True when no job failed."""
        return not self.failed

    @property
    def statuses(self) -> list[str]:
        return [j.status for j in self.jobs]

    def __len__(self) -> int:
        return len(self.jobs)

    def __iter__(self) -> Any:
        return iter(self.jobs)

    def __getitem__(self, i: int) -> JobStatus:
        return self.jobs[i]

    def summary(self) -> str:
        c = self.counts
        rendered = c["done"]
        rate = f", {60.0 * rendered / self.wall_time:.1f} frames/min" if rendered and self.wall_time > 0 else ""
        text = (
            f"{len(self)} jobs: {c['done']} done, {c['skipped']} skipped, {c['failed']} failed "
            f"in {self.wall_time:.1f} s ({self.executor}, {self.workers} worker(s){rate})"
        )
        for j in self.failed[:20]:
            text += f"\n  failed #{j.index} {j.output}: {j.reason}"
        if len(self.failed) > 20:
            text += f"\n  ... and {len(self.failed) - 20} more failures (see the manifest)"
        return text

    def to_dict(self) -> dict[str, Any]:
        return {
            "executor": self.executor,
            "workers": self.workers,
            "wall_time": self.wall_time,
            "manifest": self.manifest,
            "counts": self.counts,
            "jobs": [j.to_dict() for j in self.jobs],
        }

    def __repr__(self) -> str:
        return f"BatchReport({self.counts}, executor={self.executor!r}, wall_time={self.wall_time:.1f}s)"


# ---------------------------------------------------------------------------------------------------
# manifest
# ---------------------------------------------------------------------------------------------------


class _Manifest:
    """Finished jobs by key. ``.jsonl``: one JSON object appended (and fsynced) per finished job, the last
    record of a key wins, a torn last line (interrupted run) is ignored. ``.json``: one JSON document
    rewritten atomically after each job. Only the parent process writes it; a lock file keeps two runs
    from sharing one manifest."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.jsonl = path.suffix.lower() != ".json"
        self.records: dict[str, dict[str, Any]] = {}
        path.parent.mkdir(parents=True, exist_ok=True)
        # .jsonl: lock the manifest itself; .json is replaced on every write, so lock a sidecar file
        self._lock_file = self._lock(path if self.jsonl else path.with_name(path.name + ".lock"))
        if path.is_file():
            self._read()
        self._fh = None
        if self.jsonl:
            self._fh = open(path, "a+", encoding="utf-8")  # noqa: SIM115 - kept open for the whole run
            self._fh.seek(0, os.SEEK_END)
            if self._fh.tell() > 0:
                self._fh.seek(self._fh.tell() - 1)
                last = self._fh.read(1)
                self._fh.seek(0, os.SEEK_END)
                if last != "\n":  # a torn line from an interrupted run: start a fresh one
                    self._fh.write("\n")

    @staticmethod
    def _lock(lock_path: Path) -> Any:
        fh = open(lock_path, "a+")  # noqa: SIM115
        try:
            import fcntl
        except ImportError:  # Windows: no advisory lock
            return fh
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            raise BlendifyError(f"manifest: {str(lock_path)!r} is in use by another render_many run") from None
        return fh

    def _read(self) -> None:
        text = self.path.read_text(encoding="utf-8")
        if self.jsonl:
            for line in text.splitlines():
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue  # torn line
                if isinstance(rec, dict) and isinstance(rec.get("key"), str):
                    self.records[rec["key"]] = rec
            return
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InvalidSceneError(f"manifest: {str(self.path)!r} is not valid JSON ({exc})") from None
        jobs = doc.get("jobs") if isinstance(doc, dict) else None
        if not isinstance(jobs, dict):
            raise InvalidSceneError(f"manifest: {str(self.path)!r} is not a blendify batch manifest")
        self.records.update(jobs)

    def finished(self, key: str) -> dict[str, Any] | None:
        """The record of ``key`` if it is done and every file it wrote still exists."""
        rec = self.records.get(key)
        if rec is None or rec.get("status") != "done":
            return None
        files = rec.get("files") or []
        if not files or not all(os.path.isfile(f) for f in files):
            return None
        return rec

    def add(self, record: dict[str, Any]) -> None:
        self.records[record["key"]] = record
        if self.jsonl:
            if self._fh is None:
                raise BlendifyError("batch manifest: add() before the manifest was opened (internal error)")
            self._fh.write(json.dumps(record, sort_keys=True) + "\n")
            self._fh.flush()
            os.fsync(self._fh.fileno())
            return
        doc = {"format": "blendify-batch-manifest", "version": 1, "jobs": self.records}

        def write(tmp: str) -> None:
            with open(tmp, "w", encoding="utf-8") as f:
                json.dump(doc, f, indent=1, sort_keys=True)
                f.flush()
                os.fsync(f.fileno())

        atomic_write(self.path, write)

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None
        if self._lock_file is not None:
            self._lock_file.close()
            self._lock_file = None


def _default_manifest(jobs: list[RenderJob]) -> Path:
    folders = sorted({os.path.dirname(j.output) for j in jobs})
    try:
        common = os.path.commonpath(folders)
    except ValueError:  # different drives
        common = folders[0]
    return Path(common) / MANIFEST_NAME


# ---------------------------------------------------------------------------------------------------
# the run
# ---------------------------------------------------------------------------------------------------


class _Run:
    """State shared by the executors: payload building, finishing jobs (manifest + progress + report)."""

    def __init__(
        self,
        jobs: list[RenderJob],
        keys: dict[int, str],
        fingerprints: dict[int, str],
        manifest: _Manifest | None,
        bar: Any,
        timeout: float | None,
    ) -> None:
        self.jobs = jobs
        self.keys = keys
        self.fingerprints = fingerprints
        self.manifest = manifest
        self.bar = bar
        self.timeout = timeout
        self.statuses: dict[int, JobStatus] = {}
        self.counts = dict.fromkeys(_STATUSES, 0)
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


def _main_description(main: Any) -> str:
    path = getattr(main, "__file__", None)
    if isinstance(path, str) and not path.startswith("<"):
        return f"the script {os.path.basename(path)}"
    return "code run from stdin, `python -c` or a notebook"


def _names_main(module: str, main: Any) -> bool:
    """True when ``module`` is the script running as ``__main__`` (importing it would run it again)."""
    spec = getattr(main, "__spec__", None)
    if spec is not None and getattr(spec, "name", None) == module:
        return True
    path = getattr(main, "__file__", None)
    if not isinstance(path, str) or path.startswith("<") or not os.path.isfile(path):
        return False
    mod = sys.modules.get(module)
    if mod is not None:
        origin = getattr(mod, "__file__", None)
    elif "." in module:  # finding a submodule would import its packages: leave those to the worker
        return False
    else:
        import importlib.util

        try:
            found = importlib.util.find_spec(module)
        except (ImportError, ValueError):
            return False
        origin = None if found is None else found.origin
    try:
        return isinstance(origin, str) and os.path.samefile(origin, path)
    except OSError:
        return False


def _check_backends_importable(jobs: list[RenderJob]) -> None:
    """Fail before any work when a job's backend is registered in a way worker processes cannot import:
    a class defined in ``__main__`` or inside a function, or a "module:Class" path naming the script
    being run (workers are fresh interpreters that never run ``__main__``)."""
    main = sys.modules.get("__main__")
    for i, job in enumerate(jobs):
        if job.backend is None:
            continue
        target = backend_mod._registered.get(job.backend)
        name = job.backend
        if isinstance(target, type):
            qual = target.__qualname__
            if target.__module__ == "__main__":
                where = f"defined in __main__ ({_main_description(main)})"
                why = "never run __main__"
            elif "<locals>" in qual:
                where = f"defined inside a function ({target.__module__}.{qual})"
                why = "import a backend class by module and name"
            else:
                continue
            cls = qual.rsplit(".", 1)[-1]
            module = re.sub(r"\W", "_", name) + "_backend"
            raise InvalidSceneError(
                f"jobs[{i}]: backend {name!r} is registered as the class {cls} {where}; render_many's worker "
                f"processes are fresh Python interpreters that {why}, so they cannot import it. Move {cls} "
                f"to the top level of a module (e.g. {module}.py next to your script) and register it by path: "
                f"bf.register_backend({name!r}, '{module}:{cls}'), or render in this process with "
                "executor=concurrent.futures.ThreadPoolExecutor(1)"
            )
        if isinstance(target, str) and main is not None:
            module, _, cls = target.partition(":")
            if _names_main(module, main):
                raise InvalidSceneError(
                    f"jobs[{i}]: backend {name!r} is registered as {target!r}, but {module!r} is "
                    f"{_main_description(main)} being run: every worker would import it and run the "
                    f"script again. Move {cls or 'the backend class'} into a module of its own and register "
                    "that path"
                )


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


def _signal_name(code: int | None) -> str:
    if code is None:
        return "unknown exit"
    if code < 0:
        import signal

        try:
            return f"killed by signal {signal.Signals(-code).name} (exit code {code})"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exited with code {code}"


# ---------------------------------------------------------------------------------------------------
# local pool
# ---------------------------------------------------------------------------------------------------


class _PoolWorker:
    """One local worker: a fresh interpreter running ``_worker.BOOTSTRAP`` (never the user's ``__main__``),
    connected to this process by a duplex multiprocessing connection on an inherited descriptor."""

    def __init__(self) -> None:
        import subprocess
        from multiprocessing import Pipe, spawn

        parent, child = Pipe(duplex=True)
        handle = child.fileno()
        kwargs: dict[str, Any] = {}
        if sys.platform == "win32":  # pragma: no cover - not exercised on the project's machines
            os.set_handle_inheritable(handle, True)
            kwargs["startupinfo"] = subprocess.STARTUPINFO(lpAttributeList={"handle_list": [handle]})
        else:
            kwargs["pass_fds"] = (handle,)
        flags = getattr(subprocess, "_args_from_interpreter_flags", list)()  # -O, -X ..., as multiprocessing does
        cmd = [spawn.get_executable(), *flags, "-c", _worker.BOOTSTRAP, str(handle), "blendify-batch-worker"]
        try:
            self.proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, close_fds=True, **kwargs)
        except OSError as exc:
            parent.close()
            raise BlendifyError(f"render_many: cannot start a worker process ({cmd[0]}): {exc}") from exc
        finally:
            child.close()
        self.conn = parent
        self.pid = self.proc.pid
        # a waitable descriptor that becomes ready when the process exits (Linux); else death shows as EOF
        self.sentinel: int | None = None
        if hasattr(os, "pidfd_open"):
            try:
                self.sentinel = os.pidfd_open(self.pid)
            except OSError:
                self.sentinel = None
        try:
            parent.send(list(sys.path))
        except OSError:
            pass  # the process is already gone: the run loop sees it exit
        self.job: int | None = None
        self.assigned_at = 0.0
        self.started_at: float | None = None
        self.retired_at = 0.0
        self.count = 0
        self.ready = False
        self.eof = False
        self.start_error: str | None = None
        self.rss_mb: float | None = None

    def alive(self) -> bool:
        return self.proc.poll() is None

    def exitcode(self) -> int | None:
        """The exit code (negative: killed by that signal), waiting up to 5 s for a process whose
        connection closed to finish exiting; None if it is still running."""
        import subprocess

        try:
            return self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            return None

    def _release(self) -> None:
        self.conn.close()
        if self.sentinel is not None:
            os.close(self.sentinel)
            self.sentinel = None

    def kill(self) -> None:
        import subprocess

        if self.alive():
            self.proc.kill()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:  # stuck in the kernel: leave it, it cannot run any more Python
            pass
        self._release()

    def retire(self) -> None:
        """Ask the worker to exit after closing its backends (without waiting for it)."""
        self.retired_at = time.monotonic()
        try:
            self.conn.send(None)
        except (OSError, ValueError):
            pass

    def reap(self, grace: float) -> bool:
        """True once a retired worker has exited (killed when it takes longer than ``grace`` seconds)."""
        if self.alive() and time.monotonic() - self.retired_at < grace:
            return False
        self.kill()
        return True


def _run_local(
    run: _Run,
    pending: list[int],
    workers: int,
    recycle_after: int | None,
    threads: int,
    recycle_above_mb: float | None = None,
) -> None:
    import subprocess
    from multiprocessing import spawn as mp_spawn
    from multiprocessing.connection import wait

    if _worker.in_pool_worker():
        raise BlendifyError(
            "render_many: called inside one of render_many's own worker processes (a module the workers "
            "import, e.g. the module of a backend registered by path, starts a batch when it is imported); "
            'guard that code with `if __name__ == "__main__":` or move the backend into a module of its own'
        )
    if getattr(sys, "frozen", False) and mp_spawn.get_executable() == sys.executable:
        raise BlendifyError(
            "render_many: the local pool starts worker processes as `python -c ...`, which a frozen application "
            "cannot run; point multiprocessing.set_executable() at a Python interpreter, or pass "
            "executor=concurrent.futures.ThreadPoolExecutor(...)"
        )
    queue = list(reversed(pending))  # pop() from the end keeps job order
    pool: list[_PoolWorker] = []
    retiring: list[_PoolWorker] = []
    startup_failures = 0
    gave_up: str | None = None  # set when workers cannot start at all: the remaining jobs fail with this

    def spawn() -> None:
        if gave_up is None:
            pool.append(_PoolWorker())

    def busy() -> list[_PoolWorker]:
        return [w for w in pool if w.job is not None]

    def fail_and_replace(w: _PoolWorker, reason: str) -> None:
        nonlocal startup_failures, gave_up
        if not w.ready:
            startup_failures += 1
            detail = f"{w.start_error}; " if w.start_error else ""
            reason = f"worker failed to start ({detail}{reason}); see the worker's stderr"
            if w.start_error is not None or startup_failures >= 3:
                # an import error, or three workers in a row died before they could take a job: every
                # further worker would die the same way, so the remaining jobs fail now with the reason
                gave_up = reason
            elif w.job is not None:  # e.g. killed while starting: the job never ran, try it again
                queue.append(w.job)
                run.release(w.job)
                w.job = None
        if w.job is not None:
            run.finish(w.job, {"status": "failed", "reason": reason, "pid": w.pid})
            w.job = None
        w.kill()
        pool.remove(w)
        if gave_up is not None:
            while queue:
                run.finish(queue.pop(), {"status": "failed", "reason": gave_up})
        elif queue and len(pool) < workers:
            spawn()

    try:
        for _ in range(min(workers, len(queue))):
            spawn()
        while queue or busy():
            if not pool and queue:
                spawn()
            now = time.monotonic()
            for w in list(pool):
                if w.job is None and queue and not w.eof and w.alive():
                    index = queue.pop()
                    try:
                        w.conn.send(run.payload(index, threads, "path"))
                    except (OSError, ValueError) as exc:  # the worker died while idle: retry on a new one
                        queue.append(index)
                        run.release(index)
                        fail_and_replace(w, f"worker crashed before the job started ({exc})")
                        continue
                    except Exception as exc:  # the scene could not be written
                        run.finish(index, {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"})
                        continue
                    w.job, w.assigned_at, w.started_at = index, now, None
            if not pool:  # every worker died before receiving work
                if queue:
                    spawn()
                continue
            deadlines = []
            for w in busy():
                if w.started_at is None:
                    deadlines.append(w.assigned_at + STARTUP_TIMEOUT)
                elif run.timeout is not None:
                    deadlines.append(w.started_at + run.timeout)
            retiring[:] = [w for w in retiring if not w.reap(30.0)]
            if retiring or any(w.sentinel is None for w in pool):
                deadlines.append(time.monotonic() + 0.5)  # poll exits that no descriptor reports
            wait_for = max(0.0, min(deadlines) - time.monotonic()) if deadlines else None
            handles: list[Any] = [w.conn for w in pool] + [w.sentinel for w in pool if w.sentinel is not None]
            ready = set(wait(handles, timeout=wait_for))
            for w in list(pool):
                if w.conn in ready:
                    try:
                        while w.conn.poll():
                            msg = w.conn.recv()
                            if msg[0] == "ready":
                                w.ready = True
                                startup_failures = 0
                            elif msg[0] == "error":
                                w.start_error = str(msg[1])
                            elif msg[0] == "start" and msg[1] == w.job:
                                w.started_at = time.monotonic()
                            elif msg[0] == "result" and msg[1] == w.job:
                                run.finish(w.job, msg[2])
                                w.job, w.started_at = None, None
                                w.count += 1
                                w.rss_mb = msg[2].get("rss_mb")
                    except (EOFError, OSError):
                        w.eof = True  # the process exited (or closed its end): find out how below
                if w.eof or (w.sentinel is not None and w.sentinel in ready) or not w.alive():
                    code = w.exitcode()
                    how = _signal_name(code) if code is not None else "it closed its connection (killed)"
                    fail_and_replace(w, f"worker crashed: {how}")
                    continue
                over_memory = recycle_above_mb is not None and w.rss_mb is not None and w.rss_mb > recycle_above_mb
                if w.job is None and ((recycle_after and w.count >= recycle_after) or over_memory):
                    w.retire()  # exits in the background while its replacement starts
                    retiring.append(w)
                    pool.remove(w)
                    if queue:
                        spawn()
                    continue
                if w.job is not None:
                    now = time.monotonic()
                    if w.started_at is None and now - w.assigned_at > STARTUP_TIMEOUT:
                        fail_and_replace(w, f"timeout: the worker did not start the job within {STARTUP_TIMEOUT:g} s")
                    elif run.timeout is not None and w.started_at is not None and now - w.started_at > run.timeout:
                        fail_and_replace(w, f"timeout: the job ran longer than {run.timeout:g} s (worker killed)")
    finally:
        for w in pool:
            if w.job is None and w.alive():
                w.retire()
                retiring.append(w)
            else:
                w.kill()
        for w in retiring:
            try:
                w.proc.wait(timeout=max(0.0, 30.0 - (time.monotonic() - w.retired_at)))
            except subprocess.TimeoutExpired:
                pass
            w.reap(0.0)


# ---------------------------------------------------------------------------------------------------
# Ray and concurrent.futures-style executors
# ---------------------------------------------------------------------------------------------------


def _run_ray(
    run: _Run,
    pending: list[int],
    address: str | None,
    workers: int | None,
    recycle_after: int | None,
    threads: int | None,
) -> tuple[int, int]:
    if "ray" not in sys.modules:
        # Under `uv run`, Ray would start every worker through `uv run` in a packaged copy of the working
        # directory (re-syncing the environment per worker); use the driver's interpreter instead.
        os.environ.setdefault("RAY_ENABLE_UV_RUN_RUNTIME_ENV", "0")
    try:
        import ray
    except ImportError:
        raise BlendifyError(
            "executor='ray' needs Ray: pip install 'blendify-core[ray]' (or pip install 'ray>=2.40')"
        ) from None
    started_here = False
    if not ray.is_initialized():
        ray.init(address=address, include_dashboard=False, log_to_driver=False)
        started_here = True
    try:
        cpus = int(ray.cluster_resources().get("CPU", 1)) or 1
        if threads is None:
            threads = max(1, cpus // workers) if workers else 1
        slots = workers or max(1, cpus // threads)
        task = ray.remote(num_cpus=threads, max_retries=0, max_calls=recycle_after or 0)(_worker.run_ray_job)
        clock = ray.remote(num_cpus=0)(_worker.StartClock).remote() if run.timeout is not None else None
        queue = list(reversed(pending))
        in_flight: dict[Any, tuple[int, float]] = {}
        while queue or in_flight:
            while queue and len(in_flight) < slots:
                index = queue.pop()
                try:
                    payload = run.payload(index, threads, "bytes")
                except Exception as exc:  # the scene could not be serialised
                    run.finish(index, {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"})
                    continue
                in_flight[task.remote(payload, clock)] = (index, time.time())
            if not in_flight:
                continue
            ready, _ = ray.wait(list(in_flight), num_returns=1, timeout=0.2)
            for ref in ready:
                index, _submitted = in_flight.pop(ref)
                try:
                    info = ray.get(ref)
                except Exception as exc:  # the task's worker died (segfault, abort, killed)
                    first = (str(exc).strip().splitlines() or [""])[0]
                    info = {"status": "failed", "reason": f"worker crashed: {type(exc).__name__}: {first}"}
                run.finish(index, info)
            if clock is not None and in_flight:
                starts = ray.get(clock.starts.remote())
                now = time.time()
                for ref, (index, submitted) in list(in_flight.items()):
                    started = starts.get(index)
                    if started is not None and now - started > run.timeout:
                        reason = f"timeout: the job ran longer than {run.timeout:g} s (worker killed)"
                    elif started is None and now - submitted > STARTUP_TIMEOUT:
                        reason = f"timeout: the job did not start within {STARTUP_TIMEOUT:g} s"
                    else:
                        continue
                    ray.cancel(ref, force=True)
                    in_flight.pop(ref)
                    run.finish(index, {"status": "failed", "reason": reason})
        return slots, threads
    finally:
        if started_here:
            ray.shutdown()


def _run_futures(run: _Run, pending: list[int], executor: Any, workers: int | None) -> int:
    slots = workers or int(getattr(executor, "_max_workers", 0) or 0) or _cpu_count()
    queue = list(reversed(pending))
    in_flight: dict[Any, list[Any]] = {}  # future -> [index, first seen running (monotonic) or None]
    grace = 5.0
    while queue or in_flight:
        while queue and len(in_flight) < slots:
            index = queue.pop()
            try:
                payload = run.payload(index, None, "bytes")
                fut = executor.submit(_worker.run_job, payload)
            except Exception as exc:
                run.finish(index, {"status": "failed", "reason": f"submit failed: {type(exc).__name__}: {exc}"})
                continue
            in_flight[fut] = [index, None]
        done = [f for f in in_flight if f.done()]
        if not done:
            time.sleep(0.05)
        for fut in done:
            index, _ = in_flight.pop(fut)
            try:
                info = fut.result()
            except Exception as exc:
                first = (str(exc).strip().splitlines() or [""])[0]
                info = {"status": "failed", "reason": f"{type(exc).__name__}: {first}"}
            if not isinstance(info, dict):
                info = {"status": "failed", "reason": f"the executor returned {type(info).__name__}, not a job result"}
            run.finish(index, info)
        if run.timeout is not None:
            now = time.monotonic()
            for fut, entry in list(in_flight.items()):
                running = getattr(fut, "running", None)
                if entry[1] is None and (running is None or running()):
                    entry[1] = now
                if entry[1] is not None and now - entry[1] > run.timeout + grace:
                    # the task itself refuses to write after its timeout; here we stop waiting for it
                    if hasattr(fut, "cancel"):
                        fut.cancel()
                    in_flight.pop(fut)
                    run.finish(
                        entry[0],
                        {
                            "status": "failed",
                            "reason": f"timeout: the job ran longer than {run.timeout:g} s "
                            "(abandoned: this executor cannot stop a running task; it writes no output)",
                        },
                    )
    return slots


# ---------------------------------------------------------------------------------------------------
# entry point
# ---------------------------------------------------------------------------------------------------


def render_many(
    jobs: Iterable[RenderJob],
    executor: Any = None,
    workers: int | None = None,
    recycle_after: int | None = DEFAULT_RECYCLE_AFTER,
    timeout: float | None = None,
    progress: bool = True,
    manifest: str | os.PathLike[str] | bool | None = None,
    recycle_above_mb: float | None = None,
) -> BatchReport:
    """Render many jobs and return a :class:`BatchReport` with one status per job, in job order.

    Every job ends "done", "skipped" (its key is already "done" in the manifest and its files exist) or
    "failed" with the reason (the engine's error, ``"timeout: ..."``, ``"worker crashed: ..."``). A failing
    job never stops the run; check ``report.ok`` (a run with failed jobs also logs one warning on the
    ``blendify_core`` logger, and ``blendify batch`` exits with code 1). Outputs are written atomically
    by the workers; after each finished job one record is appended to the manifest (``manifest``: a
    ``.jsonl`` (default) or ``.json`` path; None = ``blendify_manifest.jsonl`` in the common folder of
    the outputs; False = no manifest, no resume).
    A record's key is the SHA-256 of ``scene.fingerprint()`` + backend + settings (except ``threads``) +
    backend options + output path, so re-running the same batch skips finished jobs and retries failed
    ones; changing a scene or a setting renders the job again.

    ``executor``:

    - None or ``"local"``: a pool of ``workers`` (default: one per core) worker processes, each keeping
      ``bf.render``'s backend instance warm and replaced by a fresh process after ``recycle_after`` jobs
      (engines leak; None = never) or as soon as its resident memory exceeds ``recycle_above_mb`` MiB
      after a job (None = no limit). Jobs without ``threads`` get ``cores // workers`` engine threads.
      A crash (segfault, ``os.abort``, being killed) fails only the job it was running; the pool starts
      a new worker and the run goes on. ``timeout`` (seconds of rendering, from when the worker starts
      the render) kills the worker and fails the job. Workers are fresh interpreters (``sys.executable``
      with this process's ``sys.path`` and environment) that never import ``__main__``, so no
      ``if __name__ == "__main__":`` guard is needed: scripts, ``python -``, ``python -c`` and notebooks
      all work. The one thing they cannot reach is a backend registered as a class defined in
      ``__main__`` (or inside a function): render_many raises before starting, saying to move it into a
      module and register it as ``"module:Class"``. When workers cannot start at all (e.g. a broken
      install), the remaining jobs fail with the worker's error instead of one crash per job.
    - ``"ray"``, ``"ray://host:port"`` (Ray client) or ``"ray:ADDRESS"`` (e.g. ``"ray:auto"``): Ray tasks with
      ``max_retries=0``, ``num_cpus`` = engine threads per job (default: ``cluster CPUs // workers`` when
      ``workers`` is given, else 1) and ``max_calls=recycle_after`` (Ray's worker recycling). Uses the
      running Ray session if ``ray.init()`` was already called (e.g. ``ray.init(address="auto")`` on a
      cluster), else starts a local one (or connects to ``RAY_ADDRESS``) and shuts it down at the end.
      Unless ``RAY_ENABLE_UV_RUN_RUNTIME_ENV`` is set, Ray's ``uv run`` propagation is turned off (when
      Ray is first imported here) so workers use the driver's interpreter. Needs
      ``pip install 'blendify-core[ray]'``; blendify-core and the backends must be installed on
      every node and the outputs (and scene files given by path) must be on a shared filesystem. Scenes
      given as objects travel as scene-file bytes through Ray's object store.
    - any object with ``submit(fn, *args) -> future`` whose futures have ``done()`` and ``result()``
      (a ``concurrent.futures.Executor``): e.g. Dask's ``distributed.Client(...).get_executor()`` or
      submitit's ``AutoExecutor(folder=...)`` for Slurm (set its ``timeout_min``/``cpus_per_task``
      there). At most ``workers`` jobs are in flight (default: the executor's ``_max_workers`` or the
      cores). Such executors cannot stop a running task: a job over ``timeout`` is reported failed and
      the task, which checks its own clock, writes no output. Note that ``ProcessPoolExecutor`` breaks
      for good when one of its workers dies; use the default pool for crash isolation on one machine.

    ``progress``: one tqdm bar across all jobs (skipped ones included).

    Examples::

        jobs = [bf.RenderJob(s, f"out/{i:05d}.png", backend="cycles", samples=64) for i, s in enumerate(scenes)]
        report = bf.render_many(jobs, workers=2, timeout=600)  # local pool; run it again to resume
        print(report.summary())

        import ray
        ray.init(address="auto")  # an existing cluster (or nothing: a local one is started)
        report = bf.render_many(jobs, executor="ray", workers=64)

        from distributed import Client  # Dask
        report = bf.render_many(jobs, executor=Client("tcp://scheduler:8786").get_executor(), workers=32)

        import submitit  # Slurm: one Slurm job per frame
        ex = submitit.AutoExecutor(folder="slurm_logs")
        ex.update_parameters(timeout_min=30, cpus_per_task=4)
        report = bf.render_many(jobs, executor=ex, workers=100)
    """
    t0 = time.perf_counter()
    jobs = list(jobs)
    for i, job in enumerate(jobs):
        if not isinstance(job, RenderJob):
            raise InvalidSceneError(f"jobs[{i}]: expected a blendify_core.RenderJob, got {type(job).__name__}")
    seen: dict[str, int] = {}
    for i, job in enumerate(jobs):
        for f in job.files():
            if f in seen:
                raise InvalidSceneError(f"jobs[{i}]: output {f!r} is also written by jobs[{seen[f]}]")
            seen[f] = i
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise InvalidSceneError(f"workers: expected a positive integer or None, got {workers!r}")
    if recycle_after is not None and (
        isinstance(recycle_after, bool) or not isinstance(recycle_after, int) or recycle_after < 1
    ):
        raise InvalidSceneError(f"recycle_after: expected a positive integer or None, got {recycle_after!r}")
    if recycle_above_mb is not None and (
        isinstance(recycle_above_mb, bool) or not isinstance(recycle_above_mb, (int, float)) or recycle_above_mb <= 0
    ):
        raise InvalidSceneError(f"recycle_above_mb: expected a positive number (MiB) or None, not {recycle_above_mb!r}")
    if timeout is not None:
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not timeout > 0:
            raise InvalidSceneError(f"timeout: expected a positive number of seconds or None, got {timeout!r}")
        timeout = float(timeout)
    kind, address = _executor_kind(executor)
    if kind in ("local", "ray"):
        _check_backends_importable(jobs)

    if manifest is False or not jobs:
        man = None
    else:
        man_path = _default_manifest(jobs) if manifest is None or manifest is True else Path(os.fspath(manifest))
        man = _Manifest(man_path.resolve())

    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(jobs), desc="render_many", unit="job", dynamic_ncols=True)
    run = _Run(jobs, {}, {}, man, bar, timeout)
    used_workers = 0
    try:
        pending = []
        for i, job in enumerate(jobs):
            for folder in {os.path.dirname(f) for f in job.files()}:
                os.makedirs(folder, exist_ok=True)
            try:
                scene = job.scene
                if scene is None:
                    scene = Scene.load(job.scene_path, allow_outside=job.allow_outside)  # type: ignore[arg-type]
                run.fingerprints[i] = scene.fingerprint()
            except Exception as exc:  # an unreadable scene fails its job, not the batch
                run.keys[i] = None  # type: ignore[assignment]
                run.finish(i, {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"})
                continue
            run.keys[i] = _job_key(run.fingerprints[i], job)
            record = man.finished(run.keys[i]) if man is not None else None
            if record is not None:
                run.skip(i, record)
            else:
                pending.append(i)
        if pending:
            if kind == "local":
                used_workers = workers or min(_cpu_count(), len(pending))
                threads = max(1, _cpu_count() // used_workers)
                _run_local(run, pending, used_workers, recycle_after, threads, recycle_above_mb)
            elif kind == "ray":
                used_workers, _ = _run_ray(run, pending, address, workers, recycle_after, None)
            else:
                used_workers = _run_futures(run, pending, executor, workers)
    finally:
        run.cleanup()
        if bar is not None:
            bar.close()
        if man is not None:
            man.close()
    statuses = [run.statuses[i] for i in range(len(jobs))]
    name = kind if kind != "futures" else type(executor).__name__
    report = BatchReport(statuses, name, used_workers, time.perf_counter() - t0, None if man is None else str(man.path))
    if report.failed:  # a run whose jobs failed must not pass for a success in a script that ignores the report
        first = report.failed[0]
        log.warning(
            "render_many: %d of %d jobs failed (first: jobs[%d] %s: %s); report.failed has every reason",
            len(report.failed),
            len(report),
            first.index,
            first.output,
            first.reason,
        )
    return report


def _executor_kind(executor: Any) -> tuple[str, str | None]:
    if executor is None or executor == "local":
        return "local", None
    if isinstance(executor, str):
        if executor == "ray":
            return "ray", None
        if executor.startswith("ray://"):
            return "ray", executor
        if executor.startswith("ray:"):
            return "ray", executor[4:]
        raise InvalidSceneError(
            f"executor: expected None, 'local', 'ray', 'ray:ADDRESS' or a concurrent.futures-style executor, "
            f"got {executor!r}"
        )
    if callable(getattr(executor, "submit", None)):
        return "futures", None
    raise InvalidSceneError(
        f"executor: expected None, 'local', 'ray' or an object with a submit() method, got {type(executor).__name__}"
    )
