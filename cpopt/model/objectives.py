"""Objective terms, each defined once: what it measures, its integrand, and which planners can
transcribe it. Both planners, the metrics and the problem validation use these definitions.

Integrands take quantities with one row per joint (or CP coordinate) and one column per sample,
as NumPy arrays or CasADi expressions alike, and return one value per sample.
"""

from __future__ import annotations

from collections.abc import Mapping

OBJECTIVES = ("torque", "energy", "v_squared", "duration", "gamma_margin")
"""Names of the objective terms (``optimizer.objective``)."""

MEANING = {
    "torque": "integral of tau1^2 + tau2^2 dt [N^2 m^2 s]",
    "energy": "integral of |tau1 q1dot| + |tau2 q2dot| dt [J]",
    "v_squared": "integral of |p''''|^2 dt, the CP's fourth derivative [m^2/s^7]",
    "duration": "the motion's duration T [s]",
    "gamma_margin": "minus the smallest |gamma| kept along the plan [m/s^2]",
}

LEAST_SQUARES = frozenset({"torque", "v_squared"})
"""Terms that are integrals of squares (a Gauss-Newton Hessian applies to them)."""
LINEAR = frozenset({"duration", "gamma_margin"})
"""Terms linear in the decision variables (no curvature of their own)."""

COLLOCATION_OBJECTIVES = ("torque", "duration", "gamma_margin")
"""Terms the collocation peer transcribes; v is the CP's fourth derivative, which collocation
does not have, and |power| under piecewise-constant torques has no smooth transcription."""


def weights(objective: str | Mapping[str, float]) -> dict[str, float]:
    """The objective's terms with their weights (a single name has weight 1; zero weights
    are dropped)."""
    if isinstance(objective, str):
        return {objective: 1.0}
    return {name: float(w) for name, w in objective.items() if w}


def default_hessian(objective: str | Mapping[str, float]) -> str:
    """The flat optimizer's Hessian for an objective when the file does not choose one, by
    measurement (docs/problems.md, ``optimizer.solver.hessian``): ``gauss_newton`` when
    ``torque`` and ``energy`` are absent (v_squared is linear in the coefficients, so its
    Gauss-Newton curvature is exact), ``exact`` otherwise (with the gravity torques the
    torque objective is a large-residual least-squares problem: Gauss-Newton stalls)."""
    return "exact" if {"torque", "energy"} & set(weights(objective)) else "gauss_newton"


def squared_norm(rows):
    """Per sample ``rows[0]^2 + rows[1]^2`` (torques: the ``torque`` integrand; CP fourth
    derivatives: the ``v_squared`` integrand)."""
    return rows[0, :] ** 2 + rows[1, :] ** 2


def abs_power(tau, qdot):
    """Per sample ``|tau1 q1dot| + |tau2 q2dot|`` [W], the ``energy`` integrand."""
    return abs(tau[0, :] * qdot[0, :]) + abs(tau[1, :] * qdot[1, :])


__all__ = [
    "COLLOCATION_OBJECTIVES",
    "LEAST_SQUARES",
    "LINEAR",
    "MEANING",
    "OBJECTIVES",
    "abs_power",
    "default_hessian",
    "squared_norm",
    "weights",
]
