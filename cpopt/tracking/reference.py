"""A plan on the controller's grid: what both controllers track, computed once per plan.

At every control instant t_k = t0 + k / rate the reference holds the joint state, the plan's
torque (right limit, and its mean over the period, which is the feed-forward a zero-order hold
should apply), the CP and its derivatives 0..4, the compensator state (xi, eta) and the
compensator resets to apply at that instant.

* A flat plan (:class:`~cpopt.plan.CPPlan`) gives everything exactly through the inverse flat
  map; its resets are the nodes' ``state(after=True) - state()`` on (xi, eta).
* A collocation plan (joint motion under piecewise-constant torques) gives the joint state by
  integrating the model from the last knot under that knot's torque; the CP derivatives are
  Lie derivatives of the CP along those constant-torque dynamics, defined inside each interval.
  At a knot the torque steps, so the base acceleration and with it xi and eta jump: for the
  dynamic feedback linearisation every knot is a compensator reset, exactly like a planned
  xi reset of a flat plan. Where gamma crosses zero inside an interval that controller is
  singular and :attr:`Reference.dfl_issue` says so.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from ..closedform.plan import GAMMA_ZERO, CPPlan, Node
from ..closedform.trajectory import flat_states
from ..model import flat
from ..model.dynamics import arm_dynamics, inverse_dynamics, rk4_step
from ..model.kinematics import inverse_derivatives, inverse_position, kinematic_functions
from ..model.mapping import mapped
from ..model.robot import Arm

GAUSS = np.polynomial.legendre.leggauss(3)
"""Gauss-Legendre nodes and weights on [-1, 1] for the period means of a flat plan's torque."""


@dataclass(frozen=True)
class Reference:
    """A plan sampled at the control instants (SI units, radians).

    Attributes
    ----------
    arm : Arm
        The model the plan was made for.
    period : float
        Control period [s].
    t : numpy.ndarray
        Control instants (n + 1,) [s], the last at the end of the plan (see
        :func:`control_grid`).
    x : numpy.ndarray
        Joint positions and velocities (n + 1, 6).
    tau : numpy.ndarray
        The plan's torques at the instants (n + 1, 2) (right limits) [N m or N].
    tau_mean : numpy.ndarray
        The plan's torques averaged over each period (n, 2) [N m or N].
    tau_mid : numpy.ndarray
        The plan's torques in the middle of each period (n, 2) [N m or N].
    cp : numpy.ndarray
        CP derivatives 0..4 at the instants (n + 1, 2, 5) [m/s^k] (right limits).
    cp_mid : numpy.ndarray
        CP derivatives 0..4 in the middle of each period (n, 2, 5) [m/s^k].
    compensator : numpy.ndarray
        (xi, eta) at the instants (n + 1, 2) [m/s^2, m/s^3] (right limits).
    resets : numpy.ndarray
        Jump of (xi, eta) to apply at each instant (n + 1, 2), zero except at the first instant
        at or after a reset.
    goal : Node
        The plan's last node.
    dfl_issue : str
        Why the dynamic feedback linearisation cannot follow this plan ('' when it can).
    """

    arm: Arm
    period: float
    t: np.ndarray
    x: np.ndarray
    tau: np.ndarray
    tau_mean: np.ndarray
    tau_mid: np.ndarray
    cp: np.ndarray
    cp_mid: np.ndarray
    compensator: np.ndarray
    resets: np.ndarray
    goal: Node
    dfl_issue: str = ""

    @property
    def steps(self) -> int:
        """Number of control periods n."""
        return self.t.size - 1


def control_grid(t0: float, duration: float, rate_hz: float) -> tuple[np.ndarray, float]:
    """Control instants (n + 1,) [s] spanning the plan and the period [s].

    n = ceil(duration * rate_hz) periods of duration / n: the rate is rounded up (by less than
    one period per plan) so that the last instant is the end of the plan, where the goal is.
    """
    n = max(1, int(np.ceil(duration * rate_hz - 1e-9)))
    return t0 + duration * np.arange(n + 1) / n, duration / n


def reference(plan, rate_hz: float) -> Reference:
    """The reference of a flat plan (CPPlan) or a collocation plan on a grid of ``rate_hz``."""
    if isinstance(plan, CPPlan):
        return flat_reference(plan, rate_hz)
    return joint_reference(plan, rate_hz)


