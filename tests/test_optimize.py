"""The flat optimizer: regression on optimal costs, claims against the paper, honest failures.

The stored table ``tests/optimal_costs.json`` is refreshed deliberately with
``python tests/refresh_optimal_costs.py``.
"""

import json
import textwrap
from pathlib import Path

import numpy as np
import pytest

from cpopt.cli import main
from cpopt.closedform.trajectory import sample
from cpopt.flatopt import optimize
from cpopt.flatopt.transcribe import build
from cpopt.model.objectives import default_hessian
from cpopt.pipeline import solve
from cpopt.problem import load_problem, parse_problem

HERE = Path(__file__).resolve().parent
PROBLEMS = HERE.parent / "problems"
TABLE = json.loads((HERE / "optimal_costs.json").read_text())
REL_TOL = 2e-3  # Ipopt's tol is 1e-8; the table moves only when the optimum does


@pytest.fixture(scope="module")
def optimized():
    return {name: solve(load_problem(PROBLEMS / f"{name}.yaml")) for name in TABLE}


@pytest.mark.parametrize("name", list(TABLE))
def test_optimal_costs_match_the_stored_table(optimized, name):
    sol = optimized[name]
    assert sol.status == "solved", sol.message
    from refresh_optimal_costs import measure

    now = measure(sol)
    for key, stored in TABLE[name].items():
        assert now[key] == pytest.approx(stored, rel=REL_TOL), (
            f"{name}.{key}: stored {stored:.10g}, now {now[key]:.10g} "
            "(refresh deliberately with `python tests/refresh_optimal_costs.py`)"
        )


@pytest.mark.parametrize("name", list(TABLE))
def test_optimized_plans_are_verified_and_certified(optimized, name):
    sol = optimized[name]
    v = sol.verification
    assert v.closed_loop.max_cp_error < 1e-8
    assert v.closed_loop.final_state_error < 1e-7
    assert v.open_loop.final_state_error < 1e-6  # exact torques replayed without feedback
    assert v.passive_torque_residual < 1e-9
    # certified between samples, exactly, and above gamma_min = 2 m/s^2
    assert sol.solver.details.certified_min_abs_gamma >= 2.0 * (1 - 1e-6)
    assert sol.metrics.min_abs_gamma >= 2.0 * (1 - 1e-6)
    assert "exact minimum" in sol.solver.details.certification
    # the sampled objective is close to the same integral on the fine grid
    if "torque" in sol.solver.cost_terms and len(sol.solver.cost_terms) == 1:
        assert sol.solver.objective == pytest.approx(sol.metrics.torque_sq_integral, rel=0.02)


def test_optimized_swing_up_beats_the_paper(optimized, paper_solutions):
    paper = paper_solutions["paper_swing_up"].metrics
    best = optimized["swing_up_min_torque"].metrics
    assert best.torque_sq_integral < 0.3 * paper.torque_sq_integral  # 3425 vs 12953
    assert max(best.peak_torque) < 0.5 * max(paper.peak_torque)


def test_optimized_transfer_beats_the_paper(optimized, paper_solutions):
    paper = paper_solutions["paper_transfer"].metrics
    best = optimized["transfer_min_torque"].metrics
    assert best.torque_sq_integral < 0.8 * paper.torque_sq_integral


def test_smooth_torque_removes_jumps_where_the_method_allows(optimized):
    jumps = dict(optimized["swing_up_min_torque"].metrics.torque_jumps)
    assert jumps["via[0]"] < 1e-6 and jumps["start"] < 1e-6
    # the inverted goal cannot be held: gamma < 0 there forces xi <= -(g0 + gamma_min), i.e. a
    # base still accelerating downwards at T (the sign of gamma cannot change in a swing-up)
    assert optimized["swing_up_min_torque"].plan.free_values["goal.xi"] <= -11.81 + 1e-6
    transfer = dict(optimized["transfer_min_torque"].metrics.torque_jumps)
    assert transfer["start"] < 1e-6 and transfer["goal"] < 1e-6


