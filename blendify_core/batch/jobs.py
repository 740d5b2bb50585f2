"""Batch jobs and their outcome: :class:`RenderJob` (one frame to render), :func:`read_jobs` (a JSON-lines
file of jobs), :class:`JobStatus` and :class:`BatchReport` (what :func:`~blendify_core.batch.run.render_many`
did with each job).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from blendify_core.batch.worker import output_files
from blendify_core.errors import InvalidSceneError
from blendify_core.ir.scene import Scene
from blendify_core.ir.validate import as_bool, strict_api
from blendify_core.pipeline.settings import RenderSettings, resolve_settings

__all__ = ["RenderJob", "JobStatus", "BatchReport", "read_jobs", "job_key", "STATUSES"]

_SETTING_NAMES = {f.name for f in dataclasses.fields(RenderSettings)} - {"extra"}
_OUTPUT_SUFFIXES = (".png", ".exr", ".npz")
#: the statuses a job ends with
STATUSES = ("done", "skipped", "failed")


@strict_api
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
        scene_or_path: Scene | str | os.PathLike[str],
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
        self.allow_outside = as_bool("allow_outside", allow_outside)
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


def job_key(fingerprint: str, job: RenderJob) -> str:
    """The job's manifest key: SHA-256 of the scene fingerprint, backend, settings (except ``threads``),
    backend options and output path."""
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


@strict_api
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
        out = dict.fromkeys(STATUSES, 0)
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

    def __iter__(self) -> Iterator[JobStatus]:
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
