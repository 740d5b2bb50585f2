"""The batch manifest: one record per finished job, so running the same batch again skips what is done.

A record's key is :func:`~blendify_core.batch.jobs.job_key` (scene fingerprint + backend + settings +
options + output path). ``.jsonl`` manifests get one line appended (and fsynced) per finished job;
``.json`` manifests are rewritten atomically. A lock file keeps two runs from sharing one manifest.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import IO, Any

from blendify_core.batch.jobs import RenderJob
from blendify_core.errors import BlendifyError, InvalidSceneError
from blendify_core.io.output import atomic_write

__all__ = ["Manifest", "MANIFEST_NAME", "default_manifest"]

#: default manifest file name, written in the common folder of the outputs
MANIFEST_NAME = "blendify_manifest.jsonl"


class Manifest:
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
        self._lock_file: IO[str] | None = self._lock(path if self.jsonl else path.with_name(path.name + ".lock"))
        if path.is_file():
            self._read()
        self._fh: IO[str] | None = None
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
    def _lock(lock_path: Path) -> IO[str]:
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


def default_manifest(jobs: list[RenderJob]) -> Path:
    """``MANIFEST_NAME`` in the common folder of the jobs' outputs."""
    folders = sorted({os.path.dirname(j.output) for j in jobs})
    try:
        common = os.path.commonpath(folders)
    except ValueError:  # different drives
        common = folders[0]
    return Path(common) / MANIFEST_NAME