@pytest.mark.parametrize("name", ["swing_up_torque_limited", "swing_up_min_time"])
def test_torque_limits_hold_on_a_fine_grid(optimized, name):
    sol = optimized[name]
    tau = sample(sol.plan, per_phase=2001).tau
    assert np.abs(tau[:, 0]).max() <= 120 * (1 + 1e-4)
    assert np.abs(tau[:, 1]).max() <= 50 * (1 + 1e-4)


def test_minimum_time_is_shorter_than_the_paper(optimized):
    sol = optimized["swing_up_min_time"]
    assert sol.plan.duration < 1.2  # the paper took 1.6 s with larger torques
    assert sol.plan.free_values["via[0].t"] < sol.plan.duration


def test_both_signs_tried_and_reported(optimized):
    choices = optimized["swing_up_torque_limited"].solver.details.sign_choices
    assert {c.sign for c in choices} == {"positive", "negative"}
    assert optimized["swing_up_torque_limited"].solver.details.gamma_sign == "negative"
    # the losing sign is 6200 times the winner's objective at iteration 10: abandoned there
    (loser,) = [c for c in choices if c.sign == "positive"]
    assert loser.status == "dominated" and loser.iterations <= 10


INFEASIBLE = textwrap.dedent("""\
    name: too_weak
    arm:
      kind: RRR
      links:
        - {length: 1.5, mass: 1.0}
        - {length: 1.5, mass: 1.0}
        - {length: 1.0, mass: 0.5}
    motion:
      duration: 1.6
      start: {x: 0.75, y: 1.0, theta_deg: -90}
      via:
        - {t: 1.0, x: 0.75, y: 1.0, theta_deg: 0, xi: -10}
      goal: {x: 0.75, y: 1.0, theta_deg: 90, xi: -20}
    planner: optimize
    optimizer:
      gamma_sign: [negative, negative]
      samples: 21
      limits: {torque: [5, 15]}  # holds the arm at rest (14.4 N m), cannot swing it up
      free:
        via[0].xi: [-40, 40]
        goal.xi: [-40, 40]
      solver: {max_iter: 60}
    """)


def test_failed_solve_reports_status_best_iterate_and_violations(tmp_path, capsys):
    path = tmp_path / "too_weak.yaml"
    path.write_text(INFEASIBLE)
    result = optimize(load_problem(path))
    assert result.status in ("infeasible", "max_iterations", "not_converged")
    assert result.plan is not None  # the best iterate
    assert result.violations and "|tau" in " ".join(result.violations)
    assert " at t = " in result.violations[0]
    assert main(["solve", str(path), "--out", str(tmp_path / "out")]) == 1
    doc = json.loads((tmp_path / "out" / "too_weak" / "solution.json").read_text())
    assert doc["status"] == result.status
    assert "violated" in doc["solver"]["message"]
    assert not (tmp_path / "out" / "too_weak" / "trajectory.csv").exists()


def test_solver_is_reused_for_the_same_structure(optimized):
    data = load_problem(PROBLEMS / "transfer_min_torque.yaml").spec.model_dump()
    data["motion"]["goal"]["x"] = 1.6  # other fixed values, same structure
    other = parse_problem(data)
    first = load_problem(PROBLEMS / "transfer_min_torque.yaml")
    signs = (1,) * (len(first.nodes) - 1)
    assert build(other, signs) is build(first, signs)  # one solver: fixed values are parameters
    again = optimize(other)
    assert again.status == "solved"


