"""A start the flat NLP can evaluate (cpopt.flatopt.feasible_start): a random RRR transfer with a
via state whose closed-form start leaves the arm's reach, so that its objective is not a number
and Ipopt stopped at iteration 0, is moved back into reach by Gauss-Newton steps, and then
solves; a start that is already a number is left alone."""

from pathlib import Path

import numpy as np
import pytest
import yaml
from flat_arguments import closed_form_nlp
from zoo_draws import RRR_SWING_DOWN_VIA, RRR_TRANSFER_VIA

from cpopt.flatopt import solve_for_signs
from cpopt.flatopt.feasible_start import MAX_STEPS, evaluable_start, objective_is_number
from cpopt.flatopt.refine import cost_kept
from cpopt.flatopt.transcribe import REACH_EPS
from cpopt.problem import load_problem
from cpopt.runtime.solver import NlpRun

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def rrr_transfer_via(tmp_path_factory):
    path = tmp_path_factory.mktemp("feasible") / "rrr_transfer_via.yaml"
    path.write_text(yaml.safe_dump(RRR_TRANSFER_VIA))
    return load_problem(path)


def test_a_start_out_of_reach_is_moved_into_it_with_its_equalities_held(rrr_transfer_via):
    """The closed form's second phase has the elbow's cosine past 1 (reach margin down to
    -0.99): three steps put every reach row at or above its bound, and the node and lift rows
    stay satisfied to 1e-8."""
    nlp, arguments = closed_form_nlp(rrr_transfer_via, (1, 1))
    p = arguments["p"]
    assert not objective_is_number(nlp, arguments["x0"], p)
    x, steps = evaluable_start(nlp, arguments)
    assert 1 <= steps <= 5 < MAX_STEPS
    assert objective_is_number(nlp, x, p)
    g = np.asarray(nlp.constraints(x, p)).ravel()
    equal = nlp.lbg == nlp.ubg
    assert np.max(np.abs(g - nlp.lbg)[equal]) < 1e-8
    reach = np.array([name.startswith("reach") for name, _ in nlp.rows])
    assert reach.sum() == 100  # 50 samples in each of the two phases
    assert g[reach].min() >= REACH_EPS["RRR"] - 1e-9


def test_an_evaluable_start_is_left_alone():
    problem = load_problem(ROOT / "problems" / "transfer_min_torque.yaml")
    signs = (1,) * (len(problem.nodes) - 1)
    nlp, arguments = closed_form_nlp(problem, signs)
    assert objective_is_number(nlp, arguments["x0"], arguments["p"])
    x, steps = evaluable_start(nlp, arguments)
    assert steps == 0
    assert np.array_equal(x, arguments["x0"])


def test_the_mended_start_solves_where_ipopt_stopped_at_iteration_0(rrr_transfer_via):
    """The one-sign plan of this draw had no plan at all (Invalid_Number_Detected at iteration
    0); from the mended start Ipopt solves it (objective 4002.89 measured, 1e-3 relative)."""
    attempt = solve_for_signs(rrr_transfer_via, (1, 1))
    assert attempt.status == "solved"
    assert attempt.objective == pytest.approx(4002.89, rel=1e-3)


def _run(objective: float) -> NlpRun:
    return NlpRun(np.zeros(1), objective, "Solve_Succeeded", "solved", 40, 0.1)


def test_a_refinement_that_doubles_the_cost_is_not_a_solved_plan():
    """A refinement round whose objective is more than twice its previous round's
    is ``not_converged``: the previous round's samples missed the plan's torques (the zoo's
    growing refinements went 2.2-633 times a round, the rest within 1.4)."""
    grown = cost_kept(_run(2.5e5), _run(1.0e5), 1)
    assert grown.status == "not_converged"
    assert grown.return_status == "Cost_Grew_2.5x_In_Refinement_1"
    assert cost_kept(_run(1.9e5), _run(1.0e5), 1).status == "solved"
    assert cost_kept(_run(0.4e5), _run(1.0e5), 2).status == "solved"


def test_damped_steps_mend_a_start_the_gauss_newton_steps_do_not(tmp_path):
    """The swing-down's negative-gamma closed form: every halved Gauss-Newton step raised the
    summed violation (7.5), so the start was kept and Ipopt stopped at iteration 0
    (Invalid_Number_Detected); the damped steps reach every row in 5 steps (measured)."""
    path = tmp_path / "rrr_swing_down_via.yaml"
    path.write_text(yaml.safe_dump(RRR_SWING_DOWN_VIA))
    nlp, arguments = closed_form_nlp(load_problem(path), (-1, -1))
    p = arguments["p"]
    assert not objective_is_number(nlp, arguments["x0"], p)
    assert evaluable_start(nlp, arguments) == (pytest.approx(arguments["x0"]), 0)  # undamped
    x, steps = evaluable_start(nlp, arguments, damped=True)
    assert 1 <= steps <= 8
    assert objective_is_number(nlp, x, p)
    g = np.asarray(nlp.constraints(x, p)).ravel()
    assert np.all(g >= nlp.lbg - 1e-8) and np.all(g <= nlp.ubg + 1e-8)
