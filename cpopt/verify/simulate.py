"""Verification by simulation: the reduced model, the arm's full dynamics in closed loop, and
open-loop torque replay.

* ``reduced``: model (3) with the dynamic compensator driven by the plan's v(t) = p''''(t).
* ``closed_loop``: the arm's full Lagrangian dynamics driven by the dynamic feedback
  linearisation (compensator + the static feedback that makes the third link's base accelerate
  as asked, for any arm kind) with a linear stabilising law on the two chains of four
  integrators, ``v = p_d'''' + sum_k k_k (p_d^(k) - p^(k))``, gains by pole placement.
* ``open_loop``: the plan's nominal torques applied to the full dynamics, no feedback.

The reduced model and the closed loop reset the compensator (xi and eta) at via states as the
plan does; in the open-loop replay a xi reset shows as the step of the torques there.

The controller may use a nominal arm while the simulated plant is another (model errors).

Each simulation steps along the plan's pieces with an extrapolated midpoint step
(:mod:`cpopt.verify.extrapolation`) compiled once per arm kind and curve degree, the arms'
parameters its inputs (:mod:`cpopt.verify.verify_steps`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from ..closedform.plan import CPPlan, Node
from ..flatopt.samples import arm_vector
from ..model import flat
from ..model.dynamics import arm_dynamics, inverse_dynamics
from ..model.kinematics import (
    inverse_derivatives,
    inverse_position,
    joint_state,
    kinematic_functions,
)
from ..model.mapping import mapped
from ..model.robot import Arm
from ..runtime import progress
from ..tracking.dfl import DEFAULT_POLES, dfl_law, pole_placement_gains
from .extrapolation import integrate_along
from .integrate import STEPS_PER_SECOND, DivergenceError
from .verify_steps import step_function


@dataclass(frozen=True)
class SimulationResult:
    """Outcome of one simulation.

    Attributes
    ----------
    mode : str
        ``reduced``, ``closed_loop`` or ``open_loop``.
    t : numpy.ndarray
        Output times [s].
    state : numpy.ndarray
        Simulated third-link state (N, 6): x, y, theta, xdot, ydot, thetadot.
    cp_error : numpy.ndarray
        |p(t) - p_d(t)| along the output times [m].
    max_cp_error : float
        Largest CP error [m].
    final_state_error : float
        Largest absolute error of (x, y, theta, xdot, ydot, thetadot) at the end against the
        goal (theta modulo 2 pi) [m, rad, m/s, rad/s].
    tau : numpy.ndarray or None
        Applied torques (N, 2), where the mode computes them.
    """

    mode: str
    t: np.ndarray
    state: np.ndarray
    cp_error: np.ndarray
    max_cp_error: float
    final_state_error: float
    tau: np.ndarray | None = None


def goal_error(goal: Node, state: np.ndarray) -> float:
    """Largest |error| of a third-link state (6,) against a goal node (theta modulo 2 pi)."""
    err = state - goal.state()[:6]
    err[2] = (err[2] + np.pi) % (2 * np.pi) - np.pi
    return float(np.abs(err).max())


def cp_of(K: float, s: np.ndarray) -> np.ndarray:
    """CP positions (N, 2) [m] of third-link poses s (N, >= 3)."""
    return s[:, :2] + K * np.column_stack([np.cos(s[:, 2]), np.sin(s[:, 2])])


def _result(plan, mode, t, states, tau=None) -> SimulationResult:
    ref = np.concatenate(
        [ph.curve.derivatives(tt, 0)[:, :, 0] for ph, tt in zip(plan.phases, t, strict=True)]
    )
    t = np.concatenate(t)
    states = np.concatenate(states)
    err = np.linalg.norm(cp_of(plan.arm.K, states) - ref, axis=1)
    return SimulationResult(
        mode=mode,
        t=t,
        state=states,
        cp_error=err,
        max_cp_error=float(err.max()),
        final_state_error=goal_error(plan.nodes[-1], states[-1]),
        tau=None if tau is None else np.concatenate(tau),
    )


def simulate_reduced(
    plan: CPPlan, samples: int = 201, rtol: float = 1e-11, atol: float = 1e-11
) -> SimulationResult:
    """Reduced model (3) + compensator driven open-loop by the plan's v(t) = p''''(t), each
    phase from the plan's state at its first node (after the node's planned resets).

    Each phase starts from the plan's node, not from where the previous phase's integration
    ended: open loop, a phase where the passive link is unstable amplifies the integration
    error exponentially, and carried over several phases it grows past any tolerance without
    a fault in the plan (a random PRR transfer with six switches, closed-loop CP error 1e-11 m:
    the reduced model's error carried over grew about twenty-fold a phase, 7.6e-7 m at 0.90 s,
    1.8e-4 m at 1.26 s). Every phase's end still meets the next node's state (the
    ``final_state_error`` of the last), and the closed loop runs the whole motion in one go.
    """
    K, g0 = plan.arm.K, plan.arm.gravity
    ts, states = [], []
    for k, ph in enumerate(plan.phases):
        z = plan.nodes[k].state(after=True)
        step = step_function("reduced", plan.arm.kind, ph.curve.coeffs.shape[1] - 1)
        t, zs = integrate_along(step, ph.curve, z, samples, rtol, atol, ([K, g0],))
        ts.append(t)
        states.append(zs[:, :6])
    return _result(plan, "reduced", ts, states)


@lru_cache(maxsize=16)
def _closed_loop_function(model: Arm, plant: Arm) -> ca.Function:
    """X' and tau for X = (q, qd, xi, eta), reference Pd (2 x 5) and gains (4,)."""
    X = ca.SX.sym("X", 8)
    Pd = ca.SX.sym("Pd", 2, 5)
    gains = ca.SX.sym("k", 4)
    q, qd = X[0:3], X[3:6]
    tau, c_dot = dfl_law(model)(q, qd, X[6:8], Pd, gains)
    qdd = arm_dynamics(plant)["forward"](q, qd, tau)
    Xdot = ca.vertcat(qd, qdd, c_dot)
    return ca.Function("closed_loop", [X, Pd, gains], [Xdot, tau])


def pose_states(arm: Arm, X: np.ndarray) -> np.ndarray:
    """Third-link states (N, 6): pose and velocity of joint states X (N, >= 6)."""
    kin = kinematic_functions(arm)
    n = X.shape[0]
    s = np.asarray(mapped(kin["pose"], n)(X[:, :3].T)).T
    J = np.asarray(mapped(kin["jacobian"], n)(X[:, :3].T)).T.reshape(n, 3, 3).transpose(0, 2, 1)
    return np.column_stack([s, np.einsum("nij,nj->ni", J, X[:, 3:6])])


def _initial_joint_state(plan: CPPlan, q_error) -> tuple[np.ndarray, np.ndarray]:
    q, qd = joint_state(plan.arm, plan.nodes[0].state(after=True))
    return q + np.asarray(q_error, float), qd


def simulate_closed_loop(
    plan: CPPlan,
    poles=DEFAULT_POLES,
    plant: Arm | None = None,
    q_error=(0.0, 0.0, 0.0),
    samples: int = 201,
    rtol: float = 1e-10,
    atol: float = 1e-10,
) -> SimulationResult:
    """The arm's full dynamics under dynamic feedback linearisation and linear tracking.

    Parameters
    ----------
    plan : CPPlan
        The plan; its arm is the controller's model.
    poles : sequence of float
        Poles of each CP error chain [1/s].
    plant : Arm, optional
        The simulated arm when it differs from the model (model errors).
    q_error : sequence of float
        Initial joint position error added to the plan's start [rad or m].
    """
    model = plan.arm
    f = _closed_loop_function(model, plant or model)
    gains = pole_placement_gains(poles)
    q0, qd0 = _initial_joint_state(plan, q_error)
    z0 = plan.nodes[0].state(after=True)
    X = np.concatenate([q0, qd0, z0[6:8]])
    ts, states, taus = [], [], []
    for k, ph in enumerate(plan.phases):
        if k:
            X = X.copy()
            node = plan.nodes[k]
            # the planned resets of xi and eta: the compensator jumps, the arm's state does not
            X[6:8] += node.state(after=True)[6:8] - node.state()[6:8]

        step = step_function("closed_loop", model.kind, ph.curve.coeffs.shape[1] - 1)
        # the step size shrinks with the poles: the budget grows with them (x1 up to -10 1/s)
        rate = STEPS_PER_SECOND * max(1.0, float(np.max(np.abs(poles))) / 10)
        extra = (gains, arm_vector(model), arm_vector(plant or model))
        t, Xs = integrate_along(step, ph.curve, X, samples, rtol, atol, extra, rate)
        X = Xs[-1]
        Pd = ph.curve.derivatives(t, 4)
        tau = np.asarray(mapped(f, t.size)(Xs.T, Pd.transpose(1, 0, 2).reshape(2, -1), gains)[1]).T
        ts.append(t)
        states.append(pose_states(plant or model, Xs))
        taus.append(tau)
    return _result(plan, "closed_loop", ts, states, taus)


def plan_torque(plan: CPPlan, phase: int, t: np.ndarray) -> np.ndarray:
    """The plan's nominal torques (N, 2) at times t inside one phase, computed exactly."""
    arm = plan.arm
    K, g0 = arm.K, arm.gravity
    ph = plan.phases[phase]
    P = ph.curve.derivatives(t, 4)
    z = flat.inverse(P[:, :, :4], ph.sigma, K, g0)
    _, zdot, _ = flat.compensate(z, P[:, :, 4], K, g0)
    q = inverse_position(arm, z[:, 0], z[:, 1], z[:, 2])
    qd, qdd = inverse_derivatives(arm, q, z[:, 3:6], zdot[:, 3:6])
    return inverse_dynamics(arm, q, qd, qdd)[:, :2]


def simulate_open_loop(
    plan: CPPlan,
    plant: Arm | None = None,
    q_error=(0.0, 0.0, 0.0),
    samples: int = 201,
    rtol: float = 1e-11,
    atol: float = 1e-11,
) -> SimulationResult:
    """The plan's nominal torques replayed on the arm's full dynamics without feedback."""
    q0, qd0 = _initial_joint_state(plan, q_error)
    X = np.concatenate([q0, qd0])
    ts, states, taus = [], [], []
    for k, ph in enumerate(plan.phases):
        step = step_function("open_loop", plan.arm.kind, ph.curve.coeffs.shape[1] - 1)
        extra = (ph.sigma, arm_vector(plan.arm), arm_vector(plant or plan.arm))
        t, Xs = integrate_along(step, ph.curve, X, samples, rtol, atol, extra)
        X = Xs[-1]
        ts.append(t)
        states.append(pose_states(plant or plan.arm, Xs))
        taus.append(plan_torque(plan, k, t))
    return _result(plan, "open_loop", ts, states, taus)


@dataclass(frozen=True)
class Verification:
    """Errors of the three simulations of a plan (SI units).

    Attributes
    ----------
    reduced, closed_loop, open_loop : SimulationResult
    passive_torque_residual : float
        Largest |torque| the plan asks of the passive joint [N m].
    """

    reduced: SimulationResult
    closed_loop: SimulationResult
    open_loop: SimulationResult
    passive_torque_residual: float

    @property
    def max_cp_error(self) -> float:
        """Largest CP error of the closed-loop simulation of the full arm [m]."""
        return self.closed_loop.max_cp_error

    @property
    def final_state_error(self) -> float:
        """Final-state error of the closed-loop simulation of the full arm."""
        return self.closed_loop.final_state_error

    def passed(
        self, cp_tol: float = 1e-6, state_tol: float = 1e-5, residual_tol: float = 1e-8
    ) -> bool:
        """True when the simulations reproduce the plan.

        The full arm in closed loop must meet ``cp_tol`` [m] and ``state_tol``; the reduced
        model, driven open loop through four unstable integrators per output, gets ten and a
        hundred times more (its integration error grows like t^4).
        """
        return (
            self.closed_loop.max_cp_error <= cp_tol
            and self.closed_loop.final_state_error <= state_tol
            and self.reduced.max_cp_error <= 10 * cp_tol
            and self.reduced.final_state_error <= 100 * state_tol
            and self.passive_torque_residual <= residual_tol
        )

    def summary(self) -> dict:
        """The figures written to ``solution.json`` plus one line per simulation."""
        return {
            "max_cp_error": self.max_cp_error,
            "final_state_error": self.final_state_error,
            "passive_torque_residual": self.passive_torque_residual,
            "reduced": {
                "max_cp_error": self.reduced.max_cp_error,
                "final_state_error": self.reduced.final_state_error,
            },
            "open_loop": {
                "max_cp_error": self.open_loop.max_cp_error,
                "final_state_error": self.open_loop.final_state_error,
            },
        }


@dataclass(frozen=True)
class DivergedVerification:
    """Verification stopped: one simulation diverged (or crawled) and the rest were not run.

    Attributes
    ----------
    mode : str
        ``reduced``, ``closed_loop`` or ``open_loop``.
    t : float
        Simulated time where it stopped [s].
    reason : str
        What happened.
    passive_torque_residual : float
        Largest |torque| the plan asks of the passive joint [N m].
    """

    mode: str
    t: float
    reason: str
    passive_torque_residual: float
    max_cp_error = float("inf")
    final_state_error = float("inf")

    def passed(self, *args, **kwargs) -> bool:
        """Never: the simulation did not reach the end of the plan."""
        return False

    def message(self) -> str:
        """One line for ``solver.message``."""
        return f"the {self.mode} simulation diverged at t = {self.t:.6g} s ({self.reason})"

    def summary(self) -> dict:
        """The figures written to ``solution.json``: where and why the simulation stopped."""
        return {
            "max_cp_error": None,
            "final_state_error": None,
            "passive_torque_residual": self.passive_torque_residual,
            "diverged": {"simulation": self.mode, "t": self.t, "reason": self.reason},
        }


def verify(
    plan: CPPlan, residual: float, poles=DEFAULT_POLES
) -> Verification | DivergedVerification:
    """Run the three simulations of a plan, each bounded (:mod:`cpopt.verify.extrapolation`).

    Parameters
    ----------
    plan : CPPlan
        The plan.
    residual : float
        Largest passive-joint torque of the sampled plan [N m] (from the trajectory).
    poles : sequence of float
        Tracking poles [1/s].

    Returns
    -------
    Verification or DivergedVerification
        The latter when a simulation diverged: which one, when and why.
    """
    runs = {
        "reduced": lambda: simulate_reduced(plan),
        "closed_loop": lambda: simulate_closed_loop(plan, poles=poles),
        "open_loop": lambda: simulate_open_loop(plan),
    }
    results = {}
    for mode, run in runs.items():
        progress.stage(f"simulation: {mode.replace('_', ' ')}")
        try:
            results[mode] = run()
        except DivergenceError as err:
            return DivergedVerification(mode, err.t, err.reason, float(residual))
    return Verification(**results, passive_torque_residual=float(residual))
