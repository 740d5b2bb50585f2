"""The distributed executors of :func:`~blendify_core.batch.run.render_many`: Ray tasks, and any
``concurrent.futures``-style executor (Dask's ``Client.get_executor()``, submitit's ``AutoExecutor`` for
Slurm, a ``ThreadPoolExecutor``). Scenes travel as scene-file bytes; workers run
:func:`~blendify_core.batch.worker.run_job`.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from blendify_core.batch import worker as _worker
from blendify_core.batch.state import STARTUP_TIMEOUT, BatchRun, cpu_count
from blendify_core.errors import BlendifyError

__all__ = ["run_ray", "run_futures", "Executor", "JobFuture"]


class JobFuture(Protocol):
    """A submitted task: ``done()`` and ``result()`` (``running()`` and ``cancel()`` are used when present)."""

    def done(self) -> bool: ...

    def result(self) -> Any: ...


class Executor(Protocol):
    """What render_many needs of an executor: ``submit(fn, *args)`` returning a :class:`JobFuture`
    (a ``concurrent.futures.Executor``, Dask's ``Client.get_executor()``, submitit's ``AutoExecutor``)."""

    def submit(self, fn: Callable[..., Any], /, *args: Any) -> JobFuture: ...


@dataclass
class _InFlight:
    index: int
    #: when the task was first seen running (monotonic seconds), None before
    running_since: float | None = None


def run_ray(
    run: BatchRun,
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


def run_futures(run: BatchRun, pending: list[int], executor: Executor, workers: int | None) -> int:
    slots = workers or int(getattr(executor, "_max_workers", 0) or 0) or cpu_count()
    queue = list(reversed(pending))
    in_flight: dict[JobFuture, _InFlight] = {}
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
            in_flight[fut] = _InFlight(index)
        done = [f for f in in_flight if f.done()]
        if not done:
            time.sleep(0.05)
        for fut in done:
            index = in_flight.pop(fut).index
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
                if entry.running_since is None and (running is None or running()):
                    entry.running_since = now
                if entry.running_since is not None and now - entry.running_since > run.timeout + grace:
                    # the task itself refuses to write after its timeout; here we stop waiting for it
                    if hasattr(fut, "cancel"):
                        fut.cancel()
                    in_flight.pop(fut)
                    run.finish(
                        entry.index,
                        {
                            "status": "failed",
                            "reason": f"timeout: the job ran longer than {run.timeout:g} s "
                            "(abandoned: this executor cannot stop a running task; it writes no output)",
                        },
                    )
    return slots
