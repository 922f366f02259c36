"""Direct collocation of the arm's full dynamics: the generic method, kept as a benchmark peer.

This is what a user would otherwise write: joint positions and velocities as states, the two
actuated torques as piecewise-constant controls, the passive joint torque-free through the
forward dynamics ``qdd = B^-1 ([tau; 0] - n)``, transcribed by rockit (direct collocation or
multiple shooting) and solved by Ipopt. The problem is the flat optimizer's: same nodes,
objective, limits and duration, read from the same ``optimizer`` block, plus the settings of
the ``collocation`` block. With ``gamma_constraint`` the regularity quantity

    gamma = (xddot, yddot + g0) . (cos theta, sin theta) - K thetadot^2,

computed from the joint state and the accelerations the torques produce, keeps one sign with
``sign(gamma) gamma >= gamma_min`` at every knot (not between knots: the flat optimizer
certifies it everywhere).

Node values are imposed as given: fixed fields by equality, freed fields within their bounds.
Angles are taken literally (a goal at -270 deg and one at 90 deg are different windings).
Compensator values (xi, eta) do not exist here and are ignored.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import lru_cache

import casadi as ca
import numpy as np

from . import flat
from .dynamics import arm_dynamics, holding_torque
from .integrate import integrate
from .kinematics import joint_state, kinematic_functions
from .mapping import mapped
from .optimize import _STATUS, MIN_PHASE, _initial_values, _node_names, _to_si, _weights
from .plan import Node
from .problem import Problem
from .results import SolverInfo
from .robot import Arm
from .simulate import SimulationResult, cp_of, goal_error, pose_states
from .trajectory import Metrics, Trajectory

NODE_FIELDS = ("x", "y", "theta_deg", "xdot", "ydot", "thetadot_deg")
"""Node values collocation imposes (in the file's units; xi and eta have no meaning here)."""
REFINE = 8
"""Samples per interval of the collocation polynomials in the trajectory."""


@lru_cache(maxsize=16)
def joint_functions(arm: Arm) -> ca.Function:
    """``step(q, qd, tau) -> (qdd, gamma, s, sdot, sddot)`` for the full dynamics.

    qdd are the joint accelerations the actuated torques tau (2,) [N m or N] produce with the
    passive joint free; gamma [m/s^2] is the regularity quantity of that motion; s = (x, y,
    theta) is the third link's pose, sdot and sddot its velocity and acceleration.
    """
    q = ca.SX.sym("q", 3)
    qd = ca.SX.sym("qd", 3)
    tau = ca.SX.sym("tau", 2)
    kin = kinematic_functions(arm)
    qdd = arm_dynamics(arm)["forward"](q, qd, tau)
    s = kin["pose"](q)
    J = kin["jacobian"](q)
    sdot = J @ qd
    sddot = J @ qdd + kin["jdot_qdot"](q, qd)
    theta = s[2]
    gamma = (
        sddot[0] * ca.cos(theta) + (sddot[1] + arm.gravity) * ca.sin(theta) - arm.K * sdot[2] ** 2
    )
    return ca.Function("step", [q, qd, tau], [qdd, gamma, s, sdot, sddot])


@dataclass(frozen=True)
class JointPlan:
    """A plan as joint motion and piecewise-constant torques (what collocation returns).

    Attributes
    ----------
    arm : Arm
        The arm.
    nodes : tuple of Node
        Start, via states and goal as reached by the plan (SI units).
    knots : numpy.ndarray
        Control knots (M + 1,) [s]; the torque is constant on each interval between them.
    q, qd : numpy.ndarray
        Joint positions and velocities at the knots (M + 1, 3).
    tau : numpy.ndarray
        Torques (M, 2) [N m or N] on each interval.
    fine : dict
        The collocation polynomials sampled ``REFINE`` times per interval: ``t``, ``q``,
        ``qd``, ``tau`` (the interval's torque).
    sigma : int
        The sign of gamma the plan was asked to keep (0 when unconstrained).
    """

    arm: Arm
    nodes: tuple
    knots: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    fine: dict
    sigma: int
    planner: str = "collocation"
    free_values: dict = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Duration of the motion [s]."""
        return float(self.knots[-1] - self.knots[0])

    def torque_at(self, t: float) -> np.ndarray:
        """The torque (2,) applied at time t [s] (right-continuous, the last one at the end)."""
        k = int(np.clip(np.searchsorted(self.knots, t, side="right") - 1, 0, len(self.tau) - 1))
        return self.tau[k]

    def torque_sq_integral(self) -> float:
        """Exact integral of tau1^2 + tau2^2 dt of the piecewise-constant torques."""
        return float(np.sum(np.diff(self.knots) * (self.tau**2).sum(axis=1)))


@dataclass(frozen=True)
class CollocationResult:
    """Outcome of :func:`collocate`: status, plan (or best iterate), solver statistics."""

    status: str
    plan: JointPlan | None
    solver: SolverInfo
    violations: list = field(default_factory=list)


def _cold_guess(problem: Problem, t: np.ndarray) -> tuple[np.ndarray, ...]:
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


def _warm_guess(plan, t: np.ndarray) -> tuple[np.ndarray, ...]:
    """A flat plan's joint motion and torques at times t."""
    from .trajectory import sample

    traj = sample(plan, per_phase=401)
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
class _Stage:
    stage: object
    q: object
    qd: object
    tau: object
    intervals: int


def _limits(problem: Problem, st: _Stage) -> None:
    lim = problem.spec.optimizer.limits
    revolute = problem.arm.revolute
    for i, tmax in enumerate(lim.torque):
        if tmax is not None:
            st.stage.subject_to(-tmax <= (st.tau[i] <= tmax))
    for i, pair in enumerate(lim.joint_position or ()):
        if pair is not None:
            lo, hi = np.radians(pair) if revolute[i] else pair
            st.stage.subject_to(float(lo) <= (st.q[i] <= float(hi)))
    for i, vmax in enumerate(lim.joint_velocity or ()):
        if vmax is not None:
            vm = float(np.radians(vmax) if revolute[i] else vmax)
            st.stage.subject_to(-vm <= (st.qd[i] <= vm))


def _node_constraints(ocp, problem: Problem, index: int, q, qd) -> None:
    """Fixed node fields by equality, freed ones within their bounds (q, qd at the node)."""
    free = problem.spec.optimizer.free
    values = _initial_values(problem)
    name = _node_names(len(problem.nodes))[index]
    kin = kinematic_functions(problem.arm)
    s = kin["pose"](q)
    sdot = kin["jacobian"](q) @ qd
    expr = dict(zip(NODE_FIELDS, [s[0], s[1], s[2], sdot[0], sdot[1], sdot[2]], strict=True))
    for f in NODE_FIELDS:
        key = f"{name}.{f}"
        if key in free:
            lo, hi = free[key]
            if lo is not None:
                ocp.subject_to(expr[f] >= _to_si(f, lo))
            if hi is not None:
                ocp.subject_to(expr[f] <= _to_si(f, hi))
        else:
            ocp.subject_to(expr[f] == values[key])


def _phase_times(problem: Problem) -> tuple[list, list]:
    """Node times and which of them are free (duration and via times in optimizer.free)."""
    free = problem.spec.optimizer.free
    times = [n.t for n in problem.nodes]
    names = ["", *(f"via[{i}].t" for i in range(len(times) - 2)), "duration"]
    return times, [n in free for n in names]


def _build(problem: Problem, intervals: int, gamma_constraint: bool, sign: int, guess):
    from rockit import DirectCollocation, FreeTime, MultipleShooting, Ocp

    col = problem.spec.collocation
    opt = problem.spec.optimizer
    arm = problem.arm
    step = joint_functions(arm)
    times, time_free = _phase_times(problem)
    any_free = any(time_free)
    total = times[-1]
    ocp = Ocp()
    stages: list[_Stage] = []
    weights = _weights(problem)
    margin = ocp.variable() if weights.get("gamma_margin") else None
    objective = 0
    for k in range(len(times) - 1):
        h = times[k + 1] - times[k]
        n_k = max(2, round(intervals * h / total))
        if any_free:
            stage = ocp.stage(t0=FreeTime(times[k]), T=FreeTime(h))
        else:
            stage = ocp.stage(t0=times[k], T=h)
        q = stage.state(3)
        qd = stage.state(3)
        tau = stage.control(2)
        qdd, gamma, _, _, _ = step(q, qd, tau)
        stage.set_der(q, qd)
        stage.set_der(qd, qdd)
        if col.method == "collocation":
            stage.method(DirectCollocation(N=n_k, degree=col.degree, scheme="radau"))
        else:
            stage.method(MultipleShooting(N=n_k, M=col.steps, intg="rk"))
        if gamma_constraint:
            stage.subject_to(sign * gamma >= opt.gamma_min)
        if margin is not None:
            stage.subject_to(sign * gamma >= margin)
        st = _Stage(stage, q, qd, tau, n_k)
        _limits(problem, st)
        if weights.get("torque"):
            objective += weights["torque"] * stage.integral(ca.sumsqr(tau))
        if any_free:
            stage.subject_to(stage.T >= MIN_PHASE)
        # rockit's numeric-matrix path for state guesses is broken (0.6.7): give functions of t
        grid = np.linspace(times[k], times[k + 1], 4 * n_k + 1)
        for var, values in zip((q, qd, tau), guess(grid), strict=True):
            table = ca.interpolant(f"guess{k}", "linear", [grid], values.ravel())
            stage.set_initial(var, table(stage.t))
        if k == 0:
            if any_free:
                ocp.subject_to(stage.t0 == 0)
            _node_constraints(ocp, problem, 0, stage.at_t0(q), stage.at_t0(qd))
        else:
            prev = stages[-1]
            ocp.subject_to(stage.at_t0(q) == prev.stage.at_tf(prev.q))
            ocp.subject_to(stage.at_t0(qd) == prev.stage.at_tf(prev.qd))
            if any_free:
                ocp.subject_to(stage.t0 == prev.stage.tf)
        _node_constraints(ocp, problem, k + 1, stage.at_tf(q), stage.at_tf(qd))
        if any_free:
            bounds = opt.free.get("duration" if k == len(times) - 2 else f"via[{k}].t")
            end = stage.tf
            if not time_free[k + 1]:
                ocp.subject_to(end == times[k + 1])
            else:
                lo, hi = bounds
                if lo is not None:
                    ocp.subject_to(end >= lo)
                if hi is not None:
                    ocp.subject_to(end <= hi)
        stages.append(st)
    if weights.get("duration"):
        objective += weights["duration"] * stages[-1].stage.tf
    if margin is not None:
        objective -= weights["gamma_margin"] * margin
        ocp.set_initial(margin, opt.gamma_min)
    ocp.add_objective(objective)
    ocp.solver(
        "ipopt",
        {
            "expand": True,
            "print_time": False,
            "record_time": True,
            "ipopt.print_level": opt.solver.print_level,
            "ipopt.max_iter": opt.solver.max_iter,
            "ipopt.tol": opt.solver.tol,
            "ipopt.max_wall_time": opt.solver.max_time,
            "ipopt.sb": "yes",
        },
    )
    return ocp, stages


_CACHE: dict = {}
"""Transcribed problems by (problem, intervals, gamma constraint, sign): a repeated solve
reuses rockit's transcription and CasADi's expanded solver, as the flat optimizer does."""


def _extract(problem: Problem, sol, stages: list[_Stage], sign: int) -> JointPlan:
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


def collocate(
    problem: Problem,
    intervals: int | None = None,
    gamma_constraint: bool | None = None,
    warm_start=None,
) -> CollocationResult:
    """Plan a problem by direct collocation of the arm's full dynamics (see module docstring).

    Parameters
    ----------
    problem : Problem
        The problem; ``collocation`` and ``optimizer`` blocks give the settings.
    intervals : int, optional
        Control intervals over the whole motion (default ``collocation.intervals``).
    gamma_constraint : bool, optional
        Keep ``sign(gamma) gamma >= gamma_min`` at every knot (default from the file).
    warm_start : CPPlan, optional
        A flat plan to start from (its joint motion, torques and sign of gamma); without it,
        a smooth step between the nodes' joint states at the holding torques.

    Returns
    -------
    CollocationResult
        Ipopt's status (``solved``, ``infeasible``, ``max_iterations``, ``not_converged``)
        and the plan, Ipopt's best iterate when it failed.
    """
    col = problem.spec.collocation
    intervals = intervals or col.intervals
    gamma_constraint = col.gamma_constraint if gamma_constraint is None else gamma_constraint
    sign = _sign(problem, warm_start)

    def guess(t):
        return _warm_guess(warm_start, t) if warm_start else _cold_guess(problem, t)

    tic = time.perf_counter()
    key = (problem.spec.model_dump_json(), intervals, gamma_constraint, sign)
    if warm_start is None and key in _CACHE:
        ocp, stages = _CACHE[key]
    else:
        ocp, stages = _build(problem, intervals, gamma_constraint, sign, guess)
        ocp.gist  # noqa: B018 (transcribes the problem, so the build time covers it)
        if warm_start is None:
            _CACHE[key] = (ocp, stages)
    sol = ocp.solve_limited()
    total = time.perf_counter() - tic
    stats = sol.stats
    ipopt = stats.get("return_status", "unknown")
    status = _STATUS.get(ipopt, "not_converged")
    solve_time = float(stats.get("t_wall_total", total))  # Ipopt alone (record_time)
    plan = _extract(problem, sol, stages, sign if gamma_constraint else 0)
    objective = float(sol.value(ocp.objective))
    info = SolverInfo(
        iterations=int(stats.get("iter_count", 0)),
        build_time_s=total - solve_time,
        solve_time_s=solve_time,
        message=f"Ipopt: {ipopt} (collocation, {col.method}, {sum(s.intervals for s in stages)}"
        f" intervals, gamma constraint {'on' if gamma_constraint else 'off'})",
        extra={
            "objective": objective,
            "intervals": sum(s.intervals for s in stages),
            "method": col.method,
            "gamma_constraint": gamma_constraint,
            "gamma_sign": sign if gamma_constraint else None,
            "variables": int(stats.get("n_x", 0)) if "n_x" in stats else None,
        },
    )
    return CollocationResult(status=status, plan=plan, solver=info)


def joint_trajectory(plan: JointPlan) -> Trajectory:
    """Sample a collocation plan: its polynomials ``REFINE`` times per interval.

    The CP derivatives 0..2 and xi = (xddot, yddot) . (cos theta, sin theta) follow from the
    joint state and the accelerations the torques produce; the CP's third and fourth
    derivatives, eta and alpha are not defined under piecewise-constant torques (NaN). The
    passive joint's torque is zero by construction; the transcription error shows instead in
    the open-loop replay (:func:`replay`).
    """
    f = plan.fine
    n = f["t"].size
    step = mapped(joint_functions(plan.arm), n)
    qdd, gamma, s, sdot, sddot = (np.asarray(v).T for v in step(f["q"].T, f["qd"].T, f["tau"].T))
    K = plan.arm.K
    theta, w = s[:, 2], sdot[:, 2]
    along = np.column_stack([np.cos(theta), np.sin(theta)])
    normal = np.column_stack([-np.sin(theta), np.cos(theta)])
    cp = np.full((n, 2, 5), np.nan)
    cp[:, :, 0] = s[:, :2] + K * along
    cp[:, :, 1] = sdot[:, :2] + K * w[:, None] * normal
    cp[:, :, 2] = sddot[:, :2] + K * (sddot[:, 2:3] * normal - (w**2)[:, None] * along)
    xi = (sddot[:, :2] * along).sum(axis=1)
    z = np.column_stack([s, sdot, xi, np.full(n, np.nan)])
    node_times = [node.t for node in plan.nodes]
    return Trajectory(
        t=f["t"],
        phase=np.clip(
            np.searchsorted(node_times, f["t"], side="right") - 1, 0, len(node_times) - 2
        ),
        cp=cp,
        z=z,
        alpha=np.full((n, 2), np.nan),
        accel=sddot,
        q=f["q"],
        qd=f["qd"],
        qdd=qdd,
        tau=f["tau"],
        residual=np.zeros(n),
        gamma=gamma.ravel(),
    )


def joint_metrics(plan: JointPlan, traj: Trajectory) -> Metrics:
    """:class:`Metrics` of a collocation plan: exact torque integral, the rest on the samples.

    ``min_abs_gamma`` is the smallest |gamma| on the samples (not certified between them);
    ``torque_jumps`` are the largest step at a knot (``knots``) and, at a rest start or goal,
    the step from or to the holding torque.
    """
    tau = traj.tau
    power = np.abs(tau[:, 0] * traj.qd[:, 0]) + np.abs(tau[:, 1] * traj.qd[:, 1])
    i = int(np.argmin(np.abs(traj.gamma)))
    jumps = [("knots", float(np.abs(np.diff(plan.tau, axis=0)).max(initial=0.0)))]
    problem_nodes = (plan.nodes[0], plan.nodes[-1])
    for node, k, name in ((problem_nodes[0], 0, "start"), (problem_nodes[1], -1, "goal")):
        if node.at_rest:
            hold = holding_torque(plan.arm, plan.q[k])
            jumps.append((name, float(np.abs(plan.tau[k] - hold).max())))
    theta_deg = np.degrees(traj.z[:, 2])
    return Metrics(
        torque_sq_integral=plan.torque_sq_integral(),
        abs_power_integral=float(np.trapezoid(power, traj.t)),
        peak_torque=(float(np.abs(tau[:, 0]).max()), float(np.abs(tau[:, 1]).max())),
        min_abs_gamma=float(np.abs(traj.gamma[i])),
        min_abs_gamma_time=float(traj.t[i]),
        theta_min_deg=float(theta_deg.min()),
        theta_max_deg=float(theta_deg.max()),
        max_torque_jump=max(j[1] for j in jumps),
        max_passive_residual=0.0,
        torque_jumps=tuple(jumps),
    )


@dataclass(frozen=True)
class ReplayCheck:
    """Verification of a collocation plan: its torques replayed open loop on the full arm.

    Attributes
    ----------
    open_loop : SimulationResult
        The replay; its ``cp_error`` is against the plan's own CP, its ``final_state_error``
        against the problem's goal [m, rad, m/s, rad/s].
    tolerance : float
        Largest final-state error accepted (``collocation.replay_tolerance``).
    """

    open_loop: SimulationResult
    tolerance: float

    @property
    def max_cp_error(self) -> float:
        """Largest CP deviation of the replay from the plan [m]."""
        return self.open_loop.max_cp_error

    @property
    def final_state_error(self) -> float:
        """Final-state error of the replay against the goal."""
        return self.open_loop.final_state_error

    def passed(self) -> bool:
        """True when the replay ends within ``tolerance`` of the goal."""
        return self.final_state_error <= self.tolerance

    def summary(self) -> dict:
        """The figures written to ``solution.json``."""
        return {
            "max_cp_error": self.max_cp_error,
            "final_state_error": self.final_state_error,
            "passive_torque_residual": 0.0,
            "method": "open-loop replay of the piecewise-constant torques on the full dynamics",
            "replay_tolerance": self.tolerance,
        }


def replay(plan: JointPlan, goal: Node, tolerance: float = 1e-3) -> ReplayCheck:
    """Integrate the full dynamics under the plan's torques, interval by interval (DOP853).

    Parameters
    ----------
    plan : JointPlan
        The plan.
    goal : Node
        The goal the replay should end at.
    tolerance : float
        Final-state error accepted.
    """
    forward = arm_dynamics(plan.arm)["forward"]
    f = plan.fine
    X = np.concatenate([plan.q[0], plan.qd[0]])
    states, times = [], []
    for k in range(len(plan.tau)):
        t0, t1 = plan.knots[k], plan.knots[k + 1]
        sel = (f["t"] >= t0) & (f["t"] <= t1)
        t_eval = np.clip(np.unique(f["t"][sel]), t0, t1)
        tau = plan.tau[k]

        def rhs(_t, x, tau=tau):
            return np.concatenate([x[3:], np.asarray(forward(x[:3], x[3:], tau)).ravel()])

        t, Xs = integrate(rhs, X, t0, t1, t_eval, rtol=1e-10, atol=1e-10)  # bounded
        X = Xs[-1]
        times.append(t)
        states.append(Xs)
    t = np.concatenate(times)
    state = pose_states(plan.arm, np.concatenate(states))
    K = plan.arm.K
    keep = np.r_[np.diff(f["t"]) > 0, True]
    planned = cp_of(K, pose_states(plan.arm, np.column_stack([f["q"], f["qd"]])[keep]))
    cp_ref = np.column_stack([np.interp(t, f["t"][keep], planned[:, i]) for i in range(2)])
    err = np.linalg.norm(cp_of(K, state) - cp_ref, axis=1)
    result = SimulationResult(
        "open_loop", t, state, err, float(err.max()), goal_error(goal, state[-1])
    )
    return ReplayCheck(result, tolerance)
