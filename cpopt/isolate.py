"""One problem solved in a child process, so that its wall-clock limit holds without exception.

The limit is enforced inside :func:`cpopt.pipeline.solve` by signals and checks, but a long
native call that never looks at the clock (CasADi building a large NLP: minutes for thousands
of samples) cannot be stopped from inside. The command line therefore solves each problem in a
forked child process: the child runs :func:`cpopt.pipeline.solve` (which stops itself at the
limit and returns the partial solution) and sends the :class:`~cpopt.results.Solution` back;
the parent kills a child that overruns the limit by :data:`GRACE` seconds and reports status
``time_limit`` with the last stage the child reached. Time the child's limit does not count (a
one-time compile, :func:`cpopt.runtime.budget.uncounted`) is not counted here either. Where
``fork`` is not available the problem is solved in this process.
"""

from __future__ import annotations

import copy
import multiprocessing
import os
import signal
import threading
import time

from .pipeline import solve, time_limit_solution
from .problem import Problem
from .results import Solution
from .runtime import progress

GRACE = 2.0
"""Seconds a child gets beyond the limit to stop by itself and send what it has."""
ORPHAN_CHECK = 0.5
"""Seconds between a child's checks that its parent is still there."""


def _exit_with_parent() -> None:
    """End this child when its parent is gone (killed: nobody will read the solution, and a
    child blocked sending it would stay forever). Watched by a daemon thread."""
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(ORPHAN_CHECK)
        os._exit(1)

    threading.Thread(target=watch, name="cpopt-parent-watch", daemon=True).start()


def _child(problem: Problem, conn) -> None:
    _exit_with_parent()
    signal.set_wakeup_fd(-1)  # the parent's Ctrl-C watcher is the parent's alone
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # a Ctrl-C ends the child at once, silently
    relay = copy.copy(progress.current())
    relay.listener = lambda text: conn.send(("stage", text))
    relay.on_uncounted = lambda seconds: conn.send(("uncounted", seconds))
    try:
        with progress.reporting(relay, problem.name):
            solution = solve(problem)
        conn.send(("solution", solution))
    except BaseException as err:  # a bug: the parent raises it with this text
        conn.send(("error", f"{type(err).__name__}: {err}"))
    finally:
        conn.close()


def solve_isolated(problem: Problem) -> Solution:
    """:func:`cpopt.pipeline.solve` in a child process killed when it overruns its limit.

    Returns
    -------
    Solution
        The child's solution; status ``time_limit`` (no plan) when it had to be killed, and
        ``not_converged`` when it ended without sending one (a crash in native code).

    Raises
    ------
    RuntimeError
        When the child raised (a bug in cpopt), with its message.
    KeyboardInterrupt
        On Ctrl-C (the child is killed first).
    """
    if "fork" not in multiprocessing.get_all_start_methods():
        return solve(problem)
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_child, args=(problem, send), daemon=True)
    start = time.monotonic()
    child.start()
    send.close()
    stage = "starting"  # the last stage the child reported
    deadline, paused = start + problem.max_time + GRACE, None
    try:
        # a block the child's limit does not count (a one-time compile) pauses the deadline
        while receive.poll(None if paused else max(deadline - time.monotonic(), 0)):
            kind, value = receive.recv()
            if kind == "solution":
                return value
            if kind == "error":
                raise RuntimeError(f"solving {problem.name} failed: {value}")
            if kind == "uncounted":
                if value is None:
                    paused = time.monotonic()
                else:
                    deadline, paused = deadline + time.monotonic() - paused, None
                continue
            stage = value
        return _killed(problem, child, stage, time.monotonic() - start)
    except EOFError:
        child.join()
        if child.exitcode == -signal.SIGINT:  # Ctrl-C reached the child first (same group)
            raise KeyboardInterrupt from None
        return Solution(
            problem.name,
            "not_converged",
            problem.planner,
            message=f"the solver process ended without a result (exit code {child.exitcode}) "
            f"while {stage}",
        )
    finally:
        if child.is_alive():
            child.kill()
        child.join()
        receive.close()


def _killed(problem: Problem, child, stage: str, elapsed: float) -> Solution:
    child.kill()
    why = (
        ", stopped inside a call that does not check the clock, such as building the optimizer's "
        "NLP"
    )
    return time_limit_solution(problem, stage, elapsed, why)


__all__ = ["GRACE", "solve_isolated"]
