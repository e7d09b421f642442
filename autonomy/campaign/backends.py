"""Where campaign runs are flown: a local process pool or a Dask distributed cluster.

Both backends take the same :class:`~autonomy.campaign.plan.RunTask` objects and yield run
records as runs finish (in completion order). The flights are deterministic functions of
(mission, seed), so the records are the same whichever backend flew them, apart from the
wall time.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import time
import traceback
import uuid
from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Protocol

from autonomy.campaign.plan import RunTask
from autonomy.campaign.warm import preload_modules
from autonomy.campaign.worker import error_record, fly_alone, fly_run, fly_with_page
from autonomy.errors import UserError

WORKER_DIED = "worker process died while flying this run"
# The fork server imports it first: a Ctrl-C while the server starts ends it quietly.
QUIET_CTRL_C_MODULE = "autonomy.campaign._quiet_ctrl_c"


class Backend(Protocol):
    """Flies tasks and yields their run records as they finish."""

    workers: int

    def run(self, tasks: Sequence[RunTask]) -> Iterator[dict[str, Any]]: ...

    def close(self) -> None: ...


def default_workers() -> int:
    """One worker per core this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _start_context(preload: Sequence[str]) -> multiprocessing.context.BaseContext:
    """Fork-server workers where the platform has them, else spawned ones.

    Either way workers start from a clean interpreter (never a fork of this process and its
    threads), so flights only see what they are sent. The fork server imports ``preload``
    once, so each new worker starts without re-importing the flight stack or reloading its
    compiled kernels (:mod:`autonomy.campaign.warm`).
    """
    if "forkserver" in multiprocessing.get_all_start_methods():
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(list(preload))
        return context
    return multiprocessing.get_context("spawn")  # pragma: no cover - Windows


def start_fork_server() -> None:
    """Start the fork server with Ctrl-C held back, as the standard library starts its
    resource tracker: a Ctrl-C while the server imports the flight stack (seconds) would
    otherwise print its KeyboardInterrupt traceback. The server takes the held Ctrl-C once
    it has imported :data:`QUIET_CTRL_C_MODULE`, and then ends quietly."""
    from multiprocessing import forkserver, resource_tracker

    resource_tracker.ensure_running()  # first: starting it unblocks Ctrl-C when it is done
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        forkserver.ensure_running()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


