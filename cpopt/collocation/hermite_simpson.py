"""A lean direct collocation of the full dynamics (Hermite-Simpson), for the switch search's
seed.

The rockit transcription (:mod:`cpopt.collocation.transcribe`) is the benchmark peer; building
it takes 1.5-2.5 s for 30 intervals (rockit's Python transcription and the expansion of its
Radau collocation equations), ten times its solve. The seed needs less: the same problem,
coarse, without the regularity constraint. Here the joint state x = (q, qd) at the knots and
the interval midpoints and piecewise-constant torques are the decision variables; the
dynamics, one small CasADi function, is mapped over knots and midpoints, and the
Hermite-Simpson conditions (the midpoint of the cubic through the knots, Simpson's rule) tie
them. Unexpanded, the NLP builds in about 0.05 s and Ipopt solves it in 0.2 s (measured on the
benchmark transfer: 12 iterations, the same objective and crossings as rockit's N = 30).

It takes problems whose objective is ``torque`` (others are refused,
:class:`SeedUnsupportedError`, and the caller uses the rockit transcription); freed node times
stay at their guesses: a seed only needs to say roughly where gamma changes sign.
"""

from __future__ import annotations

import itertools
import math
import time

import casadi as ca
import numpy as np

from ..closedform.nodes import node_names
from ..closedform.plan import Node
from ..model.dynamics import rk4_step, state_derivative
from ..model.kinematics import BRANCH_MARGIN, branch_margin, kinematic_functions
from ..model.objectives import weights
from ..problem import Problem
from ..problem.holding import holding_pattern
from ..runtime.budget import check_stop
from ..runtime.solver import SolverStats, ipopt_options, read_stats
from ..verify.simulate import pose_states
from .joint_plan import JointPlan, joint_functions
from .transcribe import NODE_FIELDS, cold_guess, warm_guess

SUBSTEPS = 8
"""Fine samples per interval, integrated by RK4 from each knot under the interval's torque
(gamma is read at each: the seed's crossings between the knots)."""


class SeedUnsupportedError(ValueError):
    """A problem the lean transcription does not take (free times, objective terms)."""


def _intervals(
    problem: Problem, count: int, switches: tuple[float, ...] = ()
) -> tuple[np.ndarray, list[int], np.ndarray]:
    """Knot times over the whole motion, the knot index of every node and the phase of every
    interval (the file's phases split at the ``switches`` [s], which become knots too)."""
    breaks = sorted({n.t for n in problem.nodes} | set(switches))
    knots, phase = [breaks[0]], []
    for j, (a, b) in enumerate(itertools.pairwise(breaks)):
        n = max(2, round(count * (b - a) / breaks[-1]))
        knots += list(np.linspace(a, b, n + 1)[1:])
        phase += [j] * n
    knots = np.array(knots)
    index = [int(np.argmin(np.abs(knots - n.t))) for n in problem.nodes]
    return knots, index, np.array(phase)


def _check(problem: Problem) -> dict:
    w = weights(problem.spec.optimizer.objective)
    if set(w) - {"torque"}:
        raise SeedUnsupportedError(f"objective terms {sorted(set(w) - {'torque'})}")
    return w


def _node_rows(problem: Problem, i: int, x) -> tuple[list, list, list]:
    """Node i's fields at knot state x: expressions with their lower and upper bounds."""
    name = node_names(len(problem.nodes))[i]
    kin = kinematic_functions(problem.arm)
    s = kin["pose"](x[:3])
    sdot = kin["jacobian"](x[:3]) @ x[3:]
    exprs = dict(zip(NODE_FIELDS, [s[0], s[1], s[2], sdot[0], sdot[1], sdot[2]], strict=True))
    rows, lo, hi = [], [], []
    for f in NODE_FIELDS:
        key = f"{name}.{f}"
        bounds = problem.free.get(key, (problem.values[key], problem.values[key]))
        rows.append(exprs[f])
        lo.append(bounds[0])
        hi.append(bounds[1])
    return rows, lo, hi


