"""A start the flat NLP can evaluate: Gauss-Newton steps back into the arm's reach.

A fitted or closed-form start can leave the arm's reach (the RRR elbow's cosine past 1) or let
gamma pass through zero inside a phase (its fit to a seed whose crossing it does not follow
exactly). The CP's samples there have no joint motion: the inverse kinematics takes the square
root of a negative number, or the flat inverse map divides by |gamma| = 0. The torques in the
objective are then not numbers and Ipopt stops at iteration 0 with ``Invalid_Number_Detected``
(a random RRR transfer with a via state had no one-sign plan for that reason alone).

:func:`evaluable_start` moves such a start's core variables, before Ipopt sees it, by damped
Gauss-Newton steps of minimum norm: the equality rows are held where they are satisfied, and
the violated inequality rows whose values are numbers (reach, |gamma| >= gamma_min, limits)
are pushed a little inside their bounds. The lifted samples follow the core through the lifts'
Jacobian. A start whose objective is a number is returned unchanged.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .transcribe import FlatNLP

CURVE_KINDS = ("coefficients", "control_points")
"""The layout's blocks a step moves (see :func:`_curve_mask`)."""
MAX_STEPS = 20
"""Gauss-Newton steps at most (three mended the random RRR transfer's start)."""
INSIDE = 0.02
"""How far inside a violated inequality a step aims, relative to max(1, |bound|)."""
SMALLEST_STEP = 1e-3
"""The step length below which a step that does not lower the violation ends the projection."""


def objective_is_number(nlp: FlatNLP, x: np.ndarray, p: np.ndarray) -> bool:
    """Whether the NLP's objective at x is a finite number."""
    return math.isfinite(float(nlp.solver.get_function("nlp_f")(x, p)))


def evaluable_start(
    nlp: FlatNLP, arguments: dict, deadline: float = math.inf
) -> tuple[np.ndarray, int]:
    """The start ``arguments["x0"]``, moved where the objective is a number when it is not.

    Parameters
    ----------
    nlp : FlatNLP
        The built NLP.
    arguments : dict
        nlpsol's arguments (``x0``, ``p``, ``lbx``, ``ubx``).
    deadline : float
        ``time.monotonic()`` past which no further step is taken.

    Returns
    -------
    x0 : numpy.ndarray
        The start (unchanged when its objective is a number, or when no step made it one).
    steps : int
        The Gauss-Newton steps taken (0 when the start was kept).
    """
    x0, p = np.asarray(arguments["x0"], float), arguments["p"]
    if objective_is_number(nlp, x0, p):
        return x0, 0
    n = nlp.layout.size
    lo, hi = np.asarray(arguments["lbx"])[:n], np.asarray(arguments["ubx"])[:n]
    core = np.clip(x0[:n], lo, hi)
    violation = _violation(nlp, core, p)
    steps, lift_jacobian = 0, nlp.lift.jacobian()
    while steps < MAX_STEPS and time.monotonic() < deadline:
        x = nlp.complete(core, p)
        if violation[0] == 0 and objective_is_number(nlp, x, p):
            break
        trial = _step(nlp, core, p, lo, hi, violation, lift_jacobian)
        if trial is None:
            break
        core, violation = trial
        steps += 1
    x = nlp.complete(core, p)
    return (x, steps) if objective_is_number(nlp, x, p) else (x0, 0)


def _violation(nlp: FlatNLP, core: np.ndarray, p: np.ndarray) -> tuple[int, float, np.ndarray]:
    """(rows that are not numbers, the summed violation of the others, g) at a core."""
    g = np.asarray(nlp.constraints(nlp.complete(core, p), p)).ravel()
    finite = np.isfinite(g)
    gf = np.where(finite, g, 0.0)
    equal = nlp.lbg == nlp.ubg
    below = np.maximum(nlp.lbg - gf, 0.0)
    above = np.maximum(gf - nlp.ubg, 0.0)
    total = np.where(equal, np.abs(gf - nlp.lbg), below + above)
    return int((~finite).sum()), float(total[finite].sum()), g


def _targets(nlp: FlatNLP, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows a step works on, their targets): the equality rows at their value, and the
    violated inequality rows whose values are numbers a little inside their bounds."""
    lbg, ubg = nlp.lbg, nlp.ubg
    finite = np.isfinite(g)
    equal = lbg == ubg
    low = finite & ~equal & (g < lbg)
    high = finite & ~equal & (g > ubg)
    target = np.where(equal, lbg, g)
    target[low] = lbg[low] + INSIDE * np.maximum(1.0, np.abs(lbg[low]))
    target[high] = ubg[high] - INSIDE * np.maximum(1.0, np.abs(ubg[high]))
    return finite & (equal | low | high), target


def _core_jacobian(nlp: FlatNLP, core: np.ndarray, p: np.ndarray, lift_jacobian) -> np.ndarray:
    """dg/d(core) with the lifted samples following the core (dense); ``lift_jacobian`` is
    ``nlp.lift.jacobian()``."""
    n = nlp.layout.size
    x = nlp.complete(core, p)
    _, jac_x = nlp.solver.get_function("nlp_jac_g")(x, p)
    jac_x = jac_x.sparse()
    lift = lift_jacobian(core, p, np.zeros(x.size - n))[0].sparse()
    return np.asarray((jac_x[:, :n] + jac_x[:, n:] @ lift).todense())


def _curve_mask(nlp: FlatNLP) -> np.ndarray:
    """The core variables a step moves: the curves' coefficients only. The node values (xi,
    eta, times) stay: the rows are nonlinear in the phase times, and a step in them was
    measured to miss its linear prediction by 1e5 where one in the coefficients hits it."""
    return np.concatenate(
        [np.full(b.size, b.kind in CURVE_KINDS) for b in nlp.layout.blocks]
    ).astype(bool)


def _step(nlp: FlatNLP, core, p, lo, hi, violation, lift_jacobian):
    """One damped minimum-norm Gauss-Newton step, halved until fewer rows are not numbers or,
    with as many, the violation falls; None when no step length does."""
    rows, target = _targets(nlp, violation[2])
    jac = _core_jacobian(nlp, core, p, lift_jacobian)
    rows &= np.isfinite(jac).all(axis=1)
    free = (lo < hi) & _curve_mask(nlp)
    if not rows.any() or not free.any():
        return None
    residual = (target - violation[2])[rows]
    direction = np.linalg.lstsq(jac[np.ix_(rows, free)], residual, rcond=None)[0]
    alpha = 1.0
    while alpha >= SMALLEST_STEP:
        trial = core.copy()
        trial[free] += alpha * direction
        trial = np.clip(trial, lo, hi)
        measured = _violation(nlp, trial, p)
        if measured[:2] < violation[:2]:
            return trial, measured
        alpha /= 2
    return None
