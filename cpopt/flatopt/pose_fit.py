"""A collocation seed's fit refined where the arm is: the third link's pose kept.

The linear fit of a seed's CP (:func:`cpopt.flatopt.warm_start.fitted`) matches positions and
accelerations in their own units, but the flat map reads the link's angle from the direction
of the CP's acceleration plus gravity, ``p'' + g0 e_y = gamma (cos, sin)(theta)``, and the
link's base from ``p - K (cos, sin)(theta)``. Where |gamma| is a few m/s^2 an acceleration
misfit of 0.1 m/s^2 turns the link by a few hundredths of a radian, which moves the base by
K times as much: a seed that keeps 2 mm inside the arm's reach (an RRR elbow nearly stretched,
as optimal swings are) then starts its flat solve outside it, where the torques are not
numbers (measured on random zoo draws: every start of a pattern NaN at Ipopt's first iterate,
fitted bases 7-20 cm from the seed's).

:func:`refined` starts from the linear fit and minimises the same residuals plus the base's
and the angle's misfits (:data:`BASE_FIT`, :data:`ANGLE_FIT`) by Levenberg-Marquardt steps:
the pose is nonlinear in the coefficients only through theta, and a few steps suffice.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BASE_FIT = 1e-3
"""The unit of misfit of the third link's base [m] (a millimetre: the reach margins the seed
keeps are a few)."""
ANGLE_FIT = 1e-2
"""The unit of misfit of the third link's angle [rad]."""
LINEAR_WEIGHT = 0.1
"""The weight of the linear fit's residuals beside the pose's: its fourth-derivative rows pull
towards zero as smoothing, and at full weight they held the base 4.7 cm off a seed the
B-spline can follow to 1.4 mm (a random PRR transfer); at 0.1 or 0.01 the pose wins alike."""
GAMMA_FIT = 1e-2
"""The unit of a shortfall of |gamma| below the fit's floor [m/s^2] (the pose alone let the
benchmark transfer's seeded start graze gamma = 0.03 m/s^2 where its seed crosses zero)."""
ITERATIONS = 30
"""Most Levenberg-Marquardt steps (accepted or not)."""
DAMPING = 1e-3
"""The first step's damping, relative to the diagonal of the Gauss-Newton matrix."""


@dataclass(frozen=True)
class PoseTarget:
    """What a phase's fit keeps of the seed at its sample points.

    Attributes
    ----------
    base : numpy.ndarray
        (S, 2) the third link's base [m].
    theta : numpy.ndarray
        (S,) its angle [rad].
    sign : int
        The phase's sign of gamma.
    least : float
        The floor of |gamma| [m/s^2] the fit keeps (a penalty below it).
    K : float
        The distance from the base to the CP [m].
    gravity : float
        g0 [m/s^2].
    """

    base: np.ndarray
    theta: np.ndarray
    sign: int
    least: float
    K: float
    gravity: float


@dataclass(frozen=True)
class LinearRows:
    """The linear fit's rows in the free coefficients: ``rows @ c`` against ``rhs`` (one column
    per CP coordinate), and the free coefficients' maps to the CP's position and acceleration
    at the samples with the fixed coefficients' contributions (``position_fixed``,
    ``acceleration_fixed``, (S, 2))."""

    rows: np.ndarray
    rhs: np.ndarray
    position: np.ndarray
    acceleration: np.ndarray
    position_fixed: np.ndarray
    acceleration_fixed: np.ndarray


def _pose(c: np.ndarray, lin: LinearRows, target: PoseTarget):
    """(theta (S,), base (S, 2), acceleration plus gravity (S, 2)) of free coefficients c."""
    ap = lin.acceleration @ c + lin.acceleration_fixed
    ap[:, 1] += target.gravity
    theta = np.arctan2(target.sign * ap[:, 1], target.sign * ap[:, 0])
    p = lin.position @ c + lin.position_fixed
    base = p - target.K * np.column_stack([np.cos(theta), np.sin(theta)])
    return theta, base, ap