class LocalPool:
    """A ``concurrent.futures.ProcessPoolExecutor`` of fresh worker processes.

    At most ``workers`` runs are in flight. If a worker process dies (a crash, the OOM
    killer), the pool breaks and every run in flight fails with it; the pool's remaining
    workers are killed (so that shutting it down never waits on one), and those runs are
    flown again one at a time, each in a process of its own, so only the run that kills its
    worker again is recorded as ``error``, naming how the worker died (``worker_died``:
    the signal, e.g. ``SIGKILL``, or the exit code), and the campaign goes on with a new pool.
    """

    def __init__(self, workers: int | None = None) -> None:
        self.workers = max(1, int(workers or default_workers()))
        self._context: multiprocessing.context.BaseContext | None = None

    def _ensure_fork_server(self) -> None:
        """Start the fork server, or again if it died and is gone (the OOM killer may take
        it too); here, not by the pool: Ctrl-C would reach a server the pool starts at once."""
        assert self._context is not None
        if self._context.get_start_method() == "forkserver":
            start_fork_server()

    def _pool(self, workers: int) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=workers, mp_context=self._context)

    def run(self, tasks: Sequence[RunTask]) -> Iterator[dict[str, Any]]:
        pending = deque(tasks)
        if self._context is None and tasks:
            flight_module = getattr(tasks[0].flight, "__module__", None)
            # The server imports these once; every worker forked from it starts with them.
            preload = [QUIET_CTRL_C_MODULE, "__main__", "autonomy.campaign.worker"]
            preload += [flight_module] if flight_module else []
            if tasks[0].flight is fly_with_page:  # lander flights: the stack, warm
                preload += preload_modules({id(t.mission): t.mission for t in tasks}.values())
            self._context = _start_context(preload)
        empty_breaks = 0
        while pending:
            self._ensure_fork_server()
            suspects: list[RunTask] = []
            others = set(multiprocessing.active_children())  # not this pool's workers
            pool = self._pool(min(self.workers, len(pending)))
            broken = False
            try:
                in_flight: dict[Future, RunTask] = {}
                while (pending or in_flight) and not broken:
                    while pending and len(in_flight) < self.workers:
                        task = pending.popleft()
                        try:
                            in_flight[pool.submit(fly_run, task)] = task
                        except (BrokenProcessPool, OSError, EOFError):
                            # A worker died since the last wait. The pool may have broken
                            # while this submit started a worker: the standard library then
                            # fails it with OSError or EOFError instead.
                            pending.appendleft(task)
                            broken = True
                            break
                    done, _ = wait(in_flight, return_when=FIRST_COMPLETED)
                    broken = broken or any(
                        isinstance(f.exception(), BrokenProcessPool) for f in done
                    )
                    if broken:
                        # Every other run in flight fails with the broken pool too.
                        done, _ = wait(in_flight)
                    for future in done:
                        task = in_flight.pop(future)
                        error = future.exception()
                        if isinstance(error, BrokenProcessPool):
                            suspects.append(task)
                        elif isinstance(error, KeyboardInterrupt):
                            # Ctrl-C reached the workers too: stop, record nothing for it,
                            # so that re-running the command flies this run again.
                            raise KeyboardInterrupt
                        elif error is not None:
                            yield error_record(task, _format(error))
                        else:
                            yield future.result()
            finally:
                if broken:
                    _kill_workers(others)
                pool.shutdown(wait=True, cancel_futures=True)
            empty_breaks = empty_breaks + 1 if broken and not suspects else 0
            if empty_breaks >= 3:
                raise RuntimeError("worker processes keep dying without flying any run")
            if empty_breaks:
                # No worker started: the fork server died. The next pool starts it again
                # once it is gone; a moment for the system to reap it first.
                time.sleep(0.5 * empty_breaks)
            for task in suspects:
                yield self._isolated(task)

    def _isolated(self, task: RunTask) -> dict[str, Any]:
        """Fly one run alone in a process of its own, to tell whether it kills its worker
        and, if it does, how the worker died (a pool's workers do not say)."""
        self._ensure_fork_server()
        receiving, sending = self._context.Pipe(duplex=False)
        worker = self._context.Process(target=fly_alone, args=(task, sending),
                                       name=f"lander-{task.run_id}")
        try:
            worker.start()
        except BaseException:
            receiving.close()
            raise
        finally:
            sending.close()  # the worker holds the only writer: its death ends the pipe
        try:
            kind, record = receiving.recv()
        except EOFError:
            kind, record = "died", None
        finally:
            receiving.close()
            worker.join()  # it sent its record (or died, or stops on Ctrl-C): it ends
        if kind == "interrupted":
            raise KeyboardInterrupt
        if kind == "died":
            how = death(worker.exitcode)
            return error_record(
                task, f"{WORKER_DIED}, twice (the second time alone): {how}",
                worker_died=death_name(worker.exitcode))
        return record

    def close(self) -> None:
        """Nothing to release: each :meth:`run` shuts its pools down."""


def _kill_workers(others: set[Any]) -> None:
    """Kill the workers a broken pool still has: this process's children but ``others``.
    The standard library sends them SIGTERM and then waits for each without a time limit;
    a worker it was starting while the pool broke gets no SIGTERM, and would first fly a
    run nobody waits for any more, or wait for work forever."""
    for process in set(multiprocessing.active_children()) - others:
        process.kill()


def death_name(exitcode: int | None) -> str:
    """``"SIGKILL"`` for a process killed by SIGKILL, ``"exit code 3"`` for one that
    exited with code 3 (as ``multiprocessing.Process.exitcode`` tells them apart)."""
    if exitcode is None:
        return "unknown"
    if exitcode < 0:
        try:
            return signal.Signals(-exitcode).name
        except ValueError:
            return f"signal {-exitcode}"
    return f"exit code {exitcode}"