def _box(problem: Problem, n: int, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the decision vector (6 x (n + 1) states, then 2 x ``count`` torques) from the
    limits."""
    state_lo, state_hi = np.full((6, n + 1), -np.inf), np.full((6, n + 1), np.inf)
    tau_lo, tau_hi = np.full((2, count), -np.inf), np.full((2, count), np.inf)
    for limit in problem.limits:
        lo, hi = limit.bounds()
        if limit.quantity == "tau":
            tau_lo[limit.joint], tau_hi[limit.joint] = lo, hi
        else:
            row = limit.joint + (3 if limit.quantity == "qd" else 0)
            state_lo[row], state_hi[row] = lo, hi
    lower = np.r_[state_lo.ravel(order="F"), tau_lo.ravel(order="F")]
    upper = np.r_[state_hi.ravel(order="F"), tau_hi.ravel(order="F")]
    return lower, upper


def _knots_at(knots: np.ndarray, times) -> list[int]:
    """The knot index of each of ``times`` [s]."""
    return [int(np.argmin(np.abs(knots - t))) for t in times]


class Torques:
    """The transcription's torques: constant over each interval (``linear`` False: the
    unconstrained seed, as it always was), or linear between the interval's ends and
    continuous at the knots but at ``steps`` (knot indices: a patterned seed's switches, where
    the flat plan's xi reset steps the torque). A seed with continuous torques has a
    continuous gamma, which the flat plan's C2 CP can follow; under piecewise-constant torques
    gamma steps by several m/s^2 at every knot and a flat solve started from its fit began at
    1e4 times the seed's objective."""

    def __init__(self, n: int, linear: bool, steps: list[int]) -> None:
        self.linear = linear
        self.count = 2 * n if linear else n  # torque vectors (2,) among the variables
        values = ca.MX.sym("U", 2, self.count)
        self.variables = ca.vec(values)
        self.joins = ca.MX(0, 1)
        if not linear:
            self.start = self.middle = self.end = values
            return
        self.start, self.end = values[:, :n], values[:, n:]
        self.middle = 0.5 * (self.start + self.end)
        inner = [k for k in range(1, n) if k not in set(steps)]
        if inner:
            self.joins = ca.vec(self.end[:, [k - 1 for k in inner]] - self.start[:, inner])

    def integral(self, h):
        """The integral of |tau|^2 over the motion (Simpson's rule, exact for linear torques);
        ``h`` the intervals' lengths (1 x n) [s]."""
        if not self.linear:
            return ca.sum2(h * ca.sum1(self.start**2))
        ends = ca.sum1(self.start**2) + 4 * ca.sum1(self.middle**2) + ca.sum1(self.end**2)
        return ca.sum2(h / 6 * ends)

    def guess(self, tau: np.ndarray) -> np.ndarray:
        """The torques' part of the initial guess from torques at the knots (n + 1, 2)."""
        return tau[:-1].ravel() if not self.linear else np.r_[tau[:-1].ravel(), tau[1:].ravel()]


def _gamma_rows(problem: Problem, X, M, torque, sigma: np.ndarray, at_switch, ceiling) -> tuple:
    """sigma gamma >= gamma_min at both knots and the midpoint of every interval, each under
    the interval's own torques (:class:`Torques`; gamma steps with the torque at a switch, as
    a xi reset makes it step in the flat plan); at the knots ``at_switch`` (a boolean per knot) also
    ``sigma gamma <= ceiling`` on both sides. Returns the rows, their lower and upper
    bounds."""
    n = sigma.size
    gamma = joint_functions(problem.arm).map(n)
    s = ca.DM(sigma).T
    rows = [
        s * gamma(X[:3, :-1], X[3:, :-1], torque.start)[1],
        s * gamma(M[:3, :], M[3:, :], torque.middle)[1],
        s * gamma(X[:3, 1:], X[3:, 1:], torque.end)[1],
    ]
    gamma_min = problem.spec.optimizer.gamma_min
    upper = np.full((3, n), np.inf)
    upper[0, at_switch[:-1]] = upper[2, at_switch[1:]] = ceiling
    lower = np.full(3 * n, gamma_min)
    return [ca.vec(ca.vertcat(*rows))], [lower], [upper.ravel(order="F")]


def _held_rows(problem: Problem, X, torque: Torques, held: tuple[bool, bool]) -> tuple:
    """At a held rest end (``held``: the start's and the goal's, :func:`cpopt.problem.holding.
    holding_pattern`) the actuated joints' accelerations are zero: the torque there is the
    holding torque, as the flat plan's xi = 0 with the base still makes it. Without these rows a
    patterned seed of a random RRR swing-up ended at gamma = 2.5 m/s^2 where its flat plan must
    end at g0, and the fit of its last phase swung gamma through zero (link 3 turned by 3
    rad). Returns the rows, their lower and upper bounds."""
    rhs = state_derivative(problem.arm)
    rows = []
    if held[0]:
        rows.append(rhs(X[:, 0], torque.start[:, 0])[3:5])
    if held[1]:
        rows.append(rhs(X[:, -1], torque.end[:, -1])[3:5])
    zeros = np.zeros(2 * len(rows))
    return [ca.vertcat(*rows)] if rows else [], [zeros] if rows else [], [zeros] if rows else []


def _pattern_rows(problem: Problem, X, M, torque, signs, phase, steps, ceiling) -> tuple:
    """A pattern's rows: ``sign * gamma >= gamma_min`` per interval (``phase``: each interval's
    piece of ``signs``), the ``ceiling`` at the switches' knots ``steps`` when given
    (:func:`_gamma_rows`), and the held rest ends (:func:`_held_rows`). Returns the rows, their
    lower and upper bounds."""
    at_switch = np.zeros(X.shape[1], bool)
    at_switch[steps] = ceiling is not None
    sigma = np.asarray(signs, float)[phase]
    rows, lower, upper = _gamma_rows(problem, X, M, torque, sigma, at_switch, ceiling)
    held = holding_pattern(problem, tuple(int(s) for s in signs))
    ends = _held_rows(problem, X, torque, (held[0], held[-1]))
    return rows + ends[0], lower + ends[1], upper + ends[2]


def _collocation_rows(problem: Problem, X, M, torque, h, index, branch: float) -> tuple:
    """The Hermite-Simpson conditions (the midpoint state of the cubic through the knots,
    Simpson's rule), the torques' joins, the nodes' fields and the arm's branch: the rows, their
    lower and upper bounds."""
    n = h.numel()
    rhs = state_derivative(problem.arm).map(n)
    f0, f1, fm = rhs(X[:, :-1], torque.start), rhs(X[:, 1:], torque.end), rhs(M, torque.middle)
    mid = M - 0.5 * (X[:, :-1] + X[:, 1:]) - ca.repmat(h / 8, 6, 1) * (f0 - f1)
    simpson = X[:, 1:] - X[:, :-1] - ca.repmat(h / 6, 6, 1) * (f0 + 4 * fm + f1)
    g = [ca.vec(mid), ca.vec(simpson), torque.joins]
    lbg, ubg = [np.zeros(12 * n + torque.joins.numel())], [np.zeros(12 * n + torque.joins.numel())]
    for i, k in enumerate(index):
        rows, lo, hi = _node_rows(problem, i, X[:, k])
        g.append(ca.vertcat(*rows))
        lbg.append(lo)
        ubg.append(hi)
    edge = branch_margin(problem.arm, ca.horzcat(X, M)[:3, :], branch)  # knots, midpoints
    if edge is not None:
        g.append(edge.T)
        lbg.append(np.zeros(2 * n + 1))
        ubg.append(np.full(2 * n + 1, np.inf))
    return g, lbg, ubg


def _ipopt(problem: Problem, limit: int | None, deadline: float) -> dict:
    """Ipopt's options: the file's, at most ``limit`` iterations, stopped at ``deadline``
    (``time.monotonic()``)."""
    options = ipopt_options(problem.spec.optimizer.solver, False)
    if limit is not None:
        options["max_iter"] = min(limit, options["max_iter"])
    if math.isfinite(deadline):
        left = max(deadline - time.monotonic(), 1e-3)
        options["max_wall_time"] = min(left, options.get("max_wall_time") or math.inf)
    return options


def hermite_simpson(
    problem: Problem,
    intervals: int,
    pattern=None,
    guess=None,
    limit: int | None = None,
    switch_ceiling: float | None = None,
    branch: float = BRANCH_MARGIN,
    deadline: float = math.inf,
):
    """Solve the problem by Hermite-Simpson collocation, without the regularity constraint or
    with a pattern of signs of gamma.

    Parameters
    ----------
    problem : Problem
        The problem (objective ``torque``).
    intervals : int
        Collocation intervals over the motion.
    pattern : (switch times [s], signs), optional
        Where gamma changes sign and its sign on each piece between the file's nodes and these
        times: ``sign * gamma >= gamma_min`` is then imposed, the torque free to step at a
        switch (the flat plan's xi reset). None: no regularity constraint.
    guess : Trajectory, optional
        The initial guess (joint motion and torques; linear between its samples); the cold
        guess between the nodes when None.
    limit : int, optional
        Most Ipopt iterations (the file's ``optimizer.solver.max_iter`` when None).
    switch_ceiling : float, optional
        With a pattern: ``sign * gamma <= switch_ceiling`` [m/s^2] on both sides of every
        switch too (a smooth-torque flat plan switches at the margin).
    branch : float
        How far from the edge of the arm's branch the plan keeps
        (:func:`cpopt.kinematics.branch_margin`).
    deadline : float
        ``time.monotonic()`` by which Ipopt stops (its wall-time limit), whatever it has.

    Returns
    -------
    status : str
        cpopt's status of the Ipopt solve.
    plan : JointPlan
        The plan (its best iterate when the solve failed), ``fine`` at :data:`SUBSTEPS`
        samples per interval.
    stats : SolverStats
        Iterations, build and solve time [s], objective.

    Raises
    ------
    SeedUnsupportedError
        For objective terms other than torque.
    """
    w = _check(problem)
    tic = time.perf_counter()
    switches, signs = pattern if pattern is not None else ((), None)
    knots, index, phase = _intervals(problem, intervals, switches)
    n = knots.size - 1
    steps = _knots_at(knots, switches)
    torque = Torques(n, linear=signs is not None, steps=steps)
    X, M = ca.MX.sym("X", 6, n + 1), ca.MX.sym("M", 6, n)
    nlp, lbg, ubg = _nlp(problem, X, M, knots, index, torque, branch, w["torque"])
    if signs is not None:
        rows, lower, upper = _pattern_rows(
            problem, X, M, torque, signs, phase, steps, switch_ceiling
        )
        nlp["g"], lbg, ubg = ca.vertcat(nlp["g"], *rows), lbg + lower, ubg + upper
    options = {"expand": False, "print_time": False}
    solver = ca.nlpsol("seed", "ipopt", nlp, {**options, "ipopt": _ipopt(problem, limit, deadline)})
    x0, lbx, ubx = _start(problem, knots, torque, guess)
    built = time.perf_counter()
    solution = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=np.concatenate(lbg), ubg=np.concatenate(ubg))
    solved = time.perf_counter()
    check_stop()
    status, stats = _report(solver, solution, n, signs, (tic, built, solved))
    plan = _read_plan(problem, knots, index, torque, np.asarray(solution["x"]).ravel())
    return status, plan, stats


