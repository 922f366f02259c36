"""The switch search seeded by a coarse unconstrained collocation (``optimizer.switch_search:
seed``, the default; route (b) of issue 11).

1. **Seed** (:func:`cpopt.flatopt.seed.coarse_seed`): where the unconstrained optimum's gamma
   crosses zero gives the switch times and the signs between them.
2. **Flat solve** of that pattern, started from the seed (B-spline coefficients fitted to its
   CP, xi and eta from its state, :func:`cpopt.flatopt.warm_start.seeded_guess`), the switch
   times held at the seed's crossings: a free switch time in a short phase scales every CP
   derivative there by a power of the phase's length, and Ipopt was measured to wander for
   hundreds of iterations with it (the benchmark transfer: 500 iterations, not converged, with
   free times; 361 and solved, 1.0014 times collocation's cost, with held ones).
3. **Polish**: the patterns one switch away (:func:`cpopt.flatopt.switching.neighbours`),
   each started from the plan solved so far and given at most
   :data:`~cpopt.flatopt.switching.POLISH_LIMIT` iterations and abandoned once clearly
   dominated (:func:`~cpopt.flatopt.switching.dominated`), while the polish has spent less
   than the flat solve did; the cheapest solved plan is kept. A plan that already costs no
   more than :data:`POLISH_GAIN` above the seed (the unconstrained optimum on a coarse grid)
   is not polished: no pattern can gain more than that (the benchmark transfer: 40427 against
   the seed's 40741, where the polish spent 150 iterations, 2 s, and found nothing).

Nothing here raises on a valid problem: a seed that fails or suggests no allowed pattern hands
the problem to the greedy search (:func:`cpopt.flatopt.switching.search`), which the summary
says; so does a seeded pattern that neither its seeded start, the closed form nor the polish
solved (the swing-up with the holding torque, links 1 and 2 heavier and T = 2 s: the seed's
three switches ran to the iteration limit, the greedy search solves one).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from .. import progress
from ..problem import MAX_SWITCHES, Problem
from ..trajectory import sample
from .seed import Seed, coarse_seed
from .switching import (
    POLISH_LIMIT,
    Pattern,
    Search,
    Solve,
    dominated,
    neighbours,
    pattern_of,
    preference,
    seed_pattern,
    with_switches,
)
from .switching import search as greedy_search


@dataclass
class Stage:
    """Iterations and wall time [s] of one stage of the search."""

    iterations: int = 0
    time_s: float = 0.0
    tried: int = 0

    def add(self, attempt, tic: float) -> None:
        """Count an attempt that started at ``tic`` (time.perf_counter)."""
        self.iterations += attempt.iterations
        self.time_s += time.perf_counter() - tic
        self.tried += 1

    def as_dict(self) -> dict:
        """JSON-ready figures."""
        return {"iterations": self.iterations, "time_s": self.time_s, "patterns": self.tried}


POLISH_GAIN = 0.01
"""Relative cost above the seed's below which the polish is skipped."""


def worth_polishing(problem: Problem, best, seed: Seed) -> bool:
    """True when the solved plan ``best`` may still gain from the polish: its objective is more
    than :data:`POLISH_GAIN` above the seed's. The seed's objective is the same functional
    without the regularity constraint (a lower bound up to its coarse grid's error), so it is
    compared only when the motion's duration is fixed (a seed keeps freed times at their
    guesses)."""
    if best.status != "solved" or not math.isfinite(seed.report.objective):
        return best.status == "solved"
    if "duration" in problem.free:
        return True
    return best.objective > (1 + POLISH_GAIN) * seed.report.objective


def solve_pattern(
    solve: Solve, problem: Problem, pattern: Pattern, start, limit=None, abandon=None
):
    """Solve one pattern with its switch times held, started from the trajectory ``start``
    (from the closed form through the nodes when it is None); ``limit`` and ``abandon`` as in
    :func:`cpopt.flatopt.solve_for_signs`."""
    augmented, switches = with_switches(problem, pattern.times, free_times=False)
    return solve(augmented, pattern.signs, switches, seed=start, limit=limit, abandon=abandon)


def _better(a, b) -> bool:
    """True when attempt a is a better plan than b (:func:`~cpopt.flatopt.switching.preference`)."""
    return preference(a) > preference(b)