def _phase_at(plan: CPPlan, t: np.ndarray) -> np.ndarray:
    """Index of the phase each time belongs to (right-continuous: a node starts a phase)."""
    starts = np.array([ph.curve.t0 for ph in plan.phases])
    return np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(plan.phases) - 1)


def _flat_samples(plan: CPPlan, t: np.ndarray, phase: np.ndarray | None = None) -> dict:
    """CP derivatives, states, joint motion and torques of a flat plan at sorted times t, on
    the given phases (by default the phase of each time; a phase's curve is held at its end
    beyond it)."""
    arm = plan.arm
    K, g0 = arm.K, arm.gravity
    t = np.clip(t, plan.t0, plan.nodes[-1].t)
    phase = _phase_at(plan, t) if phase is None else phase
    P, z = flat_states(plan, t, phase)
    z[:, 2] = np.unwrap(z[:, 2])
    z[:, 2] += 2 * np.pi * np.round((plan.nodes[0].theta - z[0, 2]) / (2 * np.pi))
    _, zdot, _ = flat.compensate(z, P[:, :, 4], K, g0)
    q = inverse_position(arm, z[:, 0], z[:, 1], z[:, 2], t)
    qd, qdd = inverse_derivatives(arm, q, z[:, 3:6], zdot[:, 3:6])
    tau = inverse_dynamics(arm, q, qd, qdd)[:, :2]
    return {"P": P, "z": z, "q": q, "qd": qd, "tau": tau}


def flat_reference(plan: CPPlan, rate_hz: float) -> Reference:
    """A flat plan on the control grid of ``rate_hz`` [Hz] (see the module docstring)."""
    t, period = control_grid(plan.t0, plan.duration, rate_hz)
    at = _flat_samples(plan, t)
    # means over each period by 3-point Gauss-Legendre (exact away from a torque step)
    nodes, weights = GAUSS
    inner = (t[:-1, None] + period * (nodes[None, :] + 1) / 2).ravel()
    inside = _flat_samples(plan, inner)
    tau_mean = np.einsum("knj,n->kj", inside["tau"].reshape(-1, nodes.size, 2), weights / 2)
    # the middle of each period on the phase of its start: a reset takes effect at an instant
    middle = _flat_samples(plan, t[:-1] + period / 2, _phase_at(plan, t[:-1]))
    resets = np.zeros((t.size, 2))
    for node in plan.nodes[1:-1]:
        k = min(int(np.searchsorted(t, node.t - 1e-12)), t.size - 1)
        resets[k] += node.state(after=True)[6:8] - node.state()[6:8]
    return Reference(
        arm=plan.arm,
        period=period,
        t=t,
        x=np.column_stack([at["q"], at["qd"]]),
        tau=at["tau"],
        tau_mean=tau_mean,
        tau_mid=middle["tau"],
        cp=at["P"],
        cp_mid=middle["P"],
        compensator=at["z"][:, 6:8],
        resets=resets,
        goal=plan.nodes[-1],
    )


@lru_cache(maxsize=16)
def cp_lie_derivatives(arm: Arm) -> ca.Function:
    """``cp(q, qd, tau) -> P`` (2 x 5): the CP and its derivatives 0..4 along the motion
    under a constant torque tau (Lie derivatives of the model's dynamics)."""
    q = ca.SX.sym("q", 3)
    qd = ca.SX.sym("qd", 3)
    tau = ca.SX.sym("tau", 2)
    x = ca.vertcat(q, qd)
    s = kinematic_functions(arm)["pose"](q)
    field = ca.vertcat(qd, arm_dynamics(arm)["forward"](q, qd, tau))
    derivs = [s[0:2] + arm.K * ca.vertcat(ca.cos(s[2]), ca.sin(s[2]))]
    for _ in range(4):
        derivs.append(ca.jtimes(derivs[-1], x, field))
    return ca.Function("cp_lie", [q, qd, tau], [ca.cse(ca.horzcat(*derivs))])