def _report(solver, solution, n: int, signs, times: tuple) -> tuple:
    """(cpopt's status, SolverStats) of a solve of ``n`` intervals; ``times``: the
    ``time.perf_counter()`` at its start, once built and once solved [s]."""
    said, status, iterations = read_stats(solver.stats())
    what = "no gamma constraint" if signs is None else f"signs of gamma {tuple(signs)}"
    tic, built, solved = times
    stats = SolverStats(
        iterations=iterations,
        build_time_s=built - tic,
        solve_time_s=solved - built,
        message=f"Ipopt: {said} (Hermite-Simpson, {n} intervals, {what})",
        objective=float(solution["f"]),
    )
    return status, stats


def _nlp(problem: Problem, X, M, knots: np.ndarray, index, torque: Torques, branch, weight):
    """The NLP without a pattern, for nlpsol: states X at the knots and M at the midpoints, the
    torques, the collocation, limit and branch rows (:func:`_collocation_rows`), ``weight``
    times the torque integral; and the rows' bounds."""
    h = ca.DM(np.diff(knots)).T
    g, lbg, ubg = _collocation_rows(problem, X, M, torque, h, index, branch)
    nlp = {
        "x": ca.vertcat(ca.vec(X), torque.variables, ca.vec(M)),
        "f": weight * torque.integral(h),
        "g": ca.vertcat(*g),
    }
    return nlp, lbg, ubg


