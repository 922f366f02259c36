"""A finer basis for the plan the search found (``optimizer.refine_basis``).

The flat plan's CP is a B-spline of ``coefficients`` per phase and coordinate; the search picks
the pattern of signs of gamma within that basis. On random problems the basis, not the pattern
or the regularity margin, held plans back: a random RPR swing-down's three-switch plan cost 2658
with 14 coefficients, 1711 with 20 and 1575 with 28, where Hermite-Simpson collocation (N = 200)
with the same pattern of signs imposed costs 1544 and without it 1522
(``benchmarks/zoo_gap.py``). The refinement solves the plan's pattern again with every knot
interval of every phase halved (``n`` coefficients of degree ``d`` become ``2 (n - d) + d``,
a basis that holds the coarser one exactly), started from the plan, its switch times held,
while a refinement lowers the cost by at least :data:`GAIN`, the schema's most coefficients
allow one more (at most :data:`HALVINGS`), and the search's deadline has not passed.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

from ..closedform.trajectory import sample
from ..problem import MAX_COEFFICIENTS, Problem
from ..runtime import progress
from .seeded import solve_pattern
from .switching import Solve, pattern_of

GAIN = 0.01
"""A finer basis is kept, and refined further, only when it lowers the cost by this fraction."""
ITERATIONS = 800
"""Ipopt iterations of one refinement, its certification rounds included (past them its best
feasible iterate stands): from the plan, a random RPR transfer took 99 (20 coefficients) and
272 (32), a random RPR swing-down 302 and 640."""
HALVINGS = 2
"""Most refinements (14 coefficients of degree 8 become 20, then 32): a third, to 56, lowered
the two plans above by 1.6 % and 1.7 % for 25 s and 28 s, and solved neither."""


def finer(problem: Problem) -> Problem | None:
    """The problem with every knot interval halved, or None past the schema's most
    coefficients (:data:`cpopt.problem.MAX_COEFFICIENTS`)."""
    o = problem.spec.optimizer
    count = 2 * (o.coefficients - o.degree) + o.degree
    if count > MAX_COEFFICIENTS:
        return None
    optimizer = o.model_copy(update={"coefficients": count})
    return replace(problem, spec=problem.spec.model_copy(update={"optimizer": optimizer}))


def refine_basis(problem: Problem, solve: Solve, best, deadline: float = math.inf) -> tuple:
    """Refine the basis of a solved plan ``best`` (see the module docstring).

    Parameters
    ----------
    problem : Problem
        The problem the search solved.
    solve : callable
        ``solve(problem, signs, switches, seed=None, ...) -> SignAttempt``
        (:func:`cpopt.flatopt.solve_for_signs`, its deadline bound).
    best : SignAttempt
        The search's plan (solved).
    deadline : float
        ``time.monotonic()`` after which no refinement starts.

    Returns
    -------
    tuple
        The best attempt, every refinement's attempt, and the figures for ``solver.search``
        (``basis``: the coefficients and objective of each refinement, its time [s] and why it
        stopped).
    """
    attempts, steps, tic = [], [], time.perf_counter()
    current, why = problem, f"{problem.spec.optimizer.coefficients} coefficients: the most"
    while len(steps) < HALVINGS:
        current = finer(current)
        if current is None:
            break
        if time.monotonic() > deadline:
            why = "search deadline reached"
            break
        count = current.spec.optimizer.coefficients
        progress.stage(f"flat optimizer: the plan's basis refined to {count} coefficients")
        step_tic = time.perf_counter()
        attempt = solve_pattern(solve, current, pattern_of(best), sample(best.plan), ITERATIONS)
        attempts.append(attempt)
        steps.append({"coefficients": count, "status": attempt.status,
                      "objective": attempt.objective, "iterations": attempt.iterations,
                      "time_s": time.perf_counter() - step_tic})  # fmt: skip
        gain = (best.objective - attempt.objective) / max(abs(best.objective), 1e-12)
        if attempt.status != "solved":
            why = f"{count} coefficients did not solve ({attempt.status}): stopped"
            break
        if gain < GAIN:
            why = f"{count} coefficients lowered the cost by {gain:.2%}: stopped"
            break
        best = attempt
        why = f"{count} coefficients: the most refinements ({HALVINGS})"
    figures = {"steps": steps, "time_s": time.perf_counter() - tic, "summary": why}
    return best, attempts, figures


__all__ = ["GAIN", "HALVINGS", "ITERATIONS", "finer", "refine_basis"]
