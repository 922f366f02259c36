"""Bounded integration of a system driven by a piecewise-polynomial CP curve, one CasADi call
per step: the verification's simulations (:mod:`cpopt.verify.simulate`).

A step is Gragg's modified midpoint rule with n = 2, 4, 6, 8 substeps, extrapolated to
h -> 0 (the Gragg-Bulirsch-Stoer scheme, order 8; the extrapolation's last correction is the
error estimate), built as one CasADi function of the state, the piece's local time, the step's
length and the piece's coefficients, and evaluated through a zero-copy buffer. Steps end at
every output time and every break of the curve, so no step straddles a join where the CP's
derivatives are less smooth and no dense output is needed; in between, the step size follows
the error estimate as in an embedded Runge-Kutta pair.

Why not scipy's DOP853 (:func:`cpopt.verify.integrate.integrate`, still used for right-hand sides
given as Python callables): importing ``scipy.integrate`` takes 0.3-0.5 s of a fresh
``cpopt solve`` (it imports ``scipy.special``), more than the simulations themselves; and its
steps cross the curve's breaks (measured on ``transfer_min_torque``'s open-loop replay: final
state error 1.4e-7 with DOP853 at rtol 1e-11, 5.6e-11 here; every bundled problem's figures
in docs/benchmarks.md). CasADi's cvodes was measured too: 0.3 s to build one integrator, more than a
whole verification.

The bounds of :mod:`cpopt.verify.integrate` hold with the same meaning: a state leaving
:data:`~cpopt.verify.integrate.STATE_BOUND` or not finite, a step budget, a step that cannot be made
small enough, and the problem's wall-clock budget.
"""

from __future__ import annotations

import itertools
from functools import lru_cache

import casadi as ca
import numpy as np

from ..runtime.budget import check_time
from .integrate import BASE_STEPS, STATE_BOUND, STEPS_PER_SECOND, DivergenceError

SEQUENCE = (2, 4, 6, 8)
"""Substeps of the modified midpoint rule in one step; four give order 8 (20 evaluations)."""
SMALLEST_STEP = 1e-10
"""Shortest step [s] before the integration counts as failed."""


@lru_cache(maxsize=64)
def extrapolated_step(rhs: ca.Function) -> ca.Function:
    """One extrapolated midpoint step of ``rhs``, as a function of one flat vector.

    Parameters
    ----------
    rhs : casadi.Function
        ``(x, lam, h, c, *extra) -> xdot``: the system at local time ``lam`` in [0, 1] of a
        polynomial piece of length ``h`` [s] with coefficients ``c``.

    Returns
    -------
    casadi.Function
        ``v -> [x1; err]`` with ``v = [x; lam0; dlam; h; vec(c); extra...]``: the state after
        the step from ``lam0`` to ``lam0 + dlam`` (``dlam * h`` seconds) and its error
        estimate. An SX right-hand side gives an SX function (twice as fast to evaluate as
        MX call nodes).
    """
    sx = rhs.is_a("SXFunction")
    kind = ca.SX if sx else ca.MX
    if sx:  # common subexpressions out of the right-hand side once, then inlined 20 times:
        # measured on the closed loop, 31 ms to build and 141 us a step, against 204 ms and
        # 118 us with CSE over the whole step, and 14 ms and 282 us as MX call nodes
        inputs = rhs.sx_in()
        rhs = ca.Function(rhs.name(), inputs, rhs.call(inputs), {"cse": True})
    shapes = [rhs.size_in(i) for i in range(rhs.n_in())]
    v = kind.sym("v", sum(r * c for r, c in shapes) + 1)
    x, lam0, dlam, h, *rest = _split(v, [shapes[0], (1, 1), (1, 1), *shapes[2:]])

    def f(state, lam):
        return rhs(state, lam, h, *rest)

    H = dlam * h
    f0 = f(x, lam0)
    table = []
    for n in SEQUENCE:
        before, now = x, x + (H / n) * f0
        for m in range(1, n):
            before, now = now, before + (2 * H / n) * f(now, lam0 + m * dlam / n)
        table.append([0.5 * (before + now + (H / n) * f(now, lam0 + dlam))])
    for j in range(1, len(SEQUENCE)):
        for k in range(1, j + 1):
            ratio = (SEQUENCE[j] / SEQUENCE[j - k]) ** 2
            table[j].append(table[j][k - 1] + (table[j][k - 1] - table[j - 1][k - 1]) / (ratio - 1))
    x1 = table[-1][-1]
    return ca.Function(f"{rhs.name()}_step", [v], [ca.vertcat(x1, x1 - table[-1][-2])])


