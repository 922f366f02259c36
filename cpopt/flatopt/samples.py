"""The per-sample function of the flat optimizer and its compiled library.

One sample's CP derivatives P (2 x 5) map to the arm's torques, joint motion and reach margin
through the flat inverse map, the inverse kinematics and the inverse dynamics. The arm's
parameters (lengths, masses, centres of mass, inertias, gravity, base, branch) are inputs, so one
library serves every arm of a kind; it is compiled once and cached (:mod:`cpopt.compiled`).

The library holds what the solver needs from a sample, with y = (tau1, tau2, q1, q2, q3, qd1,
qd2, qd3, reach) (:data:`OUTPUTS`):

* ``sample(P, sigma, arm) -> y``;
* ``sample_jac(P, sigma, arm) -> (y, J)``, J = dy/dvec(P) (9 x 10);
* ``sample_hess(P, sigma, arm, mu, W) -> H``: the upper triangle of the Hessian of the sample's
  part of the Lagrangian, ``J' W J + sum_i mu_i d2y_i/dvec(P)2`` (10 x 10), where ``mu`` (9)
  and ``W`` (9 x 9) are the gradient and Hessian of the Lagrangian with respect to y;
* ``sample_gn(P, sigma, arm, W) -> J' W J`` (upper triangle): the Gauss-Newton block, without
  the curvature of y.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import casadi as ca
import numpy as np

from ..model import dynamics, flat, kinematics
from ..model.dynamics import SymbolicLink, lagrangian
from ..model.kinematics import inverse_position_symbolic, link_geometry, reach_margin
from ..model.robot import Arm
from ..runtime import compiled

ARM_PARAMETERS = (
    "l1", "l2", "l3", "m1", "m2", "m3", "d1", "d2", "d3", "I1", "I2", "I3",
    "g0", "base_x", "base_y", "branch_sign",
)  # fmt: skip
"""The arm's parameters, the library's third input, in order (SI units; branch as +-1)."""
OUTPUTS = ("tau1", "tau2", "q1", "q2", "q3", "qd1", "qd2", "qd3", "reach")
"""The rows of a sample's outputs y."""
NY = len(OUTPUTS)
TAU, Q, QD, REACH = slice(0, 2), slice(2, 5), slice(5, 8), 8
"""Rows of y: torques, joint positions, joint velocities, reach margin."""


@dataclass(frozen=True)
class ParametricArm:
    """An arm of a given kind whose parameters are the symbols :data:`ARM_PARAMETERS`."""

    kind: str
    values: ca.SX

    def __getitem__(self, name: str) -> ca.SX:
        return self.values[ARM_PARAMETERS.index(name)]

    @property
    def links(self) -> tuple[SymbolicLink, ...]:
        return tuple(
            SymbolicLink(self[f"l{i}"], self[f"m{i}"], self[f"d{i}"], self[f"I{i}"])
            for i in (1, 2, 3)
        )

    @property
    def gravity(self) -> ca.SX:
        return self["g0"]

    @property
    def base(self) -> tuple[ca.SX, ca.SX]:
        return self["base_x"], self["base_y"]

    @property
    def branch_sign(self) -> ca.SX:
        return self["branch_sign"]

    @property
    def K(self) -> ca.SX:
        link = self.links[2]
        return (link.I + link.mass * link.d**2) / (link.mass * link.d)


def arm_vector(arm: Arm) -> np.ndarray:
    """A numeric arm's values of :data:`ARM_PARAMETERS`."""
    links = arm.links
    return np.array(
        [
            *(link.length for link in links),
            *(link.mass for link in links),
            *(link.d for link in links),
            *(link.I for link in links),
            arm.gravity,
            *arm.base,
            arm.branch_sign,
        ],
        float,
    )