def test_quadrature_check_refines_pieces_that_alias(monkeypatch):
    """The benchmark swing-up with 4 points per inner piece: the quadrature of two pieces
    misses the fine integral by more than 1e-3 of it; they get twice the points."""
    import cpopt.flatopt as flatopt
    from cpopt.closedform.trajectory import metrics
    from cpopt.flatopt.refine import QUADRATURE_TOL, quadrature_gaps

    data = load_problem(HERE.parent / "benchmarks/problems/swing_up.yaml").spec.model_dump()
    data["optimizer"]["samples"] = 40  # (12, 4, 4, 4, 4, 12) points on its 6 pieces
    problem = parse_problem(data)
    monkeypatch.setattr(flatopt, "MAX_REFINEMENTS", 0)
    once = optimize(problem)
    assert quadrature_gaps(
        problem, once.plan, build(problem, (-1,) * (len(problem.nodes) - 1))
    ) == [{2, 3}]
    monkeypatch.undo()
    refined = optimize(problem)
    assert refined.status == "solved" and refined.solver.details.refinements == 1
    fine = metrics(refined.plan, sample(refined.plan, per_phase=4001)).torque_sq_integral
    assert refined.solver.objective == pytest.approx(fine, rel=2 * QUADRATURE_TOL)
    assert abs(once.solver.objective - fine) > 2 * abs(refined.solver.objective - fine)


def test_optimizer_settings_are_validated(tmp_path):
    bad = INFEASIBLE.replace("gamma_sign: [negative, negative]", "gamma_sign: [negative]")
    path = tmp_path / "bad.yaml"
    path.write_text(bad)
    assert main(["check", str(path)]) == 2
    path.write_text(INFEASIBLE.replace("goal.xi: [-40, 40]", "goal.xii: [-40, 40]"))
    assert main(["check", str(path)]) == 2
    path.write_text(INFEASIBLE.replace("samples: 21", "objective: duration"))
    assert main(["check", str(path)]) == 2


def test_free_via_state_improves_on_the_paper_horizontal_rest(optimized):
    free_via = optimized["swing_up_free_via"]
    assert free_via.metrics.torque_sq_integral < 0.6 * (
        optimized["swing_up_min_torque"].metrics.torque_sq_integral
    )
    assert free_via.plan.free_values["via[0].thetadot_deg"] != 0.0  # no longer a rest state


def test_singular_closed_form_is_rescued_by_the_fallback_warm_start(optimized):
    """x_s = x_g in one phase makes the closed form hit gamma = 0 (the paper's remark)."""
    from cpopt.closedform.plan import SingularPlanError, closed_form

    problem = load_problem(PROBLEMS / "swing_up_one_phase.yaml")
    with pytest.raises(SingularPlanError):
        closed_form(problem.arm, problem.nodes)
    sol = optimized["swing_up_one_phase"]
    assert sol.status == "solved"
    assert sol.metrics.min_abs_gamma >= 2.0 * (1 - 1e-6)


def _variant(hessian=None, **settings):
    data = load_problem(PROBLEMS / "swing_up_min_torque.yaml").spec.model_dump()
    data["optimizer"].update(gamma_sign=["negative", "negative"], **settings)
    data["optimizer"]["solver"]["hessian"] = hessian
    return solve(parse_problem(data))


def test_energy_objective_lowers_the_energy(optimized):
    sol = _variant(objective="energy")
    assert sol.status == "solved", sol.message
    torque_optimal = optimized["swing_up_min_torque"].metrics.abs_power_integral
    assert sol.metrics.abs_power_integral < 0.9 * torque_optimal  # 65.8 J vs 82.6 J
    # the epigraph objective is the quadrature of |power|, whose kinks the quadrature check
    # resolves by refinement: within 0.2 % of the fine grid (uniform Simpson samples were 13 %
    # off, 60.2 J vs 67.8 J, before issue 10)
    assert sol.solver.details.refinements >= 1
    assert sol.solver.objective == pytest.approx(65.71, rel=REL_TOL)
    assert sol.metrics.abs_power_integral == pytest.approx(65.81, rel=REL_TOL)
    assert sol.solver.objective == pytest.approx(sol.metrics.abs_power_integral, rel=2e-3)