def _split(v, shapes) -> list:
    parts, start = [], 0
    for rows, cols in shapes:
        parts.append(ca.reshape(v[start : start + rows * cols], rows, cols))
        start += rows * cols
    return parts


def step_of(system: ca.Function) -> ca.Function:
    """The extrapolated step of ``system``: itself when it is one already (one input, e.g. a
    compiled step of :mod:`cpopt.verify.verify_steps`), else :func:`extrapolated_step` of it."""
    return system if system.n_in() == 1 else extrapolated_step(system)


class CurveStepper:
    """Steps of one system along one piecewise-polynomial curve, through a zero-copy buffer.

    Parameters
    ----------
    system : casadi.Function
        ``(x, lam, h, c, *extra) -> xdot`` (see :func:`extrapolated_step`), or its step
        ``v -> [x1; err]`` already built (:func:`step_of`), whose coefficient matrix may have
        more rows than the curve's pieces (they are padded with zeros).
    curve : PiecewisePolynomial
        The curve (``breaks`` [s] and per-piece coefficients in the local time).
    extra : array_like
        The right-hand side's further arguments (gains, the sign of gamma, the arm), fixed.
    """

    def __init__(self, system: ca.Function, curve, *extra) -> None:
        step = step_of(system)
        self.nx = step.size1_out(0) // 2
        self.arg = np.zeros(step.size1_in(0))
        self.out = np.zeros(step.size1_out(0))
        tail = np.concatenate([np.ravel(np.asarray(e, float)) for e in extra]) if extra else []
        self.arg[self.arg.size - len(tail) :] = tail
        self.buffer, self.trigger = step.buffer()
        self.buffer.set_arg(0, memoryview(self.arg))
        self.buffer.set_res(0, memoryview(self.out))
        self.breaks = np.asarray(curve.breaks, float)
        rows = (self.arg.size - self.nx - 3 - len(tail)) // 2
        # column-major, as CasADi stores the rows x 2 coefficient matrix (zeros below a
        # piece's own degree + 1 rows: the same polynomial)
        self.coeffs = [
            np.ravel(_padded(np.asarray(c, float), rows), order="F") for c in curve.coeffs
        ]
        self.piece = -1

    def step(self, x: np.ndarray, k: int, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        """The state at t1 from x at t0 [s], both in piece k, and the error estimate."""
        nx, a = self.nx, self.breaks[k]
        h = self.breaks[k + 1] - a
        self.arg[:nx] = x
        self.arg[nx : nx + 3] = (t0 - a) / h, (t1 - t0) / h, h
        if k != self.piece:
            self.arg[nx + 3 : nx + 3 + self.coeffs[k].size] = self.coeffs[k]
            self.piece = k
        self.trigger()
        return self.out[:nx].copy(), self.out[nx:]


def _padded(c: np.ndarray, rows: int) -> np.ndarray:
    if c.shape[0] > rows:
        raise ValueError(f"a piece of degree {c.shape[0] - 1} in a step for degree {rows - 1}")
    return np.vstack([c, np.zeros((rows - c.shape[0], c.shape[1]))])


def integrate_along(
    system: ca.Function,
    curve,
    x0: np.ndarray,
    samples: int,
    rtol: float,
    atol: float,
    extra: tuple = (),
    steps_per_second: float = STEPS_PER_SECOND,
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate ``system`` along ``curve`` from its start to its end, bounded.

    Parameters
    ----------
    system : casadi.Function
        ``(x, lam, h, c, *extra) -> xdot``, or its extrapolated step (:class:`CurveStepper`).
    curve : PiecewisePolynomial
        The phase's CP curve (``t0``, ``t1``, ``breaks``, ``coeffs``).
    x0 : numpy.ndarray
        The state at ``curve.t0``.
    samples : int
        Equally spaced output times over the curve, ends included.
    rtol, atol : float
        Tolerances of each step's error estimate, per state entry.
    extra : tuple
        Further arguments of the right-hand side.
    steps_per_second : float
        Step budget per second, on top of :data:`~cpopt.verify.integrate.BASE_STEPS`.

    Returns
    -------
    t : numpy.ndarray
        The output times [s].
    x : numpy.ndarray
        The states at those times (samples, n).

    Raises
    ------
    DivergenceError
        When the state leaves :data:`~cpopt.verify.integrate.STATE_BOUND` or is not finite, a step
        cannot meet the tolerance above :data:`SMALLEST_STEP`, or the steps exceed the budget.
    cpopt.runtime.budget.TimeLimitExceeded
        When the problem's wall-clock budget runs out.
    """
    t_eval = np.linspace(curve.t0, curve.t1, samples)
    stepper = CurveStepper(system, curve, *extra)
    inner = stepper.breaks[1:-1]
    # sorted and without repeats (np.union1d would import numpy.ma: 60 ms of a fresh process)
    grid = np.sort(np.concatenate([t_eval, inner[(inner > curve.t0) & (inner < curve.t1)]]))
    grid = grid[np.r_[True, np.diff(grid) > 0]]
    budget = int(BASE_STEPS + steps_per_second * (curve.t1 - curve.t0))
    out = np.empty((samples, len(x0)))
    out[0] = x = np.asarray(x0, float)
    steps, piece, next_output = 0, 0, 1
    h = float(grid[1] - grid[0])
    for a, b in itertools.pairwise(grid):
        while piece < len(stepper.coeffs) - 1 and stepper.breaks[piece + 1] <= a:
            piece += 1
        x, steps, h = _cover(stepper, x, piece, a, b, (rtol, atol), steps, budget, h)
        if next_output < samples and b >= t_eval[next_output]:
            out[next_output] = x
            next_output += 1
    return t_eval, out


def _cover(stepper, x, piece, a, b, tolerances, steps, budget, h):
    """x at b from x at a within one piece, with the step size control of an embedded pair:
    a step of error ratio e (error over tolerance, largest entry) is accepted when e <= 1, and
    the next is h * 0.9 * e^(-1/9), between a fifth and four times this one (order 8).

    Returns the state at b, the steps taken so far and the step size suggested next [s]."""
    rtol, atol = tolerances
    t = a
    while t < b:
        step = min(h, b - t)
        x1, error = stepper.step(x, piece, t, t + step)
        steps += 1
        if steps > budget:
            raise DivergenceError(t, f"more than {budget} integration steps (stiff or diverging)")
        if steps % 16 == 0:
            check_time()
        if not np.all(np.isfinite(x1)) or np.max(np.abs(x1)) > STATE_BOUND:
            if step <= SMALLEST_STEP:
                raise DivergenceError(t, f"the state left |x| <= {STATE_BOUND:g}")
            h = step / 4  # a step too long may overshoot: look closer first
            continue
        ratio = float(np.max(np.abs(error) / (atol + rtol * np.abs(x1))))
        factor = min(4.0, max(0.2, 0.9 * max(ratio, 1e-12) ** (-1 / 9)))
        if ratio > 1:
            if step <= SMALLEST_STEP:
                raise DivergenceError(t, f"a step of {SMALLEST_STEP:g} s misses the tolerance")
            h = step * factor
            continue
        t, x = t + step, x1
        # a step cut short by the grid says nothing against the longer one suggested before
        h = max(h, step * factor) if step < h else step * factor
    return x, steps, h


__all__ = ["SEQUENCE", "CurveStepper", "extrapolated_step", "integrate_along", "step_of"]
