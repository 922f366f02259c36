"""A run whose objective has stalled at a feasible iterate is accepted (runtime.solver.Stall)."""

import math

from cpopt.runtime.solver import STALL_CHANGE, STALL_FEASIBLE, STALL_WINDOW, Stall


def _first_stop(objective, infeasibility=lambda i: 0.0, iterations: int = 1000):
    """The first iteration where a Stall fed these iterates says stop (None: never)."""
    stall = Stall()
    for i in range(1, iterations + 1):
        if stall.stalled(i, objective(i), infeasibility(i)):
            return i
    return None


def test_a_creep_slower_than_the_change_stops_one_window_in():
    """0.1 % per 100 iterations (a fifth of STALL_CHANGE): stopped at the first iterate a
    window after the first feasible one."""
    assert STALL_CHANGE > 1e-3
    assert _first_stop(lambda i: 2800.0 * (1 - 1e-5 * i)) == STALL_WINDOW + 1


def test_a_run_still_improving_goes_on():
    """1 % per 100 iterations, twice STALL_CHANGE: never stopped."""
    assert STALL_CHANGE < 1e-2
    assert _first_stop(lambda i: 2800.0 * math.exp(-1e-4 * i)) is None


def test_only_feasible_iterates_stop_a_run():
    """A flat objective at iterates violating the rows by 10 x STALL_FEASIBLE: never stopped;
    feasible every 7th iterate: stopped at the first feasible one a window in."""
    assert _first_stop(lambda i: 1.0, lambda i: 10 * STALL_FEASIBLE) is None
    every_7th = _first_stop(lambda i: 1.0, lambda i: 0.0 if i % 7 == 0 else 1.0)
    assert every_7th == 7 * math.ceil((STALL_WINDOW + 7) / 7)


def test_an_excursion_above_the_old_objective_goes_on():
    """An iterate 5 % above the best feasible one a window before is not a stall; one back
    within STALL_CHANGE of it is."""
    stall = Stall()
    for i in range(1, 150):
        assert not stall.stalled(i, 2.0 - 0.01 * i, 0.0)  # improving: 0.5-1 % an iteration
    best_then = 2.0 - 0.01 * (150 - STALL_WINDOW)  # the best feasible a window before
    assert not stall.stalled(150, 1.05 * best_then, 0.0)
    assert stall.stalled(151, (best_then - 0.01) * (1 + 0.5 * STALL_CHANGE), 0.0)