# Why the usual senders of a deadly signal send it.
_LIKELY_CAUSES = {
    "SIGKILL": "possibly out of memory: the kernel's OOM killer sends SIGKILL",
    "SIGSEGV": "a segmentation fault: a crash in compiled code",
    "SIGBUS": "a bus error: a crash in compiled code, or a file mapped in memory shrank",
    "SIGABRT": "aborted by compiled code",
    "SIGTERM": "asked to stop by another process",
}


def death(exitcode: int | None) -> str:
    """How a worker process died, in words, e.g. ``"killed by SIGKILL (possibly out of
    memory: ...)"``."""
    name = death_name(exitcode)
    if exitcode is None or exitcode >= 0:
        return f"it ended with {name}"
    cause = _LIKELY_CAUSES.get(name)
    return f"killed by {name}" + (f" ({cause})" if cause else "")


def _format(exc: BaseException) -> str:
    return "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))


class DaskCluster:
    """Runs on a Dask distributed cluster: an existing scheduler (``tcp://HOST:PORT``) or
    ``"local"``, a ``LocalCluster`` of ``workers`` single-threaded processes on 127.0.0.1.

    Needs the optional ``distributed`` package (``pip install 'landing-autonomy[cluster]'``)
    on this machine and, for a remote cluster, this package on every worker. A worker that
    dies under a run is restarted by its nanny and the run handed to another; a run whose
    workers keep dying (``distributed.scheduler.allowed-failures`` + 1 times, 4 by default)
    is given up by Dask (``KilledWorker``) and recorded as ``error`` with ``worker_died:
    "KilledWorker"``, so that the campaign names it and running it again flies it again, as
    with the local pool.
    """

    def __init__(
        self, scheduler: str, workers: int | None = None, connect_timeout: float = 10.0
    ) -> None:
        if connect_timeout <= 0:
            raise UserError(f"--connect-timeout {connect_timeout}: must be positive")
        try:
            import distributed
        except ImportError:
            raise UserError(
                "--scheduler: needs the 'distributed' package; "
                "install it with: pip install 'landing-autonomy[cluster]'"
            ) from None
        self._cluster = None
        if scheduler == "local":
            self._cluster = distributed.LocalCluster(
                n_workers=max(1, int(workers or default_workers())),
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                dashboard_address=None,
            )
            address: Any = self._cluster
        else:
            if "://" not in scheduler or not scheduler.split("://", 1)[1]:
                raise UserError(
                    f"--scheduler {scheduler!r}: expected tcp://HOST:PORT or 'local'"
                )
            address = scheduler
        try:
            self._client = distributed.Client(
                address, timeout=f"{connect_timeout}s", set_as_default=False
            )
        except (OSError, TimeoutError, ValueError) as exc:
            self.close()
            raise UserError(
                f"--scheduler {scheduler}: cannot reach the scheduler ({exc})"
            ) from None
        threads = self._client.nthreads()
        self.workers = max(1, sum(threads.values()))

    def run(self, tasks: Sequence[RunTask]) -> Iterator[dict[str, Any]]:
        from distributed import KilledWorker, as_completed

        token = uuid.uuid4().hex[:8]
        futures = {
            self._client.submit(fly_run, task, pure=False, key=f"lander-{token}-{task.run_id}"): (
                task
            )
            for task in tasks
        }
        try:
            for future in as_completed(list(futures), loop=self._client.loop):
                task = futures[future]
                try:
                    yield future.result()
                except KilledWorker as exc:
                    yield error_record(
                        task, f"{WORKER_DIED} on every Dask worker that ran it (possibly out "
                        f"of memory; the workers' logs say why): {exc}",
                        worker_died="KilledWorker")
                except Exception as exc:  # lost data, unpicklable result
                    yield error_record(task, _format(exc))
        finally:
            self._client.cancel(list(futures))

    def close(self) -> None:
        client, cluster = getattr(self, "_client", None), self._cluster
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()


def make_backend(
    workers: int | None = None, scheduler: str | None = None, connect_timeout: float = 10.0
) -> Backend:
    """The local pool, or a Dask cluster when ``scheduler`` is given (connecting within
    ``connect_timeout`` seconds)."""
    if workers is not None and workers < 1:
        raise UserError(f"--workers {workers}: must be at least 1")
    if scheduler:
        return DaskCluster(scheduler, workers, connect_timeout)
    return LocalPool(workers)
