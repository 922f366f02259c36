"""A re-solve started from another plan: continuation along a parameter study.

A researcher who changes a mass, a duration or a limit and solves again has a plan of the
neighbouring problem. Started from it, the flat optimizer skips the switch search: the start's
pattern (its switch times and signs of gamma, where the new problem's pins allow them) is solved
once, from the start's own CP curves, xi and eta (:func:`cpopt.flatopt.warm_start.seeded_guess`
reproduces an exact plan). Measured on ``transfer_switch`` (seeded search: 178 iterations of
the flat solve from the collocation seed): with link 3 5 % heavier, 12 iterations from the
first plan, the same optimum as the whole search (43168.9); link 2 10 % heavier, 11; link 3
20 % heavier, 16.

When the start does not fit the problem (``curve: path_timing``, whose warm start is its own;
a pattern the pins refuse) or its pattern does not solve, :func:`cpopt.flatopt.optimize` runs
the usual search and its summary says so.
"""

from __future__ import annotations

import time

import numpy as np

from ..closedform.plan import CPPlan
from ..closedform.trajectory import Trajectory, sample
from ..problem import MAX_SWITCHES, Problem
from .seeded import Stage, solve_pattern
from .switching import Pattern, Search, Solve, agreeing, gamma_signs_on_grid, within_budget


def start_pattern(problem: Problem, start: CPPlan, sampled: Trajectory) -> Pattern | None:
    """The pattern of ``start`` (``sampled``: its samples) that ``problem`` allows: its switch
    times (at most the problem's ``gamma_switches``) with the signs the pins allow that agree
    with the start's gamma the longest; None for a path-timing problem or a start outside the
    motion."""
    o = problem.spec.optimizer
    duration = problem.nodes[-1].t
    times = tuple(float(start.nodes[i].t) for i in start.switches)
    if o.curve == "path_timing" or not np.isclose(start.nodes[-1].t, duration):
        return None
    budget = MAX_SWITCHES if o.gamma_switches == "auto" else o.gamma_switches
    times = tuple(t for t in within_budget(times, budget, duration) if 0 < t < duration)
    return agreeing(problem, times, gamma_signs_on_grid(problem, sampled))


def restart(problem: Problem, solve: Solve, start: CPPlan) -> tuple[Search | None, str]:
    """Solve ``problem`` with the pattern of ``start``, started from it.

    Returns
    -------
    Search or None
        The solved attempt as a search (``solver.search``: method ``start``), or None when the
        start does not fit or its pattern did not solve.
    str
        Why not, for the summary of the search that runs instead ("" when solved).
    """
    sampled = sample(start)
    pattern = start_pattern(problem, start, sampled)
    if pattern is None:
        return None, "the start does not fit this problem"
    figures, tic = Stage(), time.perf_counter()
    attempt = solve_pattern(solve, problem, pattern, sampled)
    figures.add(attempt, tic)
    if attempt.status != "solved":
        return None, f"the start's pattern ended {attempt.status}"
    summary = (
        f"{len(attempt.switch_times)} switch(es): started from the given plan, its pattern "
        f"[{', '.join(f'{t:.3f}' for t in pattern.times)}] s solved in {attempt.iterations} "
        "iterations"
    )
    search_figures = {"method": "start", "summary": summary, "flat": figures.as_dict()}
    return Search((attempt,), attempt, summary, search_figures), ""


__all__ = ["restart", "start_pattern"]
