"""A collocation plan: joint motion and piecewise-constant torques, sampled into a trajectory,
measured, and verified by replaying its torques open loop on the arm's full dynamics.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import casadi as ca
import numpy as np

from ..closedform.plan import Node
from ..closedform.trajectory import Metrics, Trajectory, checked_times, gamma_crossings
from ..model.dynamics import arm_dynamics, holding_torque
from ..model.kinematics import kinematic_functions
from ..model.mapping import mapped
from ..model.robot import Arm
from ..verify.integrate import integrate
from ..verify.simulate import SimulationResult, cp_of, goal_error, pose_states

REFINE = 8
"""Samples per interval of the collocation polynomials in the trajectory."""


@lru_cache(maxsize=16)
def joint_functions(arm: Arm) -> ca.Function:
    """``step(q, qd, tau) -> (qdd, gamma, s, sdot, sddot)`` for the full dynamics.

    qdd are the joint accelerations the actuated torques tau (2,) [N m or N] produce with the
    passive joint free; gamma [m/s^2] is the regularity quantity of that motion; s = (x, y,
    theta) is the third link's pose, sdot and sddot its velocity and acceleration.
    """
    q = ca.SX.sym("q", 3)
    qd = ca.SX.sym("qd", 3)
    tau = ca.SX.sym("tau", 2)
    kin = kinematic_functions(arm)
    qdd = arm_dynamics(arm)["forward"](q, qd, tau)
    s = kin["pose"](q)
    J = kin["jacobian"](q)
    sdot = J @ qd
    sddot = J @ qdd + kin["jdot_qdot"](q, qd)
    theta = s[2]
    gamma = (
        sddot[0] * ca.cos(theta) + (sddot[1] + arm.gravity) * ca.sin(theta) - arm.K * sdot[2] ** 2
    )
    return ca.Function("step", [q, qd, tau], [qdd, gamma, s, sdot, sddot])


@dataclass(frozen=True)
class JointPlan:
    """A plan as joint motion and piecewise-constant torques (what collocation returns).

    Attributes
    ----------
    arm : Arm
        The arm.
    nodes : tuple of Node
        Start, via states and goal as reached by the plan (SI units).
    knots : numpy.ndarray
        Control knots (M + 1,) [s]; the torque is constant on each interval between them.
    q, qd : numpy.ndarray
        Joint positions and velocities at the knots (M + 1, 3).
    tau : numpy.ndarray
        Torques (M, 2) [N m or N] on each interval.
    fine : dict
        The collocation polynomials sampled ``REFINE`` times per interval: ``t``, ``q``,
        ``qd``, ``tau`` (the interval's torque).
    sigma : int
        The sign of gamma the plan was asked to keep (0 when unconstrained).
    """

    arm: Arm
    nodes: tuple
    knots: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    fine: dict
    sigma: int
    planner: str = "collocation"
    free_values: dict = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Duration of the motion [s]."""
        return float(self.knots[-1] - self.knots[0])

    def torque_at(self, t: float) -> np.ndarray:
        """The torque (2,) applied at time t [s] (right-continuous, the last one at the end)."""
        k = int(np.clip(np.searchsorted(self.knots, t, side="right") - 1, 0, len(self.tau) - 1))
        return self.tau[k]

    def torque_sq_integral(self) -> float:
        """Exact integral of tau1^2 + tau2^2 dt of the piecewise-constant torques."""
        return float(np.sum(np.diff(self.knots) * (self.tau**2).sum(axis=1)))


def joint_trajectory(plan: JointPlan) -> Trajectory:
    """Sample a collocation plan: its polynomials ``REFINE`` times per interval.

    The CP derivatives 0..2 and xi = (xddot, yddot) . (cos theta, sin theta) follow from the
    joint state and the accelerations the torques produce; the CP's third and fourth
    derivatives, eta and alpha are not defined under piecewise-constant torques (NaN). The
    passive joint's torque is zero by construction; the transcription error shows instead in
    the open-loop replay (:func:`replay`).
    """
    f = plan.fine
    return _joint_samples(plan, f["t"], f["q"], f["qd"], f["tau"])


def joint_sample_at(plan: JointPlan, t) -> Trajectory:
    """A collocation plan at any times in its interval (as :func:`joint_trajectory` samples it).

    Between the samples of the collocation polynomials (``REFINE`` per control interval), q is
    the cubic Hermite interpolant of q and qd, and qd that of qd and the accelerations the
    interval's torque gives; at the samples both are the polynomials' values. The torque is
    the piecewise-constant one (right-continuous, :meth:`JointPlan.torque_at`).

    Parameters
    ----------
    plan : JointPlan
        The plan.
    t : float or array_like
        Times [s] within the plan, in any order.

    Raises
    ------
    ValueError
        For times that are not numbers, or lie outside the plan (:func:`checked_times`).
    """
    f = plan.fine
    tf = f["t"]
    t = checked_times(t, tf[0], tf[-1])
    # the segment [tf[i], tf[i + 1]] holding each time (a repeated time is skipped)
    i = np.clip(np.searchsorted(tf, t, side="right") - 1, 0, tf.size - 2)
    i = np.where(tf[i + 1] > tf[i], i, np.maximum(i - 1, 0))
    forward = mapped(arm_dynamics(plan.arm)["forward"], 2 * i.size)
    tau = f["tau"][i]  # the torque on the segment, at both its ends
    ends_q = np.concatenate([f["q"][i], f["q"][i + 1]])
    ends_qd = np.concatenate([f["qd"][i], f["qd"][i + 1]])
    qdd = np.asarray(forward(ends_q.T, ends_qd.T, np.concatenate([tau, tau]).T)).T
    h = (tf[i + 1] - tf[i])[:, None]
    s = (t[:, None] - tf[i][:, None]) / h
    q = _hermite(s, h, f["q"][i], f["qd"][i], f["q"][i + 1], f["qd"][i + 1])
    qd = _hermite(s, h, f["qd"][i], qdd[: i.size], f["qd"][i + 1], qdd[i.size :])
    torque = np.array([plan.torque_at(ti) for ti in t]).reshape(-1, 2)
    return _joint_samples(plan, t, q, qd, torque)


def _hermite(s, h, y0, dy0, y1, dy1):
    """The cubic Hermite interpolant at normalised times s (N, 1) of segments of lengths h."""
    h00 = 2 * s**3 - 3 * s**2 + 1
    h10 = s**3 - 2 * s**2 + s
    h01 = -2 * s**3 + 3 * s**2
    h11 = s**3 - s**2
    return h00 * y0 + h10 * h * dy0 + h01 * y1 + h11 * h * dy1


def _joint_samples(plan: JointPlan, t, q, qd, tau) -> Trajectory:
    """The trajectory of joint states and torques at times t (see :func:`joint_trajectory`)."""
    n = t.size
    step = mapped(joint_functions(plan.arm), n)
    qdd, gamma, s, sdot, sddot = (np.asarray(v).T for v in step(q.T, qd.T, tau.T))
    K = plan.arm.K
    theta, w = s[:, 2], sdot[:, 2]
    along = np.column_stack([np.cos(theta), np.sin(theta)])
    normal = np.column_stack([-np.sin(theta), np.cos(theta)])
    cp = np.full((n, 2, 5), np.nan)
    cp[:, :, 0] = s[:, :2] + K * along
    cp[:, :, 1] = sdot[:, :2] + K * w[:, None] * normal
    cp[:, :, 2] = sddot[:, :2] + K * (sddot[:, 2:3] * normal - (w**2)[:, None] * along)
    xi = (sddot[:, :2] * along).sum(axis=1)
    z = np.column_stack([s, sdot, xi, np.full(n, np.nan)])
    node_times = [node.t for node in plan.nodes]
    return Trajectory(
        t=t,
        phase=np.clip(np.searchsorted(node_times, t, side="right") - 1, 0, len(node_times) - 2),
        cp=cp,
        z=z,
        alpha=np.full((n, 2), np.nan),
        accel=sddot,
        q=q,
        qd=qd,
        qdd=qdd,
        tau=tau,
        residual=np.zeros(n),
        gamma=gamma.ravel(),
    )


def joint_metrics(plan: JointPlan, traj: Trajectory) -> Metrics:
    """:class:`Metrics` of a collocation plan: exact torque integral, the rest on the samples.

    ``min_abs_gamma`` is the smallest |gamma| on the samples (not certified between them), and
    0 where gamma changes sign between two samples (``gamma_sign_changes``: the crossings);
    ``torque_jumps`` are the largest step at a knot (``knots``) and, at a rest start or goal,
    the step from or to the holding torque.
    """
    tau = traj.tau
    power = np.abs(tau[:, 0] * traj.qd[:, 0]) + np.abs(tau[:, 1] * traj.qd[:, 1])
    i = int(np.argmin(np.abs(traj.gamma)))
    # gamma through zero between two samples: |gamma| = 0 there, not the samples' smallest
    crossings = gamma_crossings(traj.t, traj.gamma)
    jumps = [("knots", float(np.abs(np.diff(plan.tau, axis=0)).max(initial=0.0)))]
    problem_nodes = (plan.nodes[0], plan.nodes[-1])
    for node, k, name in ((problem_nodes[0], 0, "start"), (problem_nodes[1], -1, "goal")):
        if node.at_rest:
            hold = holding_torque(plan.arm, plan.q[k])
            jumps.append((name, float(np.abs(plan.tau[k] - hold).max())))
    theta_deg = np.degrees(traj.z[:, 2])
    return Metrics(
        torque_sq_integral=plan.torque_sq_integral(),
        abs_power_integral=float(np.trapezoid(power, traj.t)),
        peak_torque=(float(np.abs(tau[:, 0]).max()), float(np.abs(tau[:, 1]).max())),
        min_abs_gamma=0.0 if crossings else float(np.abs(traj.gamma[i])),
        min_abs_gamma_time=crossings[0] if crossings else float(traj.t[i]),
        theta_min_deg=float(theta_deg.min()),
        theta_max_deg=float(theta_deg.max()),
        max_torque_jump=max(j[1] for j in jumps),
        max_passive_residual=0.0,
        torque_jumps=tuple(jumps),
        gamma_sign_changes=crossings,
    )


@dataclass(frozen=True)
class ReplayCheck:
    """Verification of a collocation plan: its torques replayed open loop on the full arm.

    Attributes
    ----------
    open_loop : SimulationResult
        The replay; its ``cp_error`` is against the plan's own CP, its ``final_state_error``
        against the problem's goal [m, rad, m/s, rad/s].
    tolerance : float
        Largest final-state error accepted (``collocation.replay_tolerance``).
    """

    open_loop: SimulationResult
    tolerance: float

    @property
    def max_cp_error(self) -> float:
        """Largest CP deviation of the replay from the plan [m]."""
        return self.open_loop.max_cp_error

    @property
    def final_state_error(self) -> float:
        """Final-state error of the replay against the goal."""
        return self.open_loop.final_state_error

    def passed(self) -> bool:
        """True when the replay ends within ``tolerance`` of the goal."""
        return self.final_state_error <= self.tolerance

    def summary(self) -> dict:
        """The figures written to ``solution.json``."""
        return {
            "max_cp_error": self.max_cp_error,
            "final_state_error": self.final_state_error,
            "passive_torque_residual": 0.0,
            "method": "open-loop replay of the piecewise-constant torques on the full dynamics",
            "replay_tolerance": self.tolerance,
        }


def replay(plan: JointPlan, goal: Node, tolerance: float = 1e-3) -> ReplayCheck:
    """Integrate the full dynamics under the plan's torques, interval by interval (DOP853).

    Parameters
    ----------
    plan : JointPlan
        The plan.
    goal : Node
        The goal the replay should end at.
    tolerance : float
        Final-state error accepted.
    """

    forward = arm_dynamics(plan.arm)["forward"]
    f = plan.fine
    X = np.concatenate([plan.q[0], plan.qd[0]])
    states, times = [], []
    for k in range(len(plan.tau)):
        t0, t1 = plan.knots[k], plan.knots[k + 1]
        sel = (f["t"] >= t0) & (f["t"] <= t1)
        t_eval = np.clip(np.unique(f["t"][sel]), t0, t1)
        tau = plan.tau[k]

        def rhs(_t, x, tau=tau):
            return np.concatenate([x[3:], np.asarray(forward(x[:3], x[3:], tau)).ravel()])

        t, Xs = integrate(rhs, X, t0, t1, t_eval, rtol=1e-10, atol=1e-10)  # bounded
        X = Xs[-1]
        times.append(t)
        states.append(Xs)
    t = np.concatenate(times)
    state = pose_states(plan.arm, np.concatenate(states))
    K = plan.arm.K
    keep = np.r_[np.diff(f["t"]) > 0, True]
    planned = cp_of(K, pose_states(plan.arm, np.column_stack([f["q"], f["qd"]])[keep]))
    cp_ref = np.column_stack([np.interp(t, f["t"][keep], planned[:, i]) for i in range(2)])
    err = np.linalg.norm(cp_of(K, state) - cp_ref, axis=1)
    result = SimulationResult(
        "open_loop", t, state, err, float(err.max()), goal_error(goal, state[-1])
    )
    return ReplayCheck(result, tolerance)
