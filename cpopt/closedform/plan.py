"""CP plans: phases of CP curves between nodes, and the paper's closed-form planner.

A motion passes through nodes (start, via states, goal) at given times. Each node fixes the
third link's state and the compensator values (xi, eta); both may be reset at a via state
(``xi``, ``eta`` before, ``xi_after``, ``eta_after`` after) while the arm's state stays
continuous. A phase joins two consecutive nodes with one CP curve and keeps its own sign of
gamma; a xi reset moves gamma by the same amount, so the phases on either side of it may have
opposite signs (the torque steps once, there).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..model import flat
from ..model.robot import Arm
from .curves import PiecewisePolynomial, hermite

GAMMA_ZERO = 1e-3
"""|gamma| below this [m/s^2] counts as singular: there thetadot = (normal CP jerk) / gamma
blows up and the angle is undetermined (1e-4 g0; round-off alone leaves ~1e-5 on a curve that
touches zero exactly)."""


class SingularPlanError(ValueError):
    """A plan on which gamma vanishes or changes sign (the flat map is singular there)."""


@dataclass(frozen=True)
class Node:
    """A state the motion passes through, with its compensator values.

    Parameters
    ----------
    t : float
        Time [s].
    x, y : float
        Position of the third link's base [m].
    theta : float
        Third link's angle from the x-axis [rad].
    xdot, ydot, thetadot : float
        Velocities [m/s, m/s, rad/s].
    xi : float
        Compensator state xi [m/s^2] on arrival (and departure unless ``xi_after`` is set).
    eta : float
        Compensator state eta [m/s^3] on arrival (and departure unless ``eta_after`` is set).
    eta_after : float or None
        eta after a reset at this node [m/s^3].
    xi_after : float or None
        xi after a reset at this node [m/s^2]: gamma moves by ``xi_after - xi``, so the next
        phase may take the other sign of gamma.
    alpha : tuple of float or None
        Compensator inputs (alpha1 [m/s^4], alpha2 [m/s^2]) to pin at this node for torque
        continuity (``smooth_torque``); ``None`` leaves the fourth CP derivative free.
    """

    t: float
    x: float
    y: float
    theta: float
    xdot: float = 0.0
    ydot: float = 0.0
    thetadot: float = 0.0
    xi: float = 0.0
    eta: float = 0.0
    eta_after: float | None = None
    alpha: tuple[float, float] | None = None
    xi_after: float | None = None

    def state(self, after: bool = False) -> np.ndarray:
        """The extended state z = (x, y, theta, xdot, ydot, thetadot, xi, eta) (8,), on
        arrival or, with ``after``, after the node's resets of xi and eta."""
        xi = self.xi_after if (after and self.xi_after is not None) else self.xi
        eta = self.eta_after if (after and self.eta_after is not None) else self.eta
        return np.array(
            [self.x, self.y, self.theta, self.xdot, self.ydot, self.thetadot, xi, eta], float
        )

    @property
    def resets_xi(self) -> bool:
        """True when xi is reset here (``xi_after`` set and different from ``xi``)."""
        return self.xi_after is not None and self.xi_after != self.xi

    @property
    def at_rest(self) -> bool:
        """True when all velocities are zero."""
        return self.xdot == 0 and self.ydot == 0 and self.thetadot == 0


@dataclass(frozen=True)
class Phase:
    """One phase of a plan: a CP curve on [t0, t1] with its own fixed sign of gamma."""

    curve: PiecewisePolynomial
    sigma: int


@dataclass(frozen=True)
class CPPlan:
    """A CP plan: consecutive phases between nodes, for one arm.

    Parameters
    ----------
    arm : Arm
        The arm (its K and gravity enter the flat maps).
    nodes : tuple of Node
        Start, via states and goal, in time order.
    phases : tuple of Phase
        One per pair of consecutive nodes.
    planner : str
        Which planner made it (``closed_form``, ``optimize``, ...).
    free_values : dict
        Values the planner chose, by name (empty for the closed form).
    switches : tuple of int
        Indices in ``nodes`` of the via states a planner added to switch the sign of gamma
        (named ``switch[j]``, see :func:`cpopt.closedform.nodes.node_names`); the other via
        states are the problem's.
    """

    arm: Arm
    nodes: tuple[Node, ...]
    phases: tuple[Phase, ...]
    planner: str = "closed_form"
    free_values: dict = field(default_factory=dict)
    switches: tuple[int, ...] = ()

    @property
    def t0(self) -> float:
        """Start time [s]."""
        return self.nodes[0].t

    @property
    def duration(self) -> float:
        """Total duration [s]."""
        return self.nodes[-1].t - self.nodes[0].t

    @property
    def signs(self) -> tuple[int, ...]:
        """The sign of gamma of each phase."""
        return tuple(ph.sigma for ph in self.phases)

    def min_abs_gamma(self) -> tuple[float, float]:
        """Certified minimum of |gamma| over the whole plan [m/s^2] and where it occurs [s].

        Exact: on every polynomial piece, ``gamma^2 = |p'' + g0 e_y|^2`` is a polynomial
        minimised at a piece end or at a root of its derivative.
        """
        offset = (0.0, self.arm.gravity)
        return min(ph.curve.min_norm_of_acceleration_plus(offset) for ph in self.phases)


