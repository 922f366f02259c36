"""Time-varying LQR on the arm's full joint-space dynamics, designed for the sampled loop.

With x = (q, qd) (6,) and u = (tau1, tau2), the model's dynamics x' = f(x, u) (the passive
joint torque-free) are linearised along the reference at each control instant t_k,
A_k = df/dx, B_k = df/du (CasADi Jacobians), and discretised exactly for the zero-order hold
of one period h (SciPy's matrix exponential). The discrete Riccati recursion runs backward on
the control grid (:func:`riccati_gains`) and the law applied at t_k is

    tau = tau_ff,k - K_k (x_measured - x_ref,k),

with the plan's torque averaged over the period as feed-forward tau_ff,k. Designing for the
hold rather than integrating the continuous Riccati equation and holding its gains is what
lets the gains be high at 1 kHz: measured on the PRR swing-up with the default weights
(:data:`DEFAULT_Q`, :func:`relative_R`), the continuous design leaves 6e-4 m of CP error
on the model itself and the discrete one 9e-6 m; with a terminal weight of 1e4 the held
continuous gains diverge on 16 of 20 unsaturated plants, the discrete ones on none. Nothing
here needs gamma != 0, so the same controller tracks flat and collocation plans.
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

from ..model.dynamics import arm_dynamics
from ..model.mapping import mapped
from ..model.robot import Arm
from .controller import Controller
from .reference import Reference

DEFAULT_Q = (2000.0, 2000.0, 2000.0, 1.0, 1.0, 1.0)
"""Diagonal of Q on (q1, q2, q3 [rad or m], q1dot, q2dot, q3dot [rad/s or m/s]).

Chosen with :data:`R_RELATIVE` and :data:`DEFAULT_QF` by measurement at 1 kHz on the benchmark
plant of :mod:`cpopt.tracking.robustness`, 20 Monte Carlo plants on each of the twelve bundled
plans (noisy, partial figures: +-0.1 per plan). Mean Monte Carlo success:

* the former Q = Qf = (100, 100, 100, 1, 1, 1), R = 3e-5 on both torques: 0.67 (0.25 to 1);
  weights alone barely moved it: ten times the position weights, 1000 on the passive joint
  or R = 1e-5 stayed within 0.05 on the worst plans;
* Q = Qf = (2000, 2000, 2000, 1, 1, 1), R_RELATIVE = 0.2 (the defaults): 0.87 (0.30 to 1);
  with the same Q but Qf left at the former value 0.77, so the terminal weight matters;
* around it, on the weakest plans: Qf = 5000 on positions, velocity weights 2 in Q or 10 and
  50 in Qf, position weights 500: each equal or worse; Qf the infinite-horizon cost at the
  goal (discrete ARE): 0.15 to 0.25 (the arm reaches T still moving);
* R_RELATIVE = 1 (the same Q): half the torque noise, 0.05 less success on four of the
  weakest plans.

The price of these gains is noise: on the benchmark's measurement noise (1e-4 rad, 1e-2
rad/s) the torque's standard deviation about the feed-forward is 10 to 30 % of the plan's
peak torque (1 to 8 % with the former weights). Where sensors are noisier, raise R.

What still fails is not the gains': on paper_transfer, transfer_min_torque and
swing_up_torque_limited the motors saturate (without a torque limit: 0.95, 1.0 and 0.95), and
the minimum-time swing-up rides its torque limits 66 % of the time, leaving feedback nothing.
"""
R_RELATIVE = 0.2
"""Default torque weight relative to the plan: R_i = R_RELATIVE / (peak |tau_i| of the plan)^2
(:func:`relative_R`), so that a correction of a given fraction of a joint's peak torque costs
the same on every arm and joint (the bundled plans' peak torques range from 26 to 1046, N m
or N; one absolute R made the weak joint of the heavy transfer arm as cheap as its strong one)."""
DEFAULT_QF = DEFAULT_Q
"""Diagonal of the terminal weight Qf on the joint state (see :data:`DEFAULT_Q`)."""


@lru_cache(maxsize=16)
def linearization(model: Arm) -> ca.Function:
    """``(x, u) -> (A, B)``: Jacobians of the model's joint-space dynamics (6 x 6, 6 x 2)."""
    x = ca.SX.sym("x", 6)
    u = ca.SX.sym("u", 2)
    f = ca.vertcat(x[3:6], arm_dynamics(model)["forward"](x[0:3], x[3:6], u))
    return ca.Function("linearization", [x, u], [ca.jacobian(f, x), ca.jacobian(f, u)])


def _weights(values, size: int, name: str) -> np.ndarray:
    w = np.asarray(values, float)
    if w.shape != (size,) or np.any(w < 0) or not np.all(np.isfinite(w)):
        raise ValueError(f"{name}: give {size} finite values >= 0, got {w.tolist()}")
    return np.diag(w)


