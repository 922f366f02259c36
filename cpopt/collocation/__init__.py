"""Direct collocation of the arm's full dynamics: the generic method, kept as a benchmark peer.

This is what a user would otherwise write: joint positions and velocities as states, the two
actuated torques as piecewise-constant controls, the passive joint torque-free through the
forward dynamics ``qdd = B^-1 ([tau; 0] - n)``, transcribed by rockit (direct collocation or
multiple shooting) and solved by Ipopt or Fatrop (``collocation.solver``; Fatrop, the
structure-exploiting interior-point solver shipped with CasADi, takes single-phase problems
with fixed times in multiple shooting). The problem is the flat optimizer's: same nodes,
objective, limits and duration, read from the same ``optimizer`` block, plus the settings of
the ``collocation`` block. With ``gamma_constraint`` the regularity quantity

    gamma = (xddot, yddot + g0) . (cos theta, sin theta) - K thetadot^2,

computed from the joint state and the accelerations the torques produce, keeps one sign with
``sign(gamma) gamma >= gamma_min`` at every knot (not between knots: the flat optimizer
certifies it everywhere).

Node values are imposed as given: fixed fields by equality, freed fields within their bounds.
Angles are taken literally (a goal at -270 deg and one at 90 deg are different windings).
Compensator values (xi, eta) do not exist here and are ignored.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from ..problem import Problem
from ..runtime.budget import check_stop
from ..runtime.solver import SolverStats, read_stats
from .joint_plan import (
    REFINE,
    JointPlan,
    ReplayCheck,
    joint_functions,
    joint_metrics,
    joint_sample_at,
    joint_trajectory,
    replay,
)
from .transcribe import RUN_LABEL, extract, transcription


@dataclass(frozen=True)
class CollocationDetails:
    """What the collocation planner reports beyond the common solver statistics."""

    intervals: int
    method: str
    solver: str
    gamma_constraint: bool
    gamma_sign: int | None
    variables: int | None

    def as_dict(self) -> dict:
        """JSON-ready figures for ``solution.json``."""
        return {
            "intervals": self.intervals,
            "method": self.method,
            "solver": self.solver,
            "gamma_constraint": self.gamma_constraint,
            "gamma_sign": self.gamma_sign,
            "variables": self.variables,
        }


@dataclass(frozen=True)
class CollocationResult:
    """Outcome of :func:`collocate`: status, plan (or best iterate), solver statistics."""

    status: str
    plan: JointPlan | None
    solver: SolverStats


def collocate(
    problem: Problem,
    intervals: int | None = None,
    gamma_constraint: bool | None = None,
    warm_start=None,
) -> CollocationResult:
    """Plan a problem by direct collocation of the arm's full dynamics (see module docstring).

    Parameters
    ----------
    problem : Problem
        The problem; ``collocation`` and ``optimizer`` blocks give the settings.
    intervals : int, optional
        Control intervals over the whole motion (default ``collocation.intervals``).
    gamma_constraint : bool, optional
        Keep ``sign(gamma) gamma >= gamma_min`` at every knot (default from the file).
    warm_start : CPPlan, optional
        A flat plan to start from (its joint motion, torques and sign of gamma); without it,
        a smooth step between the nodes' joint states at the holding torques.

    Returns
    -------
    CollocationResult
        The solver's status (``solved``, ``infeasible``, ``max_iterations``,
        ``not_converged``) and the plan, its best iterate when it failed.
    """
    col = problem.spec.collocation
    intervals = intervals or col.intervals
    gamma_constraint = col.gamma_constraint if gamma_constraint is None else gamma_constraint
    tic = time.perf_counter()
    ocp, stages, sign = transcription(problem, intervals, gamma_constraint, warm_start)
    try:
        sol = ocp.solve_limited()
    except RuntimeError:  # a failure that is not a limit (Fatrop's return status 1, ...)
        sol = ocp.non_converged_solution
    check_stop()
    total = time.perf_counter() - tic
    said, status, iterations = read_stats(sol.stats)
    solve_time = float(sol.stats.get("t_wall_total", total))  # the solver alone (record_time)
    plan = extract(problem, sol, stages, sign if gamma_constraint else 0)
    count = sum(s.intervals for s in stages)
    stats = SolverStats(
        iterations=iterations,
        build_time_s=total - solve_time,
        solve_time_s=solve_time,
        message=f"{col.solver.capitalize()}: {said} (collocation, {col.method}, {count} "
        f"intervals, gamma constraint {'on' if gamma_constraint else 'off'})",
        objective=float(sol.value(ocp.objective)),
        details=CollocationDetails(
            intervals=count,
            method=col.method,
            solver=col.solver,
            gamma_constraint=gamma_constraint,
            gamma_sign=sign if gamma_constraint else None,
            variables=int(sol.stats["n_x"]) if "n_x" in sol.stats else None,
        ),
    )
    return CollocationResult(status=status, plan=plan, solver=stats)


__all__ = [
    "REFINE",
    "RUN_LABEL",
    "CollocationDetails",
    "CollocationResult",
    "JointPlan",
    "ReplayCheck",
    "collocate",
    "joint_functions",
    "joint_metrics",
    "joint_sample_at",
    "joint_trajectory",
    "replay",
]
