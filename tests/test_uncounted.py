"""Time a time limit does not count: a one-time compile of C code on a fresh machine.

A cold compile cache (a fresh machine, CI, a new release) compiles the sample and verification
libraries once, for seconds; a time limit that counted it stopped on the first run a solve that
the next run finishes (``--time-limit 3`` on ``swing_up_switches.yaml`` ended ``time_limit``
with a cold cache, ``solved`` with a warm one). Sleeps below stand for long work; the checks
are on what was stopped and what the budget counted, with tolerances far above a busy
machine's scheduling jitter.
"""

import time
from pathlib import Path

import casadi as ca
import pytest

import cpopt.isolate
from cpopt.problem import load_problem
from cpopt.results import Solution
from cpopt.runtime import budget as budget_module
from cpopt.runtime.budget import Budget, TimeLimitExceeded, enforced, remaining, uncounted
from cpopt.runtime.compiled import load_library

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"


def test_an_uncounted_block_is_not_stopped_and_the_budget_resumes_after_it():
    """A block twice as long as the limit runs to its end; the budget then has what it had
    before the block (0.2 s), and the limit stops the work after it."""
    with pytest.raises(TimeLimitExceeded), enforced(Budget(0.3)) as budget:
        time.sleep(0.1)
        with uncounted():
            time.sleep(0.6)  # the timer fires at 0.3 s and repeats: none stops this
        left = remaining()
        assert 0.1 < left < 0.25
        tic = time.monotonic()
        try:
            time.sleep(5.0)
        finally:
            assert time.monotonic() - tic == pytest.approx(left, abs=0.3)
    assert budget.uncounted == pytest.approx(0.6, abs=0.1) and budget.fired


def test_a_compile_under_a_budget_is_not_counted(tmp_path):
    """A library whose generation takes longer than the limit (the build sleeps 0.5 s of a
    0.3-s budget) is compiled, not stopped, and the budget still has most of its time."""
    x = ca.SX.sym("x")

    def slow_build() -> list[ca.Function]:
        time.sleep(0.5)
        return [ca.Function("square", [x], [x**2])]

    with enforced(Budget(0.3)) as budget:
        library = load_library("uncounted-test", [], slow_build, directory=tmp_path)
        assert remaining() > 0.2
    assert library.compiled and float(library.functions["square"](3.0)) == 9.0
    assert budget.uncounted >= 0.5 and not budget.fired


def test_the_solver_process_is_not_killed_during_a_block_its_limit_does_not_count(monkeypatch):
    """The command line's child process (cpopt.isolate) is killed once it overruns its limit
    by isolate.GRACE seconds; a child whose uncounted block outlasts limit plus grace sends
    its solution and is not killed."""
    problem = load_problem(PROBLEMS / "paper_transfer.yaml").replace(
        **{"optimizer.solver.max_time": 0.2}
    )
    pause = problem.max_time + cpopt.isolate.GRACE + 0.5

    def solve(problem):
        with enforced(Budget(problem.max_time)), uncounted():
            time.sleep(pause)
        return Solution(problem.name, "solved", problem.planner, message="after the block")

    monkeypatch.setattr(cpopt.isolate, "solve", solve)
    solution = cpopt.isolate.solve_isolated(problem)
    assert solution.status == "solved" and solution.message == "after the block"


def test_grant_grace_grants_its_documented_seconds():
    """GRACE was rebound by the Ctrl-C grace of the same name further down the module."""
    assert budget_module.GRACE == 0.9 and budget_module.INTERRUPT_GRACE == 1.0
    with enforced(Budget(0.1)) as budget:
        budget_module.grant_grace()
        assert budget.seconds == pytest.approx(1.0)
