"""Kinematics of the four arm kinds: joints <-> third-link pose (x, y, theta).

The geometry (centres of mass, link angles, third-link base) is written once, symbolically, in
:func:`link_geometry`; the dynamics and the forward maps are derived from it. The inverse position
map is closed-form per kind with an explicit branch; velocities and accelerations go through the
Jacobian of the symbolic forward map.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from .mapping import mapped
from .robot import Arm


class ReachError(ValueError):
    """A third-link pose the arm cannot reach, or reaches only at a kinematic singularity."""

    def __init__(self, message: str, t: float | None = None, point=None) -> None:
        where = "" if t is None else f" at t = {t:.4g} s"
        at = "" if point is None else f", point (x, y) = ({point[0]:.4g}, {point[1]:.4g}) m"
        super().__init__(f"{message}{where}{at}")
        self.t = t
        self.point = point


def _u(a):
    return ca.vertcat(ca.cos(a), ca.sin(a))


@dataclass(frozen=True)
class LinkGeometry:
    """Symbolic geometry of an arm for joint coordinates q (CasADi SX column vectors)."""

    com: tuple  # centres of mass of links 1..3, each a 2-vector
    angle: tuple  # absolute angles of links 1..3 (constants for sliding links)
    wrist: ca.SX  # the third joint, i.e. the third link's base (x, y)
    theta: ca.SX  # the third link's angle


def link_geometry(arm: Arm, q: ca.SX) -> LinkGeometry:
    """Centres of mass, link angles and the third link's base as functions of q.

    Parameters
    ----------
    arm : Arm
        The arm, or an object with its fields whose values are CasADi symbols (a parametric
        arm, :class:`cpopt.flatopt.samples.ParametricArm`).
    q : casadi.SX
        Joint coordinates (3 x 1): radians for revolute, metres for prismatic joints.
    """
    l1, l2, l3 = arm.links
    b = ca.vertcat(*arm.base)  # numbers, or symbols of a parametric arm
    q1, q2, q3 = q[0], q[1], q[2]
    ex, ey = ca.DM([1, 0]), ca.DM([0, 1])
    if arm.kind == "RRR":
        a1, a2 = q1, q1 + q2
        c1 = b + l1.d * _u(a1)
        wrist = b + l1.length * _u(a1) + l2.length * _u(a2)
        c2 = b + l1.length * _u(a1) + l2.d * _u(a2)
        theta = q1 + q2 + q3
    elif arm.kind == "RPR":
        a1 = a2 = q1
        c1 = b + l1.d * _u(a1)
        wrist = b + q2 * _u(a1)
        c2 = b + (q2 - l2.length + l2.d) * _u(a1)
        theta = q1 + q3
    elif arm.kind == "PRR":
        a1, a2 = ca.SX(0), q2
        c1 = b + (q1 - l1.length + l1.d) * ex
        wrist = b + q1 * ex + l2.length * _u(a2)
        c2 = b + q1 * ex + l2.d * _u(a2)
        theta = q2 + q3
    else:  # PPR
        a1, a2 = ca.SX(0), ca.SX(np.pi / 2)
        c1 = b + (q1 - l1.length + l1.d) * ex
        wrist = b + q1 * ex + q2 * ey
        c2 = b + q1 * ex + (q2 - l2.length + l2.d) * ey
        theta = q3
    c3 = wrist + l3.d * _u(theta)
    return LinkGeometry(com=(c1, c2, c3), angle=(a1, a2, theta), wrist=wrist, theta=theta)


@lru_cache(maxsize=32)
def kinematic_functions(arm: Arm) -> dict[str, ca.Function]:
    """CasADi functions of the forward map s = (x, y, theta) = f(q), built once per arm.

    Returns
    -------
    dict
        ``pose(q) -> s``, ``jacobian(q) -> J = ds/dq`` and ``jdot_qdot(q, qd) -> dJ/dt qd``,
        ``elbow(q)`` (all points the kinematic chain passes through, 2 x 4, for drawing).
    """
    q = ca.SX.sym("q", 3)
    qd = ca.SX.sym("qd", 3)
    geo = link_geometry(arm, q)
    s = ca.vertcat(geo.wrist, geo.theta)
    J = ca.jacobian(s, q)
    jdot_qdot = ca.jacobian(J @ qd, q) @ qd
    return {
        "pose": ca.Function("pose", [q], [s]),
        "jacobian": ca.Function("jacobian", [q], [J]),
        "jdot_qdot": ca.Function("jdot_qdot", [q, qd], [jdot_qdot]),
        "points": ca.Function("points", [q], [_chain_points(arm, q, geo)]),
    }


def _chain_points(arm: Arm, q: ca.SX, geo: LinkGeometry) -> ca.SX:
    """Base, second joint, third joint and the tip of link 3 (2 x 4), for drawing the arm."""
    b = ca.DM(arm.base)
    if arm.kind == "RRR" or arm.kind == "RPR":
        j2 = b + arm.links[0].length * _u(q[0])
    else:  # the carriage of the first slide
        j2 = b + ca.vertcat(q[0], 0)
    tip = geo.wrist + arm.links[2].length * _u(geo.theta)
    return ca.horzcat(b, j2, geo.wrist, tip)


def forward_pose(arm: Arm, q: np.ndarray) -> np.ndarray:
    """Third-link pose (x [m], y [m], theta [rad]) for joint coordinates q (3,) or (N, 3)."""
    f = kinematic_functions(arm)["pose"]
    q = np.atleast_2d(q)
    return np.asarray(mapped(f, q.shape[0])(q.T)).T.squeeze()


def inverse_position(
    arm: Arm, x: np.ndarray, y: np.ndarray, theta: np.ndarray, t: np.ndarray | None = None
) -> np.ndarray:
    """Joint coordinates for third-link poses, on the arm's branch, continuous along a motion.

    Parameters
    ----------
    arm : Arm
        The arm (its ``branch`` selects the solution).
    x, y : array_like
        Position of the third link's base [m], shape (N,).
    theta : array_like
        Third link's angle [rad], shape (N,), assumed continuous (unwrapped).
    t : array_like, optional
        Sample times [s], used only to name the time of an unreachable sample.

    Returns
    -------
    numpy.ndarray
        Joint coordinates (N, 3); revolute angles are continuous along the samples.

    Raises
    ------
    ReachError
        When a sample is out of reach or at a kinematic singularity of the branch.
    """
    x = np.atleast_1d(np.asarray(x, float)) - arm.base[0]
    y = np.atleast_1d(np.asarray(y, float)) - arm.base[1]
    theta = np.atleast_1d(np.asarray(theta, float))
    l1, l2 = arm.links[0].length, arm.links[1].length
    tol = 1e-9

    def fail(mask, why):
        i = int(np.flatnonzero(mask)[0])
        raise ReachError(
            f"{arm.kind} arm: {why}",
            None if t is None else float(np.atleast_1d(t)[i]),
            (x[i] + arm.base[0], y[i] + arm.base[1]),
        )

    if arm.kind == "RRR":
        r2 = x**2 + y**2
        c2 = (r2 - l1**2 - l2**2) / (2 * l1 * l2)
        if np.any(np.abs(c2) > 1 - tol):
            lo, hi = abs(l1 - l2), l1 + l2
            fail(
                np.abs(c2) > 1 - tol,
                f"out of reach or singular (distance from base must lie in ({lo:.4g}, {hi:.4g}) m)",
            )
        s2 = np.sqrt(1 - c2**2) * arm.branch_sign
        q2 = np.arctan2(s2, c2)
        q1 = np.arctan2(y, x) - np.arctan2(l2 * s2, l1 + l2 * c2)
        q1 = np.unwrap(q1)
        q3 = theta - q1 - q2
    elif arm.kind == "RPR":
        r = np.hypot(x, y)
        if np.any(r < tol):
            fail(r < tol, "the third joint cannot be at the base (prismatic extension 0)")
        q1 = np.unwrap(np.arctan2(y, x))
        q2 = r
        q3 = theta - q1
    elif arm.kind == "PRR":
        s2 = y / l2
        if np.any(np.abs(s2) > 1 - tol):
            fail(
                np.abs(s2) > 1 - tol,
                f"out of reach or singular (|y - base_y| must be < {l2:.4g} m)",
            )
        c2 = np.sqrt(1 - s2**2) * arm.branch_sign
        q2 = np.unwrap(np.arctan2(s2, c2))
        q1 = x - l2 * c2
        q3 = theta - q2
    else:  # PPR
        q1, q2, q3 = x, y, theta
    return np.column_stack([q1, q2, q3])


def inverse_derivatives(
    arm: Arm, q: np.ndarray, s_dot: np.ndarray, s_ddot: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Joint velocities and accelerations from third-link pose velocities and accelerations.

    Parameters
    ----------
    arm : Arm
        The arm.
    q : numpy.ndarray
        Joint coordinates (N, 3).
    s_dot, s_ddot : numpy.ndarray
        (xdot, ydot, thetadot) [m/s, rad/s] and their derivatives [m/s^2, rad/s^2], (N, 3).

    Returns
    -------
    qd, qdd : numpy.ndarray
        Joint velocities and accelerations, (N, 3).
    """
    fns = kinematic_functions(arm)
    n = q.shape[0]
    J = np.asarray(mapped(fns["jacobian"], n)(q.T)).T.reshape(n, 3, 3).transpose(0, 2, 1)
    qd = np.linalg.solve(J, s_dot[..., None])[..., 0]
    bias = np.asarray(mapped(fns["jdot_qdot"], n)(q.T, qd.T)).T
    qdd = np.linalg.solve(J, (s_ddot - bias)[..., None])[..., 0]
    return qd, qdd


