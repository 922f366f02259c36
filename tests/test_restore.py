"""A run cpopt cut before it passed a feasible iterate keeps its nearly feasible iterate with the
lowest objective, and that iterate is moved onto the constraints
(cpopt.flatopt.feasible_start.restored_run): the bundled swing-up's one-sign run, capped at 30
Ipopt iterations, has no iterate feasible to 1e-5 but one within 1e-2, which Gauss-Newton steps
make a plan; a cap where none is within 1e-2 leaves the run as it was; a plan moved past the
arm's reach is stepped back into it, and a restoration that would raise the objective past its
guard is refused."""

from pathlib import Path

import numpy as np
import pytest
from flat_arguments import closed_form_nlp
from zoo_draws import PPR_SWING_DOWN_VIA

import cpopt
from cpopt.flatopt import RESTORED_REFINE_LIMIT
from cpopt.flatopt.feasible_start import (
    CURVE_KINDS,
    RESTORE_GROWTH,
    RESTORED,
    largest_violation,
    restored,
    restored_run,
)
from cpopt.problem import load_problem
from cpopt.runtime.solver import RESTORABLE, STALL_FEASIBLE, run_nlp

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def swing_up():
    """(nlp, nlpsol's arguments) of the bundled swing-up's one-sign NLP from its closed form."""
    problem = load_problem(ROOT / "problems" / "swing_up_min_torque.yaml")
    return closed_form_nlp(problem, (1,) * (len(problem.nodes) - 1))


def _capped(nlp, arguments, cap: int):
    return run_nlp(nlp.solver, nlp.reporter, "capped", cap, None, np.inf, True, **arguments)


def test_a_cut_run_without_a_feasible_iterate_is_restored(swing_up):
    """Measured: iteration 30 is the first within 1e-2 (objective 1.8898e6; 2.9e-3, in the
    lifted samples' rows), none within 1e-5; restored (the samples lifted from its curves
    again), every row holds to STALL_FEASIBLE and the objective moved less than 1e-6."""
    nlp, arguments = swing_up
    run = _capped(nlp, arguments, 30)
    assert run.status == "max_iterations"
    assert nlp.reporter.best.x is None  # no iterate feasible to STALL_FEASIBLE
    nearly = nlp.reporter.nearly
    assert nearly.iteration == 30
    g = np.asarray(nlp.constraints(nearly.x, arguments["p"])).ravel()
    assert STALL_FEASIBLE < largest_violation(nlp, g) <= RESTORABLE
    restored = restored_run(nlp, arguments, run, np.inf)
    assert restored.status == "solved"
    assert restored.return_status == f"{RESTORED}30"
    g = np.asarray(nlp.constraints(restored.x, arguments["p"])).ravel()
    assert largest_violation(nlp, g) <= STALL_FEASIBLE
    assert restored.objective == pytest.approx(nearly.objective, rel=1e-6)
    assert restored.objective == pytest.approx(1.8898e6, rel=1e-3)


def test_a_cut_run_with_no_nearly_feasible_iterate_stays_cut(swing_up):
    """At 20 iterations the rows are still violated by 0.19: nothing to restore."""
    nlp, arguments = swing_up
    run = _capped(nlp, arguments, 20)
    assert nlp.reporter.nearly.x is None
    assert restored_run(nlp, arguments, run, np.inf) is run


def _moved_plan(nlp, arguments) -> np.ndarray:
    """The solved plan's core with the one curve coefficient whose move by 1e-3 violates its
    rows most, so moved (measured: the reach rows of phase 1, by 6.8e-4)."""
    p, n = arguments["p"], nlp.layout.size
    plan = _capped(nlp, arguments, 3000).x[:n]
    curves = [b.kind in CURVE_KINDS for b in nlp.layout.blocks for _ in range(b.size)]
    moves = []
    for i in np.flatnonzero(curves):
        core = plan.copy()
        core[i] += 1e-3
        g = np.asarray(nlp.constraints(nlp.complete(core, p), p)).ravel()
        moves.append((largest_violation(nlp, g), i, core))
    return max(moves, key=lambda move: move[0])[2]


def test_a_plan_moved_past_its_reach_is_stepped_back_into_it(swing_up):
    """A curve coefficient moved by 1e-3 puts the arm past its reach by 6.8e-4 (its objective
    not a number); with no guard one restoring step holds every row to STALL_FEASIBLE again,
    but the plan now runs along the edge of the reach, its objective 4.0e9 (measured)."""
    nlp, arguments = swing_up
    x, p = _moved_plan(nlp, arguments), arguments["p"]
    moved = np.asarray(nlp.constraints(nlp.complete(x, p), p)).ravel()
    assert largest_violation(nlp, moved) == pytest.approx(6.8e-4, rel=0.02)
    moved_back = restored(nlp, arguments, x, np.inf, np.inf)
    assert moved_back is not None
    back, objective = moved_back
    assert largest_violation(nlp, np.asarray(nlp.constraints(back, p)).ravel()) <= STALL_FEASIBLE
    assert float(nlp.solver.get_function("nlp_f")(back, p)) == pytest.approx(4.0e9, rel=0.05)
    assert objective == float(nlp.solver.get_function("nlp_f")(back, p))


def test_a_restoration_may_not_raise_the_objective_past_its_guard(swing_up):
    """Guarded by the solved plan's objective (4.3e5), that restoration is refused."""
    nlp, arguments = swing_up
    solved = _capped(nlp, arguments, 3000)
    assert solved.objective == pytest.approx(4.307e5, rel=1e-3)
    assert RESTORE_GROWTH * solved.objective < 4.0e9
    assert restored(nlp, arguments, _moved_plan(nlp, arguments), solved.objective, np.inf) is None


def test_a_solved_run_is_not_touched(swing_up):
    nlp, arguments = swing_up
    run = _capped(nlp, arguments, 3000)
    assert run.status == "solved"
    assert restored_run(nlp, arguments, run, np.inf) is run


def test_a_creeping_search_returns_its_restored_plan_not_the_one_sign_one():
    """The four-switch pattern's restored plan (41900 measured) is kept over the one-sign plan
    (80723): before restoration the search returned the latter, 4.4 times collocation's
    18467. Its refinement rounds, capped at RESTORED_REFINE_LIMIT iterations, are restored
    too; the plan is verified and certified at gamma_min. The search takes about 19 s idle, so
    the time limit is 60 s: at 20 s a loaded CI machine cut it before the pattern (the deadline's
    own behaviour is tests/test_budget.py's)."""
    solution = cpopt.solve(cpopt.load(PPR_SWING_DOWN_VIA), time_limit=60.0)
    assert solution.status == "solved"
    details = solution.solver.details
    assert len(details.switch_times) == 4
    assert solution.solver.objective == pytest.approx(41900, rel=0.01)
    assert solution.solver.message.startswith(f"Ipopt: {RESTORED}{RESTORED_REFINE_LIMIT} ")
    one_sign = [a for a in details.sign_choices if not a.switch_times and a.status == "solved"]
    assert solution.solver.objective < 0.55 * min(a.objective for a in one_sign)
    assert details.certified_min_abs_gamma >= 2.38 * (1 - 1e-4)
    assert solution.verification.passed()
    assert solution.verification.max_cp_error < 1e-6