def polish(solve: Solve, problem: Problem, best, budget: float, figures: Stage):
    """The cheapest plan among ``best`` and the patterns one switch away from it, each started
    from ``best``'s plan and capped at POLISH_LIMIT iterations, tried while the polish has
    spent less than ``budget`` seconds. Returns the best attempt and every attempt made."""
    attempts = []
    start = sample(best.plan)
    for pattern in neighbours(problem, pattern_of(best)):
        if figures.time_s >= budget:
            break
        progress.stage(f"switch search: polish, {len(pattern.times)} switch(es)")
        tic = time.perf_counter()
        # a neighbour still at twice the plan's cost after 30 iterations will not win (the
        # swing-up with two switches: both neighbours ran to the limit, 6.9 s, at 1e5-1e6)
        abandon = dominated(best.objective)
        attempt = solve_pattern(solve, problem, pattern, start, POLISH_LIMIT, abandon)
        figures.add(attempt, tic)
        attempts.append(attempt)
        if attempt.status == "solved" and _better(attempt, best):
            best = attempt
    return best, attempts


def search(problem: Problem, solve: Solve) -> Search:
    """The seeded switch search (see the module docstring).

    Parameters
    ----------
    problem : Problem
        A problem with ``gamma_switches`` other than 0.
    solve : callable
        ``solve(problem, signs, switches, seed=None, limit=None) -> SignAttempt``
        (:func:`cpopt.flatopt.solve_for_signs`).

    Returns
    -------
    Search
        Every attempt, the best, a summary and the figures of the seed, the flat solve and the
        polish (``solution.json``: ``solver.search``).
    """
    wanted = problem.spec.optimizer.gamma_switches
    budget = MAX_SWITCHES if wanted == "auto" else wanted
    progress.stage("switch search: coarse collocation seed")
    seed = coarse_seed(problem)
    pattern = seed_pattern(problem, seed, budget) if seed.trajectory is not None else None
    if pattern is None:
        return _greedy_after(problem, solve, seed)
    flat, tried = Stage(), []
    tic = time.perf_counter()
    best = solve_pattern(solve, problem, pattern, seed.trajectory)
    flat.add(best, tic)
    tried.append(best)
    if best.status != "solved":  # the closed form through the seed's switch states
        tic = time.perf_counter()
        retry = solve_pattern(solve, problem, pattern, None)
        flat.add(retry, tic)
        tried.append(retry)
        best = retry if _better(retry, best) else best
    polished = Stage()
    if worth_polishing(problem, best, seed):
        best, more = polish(solve, problem, best, flat.time_s, polished)
        tried += more
        finish = f"polish tried {polished.tried} neighbour(s)"
    else:
        finish = "no polish" + (
            f" (within {POLISH_GAIN:.0%} of the seed's cost)" if best.status == "solved" else ""
        )
    method = "seed"
    if best.status != "solved":  # the greedy search starts from fewer switches
        best, method, said = _greedy_if_better(problem, solve, best, tried)
        finish += f"; not solved, then greedy search: {said}"
    summary = (
        f"{len(best.switch_times)} switch(es) ({wanted} asked): seed crossings at "
        f"{_times(seed.report.crossings)}, pattern {_times(pattern.times)}; {finish}"
    )
    figures = {
        "method": method,
        "summary": summary,
        "seed": seed.report.as_dict(),
        "flat": flat.as_dict(),
        "polish": polished.as_dict(),
    }
    return Search(tuple(tried), best, summary, figures)


def _greedy_if_better(problem: Problem, solve: Solve, best, tried: list) -> tuple:
    """After the seed's pattern did not solve: the greedy search's best if it beats ``best``
    (its attempts added to ``tried``), the method that found the plan kept, and the greedy
    search's summary."""
    progress.stage("switch search: the seed's pattern did not solve, greedy search")
    result = greedy_search(problem, solve)
    tried += list(result.attempts)
    if _better(result.best, best):
        return result.best, "greedy", result.summary
    return best, "seed", result.summary


def _greedy_after(problem: Problem, solve: Solve, seed: Seed) -> Search:
    """The greedy search, when the seed failed or the pins allow none of its patterns."""
    found = seed.report
    why = "failed" if seed.trajectory is None else "suggested no pattern the fixed signs allow"
    result = greedy_search(problem, solve)
    summary = f"seed {why} ({found.status}): greedy search; " + result.summary
    figures = {"method": "greedy", "summary": summary, "seed": found.as_dict()}
    return Search(result.attempts, result.best, summary, figures)


def _times(times) -> str:
    return "[" + ", ".join(f"{t:.3f}" for t in times) + "] s"


__all__ = ["Stage", "polish", "search", "solve_pattern"]
