"""Time-varying LQR on the arm's full joint-space dynamics, linearised along the plan.

With x = (q, qd) (6,) and u = (tau1, tau2), the model's dynamics x' = f(x, u) (the passive
joint torque-free) are linearised along the reference, A(t) = df/dx, B(t) = df/du (CasADi
Jacobians at the control instants, linear in between). The Riccati equation

    -S' = A^T S + S A - S B R^-1 B^T S + Q,   S(T) = Qf,

is integrated backward with SciPy, and the law applied at instant t_k is

    tau = tau_ff,k - R^-1 B_k^T S(t_k) (x_measured - x_ref,k),

with the plan's torque averaged over the period as feed-forward. Nothing here needs gamma != 0,
so the same controller tracks flat and collocation plans.
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np
from scipy.integrate import solve_ivp

from ..dynamics import arm_dynamics
from ..robot import Arm
from .controller import Controller
from .reference import Reference

DEFAULT_Q = (100.0, 100.0, 100.0, 1.0, 1.0, 1.0)
"""Diagonal of Q on (q1, q2, q3 [rad or m], q1dot, q2dot, q3dot [rad/s or m/s]).

Chosen with :data:`DEFAULT_R` by measurement at 1 kHz on six bundled plans (the two paper
transfers' fast one, the paper's and the PRR swing-ups, the minimum-time, torque-limited and
minimum-torque-transfer plans) on the benchmark plant of :mod:`cpopt.tracking.robustness`,
21-step sweeps and 30 Monte Carlo plants each, Qf = Q. Success in sweeps / Monte Carlo:

* R = 3e-5 (the default): 0.83-0.92 / 0.23-0.60, every plan followed on the model within
  2e-5 m;
* R = 1e-4: 0.81-0.91 / 0.17-0.57; R = 1e-3: 0 % on the heavy transfer arm;
* R = 1e-5: 0.84-0.93 / 0.27-0.70, but too fast for a 1 kHz hold on the PRR swing-up
  (1e-3 m on the model), as are Q = 1000 on positions with 10 on velocities (2e-2 m) and a
  velocity weight of 3 (2e-3 to 5e-3 m);
* a terminal weight 100 times Q helps the paper's swing-up and hurts the minimum-time and
  torque-limited plans (0.03 and 0.13 in Monte Carlo).
"""
DEFAULT_R = (3e-5, 3e-5)
"""Diagonal of R on (tau1, tau2) [1/(N m)^2 or 1/N^2] (see :data:`DEFAULT_Q`)."""
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


def riccati_gains(reference: Reference, Q=DEFAULT_Q, R=DEFAULT_R, Qf=DEFAULT_QF) -> np.ndarray:
    """Feedback gains R^-1 B^T S at every control instant (n + 1, 2, 6).

    Parameters
    ----------
    reference : Reference
        The plan on the control grid.
    Q, R, Qf : sequence of float
        Diagonals of the state weight (6), input weight (2, > 0) and terminal weight (6).
    """
    Q, Qf = _weights(Q, 6, "Q"), _weights(Qf, 6, "Qf")
    R = _weights(R, 2, "R")
    if np.any(np.diag(R) <= 0):
        raise ValueError(f"R: the input weights must be > 0, got {np.diag(R).tolist()}")
    n = reference.t.size
    f = linearization(reference.arm).map(n)
    A, B = (np.asarray(m) for m in f(reference.x.T, reference.tau.T))
    A = A.reshape(6, n, 6).transpose(1, 0, 2)
    B = B.reshape(6, n, 2).transpose(1, 0, 2)
    R_inv = np.linalg.inv(R)
    t = reference.t
    h = reference.period

    def rhs(s, S_flat):
        # s = t_end - t runs forward; linear interpolation between the instants
        tt = t[-1] - s
        k = int(np.clip((tt - t[0]) // h, 0, n - 2))
        w = np.clip((tt - t[k]) / h, 0.0, 1.0)
        Ak = (1 - w) * A[k] + w * A[k + 1]
        Bk = (1 - w) * B[k] + w * B[k + 1]
        S = S_flat.reshape(6, 6)
        dS = Ak.T @ S + S @ Ak - S @ Bk @ R_inv @ Bk.T @ S + Q
        return dS.ravel()

    span = t[-1] - t[0]
    sol = solve_ivp(rhs, (0.0, span), Qf.ravel(), method="RK45", t_eval=span - (t - t[0])[::-1],
                    rtol=1e-6, atol=1e-8, max_step=max(h, span / 50))  # fmt: skip
    if not sol.success:
        raise RuntimeError(f"the Riccati equation failed to integrate: {sol.message}")
    S = sol.y.T[::-1].reshape(n, 6, 6)
    S = (S + S.transpose(0, 2, 1)) / 2
    return np.einsum("ij,nkj,nkl->nil", R_inv, B, S)


class TVLQRController(Controller):
    """Time-varying LQR along the plan with the plan's torques as feed-forward.

    Parameters
    ----------
    reference : Reference
        The plan on the control grid.
    Q, R, Qf : sequence of float
        Diagonals of the weights (see :func:`riccati_gains`).
    """

    name = "tvlqr"

    def __init__(self, reference: Reference, Q=DEFAULT_Q, R=DEFAULT_R, Qf=DEFAULT_QF) -> None:
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