def _phase_sign(gam_start: float, gam_end: float, index: int) -> int:
    if abs(gam_start) < GAMMA_ZERO or abs(gam_end) < GAMMA_ZERO:
        raise SingularPlanError(
            f"phase {index + 1}: gamma is zero at a node (gamma = {gam_start:.4g} at its start, "
            f"{gam_end:.4g} at its end, m/s^2); choose xi at the node so that "
            "gamma = xi - K thetadot^2 + g0 sin(theta) is not zero"
        )
    if np.sign(gam_start) != np.sign(gam_end):
        raise SingularPlanError(
            f"phase {index + 1}: gamma changes sign between its nodes (gamma = {gam_start:.4g} "
            f"at its start, {gam_end:.4g} at its end, m/s^2), so it must vanish in between; "
            "choose xi at the nodes so that gamma keeps one sign in the phase (a xi reset at "
            "a via state, xi_after, lets the next phase take the other sign)"
        )
    return int(np.sign(gam_start))


def node_boundary(arm: Arm, node: Node, after: bool, pin_fourth: bool) -> np.ndarray:
    """CP derivatives 0..3 (2, 4) at a node, plus the fourth (2, 5) when it is pinned.

    The fourth derivative is ``A(z) alpha + b(z)`` for the node's compensator inputs alpha
    (zero by default), which fixes the base acceleration and hence the torque at the node.
    """
    K, g0 = arm.K, arm.gravity
    z = node.state(after)
    P = flat.output(z, K, g0)
    if not pin_fourth:
        return P
    alpha = np.zeros(2) if node.alpha is None else np.asarray(node.alpha, float)
    v = np.asarray(flat.flat_functions(K, g0)["fourth"](z, alpha)).ravel()
    return np.column_stack([P, v])


def check_regular(plan: CPPlan) -> None:
    """Refuse a plan on which |gamma| gets below :data:`GAMMA_ZERO` (certified, not sampled).

    Raises
    ------
    SingularPlanError
        Naming the time where gamma vanishes.
    """
    value, t = plan.min_abs_gamma()
    if value < GAMMA_ZERO:
        raise SingularPlanError(
            f"gamma vanishes at t = {t:.4g} s (|gamma| = {value:.3g} m/s^2): the plan crosses "
            "the singularity of the flat map; change the compensator values, add a via state "
            "or move the via time"
        )


def closed_form(
    arm: Arm, nodes: Sequence[Node], smooth_torque: bool = False, check: bool = True
) -> CPPlan:
    """The paper's closed-form plan: one Hermite polynomial per CP coordinate per phase.

    Parameters
    ----------
    arm : Arm
        The arm.
    nodes : sequence of Node
        Start, via states and goal with strictly increasing times.
    smooth_torque : bool
        False: seventh-degree polynomials matching derivatives 0..3 (the paper). True:
        ninth-degree polynomials that also pin the fourth derivative at every node from the
        node's compensator inputs ``alpha`` (zero by default), so the torque is continuous at
        via states (except where xi is reset: it steps there) and equals the holding torque at
        rest ends with xi = eta = 0.
    check : bool
        Refuse a plan on which gamma vanishes (False only to get a warm start for an
        optimizer, which must move the plan away from the singularity).

    Returns
    -------
    CPPlan

    Raises
    ------
    SingularPlanError
        If gamma is zero or changes sign at the nodes, or vanishes anywhere along the plan.
    """
    nodes = tuple(nodes)
    if len(nodes) < 2:
        raise ValueError("a plan needs at least a start and a goal node")
    times = np.array([n.t for n in nodes])
    if np.any(np.diff(times) <= 0):
        raise ValueError(f"node times must increase strictly, got {times.tolist()} s")
    K, g0 = arm.K, arm.gravity
    phases = []
    for i, (a, b) in enumerate(itertools.pairwise(nodes)):
        gam_a = float(flat.gamma(a.state(after=True), K, g0))
        sigma = (
            _phase_sign(gam_a, float(flat.gamma(b.state(), K, g0)), i)
            if check
            else (1 if gam_a >= 0 else -1)
        )
        start = node_boundary(arm, a, True, smooth_torque)
        end = node_boundary(arm, b, False, smooth_torque)
        phases.append(Phase(hermite(a.t, b.t, start, end), sigma))
    plan = CPPlan(arm=arm, nodes=nodes, phases=tuple(phases), planner="closed_form")
    if check:
        check_regular(plan)
    return plan
