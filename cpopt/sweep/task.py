"""What a Dask worker runs for one point: plain problem data in, a solution out.

No CasADi object crosses the wire: the task receives the point's problem data (a dict), builds
the problem and its solver inside the worker (the compiled-function cache of
:mod:`cpopt.runtime.compiled` is the worker machine's own) and sends back the
:class:`~cpopt.results.Solution`, which the client writes as ``cpopt solve`` would.
"""

from __future__ import annotations

import multiprocessing
import os
import socket
import time
from dataclasses import dataclass

THREAD_VARIABLES = (
    "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)  # fmt: skip
"""Environment variables that keep BLAS and MUMPS (OpenMP) single-threaded in a worker: one
point per core, not one point fighting its neighbours for every core."""


@dataclass(frozen=True)
class Outcome:
    """A point's result as it comes back from a worker.

    Attributes
    ----------
    solution : Solution or None
        The solution (None when the task raised: ``error`` says what).
    wall_s : float
        Wall time of the task in the worker, the problem's validation included [s].
    worker : str
        ``host:pid`` of the worker process.
    error : str
        ``Type: message`` of an exception raised inside the task (a bug), else empty.
    """

    solution: object
    wall_s: float
    worker: str
    error: str = ""


def _can_fork_children() -> bool:
    """True where :func:`cpopt.isolate.solve_isolated` may start its child process: a daemonic
    process (a Dask worker started with the default ``distributed.worker.daemon: True``) may
    not have children."""
    return not multiprocessing.current_process().daemon


def solve_point(data: dict, source: str) -> Outcome:
    """Validate and solve one point in this process (the task a worker runs).

    The solve is :func:`cpopt.isolate.solve_isolated` where this process may have children
    (its wall-clock limit then holds even inside a native call), else
    :func:`cpopt.pipeline.solve` (the limit is checked by Ipopt and between stages).

    Parameters
    ----------
    data : dict
        The point's problem data.
    source : str
        Where it came from (shown in messages).

    Returns
    -------
    Outcome
        Never raises for a failed solve; an exception inside cpopt is returned as ``error``.
    """
    start = time.perf_counter()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    try:
        from ..problem import parse_problem

        problem = parse_problem(data, source)
        if _can_fork_children():
            from ..isolate import solve_isolated

            solution = solve_isolated(problem)
        else:
            from ..pipeline import solve

            solution = solve(problem)
    except (Exception, KeyboardInterrupt) as err:  # Ctrl-C reached the solver's child process
        return Outcome(None, time.perf_counter() - start, worker, f"{type(err).__name__}: {err}")
    return Outcome(solution, time.perf_counter() - start, worker)


__all__ = ["THREAD_VARIABLES", "Outcome", "solve_point"]
