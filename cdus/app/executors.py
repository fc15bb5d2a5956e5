"""Where a sweep's runs execute: this process, local processes, or a Dask cluster.

All three share one small interface (``submit``, ``wait`` for the first done, ``result``,
``close``) so the sweep keeps a bounded window of runs in flight and streams each result as it
comes. A task never raises (the run catches its own failures); an exception from ``result`` is
the executor's (a worker killed, the cluster gone), and the sweep does not record that run.

Dask: ``dask.distributed`` (the ``cluster`` extra). Without an address a ``LocalCluster`` of
``jobs`` worker processes is started, bound to 127.0.0.1, dashboard off; with an address the
scheduler there is used as it is (its workers need only the cdus package installed).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import os
import signal
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import get_context
from typing import Any, Callable, Iterator

from cdus.scenario.config import ConfigError

EXECUTORS = ("local", "dask")
CONNECT_TIMEOUT_S = 10.0
FRUITLESS_POOLS = 2  # local pools in a row that may break before finishing a task before the executor gives up
# A LocalCluster on loopback only: the scheduler, the workers and the scheduler's HTTP server
# (health checks; it always runs, on 8787 by default) on 127.0.0.1, on free ports, no dashboard.
LOCAL_CLUSTER = {"host": "127.0.0.1", "dashboard_address": None, "worker_dashboard_address": None,
                 "scheduler_kwargs": {"dashboard": False, "dashboard_address": "127.0.0.1:0"}}


class Executor:
    """The interface; ``slots`` is how many tasks the sweep keeps in flight."""
    name = "?"
    slots = 1

    def submit(self, fn: Callable, *args: Any) -> Any:
        raise NotImplementedError

    def wait(self, pending: set) -> tuple[set, set]:
        """Block until at least one of ``pending`` is done: (done, not done)."""
        done, not_done = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
        return set(done), set(not_done)

    def result(self, fut: Any) -> Any:
        return fut.result()

    def cancel(self, pending: set) -> None:
        for f in pending:
            f.cancel()

    def close(self) -> None:
        pass

    def describe(self) -> str:
        return self.name

    def __enter__(self) -> "Executor":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


class InlineExecutor(Executor):
    """Runs each task in this process when it is submitted (``jobs=1``)."""
    name = "local (this process)"
    slots = 1

    def submit(self, fn: Callable, *args: Any) -> cf.Future:
        fut: cf.Future = cf.Future()
        try:
            fut.set_result(fn(*args))
        except Exception as e:  # the task's own errors are caught inside it; this is a bug, kept as a lost run
            fut.set_exception(e)
        return fut


class ProcessExecutor(Executor):
    """A pool of ``jobs`` spawned processes of this machine.

    A worker process that dies (killed, out of memory) breaks the whole pool: the runs in
    flight on it come back as the executor's failures (lost, run again by the next call) and
    the next ``submit`` starts a new pool, so the sweep goes on. After ``FRUITLESS_POOLS``
    pools in a row broke before finishing any task (the processes cannot start, e.g. a
    script without the ``__main__`` guard), ``submit`` raises ``BrokenProcessPool``."""

    def __init__(self, jobs: int):
        self.jobs = jobs
        self.slots = 2 * jobs
        self.name = f"local ({jobs} processes)"
        self.pool = self._new_pool()
        self.finished = 0  # tasks the current pool finished
        self.replaced = 0  # broken pools replaced
        self.fruitless = 0  # pools in a row that broke before finishing a task
        self.owner: dict[cf.Future, cf.ProcessPoolExecutor] = {}

    def _new_pool(self) -> cf.ProcessPoolExecutor:
        return cf.ProcessPoolExecutor(max_workers=self.jobs, mp_context=get_context("spawn"),
                                      initializer=_die_with_parent, initargs=(os.getpid(),))

    def submit(self, fn: Callable, *args: Any) -> cf.Future:
        try:
            fut = self.pool.submit(fn, *args)
        except BrokenProcessPool:
            self.fruitless = 0 if self.finished else self.fruitless + 1
            if self.fruitless >= FRUITLESS_POOLS:  # its processes die before finishing anything: they cannot start
                raise
            self.pool.shutdown(wait=False, cancel_futures=True)
            self.pool, self.finished = self._new_pool(), 0
            self.replaced += 1
            fut = self.pool.submit(fn, *args)
        self.owner[fut] = self.pool
        return fut

    def result(self, fut: Any) -> Any:
        pool = self.owner.pop(fut, None)
        value = fut.result()
        if pool is self.pool:
            self.finished += 1
        return value

    def cancel(self, pending: set) -> None:
        self.pool.shutdown(wait=False, cancel_futures=True)

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)


PARENT_POLL_S = 0.5


def _die_with_parent(parent: int) -> None:
    """In a pool worker: exit once the driver that started it is gone. A driver killed with
    SIGKILL cannot stop its pool, and the workers would wait on its queue forever."""
    import threading
    import time

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="cdus-parent-watch", daemon=True).start()


class DaskExecutor(Executor):
    """A ``dask.distributed`` client: of the scheduler at ``address``, or of a LocalCluster
    of ``jobs`` processes on 127.0.0.1 that this object starts and stops."""

    def __init__(self, address: str | None = None, jobs: int | None = None,
                 connect_timeout: float = CONNECT_TIMEOUT_S):
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise ConfigError("command line", [("--executor", "the Dask executor needs dask.distributed: pip install "
                                                              "'cdus[cluster]'")]) from None
        self.cluster = None
        if address is not None:
            try:
                _probe(address, connect_timeout)  # a failed Client() complains again when collected
                self.client = Client(address, timeout=connect_timeout, set_as_default=False)
            except Exception as e:  # OSError, TimeoutError, ValueError (a malformed address)
                why = str(e).splitlines()[0] if str(e) else type(e).__name__
                raise ConfigError("command line", [("--cluster", f"no Dask scheduler reachable at {address!r} within "
                                                                 f"{connect_timeout:g} s ({why}); start one with `dask "
                                                                 f"scheduler --host 127.0.0.1` and give its "
                                                                 f"address, e.g. tcp://127.0.0.1:8786")]) from None
            self.name = f"dask ({address})"
        else:
            n = jobs or os.cpu_count() or 1
            with _sigint_ignored():  # the workers inherit it: Ctrl-C is the driver's to handle, which stops them
                self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, **LOCAL_CLUSTER)
            self.client = Client(self.cluster, set_as_default=False)
            self.name = f"dask (LocalCluster, {n} processes)"
        nthreads = self.client.nthreads()
        self.workers = len(nthreads)  # 0: a scheduler no worker has joined yet (the runs wait for one)
        self.slots = max(8, 2 * sum(nthreads.values()))

    def submit(self, fn: Callable, *args: Any) -> Any:
        return self.client.submit(fn, *args, pure=False)

    def wait(self, pending: set) -> tuple[set, set]:
        from distributed import wait

        with self.client.as_current():  # not set as the process's default client (a notebook may have its own)
            done, not_done = wait(list(pending), return_when="FIRST_COMPLETED")
        return set(done), set(not_done)

    def cancel(self, pending: set) -> None:
        if pending:
            self.client.cancel(list(pending))

    def close(self) -> None:
        try:
            self.client.close()
        finally:
            if self.cluster is not None:
                self.cluster.close()


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """SIGINT ignored while worker processes are started (they inherit that), so a terminal's
    Ctrl-C, which reaches the whole process group, stops the sweep through the driver alone
    instead of printing a traceback from every worker. Only the main thread can do it."""
    try:
        old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def _probe(address: str, timeout: float) -> None:
    """Open and close one connection to the scheduler at ``address``; raises if it cannot."""
    import asyncio

    from distributed.comm import connect

    async def once() -> None:
        comm = await connect(address, timeout=timeout)
        await comm.close()

    # connect's timeout bounds the TCP connect, not Dask's handshake after it: a listener that
    # accepts and says nothing (not a scheduler) would hang here forever without this bound.
    try:
        asyncio.run(asyncio.wait_for(once(), timeout))
    except asyncio.TimeoutError:
        raise TimeoutError(f"{address} accepted the connection but did not answer as a Dask scheduler") from None


def make_executor(executor: str = "local", cluster: str | None = None, jobs: int | None = None,
                  connect_timeout: float = CONNECT_TIMEOUT_S) -> Executor:
    """``executor="local"`` (processes of this machine; ``jobs=1``: this process),
    ``"dask"`` (a LocalCluster), or any ``cluster`` address (a running Dask scheduler)."""
    if executor not in EXECUTORS:
        raise ConfigError("command line", [("--executor", f"expected one of {', '.join(EXECUTORS)}, got {executor!r}")])
    if jobs is not None and jobs < 1:
        raise ConfigError("command line", [("--jobs", f"must be at least 1, got {jobs}")])
    if cluster is not None:
        return DaskExecutor(cluster, connect_timeout=connect_timeout)
    if executor == "dask":
        return DaskExecutor(None, jobs)
    n = jobs or os.cpu_count() or 1
    return InlineExecutor() if n == 1 else ProcessExecutor(n)
