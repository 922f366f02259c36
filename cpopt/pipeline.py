"""One problem through every stage: plan, sample, measure, verify by simulation.

The whole of it runs under the problem's wall-clock budget (``optimizer.solver.max_time``,
see :mod:`cpopt.runtime.budget`): when it runs out, the solution so far is returned with status
``time_limit``. Each stage is reported to :mod:`cpopt.runtime.progress`.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from .closedform.plan import CPPlan, SingularPlanError, closed_form
from .closedform.trajectory import metrics, sample
from .model.kinematics import ReachError
from .model.limits import Limit, rated_torques, violations
from .problem import Problem
from .results import Solution
from .runtime import progress
from .runtime.budget import Budget, TimeLimitExceeded, enforced, remaining
from .runtime.solver import SolverStats
from .verify.simulate import DivergedVerification, verify


@dataclass
class StageRecord:
    """What the stages of one solve have produced so far (kept for a solve stopped by the
    time limit), and the stage reached."""

    stage: str = "planning"
    plan: object = None
    trajectory: object = None
    metrics: object = None
    solver: SolverStats = field(default_factory=SolverStats)
    started: list = field(default_factory=lambda: [("plan", time.perf_counter())])

    def reached(self, stage: str, **done) -> None:
        """Enter a stage (reported to :mod:`cpopt.runtime.progress`), keeping what was ``done``."""
        self.stage = stage
        for key, value in done.items():
            setattr(self, key, value)
        self.started.append((STAGE_KINDS.get(stage, "plan"), time.perf_counter()))
        progress.stage(stage)

    def times(self) -> dict[str, float]:
        """Wall time [s] spent in each kind of stage so far (``plan``, ``sample``, ...)."""
        out: dict[str, float] = {}
        marks = [*self.started, ("end", time.perf_counter())]
        for (kind, start), (_, end) in itertools.pairwise(marks):
            out[kind] = out.get(kind, 0.0) + end - start
        return out


STAGE_KINDS = {
    "sampling the plan": "sample",
    "verifying by simulation": "verify",
    "open-loop replay": "verify",
    "tracking on the plant": "track",
}
"""The kind of each stage :class:`StageRecord` times (any other stage is planning)."""


def evaluate(
    plan: CPPlan,
    name: str,
    solver: SolverStats,
    status: str = "solved",
    samples: int = 401,
    poles=(-10.0, -10.0, -10.0, -10.0),
    message: str = "",
    limits: tuple[Limit, ...] = (),
) -> Solution:
    """Sample, measure and verify a plan; a plan that fails verification, or leaves one of
    the arm's limits, is not ``solved`` (``verification_failed``, ``limits_violated``).

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
    limits : tuple of Limit
        The arm's limits, checked on the sampled plan.
    """
    checks = Checks(samples, tuple(poles), tuple(limits))
    return _evaluate(plan, name, solver, status, message, StageRecord(), checks)


@dataclass(frozen=True)
class Checks:
    """How a plan is checked: trajectory samples per phase, poles of the closed-loop
    verification [1/s], the arm's limits."""

    samples: int = 401
    poles: tuple = (-10.0, -10.0, -10.0, -10.0)
    limits: tuple[Limit, ...] = ()

    @classmethod
    def of(cls, problem: Problem) -> Checks:
        """A problem's checks (``verification`` block, ``optimizer.limits``)."""
        v = problem.spec.verification
        return cls(v.samples, tuple(v.poles), problem.limits)


def with_limits(measured, limits: tuple[Limit, ...]):
    """Metrics with the motors' torque limits and the plan's headroom (``torque_limit``,
    ``torque_headroom``) of the arm's limits."""
    rated, headroom = rated_torques(limits)
    return replace(measured, torque_limit=rated, torque_headroom=headroom)


def limit_status(limits, traj, status: str, message: str) -> tuple[str, str]:
    """``limits_violated`` and a message naming each limit and time, for a solved plan that
    leaves a limit; otherwise the status and message as they were."""
    found = violations(limits, traj)
    if status != "solved" or not found:
        return status, message
    return "limits_violated", "; ".join(v.message() for v in found)


