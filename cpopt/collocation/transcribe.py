"""Direct collocation of the arm's full dynamics with rockit: one stage per phase, joint
positions and velocities as states, the two actuated torques as piecewise-constant controls.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..closedform.nodes import MIN_PHASE, node_names
from ..closedform.plan import Node
from ..closedform.trajectory import sample
from ..model import flat
from ..model.dynamics import holding_torque
from ..model.kinematics import branch_margin, joint_state, kinematic_functions
from ..model.objectives import squared_norm, weights
from ..problem import Problem
from ..runtime import progress
from ..runtime.solver import fatrop_options, ipopt_options
from ..verify.simulate import pose_states
from .joint_plan import REFINE, JointPlan, joint_functions

RUN_LABEL = "direct collocation"
"""The label of a collocation solve in progress lines (``iteration 12 (direct collocation)``)."""

NODE_FIELDS = ("x", "y", "theta_deg", "xdot", "ydot", "thetadot_deg")
"""Node values collocation imposes (in the file's units; xi and eta have no meaning here)."""


def cold_guess(problem: Problem, t: np.ndarray) -> tuple[np.ndarray, ...]:
    """Smooth-step joint motion between the nodes' joint states; the holding torques."""
    arm = problem.arm
    states = [joint_state(arm, n.state()) for n in problem.nodes]
    times = [n.t for n in problem.nodes]
    q = np.zeros((t.size, 3))
    qd = np.zeros((t.size, 3))
    for k in range(len(times) - 1):
        h = times[k + 1] - times[k]
        sel = (t >= times[k]) & (t <= times[k + 1])
        s = (t[sel] - times[k]) / h
        step, rate = s**3 * (10 - 15 * s + 6 * s**2), 30 * s**2 * (1 - s) ** 2 / h
        dq = states[k + 1][0] - states[k][0]
        q[sel] = states[k][0] + np.outer(step, dq)
        qd[sel] = np.outer(rate, dq)
    tau = np.array([holding_torque(arm, qi) for qi in q])
    return q, qd, tau


def warm_guess(traj, t: np.ndarray) -> tuple[np.ndarray, ...]:
    """A sampled plan's joint motion and torques at times t (linear between its samples)."""
    keep = np.r_[np.diff(traj.t) > 0, True]
    tt = traj.t[keep]

    def at(a):
        return np.column_stack([np.interp(t, tt, a[keep, i]) for i in range(a.shape[1])])

    return at(traj.q), at(traj.qd), at(traj.tau)


def _sign(problem: Problem, warm) -> int:
    choice = (problem.spec.optimizer.gamma_sign or ["auto"])[0]
    if choice != "auto":
        return 1 if choice == "positive" else -1
    if warm is not None:
        return int(warm.phases[0].sigma)
    start = problem.nodes[0]
    return 1 if flat.gamma(start.state(), problem.arm.K, problem.arm.gravity) > 0 else -1


@dataclass
class Stage:
    """One phase of the transcription: the rockit stage, its states and controls."""

    stage: object
    q: object
    qd: object
    tau: object
    intervals: int


def _limits(problem: Problem, st: Stage) -> None:
    """The file's limits and the arm's branch (:func:`cpopt.kinematics.branch_margin`)."""
    branch = branch_margin(problem.arm, st.q)
    if branch is not None:
        st.stage.subject_to(branch >= 0)
    quantities = {"tau": st.tau, "q": st.q, "qd": st.qd}
    for limit in problem.limits:
        lo, hi = limit.bounds()
        st.stage.subject_to(lo <= (quantities[limit.quantity][limit.joint] <= hi))


def _bounded(ocp, expr, lo: float, hi: float) -> None:
    """lo <= expr <= hi, each side only where it is finite."""
    if np.isfinite(lo):
        ocp.subject_to(expr >= lo)
    if np.isfinite(hi):
        ocp.subject_to(expr <= hi)


def _node_constraints(ocp, problem: Problem, index: int, q, qd) -> None:
    """Fixed node fields by equality, freed ones within their bounds (q, qd at the node)."""
    name = node_names(len(problem.nodes))[index]
    kin = kinematic_functions(problem.arm)
    s = kin["pose"](q)
    sdot = kin["jacobian"](q) @ qd
    expr = dict(zip(NODE_FIELDS, [s[0], s[1], s[2], sdot[0], sdot[1], sdot[2]], strict=True))
    for f in NODE_FIELDS:
        key = f"{name}.{f}"
        if key in problem.free:
            _bounded(ocp, expr[f], *problem.free[key])
        else:
            ocp.subject_to(expr[f] == problem.values[key])


def _time_names(problem: Problem) -> list[str]:
    """The names of the phases' end times: ``via[i].t`` and ``duration``."""
    return [*(f"via[{i}].t" for i in range(len(problem.nodes) - 2)), "duration"]


def _new_stage(ocp, problem: Problem, k: int, intervals: int, free_times: bool) -> Stage:
    """Phase k's stage: states q, qd, controls tau, the full dynamics and the method."""
    from rockit import DirectCollocation, FreeTime, MultipleShooting

    col = problem.spec.collocation
    times = [n.t for n in problem.nodes]
    h = times[k + 1] - times[k]
    n_k = max(2, round(intervals * h / times[-1]))
    if col.solver == "fatrop":
        stage = ocp  # Fatrop's structure detection needs one stage: the Ocp itself
    elif free_times:
        stage = ocp.stage(t0=FreeTime(times[k]), T=FreeTime(h))
    else:
        stage = ocp.stage(t0=times[k], T=h)
    q, qd, tau = stage.state(3), stage.state(3), stage.control(2)
    qdd = joint_functions(problem.arm)(q, qd, tau)[0]
    stage.set_der(q, qd)
    stage.set_der(qd, qdd)
    if col.method == "collocation":
        stage.method(DirectCollocation(N=n_k, degree=col.degree, scheme="radau"))
    else:
        stage.method(MultipleShooting(N=n_k, M=col.steps, intg="rk"))
    return Stage(stage, q, qd, tau, n_k)


def _path_constraints(problem: Problem, st: Stage, gamma_constraint: bool, sign: int, margin):
    """Along the stage: the sign of gamma (and the margin variable), limits, phase length."""
    gamma = joint_functions(problem.arm)(st.q, st.qd, st.tau)[1]
    # gamma depends on the control, which Fatrop's last node does not have
    where = {"include_last": False} if problem.spec.collocation.solver == "fatrop" else {}
    if gamma_constraint:
        st.stage.subject_to(sign * gamma >= problem.spec.optimizer.gamma_min, **where)
    if margin is not None:
        st.stage.subject_to(sign * gamma >= margin, **where)
    _limits(problem, st)


def _set_guess(st: Stage, k: int, times: list, guess) -> None:
    # rockit's numeric-matrix path for state guesses is broken (0.6.7): give functions of t
    grid = np.linspace(times[k], times[k + 1], 4 * st.intervals + 1)
    for var, values in zip((st.q, st.qd, st.tau), guess(grid), strict=True):
        table = ca.interpolant(f"guess{k}", "linear", [grid], values.ravel())
        st.stage.set_initial(var, table(st.stage.t))


def _link(ocp, problem: Problem, k: int, st: Stage, previous: Stage | None, free_times: bool):
    """Continuity with the previous stage, node values at both ends, the phase's end time."""
    stage = st.stage
    if previous is None:
        if free_times:
            ocp.subject_to(stage.t0 == 0)
        _node_constraints(ocp, problem, 0, stage.at_t0(st.q), stage.at_t0(st.qd))
    else:
        ocp.subject_to(stage.at_t0(st.q) == previous.stage.at_tf(previous.q))
        ocp.subject_to(stage.at_t0(st.qd) == previous.stage.at_tf(previous.qd))
        if free_times:
            ocp.subject_to(stage.t0 == previous.stage.tf)
    _node_constraints(ocp, problem, k + 1, stage.at_tf(st.q), stage.at_tf(st.qd))
    if free_times:
        stage.subject_to(stage.T >= MIN_PHASE)
        name = _time_names(problem)[k]
        if name in problem.free:
            _bounded(ocp, stage.tf, *problem.free[name])
        else:
            ocp.subject_to(stage.tf == problem.nodes[k + 1].t)


def build(problem: Problem, intervals: int, gamma_constraint: bool, sign: int, guess):
    """The rockit Ocp of a problem and its stages (one per phase)."""
    from rockit import Ocp

    times = [n.t for n in problem.nodes]
    free_times = any(name in problem.free for name in _time_names(problem))
    fatrop = problem.spec.collocation.solver == "fatrop"
    ocp = Ocp(T=times[-1]) if fatrop else Ocp()
    w = weights(problem.spec.optimizer.objective)
    margin = ocp.variable() if w.get("gamma_margin") else None
    objective = 0
    stages: list[Stage] = []
    for k in range(len(times) - 1):
        st = _new_stage(ocp, problem, k, intervals, free_times)
        _path_constraints(problem, st, gamma_constraint, sign, margin)
        if w.get("torque"):
            objective += w["torque"] * st.stage.integral(squared_norm(st.tau))
        _set_guess(st, k, times, guess)
        _link(ocp, problem, k, st, stages[-1] if stages else None, free_times)
        stages.append(st)
    if w.get("duration"):
        objective += w["duration"] * stages[-1].stage.tf
    if margin is not None:
        objective -= w["gamma_margin"] * margin
        ocp.set_initial(margin, problem.spec.optimizer.gamma_min)
    ocp.add_objective(objective)
    if fatrop:
        ocp.solver("fatrop", fatrop_options(problem.spec.optimizer.solver))
    else:
        options = {
            f"ipopt.{k}": v for k, v in ipopt_options(problem.spec.optimizer.solver, False).items()
        }
        ocp.solver("ipopt", {"expand": True, "print_time": False, "record_time": True, **options})
        if progress.active():  # rockit's callback builds a solution object at every
            # iteration: 25 % of a solve (transfer, N = 50: 0.17 -> 0.23 s), so only where
            # someone is told (and where Ctrl-C must reach Python during the solve)
            ocp.callback(report_iteration)
    return ocp, stages


def report_iteration(iteration: int, _solution) -> None:
    """rockit's callback after each Ipopt iteration: the count to :func:`cpopt.progress.iteration`.

    Counted from 1 at Ipopt's iteration 0, as the flat optimizer's
    :class:`~cpopt.solver.IterationReporter` counts. A Ctrl-C or the time limit raised here
    stops Ipopt (CasADi turns it into a failed solve), and the budget raises it again outside
    (:mod:`cpopt.budget`).
    """
    progress.iteration(int(iteration) + 1, RUN_LABEL)


_CACHE: dict = {}
"""Transcribed problems by (problem, intervals, gamma constraint, sign): a repeated solve
reuses rockit's transcription and CasADi's expanded solver, as the flat optimizer does."""


def transcription(problem: Problem, intervals: int, gamma_constraint: bool, warm_start):
    """The (cached) Ocp, its stages and the sign of gamma kept.

    A warm-started transcription is built anew (its initial guess is the flat plan's).
    """
    sign = _sign(problem, warm_start)

    traj = sample(warm_start, per_phase=401) if warm_start else None  # once, for every stage

    def guess(t):
        return warm_guess(traj, t) if warm_start else cold_guess(problem, t)

    key = (problem.spec.model_dump_json(), intervals, gamma_constraint, sign, progress.active())
    if warm_start is None and key in _CACHE:
        return (*_CACHE[key], sign)
    ocp, stages = build(problem, intervals, gamma_constraint, sign, guess)
    ocp.gist  # noqa: B018 (transcribes the problem, so the build time covers it)
    if warm_start is None:
        _CACHE[key] = (ocp, stages)
    return ocp, stages, sign


def extract(problem: Problem, sol, stages: list[Stage], sign: int) -> JointPlan:
    """The plan of a solved (or failed) Ocp: knots, joint states, torques, fine samples."""
    knots, qs, qds, taus = [], [], [], []
    fine = {"t": [], "q": [], "qd": [], "tau": []}
    for k, st in enumerate(stages):
        s = sol(st.stage)
        t, q = s.sample(st.q, grid="control")
        _, qd = s.sample(st.qd, grid="control")
        _, tau = s.sample(st.tau, grid="control")
        tf, qf = s.sample(st.q, grid="integrator", refine=REFINE)
        _, qdf = s.sample(st.qd, grid="integrator", refine=REFINE)
        _, tauf = s.sample(st.tau, grid="integrator", refine=REFINE)
        first = 0 if k == 0 else 1
        knots.append(t[first:])
        qs.append(q[first:])
        qds.append(qd[first:])
        taus.append(tau[:-1])
        for key, value in zip(fine, (tf, qf, qdf, tauf), strict=True):
            fine[key].append(value)
    knots = np.concatenate(knots)
    q = np.concatenate(qs)
    qd = np.concatenate(qds)
    reached = pose_states(problem.arm, np.column_stack([q, qd]))
    reached[:, 3:][np.abs(reached[:, 3:]) < 1e-9] = 0.0  # at rest, as asked
    nodes = []
    for node in problem.nodes:
        i = int(np.argmin(np.abs(knots - node.t))) if node is not problem.nodes[-1] else -1
        nodes.append(Node(float(knots[i]), *reached[i], 0.0, 0.0))
    return JointPlan(
        arm=problem.arm,
        nodes=tuple(nodes),
        knots=knots,
        q=q,
        qd=qd,
        tau=np.concatenate(taus),
        fine={k: np.concatenate(v) for k, v in fine.items()},
        sigma=sign,
    )
