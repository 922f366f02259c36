"""The next best solved plans of a search, for when its best one fails verification.

The search ranks plans by their flat objective, certified |gamma| >= gamma_min at every
sample; the simulation of the full dynamics comes after it (:mod:`cpopt.verify.simulate`) and
can still fail, for instance a closed-loop simulation that diverges near a switch whose torque
jumps by hundreds of N m. The search's other solved plans (the one-sign bound among them) are
then verified in the search's order, and the first that passes is returned: ``auto`` may not
end ``verification_failed`` where the one-sign plan of the same file verifies.
"""

from __future__ import annotations

from collections.abc import Iterator

from .switching import Search, preference

RUNNER_UPS = 3
"""Most plans verified after the search's best failed (each verification takes 0.05-0.3 s on
the zoo's draws)."""


def runner_ups(result, failure: str, count: int = RUNNER_UPS) -> Iterator:
    """The OptimizeResults of the next best solved attempts of ``result``'s search (at most
    ``count``, best first, each plan once), its summary saying that the best plan failed
    verification (``failure``: why) and ``solver.search.method`` ``runner_up``.

    Parameters
    ----------
    result : OptimizeResult
        A solved flat optimization whose plan failed verification.
    failure : str
        What the verification said.
    count : int
        Most alternatives yielded.
    """
    from . import result_of  # the package builds results; it imports this module's siblings

    details = result.solver.details
    best = result.plan
    solved = [a for a in details.sign_choices if a.status == "solved" and a.plan is not best]
    seen: set = set()
    for attempt in sorted(solved, key=preference, reverse=True):
        key = (attempt.signs, attempt.switch_times, round(attempt.objective, 6))
        if key in seen:
            continue
        seen.add(key)
        if len(seen) > count:
            return
        summary = (
            f"{details.search}; its plan (objective {result.solver.objective:.6g}) failed "
            f"verification ({failure}): the next solved plan, objective {attempt.objective:.6g}"
            f", signs {'/'.join(attempt.signs)}"
        )
        figures = {**details.search_figures, "method": "runner_up", "summary": summary}
        yield result_of(Search(details.sign_choices, attempt, summary, figures))


__all__ = ["RUNNER_UPS", "runner_ups"]