def _evaluate(plan, name, solver, status, message, partial, checks: Checks) -> Solution:
    partial.reached("sampling the plan", plan=plan, solver=solver)
    try:
        traj = sample(plan, per_phase=checks.samples)
    except ReachError as err:
        return Solution(
            name, "unreachable", plan.planner, plan=plan, solver=solver, message=str(err)
        )
    measured = with_limits(metrics(plan, traj), checks.limits)
    partial.reached("verifying by simulation", trajectory=traj, metrics=measured)
    checked = verify(plan, measured.max_passive_residual, checks.poles)
    if status == "solved" and not checked.passed():
        status = "verification_failed"
        if isinstance(checked, DivergedVerification):
            message = checked.message()
        else:
            message = (
                f"simulation does not reproduce the plan: CP error "
                f"{checked.max_cp_error:.3g} m, final state error "
                f"{checked.final_state_error:.3g}, reduced-model CP error "
                f"{checked.reduced.max_cp_error:.3g} m"
            )
    status, message = limit_status(checks.limits, traj, status, message)
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


def plan_collocation(problem: Problem, partial: StageRecord) -> Solution:
    """The collocation peer: warm start (optional), solve, sample, replay open loop."""
    from .collocation import RUN_LABEL, collocate, joint_metrics, joint_trajectory, replay
    from .verify.integrate import DivergenceError

    warm = None
    if problem.spec.collocation.warm_start == "flat":
        from .flatopt import optimize

        partial.reached("warm start (flat optimizer)")
        progress.ipopt_run("flat optimizer (warm start of collocation)")
        warm = optimize(problem).plan
    partial.reached("planning (collocation)")
    progress.ipopt_run(RUN_LABEL)
    result = collocate(problem, warm_start=warm)
    plan = result.plan
    traj = joint_trajectory(plan)
    partial.reached("open-loop replay", plan=plan, trajectory=traj, solver=result.solver)
    status, message = result.status, result.solver.message
    try:
        checked = replay(plan, problem.nodes[-1], problem.spec.collocation.replay_tolerance)
    except DivergenceError as err:
        checked = None
        status, message = "verification_failed", f"the open-loop replay diverged: {err}"
    if status == "solved" and not checked.passed():
        status = "verification_failed"
        message = (
            f"the open-loop replay of the torques ends {checked.final_state_error:.3g} from the "
            f"goal (replay_tolerance {checked.tolerance:g})"
        )
    status, message = limit_status(problem.limits, traj, status, message)
    return Solution(
        problem.name,
        status,
        "collocation",
        plan=plan,
        trajectory=traj,
        metrics=with_limits(joint_metrics(plan, traj), problem.limits),
        verification=checked,
        solver=result.solver,
        message=message,
    )


def plan_optimized(problem: Problem, partial: StageRecord, start: CPPlan | None = None) -> Solution:
    """The flat optimizer (started from the plan ``start`` when given, see
    :func:`cpopt.flatopt.optimize`), then sampling and verification of its plan (or best
    iterate)."""
    from .flatopt import optimize

    partial.reached("planning (flat optimizer)")
    progress.ipopt_run("flat optimizer")
    result = optimize(problem, start)
    if result.status == "time_limit":  # the search's deadline came before any plan solved
        elapsed = problem.max_time - remaining()
        why = "; no plan solved by the search's deadline"
        return time_limit_solution(
            problem, partial.stage, elapsed, why, plan=result.plan, solver=result.solver
        )
    if result.plan is None:
        return Solution(
            problem.name,
            result.status,
            "optimize",
            solver=result.solver,
            message=result.solver.message,
        )
    solution = _evaluate(
        result.plan,
        problem.name,
        result.solver,
        result.status,
        result.solver.message,
        partial,
        Checks.of(problem),
    )
    if result.status == "solved" and solution.status in ("verification_failed", "unreachable"):
        return _runner_up(problem, result, solution, partial)
    return solution


RUNNER_UP_TIME = 0.5
"""Seconds left in the time limit below which no other plan is verified after the search's
best failed (a verification takes 0.05-0.3 s on the zoo's draws)."""


