"""A plan sampled into the arm's motion and torques, and its metrics."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..io.safe_yaml import echo
from ..model import flat
from ..model.dynamics import holding_torque, inverse_dynamics
from ..model.kinematics import ReachError, inverse_derivatives, inverse_position
from .nodes import node_names
from .plan import CPPlan


@dataclass(frozen=True)
class Trajectory:
    """Samples of a plan. At a phase join the time appears twice (left and right limits).

    Attributes
    ----------
    t : (N,) times [s]
    phase : (N,) index of the phase of each sample
    cp : (N, 2, 5) CP and its derivatives 0..4 [m/s^k]
    z : (N, 8) third-link state and compensator (x, y, theta, xdot, ydot, thetadot, xi, eta)
    alpha : (N, 2) compensator inputs (alpha1 [m/s^4], alpha2 [m/s^2])
    accel : (N, 3) (xddot, yddot, thetaddot) [m/s^2, rad/s^2]
    q, qd, qdd : (N, 3) joint positions, velocities, accelerations (SI; rad for revolute)
    tau : (N, 2) actuated joint torques/forces [N m or N]
    residual : (N,) the passive joint's torque residual [N m] (zero for an exact plan)
    gamma : (N,) the regularity quantity gamma [m/s^2]
    """

    t: np.ndarray
    phase: np.ndarray
    cp: np.ndarray
    z: np.ndarray
    alpha: np.ndarray
    accel: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    residual: np.ndarray
    gamma: np.ndarray


def sample(plan: CPPlan, per_phase: int = 401) -> Trajectory:
    """Sample a plan into third-link states, joint motion and torques.

    Parameters
    ----------
    plan : CPPlan
        The plan.
    per_phase : int
        Samples per phase, both ends included.

    Returns
    -------
    Trajectory

    Raises
    ------
    cpopt.model.kinematics.ReachError
        If a sample is out of the arm's reach.
    """
    t = np.concatenate([np.linspace(ph.curve.t0, ph.curve.t1, per_phase) for ph in plan.phases])
    phase = np.repeat(np.arange(len(plan.phases)), per_phase)
    cp, z = flat_states(plan, t, phase)
    z[:, 2] = np.unwrap(z[:, 2])
    # Start the angle on the branch of the start node (theta and theta + 2 pi are one pose).
    z[:, 2] += 2 * np.pi * np.round((plan.nodes[0].theta - z[0, 2]) / (2 * np.pi))
    return _completed(plan, t, phase, cp, z)


def reachable(plan: CPPlan, per_phase: int = 401) -> Trajectory | None:
    """The plan sampled (:func:`sample`, ``per_phase`` samples a phase) when its joint motion
    exists at every point, else None: a plan solved on a grid may leave the arm's reach
    between the grid's points, and a plan handed back as solved must be one the caller can
    sample (and re-plan from)."""
    try:
        return sample(plan, per_phase)
    except ReachError:
        return None


def checked_times(t, start: float, end: float) -> np.ndarray:
    """Times to sample a plan at, as a 1-D float array: finite and within ``[start, end]`` s.

    Raises
    ------
    ValueError
        Naming ``t``, what was given and what was expected: not numbers, no times, more
        than one dimension, a non-finite time or one outside the plan.
    """
    expected = f"expected a time or a 1-D array of times in [{start:g}, {end:g}] s"
    try:
        given = np.asarray(t)
        times = given.astype(float)
    except (TypeError, ValueError):
        raise ValueError(f"t: {expected}, got {echo(t)}") from None
    if given.dtype.kind not in "iuf":  # booleans, strings of digits, objects
        raise ValueError(f"t: {expected}, got {echo(t)}")
    if times.ndim > 1:
        raise ValueError(f"t: {expected}, got an array of shape {times.shape}")
    times = np.atleast_1d(times)
    if not times.size:
        raise ValueError(f"t: {expected}, got no times")
    if not np.all(np.isfinite(times)):
        raise ValueError(f"t: {expected}, got a non-finite time")
    if not (np.all(times >= start - 1e-12) and np.all(times <= end + 1e-12)):
        raise ValueError(f"t: times must lie within the plan, [{start:g}, {end:g}] s")
    return times


def sample_at(plan: CPPlan, t, along: Trajectory) -> Trajectory:
    """A plan at any times in its interval, on the angle branches of a sampled trajectory.

    Parameters
    ----------
    plan : CPPlan
        The plan.
    t : float or array_like
        Times [s] within [t0, t0 + duration], in any order. At a join of two phases the
        sample is the later phase's (the right limit), at the end the last phase's.
    along : Trajectory
        The plan sampled densely (:func:`sample`): theta and the revolute joint angles are
        taken on the turn (multiple of 2 pi) nearest to it, as a continuous motion has them.

    Returns
    -------
    Trajectory
        One sample per time, in the order given.

    Raises
    ------
    ValueError
        For times that are not numbers, or lie outside the plan (:func:`checked_times`).
    """
    t = checked_times(t, plan.t0, plan.t0 + plan.duration)
    starts = np.array([ph.curve.t0 for ph in plan.phases])
    phase = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(plan.phases) - 1)
    cp, z = flat_states(plan, t, phase)
    z[:, 2] = nearest_turn(z[:, 2], np.interp(t, along.t, along.z[:, 2]))
    reference = np.column_stack([np.interp(t, along.t, along.q[:, j]) for j in range(3)])
    return _completed(plan, t, phase, cp, z, reference)


def nearest_turn(angle: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``angle`` [rad] moved by whole turns (2 pi) to lie nearest to ``reference``."""
    return angle + 2 * np.pi * np.round((reference - angle) / (2 * np.pi))


