"""A search stopped by the hard time limit keeps the best plan it had solved.

Every search plans its stages by its own deadline (the limit less a reserve for sampling and
verifying, :func:`cpopt.flatopt.search_deadline`) and returns its best plan by then. A stage
can still overrun it (an NLP build or an Ipopt iteration that takes longer than the reserve
left), and the budget's timer then stops the search wherever it is
(:mod:`cpopt.runtime.budget`). Losing the plans solved before that would turn a solved
problem into ``time_limit``; so every attempt is recorded as it returns, and a stopped search
ends with the best solved one (status ``solved``), given the budget's grace to be verified.
"""

from __future__ import annotations

from collections.abc import Callable

from ..problem import Problem
from ..runtime import progress
from ..runtime.budget import grant_grace, remaining
from .switching import Search, preference


class Recorded:
    """A solve function (``solve(problem, signs, ...) -> SignAttempt``) that keeps every
    attempt it returned, in order, in :attr:`made`."""

    def __init__(self, solve: Callable) -> None:
        self.solve = solve
        self.made: list = []

    def __call__(self, *args, **options):
        attempt = self.solve(*args, **options)
        self.made.append(attempt)
        return attempt


def stopped_search(problem: Problem, made: list) -> Search | None:
    """The search that the time limit stopped, as if it had returned: the best solved attempt
    among ``made`` (``solver.search.method`` ``stopped``), the budget's grace granted to
    verify it; None when none had solved (the stop then stands: status ``time_limit``)."""
    solved = [a for a in made if a.status == "solved"]
    if not solved:
        return None
    elapsed = problem.max_time - remaining()  # before the grace extends the budget
    grant_grace()
    best = max(solved, key=preference)
    summary = (
        f"stopped by the time limit of {problem.max_time:g} s inside a stage that overran the "
        f"search's deadline (after {elapsed:.3g} s): the best of the {len(solved)} plan(s) solved "
        f"by then, objective {best.objective:.6g}, signs {'/'.join(best.signs)}"
    )
    progress.stage(f"flat optimizer: {summary}")
    return Search(tuple(made), best, summary, {"method": "stopped", "summary": summary})
