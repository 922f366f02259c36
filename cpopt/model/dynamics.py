"""The arm's Lagrangian dynamics, derived symbolically once per arm.

``B(q) qdd + c(q, qd) + g(q) = (tau1, tau2, 0)``: joint coordinates q as in
:mod:`cpopt.model.robot`, the generalised forces of the first two (actuated) joints are their
torques or forces, and the third joint is passive. Everything is a CasADi ``Function`` built
from the kinetic and potential energy of :func:`cpopt.model.kinematics.link_geometry`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from .kinematics import link_geometry
from .mapping import mapped
from .robot import Arm


@dataclass(frozen=True)
class SymbolicLink:
    """A link whose values are CasADi symbols: the fields of :class:`cpopt.model.robot.Link` that
    :func:`lagrangian` reads (length [m], mass [kg], centre of mass d [m], inertia I [kg m^2])."""

    length: ca.SX
    mass: ca.SX
    d: ca.SX
    I: ca.SX  # noqa: E741 - the paper's symbol


def lagrangian(arm, q, qd) -> tuple[ca.SX, ...]:
    """B(q), n(q, qd) = c + g, g(q), kinetic and potential energy of an arm (SX expressions).

    Parameters
    ----------
    arm : Arm or an object with the same fields
        ``kind``, ``base``, ``gravity`` and ``links`` with ``length``, ``d``, ``mass`` and
        ``I``; the link values may be CasADi symbols (a plant whose parameters are inputs).
    q, qd : casadi.SX
        Joint positions and velocities (3 x 1).
    """
    geo = link_geometry(arm, q)
    kinetic = 0
    potential = 0
    for link, com, angle in zip(arm.links, geo.com, geo.angle, strict=True):
        v = ca.jtimes(com, q, qd)
        w = ca.jtimes(angle, q, qd) if isinstance(angle, ca.SX) else 0
        kinetic += 0.5 * link.mass * ca.dot(v, v) + 0.5 * link.I * w**2
        potential += link.mass * arm.gravity * com[1]
    B = ca.simplify(ca.hessian(kinetic, qd)[0])
    dT_dqd = ca.gradient(kinetic, qd)
    c = ca.jtimes(dT_dqd, q, qd) - ca.gradient(kinetic, q)
    g = ca.gradient(potential, q)
    return B, c + g, g, kinetic, potential


ACTUATION = ca.vertcat(ca.SX.eye(2), ca.SX.zeros(1, 2))
"""Which joints the two torques act on: the first two (the third is passive)."""


def _forward(B: ca.SX, n: ca.SX, tau: ca.SX) -> ca.SX:
    return ca.solve(B, ACTUATION @ tau - n)


def _tracking(arm, q: ca.SX, qd: ca.SX, B: ca.SX, n: ca.SX, a: ca.SX) -> ca.SX:
    # Unknowns (qdd, tau): B qdd + n = [I; 0] tau and J_w qdd + dJ_w/dt qd = a.
    Jw = ca.jacobian(link_geometry(arm, q).wrist, q)
    jdot_qd = ca.jtimes(Jw @ qd, q, qd)
    M = ca.blockcat([[B, -ACTUATION], [Jw, ca.SX.zeros(2, 2)]])
    return ca.solve(M, ca.vertcat(-n, a - jdot_qd))


def forward_acceleration(arm, q: ca.SX, qd: ca.SX, tau) -> ca.SX:
    """Joint accelerations (3) under the actuated torques tau = (tau1, tau2), the passive joint
    free (an expression; q and qd symbols, the arm numeric or parametric as in
    :func:`lagrangian`)."""
    B, n, *_ = lagrangian(arm, q, qd)
    return _forward(B, n, tau)


def tracking_acceleration(arm, q: ca.SX, qd: ca.SX, a) -> tuple[ca.SX, ca.SX]:
    """The joint accelerations (3) and actuated torques (2) that give the third link's base the
    Cartesian acceleration ``a`` while the passive joint stays torque-free (expressions; q and
    qd symbols, the arm numeric or parametric)."""
    B, n, *_ = lagrangian(arm, q, qd)
    sol = _tracking(arm, q, qd, B, n, a)
    return sol[:3], sol[3:]


@lru_cache(maxsize=32)
def arm_dynamics(arm: Arm) -> dict[str, ca.Function]:
    """Dynamics functions of an arm (built once per arm and cached).

    Returns
    -------
    dict of casadi.Function
        ``B(q)`` inertia matrix (3 x 3); ``n(q, qd)`` = c + g, the velocity and gravity terms;
        ``g(q)`` gravity terms; ``inverse(q, qd, qdd) -> (tau1, tau2, residual)`` with the
        passive joint's residual torque [N m] third; ``forward(q, qd, tau) -> qdd`` with
        tau = (tau1, tau2) and the passive joint free; ``track(q, qd, a) -> (qdd, tau)``, the
        joint accelerations and actuated torques that give the third link's base the Cartesian
        acceleration ``a`` while the passive joint stays torque-free (the static feedback of
        the paper's section 2.1, for any arm kind); ``energy(q, qd) -> (T, V)`` [J].
    """
    q = ca.SX.sym("q", 3)
    qd = ca.SX.sym("qd", 3)
    qdd = ca.SX.sym("qdd", 3)
    tau = ca.SX.sym("tau", 2)
    a = ca.SX.sym("a", 2)
    B, n, g, kinetic, potential = lagrangian(arm, q, qd)
    generalized = B @ qdd + n
    qdd_forward = _forward(B, n, tau)
    sol = _tracking(arm, q, qd, B, n, a)
    return {
        "B": ca.Function("B", [q], [B]),
        "n": ca.Function("n", [q, qd], [n]),
        "g": ca.Function("g", [q], [g]),
        "inverse": ca.Function("inverse", [q, qd, qdd], [generalized]),
        "forward": ca.Function("forward", [q, qd, tau], [qdd_forward]),
        "track": ca.Function("track", [q, qd, a], [sol[:3], sol[3:]]),
        "energy": ca.Function("energy", [q, qd], [kinetic, potential]),
    }


def inverse_dynamics(arm: Arm, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """Joint torques along samples.

    Parameters
    ----------
    arm : Arm
        The arm.
    q, qd, qdd : numpy.ndarray
        Joint positions, velocities and accelerations, shape (N, 3).

    Returns
    -------
    numpy.ndarray
        (N, 3): tau1, tau2 [N m or N] and the passive joint's residual torque [N m], which is
        zero for a dynamically feasible motion.
    """
    f = mapped(arm_dynamics(arm)["inverse"], q.shape[0])
    return np.asarray(f(q.T, qd.T, qdd.T)).T


def holding_torque(arm: Arm, q: np.ndarray) -> np.ndarray:
    """Static torques (tau1, tau2) [N m or N] that hold the arm at rest at q (3,)."""
    return np.asarray(arm_dynamics(arm)["g"](q)).ravel()[:2]


@lru_cache(maxsize=32)
def state_derivative(arm: Arm) -> ca.Function:
    """``(x, tau) -> xdot``: the full dynamics in first-order form, x = (q, qd), the passive
    joint free under the actuated torques tau (2,)."""
    x = ca.SX.sym("x", 6)
    tau = ca.SX.sym("tau", 2)
    qdd = arm_dynamics(arm)["forward"](x[:3], x[3:], tau)
    return ca.Function("state_derivative", [x, tau], [ca.vertcat(x[3:], qdd)])


@lru_cache(maxsize=32)
def rk4_step(arm: Arm, substeps: int = 8) -> ca.Function:
    """``(x, tau, h) -> (x_next, states)``: the joint state x = (q, qd) after h [s] under the
    constant torque tau (RK4, ``substeps`` steps), and the states at the start of each step
    (6 x substeps)."""
    x = ca.SX.sym("x", 6)
    tau = ca.SX.sym("tau", 2)
    h = ca.SX.sym("h")
    derivative = state_derivative(arm)

    def f(y):
        return derivative(y, tau)

    dt, y, states = h / substeps, x, []
    for _ in range(substeps):
        states.append(y)
        k1 = f(y)
        k2 = f(y + dt / 2 * k1)
        k3 = f(y + dt / 2 * k2)
        k4 = f(y + dt * k3)
        y = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("rk4_step", [x, tau, h], [y, ca.horzcat(*states)])
