"""A re-plan's NLP condensed to its core variables and solved by a dense SQP.

The flat NLP lifts every sample's CP derivatives into its decision vector (hundreds of
variables); they are functions of the core variables (the phases' free coefficients and the
freed node values, 13-30 of them: :attr:`~cpopt.flatopt.transcribe.FlatNLP.lift`). A re-plan
starts next to its optimum, where Ipopt's interior point still takes 10-15 iterations at
4-5 ms each on the lifted KKT system. Condensed to the core variables, one iteration is one
evaluation of the lifted NLP's value, gradient, Jacobian and Hessian chained through the
lift's Jacobian (about 1.3 ms) and one dense QP of 13-30 variables (DAQP, a dense active-set
solver: a fraction of a millisecond; qpOASES was as fast but prints its licence on creation,
CasADi's qrqp failed on the first QP), and an SQP started next to its optimum converges in a
few (measured on a re-plan of transfer_min_torque at 0.3 s from the plan's own state: six
iterations, 11 ms, Ipopt's optimum to 1e-9 relative; Ipopt on the lifted NLP, ten iterations,
40 ms).

Rows and objective are scaled as Ipopt scales them (:class:`Scaled`). Each iteration solves
the QP with the exact Hessian of the Lagrangian at the previous QP's multipliers, condensed
through the lift (its own curvature included), made positive definite on the active rows'
face (:func:`convexified`) and damped where steps keep being cut (:data:`DAMPING`); a line
search on the l1 merit function f + nu sum(violations), with a second-order correction of a
rejected whole step (:func:`corrected`), keeps the steps honest far from the optimum. It
stops when the rows hold within :data:`FEASIBILITY` and the QP predicts less than
:data:`DECREASE_TOLERANCE` of the objective, or at its iteration limit or deadline (before an
iteration as long as the mean one so far would overrun it), returning an
:class:`~cpopt.runtime.solver.NlpRun` as Ipopt's runs are returned, so the re-plan's
unpacking, certificate and fallback are the same. Stopped before it converged, it returns its
best iterate that keeps every row, status ``feasible`` (an anytime answer: the boundary
conditions are eliminated, so every iterate starts at the measured state and ends at the
goal, and one that keeps the rows is a plan within the limits; measured on
transfer_min_torque's re-plan loop at a 20-ms deadline, 81 of 88 re-plans were followed that
way, against none solved by Ipopt or by this SQP run to convergence), else its last
iterate.

Measured in the re-plan loop (benchmarks/replan_loop.py, ``--method sqp``, one round, the
other core busy): swing_up_holding 89.2 % solved (66 of 74; Ipopt, two rounds idle, 93.9 %),
median 114 ms; transfer_min_torque 41 of 44 (Ipopt 90.9 %). An iteration costs 3-8 ms (the
lifted NLP's functions through CasADi's MX virtual machine, 1.3-3.6 ms of it), so Ipopt
stays the re-plan's default and this solver is ``method="sqp"``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..runtime.solver import NlpRun

FEASIBILITY = 1e-6
"""Largest violation of a row or bound [the row's unit] of a solved re-plan (Ipopt's re-plan
tolerance, :data:`cpopt.flatopt.replan.SOLVER_SETTINGS`)."""
DECREASE_TOLERANCE = 1e-8
"""A step whose predicted decrease of the objective (the QP's) is below this fraction of the
objective (plus one) ends the iterations at a feasible point. Measured on a re-plan of
transfer_min_torque at 0.3 s: the QP's predicted decreases 3e3, 6e2, 1e2, 4, 9e-3, 7e-5
(the objective 52489.464610 after five steps, Ipopt's optimum 52489.464557)."""
MIN_EIGENVALUE = 1e-12
"""The smallest eigenvalue of the QP's Hessian, in variables scaled by their start's
magnitudes, as a fraction of its largest (a dense QP solver needs it positive definite; a
time-optimal plan's re-plan has a constant objective, its Hessian zero but for this). Scaled,
because the core variables span five orders of magnitude (a node's eta 1.5e4 m/s^3 beside
coefficients of order one): the re-plan above, convexified unscaled, crawled 0.05 a step
along a direction of negative curvature for 30 iterations."""
AUGMENTATION = (10.0, 1e3, 1e5)
"""rho of :func:`convexified`, multiples of the scaled Hessian's most negative eigenvalue,
tried in turn (the more nearly the negative curvature lies along the face, the more it takes;
measured: 10 alone left a re-plan of transfer_min_torque at 0.34 s shifted, crawling 30
iterations)."""
ARMIJO = 1e-4
"""Sufficient decrease of the merit function along a step, a fraction of its predicted one."""
DAMPING = 1e-4
"""The first damping (Levenberg-Marquardt: a multiple of the identity added to the QP's
Hessian in scaled variables), as a fraction of the Hessian's largest scaled diagonal entry;
it grows tenfold after each step the line search cut below :data:`SHORT_STEP` and shrinks
tenfold after each whole step. A step the merit function keeps cutting has a model that is
wrong far out (the rows' curvature, stale multipliers): damping turns it towards the
gradient, which a shorter step along the same direction does not. Measured on the re-plan
loop (benchmarks/replan_loop.py, one round): without damping swing_up_holding solved 51 of
74 re-plans (17 stopped at the iteration limit, their steps cut to 1/256 for twenty
iterations); with it 65 (1e-8: 61; 1e-6: 64), transfer_min_torque 41 of 44."""
SHORT_STEP = 0.125
"""A step cut below this fraction raises the damping."""
GRADIENT_SCALE = 100.0
"""The largest gradient entry a row or the objective is scaled to (Ipopt's
``scaledscaling_max_gradient``)."""
BACKTRACKS = 8
"""Most halvings of a step in the line search (the last one is taken regardless)."""


@dataclass(frozen=True)
class Condensed:
    """A flat NLP on its core variables: the functions one SQP iteration evaluates.

    Attributes
    ----------
    derivatives : casadi.Function
        ``(x, p, lam) -> (f, grad f, g, jac g, hess L)`` on the core variables x, the kept
        rows, with their multipliers lam (one call: the lift and the samples' outputs are
        shared; measured 1.3 ms together, 0.7 + 1.1 ms as two functions).
    values : casadi.Function
        ``(x, p) -> (f, g)``, for the line search.
    rows : numpy.ndarray
        Indices of the lifted NLP's rows that are kept (all but the lifting rows).
    qp : casadi.Function
        The dense QP solver (DAQP) of the condensed sizes.
    """

    derivatives: ca.Function
    values: ca.Function
    rows: np.ndarray
    qp: ca.Function


_CACHE: dict[int, tuple[object, Condensed]] = {}
SETUP_TIMES: dict[int, float] = {}
"""The last measured time [s] of the first derivatives (the scaling) of each condensed NLP (by
``id``, as :func:`condensed` caches them): a run that cannot fit them before its deadline
returns its start (:func:`_start_only`). Measured on swing_up_holding's re-plan loop at a
20-ms deadline: its two-phase NLP's first derivatives take 3-7 ms, and 15 of 148 re-plans
that began them with less time left ended late with no iteration done."""


def condensed(nlp) -> Condensed:
    """The condensed functions of a :class:`~cpopt.flatopt.transcribe.FlatNLP` (built once
    per NLP and kept as long as the NLP is)."""
    hit = _CACHE.get(id(nlp))
    if hit is not None and hit[0] is nlp:
        return hit[1]
    if len(_CACHE) > 32:
        _CACHE.clear()
        SETUP_TIMES.clear()
    made = _condense(nlp)
    _CACHE[id(nlp)] = (nlp, made)
    return made


def _condense(nlp) -> Condensed:
    n = nlp.layout.size
    solver = nlp.solver
    p = ca.MX.sym("p", solver.size_in("p")[0])
    x = ca.MX.sym("x", n)
    lifted = nlp.lift(x, p)
    X = ca.vertcat(x, lifted)
    T = ca.vertcat(ca.MX.eye(n), ca.jacobian(lifted, x))
    rows = np.array([i for i, (name, _) in enumerate(nlp.rows) if not _lifting(name)], int)
    lam = ca.MX.sym("lam", rows.size)
    lam_all = ca.MX(len(nlp.rows), 1)
    kept = rows.tolist()
    lam_all[kept] = lam
    f, grad = solver.get_function("nlp_grad_f")(X, p)
    g, jac = solver.get_function("nlp_jac_g")(X, p)
    # Ipopt reads the upper triangle only, and the samples' blocks are whole: take the triangle
    upper = ca.triu(solver.get_function("nlp_hess_l")(X, p, 1.0, lam_all))
    H = upper + upper.T - ca.diag(ca.diag(upper))
    g_kept, jac_kept = g[kept], jac[kept, :]
    # the lift's own curvature, weighted by the Lagrangian's gradient in the lifted variables
    mu = ca.MX.sym("mu", lifted.numel())
    curvature = ca.Function("lift_curvature", [x, p, mu], [ca.hessian(ca.dot(mu, lifted), x)[0]])
    mu_value = grad[n:] + ca.mtimes(jac_kept[:, n:].T, lam)
    H_condensed = ca.mtimes([T.T, H, T]) + curvature(x, p, mu_value)
    derivatives = ca.Function(
        "condensed_derivatives",
        [x, p, lam],
        [f, ca.mtimes(T.T, grad), g_kept, ca.densify(ca.mtimes(jac_kept, T)),
         ca.densify(H_condensed)],
    )  # fmt: skip
    f_only = solver.get_function("nlp_f")(X, p)
    g_only = solver.get_function("nlp_g")(X, p)[kept]
    values = ca.Function("condensed_values", [x, p], [f_only, g_only])
    qp = ca.conic(
        "replan_qp",
        "daqp",
        {"h": ca.Sparsity.dense(n, n), "a": ca.Sparsity.dense(rows.size, n)},
        {"error_on_fail": False},
    )
    return Condensed(derivatives, values, rows, qp)


def _lifting(name: str) -> bool:
    """True for the rows that tie lifted variables to the core ones (the lift satisfies
    them exactly)."""
    lifting = name.startswith(("lifted samples", "energy slack"))
    return lifting or name.endswith(": CP derivatives")


def convexified(H: np.ndarray, scale: np.ndarray, active: np.ndarray | None = None) -> np.ndarray:
    """H made positive definite for the QP, its curvature on the active rows' face kept.

    In variables scaled by ``scale`` (D = diag(scale)): D H D plus rho a_i a_i' for each
    active row's gradient a_i (rows of ``active``, normalised; rho :data:`AUGMENTATION` times
    the most negative eigenvalue's magnitude, the smallest of them that makes it positive
    definite), when D H D is not positive definite. On the face where the active rows hold,
    a_i' d is fixed, so the added terms are constant there and the QP's minimiser on that face
    is the same (the augmented Lagrangian's convexification): the negative curvature the
    |gamma| >= gamma_min rows bring (reverse convex) is moved off the face. Where that is not
    enough (a new active set, the first iteration), the whole matrix is shifted by the
    identity until its smallest eigenvalue is :data:`MIN_EIGENVALUE` of the largest of D H D
    (relative to D H D's, not the augmented one's: the floor must stay below the flat
    directions' curvature on the face).

    Why not clip the eigenvalues: measured on transfer_min_torque's re-plan loop, the
    Hessian's eigenvalues are -1e6 .. 5e8 (scaled) while on the face they are 0.2 .. 5e8 (the
    compensator input at the goal barely moves the torque); clipped to 1e-8 of the largest,
    the flat direction's curvature became 25 times too large and the input crawled 3 % a
    step for 30 iterations."""
    S = np.outer(scale, scale)
    Hs = 0.5 * (H + H.T) * S
    values = np.linalg.eigvalsh(Hs)
    floor = MIN_EIGENVALUE * max(1e-12, float(np.max(np.abs(values))))
    if values[0] < floor and active is not None and active.size:
        A = active * scale
        A = A / np.maximum(np.linalg.norm(A, axis=1, keepdims=True), 1e-300)
        negative = floor - values[0]
        for rho in AUGMENTATION:
            augmented = Hs + rho * negative * (A.T @ A)
            values = np.linalg.eigvalsh(augmented)
            if values[0] >= floor:
                break
        Hs = augmented
    if values[0] < floor:
        Hs = Hs + (floor - values[0]) * np.eye(len(scale))
    return Hs / S


def violation(g: np.ndarray, lbg: np.ndarray, ubg: np.ndarray) -> np.ndarray:
    """Each row's violation of its bounds (zero where it holds)."""
    return np.maximum(0.0, np.maximum(lbg - g, g - ubg))


@dataclass(frozen=True)
class Scaled:
    """The condensed NLP with its rows and objective scaled as Ipopt scales them (each row and
    the objective by min(1, :data:`GRADIENT_SCALE` / its largest gradient entry at the
    start): rows in different units otherwise give multipliers of 1e4 and more, and the l1
    merit function's penalty, their largest, then shortens every step to a few per cent).

    Attributes
    ----------
    c : Condensed
        The condensed functions.
    p : numpy.ndarray
        The NLP's parameters.
    rows : numpy.ndarray
        Each kept row's scale.
    objective : float
        The objective's scale.
    start : tuple
        (x, multipliers in the NLP's units, outputs of :attr:`Condensed.derivatives`) of the
        evaluation the scaling came from, which the first iteration uses again.
    """

    c: Condensed
    p: np.ndarray
    rows: np.ndarray
    objective: float
    start: tuple

    @classmethod
    def at(cls, c: Condensed, p: np.ndarray, x: np.ndarray, lam: np.ndarray) -> Scaled:
        """The scaling at x (from the gradients there), lam the kept rows' multipliers in the
        NLP's own units (the first iteration's)."""
        outputs = c.derivatives(x, p, lam)
        largest = np.max(np.abs(np.asarray(outputs[3])), axis=1, initial=0.0)
        rows = np.minimum(1.0, GRADIENT_SCALE / np.maximum(largest, 1e-300))
        top = float(np.max(np.abs(np.asarray(outputs[1])), initial=0.0))
        objective = min(1.0, GRADIENT_SCALE / max(top, 1e-300))
        return cls(c, p, rows, objective, (x, lam, outputs))

    def values(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """The scaled objective and rows at x."""
        f, g = self.c.values(x, self.p)
        return self.objective * float(f), self.rows * np.asarray(g).ravel()

    def derivatives(self, x: np.ndarray, lam: np.ndarray) -> tuple:
        """(f, grad f, g, jac g, hess L), scaled, with the scaled rows' multipliers lam."""
        original = self.original(lam)
        x0, lam0, outputs = self.start
        if not (np.array_equal(x, x0) and np.array_equal(original, lam0)):
            outputs = self.c.derivatives(x, self.p, original)
        f, grad, g, J, H = outputs
        return (
            self.objective * float(f),
            self.objective * np.asarray(grad).ravel(),
            self.rows * np.asarray(g).ravel(),
            self.rows[:, None] * np.asarray(J),
            self.objective * np.asarray(H),
        )

    def original(self, lam: np.ndarray) -> np.ndarray:
        """The scaled rows' multipliers in the NLP's own units."""
        return self.rows * lam / self.objective


@dataclass
class _Iterate:
    x: np.ndarray
    f: float
    g: np.ndarray
    lam: np.ndarray
    alpha: float = 1.0  # the step length that reached it (0: the line search failed)

    def infeasibility(self, lbg, ubg) -> float:
        return float(np.sum(violation(self.g, lbg, ubg)))


def solve(
    nlp,
    x0: np.ndarray,
    p: np.ndarray,
    bounds: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    iterations: int,
    deadline: float,
    lam0: np.ndarray | None = None,
) -> NlpRun:
    """Solve a flat NLP condensed to its core variables by SQP.

    Parameters
    ----------
    nlp : FlatNLP
        The re-plan's NLP (built by :func:`cpopt.flatopt.transcribe.build`).
    x0 : numpy.ndarray
        Start (the lifted NLP's vector; its core variables are used).
    p : numpy.ndarray
        The NLP's parameters.
    bounds : tuple of numpy.ndarray
        (lbx, ubx, lbg, ubg) of the lifted NLP.
    iterations : int
        Most SQP iterations.
    deadline : float
        ``time.monotonic()`` instant to stop at (status ``time_limit``).
    lam0 : numpy.ndarray, optional
        Multipliers of the lifted NLP's rows to start from (CasADi's sign; a previous
        re-plan's): the first Hessian is the Lagrangian's at them.

    Returns
    -------
    NlpRun
        The last iterate as the lifted NLP's vector; ``solved`` when it converged.
    """
    tic = time.perf_counter()
    c = condensed(nlp)
    n = nlp.layout.size
    lbx, ubx = bounds[0][:n], bounds[1][:n]
    lbg, ubg = bounds[2][c.rows], bounds[3][c.rows]
    x = np.clip(np.asarray(x0, float)[:n], lbx, ubx)
    lam = np.zeros(c.rows.size) if lam0 is None else np.asarray(lam0, float)[c.rows]
    if time.monotonic() + SETUP_TIMES.get(id(c), 0.0) > deadline:
        return _start_only(nlp, c, p, x, lam, (lbg, ubg), tic)  # no time for the derivatives
    setup = time.perf_counter()
    scaled = Scaled.at(c, p, x, lam)
    SETUP_TIMES[id(c)] = time.perf_counter() - setup
    lbg, ubg = scaled.rows * lbg, scaled.rows * ubg
    f, _, g, _, _ = scaled.derivatives(x, lam * scaled.objective / scaled.rows)
    it = _Iterate(x, f, g, lam * scaled.objective / scaled.rows)
    scale = np.maximum(1.0, np.abs(x))
    nu, status, k, damping = 1.0, "max_iterations", 0, 0.0
    best = _Best()
    for k in range(1, iterations + 1):
        if _out_of_time(deadline, tic, k - 1):
            status, k = "time_limit", k - 1
            break
        step = _step(scaled, it, (lbx, ubx, lbg, ubg), scale, damping)
        if step is None:
            status = "infeasible" if it.infeasibility(lbg, ubg) > FEASIBILITY else "not_converged"
            break
        feasible = _keeps_rows(it.g, (lbg, ubg), scaled.rows)
        if feasible and step.decrease <= DECREASE_TOLERANCE * (1.0 + abs(it.f)):
            status = "solved"  # the point, not the step: it is feasible and optimal
            it.lam = step.lam
            break
        best.offer(it, feasible)
        nu = max(nu, 1.1 * float(np.max(np.abs(step.lam), initial=0.0)))
        it = _line_search(scaled, it, step, nu, (lbg, ubg))
        damping = _damped(damping, it.alpha, step, scale)
    if status != "solved":
        best.offer(it, _keeps_rows(it.g, (lbg, ubg), scaled.rows))
        if best.iterate is not None:
            it, status = best.iterate, "feasible"
    return _run(nlp, scaled, it, status, k, time.perf_counter() - tic)


def _start_only(nlp, c: Condensed, p, x, lam, bounds, tic: float):
    """The run that stops at its start (the deadline passed before the first derivatives,
    which take a few milliseconds): ``feasible`` when the start keeps every row, else
    ``time_limit``; its values alone are evaluated, unscaled."""
    unit = Scaled(c, p, np.ones(c.rows.size), 1.0, (x, lam, None))
    f, g = unit.values(x)
    it = _Iterate(x, f, g, lam)
    keeps = _keeps_rows(g, bounds, 1.0) and math.isfinite(f)
    return _run(nlp, unit, it, "feasible" if keeps else "time_limit", 0, time.perf_counter() - tic)


def _keeps_rows(g: np.ndarray, bounds, row_scale) -> bool:
    """True when the rows g (scaled by ``row_scale``) hold their bounds within
    :data:`FEASIBILITY` in the NLP's own units."""
    return bool(np.max(violation(g, *bounds) / row_scale, initial=0.0) <= FEASIBILITY)


@dataclass
class _Best:
    """The feasible iterate of lowest objective an SQP run has passed (its anytime answer)."""

    iterate: _Iterate | None = None

    def offer(self, it: _Iterate, feasible: bool) -> None:
        if feasible and math.isfinite(it.f) and (self.iterate is None or it.f < self.iterate.f):
            self.iterate = it


def _out_of_time(deadline: float, tic: float, done: int) -> bool:
    """True when another iteration, as long as the mean of the ``done`` ones so far, would end
    after ``deadline`` (a ``time.monotonic()`` instant): a re-plan is stopped before it
    overruns, not after."""
    mean = (time.perf_counter() - tic) / done if done else 0.0
    return time.monotonic() + mean > deadline


def _step(nlp: Scaled, it: _Iterate, bounds, scale: np.ndarray, damping: float = 0.0):
    """The QP's step, its multipliers, the objective's gradient at the iterate and the QP's
    predicted decrease of the objective, or None when the QP fails; ``damping`` adds that
    multiple of D^-2 (D = diag(scale)) to the QP's Hessian (Levenberg-Marquardt)."""
    lbx, ubx, lbg, ubg = bounds
    _, grad, g, J, H = nlp.derivatives(it.x, it.lam)
    if not (np.all(np.isfinite(H)) and np.all(np.isfinite(J))):
        return None
    c = nlp.c
    qp = {"g": grad, "a": J, "lba": lbg - g, "uba": ubg - g, "lbx": lbx - it.x, "ubx": ubx - it.x}
    # the face's curvature kept; where the QP fails on it (ill-conditioned), the plain shift
    for active in (J[np.abs(it.lam) > 0], None):
        convex = convexified(H, scale, active) + np.diag(damping / scale**2)
        out = c.qp(h=convex, **qp)
        if c.qp.stats().get("success", False):
            d = np.asarray(out["x"]).ravel()
            decrease = -float(grad @ d + 0.5 * d @ convex @ d)
            return Step(d, np.asarray(out["lam_a"]).ravel(), grad, decrease, {**qp, "h": convex})
    return None


@dataclass(frozen=True)
class Step:
    """An SQP step: the QP's solution d, multipliers lam, the objective's gradient, the QP's
    predicted decrease of the objective and the QP itself (for a second-order correction)."""

    d: np.ndarray
    lam: np.ndarray
    grad: np.ndarray
    decrease: float
    qp: dict


def corrected(c: Condensed, step: Step, g_trial: np.ndarray, bounds) -> np.ndarray | None:
    """The second-order correction of a rejected step: the QP again, its rows shifted by what
    the rows did at the trial point beyond their linearisation (the Maratos effect: a step
    along curved equality rows, such as |gamma| = gamma_min at a switch, raises their
    violation to second order and the merit function rejects it although it is good)."""
    lbg, ubg = bounds
    shift = g_trial - step.qp["a"] @ step.d
    out = c.qp(**{**step.qp, "lba": lbg - shift, "uba": ubg - shift})
    return np.asarray(out["x"]).ravel() if c.qp.stats().get("success", False) else None


def _damped(damping: float, alpha: float, step: Step, scale: np.ndarray) -> float:
    """The next iteration's damping: raised tenfold (from :data:`DAMPING` of the Hessian's
    scaled diagonal) after a step the line search cut below :data:`SHORT_STEP`, lowered
    tenfold after a whole one."""
    if alpha >= 1.0:
        return damping / 10.0 if damping > 1e-12 else 0.0
    if alpha >= SHORT_STEP:
        return damping
    diagonal = np.abs(np.diag(step.qp["h"])) * scale**2
    return max(10.0 * damping, DAMPING * float(np.max(diagonal)))


def _trial(nlp: Scaled, x: np.ndarray, lam: np.ndarray) -> _Iterate | None:
    """The iterate at x, or None where the objective or a row is not finite."""
    f, g = nlp.values(x)
    if not (math.isfinite(f) and np.all(np.isfinite(g))):
        return None
    return _Iterate(x, f, g, lam)


def _line_search(nlp: Scaled, it: _Iterate, step: Step, nu: float, bounds) -> _Iterate:
    """The iterate after the step: whole, corrected (:func:`corrected`) or shortened until
    the l1 merit function with penalty nu decreases enough (the last halving taken
    regardless)."""
    lbg, ubg = bounds
    merit = it.f + nu * it.infeasibility(lbg, ubg)
    slope = min(float(np.dot(step.grad, step.d)) - nu * it.infeasibility(lbg, ubg), 0.0)

    def accepted(trial, alpha):
        value = trial.f + nu * trial.infeasibility(lbg, ubg)
        return value <= merit + ARMIJO * alpha * slope

    alpha, last = 1.0, None
    for attempt in range(BACKTRACKS + 1):
        lam = it.lam + alpha * (step.lam - it.lam)
        trial = _trial(nlp, it.x + alpha * step.d, lam)
        if trial is not None and accepted(trial, alpha):
            trial.alpha = alpha
            return trial
        if attempt == 0 and trial is not None:
            d2 = corrected(nlp.c, step, trial.g, bounds)
            second = None if d2 is None else _trial(nlp, it.x + d2, step.lam)
            if second is not None and accepted(second, 1.0):
                second.alpha = 1.0
                return second
        last = trial if trial is not None else last
        alpha *= 0.5
    if last is not None:
        last.alpha = 0.0  # not accepted
        return last
    it.alpha = 0.0
    return it


def _run(nlp, scaled: Scaled, it: _Iterate, status: str, iterations: int, seconds: float):
    """The iterate as an :class:`NlpRun` of the lifted NLP."""
    c = scaled.c
    x = np.r_[it.x, np.asarray(nlp.lift(it.x, scaled.p)).ravel()]
    lam_g = np.zeros(len(nlp.rows))
    lam_g[c.rows] = -scaled.original(it.lam)  # NlpRun's sign: positive where a lower bound binds
    words = {
        "solved": "Solve_Succeeded",
        "time_limit": "Maximum_CpuTime_Exceeded",
        "feasible": "SQP_Feasible_Iterate",
    }
    return NlpRun(
        x=x,
        objective=it.f / scaled.objective,
        return_status=words.get(status, f"SQP_{status}"),
        status=status,
        iterations=iterations,
        solve_time_s=seconds,
        lam_g=lam_g,
    )


__all__ = ["Condensed", "condensed", "convexified", "solve", "violation"]
