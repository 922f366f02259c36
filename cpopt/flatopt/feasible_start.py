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

:func:`restored_run` takes the same steps from the nearly feasible iterate of a run cpopt cut
(its iteration cap, the search's deadline) that passed no feasible one: a creeping run can end
so at half the cost of the plans the search has, its rows violated by 1e-5 to 1e-2 (a random
PPR swing-down with four switches: 42402 at its 500th iteration, the one-sign plan 80723).
Moved onto its constraints it is a plan like any other: certified, refined and verified.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ..runtime.solver import STALL_FEASIBLE, NlpRun, bound_violation
from .transcribe import FlatNLP

CURVE_KINDS = ("coefficients", "control_points")
"""The layout's blocks a step moves (see :func:`_curve_mask`)."""
MAX_STEPS = 20
"""Gauss-Newton steps at most (three mended the random RRR transfer's start)."""
INSIDE = 0.02
"""How far inside a violated inequality a step aims, relative to max(1, |bound|)."""
RESTORE_INSIDE = 1e-6
"""How far inside a violated inequality a restoring step aims, relative to max(1, |bound|):
just inside, the iterate moved no further than its rows need."""
RESTORE_STEPS = 8
"""Gauss-Newton steps at most of a restoration."""
RESTORE_GROWTH = 1.1
"""How much a restoration may raise the objective (a factor): a step that fixes a few rows by
a large move of the curves passes near gamma = 0 or the edge of the reach, where the torques
grow without bound (a random PPR swing-down's refinement: 42465 to 7.5e20)."""
RESTORED = "Restored_Iterate_At_"
"""How Ipopt's word of a restored run begins (:func:`restored_run`)."""
RESTORE_TIME = 0.5
"""Seconds a restoration may take past the search's deadline (a run cut there): each step
is one dense least-squares solve of the rows against the curves' coefficients."""
SMALLEST_STEP = 1e-3
"""The Gauss-Newton step length below which the damped steps are tried."""
DAMPING_FIRST = 1e-6
"""The first Levenberg-Marquardt damping, relative to the mean diagonal of J'J."""
DAMPING_GROWTH = 4.0
"""The factor by which the damping grows while a damped step does not lower the violation."""
DAMPING_STEPS = 20
"""Damped steps tried at most (the last damping 3e5 times the mean diagonal: nearly a step
along the gradient of the violation, short)."""


def objective_is_number(nlp: FlatNLP, x: np.ndarray, p: np.ndarray) -> bool:
    """Whether the NLP's objective at x is a finite number."""
    return math.isfinite(float(nlp.solver.get_function("nlp_f")(x, p)))


def evaluable_start(
    nlp: FlatNLP, arguments: dict, deadline: float = math.inf, damped: bool = False
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
    damped : bool
        Also try Levenberg-Marquardt steps where no halved Gauss-Newton step lowers the
        violation (:func:`_directions`; the switch search's patterns: a random PRR transfer's
        three-switch pattern, 3.77 times collocation from the undamped start, solves at 1.033
        from the damped one, where for one-sign runs the starts they mend ran long and failed).

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

    def evaluable(core: np.ndarray, violation: tuple) -> bool:
        return violation[0] == 0 and objective_is_number(nlp, nlp.complete(core, p), p)

    core, _, steps = _walk(nlp, arguments, x0, MAX_STEPS, deadline, evaluable, damped=damped)
    x = nlp.complete(core, p)
    return (x, steps) if objective_is_number(nlp, x, p) else (x0, 0)


def _walk(nlp: FlatNLP, arguments: dict, x, most: int, deadline: float, reached, **options):
    """(core, violation, steps): the core of ``x`` clipped into its bounds, then moved by
    :func:`_step` (``options``: its ``inside``, ``ceiling``, ``damped``) until
    ``reached(core, violation)``, after ``most`` steps, at ``deadline`` (``time.monotonic()``)
    or when no step lowers the violation."""
    p, n = arguments["p"], nlp.layout.size
    lo, hi = np.asarray(arguments["lbx"])[:n], np.asarray(arguments["ubx"])[:n]
    core = np.clip(np.asarray(x, float)[:n], lo, hi)
    violation, lift_jacobian = _violation(nlp, core, p), nlp.lift.jacobian()
    steps = 0
    while steps < most and time.monotonic() < deadline and not reached(core, violation):
        trial = _step(nlp, core, p, lo, hi, violation, lift_jacobian, **options)
        if trial is None:
            break
        core, violation = trial
        steps += 1
    return core, violation, steps


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


def _targets(nlp: FlatNLP, g: np.ndarray, inside: float = INSIDE) -> tuple[np.ndarray, np.ndarray]:
    """(rows a step works on, their targets): the equality rows at their value, and the
    violated inequality rows whose values are numbers ``inside`` (relative) inside their
    bounds."""
    lbg, ubg = nlp.lbg, nlp.ubg
    finite = np.isfinite(g)
    equal = lbg == ubg
    low = finite & ~equal & (g < lbg)
    high = finite & ~equal & (g > ubg)
    target = np.where(equal, lbg, g)
    target[low] = lbg[low] + inside * np.maximum(1.0, np.abs(lbg[low]))
    target[high] = ubg[high] - inside * np.maximum(1.0, np.abs(ubg[high]))
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


def _step(
    nlp: FlatNLP, core, p, lo, hi, violation, lift_jacobian, inside=INSIDE, ceiling=math.inf,
    damped=False,
):  # fmt: skip
    """One step that lowers the violation: the minimum-norm Gauss-Newton step, halved, then
    (``damped``) Levenberg-Marquardt steps ever more damped (:func:`_directions`); the first
    whose trial has fewer rows that are not numbers or, with as many, a lower violation, and
    an objective at most ``ceiling``; None when none does."""
    rows, target = _targets(nlp, violation[2], inside)
    jac = _core_jacobian(nlp, core, p, lift_jacobian)
    rows &= np.isfinite(jac).all(axis=1)
    free = (lo < hi) & _curve_mask(nlp)
    if not rows.any() or not free.any():
        return None
    residual = (target - violation[2])[rows]
    for direction in _directions(jac[np.ix_(rows, free)], residual, damped):
        trial = core.copy()
        trial[free] += direction
        trial = np.clip(trial, lo, hi)
        measured = _violation(nlp, trial, p)
        # evaluable_start's steps (no ceiling) pass through iterates whose objective is NaN
        within = ceiling == math.inf or _objective(nlp, trial, p) <= ceiling
        if measured[:2] < violation[:2] and within:
            return trial, measured
    return None


def _directions(jac: np.ndarray, residual: np.ndarray, damped: bool):
    """The steps :func:`_step` tries, in order: the minimum-norm solution of ``jac d =
    residual`` halved down to :data:`SMALLEST_STEP`, then (``damped``) the damped solutions of
    ``(J'J + lambda I) d = J'r`` with lambda from :data:`DAMPING_FIRST` times J'J's mean
    diagonal up by :data:`DAMPING_GROWTH` (a random RRR swing-down's closed form, out of reach
    by 2.6: each halved Gauss-Newton step raised the summed violation, 34.1, where damped
    steps brought it to 0 in 7 steps with the other sign)."""
    direction = np.linalg.lstsq(jac, residual, rcond=None)[0]
    alpha = 1.0
    while alpha >= SMALLEST_STEP:
        yield alpha * direction
        alpha /= 2
    if not damped:
        return
    normal, gradient = jac.T @ jac, jac.T @ residual
    damping = DAMPING_FIRST * max(float(np.trace(normal)) / len(normal), 1e-300)
    for _ in range(DAMPING_STEPS):
        yield np.linalg.solve(normal + damping * np.eye(len(normal)), gradient)
        damping *= DAMPING_GROWTH


def _objective(nlp: FlatNLP, core: np.ndarray, p: np.ndarray) -> float:
    """The objective at a core, its lifted samples following."""
    return float(nlp.solver.get_function("nlp_f")(nlp.complete(core, p), p))


def largest_violation(nlp: FlatNLP, g: np.ndarray) -> float:
    """The largest violation of ``lbg <= g <= ubg`` (inf when a row is not a number)."""
    return bound_violation(g, nlp.lbg, nlp.ubg)


def restored(
    nlp: FlatNLP, arguments: dict, x: np.ndarray, objective: float, deadline: float
) -> tuple[np.ndarray, float] | None:
    """(x, its objective): ``x`` moved onto the NLP's constraints (violations up to
    :data:`cpopt.runtime.solver.STALL_FEASIBLE`) by the steps of :func:`evaluable_start`
    aiming :data:`RESTORE_INSIDE` inside, its objective at most :data:`RESTORE_GROWTH` times
    ``objective``; None when they do not get there.

    Parameters
    ----------
    nlp : FlatNLP
        The built NLP.
    arguments : dict
        nlpsol's arguments of the run (``p``, ``lbx``, ``ubx``).
    x : numpy.ndarray
        A nearly feasible iterate of the run.
    objective : float
        Its objective as the run measured it (the restored one's is not above
        :data:`RESTORE_GROWTH` times it; at its edge of reach the completed iterate's own
        objective may not be a number).
    deadline : float
        ``time.monotonic()`` past which no further step is taken.
    """
    ceiling = RESTORE_GROWTH * objective

    def feasible(core: np.ndarray, violation: tuple) -> bool:
        return largest_violation(nlp, violation[2]) <= STALL_FEASIBLE

    options = {"inside": RESTORE_INSIDE, "ceiling": ceiling}
    core, violation, _ = _walk(nlp, arguments, x, RESTORE_STEPS, deadline, feasible, **options)
    restored_objective = _objective(nlp, core, arguments["p"])
    if not feasible(core, violation) or not restored_objective <= ceiling:
        return None
    return nlp.complete(core, arguments["p"]), restored_objective


def restored_run(nlp: FlatNLP, arguments: dict, run: NlpRun, deadline: float) -> NlpRun:
    """A run cpopt cut (``max_iterations``, ``time_limit``) that passed no feasible iterate,
    replaced by its nearly feasible iterate with the lowest objective moved onto its
    constraints (:func:`restored`; status ``solved``, Ipopt's word
    ``Restored_Iterate_At_<iteration>``); any other run, or one that is not restored, as it
    is."""
    nearly = nlp.reporter.nearly if nlp.reporter is not None else None
    if run.status not in ("max_iterations", "time_limit") or nearly is None or nearly.x is None:
        return run
    late = max(deadline, time.monotonic() + RESTORE_TIME)
    moved = restored(nlp, arguments, nearly.x, nearly.objective, late)
    if moved is None:
        return run
    x, objective = moved
    word = f"{RESTORED}{nearly.iteration}"
    return replace(run, x=x, objective=objective, status="solved", return_status=word,
                   lam_g=-nearly.lam_g, lam_x=nearly.lam_x)  # fmt: skip
