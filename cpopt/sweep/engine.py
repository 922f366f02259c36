"""The Dask side of a sweep: the cluster, one task per point, results as they complete.

By default a ``LocalCluster`` of one single-threaded worker process per core: BLAS, OpenMP
(MUMPS) and MKL are held to one thread in the workers (:data:`cpopt.sweep.task.THREAD_VARIABLES`),
and the workers are not daemonic processes, so that each point is solved in a child process
whose wall-clock limit holds as in ``cpopt solve``. The workers ignore Ctrl-C (the client
stops them). ``--scheduler tcp://host:8786`` connects to a running cluster instead.

A task whose worker is lost is run again by the scheduler (up to its
``distributed.scheduler.allowed-failures``, 3 by default); a task that raised is retried
:data:`RETRIES` times; a point still without a result becomes a ``worker_lost`` row.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
import uuid
from collections.abc import Callable, Iterator

from .spec import Point, SweepError
from .task import THREAD_VARIABLES, solve_point

RETRIES = 1
"""Extra runs of a task that raised (its worker died in a way the scheduler saw as an error)."""
CONNECT_TIMEOUT = "10s"
"""How long to wait for a ``--scheduler`` to answer."""


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """Processes started inside ignore Ctrl-C (a spawned process keeps the ignored SIGINT and
    Python then installs no KeyboardInterrupt handler): the client alone answers Ctrl-C."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def inside_finalizer(frame) -> bool:
    """True when ``frame`` or one of its callers is a ``__del__``: a signal lands in the
    innermost Python frame, which under Dask's ``Future.__del__`` may be asyncio's
    ``_write_to_self`` a few calls down (seen in CI: the KeyboardInterrupt raised there was
    printed as an ignored exception with its traceback)."""
    while frame is not None:
        if frame.f_code.co_name == "__del__":
            return True
        frame = frame.f_back
    return False


@contextlib.contextmanager
def _interrupt_noted() -> Iterator[list]:
    """Ctrl-C while the results come in is noted as well as raised: Python swallows a
    KeyboardInterrupt raised inside a ``__del__`` (Dask's ``Future.__del__`` runs often), and
    the sweep then went on recording the points whose solver children the same Ctrl-C had
    stopped as errors, and exited 1. A Ctrl-C that lands in a ``__del__``, or below one
    (:func:`inside_finalizer`), is only noted; the
    loop raises it before the next result is taken. Main thread with Python's own handler
    only (elsewhere nothing is noted)."""
    noted: list = []
    own = signal.getsignal(signal.SIGINT) is signal.default_int_handler
    if threading.current_thread() is not threading.main_thread() or not own:
        yield noted
        return

    def on_interrupt(signum, frame) -> None:
        noted.append(signum)
        if not inside_finalizer(frame):
            raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, on_interrupt)
    try:
        yield noted
    finally:
        signal.signal(signal.SIGINT, previous)


@contextlib.contextmanager
def connect(workers: int | None = None, scheduler: str | None = None):
    """A Dask ``Client``: on a new ``LocalCluster`` of ``workers`` single-threaded worker
    processes (default: one per core), or on the running scheduler at ``scheduler``.

    The cluster (a local one) and the client are closed on the way out, whatever happened.

    Raises
    ------
    SweepError
        When the scheduler cannot be reached.
    """
    import dask
    from dask.distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError) as err:
            raise SweepError(f"--scheduler {scheduler}: cannot connect ({err})") from None
        try:
            yield client
        finally:
            client.close()
        return
    env = dict.fromkeys(THREAD_VARIABLES, "1")
    config = {"distributed.worker.daemon": False, "distributed.nanny.pre-spawn-environ": env}
    with dask.config.set(config), _sigint_ignored():
        cluster = LocalCluster(
            n_workers=workers or os.cpu_count() or 1,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            # the scheduler's health and metrics server still listens: not on 8787, which
            # another cluster may hold (a warning), but on a free port of this machine only
            scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
            # the workers' own log lines would interleave with the sweep's progress, and on
            # Ctrl-C a worker whose scheduler closed first logs a heartbeat traceback; every
            # failure a point meets reaches the client (its exception, a lost worker) and the
            # table: the workers log nothing below CRITICAL
            silence_logs=logging.CRITICAL,
            env=env,
        )
    try:
        client = Client(cluster)
        try:
            from .quiet_workers import IgnoreCtrlC

            client.register_plugin(IgnoreCtrlC())
            yield client
        finally:
            client.close()
    finally:
        cluster.close()


def slots(client) -> int:
    """Points that run at once: the worker threads of the cluster."""
    return max(sum(client.nthreads().values()), 1)


def run(client, points: list[Point], source: str, done: Callable[..., None]) -> None:
    """Submit one task per point and call ``done(point, outcome, lost)`` as each completes
    (in the order they complete). ``outcome`` is None when the task never returned (``lost``
    says why). On any exception (Ctrl-C included) the tasks left are cancelled.
    """
    from dask.distributed import as_completed

    futures = {}
    for point in points:
        future = client.submit(
            solve_point,
            point.data,
            f"{source} [point {point.name}]",
            key=f"cpopt-sweep-{point.name}-{uuid.uuid4().hex[:12]}",  # one run, one key
            retries=RETRIES,
        )
        futures[future] = point
    try:
        with _interrupt_noted() as noted:
            for future in as_completed(futures):
                if noted:  # a Ctrl-C swallowed inside a __del__: this result came after it
                    raise KeyboardInterrupt
                point = futures.pop(future)
                try:
                    outcome, lost = future.result(), ""
                except Exception as err:  # KilledWorker, a task that raised twice, a lost scheduler
                    outcome, lost = None, f"{type(err).__name__}: {err}"
                done(point, outcome, lost)
    finally:
        if futures:
            with contextlib.suppress(Exception):
                client.cancel(list(futures), force=True)


__all__ = ["CONNECT_TIMEOUT", "RETRIES", "connect", "run", "slots"]
