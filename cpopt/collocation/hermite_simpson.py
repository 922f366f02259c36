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
import time

import casadi as ca
import numpy as np

from ..budget import check_stop
from ..dynamics import rk4_step, state_derivative
from ..kinematics import kinematic_functions
from ..nodes import node_names
from ..objectives import weights
from ..plan import Node
from ..problem import Problem
from ..simulate import pose_states
from ..solver import SolverStats, ipopt_options, read_stats
from .joint_plan import JointPlan
from .transcribe import NODE_FIELDS, cold_guess

SUBSTEPS = 8
"""Fine samples per interval, integrated by RK4 from each knot under the interval's torque
(gamma is read at each: the seed's crossings between the knots)."""


class SeedUnsupportedError(ValueError):
    """A problem the lean transcription does not take (free times, objective terms)."""


def _intervals(problem: Problem, count: int) -> tuple[np.ndarray, list[int]]:
    """Knot times over the whole motion and the knot index of every node."""
    times = [n.t for n in problem.nodes]
    knots, index = [times[0]], [0]
    for a, b in itertools.pairwise(times):
        n = max(2, round(count * (b - a) / times[-1]))
        knots += list(np.linspace(a, b, n + 1)[1:])
        index.append(len(knots) - 1)
    return np.array(knots), index


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


def _box(problem: Problem, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the decision vector (6 x (n + 1) states, then 2 x n torques) from the limits."""
    state_lo, state_hi = np.full((6, n + 1), -np.inf), np.full((6, n + 1), np.inf)
    tau_lo, tau_hi = np.full((2, n), -np.inf), np.full((2, n), np.inf)
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


def hermite_simpson(problem: Problem, intervals: int):
    """Solve the problem by Hermite-Simpson collocation without the regularity constraint.

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
    knots, index = _intervals(problem, intervals)
    n = knots.size - 1
    X, M, U = ca.MX.sym("X", 6, n + 1), ca.MX.sym("M", 6, n), ca.MX.sym("U", 2, n)
    h = ca.DM(np.diff(knots)).T
    rhs = state_derivative(problem.arm).map(n)
    f0, f1, fm = rhs(X[:, :-1], U), rhs(X[:, 1:], U), rhs(M, U)
    # Hermite-Simpson: the midpoint state of the cubic through the knots, Simpson's rule
    mid = M - 0.5 * (X[:, :-1] + X[:, 1:]) - ca.repmat(h / 8, 6, 1) * (f0 - f1)
    simpson = X[:, 1:] - X[:, :-1] - ca.repmat(h / 6, 6, 1) * (f0 + 4 * fm + f1)
    g = [ca.vec(mid), ca.vec(simpson)]
    lbg, ubg = [np.zeros(12 * n)], [np.zeros(12 * n)]
    for i, k in enumerate(index):
        rows, lo, hi = _node_rows(problem, i, X[:, k])
        g.append(ca.vertcat(*rows))
        lbg.append(lo)
        ubg.append(hi)
    objective = w["torque"] * ca.sum2(h * ca.sum1(U**2))
    nlp = {"x": ca.vertcat(ca.vec(X), ca.vec(U), ca.vec(M)), "f": objective, "g": ca.vertcat(*g)}
    options = ipopt_options(problem.spec.optimizer.solver, False)
    solver = ca.nlpsol(
        "seed", "ipopt", nlp, {"expand": False, "print_time": False, "ipopt": options}
    )
    q, qd, tau = cold_guess(problem, knots)
    states = np.column_stack([q, qd])
    middle = 0.5 * (states[:-1] + states[1:])
    x0 = np.r_[states.ravel(), tau[:-1].ravel(), middle.ravel()]
    lbx, ubx = _box(problem, n)
    lbx, ubx = np.r_[lbx, np.full(6 * n, -np.inf)], np.r_[ubx, np.full(6 * n, np.inf)]
    built = time.perf_counter()
    solution = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=np.concatenate(lbg), ubg=np.concatenate(ubg))
    solved = time.perf_counter()
    check_stop()
    said, status, iterations = read_stats(solver.stats())
    xs = np.asarray(solution["x"]).ravel()
    states = xs[: 6 * (n + 1)].reshape(n + 1, 6)
    torques = xs[6 * (n + 1) : 6 * (n + 1) + 2 * n].reshape(n, 2)
    plan = _plan(problem, knots, index, states, torques)
    stats = SolverStats(
        iterations=iterations,
        build_time_s=built - tic,
        solve_time_s=solved - built,
        message=f"Ipopt: {said} (Hermite-Simpson, {n} intervals, no gamma constraint)",
        objective=float(solution["f"]),
    )
    return status, plan, stats


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


__all__ = ["SUBSTEPS", "SeedUnsupportedError", "hermite_simpson"]
