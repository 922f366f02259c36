"""One problem through every stage: plan, sample, measure, verify by simulation."""

from __future__ import annotations

import time
from dataclasses import replace

from .kinematics import ReachError
from .plan import CPPlan, SingularPlanError, closed_form
from .problem import Problem
from .results import Solution, SolverInfo
from .simulate import verify
from .trajectory import metrics, sample


def evaluate(
    plan: CPPlan,
    name: str,
    solver: SolverInfo,
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
    solver : SolverInfo
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


def _collocation(problem: Problem) -> Solution:
    """The collocation peer: warm start (optional), solve, sample, replay open loop."""
    from .collocation import collocate, joint_metrics, joint_trajectory, replay

    warm = None
    if problem.spec.collocation.warm_start == "flat":
        from .optimize import optimize

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


def solve(problem: Problem) -> Solution:
    """Solve a validated problem with its planner, verify the result and, when the problem
    has a ``tracking`` block, track the solved plan on its plant.

    Returns
    -------
    Solution
        Its ``status`` says whether it worked; failures never raise.
    """
    solution = _planned(problem)
    if problem.spec.tracking is not None and solution.ok:
        from .tracking import track_problem

        solution = replace(solution, tracking=track_problem(problem, solution.plan))
    return solution


def _planned(problem: Problem) -> Solution:
    """Plan with the problem's planner and verify (the solve without tracking)."""
    spec = problem.spec
    verification = spec.verification
    if problem.planner == "collocation":
        return _collocation(problem)
    if problem.planner == "optimize":
        from .optimize import optimize

        result = optimize(problem)
        if result.plan is None:
            return Solution(
                problem.name,
                result.status,
                "optimize",
                solver=result.solver,
                message=result.solver.message,
            )
        return evaluate(
            result.plan,
            problem.name,
            result.solver,
            result.status,
            verification.samples,
            verification.poles,
            result.solver.message,
        )
    start = time.perf_counter()
    try:
        plan = closed_form(problem.arm, problem.nodes, spec.closed_form.smooth_torque)
    except SingularPlanError as err:
        return Solution(
            problem.name,
            "singular",
            "closed_form",
            message=str(err),
            solver=SolverInfo(message=str(err)),
        )
    info = SolverInfo(
        build_time_s=0.0, solve_time_s=time.perf_counter() - start, message="closed form"
    )
    return evaluate(plan, problem.name, info, "solved", verification.samples, verification.poles)
