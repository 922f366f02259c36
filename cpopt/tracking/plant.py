"""The simulated arm: its own link parameters, joint friction and torque saturation.

A :class:`Plant` is the arm a controller meets, which may differ from the model the plan was
made for. Its dynamics are derived once per arm kind with every physical parameter a CasADi
input (:data:`PARAMETER_NAMES`), so one function serves every plant of a kind and many
plants are simulated in one mapped call.

Friction on joint i (the passive joint 3 included) is the generalised force

    f_i = viscous_i qdot_i + coulomb_i tanh(qdot_i / COULOMB_VELOCITY_SCALE)

opposing the motion. The Coulomb term is smoothed with tanh so that the fixed-step RK4
integration of a control period keeps its order and no stick/slip events need locating (a
sign function would make the right-hand side discontinuous at every velocity reversal); the
price is that a joint held at rest creeps instead of sticking, at velocities below the scale.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache

import casadi as ca
import numpy as np

from ..model.dynamics import SymbolicLink, lagrangian
from ..model.robot import Arm, Link

COULOMB_VELOCITY_SCALE = 0.01
"""Velocity [rad/s or m/s] at which the smoothed Coulomb friction reaches tanh(1) = 76 % of
its level (99.9 % at four times it). The bundled plans move their joints at metres and radians
per second, so the smoothing acts only around velocity reversals."""

SUBSTEPS = 2
"""RK4 steps of the plant per control period (0.5 ms at 1 kHz). Measured against DOP853 along
the paper's plans, the state error of one period is at most 2e-10 on the swing-up and 1e-13 on
the transfer (3e-9 and 2e-12 with one step), far below the tracking errors."""

LINK_FIELDS = ("length", "mass", "com", "inertia")
PARAMETER_NAMES = (
    *(f"links[{i}].{f}" for i in range(3) for f in LINK_FIELDS),
    *(f"friction.viscous[{i}]" for i in range(3)),
    *(f"friction.coulomb[{i}]" for i in range(3)),
    "torque_limit[0]",
    "torque_limit[1]",
    "gain[0]",
    "gain[1]",
)
"""Names of the plant's parameters, in the order of :meth:`Plant.parameters` (SI units:
m, kg, m, kg m^2; N m s/rad or N s/m; N m or N; the actuator gains are ratios)."""

NO_LIMIT = 1e12
"""Stands for an absent torque limit in the parameter vector [N m or N]."""


@dataclass(frozen=True)
class Plant:
    """An arm as simulated.

    Parameters
    ----------
    arm : Arm
        Its links (length, mass, centre of mass, inertia); kind, base, gravity and branch are
        the model's.
    viscous : tuple of float
        Viscous friction of joints 1..3 [N m s/rad or N s/m].
    coulomb : tuple of float
        Coulomb friction level of joints 1..3 [N m or N].
    torque_limit : tuple of float or None
        Saturation of tau1, tau2 [N m or N] (None: none; per joint None too).
    gain : tuple of float
        Actuator gains of motors 1, 2: the torque applied is the gain times the saturated
        command (1: an exact motor).
    delay : float
        Actuation delay [s]: a command reaches the motors this much later (rounded to whole
        control periods; before the start the motors hold the plan's initial torque).

    Noise on the applied torques is drawn with the measurement noise
    (:attr:`cpopt.tracking.simulation.Noise.torque`).
    """

    arm: Arm
    viscous: tuple[float, float, float] = (0.0, 0.0, 0.0)
    coulomb: tuple[float, float, float] = (0.0, 0.0, 0.0)
    torque_limit: tuple[float | None, float | None] | None = None
    gain: tuple[float, float] = (1.0, 1.0)
    delay: float = 0.0

    def delay_steps(self, period: float) -> int:
        """The actuation delay in whole control periods of ``period`` [s]."""
        return max(0, round(self.delay / period))

    def parameters(self) -> np.ndarray:
        """The parameter vector (22,) in :data:`PARAMETER_NAMES` order."""
        links = [[lk.length, lk.mass, lk.d, lk.I] for lk in self.arm.links]
        limit = self.torque_limit or (None, None)
        return np.array(
            [
                *np.ravel(links),
                *self.viscous,
                *self.coulomb,
                *(NO_LIMIT if v is None else v for v in limit),
                *self.gain,
            ],
            float,
        )

    def with_parameters(self, values: np.ndarray) -> Plant:
        """The plant with the parameter vector ``values`` (22,) (see :data:`PARAMETER_NAMES`);
        its delay is this plant's."""
        v = np.asarray(values, float)
        links = tuple(Link(*v[4 * i : 4 * i + 4]) for i in range(3))
        limit = tuple(None if x >= NO_LIMIT else float(x) for x in v[18:20])
        return replace(
            self,
            arm=replace(self.arm, links=links),
            viscous=tuple(v[12:15]),
            coulomb=tuple(v[15:18]),
            torque_limit=None if limit == (None, None) else limit,
            gain=tuple(v[20:22]),
        )


@dataclass(frozen=True)
class _SymbolicArm:
    kind: str
    base: tuple[float, float]
    gravity: float
    links: tuple = field(default_factory=tuple)


@lru_cache(maxsize=8)
def plant_dynamics(kind: str, base: tuple[float, float], gravity: float) -> ca.Function:
    """``qdd(q, qd, tau, p)``: forward dynamics of a plant with parameters p (20,).

    Friction acts on all three joints; tau (2,) is applied to joints 1 and 2 as given (the
    saturation is the caller's, see :func:`plant_period`).
    """
    q = ca.SX.sym("q", 3)
    qd = ca.SX.sym("qd", 3)
    tau = ca.SX.sym("tau", 2)
    p = ca.SX.sym("p", len(PARAMETER_NAMES))
    links = tuple(SymbolicLink(*(p[4 * i + j] for j in range(4))) for i in range(3))
    B, n, *_ = lagrangian(_SymbolicArm(kind, base, gravity, links), q, qd)
    friction = p[12:15] * qd + p[15:18] * ca.tanh(qd / COULOMB_VELOCITY_SCALE)
    force = ca.vertcat(tau, 0) - friction
    qdd = ca.cse(ca.solve(B, force - n))
    return ca.Function("plant_dynamics", [q, qd, tau, p], [qdd])


@lru_cache(maxsize=8)
def plant_period(
    kind: str, base: tuple[float, float], gravity: float, period: float, substeps: int = SUBSTEPS
) -> ca.Function:
    """``(X, tau, p, w) -> (X_next, qdd, tau_applied)``: one control period of a plant.

    The commanded torque tau (2,) is saturated at the plant's limit, multiplied by the
    actuator gains, added the torque noise w (2,) [N m or N] and held (zero-order hold) while
    the state X = (q, qd) (6,) is integrated by ``substeps`` RK4 steps over ``period`` [s];
    qdd (3,) are the accelerations at the start of the period.
    """
    X = ca.SX.sym("X", 6)
    tau = ca.SX.sym("tau", 2)
    p = ca.SX.sym("p", len(PARAMETER_NAMES))
    w = ca.SX.sym("w", 2)
    accel = plant_dynamics(kind, base, gravity)
    held = p[20:22] * ca.fmin(ca.fmax(tau, -p[18:20]), p[18:20]) + w

    def f(x):
        return ca.vertcat(x[3:6], accel(x[0:3], x[3:6], held, p))

    h = period / substeps
    x = X
    qdd = None
    for _ in range(substeps):
        k1 = f(x)
        qdd = k1[3:6] if qdd is None else qdd
        k2 = f(x + h / 2 * k1)
        k3 = f(x + h / 2 * k2)
        k4 = f(x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    # one expression graph for the period: cse merges the trigonometry the stages share
    x, qdd, held = ca.cse([x, qdd, held])
    return ca.Function("plant_period", [X, tau, p, w], [x, qdd, held])