def _start(problem: Problem, knots: np.ndarray, torque: Torques, guess):
    """The initial vector and the variables' bounds: the guess (cold between the nodes when
    None) at the knots, the midpoints' states halfway, the torques per :class:`Torques`."""
    n = knots.size - 1
    q, qd, tau = cold_guess(problem, knots) if guess is None else warm_guess(guess, knots)
    states = np.column_stack([q, qd])
    middle = 0.5 * (states[:-1] + states[1:])
    x0 = np.r_[states.ravel(), torque.guess(tau), middle.ravel()]
    lbx, ubx = _box(problem, n, torque.count)
    lbx, ubx = np.r_[lbx, np.full(6 * n, -np.inf)], np.r_[ubx, np.full(6 * n, np.inf)]
    return x0, lbx, ubx


def _read_plan(problem: Problem, knots, index, torque: Torques, xs: np.ndarray) -> JointPlan:
    """The JointPlan of a solution vector ``xs`` (knot states, torques, midpoint states)."""
    n = knots.size - 1
    states = xs[: 6 * (n + 1)].reshape(n + 1, 6)
    values = xs[6 * (n + 1) : 6 * (n + 1) + 2 * torque.count].reshape(torque.count, 2)
    return (_linear_plan if torque.linear else _plan)(problem, knots, index, states, values)


