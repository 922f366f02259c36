"""When a run of the flat NLP is abandoned because another plan has clearly beaten it
(status ``dominated``): the rule the switch search's stages share
(:mod:`cpopt.flatopt.switching`, :mod:`cpopt.flatopt.seeded`)."""

from __future__ import annotations

import math

DOMINATED_AFTER = 30
"""Iterations after which a run is abandoned at :data:`DOMINATED_FACTOR` times the best."""
DOMINATED_FACTOR = 2.0
"""A run whose objective is still this many times a solved pattern's is abandoned."""
DOMINATED_EARLIEST = 10
"""Iterations a run gets before it may be abandoned at all."""


def dominated_factor(iteration: int) -> float:
    """How many times the best objective a run may still be at ``iteration`` without being
    abandoned: DOMINATED_FACTOR (DOMINATED_AFTER / iteration)^2 from DOMINATED_EARLIEST
    iterations on (18 at 10, 4.5 at 20), DOMINATED_FACTOR from DOMINATED_AFTER on. Measured
    on the losing signs of the bundled problems: transfer_min_torque's falls from 30 times the
    winner's objective at its start to 7.7 at iteration 10, 2.2 at 20 and its optimum, 2.08, at
    29 (a fall of 3.7 after iteration 10, well inside 18 / 1); swing_up_min_torque's and
    swing_up_torque_limited's are 5200 and 6200 times at iteration 10 and never converge."""
    if iteration < DOMINATED_EARLIEST:
        return math.inf
    return DOMINATED_FACTOR * max(1.0, (DOMINATED_AFTER / iteration) ** 2)


SEEDED_EARLIEST = DOMINATED_AFTER
"""Iterations a run started from a seed fit gets before it may be abandoned."""
SEEDED_FEASIBLE = 1e-2
"""The largest violation of its constraints at which a run started from a seed fit is judged
by its objective (its rows are in the phases' normalised time)."""
STALLED_SPAN = 5
"""Iterations over which a run is seen to have stalled (:func:`dominated`)."""
STALLED_FALL = 0.1
"""A relative fall of the objective over :data:`STALLED_SPAN` iterations below which it has
stalled."""
STALLED_INFEASIBILITY = 1e-6
"""A run still violating its constraints by more than this, by more than half of what it did
:data:`STALLED_SPAN` iterations before, has stalled infeasible."""


def dominated(best: float, earliest: int = DOMINATED_EARLIEST):
    """``abandon(iteration, objective, infeasibility)`` for a run that another pattern, solved
    with objective ``best``, has clearly beaten, after DOMINATED_EARLIEST iterations:

    * its objective is still above :func:`dominated_factor` times ``best`` (an interior-point
      run's objective falls as it converges, but not by that much that late; the positive sign
      of swing_up_min_torque is at 2.4e5 after 1000 iterations, the negative one solved at
      3425);
    * or it is above DOMINATED_FACTOR times ``best`` and has stalled: fallen by less than
      STALLED_FALL over the last STALLED_SPAN iterations (transfer_min_torque's losing sign at
      2.09 times the winner's, 4 iterations before it converges there);
    * or it is still infeasible and its infeasibility has not halved over the last
      STALLED_SPAN iterations (transfer_straight_line's negative sign: 11.8 to 7.6 between
      iterations 5 and 10, in Ipopt's restoration phase, which reports it infeasible at 15).

    A heuristic, measured on the runs it is used for: the other sign, and the polish's
    neighbours, each against a solved plan. The greedy search's patterns with a switch more do
    not use it: on ``transfer_switch`` (``switch_search: greedy``) one was 82 times the
    one-sign plan at iteration 10, its infeasibility growing from 1.3e3 to 5.7e3, and then
    solved a quarter below it; an early abandonment there would have kept one sign.
    A run started from a seed fit (``earliest`` :data:`SEEDED_EARLIEST`) is judged only from then
    on, and only once nearly feasible (violations below :data:`SEEDED_FEASIBLE`), by the stall
    rule: its start is far above where it lands, its objective swings while it is infeasible, and
    so does its infeasibility (the seed's pattern of ``transfer_switch`` starts at 200 times the
    one-sign plan's objective, is at 20 times it with its infeasibility grown from 0.01 to 22 at
    iteration 10, at 0.7 times it at 30, and solves at half of it at 208; a random RPR swing-down's
    is at 5.7 times the one-sign plan's at iteration 30, 1.9 at 34, 3.1 at 40, and solves at 0.45
    at 98; abandoning any run still above twice the best at iteration 100 lost a random PPR
    transfer's four switches, which solve at 0.094 times the bound).
    """
    objectives: list[float] = []
    infeasibilities: list[float] = []

    def above(factor: float, objective: float) -> bool:
        return objective > best + (factor - 1) * abs(best)

    def earlier(history: list[float]) -> float:
        return history[-1 - STALLED_SPAN] if len(history) > STALLED_SPAN else math.inf

    def abandon(iteration: int, objective: float, infeasibility: float = 0.0) -> bool:
        objectives.append(objective)
        infeasibilities.append(infeasibility)
        if iteration < earliest:
            return False
        if earliest > DOMINATED_EARLIEST:  # a seeded run: judged once nearly feasible
            stalled = objective > (1 - STALLED_FALL) * earlier(objectives)
            nearly = infeasibility <= SEEDED_FEASIBLE
            return nearly and stalled and above(DOMINATED_FACTOR, objective)
        if above(dominated_factor(iteration), objective):
            return True
        if above(DOMINATED_FACTOR, objective) and objective > (1 - STALLED_FALL) * earlier(
            objectives
        ):
            return True
        return infeasibility > STALLED_INFEASIBILITY and infeasibility > 0.5 * earlier(
            infeasibilities
        )

    return abandon


__all__ = [
    "DOMINATED_AFTER",
    "DOMINATED_EARLIEST",
    "DOMINATED_FACTOR",
    "SEEDED_EARLIEST",
    "SEEDED_FEASIBLE",
    "STALLED_FALL",
    "STALLED_INFEASIBILITY",
    "STALLED_SPAN",
    "dominated",
    "dominated_factor",
]
