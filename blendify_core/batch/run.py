"""Batch and distributed rendering with resume: :func:`render_many`.

Jobs (:mod:`.jobs`) travel to workers as portable scene files (``Scene.save``) or the path of one, plus
JSON-like settings; engine objects are never pickled. Each worker process (:mod:`.worker`) keeps
``bf.render``'s shared backend instance warm from job to job and writes its outputs atomically. A manifest
(:mod:`.manifest`) next to the outputs records every finished job under a key (scene fingerprint + backend +
settings + output path), so running the same batch again skips what is done and retries what failed. The
executors: a local pool (:mod:`.local`), Ray or any ``concurrent.futures``-style executor (:mod:`.remote`).
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Iterable
from pathlib import Path

from blendify_core.batch.importable import check_backends_importable
from blendify_core.batch.jobs import BatchReport, JobStatus, RenderJob, job_key, read_jobs
from blendify_core.batch.local import DEFAULT_RECYCLE_AFTER, run_local
from blendify_core.batch.manifest import MANIFEST_NAME, Manifest, default_manifest
from blendify_core.batch.remote import Executor, run_futures, run_ray
from blendify_core.batch.state import BatchRun, ProgressBar, cpu_count
from blendify_core.errors import InvalidSceneError
from blendify_core.ir.scene import Scene
from blendify_core.ir.validate import as_bool, strict_arguments

__all__ = [
    "RenderJob",
    "JobStatus",
    "BatchReport",
    "render_many",
    "read_jobs",
    "DEFAULT_RECYCLE_AFTER",
    "MANIFEST_NAME",
]

log = logging.getLogger("blendify_core")


@strict_arguments
def render_many(
    jobs: Iterable[RenderJob],
    executor: str | Executor | None = None,
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
    jobs = _checked_jobs(jobs)
    timeout = _check_limits(workers, recycle_after, recycle_above_mb, timeout)
    kind, address = _executor_kind(executor)
    if kind in ("local", "ray"):
        check_backends_importable(jobs)
    if manifest is not None and not isinstance(manifest, (str, os.PathLike)):
        manifest = None if as_bool("manifest", manifest) else False  # True: the default place, as None
    man = None if manifest is False or not jobs else Manifest(_manifest_path(manifest, jobs).resolve())
    bar: ProgressBar | None = None
    if as_bool("progress", progress):
        from tqdm.auto import tqdm

        bar = tqdm(total=len(jobs), desc="render_many", unit="job", dynamic_ncols=True)
    run = BatchRun(jobs, {}, {}, man, bar, timeout)
    used_workers = 0
    try:
        pending = _pending_jobs(run, man)
        if pending:
            used_workers = _execute(run, pending, kind, address, executor, workers, recycle_after, recycle_above_mb)
    finally:
        run.cleanup()
        if bar is not None:
            bar.close()
        if man is not None:
            man.close()
    statuses = [run.statuses[i] for i in range(len(jobs))]
    name = kind if kind != "futures" else type(executor).__name__
    report = BatchReport(statuses, name, used_workers, time.perf_counter() - t0, None if man is None else str(man.path))
    _warn_failures(report)
    return report


def _checked_jobs(jobs: Iterable[RenderJob]) -> list[RenderJob]:
    """The jobs as a list; each must be a RenderJob and no two may write the same file."""
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
    return jobs


def _check_limits(workers: object, recycle_after: object, recycle_above_mb: object, timeout: object) -> float | None:
    """Validate the pool limits; return ``timeout`` as a float (or None)."""
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
    if timeout is None:
        return None
    if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not timeout > 0:
        raise InvalidSceneError(f"timeout: expected a positive number of seconds or None, got {timeout!r}")
    return float(timeout)


def _manifest_path(manifest: str | os.PathLike[str] | bool | None, jobs: list[RenderJob]) -> Path:
    if manifest is None or isinstance(manifest, bool):  # False never gets here: no manifest at all
        return default_manifest(jobs)
    return Path(os.fspath(manifest))


def _pending_jobs(run: BatchRun, man: Manifest | None) -> list[int]:
    """Key every job, skip the ones the manifest has finished, fail the ones whose scene cannot be read;
    the indices left to render."""
    pending = []
    for i, job in enumerate(run.jobs):
        for folder in {os.path.dirname(f) for f in job.files()}:
            os.makedirs(folder, exist_ok=True)
        try:
            scene = job.scene
            if scene is None:
                scene = Scene.load(job.scene_path or "", allow_outside=job.allow_outside)
            run.fingerprints[i] = scene.fingerprint()
        except Exception as exc:  # an unreadable scene fails its job, not the batch
            run.finish(i, {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"})
            continue
        run.keys[i] = job_key(run.fingerprints[i], job)
        record = man.finished(run.keys[i]) if man is not None else None
        if record is not None:
            run.skip(i, record)
        else:
            pending.append(i)
    return pending


def _execute(
    run: BatchRun,
    pending: list[int],
    kind: str,
    address: str | None,
    executor: str | Executor | None,
    workers: int | None,
    recycle_after: int | None,
    recycle_above_mb: float | None,
) -> int:
    """Render the pending jobs with the chosen executor; the number of workers used."""
    if kind == "local":
        used_workers = workers or min(cpu_count(), len(pending))
        threads = max(1, cpu_count() // used_workers)
        run_local(run, pending, used_workers, recycle_after, threads, recycle_above_mb)
        return used_workers
    if kind == "ray":
        return run_ray(run, pending, address, workers, recycle_after, None)[0]
    if executor is None or isinstance(executor, str):
        raise InvalidSceneError(f"executor: {executor!r} is not an executor object")
    return run_futures(run, pending, executor, workers)


def _warn_failures(report: BatchReport) -> None:
    """A run whose jobs failed must not pass for a success in a script that ignores the report."""
    if report.failed:
        first = report.failed[0]
        log.warning(
            "render_many: %d of %d jobs failed (first: jobs[%d] %s: %s); report.failed has every reason",
            len(report.failed),
            len(report),
            first.index,
            first.output,
            first.reason,
        )


def _executor_kind(executor: object) -> tuple[str, str | None]:
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
