"""Dynamic feedback linearisation with pole placement (the paper's controller, sampled).

The compensator (5)-(8) with the static feedback of section 2.1 turns the arm into two chains
of four integrators from the CP's fourth derivative v to the CP; the linear law

    v = p_d'''' + sum_k k_k (p_d^(k) - p^(k)),   k = 0..3,

places the poles of each error chain. The controller's own state is the compensator's
(xi, eta): it is reset at the instants the plan resets it (a via node's
``state(after=True) - state()`` on (xi, eta), or every knot of a collocation plan) and
integrated over each control period (explicit Euler with the derivative at the instant).
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

from ..model import flat
from ..model.dynamics import arm_dynamics, tracking_acceleration
from ..model.kinematics import link_geometry
from ..model.robot import Arm
from .controller import Controller
from .reference import Reference

DEFAULT_POLES = (-10.0, -10.0, -10.0, -10.0)
"""Closed-loop poles of each CP error chain [1/s]."""


class SingularTrackingError(ValueError):
    """A plan the dynamic feedback linearisation cannot follow (gamma crosses zero)."""


def pole_placement_gains(poles=DEFAULT_POLES) -> np.ndarray:
    """Gains (k0, k1, k2, k3) giving the error chain e'''' + k3 e''' + ... + k0 e = 0 the poles.

    Parameters
    ----------
    poles : sequence of float or complex
        Four poles with negative real parts [1/s] (complex ones in conjugate pairs).
    """
    poles = np.asarray(poles, complex)
    if poles.size != 4 or np.any(poles.real >= 0):
        raise ValueError(f"give four poles with negative real parts, got {poles.tolist()}")
    coeffs = np.poly(poles)  # s^4 + c1 s^3 + c2 s^2 + c3 s + c4
    if np.max(np.abs(coeffs.imag)) > 1e-9 * np.max(np.abs(coeffs)):
        raise ValueError("complex poles must come in conjugate pairs")
    return coeffs.real[::-1][:4].copy()


def dfl_expressions(model, q, qd, c, Pd, gains) -> tuple[ca.SX, ca.SX]:
    """The linearising law as expressions: torques (2) and compensator derivative (2) for a
    model arm, numeric or parametric (its values CasADi symbols: one compiled verification step
    per arm kind, :mod:`cpopt.verify_steps`); q and qd are symbols.

    c = (xi, eta) is the compensator's state, Pd (2 x 5) the desired CP and its derivatives
    0..4, gains (4,) the pole-placement gains.
    """
    K, g0 = model.K, model.gravity
    geo = link_geometry(model, q)
    pose = ca.vertcat(geo.wrist, geo.theta)
    z = ca.vertcat(pose, ca.jtimes(pose, q, qd), c)
    zs, alpha = ca.SX.sym("z", 8), ca.SX.sym("alpha", 2)
    _, _, derivs = flat.cp_derivatives(zs, alpha, K, g0)
    lower = ca.substitute(ca.horzcat(*derivs[:4]), alpha, ca.DM.zeros(2))  # free of alpha
    P = ca.substitute(lower, zs, z)
    v = Pd[:, 4] + (Pd[:, 0:4] - P) @ gains
    _, zdot, a = flat.compensator_expressions(z, v, K, g0)
    return tracking_acceleration(model, q, qd, a)[1], zdot[6:8]


@lru_cache(maxsize=16)
def dfl_law(model: Arm) -> ca.Function:
    """``(q, qd, c, Pd, gains) -> (tau, c_dot)``: the linearising law of a model arm
    (:func:`dfl_expressions`).

    c = (xi, eta) is the compensator's state, Pd (2 x 5) the desired CP and its derivatives
    0..4, gains (4,) the pole-placement gains; tau (2,) [N m or N] are the actuated torques
    and c_dot the compensator's derivative.
    """
    q = ca.SX.sym("q", 3)
    qd = ca.SX.sym("qd", 3)
    c = ca.SX.sym("c", 2)
    Pd = ca.SX.sym("Pd", 2, 5)
    gains = ca.SX.sym("k", 4)
    tau, c_dot = dfl_expressions(model, q, qd, c, Pd, gains)
    return ca.Function("dfl", [q, qd, c, Pd, gains], [tau, c_dot])


class DFLController(Controller):
    """Dynamic feedback linearisation with pole placement, sampled at the reference's rate.

    Parameters
    ----------
    reference : Reference
        The plan on the control grid.
    poles : sequence of float
        Poles of each CP error chain [1/s].

    Raises
    ------
    SingularTrackingError
        When gamma crosses zero along the plan (a collocation plan without its gamma
        constraint), where the compensator is singular.
    """

    name = "dfl"

    def __init__(self, reference: Reference, poles=DEFAULT_POLES) -> None:
        if reference.dfl_issue:
            raise SingularTrackingError(reference.dfl_issue)
        self.gains = pole_placement_gains(poles)
        super().__init__(reference)

    def initial_state(self) -> np.ndarray:
        """The plan's (xi, eta) at its start [m/s^2, m/s^3]."""
        return self.reference.compensator[0] - self.reference.resets[0]

    def schedule(self) -> np.ndarray:
        """Rows: the desired CP derivatives at the instant and in the middle of the period
        (2 x 5 each, column-major) and the reset of (xi, eta)."""
        ref = self.reference
        Pd = ref.cp.transpose(0, 2, 1).reshape(ref.t.size, 10)
        mid = np.vstack([ref.cp_mid, ref.cp[-1:]]).transpose(0, 2, 1).reshape(ref.t.size, 10)
        hold = np.vstack([ref.tau_mean - ref.tau_mid, [[0.0, 0.0]]])
        return np.column_stack([Pd, mid, ref.resets, hold]).T

    def law(self) -> ca.Function:
        """The sampled law, a midpoint step of the continuous closed loop.

        The continuous law's torque changes within a period; holding its value at the
        instant lags it by half a period and leaves an error of the order of the period
        (centimetres at 1 kHz on the swing-ups). So the law is evaluated at the instant, the
        joint state and compensator are predicted to the middle of the period with the model
        under that torque, and the law evaluated there is held; the compensator advances by
        its derivative at the middle (second order in the period).
        """
        model = self.reference.arm
        r = ca.SX.sym("r", 24)
        q = ca.SX.sym("q", 3)
        qd = ca.SX.sym("qd", 3)
        c = ca.SX.sym("c", 2)
        law = dfl_law(model)
        gains = ca.DM(self.gains)
        h = self.period / 2
        c0 = c + r[20:22]
        tau0, c_dot0 = law(q, qd, c0, ca.reshape(r[0:10], 2, 5), gains)
        qdd0 = arm_dynamics(model)["forward"](q, qd, tau0)
        q_mid, qd_mid = q + h * qd + h**2 / 2 * qdd0, qd + h * qdd0
        tau, c_dot = law(q_mid, qd_mid, c0 + h * c_dot0, ca.reshape(r[10:20], 2, 5), gains)
        tau = tau + r[22:24]  # the plan's period mean less its midpoint value
        return ca.Function("dfl_sampled", [r, q, qd, c], [tau, c0 + self.period * c_dot])