def relative_R(reference: Reference, relative: float = R_RELATIVE) -> tuple[float, float]:
    """The default R: ``relative`` over the square of the plan's peak |torque| of each joint
    [1/(N m)^2 or 1/N^2]; a joint the plan never loads is weighted as if its peak were 1."""
    peak = np.abs(reference.tau).max(axis=0)
    peak = np.where(peak > 0, peak, 1.0)
    return tuple(float(v) for v in relative / peak**2)


def discrete_linearization(reference: Reference) -> tuple[np.ndarray, np.ndarray]:
    """Ad (n, 6, 6) and Bd (n, 6, 2): the model linearised at each instant t_k (k < n) and
    discretised exactly for a zero-order hold over the period (matrix exponential of
    [[A_k, B_k], [0, 0]] h)."""
    n = reference.steps
    A, B = mapped(linearization(reference.arm), n)(reference.x[:-1].T, reference.tau[:-1].T)
    M = np.zeros((n, 8, 8))
    M[:, :6, :6] = np.asarray(A).reshape(6, n, 6).transpose(1, 0, 2)
    M[:, :6, 6:] = np.asarray(B).reshape(6, n, 2).transpose(1, 0, 2)
    from scipy.linalg import expm  # imported where used: start-up time

    E = expm(M * reference.period)
    return E[:, :6, :6], E[:, :6, 6:]


def riccati_gains(reference: Reference, Q=DEFAULT_Q, R=None, Qf=DEFAULT_QF) -> np.ndarray:
    """Feedback gains K_k at every control instant (n + 1, 2, 6); the last repeats K_{n-1}.

    The discrete Riccati recursion on the zero-order-hold model of :func:`discrete_linearization`
    with the stage cost weighted by the period h, so that Q and R keep their continuous-time
    meaning:

        S_n = Qf,   K_k = (R h + Bd^T S_{k+1} Bd)^-1 Bd^T S_{k+1} Ad,
        S_k = Q h + Ad^T S_{k+1} (Ad - Bd K_k).

    Parameters
    ----------
    reference : Reference
        The plan on the control grid.
    Q, R, Qf : sequence of float
        Diagonals of the state weight (6), input weight (2, > 0; None: :func:`relative_R`)
        and terminal weight (6).
    """
    Q, Qf = _weights(Q, 6, "Q"), _weights(Qf, 6, "Qf")
    R = _weights(relative_R(reference) if R is None else R, 2, "R")
    if np.any(np.diag(R) <= 0):
        raise ValueError(f"R: the input weights must be > 0, got {np.diag(R).tolist()}")
    Ad, Bd = discrete_linearization(reference)
    h = reference.period
    gains = np.zeros((reference.steps + 1, 2, 6))
    S = Qf
    for k in range(reference.steps - 1, -1, -1):
        BtS = Bd[k].T @ S
        gains[k] = np.linalg.solve(R * h + BtS @ Bd[k], BtS @ Ad[k])
        S = Q * h + Ad[k].T @ S @ (Ad[k] - Bd[k] @ gains[k])
        S = (S + S.T) / 2  # symmetric against round-off over thousands of steps
    gains[-1] = gains[-2]
    return gains


class TVLQRController(Controller):
    """Time-varying LQR along the plan with the plan's torques as feed-forward.

    Parameters
    ----------
    reference : Reference
        The plan on the control grid.
    Q, R, Qf : sequence of float
        Diagonals of the weights (see :func:`riccati_gains`; R None: :func:`relative_R`).
    """

    name = "tvlqr"

    def __init__(self, reference: Reference, Q=DEFAULT_Q, R=None, Qf=DEFAULT_QF) -> None:
        self.gains = riccati_gains(reference, Q, R, Qf)
        super().__init__(reference)

    def schedule(self) -> np.ndarray:
        """Rows: the reference joint state (6), the feed-forward torque (2), the gains (12)."""
        ref = self.reference
        ff = np.vstack([ref.tau_mean, ref.tau[-1:]])
        gains = self.gains.transpose(0, 2, 1).reshape(ref.t.size, 12)  # column-major (2 x 6)
        return np.column_stack([ref.x, ff, gains]).T

    def law(self) -> ca.Function:
        """tau = tau_ff - K (x - x_ref); the controller has no state of its own."""
        r = ca.SX.sym("r", 20)
        q = ca.SX.sym("q", 3)
        qd = ca.SX.sym("qd", 3)
        c = ca.SX.sym("c", 2)
        gain = ca.reshape(r[8:20], 2, 6)
        tau = r[6:8] - gain @ (ca.vertcat(q, qd) - r[0:6])
        return ca.Function("tvlqr", [r, q, qd, c], [tau, c])