def sample_outputs(arm, P: ca.SX, sigma) -> ca.SX:
    """One sample's y (:data:`OUTPUTS`) as an expression of its CP derivatives.

    Parameters
    ----------
    arm : Arm or ParametricArm
        The arm (its values may be symbols).
    P : casadi.SX
        The CP derivatives 0..4 [m/s^k] (2 x 5).
    sigma : casadi.SX or float
        The sign of gamma.
    """
    K, g0 = arm.K, arm.gravity
    z = flat.inverse_expressions(P, sigma, K, g0)
    _, zdot, _ = flat.compensator_expressions(z, P[:, 4], K, g0)
    q = inverse_position_symbolic(arm, z[0], z[1], z[2])
    qs, qds, qdds = ca.SX.sym("q", 3), ca.SX.sym("qd", 3), ca.SX.sym("qdd", 3)
    geo = link_geometry(arm, qs)
    J = ca.jacobian(ca.vertcat(geo.wrist, geo.theta), qs)
    jdot_qd = ca.jacobian(J @ qds, qs) @ qds
    B, n, *_ = lagrangian(arm, qs, qds)
    Jq = ca.substitute(J, qs, q)
    qd = ca.solve(Jq, z[3:6])
    qdd = ca.solve(Jq, zdot[3:6] - ca.substitute(ca.substitute(jdot_qd, qds, qd), qs, q))
    generalized = ca.substitute([B @ qdds + n], [qs, qds, qdds], [q, qd, qdd])[0]
    return ca.vertcat(generalized[:2], q, qd, reach_margin(arm, z[0], z[1]))


def library_functions(kind: str) -> list[ca.Function]:
    """The functions of a kind's library (see the module docstring)."""
    P = ca.SX.sym("P", 2, 5)
    sigma = ca.SX.sym("sigma")
    values = ca.SX.sym("arm", len(ARM_PARAMETERS))
    mu = ca.SX.sym("mu", len(OUTPUTS))
    W = ca.SX.sym("W", len(OUTPUTS), len(OUTPUTS))
    y = sample_outputs(ParametricArm(kind, values), P, sigma)
    J = ca.jacobian(y, ca.vec(P))
    gauss_newton = J.T @ W @ J
    curvature = ca.hessian(ca.dot(mu, y), ca.vec(P))[0]
    opts = {"cse": True}
    ins = [P, sigma, values]
    return [
        ca.Function("sample", ins, [y], opts),
        ca.Function("sample_jac", ins, [y, J], opts),
        ca.Function("sample_hess", [*ins, mu, W], [ca.triu(gauss_newton + curvature)], opts),
        ca.Function("sample_gn", [*ins, W], [ca.triu(gauss_newton)], opts),
    ]


SOURCES = (*(Path(m.__file__) for m in (compiled, dynamics, flat, kinematics)), Path(__file__))
"""The files that determine the library's code (its cache key)."""


@lru_cache(maxsize=8)
def sample_library(kind: str) -> compiled.Library:
    """The compiled (or, without a compiler, interpreted) library of an arm kind."""
    return compiled.load_library(f"samples-{kind}", SOURCES, lambda: library_functions(kind))


@lru_cache(maxsize=64)
def mapped_outputs(arm: Arm, count: int) -> ca.Function:
    """``(P (2 x 5 count), sigma (1 x count)) -> y (9 x count)``: the library's outputs of count
    samples of one arm (sample j's CP derivatives in columns 5j..5j+4)."""
    P = ca.MX.sym("P", 2, 5 * count)
    sigma = ca.MX.sym("sigma", 1, count)
    y = sample_library(arm.kind).functions["sample"].map(count)(P, sigma, ca.DM(arm_vector(arm)))
    return ca.Function("outputs", [P, sigma], [y])


def sample_values(arm: Arm, P: np.ndarray, sigma) -> np.ndarray:
    """y (:data:`OUTPUTS`) at many samples, numerically.

    Parameters
    ----------
    arm : Arm
        The arm.
    P : numpy.ndarray
        CP derivatives 0..4 of N samples, (N, 2, 5) [m/s^k].
    sigma : float or numpy.ndarray
        The sign of gamma (one, or one per sample).

    Returns
    -------
    numpy.ndarray
        (N, 9).
    """
    n = P.shape[0]
    columns = np.asarray(P, float).transpose(1, 0, 2).reshape(2, 5 * n)
    sig = np.broadcast_to(np.asarray(sigma, float), (n,))[None, :]
    return np.asarray(mapped_outputs(arm, n)(columns, sig)).T