def _runner_up(problem: Problem, result, failed: Solution, partial: StageRecord) -> Solution:
    """The first of the search's next best solved plans that verifies
    (:func:`cpopt.flatopt.runner_up.runner_ups`), else the failed solution as it was."""
    from .flatopt.runner_up import runner_ups

    for alternative in runner_ups(result, failed.message):
        if remaining() < RUNNER_UP_TIME:
            break
        progress.stage("flat optimizer: the best plan failed verification, the next solved plan")
        candidate = _evaluate(
            alternative.plan,
            problem.name,
            alternative.solver,
            alternative.status,
            alternative.solver.message,
            partial,
            Checks.of(problem),
        )
        if candidate.ok:
            return candidate
    return failed


def plan_closed_form(problem: Problem, partial: StageRecord) -> Solution:
    """The paper's closed-form plan, then sampling and verification."""
    spec = problem.spec
    partial.reached("planning (closed form)")
    start = time.perf_counter()
    try:
        plan = closed_form(problem.arm, problem.nodes, spec.closed_form.smooth_torque)
    except SingularPlanError as err:
        return Solution(
            problem.name,
            "singular",
            "closed_form",
            message=str(err),
            solver=SolverStats(message=str(err)),
        )
    info = SolverStats(solve_time_s=time.perf_counter() - start, message="closed form")
    return _evaluate(plan, problem.name, info, "solved", "", partial, Checks.of(problem))


PLANNERS: dict[str, Callable[[Problem, StageRecord], Solution]] = {
    "closed_form": plan_closed_form,
    "optimize": plan_optimized,
    "collocation": plan_collocation,
}
"""The planners by the name ``planner:`` gives in a problem file: each plans, samples and
verifies, recording its stages."""


def solve(problem: Problem, start: CPPlan | None = None) -> Solution:
    """Solve a validated problem with its planner and verify the result, within its time limit;
    with a ``tracking`` block, also track the solved plan on its plant. ``start``, a plan of a
    neighbouring problem, starts the flat optimizer (``planner: optimize`` only).

    Returns
    -------
    Solution
        Its ``status`` says whether it worked; failures never raise. When the wall-clock
        limit ``optimizer.solver.max_time`` runs out, the status is ``time_limit`` and the
        solution holds what was done (the plan, when planning had finished).

    Raises
    ------
    KeyboardInterrupt
        On Ctrl-C (however CasADi reported it).
    """
    partial = StageRecord()
    budget = Budget(problem.max_time)
    try:
        with enforced(budget):
            if start is not None and problem.planner == "optimize":
                solution = plan_optimized(problem, partial, start)
            else:
                solution = PLANNERS[problem.planner](problem, partial)
            if problem.spec.tracking is not None and solution.ok:
                from .tracking import track_problem

                partial.reached("tracking on the plant")
                solution = replace(solution, tracking=track_problem(problem, solution.plan))
    except TimeLimitExceeded:
        return _time_limited(problem, budget, partial)
    if budget.fired and not solution.ok:  # stopped inside Ipopt, which then returned
        return _time_limited(problem, budget, partial)
    return replace(solution, solver=replace(solution.solver, stage_times=partial.times()))


def _time_limited(problem: Problem, budget: Budget, partial: StageRecord) -> Solution:
    return time_limit_solution(
        problem,
        partial.stage,
        budget.elapsed,
        plan=partial.plan,
        trajectory=partial.trajectory,
        metrics=partial.metrics,
        solver=partial.solver,
    )


def time_limit_solution(
    problem: Problem, stage: str, elapsed: float, why: str = "", **partial
) -> Solution:
    """Status ``time_limit``: what was reached by then (``partial``: plan, trajectory, ...),
    the stage the limit struck in and the elapsed time [s] (``why``: how it was stopped),
    reported to progress as well."""
    message = (
        f"wall-clock limit of {problem.max_time:g} s reached while {stage} "
        f"(after {elapsed:.3g} s{why}); raise optimizer.solver.max_time or --time-limit"
    )
    progress.stage(message)
    return Solution(problem.name, "time_limit", problem.planner, message=message, **partial)