def test_gamma_margin_objective_widens_the_margin():
    sol = _variant(objective={"gamma_margin": 1.0, "torque": 1e-4})
    assert sol.status == "solved", sol.message
    # the start (hanging, held: xi = 0) has |gamma| = g0, so the margin cannot exceed it
    assert 9.0 < sol.metrics.min_abs_gamma <= 9.81 + 1e-6


def test_v_squared_objective_and_polynomial_curves(paper_solutions):
    sol = _variant(objective="v_squared")
    assert sol.status == "solved", sol.message
    paper = paper_solutions["paper_swing_up"].trajectory
    paper_v2 = np.trapezoid((paper.cp[:, :, 4] ** 2).sum(axis=1), paper.t)
    assert sol.solver.objective < paper_v2
    # the Gauss-Newton and the exact Hessian find the same optimum (v is linear in the
    # coefficients: they differ only by the curvature of the reach constraints)
    other = "exact" if default_hessian("v_squared") != "exact" else "gauss_newton"
    again = _variant(objective="v_squared", hessian=other)
    assert again.solver.objective == pytest.approx(sol.solver.objective, rel=1e-7)
    poly = _variant(curve="polynomial", degree=11)
    assert poly.status == "solved", poly.message
    assert 3000 < poly.metrics.torque_sq_integral < 12953  # fewer freedoms than the B-spline


def test_gauss_newton_needs_a_least_squares_objective(tmp_path, capsys):
    path = tmp_path / "energy.yaml"
    text = INFEASIBLE.replace("solver: {max_iter: 60}", "solver: {hessian: gauss_newton}")
    path.write_text(text.replace("samples: 21", "objective: energy"))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "optimizer.solver.hessian" in err and "energy" in err


def test_removed_jit_key_names_its_replacement(tmp_path, capsys):
    path = tmp_path / "old.yaml"
    path.write_text(
        INFEASIBLE.replace("solver: {max_iter: 60}", "solver: {max_iter: 60, jit: true}")
    )
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "optimizer.solver.jit" in err and "compiled" in err and "cache" in err


def test_path_timing_swing_up_passes_the_rest_via_along_its_acceleration(optimized):
    """At the horizontal rest via state the CP's first nonzero derivative is y'' = (xi, -g0):
    the first path arrives against it, the second leaves along it, and the jerk (eta, 0) must
    lie along it too, which pins eta and eta_after at 0 (docs/problems.md)."""
    from cpopt.closedform.paths import cross
    from cpopt.model import flat

    sol = optimized["swing_up_path_timing"]
    plan, arm = sol.plan, sol.plan.arm
    via = plan.nodes[1]
    acc = flat.output(via.state(), arm.K, arm.gravity)[:, 2]
    assert acc == pytest.approx([plan.free_values["via[0].xi"], -9.81], abs=1e-9)
    first, second = (ph.curve.control_points for ph in plan.phases)
    for tangent, sense in ((first[-1] - first[-2], -1), (second[1] - second[0], 1)):
        assert abs(cross(tangent, acc)) < 1e-7 * np.linalg.norm(tangent) * np.linalg.norm(acc)
        assert sense * tangent @ acc > 0
    assert abs(plan.free_values["via[0].eta"]) < 1e-6
    assert abs(plan.free_values["via[0].eta_after"]) < 1e-6
    # both phases meet the via state's CP derivatives 0..3 exactly
    for k, after in ((0, False), (1, True)):
        got = plan.phases[k].curve.derivatives(np.array([via.t]), 3)[0]
        assert got == pytest.approx(flat.output(via.state(after), arm.K, arm.gravity), abs=1e-8)
    # and a low-order path wanders less than the free B-splines (benchmarks/path_timing.py)
    from cpopt.closedform.paths import wandering

    ratios = [
        wandering(sample(optimized[n].plan, per_phase=1001).cp[:, :, 0])[0]
        for n in ("swing_up_path_timing", "swing_up_min_torque")
    ]
    assert ratios[0] < ratios[1]


