"""``cpopt.replan``: the remaining motion of a solved plan from a measured state.

The public face of :mod:`cpopt.flatopt.replan` (what the ``flat_mpc`` controller calls in its
loop): it checks its arguments and names what is wrong, as the rest of the API does.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from .closedform.plan import CPPlan
from .flatopt.replan import METHODS, Multipliers, Replan
from .flatopt.replan import replan as solve_remaining
from .io.safe_yaml import echo as echo_value
from .solution import Solution


def echo(value) -> str:
    """A value as an error message shows it, on one line (an array's repr has several)."""
    return " ".join(echo_value(value).split())


def _vector(value, name: str) -> np.ndarray:
    """Three finite numbers, or a ValueError naming the argument."""
    try:
        out = np.asarray(value, float).ravel()
    except (TypeError, ValueError):
        out = np.zeros(0)
    if out.shape != (3,) or not np.all(np.isfinite(out)):
        raise ValueError(f"{name}: expected 3 finite numbers (one per joint), got {echo(value)}")
    return out


def _checked_time(t, plan: CPPlan) -> float:
    """t as seconds within the plan, or a ValueError naming it."""
    real = isinstance(t, numbers.Real) and not isinstance(t, bool)
    if not real or not math.isfinite(t) or not plan.t0 <= t <= plan.t0 + plan.duration:
        raise ValueError(
            f"t: expected a time [s] within the plan, {plan.t0:g} to "
            f"{plan.t0 + plan.duration:g}, got {echo(t)}"
        )
    return float(t)


def replan(
    solution: Solution,
    t,
    q,
    qd,
    *,
    plan: CPPlan | None = None,
    deadline_s: float | None = None,
    warm: Multipliers | None = None,
    free_compensator: bool = True,
    method: str = "ipopt",
) -> Replan:
    """Re-plan a solved flat plan from the measured joint state (q, qd) at time t.

    The remaining motion to the plan's goal at T (a shrinking horizon) keeps the plan's
    pattern of signs of gamma and its switch times still ahead, chooses the compensator's xi
    and eta at t (within the problem's bounds, see :mod:`cpopt.flatopt.remaining_motion`),
    and has the problem's objective and limits; it is warm started from the current plan and
    solved within ``deadline_s`` by Ipopt on the lifted NLP, or by a dense SQP on the NLP's
    core variables (:mod:`cpopt.flatopt.replan_sqp`).

    Parameters
    ----------
    solution : Solution
        A solution of :func:`cpopt.solve` with a flat plan (``planner: optimize``,
        B-spline curves) and its problem.
    t : float
        The re-plan instant [s], within the plan.
    q, qd : array_like
        Measured joint positions and velocities (3,) [rad or m, rad/s or m/s].
    plan : CPPlan, optional
        The current plan when it is a re-plan of the solution's (default: the solution's).
    deadline_s : float, optional
        Wall time the re-plan may take [s] (status ``time_limit`` or ``late`` past it; None:
        no deadline).
    warm : Multipliers, optional
        The previous re-plan's :attr:`~cpopt.flatopt.replan.Replan.multipliers`.
    free_compensator : bool
        False holds xi and eta at the plan's values at t.
    method : str
        ``ipopt`` (the default) or ``sqp``: stopped early, the SQP returns its best iterate
        that keeps every row, status ``feasible``, followed like a solved plan.

    Returns
    -------
    Replan
        ``.status``, ``.plan`` (the new plan, or the previous one when the re-plan did not
        solve in time: ``.kept_previous``), ``.usable`` (``solved`` or ``feasible``),
        ``.iterate``, ``.iterations``, ``.time_s``.

    Raises
    ------
    ValueError
        For an argument of the wrong kind (naming it), a solution without a flat plan or its
        problem, a path-timing plan, or a time outside the plan.
    """
    if not isinstance(solution, Solution) or solution.problem is None:
        raise ValueError(f"solution: expected a Solution of cpopt.solve, got {echo(solution)}")
    if plan is not None and not isinstance(plan, CPPlan):
        raise ValueError(f"plan: expected a CPPlan (a re-plan's .plan), got {echo(plan)}")
    current = plan if plan is not None else solution.plan
    arguments = (_checked_time(t, current), _vector(q, "q"), _vector(qd, "qd"))
    _check_options(deadline_s, warm, free_compensator)
    if not isinstance(method, str) or method not in METHODS:
        raise ValueError(f"method: expected one of {', '.join(METHODS)}, got {echo(method)}")
    if current.planner != "optimize" or solution.problem.planner != "optimize":
        raise ValueError(
            f"{solution.name}: re-planning needs a flat plan of planner: optimize "
            f"(status {solution.status}, planner {solution.planner})"
        )
    return solve_remaining(
        solution.problem,
        current,
        *arguments,
        deadline_s=math.inf if deadline_s is None else float(deadline_s),
        warm=warm,
        free_compensator=free_compensator,
        method=method,
    )


def _check_options(deadline_s, warm, free_compensator) -> None:
    """Refuse a deadline that is not seconds > 0, a ``warm`` that is not a re-plan's
    multipliers, a ``free_compensator`` that is not True or False."""
    real = isinstance(deadline_s, numbers.Real) and not isinstance(deadline_s, bool)
    if deadline_s is not None and not (real and math.isfinite(deadline_s) and deadline_s > 0):
        raise ValueError(
            f"deadline_s: expected a finite number of seconds > 0, got {echo(deadline_s)}"
        )
    if warm is not None and not isinstance(warm, Multipliers):
        raise ValueError(
            f"warm: expected a re-plan's multipliers (Replan.multipliers), got {echo(warm)}"
        )
    if not isinstance(free_compensator, bool):
        raise ValueError(f"free_compensator: expected True or False, got {echo(free_compensator)}")


__all__ = ["replan"]