def _plan(problem: Problem, knots, index, states, torques) -> JointPlan:
    """The JointPlan of a solution, fine samples at RK4 substeps from each knot's state under
    the interval's torque (the seed reads gamma there, between the knots)."""
    n = knots.size - 1
    step = rk4_step(problem.arm, SUBSTEPS).map(n)
    _, inner = step(states[:-1].T, torques.T, ca.DM(np.diff(knots)).T)
    inner = np.asarray(inner).T.reshape(n * SUBSTEPS, 6)
    fraction = np.arange(SUBSTEPS) / SUBSTEPS
    t = (knots[:-1, None] + np.diff(knots)[:, None] * fraction).ravel()
    fine_x = np.vstack([inner, states[-1]])
    fine_tau = np.vstack([np.repeat(torques, SUBSTEPS, axis=0), torques[-1]])
    return _joint_plan(problem, knots, index, states, torques, (t, fine_x, fine_tau))


def _joint_plan(problem: Problem, knots, index, states, torques, fine) -> JointPlan:
    """The JointPlan of knot ``states``, interval ``torques`` and ``fine`` samples (times
    without the last knot, states and torques with it)."""
    t, fine_x, fine_tau = fine
    reached = pose_states(problem.arm, states)
    nodes = [Node(float(knots[k]), *reached[k], 0.0, 0.0) for k in index]
    return JointPlan(
        arm=problem.arm,
        nodes=tuple(nodes),
        knots=knots,
        q=states[:, :3],
        qd=states[:, 3:],
        tau=torques,
        fine={"t": np.r_[t, knots[-1]], "q": fine_x[:, :3], "qd": fine_x[:, 3:], "tau": fine_tau},
        sigma=0,
    )


def _linear_plan(problem: Problem, knots, index, states, values) -> JointPlan:
    """The JointPlan of a solution with linear torques (``values``: each interval's start
    torques, then its end torques), fine samples at :data:`SUBSTEPS` per interval on the
    cubic Hermite interpolants of q (from q, qd) and qd (from qd, qdd) and the linear torque."""
    n = knots.size - 1
    start, end = values[:n], values[n:]
    rhs = state_derivative(problem.arm).map(n)
    h = np.diff(knots)[:, None, None]
    x0, x1 = states[:-1], states[1:]
    d0 = np.asarray(rhs(x0.T, start.T)).T  # (qd, qdd) at each interval's start
    d1 = np.asarray(rhs(x1.T, end.T)).T
    s = (np.arange(SUBSTEPS) / SUBSTEPS)[None, :, None]
    h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
    h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
    fine_x = (
        h00 * x0[:, None] + h10 * h * d0[:, None] + h01 * x1[:, None] + h11 * h * d1[:, None]
    ).reshape(n * SUBSTEPS, 6)
    fine_tau = ((1 - s) * start[:, None] + s * end[:, None]).reshape(n * SUBSTEPS, 2)
    t = (knots[:-1, None] + np.diff(knots)[:, None] * s[..., 0]).ravel()
    fine = (t, np.vstack([fine_x, states[-1]]), np.vstack([fine_tau, end[-1]]))
    return _joint_plan(problem, knots, index, states, 0.5 * (start + end), fine)


__all__ = ["SUBSTEPS", "SeedUnsupportedError", "Torques", "hermite_simpson"]
