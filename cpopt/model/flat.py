"""The centre-of-percussion (CP) flat output and its maps, derived symbolically.

State of the reduced model (3) with the dynamic compensator:
``z = (x, y, theta, xdot, ydot, thetadot, xi, eta)``, inputs ``alpha = (alpha1, alpha2)``:

* base acceleration ``(a_x, a_y) = R(theta) (xi, alpha2)``  (8),
* ``theta_ddot = (sin(theta) a_x - cos(theta) (a_y + g0)) / K``  (3),
* ``xi_dot = eta - 2 thetadot alpha2``  (5),  ``eta_dot = alpha1``  (6).

The CP ``p = (x, y) + K (cos theta, sin theta)`` (4) is differentiated along this vector field
with CasADi: its derivatives 1..3 do not depend on alpha (checked by the tests), and the fourth
is affine in alpha, ``p'''' = A(z) alpha + b(z)``; the compensator (7) is ``alpha = A^-1 (v - b)``.
No equation is copied from the paper: (7), (10)-(12) come out of the derivation and the tests
compare them with the paper's (corrected) formulas.

The inverse map rests on one identity of the derivation, ``p'' + g0 e_y = gamma (cos, sin)(theta)``
with ``gamma = xi - K thetadot^2 + g0 sin(theta)``, and its derivative
``p''' = R(theta) (gamma_dot, gamma thetadot)`` with ``gamma_dot = eta + 3 g0 cos(theta) thetadot``.
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

from .mapping import mapped


def rotation(theta):
    """Planar rotation matrix R(theta) (CasADi)."""
    c, s = ca.cos(theta), ca.sin(theta)
    return ca.blockcat([[c, -s], [s, c]])


def closed_loop_field(z, alpha, K, g0):
    """Time derivative of z under inputs alpha (CasADi expressions); also returns (a_x, a_y)."""
    theta, thetadot, xi, eta = z[2], z[5], z[6], z[7]
    a = rotation(theta) @ ca.vertcat(xi, alpha[1])
    theta_ddot = (ca.sin(theta) * a[0] - ca.cos(theta) * (a[1] + g0)) / K
    zdot = ca.vertcat(
        z[3], z[4], thetadot, a[0], a[1], theta_ddot, eta - 2 * thetadot * alpha[1], alpha[0]
    )
    return zdot, a


def cp_derivatives(z, alpha, K, g0) -> tuple[ca.SX, ca.SX, list]:
    """The CP and its derivatives 0..4 along the closed-loop field, for symbols z and alpha.

    Returns
    -------
    zdot, a : casadi.SX
        The state derivative (8) and the base acceleration (2).
    derivs : list of casadi.SX
        The CP's derivatives 0..4 (each 2,).
    """
    zdot, a = closed_loop_field(z, alpha, K, g0)
    derivs = [z[0:2] + K * ca.vertcat(ca.cos(z[2]), ca.sin(z[2]))]
    for _ in range(4):
        derivs.append(ca.jtimes(derivs[-1], z, zdot))
    return zdot, a, derivs


def compensator_expressions(z, v, K, g0):
    """The dynamic compensator (5)-(8) for a desired CP fourth derivative, as expressions.

    Parameters
    ----------
    z, v : casadi.SX
        State (8) and desired fourth CP derivative (2): symbols or expressions.
    K, g0 : float or casadi.SX
        CP distance [m] and gravity [m/s^2] (numbers, or symbols of a parametric arm).

    Returns
    -------
    alpha, zdot, a : casadi.SX
        Compensator inputs (2), state derivative (8) and base acceleration (2).
    """
    zs = ca.SX.sym("z", 8)
    alpha = ca.SX.sym("alpha", 2)
    zdot, a, derivs = cp_derivatives(zs, alpha, K, g0)
    fourth = derivs[4]
    # the fourth derivative is affine in alpha: A and b at alpha = 0 (cancelling terms vanish)
    A = ca.substitute(ca.jacobian(fourth, alpha), alpha, ca.DM.zeros(2))
    b = ca.substitute(fourth, alpha, ca.DM.zeros(2))
    alpha_v = ca.solve(A, v - b)
    out = [alpha_v, ca.substitute(zdot, alpha, alpha_v), ca.substitute(a, alpha, alpha_v)]
    return tuple(ca.substitute(e, zs, z) for e in out)


def inverse_expressions(P, sigma, K, g0):
    """The inverse flat map as an expression: the state z (8) from the CP derivatives 0..3.

    Parameters
    ----------
    P : casadi.SX
        CP and its derivatives 0..3 [m/s^k] (2 x 4, or more columns: the first four are used).
    sigma : casadi.SX or float
        Sign of gamma.
    K, g0 : float or casadi.SX
        CP distance [m] and gravity [m/s^2] (numbers, or symbols of a parametric arm).
    """
    acc = P[:, 2] + ca.vertcat(0, g0)
    theta = ca.atan2(sigma * acc[1], sigma * acc[0])
    gam = sigma * ca.norm_2(acc)
    c, s = ca.cos(theta), ca.sin(theta)
    jerk_link = rotation(theta).T @ P[:, 3]  # (gamma_dot, gamma * thetadot)
    thetadot = jerk_link[1] / gam
    xi = gam + K * thetadot**2 - g0 * s
    eta = jerk_link[0] - 3 * g0 * c * thetadot
    pos = P[:, 0] - K * ca.vertcat(c, s)
    vel = P[:, 1] - K * thetadot * ca.vertcat(-s, c)
    return ca.vertcat(pos, theta, vel, thetadot, xi, eta)


@lru_cache(maxsize=16)
def flat_functions(K: float, g0: float) -> dict[str, ca.Function]:
    """CasADi functions of the flat maps for a CP distance K [m] and gravity g0 [m/s^2].

    Returns
    -------
    dict of casadi.Function
        ``output(z) -> P`` with P (2 x 4) = CP and its derivatives 0..3 (the forward map);
        ``fourth(z, alpha) -> p''''`` (2,); ``compensator(z, v) -> (alpha, zdot, a)``: the
        dynamic feedback (5)-(8) giving inputs, the state derivative and the base acceleration
        for a desired p'''' = v; ``gamma(z)``; ``inverse(P, sigma) -> z`` (the inverse map,
        sigma = sign of gamma); ``lie_alpha(z)`` the Jacobian of derivatives 1..3 w.r.t. alpha
        (zero: the relative degree is four).
    """
    z = ca.SX.sym("z", 8)
    alpha = ca.SX.sym("alpha", 2)
    v = ca.SX.sym("v", 2)
    _, _, derivs = cp_derivatives(z, alpha, K, g0)
    lower = ca.horzcat(*derivs[:4])
    # Derivatives 1..3 are independent of alpha (checked by the tests): evaluate at alpha = 0.
    lower0 = ca.substitute(lower, alpha, ca.DM.zeros(2))
    gamma = z[6] - K * z[5] ** 2 + g0 * ca.sin(z[2])
    P = ca.SX.sym("P", 2, 4)
    sigma = ca.SX.sym("sigma")
    compensator = compensator_expressions(z, v, K, g0)

    return {
        "output": ca.Function("output", [z], [lower0]),
        "lie_alpha": ca.Function("lie_alpha", [z, alpha], [ca.jacobian(ca.vec(lower), alpha)]),
        "fourth": ca.Function("fourth", [z, alpha], [derivs[4]]),
        "compensator": ca.Function("compensator", [z, v], list(compensator)),
        "gamma": ca.Function("gamma", [z], [gamma]),
        "inverse": ca.Function("inverse", [P, sigma], [inverse_expressions(P, sigma, K, g0)]),
    }


def output(z: np.ndarray, K: float, g0: float) -> np.ndarray:
    """Forward flat map: CP and its derivatives 0..3 for states z.

    Parameters
    ----------
    z : numpy.ndarray
        (8,) or (N, 8): x, y [m], theta [rad], xdot, ydot [m/s], thetadot [rad/s],
        xi [m/s^2], eta [m/s^3].
    K, g0 : float
        CP distance [m] and gravity [m/s^2].

    Returns
    -------
    numpy.ndarray
        (2, 4) or (N, 2, 4): column k is the k-th derivative of (y1, y2) [m/s^k].
    """
    z = np.asarray(z, float)
    f = flat_functions(K, g0)["output"]
    if z.ndim == 1:
        return np.asarray(f(z))
    out = np.asarray(mapped(f, z.shape[0])(z.T))
    return out.reshape(2, z.shape[0], 4).transpose(1, 0, 2)


def inverse(P: np.ndarray, sigma: float, K: float, g0: float) -> np.ndarray:
    """Inverse flat map: states z from the CP and its derivatives 0..3.

    Parameters
    ----------
    P : numpy.ndarray
        (2, 4) or (N, 2, 4), as returned by :func:`output`.
    sigma : float
        Sign of gamma (+1 or -1) on this stretch of motion.
    K, g0 : float
        CP distance [m] and gravity [m/s^2].

    Returns
    -------
    numpy.ndarray
        (8,) or (N, 8); theta is in (-pi, pi] (unwrap it along a motion).
    """
    P = np.asarray(P, float)
    f = flat_functions(K, g0)["inverse"]
    if P.ndim == 2:
        return np.asarray(f(P, sigma)).ravel()
    n = P.shape[0]
    flat = P.transpose(1, 0, 2).reshape(2, 4 * n)
    return np.asarray(mapped(f, n)(flat, sigma)).T


def gamma(z: np.ndarray, K: float, g0: float) -> np.ndarray:
    """Regularity quantity gamma = xi - K thetadot^2 + g0 sin(theta) [m/s^2]."""
    z = np.asarray(z, float)
    return z[..., 6] - K * z[..., 5] ** 2 + g0 * np.sin(z[..., 2])


def compensate(z: np.ndarray, v: np.ndarray, K: float, g0: float):
    """Dynamic compensator (5)-(8) for desired CP fourth derivatives v, along samples.

    Parameters
    ----------
    z : numpy.ndarray
        States (N, 8).
    v : numpy.ndarray
        Desired CP fourth derivatives (N, 2) [m/s^4].

    Returns
    -------
    alpha, zdot, a : numpy.ndarray
        Compensator inputs (N, 2), state derivatives (N, 8), base accelerations (N, 2) [m/s^2].
    """
    f = mapped(flat_functions(K, g0)["compensator"], z.shape[0])
    alpha, zdot, a = f(np.asarray(z, float).T, np.asarray(v, float).T)
    return np.asarray(alpha).T, np.asarray(zdot).T, np.asarray(a).T
