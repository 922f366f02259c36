"""One problem through every stage: plan, sample, measure, verify by simulation."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

from .kinematics import ReachError
from .plan import CPPlan, SingularPlanError, closed_form
from .problem import Problem
from .results import Solution
from .simulate import verify
from .solver import SolverStats
from .trajectory import metrics, sample


def evaluate(
    plan: CPPlan,
    name: str,
    solver: SolverStats,
    status: str = "solved",
    samples: int = 401,
    poles=(-10.0, -10.0, -10.0, -10.0),
    message: str = "",
) -> Solution:
    """Sample, measure and verify a plan; a plan that fails verification is not ``solved``.

    Parameters
    ----------
    plan : CPPlan
        The plan.
    name : str
        Problem name.
    solver : SolverStats
        How the plan was found.
    status : str
        The planner's status; kept unless it is ``solved`` and verification fails.
    samples : int
        Trajectory samples per phase.
    poles : sequence of float
        Tracking poles of the closed-loop verification [1/s].
    message : str
        The planner's message.
    """
    try:
        traj = sample(plan, per_phase=samples)
    except ReachError as err:
        return Solution(
            name, "unreachable", plan.planner, plan=plan, solver=solver, message=str(err)
        )
    measured = metrics(plan, traj)
    checked = verify(plan, measured.max_passive_residual, poles)
    if status == "solved" and not checked.passed():
        status = "verification_failed"
        message = (
            f"simulation does not reproduce the plan: CP error "
            f"{checked.max_cp_error:.3g} m, final state error "
            f"{checked.final_state_error:.3g}, reduced-model CP error "
            f"{checked.reduced.max_cp_error:.3g} m"
        )
    return Solution(
        name,
        status,
        plan.planner,
        plan=plan,
        trajectory=traj,
        metrics=measured,
        verification=checked,
        solver=solver,
        message=message,
    )


def plan_closed_form(problem: Problem) -> Solution:
    """The paper's closed-form plan through the problem's nodes, verified."""
    start = time.perf_counter()
    try:
        plan = closed_form(problem.arm, problem.nodes, problem.spec.closed_form.smooth_torque)
    except SingularPlanError as err:
        return Solution(
            problem.name,
            "singular",
            "closed_form",
            message=str(err),
            solver=SolverStats(message=str(err)),
        )
    stats = SolverStats(solve_time_s=time.perf_counter() - start, message="closed form")
    return _evaluate_for(problem, plan, stats, "solved", "")


def plan_optimized(problem: Problem) -> Solution:
    """The flat optimizer's plan (or its best iterate, with the failure's status), verified."""
    from .flatopt import optimize

    result = optimize(problem)
    if result.plan is None:
        return Solution(
            problem.name,
            result.status,
            "optimize",
            solver=result.solver,
            message=result.solver.message,
        )
    return _evaluate_for(problem, result.plan, result.solver, result.status, result.solver.message)


def plan_collocation(problem: Problem) -> Solution:
    """The collocation peer: warm start (optional), solve, sample, replay open loop."""
    from .collocation import collocate, joint_metrics, joint_trajectory, replay

    warm = None
    if problem.spec.collocation.warm_start == "flat":
        from .flatopt import optimize

        warm = optimize(problem).plan
    result = collocate(problem, warm_start=warm)
    plan = result.plan
    traj = joint_trajectory(plan)
    checked = replay(plan, problem.nodes[-1], problem.spec.collocation.replay_tolerance)
    status, message = result.status, result.solver.message
    if status == "solved" and not checked.passed():
        status = "verification_failed"
        message = (
            f"the open-loop replay of the torques ends {checked.final_state_error:.3g} from the "
            f"goal (replay_tolerance {checked.tolerance:g})"
        )
    return Solution(
        problem.name,
        status,
        "collocation",
        plan=plan,
        trajectory=traj,
        metrics=joint_metrics(plan, traj),
        verification=checked,
        solver=result.solver,
        message=message,
    )


def _evaluate_for(
    problem: Problem, plan: CPPlan, stats: SolverStats, status: str, message: str
) -> Solution:
    """:func:`evaluate` with the problem's verification settings."""
    verification = problem.spec.verification
    return evaluate(
        plan, problem.name, stats, status, verification.samples, verification.poles, message
    )


PLANNERS: dict[str, Callable[[Problem], Solution]] = {
    "closed_form": plan_closed_form,
    "optimize": plan_optimized,
    "collocation": plan_collocation,
}
"""The planners by the name ``planner:`` gives in a problem file."""


def solve(problem: Problem) -> Solution:
    """Solve a validated problem with its planner, verify the result and, when the problem
    has a ``tracking`` block, track the solved plan on its plant.

    Returns
    -------
    Solution
        Its ``status`` says whether it worked; failures never raise.
    """
    solution = PLANNERS[problem.planner](problem)
    if problem.spec.tracking is not None and solution.ok:
        from .tracking import track_problem

        solution = replace(solution, tracking=track_problem(problem, solution.plan))
    return solution