def test_switches_needed_by_the_fixed_signs():
    """Hanging rest (gamma = -g0) to inverted rest (+g0): one switch, first guessed in the
    middle of the motion, negative before it and positive after."""
    from cpopt.flatopt.switching import needed_times, sign_assignments

    problem = load_problem(PROBLEMS / "swing_up_holding.yaml")
    assert needed_times(problem) == (0.8,)
    assert sign_assignments(problem, (0.8,)) == [(-1, 1)]
    assert sign_assignments(problem) == []  # no pattern without a switch


def test_swing_up_holding_steps_once_at_its_switch(optimized):
    """Both ends at the holding torque, one xi reset: the only torque step is at the reset,
    as small as gamma_min allows (|gamma| = gamma_min on both sides)."""
    sol = optimized["swing_up_holding"]
    d = sol.solver.details
    assert d.gamma_signs == ("negative", "positive")
    assert len(d.switch_times) == 1 and 0.9 < d.switch_times[0] < 1.2  # measured 1.038 s
    steps = dict(sol.metrics.torque_jumps)
    assert set(steps) == {"start", "switch[0]", "goal"}
    assert steps["start"] < 1e-6 and steps["goal"] < 1e-6
    assert sol.metrics.reset_torque_jump == sol.metrics.max_torque_jump == steps["switch[0]"]
    assert 1.0 < steps["switch[0]"] < 20.0  # measured 8.8 N m
    node = sol.plan.nodes[1]
    assert node.xi_after - node.xi == pytest.approx(2 * 2.0 * (1 + 2e-3), rel=1e-6)
    assert sol.metrics.min_abs_gamma >= 2.0
    v = sol.verification
    assert v.closed_loop.max_cp_error < 1e-6 and v.open_loop.final_state_error < 1e-5
    doc = sol.solver.details.as_dict()
    assert doc["gamma_signs"] == ["negative", "positive"]
    assert doc["switch_times"] == list(d.switch_times)
    assert doc["sign_choices"][0]["signs"] == ["negative", "positive"]


def test_the_greedy_search_lowers_the_transfer_cost():
    """switch_search: greedy (issue 11's search) on the T = 1 s transfer, one switch allowed:
    every pattern tried is reported, and the one kept costs at least 1 % less than the best
    plan with one sign of gamma. Where it places the switch depends on which active margin
    constraint weighs most on the one-sign plan, a near tie: the B-spline basis from
    scipy.interpolate gave 62753 (switch at 0.616 s), cpopt's own (equal to 1.5e-15) 70242
    (-/+ tried at 0.948 s, failed; +/- at 0.339 s kept); now -/+ at 0.616 s, 62753. The
    seeded search finds 42521. (With gamma_switches: auto the greedy pass goes on to two
    switches, 70 s here for nothing better, +/-/+ at 549070: so this test allows one.)"""
    problem = load_problem(PROBLEMS / "transfer_switch.yaml")
    data = problem.spec.model_dump()
    data["optimizer"]["switch_search"] = "greedy"
    data["optimizer"]["gamma_switches"] = 1
    sol = solve(parse_problem(data, problem.source, problem.name))
    assert sol.solver.objective < 0.85 * 82694.28  # the one-sign plan (transfer_min_torque)
    d = sol.solver.details
    choices = d.sign_choices
    # a one-sign run that a solved one dominates is abandoned early (status dominated)
    one_sign = [c for c in choices if not c.switch_times and c.status in ("solved", "dominated")]
    assert {c.signs for c in one_sign} == {("positive",), ("negative",)}
    assert len(d.switch_times) >= 1 and len(set(d.gamma_signs)) == 2
    assert sol.solver.objective < 0.99 * min(c.objective for c in one_sign)
    assert sol.solver.objective == min(c.objective for c in choices if c.status == "solved")
    assert "(1 asked)" in d.search
    assert sol.metrics.min_abs_gamma >= 2.0
    assert sol.verification.closed_loop.max_cp_error < 1e-6