def flat_states(plan: CPPlan, t: np.ndarray, phase: np.ndarray):
    """CP derivatives (N, 2, 5) and third-link states (N, 8) at times t [s], each on the curve
    of the given phase (theta as the flat map gives it, not yet on a continuous branch)."""
    arm = plan.arm
    cp = np.empty((t.size, 2, 5))
    z = np.empty((t.size, 8))
    for i, ph in enumerate(plan.phases):
        sel = phase == i
        if sel.any():
            cp[sel] = ph.curve.derivatives(t[sel], 4)
            z[sel] = flat.inverse(cp[sel][:, :, :4], ph.sigma, arm.K, arm.gravity)
    return cp, z


def _completed(plan: CPPlan, t, phase, cp, z, reference=None) -> Trajectory:
    """The trajectory of CP derivatives and third-link states: compensator, joints, torques
    (revolute joint angles nearest to ``reference`` (N, 3) when given)."""
    arm = plan.arm
    alpha, zdot, _ = flat.compensate(z, cp[:, :, 4], arm.K, arm.gravity)
    accel = zdot[:, 3:6]
    q = inverse_position(arm, z[:, 0], z[:, 1], z[:, 2], t)
    if reference is not None:
        for j in np.flatnonzero(arm.revolute):
            q[:, j] = nearest_turn(q[:, j], reference[:, j])
    qd, qdd = inverse_derivatives(arm, q, z[:, 3:6], accel)
    torques = inverse_dynamics(arm, q, qd, qdd)
    return Trajectory(
        t=t,
        phase=phase,
        cp=cp,
        z=z,
        alpha=alpha,
        accel=accel,
        q=q,
        qd=qd,
        qdd=qdd,
        tau=torques[:, :2],
        residual=torques[:, 2],
        gamma=flat.gamma(z, arm.K, arm.gravity),
    )


@dataclass(frozen=True)
class Metrics:
    """Figures of merit of a sampled plan (SI units).

    Attributes
    ----------
    torque_sq_integral : integral of tau1^2 + tau2^2 dt [N^2 m^2 s]
    abs_power_integral : integral of |tau1 q1dot| + |tau2 q2dot| dt [J]
    peak_torque : (max |tau1|, max |tau2|) [N m or N]
    min_abs_gamma : certified minimum of |gamma| over the plan [m/s^2]
    min_abs_gamma_time : where it occurs [s]
    theta_min_deg, theta_max_deg : range of the third link's angle [deg]
    max_torque_jump : largest torque step at a phase join, or at a rest start/end against
        the static holding torque of that rest state [N m or N]
    max_passive_residual : largest |passive joint torque| along the samples [N m]
    torque_jumps : ((where, size), ...) each torque step: ``via[i]`` and ``switch[j]`` joins,
        ``start`` and ``goal`` rest ends [N m or N]
    reset_torque_jump : largest torque step at a via state that resets xi (0 without one)
        [N m or N]
    gamma_sign_changes : times where gamma changes sign [s]: a flat plan's switches (a xi
        reset steps gamma across zero, never through it), a collocation plan's crossings
        through zero, read between its knots (its ``min_abs_gamma`` is then 0)
    torque_limit : (limit of tau1 or None, limit of tau2 or None): the motors' full torque
        limits (``optimizer.limits.torque``) [N m or N]
    torque_headroom : (h1, h2) the fractions of those limits the plan was asked to leave to
        feedback (``optimizer.limits.torque_headroom``); the plan keeps |tau_i| <= (1 - h_i)
        times the limit
    """

    torque_sq_integral: float
    abs_power_integral: float
    peak_torque: tuple[float, float]
    min_abs_gamma: float
    min_abs_gamma_time: float
    theta_min_deg: float
    theta_max_deg: float
    max_torque_jump: float
    max_passive_residual: float
    torque_jumps: tuple = ()
    reset_torque_jump: float = 0.0
    gamma_sign_changes: tuple[float, ...] = ()
    torque_limit: tuple = (None, None)
    torque_headroom: tuple[float, float] = (0.0, 0.0)

    @property
    def torque_usage(self) -> tuple:
        """Peak |tau_i| as a fraction of the motor's limit (None without a limit): 1 - usage
        is the headroom the plan actually leaves."""
        return tuple(
            None if lim is None else peak / lim
            for peak, lim in zip(self.peak_torque, self.torque_limit, strict=True)
        )

    def as_dict(self) -> dict:
        """The metrics as a plain dict (JSON-ready)."""
        return {
            "torque_sq_integral": self.torque_sq_integral,
            "abs_power_integral": self.abs_power_integral,
            "peak_torque": list(self.peak_torque),
            "min_abs_gamma": self.min_abs_gamma,
            "theta_min_deg": self.theta_min_deg,
            "theta_max_deg": self.theta_max_deg,
            "max_torque_jump": self.max_torque_jump,
            "reset_torque_jump": self.reset_torque_jump,
            "torque_jumps": dict(self.torque_jumps),
            "gamma_sign_changes": list(self.gamma_sign_changes),
            "torque_limit": list(self.torque_limit),
            "torque_headroom": list(self.torque_headroom),
            "torque_usage": list(self.torque_usage),
        }