def residual(c: np.ndarray, lin: LinearRows, target: PoseTarget) -> np.ndarray:
    """All residuals (the linear fit's, the base's, the angle's and |gamma|'s shortfall below
    its floor, each in its unit)."""
    theta, base, ap = _pose(c, lin, target)
    turn = np.angle(np.exp(1j * (theta - target.theta)))
    shortfall = np.maximum(target.least - np.hypot(ap[:, 0], ap[:, 1]), 0.0)
    return np.concatenate(
        [
            LINEAR_WEIGHT * (lin.rows @ c - lin.rhs).T.ravel(),
            ((base - target.base) / BASE_FIT).T.ravel(),
            turn / ANGLE_FIT,
            shortfall / GAMMA_FIT,
        ]
    )


def linear_jacobian(lin: LinearRows) -> np.ndarray:
    """The linear fit's rows of the Jacobian in (c[:, 0], c[:, 1]) stacked (constant)."""
    n, m = lin.rows.shape
    linear = np.zeros((2 * n, 2 * m))
    linear[:n, :m] = linear[n:, m:] = LINEAR_WEIGHT * lin.rows
    return linear


def jacobian(
    c: np.ndarray, lin: LinearRows, target: PoseTarget, linear: np.ndarray | None = None
) -> np.ndarray:
    """The residuals' Jacobian in (c[:, 0], c[:, 1]) stacked (``linear``: the constant rows of
    :func:`linear_jacobian`, when the caller has them)."""
    theta, _, ap = _pose(c, lin, target)
    norm2 = np.maximum((ap**2).sum(axis=1), 1e-12)[:, None]
    d_theta = np.hstack(
        [-ap[:, 1:2] / norm2 * lin.acceleration, ap[:, 0:1] / norm2 * lin.acceleration]
    )
    zero = np.zeros_like(lin.position)
    K = target.K
    base_x = np.hstack([lin.position, zero]) + K * np.sin(theta)[:, None] * d_theta
    base_y = np.hstack([zero, lin.position]) - K * np.cos(theta)[:, None] * d_theta
    linear = linear_jacobian(lin) if linear is None else linear
    norm = np.sqrt(norm2)
    short = (np.hypot(ap[:, 0], ap[:, 1]) < target.least)[:, None]
    d_gamma = np.hstack(
        [ap[:, 0:1] / norm * lin.acceleration, ap[:, 1:2] / norm * lin.acceleration]
    )
    rows = [linear, base_x / BASE_FIT, base_y / BASE_FIT, d_theta / ANGLE_FIT]
    return np.vstack([*rows, -(short * d_gamma) / GAMMA_FIT])


def refined(c0: np.ndarray, lin: LinearRows, target: PoseTarget) -> np.ndarray:
    """The free coefficients (m, 2) from the linear fit ``c0`` refined by Levenberg-Marquardt
    steps on :func:`residual`; ``c0`` itself when no step lowers it."""
    c, m = np.array(c0, float), c0.shape[0]
    linear = linear_jacobian(lin)
    r = residual(c, lin, target)
    J = jacobian(c, lin, target, linear)
    cost, damping = float(r @ r), DAMPING
    for _ in range(ITERATIONS):
        normal = J.T @ J
        lhs = normal + damping * np.diag(np.diag(normal) + 1e-12)
        step = np.linalg.solve(lhs, -J.T @ r).reshape(2, m).T
        trial = residual(c + step, lin, target)
        new = float(trial @ trial)
        if not (np.isfinite(new) and new < cost):
            damping *= 10  # the same point, a shorter step: its Jacobian stands
            continue
        c, r, damping = c + step, trial, damping / 3
        if cost - new < 1e-6 * cost:
            break
        cost = new
        J = jacobian(c, lin, target, linear)
    return c


__all__ = ["ANGLE_FIT", "BASE_FIT", "LinearRows", "PoseTarget", "refined"]