def test_swing_up_switches_crosses_gamma_zero_twice(optimized):
    """gamma_switches: auto on the minimum-torque swing-up: the seed crosses four times (0.94,
    1.00, 1.10, 1.48 s); the first pair lands on the via state and cancels, the plan keeps two
    switches and costs half the one-sign plan (measured 1749.6 against 3424.8)."""
    sol = optimized["swing_up_switches"]
    d = sol.solver.details
    assert d.switch_times == pytest.approx((1.104, 1.485), abs=0.01)
    assert d.gamma_signs == ("negative", "negative", "positive", "negative")
    assert sol.solver.objective < 0.55 * optimized["swing_up_min_torque"].solver.objective
    assert sol.metrics.min_abs_gamma >= 2.0
    assert sol.metrics.gamma_sign_changes == pytest.approx(d.switch_times)
    assert sol.verification.closed_loop.max_cp_error < 1e-6
    search = d.as_dict()["search"]
    assert search["method"] == "seed" and len(search["seed"]["crossings"]) == 4


def test_a_freed_via_eta_without_eta_after_stays_continuous():
    """Freeing ``via[0].eta`` alone must not reset eta at the via state (found by review: the
    value after it stayed the file's eta, a hidden reset and a jerk step)."""
    data = load_problem(PROBLEMS / "swing_up_free_via.yaml").spec.model_dump()
    del data["optimizer"]["free"]["via[0].eta_after"]
    data["optimizer"]["samples"] = 21
    result = optimize(parse_problem(data))
    assert result.status == "solved"
    via = result.plan.nodes[1]
    assert via.eta_after is None and via.eta != pytest.approx(data["motion"]["via"][0]["eta"])
    t = np.array([via.t])
    before, after = (result.plan.phases[k].curve.derivatives(t, 4)[0] for k in (0, 1))
    assert after[:, 3] == pytest.approx(before[:, 3], abs=1e-6)  # CP jerk continuous [m/s^3]


def test_a_neighbouring_plan_starts_the_optimizer(optimized):
    """Continuation: swing_up_switches with link 3 5 % heavier, started from the bundled plan,
    solves its pattern once (measured: 23 iterations, 1821.70; the whole seeded search from
    scratch: 250 iterations, 1821.70) and keeps its switches."""
    base = load_problem(PROBLEMS / "swing_up_switches.yaml")
    heavier = base.replace(**{"arm.links[2].mass": 1.05 * base.spec.arm.links[2].mass})
    sol = solve(heavier, optimized["swing_up_switches"].plan)
    d = sol.solver.details
    assert sol.status == "solved", sol.message
    assert d.as_dict()["search"]["method"] == "start"
    assert sol.solver.iterations <= 60
    assert sol.solver.objective == pytest.approx(1821.70, rel=1e-4)
    assert d.switch_times == pytest.approx((1.104, 1.485), abs=0.01)
    assert sol.metrics.min_abs_gamma >= 2.0
    assert sol.verification.closed_loop.max_cp_error < 1e-6


def test_a_start_that_does_not_fit_runs_the_usual_search(paper_solutions):
    """A start of another duration (the paper's slow transfer, 5 s) for the 1 s transfer: the
    usual sign search runs, says why, and finds the same plan as without a start. (The paper's
    1 s transfer, the same motion by the closed form, starts it: 13 iterations.)"""
    problem = load_problem(PROBLEMS / "transfer_min_torque.yaml")
    result = optimize(problem, paper_solutions["paper_transfer_slow"].plan)
    assert result.status == "solved"
    assert result.solver.details.search.startswith("the start does not fit this problem")
    assert result.solver.objective == pytest.approx(optimize(problem).solver.objective, rel=1e-9)
