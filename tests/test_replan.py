"""Re-planning from a measured state (cpopt.replan, cpopt.flatopt.replan)."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import cpopt
from cpopt.closedform.trajectory import sample, sample_at
from cpopt.flatopt.remaining_motion import NEAR_NODE, remaining
from cpopt.flatopt.replan import METHODS
from cpopt.verify.simulate import simulate_open_loop

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def transfer():
    """transfer_min_torque solved (one phase, gamma positive, 1 s), and its plan sampled."""
    solution = cpopt.solve(cpopt.load(ROOT / "problems" / "transfer_min_torque.yaml"))
    assert solution.status == "solved"
    return solution, sample(solution.plan)


def tail_cost(plan, t: float) -> float:
    """The torque objective of ``plan`` on [t, T]: the integral of |tau|^2 [N^2 m^2 s]."""
    tt = np.linspace(t, plan.t0 + plan.duration, 4001)
    tau = sample_at(plan, tt, sample(plan)).tau
    return float(np.trapezoid((tau**2).sum(axis=1), tt))


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("free_compensator", [False, True])
def test_a_replan_from_the_plans_own_state_reproduces_it(transfer, free_compensator, method):
    solution, seed = transfer
    plan, t = solution.plan, 0.4
    now = sample_at(plan, [t], seed)
    r = cpopt.replan(
        solution, t, now.q[0], now.qd[0], free_compensator=free_compensator, method=method
    )
    assert r.status == "solved" and not r.kept_previous
    new = r.plan
    assert new.t0 == pytest.approx(t)
    goal, end = plan.nodes[-1], new.nodes[-1]
    assert end.t == goal.t and np.array_equal(end.state()[:6], goal.state()[:6])
    # the remainder in a B-spline basis of its own: the plan's tail is not in it, so the
    # re-plan is the best in that basis, measured 1.0 % (2.7 % with xi, eta free) cheaper
    old, cost = tail_cost(plan, t), tail_cost(new, t)
    assert r.objective == pytest.approx(cost, rel=1e-3)
    assert old * 0.95 <= cost <= old * (1 + 1e-3)
    tt = np.linspace(t, 1.0, 101)
    a, b = sample_at(plan, tt, seed), sample_at(new, tt, sample(new))
    assert np.abs(a.cp[:, :, 0] - b.cp[:, :, 0]).max() < 0.03  # [m], measured 0.014-0.023
    assert np.abs(a.q - b.q).max() < 0.05  # [rad], measured 0.032 with xi, eta free
    assert np.abs(b.q[0] - now.q[0]).max() < 1e-9  # it starts where the arm is


@pytest.mark.parametrize("method", METHODS)
def test_a_replan_from_a_perturbed_state_reaches_the_goal_on_the_model(transfer, method):
    solution, seed = transfer
    t = 0.3
    now = sample_at(solution.plan, [t], seed)
    # what 20 ms of a 10 % model error do (five times this did not solve in 300 iterations:
    # the margin on gamma binds near the end of this plan)
    q = now.q[0] + np.array([0.004, -0.004, 0.01])  # [rad]
    qd = now.qd[0] + np.array([0.02, 0.0, -0.04])  # [rad/s]
    r = cpopt.replan(solution, t, q, qd, method=method)
    assert r.status == "solved"
    start = sample_at(r.plan, [t], sample(r.plan))
    assert np.allclose(start.q[0], q, atol=1e-8) and np.allclose(start.qd[0], qd, atol=1e-7)
    replay = simulate_open_loop(r.plan)  # its torques on the model, no feedback
    assert replay.final_state_error < 1e-4  # [m, rad, m/s, rad/s]


@pytest.mark.parametrize("method", METHODS)
def test_a_missed_deadline_keeps_the_previous_plan(transfer, method):
    solution, seed = transfer
    now = sample_at(solution.plan, [0.3], seed)
    r = cpopt.replan(solution, 0.3, now.q[0] + 0.01, now.qd[0], deadline_s=1e-4, method=method)
    assert r.status in ("time_limit", "late")
    assert r.kept_previous and r.plan is solution.plan
    assert r.iterate is not None and r.time_s > 1e-4


def test_near_the_goal_the_plan_holds(transfer):
    solution, seed = transfer
    t = 1.0 - NEAR_NODE / 2
    now = sample_at(solution.plan, [t], seed)
    assert remaining(solution.problem, solution.plan, t, now.q[0], now.qd[0]) is None
    r = cpopt.replan(solution, t, now.q[0], now.qd[0])
    assert r.status == "holding" and r.plan is solution.plan


@pytest.mark.parametrize(
    "change, words",
    [
        ({"t": 1.5}, "t: expected a time [s] within the plan, 0 to 1, got 1.5"),
        ({"q": [0.0, 1.0]}, "q: expected 3 finite numbers"),
        ({"qd": [0.0, np.nan, 1.0]}, "qd: expected 3 finite numbers"),
        ({"deadline_s": 0}, "deadline_s: expected a finite number of seconds > 0, got 0"),
        ({"method": "newton"}, "method: expected one of ipopt, sqp, got 'newton'"),
    ],
)
def test_bad_arguments_are_refused_by_name(transfer, change, words):
    solution, seed = transfer
    now = sample_at(solution.plan, [0.3], seed)
    arguments = {"t": 0.3, "q": now.q[0], "qd": now.qd[0], **change}
    t, q, qd = arguments.pop("t"), arguments.pop("q"), arguments.pop("qd")
    with pytest.raises(ValueError, match=words.replace("[", r"\[").replace("]", r"\]")):
        cpopt.replan(solution, t, q, qd, **arguments)


def test_a_closed_form_plan_cannot_be_replanned(paper_solutions):
    problem = cpopt.load(ROOT / "problems" / "paper_transfer.yaml")
    solution = cpopt.Solution.of(paper_solutions["paper_transfer"], problem)
    with pytest.raises(ValueError, match=r"re-planning needs a flat plan of planner: optimize"):
        cpopt.replan(solution, 0.1, np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match=r"solution: expected a Solution of cpopt\.solve"):
        cpopt.replan(paper_solutions["paper_transfer"], 0.1, np.zeros(3), np.zeros(3))


def test_xi_and_eta_at_the_replan_instant_keep_the_problems_bounds(transfer):
    """transfer_min_torque frees xi in [-40, 40] m/s^2 and eta in [-200, 200] m/s^3 at its
    start and goal: a re-plan's start keeps within them."""
    from cpopt.flatopt.remaining_motion import compensator_bounds

    solution, seed = transfer
    problem = solution.problem
    assert compensator_bounds(problem, "xi") == (-40.0, 40.0)
    assert compensator_bounds(problem, "eta") == (-200.0, 200.0)
    unbounded = replace(problem, free={})
    assert compensator_bounds(unbounded, "eta") == (-np.inf, np.inf)
    t = 0.3
    now = sample_at(solution.plan, [t], seed)
    rest = remaining(problem, solution.plan, t, now.q[0], now.qd[0])
    assert rest.problem.free["start.eta"] == (-200.0, 200.0)
    r = cpopt.replan(solution, t, now.q[0], now.qd[0] + np.array([0.02, 0.0, -0.04]))
    assert r.status == "solved"
    xi, eta = r.plan.nodes[0].xi, r.plan.nodes[0].eta
    assert -40.0 <= xi <= 40.0 and -200.0 <= eta <= 200.0


def test_a_plan_out_of_reach_between_its_samples_is_not_reachable(transfer):
    """A re-plan is handed back as solved only when it can be sampled: the same CP plan on an
    arm with its first link halved leaves the reach (the base of link 3 is 1.18-2.43 m from
    the shoulder; the shortened arm reaches 0.75-2.25 m), and is refused (``out_of_reach``)."""
    from cpopt.flatopt.replan import reachable, verdict

    solution, _ = transfer
    plan = solution.plan
    assert reachable(plan)
    links = list(plan.arm.links)
    links[0] = replace(links[0], length=0.5 * links[0].length)
    short = replace(plan, arm=replace(plan.arm, links=tuple(links)))
    assert not reachable(short)
    assert verdict("solved", short, 0.5) == "out_of_reach"
    assert verdict("solved", plan, 0.5) == "solved"
