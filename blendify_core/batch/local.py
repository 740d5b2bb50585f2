"""The local executor of :func:`~blendify_core.batch.run.render_many`: a pool of worker processes on this
machine, each a fresh interpreter running :data:`~blendify_core.batch.worker.BOOTSTRAP` (never the user's
``__main__``), replaced after ``recycle_after`` jobs or above ``recycle_above_mb``, killed on ``timeout``;
a crash fails only the job it was running.
"""

from __future__ import annotations

import os
import sys
import time
from typing import TYPE_CHECKING, Any

from blendify_core.batch import worker as _worker
from blendify_core.batch.state import STARTUP_TIMEOUT, BatchRun
from blendify_core.errors import BlendifyError

if TYPE_CHECKING:  # annotations only: subprocess and multiprocessing load when a pool starts
    from multiprocessing.connection import Connection

__all__ = ["run_local", "DEFAULT_RECYCLE_AFTER"]

#: jobs a local pool worker renders before it is replaced by a fresh process (engines leak memory).
#: Measured (benchmarks/results/batch.md): Mitsuba 3.9 grows ~0.37 MiB per small job, Cycles ~0.01;
#: a restart costs ~1.5-3 s (process + engine start). 250 bounds the Mitsuba growth to ~100 MiB with a
#: restart overhead under ~8% for 0.1 s frames and under 1% for 1 s frames; use ``recycle_above_mb``
#: as the safety net for scenes that leak more.
DEFAULT_RECYCLE_AFTER = 250


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
        # -O, -X ..., as multiprocessing does
        flags: list[str] = getattr(subprocess, "_args_from_interpreter_flags", list)()
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