def _cp_and_compensator(arm: Arm, x: np.ndarray, tau: np.ndarray):
    """CP derivatives (N, 2, 5), (xi, eta) (N, 2) and gamma (N,) of joint states under torques."""
    n = x.shape[0]
    P = np.asarray(mapped(cp_lie_derivatives(arm), n)(x[:, :3].T, x[:, 3:].T, tau.T))
    P = P.reshape(2, n, 5).transpose(1, 0, 2)
    theta = np.asarray(mapped(kinematic_functions(arm)["pose"], n)(x[:, :3].T))[2]
    # p'' + g0 e_y = gamma (cos theta, sin theta)
    gamma = np.cos(theta) * P[:, 0, 2] + np.sin(theta) * (P[:, 1, 2] + arm.gravity)
    compensator = np.zeros((n, 2))
    for sigma in (-1.0, 1.0):
        sel = np.sign(gamma) == sigma
        if sel.any():
            z = flat.inverse(P[sel][:, :, :4], sigma, arm.K, arm.gravity)
            compensator[sel] = z[:, 6:8]
    return P, compensator, gamma


def _joint_states(plan, t: np.ndarray, j: np.ndarray | None = None):
    """Joint states (N, 6), torques (N, 2) and interval indices (N,) of a collocation plan at
    times t: the model integrated from the start of interval j (by default the one holding
    t) under that interval's torque."""
    knots = np.asarray(plan.knots, float)
    tc = np.clip(t, knots[0], knots[-1])
    if j is None:
        j = np.clip(np.searchsorted(knots, tc, side="right") - 1, 0, len(plan.tau) - 1)
    start = np.column_stack([plan.q[j], plan.qd[j]])
    x = np.asarray(mapped(rk4_step(plan.arm), t.size)(start.T, plan.tau[j].T, tc - knots[j])[0]).T
    return x, plan.tau[j], j


def joint_reference(plan, rate_hz: float) -> Reference:
    """A collocation plan (``knots``, ``q``, ``qd``, ``tau``) on the control grid [Hz]."""
    arm = plan.arm
    knots = np.asarray(plan.knots, float)
    t, period = control_grid(knots[0], knots[-1] - knots[0], rate_hz)
    x, tau, j = _joint_states(plan, t)
    x_mid, tau_mid, _ = _joint_states(plan, t[:-1] + period / 2, j[:-1])
    tc = np.clip(t, knots[0], knots[-1])
    cumulative = np.concatenate([[[0.0, 0.0]], np.cumsum(np.diff(knots)[:, None] * plan.tau, 0)])
    integral = np.column_stack([np.interp(tc, knots, cumulative[:, i]) for i in range(2)])
    tau_mean = np.diff(integral, axis=0) / period
    P, compensator, gamma = _cp_and_compensator(arm, x, tau)
    P_mid, _, _ = _cp_and_compensator(arm, x_mid, tau_mid)
    resets = np.zeros((t.size, 2))
    at_knots = np.column_stack([plan.q[1:-1], plan.qd[1:-1]])
    if len(at_knots):
        _, before, _ = _cp_and_compensator(arm, at_knots, plan.tau[:-1])
        _, after, _ = _cp_and_compensator(arm, at_knots, plan.tau[1:])
        k = np.minimum(np.searchsorted(t, knots[1:-1] - 1e-12), t.size - 1)
        np.add.at(resets, k, after - before)
    return Reference(
        arm=arm,
        period=period,
        t=t,
        x=x,
        tau=tau,
        tau_mean=tau_mean,
        tau_mid=tau_mid,
        cp=P,
        cp_mid=P_mid,
        compensator=compensator,
        resets=resets,
        goal=plan.nodes[-1],
        dfl_issue=_gamma_issue(t, j, gamma),
    )


def _gamma_issue(t: np.ndarray, interval: np.ndarray, gamma: np.ndarray) -> str:
    """Where gamma vanishes or changes sign inside a constant-torque interval ('' if nowhere)."""
    small = np.abs(gamma) < GAMMA_ZERO
    flips = (np.sign(gamma[1:]) != np.sign(gamma[:-1])) & (interval[1:] == interval[:-1])
    bad = np.flatnonzero(small | np.r_[flips, False])
    if bad.size == 0:
        return ""
    return (
        f"gamma crosses zero at t = {t[bad[0]]:.4g} s inside a constant-torque interval of the "
        "collocation plan: the dynamic feedback linearisation is singular there (plan with "
        "collocation.gamma_constraint: true, or track with tvlqr)"
    )
