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

``refine_basis: auto`` (the default) refines only a plan that costs more than :data:`AUTO_GAP`
above the seeded search's collocation seed (the same functional, solved by coarse collocation
of the full dynamics, N = 30: on the 30 draws of ``benchmarks/zoo.py --seed 31`` within 3.3 %
of collocation with N = 200 on 26, below it on two where N = 200 found a worse local optimum,
5.6 % and 7.5 % above on two), stops once the plan is within that gap, and gives the refinements
the time :func:`auto_deadline` allows. Measured on the draws of ``benchmarks/zoo.py --seed 31``
with a plan 5 % or more above its seed (refinements unbounded in time): a one-sign RPR
transfer 301.96 -> 249.94 (+0.7 s), a PPR swing-up 6809.6 -> 6460.3 after one round (+0.4 s),
a PRR transfer 273.67 -> 223.1 after one round (+0.5 s; the second, 209.2, took 5.7 s), an
RRR transfer 2836.6 -> 2630.7 (+0.3 s); a search whose seed has no plan, or no seeded search
(``gamma_switches: 0``), is not refined.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Literal

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
AUTO_GAP = 0.05
"""``refine_basis: auto`` refines a plan whose objective is more than this fraction above its
search's collocation seed's, while it stays so (:func:`seed_gap`). On 30 zoo draws of seed 31
the 21 plans within 5 % of their seed were within 6.5 % of collocation with N = 200; of the
nine above it, the five solved within 3 s each cost 3-18 % less with a finer basis."""
AUTO_MIN_TIME = 2.0
"""Seconds ``refine_basis: auto`` may spend refining at least (:func:`auto_deadline`)."""
AUTO_TIME_FACTOR = 1.0
"""``refine_basis: auto`` may spend this multiple of the search's own time refining, when that
is more than :data:`AUTO_MIN_TIME` (a refinement round from the plan took 0.1-0.5 s for 20
coefficients and 0.4-8.6 s for 32 on the zoo's draws): a search that took long found a
plan that is hard to improve, and doubling its time is the most the refinement adds."""


def seed_gap(search) -> float:
    """How far [fraction] the search's plan costs above its collocation seed (the seeded
    search's ``seed`` figures), NaN without a solved seed with a positive objective."""
    seed = search.figures.get("seed", {})
    objective = seed.get("objective", math.nan)
    if seed.get("status") != "solved" or not objective > 0:
        return math.nan
    return search.best.objective / objective - 1.0


def auto_deadline(started: float, deadline: float) -> float:
    """``time.monotonic()`` after which ``refine_basis: auto`` stops refining: the search's
    time since ``started`` (a ``time.monotonic()`` instant) times :data:`AUTO_TIME_FACTOR`,
    at least :data:`AUTO_MIN_TIME`, from now, and never past the search's ``deadline``."""
    now = time.monotonic()
    return min(deadline, now + max(AUTO_MIN_TIME, AUTO_TIME_FACTOR * (now - started)))


def wanted(setting: bool | Literal["auto"], curve: str, search) -> bool:
    """True when the search's solved plan gets its basis refined: ``refine_basis: true``, or
    ``auto`` with B-spline curves and the plan more than :data:`AUTO_GAP` above its seed."""
    if search.best.status != "solved":
        return False
    if setting == "auto":
        return curve == "bspline" and seed_gap(search) > AUTO_GAP
    return bool(setting)


def finer(problem: Problem) -> Problem | None:
    """The problem with every knot interval halved, or None past the schema's most
    coefficients (:data:`cpopt.problem.MAX_COEFFICIENTS`)."""
    o = problem.spec.optimizer
    count = 2 * (o.coefficients - o.degree) + o.degree
    if count > MAX_COEFFICIENTS:
        return None
    optimizer = o.model_copy(update={"coefficients": count})
    return replace(problem, spec=problem.spec.model_copy(update={"optimizer": optimizer}))


def refine_basis(
    problem: Problem, solve: Solve, best, deadline: float = math.inf, target: float = -math.inf
) -> tuple:
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
        ``time.monotonic()`` after which no refinement starts (a refinement still running
        then is stopped and not kept).
    target : float
        The objective at or below which no further refinement is made (``refine_basis:
        auto``: :data:`AUTO_GAP` above the seed's).

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
        if best.objective <= target:
            why = f"objective {best.objective:.6g} within {AUTO_GAP:.0%} of the seed's: stopped"
            break
        if time.monotonic() > deadline:
            why = "deadline reached"
            break
        count = current.spec.optimizer.coefficients
        progress.stage(f"flat optimizer: the plan's basis refined to {count} coefficients")
        step_tic = time.perf_counter()
        start = sample(best.plan)
        attempt = solve_pattern(solve, current, pattern_of(best), start, ITERATIONS,
                                deadline=deadline)  # fmt: skip
        attempts.append(attempt)
        steps.append({"coefficients": count, "status": attempt.status,
                      "objective": attempt.objective, "iterations": attempt.iterations,
                      "time_s": time.perf_counter() - step_tic})  # fmt: skip
        gain = (best.objective - attempt.objective) / max(abs(best.objective), 1e-12)
        if attempt.status != "solved":
            why = f"{count} coefficients did not solve ({attempt.status}): stopped"
            break
        if gain < GAIN:
            change = f"lowered the cost by {gain:.2%}" if gain >= 0 else "did not lower the cost"
            why = f"{count} coefficients {change}: stopped"
            break
        best = attempt
        why = f"{count} coefficients: the most refinements ({HALVINGS})"
    figures = {"steps": steps, "time_s": time.perf_counter() - tic, "summary": why}
    return best, attempts, figures


__all__ = [
    "AUTO_GAP",
    "AUTO_MIN_TIME",
    "AUTO_TIME_FACTOR",
    "GAIN",
    "HALVINGS",
    "ITERATIONS",
    "auto_deadline",
    "finer",
    "refine_basis",
    "seed_gap",
    "wanted",
]
