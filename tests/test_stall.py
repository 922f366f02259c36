"""A run whose objective has stalled at a feasible iterate is accepted (runtime.solver.Stall)."""

import math

import casadi as ca
import numpy as np

from cpopt.runtime.solver import (
    STALL_CHANGE,
    STALL_FEASIBLE,
    STALL_NEARLY,
    STALL_WINDOW,
    BestFeasible,
    IterationReporter,
    Stall,
    run_nlp,
)


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


def test_a_nearly_feasible_creep_stops_against_the_best_feasible_iterate():
    """Feasible once at iteration 1, then violating the rows by a tenth of STALL_NEARLY at the
    same objective: stopped a window after the feasible iterate; violating them by ten times
    STALL_NEARLY: never."""
    nearly = _first_stop(lambda i: 1.0, lambda i: 0.0 if i == 1 else 0.1 * STALL_NEARLY)
    assert nearly == STALL_WINDOW + 1
    assert _first_stop(lambda i: 1.0, lambda i: 0.0 if i == 1 else 10 * STALL_NEARLY) is None


def test_the_best_feasible_iterate_is_the_lowest_feasible_one():
    best = BestFeasible()
    assert best.run(5, 0.1) is None
    iterates = [(0.5, 0.0), (3.0, 0.0), (1.0, 1.0), (2.0, 0.0), (2.5, 0.0)]  # the first: the start
    for i, (objective, violation) in enumerate(iterates):
        arg = [np.full(2, float(i)), objective, 0.0, np.zeros(2), np.ones(1), np.zeros(0)]
        best.offer(i + 1, objective, STALL_FEASIBLE * violation * 10, arg)
    run = best.run(9, 0.5)
    assert (run.objective, run.status, run.iterations) == (2.0, "solved", 9)
    assert run.return_status == "Best_Feasible_Iterate_At_4"
    np.testing.assert_array_equal(run.x, [3.0, 3.0])
    np.testing.assert_array_equal(run.lam_g, [-1.0])  # NlpRun's sign: positive at a lower bound


def _rosenbrock_on_a_line(max_iter: int = 3000):
    """min (1 - x0)^2 + 100 (x1 - x0^2)^2 s.t. x0 + x1 = 1.5: Ipopt needs more than 2
    iterations, and its iterates are feasible from the first (the row is linear)."""
    x = ca.SX.sym("x", 2)
    f = (1 - x[0]) ** 2 + 100 * (x[1] - x[0] ** 2) ** 2
    reporter = IterationReporter(2, 1, 0)
    options = {"iteration_callback": reporter, "print_time": False, "ipopt": {"sb": "yes"}}
    options["ipopt"].update(print_level=0, max_iter=max_iter)
    solver = ca.nlpsol("s", "ipopt", {"x": x, "f": f, "g": x[0] + x[1]}, options)
    return solver, reporter, {"x0": [0.0, 1.5], "lbg": 1.5, "ubg": 1.5}


def test_a_capped_run_returns_its_best_feasible_iterate():
    """Capped at 2 iterations: without stall the cap's status; with it the lowest feasible
    iterate, solved, and Ipopt's word says so."""
    solver, reporter, arguments = _rosenbrock_on_a_line()
    plain = run_nlp(solver, reporter, "", 2, **arguments)
    assert plain.status == "max_iterations"
    kept = run_nlp(solver, reporter, "", 2, stall=True, **arguments)
    assert kept.status == "solved" and kept.return_status.startswith("Best_Feasible_Iterate_At_")
    assert abs(kept.x.sum() - 1.5) <= STALL_FEASIBLE
    assert kept.objective < 0.1 * (1 + 100 * 1.5**2)  # far below the start's, 226
    assert kept.iterations == 2
    converged = run_nlp(solver, reporter, "", None, stall=True, **arguments)
    assert converged.return_status == "Solve_Succeeded"
    assert converged.objective <= kept.objective


def test_a_run_ipopt_gave_up_on_stays_failed():
    """Ipopt's own iteration limit (2) is not cpopt's cap: no feasible iterate is kept."""
    solver, reporter, arguments = _rosenbrock_on_a_line(max_iter=2)
    run = run_nlp(solver, reporter, "", None, stall=True, **arguments)
    assert (run.status, run.return_status) == ("max_iterations", "Maximum_Iterations_Exceeded")


def test_a_stall_never_returns_an_infeasible_iterate():
    """A run whose only feasible iterate was its start, then nearly feasible at the same
    objective for a window: the stall test says stop, but no feasible iterate is kept, so the
    reporter goes on (the run is not accepted at a violated iterate)."""
    reporter = IterationReporter(2, 1, 0)
    reporter.start("", lbg=[1.5], ubg=[1.5], stall=True)
    for i in range(1, STALL_WINDOW + 20):
        g = 1.5 if i == 1 else 1.5 + 0.1 * STALL_NEARLY
        arg = [np.zeros(2), np.array(1.0), np.array([g]), np.zeros(2), np.zeros(1), np.zeros(0)]
        reporter.eval(arg)
        assert not reporter.stalled
    assert reporter.best.x is None
