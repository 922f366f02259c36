"""The remaining motion of a flat plan from a measured state: the problem a re-plan solves.

At time t the arm is measured at (q, qd). The remaining motion runs from there to the plan's
goal at T (a shrinking horizon). Its start is the measured third-link state with the
compensator's xi and eta free within the problem's bounds: the widest the problem gives xi
(``xi`` or ``xi_after`` of any node in ``optimizer.free``), and eta likewise; unbounded when
it frees none (measured on transfer_min_torque, a re-plan at 0.3 s from a perturbed state
wanted eta past the problem's +-200 m/s^3: bounded, it is a harder problem). The plan's
nodes still ahead keep their values (the switches the optimizer added keep their times and
their freed state, as the search solved them), and every other freed value of those nodes
stays free. Node times and the duration are fixed: the goal is still due at T. The
objective, limits and settings are the problem's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..closedform.curves import PiecewisePolynomial
from ..closedform.nodes import node_names
from ..closedform.plan import CPPlan, Node, Phase
from ..model.kinematics import forward_pose, kinematic_functions
from ..problem import Problem
from .switching import with_switches

NEAR_NODE = 0.1
"""A node closer than this ahead of the re-plan instant [s] is dropped from the remaining
motion: a phase that short leaves the NLP no room (the start's free xi gives the next phase's
sign of gamma, so a switch that close simply happens at the re-plan instant)."""
START_FREE = ("xi", "eta")
"""The start's values a re-plan chooses: the compensator's, not measured."""


@dataclass(frozen=True)
class Remaining:
    """The remaining motion of a plan from time ``t0`` [s] (in the plan's clock).

    Attributes
    ----------
    problem : Problem
        Nodes in the re-plan's own clock (start at 0), freed values and bounds.
    signs : tuple of int
        The sign of gamma of each remaining phase.
    switches : tuple of int
        Indices of the optimizer's switches among the problem's nodes.
    t0 : float
        The re-plan instant in the plan's clock [s].
    """

    problem: Problem
    signs: tuple[int, ...]
    switches: tuple[int, ...]
    t0: float


def measured_state(arm, q, qd) -> np.ndarray:
    """The third-link state (x, y, theta, xdot, ydot, thetadot) (6,) of joint positions and
    velocities [rad or m, rad/s or m/s]. theta is the joints' own sum, continuous along the
    motion, so it stays on the plan's branch (its joint motion starts on the start node's)."""
    q = np.asarray(q, float).ravel()
    qd = np.asarray(qd, float).ravel()
    pose = np.asarray(forward_pose(arm, q), float).ravel()
    velocity = np.asarray(kinematic_functions(arm)["jacobian"](q)) @ qd
    return np.r_[pose, velocity]


def plan_state_at(plan: CPPlan, t: float) -> np.ndarray:
    """The plan's extended state z (8,) at time t [s] (right limit at a node; theta as the flat
    map gives it, maybe 2 pi off the plan's branch: only xi and eta are used)."""
    from ..closedform.trajectory import flat_states

    starts = np.array([ph.curve.t0 for ph in plan.phases])
    phase = np.clip(np.searchsorted(starts, [t], side="right") - 1, 0, len(plan.phases) - 1)
    _, z = flat_states(plan, np.array([t]), phase)
    return np.asarray(z, float)[0]


def _augmented_free(problem: Problem, plan: CPPlan) -> dict:
    """The plan's freed values by the names of its own nodes (switches included, their times
    held)."""
    times = tuple(float(plan.nodes[i].t) for i in plan.switches)
    augmented, _ = with_switches(problem, times, free_times=False)
    return augmented.free


def compensator_bounds(problem: Problem, field: str) -> tuple[float, float]:
    """The widest bounds the problem gives ``field`` (``xi`` [m/s^2] or ``eta`` [m/s^3]) at
    any node (before or after a reset), or (-inf, inf) when it frees it nowhere."""
    bounds = [
        b for name, b in problem.free.items() if name.partition(".")[2] in (field, f"{field}_after")
    ]
    if not bounds:
        return (-math.inf, math.inf)
    return (min(lo for lo, _ in bounds), max(hi for _, hi in bounds))


def remaining(
    problem: Problem, plan: CPPlan, t: float, q, qd, free_compensator: bool = True
) -> Remaining | None:
    """The remaining motion of ``plan`` (a solution of ``problem``) from joint state (q, qd)
    at time t [s]; None when no node is more than :data:`NEAR_NODE` seconds ahead (hold the
    goal). With ``free_compensator`` False, xi and eta stay the plan's at t (the whole
    extended state is then given, and the plan's own state gives back its remainder).

    Raises
    ------
    ValueError
        For a path-timing plan (its path is fixed by the file, not by the nodes).
    """
    if problem.spec.optimizer.curve == "path_timing":
        raise ValueError("re-planning supports B-spline plans, not curve: path_timing")
    ahead = [i for i, n in enumerate(plan.nodes) if n.t > t + NEAR_NODE]
    if not ahead:
        return None
    guess = plan_state_at(plan, t)
    state = measured_state(plan.arm, q, qd)
    start = Node(0.0, *state, xi=guess[6], eta=guess[7])
    nodes = [start] + [replace(plan.nodes[i], t=plan.nodes[i].t - t) for i in ahead]
    old = node_names(len(plan.nodes))
    new = node_names(len(nodes))
    renamed = {old[i]: new[j + 1] for j, i in enumerate(ahead)}
    free = {}
    for name, bounds in _augmented_free(problem, plan).items():
        node, _, field = name.partition(".")
        if node in renamed and field != "t":
            free[f"{renamed[node]}.{field}"] = bounds
    for field in START_FREE if free_compensator else ():
        free[f"start.{field}"] = compensator_bounds(problem, field)
    signs = tuple(plan.phases[i - 1].sigma for i in ahead)
    switches = tuple(j + 1 for j, i in enumerate(ahead) if i in plan.switches)
    return Remaining(replace(problem, nodes=tuple(nodes), free=free), signs, switches, t)


def shifted(plan: CPPlan, dt: float) -> CPPlan:
    """The plan with every time moved by dt [s] (its curves, nodes and nothing else)."""
    phases = tuple(
        Phase(PiecewisePolynomial(ph.curve.breaks + dt, ph.curve.coeffs), ph.sigma)
        for ph in plan.phases
    )
    nodes = tuple(replace(n, t=n.t + dt) for n in plan.nodes)
    return replace(plan, nodes=nodes, phases=phases)


__all__ = [
    "NEAR_NODE",
    "Remaining",
    "compensator_bounds",
    "measured_state",
    "plan_state_at",
    "remaining",
    "shifted",
]