class _LocalPool:
    """The run loop of the local pool: hand jobs to idle workers, read their messages, replace workers
    that crash, time out, or are due for recycling."""

    def __init__(
        self,
        run: BatchRun,
        pending: list[int],
        workers: int,
        recycle_after: int | None,
        threads: int,
        recycle_above_mb: float | None,
    ) -> None:
        self.run = run
        self.queue = list(reversed(pending))  # pop() from the end keeps job order
        self.workers = workers
        self.recycle_after = recycle_after
        self.threads = threads
        self.recycle_above_mb = recycle_above_mb
        self.pool: list[_PoolWorker] = []
        self.retiring: list[_PoolWorker] = []
        self.startup_failures = 0
        self.gave_up: str | None = None  # set when workers cannot start at all: the remaining jobs fail with this

    def spawn(self) -> None:
        if self.gave_up is None:
            self.pool.append(_PoolWorker())

    def busy(self) -> list[_PoolWorker]:
        return [w for w in self.pool if w.job is not None]

    def fail_and_replace(self, w: _PoolWorker, reason: str) -> None:
        """Fail ``w``'s job (or requeue a job that never started), kill ``w`` and start a replacement."""
        run, queue = self.run, self.queue
        if not w.ready:
            self.startup_failures += 1
            detail = f"{w.start_error}; " if w.start_error else ""
            reason = f"worker failed to start ({detail}{reason}); see the worker's stderr"
            if w.start_error is not None or self.startup_failures >= 3:
                # an import error, or three workers in a row died before they could take a job: every
                # further worker would die the same way, so the remaining jobs fail now with the reason
                self.gave_up = reason
            elif w.job is not None:  # e.g. killed while starting: the job never ran, try it again
                queue.append(w.job)
                run.release(w.job)
                w.job = None
        if w.job is not None:
            run.finish(w.job, {"status": "failed", "reason": reason, "pid": w.pid})
            w.job = None
        w.kill()
        self.pool.remove(w)
        if self.gave_up is not None:
            while queue:
                run.finish(queue.pop(), {"status": "failed", "reason": self.gave_up})
        elif queue and len(self.pool) < self.workers:
            self.spawn()

    def loop(self) -> None:
        for _ in range(min(self.workers, len(self.queue))):
            self.spawn()
        while self.queue or self.busy():
            if not self.pool and self.queue:
                self.spawn()
            self.assign()
            if not self.pool:  # every worker died before receiving work
                if self.queue:
                    self.spawn()
                continue
            ready = self.wait()
            for w in list(self.pool):
                self.service(w, ready)

    def assign(self) -> None:
        """Send the next queued jobs to idle workers."""
        now = time.monotonic()
        for w in list(self.pool):
            if w.job is None and self.queue and not w.eof and w.alive():
                index = self.queue.pop()
                try:
                    w.conn.send(self.run.payload(index, self.threads, "path"))
                except (OSError, ValueError) as exc:  # the worker died while idle: retry on a new one
                    self.queue.append(index)
                    self.run.release(index)
                    self.fail_and_replace(w, f"worker crashed before the job started ({exc})")
                    continue
                except Exception as exc:  # the scene could not be written
                    self.run.finish(index, {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"})
                    continue
                w.job, w.assigned_at, w.started_at = index, now, None

    def wait(self) -> set[object]:
        """Wait for a message, a worker's exit or the next deadline; the connections and sentinels ready."""
        from multiprocessing.connection import wait

        deadlines = []
        for w in self.busy():
            if w.started_at is None:
                deadlines.append(w.assigned_at + STARTUP_TIMEOUT)
            elif self.run.timeout is not None:
                deadlines.append(w.started_at + self.run.timeout)
        self.retiring[:] = [w for w in self.retiring if not w.reap(30.0)]
        if self.retiring or any(w.sentinel is None for w in self.pool):
            deadlines.append(time.monotonic() + 0.5)  # poll exits that no descriptor reports
        wait_for = max(0.0, min(deadlines) - time.monotonic()) if deadlines else None
        handles: list[Connection | int] = [w.conn for w in self.pool] + [
            w.sentinel for w in self.pool if w.sentinel is not None
        ]
        return set(wait(handles, timeout=wait_for))

    def receive(self, w: _PoolWorker) -> None:
        """Read every message ``w`` sent: ready, a start-up error, a job started, a job's result."""
        try:
            while w.conn.poll():
                msg = w.conn.recv()
                if msg[0] == "ready":
                    w.ready = True
                    self.startup_failures = 0
                elif msg[0] == "error":
                    w.start_error = str(msg[1])
                elif msg[0] == "start" and msg[1] == w.job:
                    w.started_at = time.monotonic()
                elif msg[0] == "result" and msg[1] == w.job:
                    self.run.finish(msg[1], msg[2])
                    w.job, w.started_at = None, None
                    w.count += 1
                    w.rss_mb = msg[2].get("rss_mb")
        except (EOFError, OSError):
            w.eof = True  # the process exited (or closed its end): find out how in service()

    def service(self, w: _PoolWorker, ready: set[object]) -> None:
        """Handle ``w`` after a wait: its messages, its death, its recycling, its job's deadline."""
        if w.conn in ready:
            self.receive(w)
        if w.eof or (w.sentinel is not None and w.sentinel in ready) or not w.alive():
            code = w.exitcode()
            how = _signal_name(code) if code is not None else "it closed its connection (killed)"
            self.fail_and_replace(w, f"worker crashed: {how}")
            return
        limit = self.recycle_above_mb
        over_memory = limit is not None and w.rss_mb is not None and w.rss_mb > limit
        if w.job is None and ((self.recycle_after and w.count >= self.recycle_after) or over_memory):
            w.retire()  # exits in the background while its replacement starts
            self.retiring.append(w)
            self.pool.remove(w)
            if self.queue:
                self.spawn()
            return
        if w.job is not None:
            now = time.monotonic()
            timeout = self.run.timeout
            if w.started_at is None and now - w.assigned_at > STARTUP_TIMEOUT:
                self.fail_and_replace(w, f"timeout: the worker did not start the job within {STARTUP_TIMEOUT:g} s")
            elif timeout is not None and w.started_at is not None and now - w.started_at > timeout:
                self.fail_and_replace(w, f"timeout: the job ran longer than {timeout:g} s (worker killed)")

    def shutdown(self) -> None:
        """Retire idle workers (they close their backends), kill busy ones, wait up to 30 s for exits."""
        import subprocess

        for w in self.pool:
            if w.job is None and w.alive():
                w.retire()
                self.retiring.append(w)
            else:
                w.kill()
        for w in self.retiring:
            try:
                w.proc.wait(timeout=max(0.0, 30.0 - (time.monotonic() - w.retired_at)))
            except subprocess.TimeoutExpired:
                pass
            w.reap(0.0)


def run_local(
    run: BatchRun,
    pending: list[int],
    workers: int,
    recycle_after: int | None,
    threads: int,
    recycle_above_mb: float | None = None,
) -> None:
    """Render the ``pending`` jobs of ``run`` on a pool of ``workers`` local worker processes."""
    from multiprocessing import spawn as mp_spawn

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
    pool = _LocalPool(run, pending, workers, recycle_after, threads, recycle_above_mb)
    try:
        pool.loop()
    finally:
        pool.shutdown()
