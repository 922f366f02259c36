"""The direct-collocation peer: same problem as the flat optimizer, honest figures."""

from pathlib import Path

import numpy as np
import pytest

from cpopt.collocation import collocate, joint_functions, joint_metrics, joint_trajectory, replay
from cpopt.model.dynamics import arm_dynamics
from cpopt.model.flat import gamma as flat_gamma
from cpopt.problem import ProblemError, load_problem, parse_problem

ROOT = Path(__file__).resolve().parent.parent
TRANSFER = ROOT / "benchmarks" / "problems" / "transfer.yaml"


@pytest.fixture(scope="module")
def transfer():
    problem = load_problem(TRANSFER)
    data = problem.spec.model_dump()
    data["planner"] = "collocation"
    return parse_problem(data, "transfer", "transfer")


@pytest.fixture(scope="module")
def solved(transfer):
    return collocate(transfer, intervals=30, gamma_constraint=True)


def test_joint_gamma_matches_the_flat_definition(transfer):
    """gamma from joint state and accelerations equals xi - K thetadot^2 + g0 sin(theta)."""
    arm = transfer.arm
    rng = np.random.default_rng(3)
    step = joint_functions(arm)
    for _ in range(5):
        q = np.array([0.5, -1.2, 1.9]) + 0.3 * rng.standard_normal(3)
        qd = rng.standard_normal(3)
        tau = 20 * rng.standard_normal(2)
        qdd, gam, s, sdot, sddot = (np.asarray(v).ravel() for v in step(q, qd, tau))
        theta = s[2]
        xi = sddot[0] * np.cos(theta) + sddot[1] * np.sin(theta)
        z = np.r_[s, sdot, xi, 0.0]
        assert gam[0] == pytest.approx(float(flat_gamma(z, arm.K, arm.gravity)), abs=1e-9)
        # the passive joint is torque-free under the forward dynamics
        res = np.asarray(arm_dynamics(arm)["inverse"](q, qd, qdd)).ravel()
        assert abs(res[2]) < 1e-9


def test_collocation_solves_the_transfer_and_keeps_gamma_at_knots(transfer, solved):
    assert solved.status == "solved"
    plan = solved.plan
    assert plan.knots.size == 31 and plan.tau.shape == (30, 2)
    step = joint_functions(transfer.arm)
    gam = [float(step(plan.q[k], plan.qd[k], plan.tau[k])[1]) for k in range(30)]
    assert min(gam) >= 2.0 - 1e-6  # sign positive, gamma_min 2 m/s^2, at every knot
    # boundary states as asked
    start, goal = transfer.nodes[0], transfer.nodes[-1]
    np.testing.assert_allclose(plan.nodes[0].state()[:6], start.state()[:6], atol=1e-8)
    np.testing.assert_allclose(plan.nodes[-1].state()[:6], goal.state()[:6], atol=1e-8)
    # the cost of N = 30: within 3 % of the N = 200 optimum measured by the benchmark (66183)
    assert plan.torque_sq_integral() == pytest.approx(66183, rel=0.03)


def test_replay_and_metrics(transfer, solved):
    plan = solved.plan
    traj = joint_trajectory(plan)
    m = joint_metrics(plan, traj)
    assert m.torque_sq_integral == pytest.approx(plan.torque_sq_integral())
    assert m.peak_torque[0] == pytest.approx(np.abs(plan.tau[:, 0]).max())
    check = replay(plan, transfer.nodes[-1], 1e-3)
    # radau degree 3 on 30 intervals: the replay ends within 1e-4 of the goal, not exactly
    assert 1e-12 < check.final_state_error < 1e-4
    assert check.passed()
    # a second solve of the same structure reuses the transcription
    again = collocate(transfer, intervals=30, gamma_constraint=True)
    assert again.solver.build_time_s < 0.5
    assert again.plan.torque_sq_integral() == pytest.approx(plan.torque_sq_integral(), rel=1e-8)


def test_collocation_refuses_flat_only_objectives():
    data = load_problem(TRANSFER).spec.model_dump()
    data["planner"] = "collocation"
    data["optimizer"]["objective"] = "v_squared"
    with pytest.raises(ProblemError, match=r"optimizer\.objective"):
        parse_problem(data, "x.yaml")


def _fatrop(**collocation):
    data = load_problem(TRANSFER).spec.model_dump()
    data["planner"] = "collocation"
    data["collocation"].update({"solver": "fatrop", "method": "multiple_shooting", **collocation})
    return data


def test_fatrop_solves_the_single_phase_transfer():
    problem = parse_problem(_fatrop(), "transfer", "transfer")
    result = collocate(problem, intervals=20, gamma_constraint=True)
    assert result.status == "solved", result.solver.message
    assert result.solver.message.startswith("Fatrop:")
    assert result.solver.details.solver == "fatrop"
    plan = result.plan
    step = joint_functions(problem.arm)
    gam = [float(step(plan.q[k], plan.qd[k], plan.tau[k])[1]) for k in range(20)]
    assert min(gam) >= 2.0 - 1e-6  # at every knot where a control acts
    # one RK4 step per interval on 20 intervals: the replay ends 1.3e-2 from the goal, the
    # cost is near the N = 200 optimum (66183)
    assert replay(plan, problem.nodes[-1]).final_state_error < 2e-2
    assert plan.torque_sq_integral() == pytest.approx(66183, rel=0.05)


def test_fatrop_is_refused_where_its_structure_detection_fails():
    via = _fatrop()
    via["motion"]["via"] = [{"t": 0.5, "x": 1.25, "y": 1.0, "theta_deg": 90, "xi": 5.0}]
    with pytest.raises(ProblemError, match=r"collocation\.solver: fatrop solves single-phase"):
        parse_problem(via, "x.yaml")
    with pytest.raises(ProblemError, match=r"collocation\.solver: .*multiple_shooting"):
        parse_problem(_fatrop(method="collocation"), "x.yaml")
    free_time = _fatrop()
    free_time["optimizer"]["free"]["duration"] = [0.5, 2.0]
    with pytest.raises(ProblemError, match=r"collocation\.solver: .*fixed duration"):
        parse_problem(free_time, "x.yaml")


def test_collocation_keeps_the_torque_headroom(transfer, solved):
    # the N = 30 transfer peaks at 407 N m and 210 N m; motors of 400 N m and 200 N m with 25 %
    # headroom leave the plan 300 N m and 150 N m
    data = transfer.spec.model_dump()
    data["optimizer"]["limits"].update(torque=[400.0, 200.0], torque_headroom=0.25)
    limited = parse_problem(data, "transfer", "transfer")
    result = collocate(limited, intervals=30, gamma_constraint=True)
    assert result.status == "solved", result.solver.message
    peak = np.abs(result.plan.tau).max(axis=0)
    assert np.all(peak <= np.array([300.0, 150.0]) * (1 + 1e-6))  # Ipopt's tolerance
    assert peak == pytest.approx([300.0, 150.0], rel=1e-4)  # and the plan uses them
    # 72347 against 66688 without the limits: 8.5 % more
    cost = result.plan.torque_sq_integral()
    assert cost == pytest.approx(72347, rel=1e-3)
    assert cost > 1.08 * solved.plan.torque_sq_integral()