def joint_state(arm: Arm, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joint positions and velocities (3,), (3,) of a third-link state z = (x, y, theta,
    xdot, ydot, thetadot, ...) on the arm's branch.

    Raises
    ------
    ReachError
        If the pose is out of reach or singular.
    """
    q = inverse_position(arm, z[0], z[1], z[2])
    qd, _ = inverse_derivatives(arm, q, np.asarray(z[None, 3:6], float), np.zeros((1, 3)))
    return q[0], qd[0]


def inverse_position_symbolic(arm: Arm, x, y, theta):
    """Joint coordinates (3,) from the pose as CasADi expressions, on the arm's branch.

    Angles come out of atan2 (wrapped); the dynamics depend on them only through sines and
    cosines, so wrapping does not matter for torques. Valid inside the reach
    (see :func:`reach_margin`). The arm may be parametric (its values CasADi symbols, the
    branch given by ``arm.branch_sign``).
    """
    px, py = x - arm.base[0], y - arm.base[1]
    l1, l2 = arm.links[0].length, arm.links[1].length
    if arm.kind == "RRR":
        c2 = (px**2 + py**2 - l1**2 - l2**2) / (2 * l1 * l2)
        s2 = ca.sqrt(1 - c2**2) * arm.branch_sign
        q2 = ca.atan2(s2, c2)
        q1 = ca.atan2(py, px) - ca.atan2(l2 * s2, l1 + l2 * c2)
        return ca.vertcat(q1, q2, theta - q1 - q2)
    if arm.kind == "RPR":
        q1 = ca.atan2(py, px)
        return ca.vertcat(q1, ca.sqrt(px**2 + py**2), theta - q1)
    if arm.kind == "PRR":
        s2 = py / l2
        c2 = ca.sqrt(1 - s2**2) * arm.branch_sign
        q2 = ca.atan2(s2, c2)
        return ca.vertcat(px - l2 * c2, q2, theta - q2)
    return ca.vertcat(px, py, theta)


def reach_margin(arm: Arm, x, y):
    """A CasADi expression that is >= 0 exactly where (x, y) is inside the branch's reach.

    RRR: 1 - c2^2 (the elbow cosine); PRR: 1 - s2^2; RPR: distance from the base squared;
    PPR: 1 (everywhere).
    """
    px, py = x - arm.base[0], y - arm.base[1]
    l1, l2 = arm.links[0].length, arm.links[1].length
    if arm.kind == "RRR":
        c2 = (px**2 + py**2 - l1**2 - l2**2) / (2 * l1 * l2)
        return 1 - c2**2
    if arm.kind == "PRR":
        return 1 - (py / l2) ** 2
    if arm.kind == "RPR":
        return px**2 + py**2
    return ca.DM(1.0) + 0 * px


BRANCH_MARGIN = 1e-2
"""How far a joint-space plan keeps from the edge of the arm's branch: RRR |sin q2|, PRR
|cos q2| and RPR's extension q2 [m] at least this (the flat optimizer's reach constraint,
``reach_margin >= 1e-4``, is the same bound squared)."""


def branch_margin(arm: Arm, q, margin: float = BRANCH_MARGIN):
    """A CasADi expression of joint coordinates q (3 x N, one column a configuration) that is
    >= 0 exactly where the arm is on its branch at least ``margin`` from the edge (sine,
    cosine or metres as in :data:`BRANCH_MARGIN`), or None for PPR (one branch, no edge).

    A joint-space plan (collocation) is free to pass through the stretched elbow, RPR's base or
    PRR's vertical link 2 into the other branch; a plan of the flat outputs, whose inverse map
    keeps the arm's branch, cannot: without this bound the collocation peer solves another
    problem than the flat optimizer (and than the arm, for RPR's negative extension).
    """
    if arm.kind == "RRR":
        return arm.branch_sign * ca.sin(q[1, :]) - margin
    if arm.kind == "PRR":
        return arm.branch_sign * ca.cos(q[1, :]) - margin
    if arm.kind == "RPR":
        return q[1, :] - margin
    return None