def torque_jumps(plan: CPPlan, traj: Trajectory) -> list[tuple[str, float, float]]:
    """Torque steps (where, time [s], size [N m]) at joins and at rest ends.

    At a phase join (named as in :func:`cpopt.closedform.nodes.node_names`: ``via[i]``,
    ``switch[j]``) the step is ``max_i |tau_i(t+) - tau_i(t-)|``; at a start or goal at rest it is
    the step from (to) the static torque that holds the arm in that state.
    """
    jumps = []
    names = node_names(len(plan.nodes), plan.switches)
    for k in range(1, len(plan.phases)):
        left = np.flatnonzero(traj.phase == k - 1)[-1]
        right = np.flatnonzero(traj.phase == k)[0]
        step = float(np.abs(traj.tau[right] - traj.tau[left]).max())
        jumps.append((names[k], float(traj.t[left]), step))
    for node, idx, name in ((plan.nodes[0], 0, "start"), (plan.nodes[-1], -1, "goal")):
        if node.at_rest:
            hold = holding_torque(plan.arm, traj.q[idx])
            jumps.append((name, float(traj.t[idx]), float(np.abs(traj.tau[idx] - hold).max())))
    return jumps


def metrics(plan: CPPlan, traj: Trajectory) -> Metrics:
    """Compute :class:`Metrics` of a sampled plan (trapezoidal integrals on the samples)."""
    tau = traj.tau
    power = np.abs(tau[:, 0] * traj.qd[:, 0]) + np.abs(tau[:, 1] * traj.qd[:, 1])
    gmin, gmin_t = plan.min_abs_gamma()
    jumps = torque_jumps(plan, traj)
    names = node_names(len(plan.nodes), plan.switches)
    resets = {name for name, node in zip(names, plan.nodes, strict=True) if node.resets_xi}
    theta_deg = np.degrees(traj.z[:, 2])
    return Metrics(
        torque_sq_integral=float(np.trapezoid((tau**2).sum(axis=1), traj.t)),
        abs_power_integral=float(np.trapezoid(power, traj.t)),
        peak_torque=(float(np.abs(tau[:, 0]).max()), float(np.abs(tau[:, 1]).max())),
        min_abs_gamma=gmin,
        min_abs_gamma_time=gmin_t,
        theta_min_deg=float(theta_deg.min()),
        theta_max_deg=float(theta_deg.max()),
        max_torque_jump=max((j[2] for j in jumps), default=0.0),
        max_passive_residual=float(np.abs(traj.residual).max()),
        torque_jumps=tuple((where, size) for where, _, size in jumps),
        reset_torque_jump=max((j[2] for j in jumps if j[0] in resets), default=0.0),
        gamma_sign_changes=tuple(
            float(plan.nodes[k].t)
            for k in range(1, len(plan.phases))
            if plan.phases[k].sigma != plan.phases[k - 1].sigma
        ),
    )


def gamma_crossings(t: np.ndarray, gamma: np.ndarray) -> tuple[float, ...]:
    """Every time [s] a sampled gamma changes sign, interpolated linearly between samples."""
    out = []
    for i in np.nonzero(np.sign(gamma[:-1]) * np.sign(gamma[1:]) < 0)[0]:
        g0, g1 = gamma[i], gamma[i + 1]
        out.append(float(t[i] + (t[i + 1] - t[i]) * g0 / (g0 - g1)))
    return tuple(out)
