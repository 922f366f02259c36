"""The flat optimizer: CP curves as B-splines, free compensator values, Ipopt.

Decision variables: the inner B-spline coefficients of each CP coordinate in each phase (the
first and last 4 coefficients, 5 with ``smooth_torque``, are eliminated so that the boundary
conditions hold exactly: they are linear in the coefficients once the node values are known),
the node values freed in ``optimizer.free``, the compensator inputs alpha at the nodes where the
fourth CP derivative is pinned, and the margin variable of the ``gamma_margin`` objective. Fixed
node values are solver parameters, so one solver serves every problem of the same structure.

Every sample-wise quantity (torques, joint motion, reach) goes through one CasADi function of
the CP derivatives, mapped over the samples; the whole NLP is expanded to SX for Ipopt.

The sign of gamma is one for the whole motion: gamma depends on (xi, theta, thetadot), all
continuous at via states (an eta reset does not change it), so two phases meeting at a via state
share their sign. ``auto`` tries both signs and keeps the better solution.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import lru_cache

import casadi as ca
import numpy as np

from . import flat
from .bspline import SplineBasis, fit
from .dynamics import arm_dynamics
from .kinematics import ReachError, inverse_position_symbolic, kinematic_functions, reach_margin
from .plan import CPPlan, Node, Phase, SingularPlanError, closed_form
from .problem import Problem, gamma_is_free
from .results import SolverInfo
from .robot import Arm
from .trajectory import sample

FIELDS = ("x", "y", "theta_deg", "xdot", "ydot", "thetadot_deg", "xi", "eta")
"""Node values by their file names (angles in degrees there, radians here)."""
ANGLES = {"theta_deg", "thetadot_deg"}
REACH_EPS = {"RRR": 1e-4, "PRR": 1e-4, "RPR": 1e-4, "PPR": -1.0}
GAMMA_SAFETY = 2e-3
"""Relative margin added to gamma_min on the sample grid."""
LIMIT_SAFETY = 2e-3
"""Relative margin kept from torque and velocity limits on the sample grid."""
LIMIT_CHECK_SAMPLES = 2001
"""Samples per phase on which limits are checked after a solve."""
MAX_REFINEMENTS = 4
"""Re-solves with samples added where gamma or a limit failed between samples."""
MIN_PHASE = 0.05
"""Shortest phase [s] when times are free."""
CERTIFICATION = (
    "exact minimum of |p'' + g0 e_y| over every polynomial piece of the B-spline "
    "(end points and real roots of the derivative of its square)"
)


@dataclass(frozen=True)
class OptimizeResult:
    """Outcome of :func:`optimize`.

    Attributes
    ----------
    status : str
        ``solved``, ``infeasible``, ``max_iterations`` or ``not_converged``.
    plan : CPPlan or None
        The optimal plan, or Ipopt's best iterate when it failed.
    solver : SolverInfo
        Iterations, build and solve times, message and extra figures (certified min |gamma|,
        the sign choices tried, violated constraints).
    """

    status: str
    plan: CPPlan | None
    solver: SolverInfo
    violations: list = field(default_factory=list)


def _node_names(n_nodes: int) -> list[str]:
    return ["start", *(f"via[{i}]" for i in range(n_nodes - 2)), "goal"]


def _to_si(name: str, value: float) -> float:
    return float(np.radians(value)) if name.split(".")[-1] in ANGLES else float(value)


def _to_file(name: str, value: float) -> float:
    return float(np.degrees(value)) if name.split(".")[-1] in ANGLES else float(value)


def _initial_values(problem: Problem) -> dict[str, float]:
    """Every node value by name, SI units (the fixed values and the free values' guesses)."""
    spec = problem.spec.motion
    out = {"duration": spec.duration}
    states = [spec.start, *spec.via, spec.goal]
    for name, st in zip(_node_names(len(states)), states, strict=True):
        for f in FIELDS:
            out[f"{name}.{f}"] = _to_si(f, getattr(st, f))
        if name.startswith("via"):
            out[f"{name}.t"] = st.t
            out[f"{name}.eta_after"] = st.eta if st.eta_after is None else st.eta_after
    return out


@lru_cache(maxsize=16)
def _sample_function(arm: Arm, jit: bool = False) -> ca.Function:
    """(P (2 x 5) CP derivatives 0..4, sigma) -> (tau (2), q (3), qd (3), reach margin)."""
    K, g0 = arm.K, arm.gravity
    P = ca.SX.sym("P", 2, 5)
    sigma = ca.SX.sym("sigma")
    fl = flat.flat_functions(K, g0)
    z = fl["inverse"](P[:, :4], sigma)
    _, zdot, _ = fl["compensator"](z, P[:, 4])
    q = inverse_position_symbolic(arm, z[0], z[1], z[2])
    kin = kinematic_functions(arm)
    J = kin["jacobian"](q)
    qd = ca.solve(J, z[3:6])
    qdd = ca.solve(J, zdot[3:6] - kin["jdot_qdot"](q, qd))
    tau = arm_dynamics(arm)["inverse"](q, qd, qdd)[:2]
    opts = {"jit": True, "compiler": "shell", "jit_options": {"flags": ["-O2"]}} if jit else {}
    return ca.Function("sample", [P, sigma], [tau, q, qd, reach_margin(arm, z[0], z[1])], opts)


def _simpson(m: int) -> np.ndarray:
    w = np.ones(m)
    w[1:-1:2], w[2:-1:2] = 4, 2
    return w / (3 * (m - 1))


@dataclass
class _NLP:
    solver: ca.Function
    x_names: list
    p_names: list
    lbg: np.ndarray
    ubg: np.ndarray
    rows: list
    unpack: ca.Function
    blocks: list
    build_time: float
    graph: dict
    lift: ca.Function
    constraints: ca.Function


def _settings_key(problem: Problem):
    o = problem.spec.optimizer
    objective = o.objective if isinstance(o.objective, str) else tuple(sorted(o.objective.items()))
    lim = o.limits
    return (
        o.curve,
        o.degree,
        o.coefficients,
        objective,
        o.gamma_min,
        o.smooth_torque,
        o.samples,
        lim.model_dump_json(),
        o.solver.model_dump_json(),  # Ipopt options are baked into the solver
    )


_CACHE: dict = {}


def _weights(problem: Problem) -> dict[str, float]:
    o = problem.spec.optimizer.objective
    return {o: 1.0} if isinstance(o, str) else {k: v for k, v in o.items() if v}


def _rest_ends(problem: Problem, free: set) -> list[bool]:
    nodes = problem.nodes
    out = []
    for i, (name, node) in enumerate(zip(_node_names(len(nodes)), nodes, strict=True)):
        end = i in (0, len(nodes) - 1)
        fixed_still = all(f"{name}.{f}" not in free for f in ("xdot", "ydot", "thetadot_deg"))
        out.append(end and fixed_still and node.at_rest)
    return out


def _holding_possible(problem, free, sign, index) -> bool:
    """Can the rest end ``index`` sit at the holding torque (xi = 0, base still) with this sign?"""
    name = _node_names(len(problem.nodes))[index]
    node = problem.nodes[index]
    if f"{name}.theta_deg" in free:
        return False
    if f"{name}.xi" not in free and node.xi != 0:
        return False
    gamma_min = problem.spec.optimizer.gamma_min
    return sign * problem.arm.gravity * np.sin(node.theta) >= max(gamma_min, 1e-3)


def _build(problem: Problem, sign: int, extra: tuple) -> _NLP:
    """Build (or fetch) the NLP for a problem structure, a sign of gamma and extra samples."""
    o = problem.spec.optimizer
    free = dict(o.free)
    n_nodes = len(problem.nodes)
    rest = _rest_ends(problem, set(free))
    holding = tuple(
        r and o.smooth_torque and _holding_possible(problem, free, sign, i)
        for i, r in enumerate(rest)
    )
    key = (problem.arm, n_nodes, tuple(sorted(free)), sign, extra, holding, _settings_key(problem))
    if key in _CACHE:
        return _CACHE[key]
    start = time.perf_counter()
    arm = problem.arm
    K, g0 = arm.K, arm.gravity
    fl = flat.flat_functions(K, g0)
    names = list(_initial_values(problem))
    sym = {n: ca.MX.sym(n) for n in names}
    x_names = [n for n in names if n in free]
    p_names = [n for n in names if n not in free]
    x_parts = [sym[n] for n in x_names]
    # (label, size) of each entry of x_parts, for warm starts and bounds
    blocks = [(("value", n), 1) for n in x_names]

    def decide(expr, label):
        x_parts.append(ca.vec(expr))
        blocks.append((label, int(expr.numel())))

    node_names = _node_names(n_nodes)
    times = [ca.MX(0.0), *(sym[f"{v}.t"] for v in node_names[1:-1]), sym["duration"]]

    def state(i, after):
        nm = node_names[i]
        vals = [sym[f"{nm}.{f}"] for f in FIELDS]
        if after and nm.startswith("via"):
            vals[-1] = sym[f"{nm}.eta_after"]
        return ca.vertcat(*vals)

    pin = o.smooth_torque
    R = 5 if pin else 4
    n = o.coefficients if o.curve == "bspline" else o.degree + 1
    basis = SplineBasis(o.degree, n)
    if n < 2 * R:
        raise ValueError(f"{n} coefficients cannot hold {R} boundary conditions at each end")
    E0, E1 = (np.linalg.inv(E) for E in basis.end_matrices(R))
    F0, F1 = (np.linalg.inv(E) for E in basis.end_matrices(4))  # ends left unpinned

    # Compensator inputs at pinned nodes (torque continuity / holding torque).
    alphas = {}
    if pin:
        for i in range(n_nodes):
            if holding[i]:
                a1 = ca.MX.sym(f"alpha1_{i}")
                decide(a1, ("zero",))
                alphas[i] = ca.vertcat(a1, 0)
            elif 0 < i < n_nodes - 1:
                a = ca.MX.sym(f"alpha_{i}", 2)
                decide(a, ("zero",))
                alphas[i] = a
    weights = _weights(problem)
    margin = None
    if "gamma_margin" in weights:
        margin = ca.MX.sym("margin")
        decide(margin, ("margin",))
    # the samples ask slightly more than gamma_min so that the certificate between samples
    # (exact, after the solve) rarely needs a refinement round
    gmin = (margin if margin is not None else o.gamma_min) * (1 + GAMMA_SAFETY)

    m = o.samples + (1 - o.samples % 2)  # odd, for Simpson's rule
    s_base = np.linspace(0.0, 1.0, m)
    quad = _simpson(m)
    sample_fn = _sample_function(arm, o.solver.jit)
    g, lbg, ubg, rows = [], [], [], []

    def add(expr, lo, hi, name, t):
        g.append(expr)
        k = int(expr.numel())
        lbg.extend([lo] * k)
        ubg.extend([hi] * k)
        rows.extend((name, tk) for tk in (t if len(t) == k else t * k))

    cost_terms = {k: 0 for k in weights}
    lifted_parts, lifted_values = [], []
    coeff_blocks = []
    lim = o.limits
    revolute = arm.revolute
    for k in range(n_nodes - 1):
        h = times[k + 1] - times[k]
        za, zb = state(k, True), state(k + 1, False)
        Pa, Pb = fl["output"](za), fl["output"](zb)
        if pin and k in alphas:
            Pa = ca.horzcat(Pa, fl["fourth"](za, alphas[k]))
        elif pin:
            Pa = None
        if pin and (k + 1) in alphas:
            Pb = ca.horzcat(Pb, fl["fourth"](zb, alphas[k + 1]))
        elif pin:
            Pb = None
        scale = ca.vertcat(*[h**r for r in range(R)])
        parts = []
        if Pa is None:  # not pinned here: the 5th coefficient is free too
            head_free = ca.MX.sym(f"c{k}_head", 1, 2)
            parts += [ca.mtimes(F0, (fl["output"](za) * ca.repmat(scale[:4].T, 2, 1)).T), head_free]
            decide(head_free, ("coef", k, 4, 5))
        else:
            parts.append(ca.mtimes(E0, (Pa * ca.repmat(scale.T, 2, 1)).T))
        inner = ca.MX.sym(f"c{k}", n - 2 * R, 2)
        parts.append(inner)
        decide(inner, ("coef", k, R, n - R))
        if Pb is None:
            tail_free = ca.MX.sym(f"c{k}_tail", 1, 2)
            parts += [tail_free, ca.mtimes(F1, (fl["output"](zb) * ca.repmat(scale[:4].T, 2, 1)).T)]
            decide(tail_free, ("coef", k, n - 5, n - 4))
        else:
            parts.append(ca.mtimes(E1, (Pb * ca.repmat(scale.T, 2, 1)).T))
        C = ca.vertcat(*parts)
        coeff_blocks.append(C)

        s = np.r_[s_base, np.asarray(extra[k], float)] if extra else s_base
        D = [ca.mtimes(basis.matrix(s, r), C) / h**r for r in range(5)]  # each (len(s), 2)
        # sample j's CP derivatives as the 2 x 5 block j of one 2 x 5N matrix, for the map
        P_all = ca.reshape(ca.vertcat(*[d.T for d in D]), 2, 5 * len(s))
        # Lifting: the samples' CP derivatives are decision variables tied to the coefficients
        # by linear constraints, so the Hessian of the Lagrangian is block diagonal (10 x 10 per
        # sample) instead of one dense block through every sample's inverse dynamics.
        lifted = ca.MX.sym(f"P{k}", 2, 5 * len(s))
        lifted_parts.append(ca.vec(lifted))
        lifted_values.append(ca.vec(P_all))
        add(
            ca.vec(lifted - P_all),
            0,
            0,
            f"lifted samples (phase {k + 1})",
            [(k, float(sj)) for sj in s for _ in range(10)],
        )
        tau, q, qd, reach = sample_fn.map(len(s), "serial")(lifted, sign)
        tnodes = [(k, float(sj)) for sj in s]
        # gamma is cheap (linear in the coefficients): check it on a grid 4 times finer
        s_gamma = np.r_[np.linspace(0.0, 1.0, 4 * (m - 1) + 1), s[m:]]
        acc = ca.mtimes(basis.matrix(s_gamma, 2), C) / h**2 + ca.repmat(
            ca.DM([[0, g0]]), len(s_gamma), 1
        )
        add(
            ca.sum2(acc**2) - gmin**2,
            0,
            ca.inf,
            f"|gamma| >= gamma_min (phase {k + 1})",
            [(k, float(sj)) for sj in s_gamma],
        )
        if arm.kind != "PPR":
            add(reach.T, REACH_EPS[arm.kind], ca.inf, f"reach (phase {k + 1})", tnodes)
        for i, tmax in enumerate(lim.torque):
            if tmax is not None:
                tm = tmax * (1 - LIMIT_SAFETY)
                add(tau[i, :].T, -tm, tm, f"|tau{i + 1}| <= {tmax:g}", tnodes)
        if lim.joint_position is not None:
            for i, pair in enumerate(lim.joint_position):
                if pair is not None:
                    lo, hi = np.radians(pair) if revolute[i] else pair
                    add(q[i, :].T, float(lo), float(hi), f"q{i + 1} within limits", tnodes)
        if lim.joint_velocity is not None:
            for i, vmax in enumerate(lim.joint_velocity):
                if vmax is not None:
                    vm = float(np.radians(vmax) if revolute[i] else vmax) * (1 - LIMIT_SAFETY)
                    add(qd[i, :].T, -vm, vm, f"|q{i + 1}dot| within limits", tnodes)
        mm = len(s_base)
        if "torque" in cost_terms:
            cost_terms["torque"] += h * ca.dot(quad, ca.sum1(tau[:, :mm] ** 2).T)
        if "energy" in cost_terms:
            # |tau_i q_i'| through its epigraph: slack >= +-power, exact and smooth for Ipopt
            power = tau[:, :mm] * qd[:2, :mm]
            slack = ca.MX.sym(f"e{k}", 2, mm)
            tau0, _, qd0, _ = sample_fn.map(len(s), "serial")(P_all, sign)
            lifted_parts.append(ca.vec(slack))
            lifted_values.append(ca.vec(ca.fabs(tau0[:, :mm] * qd0[:2, :mm])))
            add(
                ca.vec(slack - power),
                0,
                ca.inf,
                f"energy slack (phase {k + 1})",
                [(k, float(sj)) for sj in s[:mm] for _ in range(2)],
            )
            add(
                ca.vec(slack + power),
                0,
                ca.inf,
                f"energy slack (phase {k + 1})",
                [(k, float(sj)) for sj in s[:mm] for _ in range(2)],
            )
            cost_terms["energy"] += h * ca.dot(quad, ca.sum1(slack).T)
        if "v_squared" in cost_terms:
            cost_terms["v_squared"] += h * ca.dot(quad, ca.sum2(D[4][:mm, :] ** 2))
        # the sign of gamma at the phase's nodes, where it is free
        for z, tn in ((za, 0.0), (zb, 1.0)):
            gam = fl["gamma"](z)
            if ca.depends_on(gam, ca.vertcat(*x_parts)):
                add(sign * gam - gmin, 0, ca.inf, f"sign(gamma) at node (phase {k + 1})", [(k, tn)])
        if ca.depends_on(h, ca.vertcat(*x_parts)):
            add(h, MIN_PHASE, ca.inf, f"phase {k + 1} duration >= {MIN_PHASE}", [(k, 0.0)])
    for i, hold in enumerate(holding):
        nm = _node_names(n_nodes)[i]
        if hold and f"{nm}.xi" in free:
            add(sym[f"{nm}.xi"], 0, 0, f"{nm}: xi = 0 for the holding torque", [(0, 0.0)])
    if "duration" in cost_terms:
        cost_terms["duration"] = sym["duration"]
    if "gamma_margin" in cost_terms:
        cost_terms["gamma_margin"] = -margin
        add(margin, o.gamma_min, ca.inf, "gamma margin >= gamma_min", [(0, 0.0)])
    cost = sum(weights[k] * cost_terms[k] for k in weights)
    x_core = ca.vertcat(*x_parts)
    x = ca.vertcat(x_core, *lifted_parts)
    p = ca.vertcat(*[sym[n] for n in p_names])
    nlp = {"x": x, "p": p, "f": cost, "g": ca.vertcat(*g)}
    opts = {
        # the first-round solver is expanded to SX (fast iterations, cached for reuse); the
        # refinement rounds start warm and need few iterations, so a cheap MX build wins there
        "expand": not extra,
        "print_time": False,
        "show_eval_warnings": False,
        "ipopt": {
            "print_level": o.solver.print_level,
            "max_iter": o.solver.max_iter,
            "tol": o.solver.tol,
            "sb": "yes",
            "mu_strategy": o.solver.mu_strategy,
            "max_wall_time": o.solver.max_time,
        },
    }
    if o.solver.jit:
        # compile the small per-sample function (and CasADi its derivatives) to C; compiling
        # the whole expanded NLP takes gcc minutes, so the outer graph stays MX
        opts["expand"] = False
    solver = ca.nlpsol("flat", "ipopt", nlp, opts)
    outs = [ca.vertcat(*[sym[n] for n in names]), *coeff_blocks, *[cost_terms[k] for k in weights]]
    unpack = ca.Function("unpack", [x, p], outs)
    lift = ca.Function("lift", [x_core, p], [ca.vertcat(*lifted_values)])
    constraints = ca.Function("constraints", [x, p], [nlp["g"]])
    built = _NLP(
        solver,
        x_names,
        p_names,
        np.array(lbg, float),
        np.array(ubg, float),
        rows,
        unpack,
        blocks,
        time.perf_counter() - start,
        nlp,
        lift,
        constraints,
    )
    _CACHE[key] = built
    return built


def _nodes_from(values: dict, count: int, xi: dict | None = None) -> list[Node]:
    """Nodes from values by name (SI units); ``xi`` overrides xi by node name."""
    names = _node_names(count)
    times = [0.0, *(values[f"{v}.t"] for v in names[1:-1]), values["duration"]]
    nodes = []
    for t, nm in zip(times, names, strict=True):
        after = values.get(f"{nm}.eta_after")
        eta = values[f"{nm}.eta"]
        nodes.append(
            Node(
                t=t,
                x=values[f"{nm}.x"],
                y=values[f"{nm}.y"],
                theta=values[f"{nm}.theta_deg"],
                xdot=values[f"{nm}.xdot"],
                ydot=values[f"{nm}.ydot"],
                thetadot=values[f"{nm}.thetadot_deg"],
                xi=(xi or {}).get(nm, values[f"{nm}.xi"]),
                eta=eta,
                eta_after=None if after is None or after == eta else after,
            )
        )
    return nodes


def _initial_plan(problem: Problem, values: dict, sign: int) -> CPPlan:
    """Closed-form warm start; for nodes whose guesses give gamma the other sign, xi is moved
    to the sign's side (documented fallback); where the closed form is singular (e.g. a
    swing-up with x_s = x_g), its curve is used anyway with a lateral CP excursion added."""
    o = problem.spec.optimizer
    arm = problem.arm
    K, g0 = arm.K, arm.gravity
    xis = {}
    for nm in _node_names(len(problem.nodes)):
        xi = values[f"{nm}.xi"]
        gam = xi - K * values[f"{nm}.thetadot_deg"] ** 2 + g0 * np.sin(values[f"{nm}.theta_deg"])
        if sign * gam < o.gamma_min and f"{nm}.xi" in o.free:
            xi += sign * (o.gamma_min + 2.0) - gam
        xis[nm] = xi
    nodes = _nodes_from(values, len(problem.nodes), xis)
    try:
        return closed_form(arm, nodes)
    except SingularPlanError:
        return closed_form(arm, nodes, check=False)


def _fallback_excursion(plan: CPPlan) -> list[np.ndarray]:
    """A lateral CP excursion K sin^2(pi s) on phases whose closed form is singular."""
    out = []
    for ph in plan.phases:
        value, _ = ph.curve.min_norm_of_acceleration_plus((0.0, plan.arm.gravity))
        out.append(plan.arm.K if value < 0.1 else 0.0)
    return out


def _guess(nlp: _NLP, problem: Problem, values: dict, sign: int) -> np.ndarray:
    """Initial decision vector: free values at their guesses, coefficients from the closed form
    projected onto the B-spline basis."""
    o = problem.spec.optimizer
    plan = _initial_plan(problem, values, sign)
    bump = _fallback_excursion(plan)
    n = o.coefficients if o.curve == "bspline" else o.degree + 1
    basis = SplineBasis(o.degree, n)
    coeffs = []
    for k, ph in enumerate(plan.phases):
        C = fit(basis, ph.curve)
        C[:, 0] += bump[k] * np.sin(np.pi * np.linspace(0, 1, n)) ** 2
        coeffs.append(C)
    node_of = {nm: i for i, nm in enumerate(_node_names(len(plan.nodes)))}
    out = []
    for label, size in nlp.blocks:
        if label[0] == "value":
            nm = label[1]
            node = nm.split(".")[0]
            out.append(plan.nodes[node_of[node]].xi if nm.endswith(".xi") else values[nm])
        elif label[0] == "zero":
            out.extend([0.0] * size)
        elif label[0] == "margin":
            out.append(o.gamma_min)
        else:
            _, k, lo, hi = label
            out.extend(coeffs[k][lo:hi].T.ravel())
    core = np.asarray(out, float)
    p = np.array([values[n] for n in nlp.p_names], float)
    return np.concatenate([core, np.asarray(nlp.lift(core, p)).ravel()])


def _signs(problem: Problem) -> list[int]:
    """The signs of gamma to try: one for the whole motion (see the module docstring)."""
    o = problem.spec.optimizer
    wanted = set(o.gamma_sign or ["auto"])
    if len(wanted - {"auto"}) > 1:
        raise ValueError(
            "gamma_sign: gamma keeps one sign over the whole motion (it is "
            "continuous at via states); give the same sign for every phase"
        )
    if wanted - {"auto"}:
        return [1 if "positive" in wanted else -1]
    arm = problem.arm
    fixed = []
    for nm, node in zip(_node_names(len(problem.nodes)), problem.nodes, strict=True):
        if not gamma_is_free(nm, o.free):
            fixed.append(float(flat.gamma(node.state(), arm.K, arm.gravity)))
    signs = {int(np.sign(g)) for g in fixed if abs(g) > 0}
    return sorted(signs) if signs else [-1, 1]


_STATUS = {
    "Solve_Succeeded": "solved",
    "Solved_To_Acceptable_Level": "solved",
    "Infeasible_Problem_Detected": "infeasible",
    "Maximum_Iterations_Exceeded": "max_iterations",
    "Maximum_CpuTime_Exceeded": "max_iterations",
    "Maximum_WallTime_Exceeded": "time_limit",
}


def _violations(nlp: _NLP, g: np.ndarray, times: list, tol: float = 1e-6) -> list[str]:
    """The violated constraints, the worst place of each by name and time (at most 10)."""
    excess = np.maximum(nlp.lbg - g, g - nlp.ubg)
    out = []
    seen = set()
    for i in np.argsort(-excess):
        if excess[i] <= tol or len(out) == 10:
            break
        name, (phase, s) = nlp.rows[i][0], nlp.rows[i][1]
        if name in seen:
            continue
        seen.add(name)
        t = times[phase] + s * (times[phase + 1] - times[phase])
        out.append(
            f"{name} at t = {t:.4g} s: value {g[i]:.4g}, bounds "
            f"[{nlp.lbg[i]:.4g}, {nlp.ubg[i]:.4g}]"
        )
    return out


def _plan_from(problem: Problem, nlp: _NLP, x: np.ndarray, p: np.ndarray, sign: int):
    """Unpack a decision vector into a CPPlan, the node values and the cost terms."""
    o = problem.spec.optimizer
    outs = nlp.unpack(x, p)
    names = list(_initial_values(problem))
    vals = dict(zip(names, np.asarray(outs[0]).ravel(), strict=True))
    n_ph = len(problem.nodes) - 1
    nodes = _nodes_from(vals, len(problem.nodes))
    times = [node.t for node in nodes]
    n = o.coefficients if o.curve == "bspline" else o.degree + 1
    basis = SplineBasis(o.degree, n)
    phases = tuple(
        Phase(basis.to_pieces(np.asarray(outs[1 + k]), times[k], times[k + 1] - times[k]), sign)
        for k in range(n_ph)
    )
    weights = _weights(problem)
    terms = {k: float(v) for k, v in zip(weights, outs[1 + n_ph :], strict=True)}
    free_values = {nm: _to_file(nm, vals[nm]) for nm in o.free}
    plan = CPPlan(
        arm=problem.arm,
        nodes=tuple(nodes),
        phases=phases,
        planner="optimize",
        free_values=free_values,
    )
    return plan, times, terms


def _solve_sign(problem: Problem, sign: int, values: dict, p: np.ndarray):
    """Solve for one sign of gamma, refining the sample grid until the margin is certified."""
    extra = ()
    x0 = None
    build = solve = 0.0
    iters = refinements = 0
    for _ in range(1 + MAX_REFINEMENTS):
        tic = time.perf_counter()
        nlp = _build(problem, sign, extra)
        build += time.perf_counter() - tic  # ~0 when the solver was cached
        if x0 is None:
            x0 = _guess(nlp, problem, values, sign)
        else:  # a refinement round: keep the core variables, lift them onto the new samples
            core = x0[: nlp.lift.size_in(0)[0]]
            x0 = np.concatenate([core, np.asarray(nlp.lift(core, p)).ravel()])
        lbx, ubx = _bounds(problem, nlp)
        start = time.perf_counter()
        sol = nlp.solver(x0=x0, p=p, lbx=lbx, ubx=ubx, lbg=nlp.lbg, ubg=nlp.ubg)
        solve += time.perf_counter() - start
        stats = nlp.solver.stats()
        iters += int(stats.get("iter_count", 0))
        x = np.asarray(sol["x"]).ravel()
        plan, times, terms = _plan_from(problem, nlp, x, p, sign)
        status = _STATUS.get(stats["return_status"], "not_converged")
        certified, _ = plan.min_abs_gamma()
        if status != "solved":
            break
        # refine where the margin or a limit fails between samples, then solve again
        dips = _between_samples(problem, plan, times)
        if not any(dips):
            break
        per = [set(e) for e in (extra or [() for _ in range(len(times) - 1)])]
        for k, new in enumerate(dips):
            per[k].update(new)
        extra = tuple(tuple(sorted(e)) for e in per)
        x0 = x
        refinements += 1
    # constraints of the plan the user gets: lifted samples recomputed from the core variables
    core = x[: nlp.lift.size_in(0)[0]]
    consistent = np.concatenate([core, np.asarray(nlp.lift(core, p)).ravel()])
    g = np.asarray(nlp.constraints(consistent, p)).ravel()
    info = {
        "sign": "positive" if sign > 0 else "negative",
        "status": status,
        "ipopt_status": stats["return_status"],
        "objective": float(sol["f"]),
        "cost_terms": terms,
        "iterations": iters,
        "certified_min_abs_gamma": certified,
        "refinements": refinements,
    }
    return plan, info, _violations(nlp, g, times), build, solve


def _between_samples(problem: Problem, plan: CPPlan, times: list) -> list[set]:
    """Per phase, the normalised times where gamma_min (certified exactly) or a torque or
    joint-velocity limit (checked on a grid of :data:`LIMIT_CHECK_SAMPLES`) fails between
    samples."""
    o = problem.spec.optimizer
    target = o.gamma_min * (1 - 1e-6) - 1e-9
    found = [set() for _ in plan.phases]
    for k, ph in enumerate(plan.phases):
        for value, t in ph.curve.piece_minima((0.0, problem.arm.gravity)):
            if value < target:
                found[k].add(round((t - times[k]) / (times[k + 1] - times[k]), 9))
    lim = o.limits
    checks = []
    for i, tmax in enumerate(lim.torque):
        if tmax is not None:
            checks.append((lambda tr, i=i: np.abs(tr.tau[:, i]), tmax))
    revolute = problem.arm.revolute
    for i, vmax in enumerate(lim.joint_velocity or ()):
        if vmax is not None:
            vm = np.radians(vmax) if revolute[i] else vmax
            checks.append((lambda tr, i=i: np.abs(tr.qd[:, i]), vm))
    if not checks:
        return found
    try:
        traj = sample(plan, per_phase=max(LIMIT_CHECK_SAMPLES, problem.spec.verification.samples))
    except ReachError:
        return found
    for values, bound in checks:
        excess = values(traj) - bound * (1 + 1e-6)
        for j in np.flatnonzero(excess > 0):
            k = int(traj.phase[j])
            found[k].add(round((traj.t[j] - times[k]) / (times[k + 1] - times[k]), 9))
    # one point per stretch of violation is enough
    return [set(sorted(f)[:: max(1, len(f) // 8)]) for f in found]


def _bounds(problem: Problem, nlp: _NLP) -> tuple[np.ndarray, np.ndarray]:
    free = problem.spec.optimizer.free
    lo, hi = [], []
    for label, size in nlp.blocks:
        if label[0] == "value":
            a, b = free[label[1]]
            lo.append(-np.inf if a is None else _to_si(label[1], a))
            hi.append(np.inf if b is None else _to_si(label[1], b))
        else:
            lo += [-np.inf] * size
            hi += [np.inf] * size
    n_lifted = nlp.solver.size_in(0)[0] - len(lo)
    return np.r_[lo, [-np.inf] * n_lifted], np.r_[hi, [np.inf] * n_lifted]


def optimize(problem: Problem) -> OptimizeResult:
    """Optimize a problem's plan with Ipopt (see the module docstring).

    Parameters
    ----------
    problem : Problem
        A problem with ``planner: optimize``.

    Returns
    -------
    OptimizeResult
        The best plan over the signs of gamma tried, with an honest status: a failed solve
        returns Ipopt's best iterate, its status and the violated constraints by name and time.
    """
    values = _initial_values(problem)
    attempts = []
    for sign in _signs(problem):
        tic = time.perf_counter()
        nlp = _build(problem, sign, ())
        first_build = time.perf_counter() - tic
        p = np.array([values[n] for n in nlp.p_names], float)
        plan, info, violations, build, solve = _solve_sign(problem, sign, values, p)
        attempts.append((plan, info, violations, build + first_build, solve))
    solved = [a for a in attempts if a[1]["status"] == "solved"]
    pool = solved or attempts
    plan, info, violations, _, _ = min(pool, key=lambda a: a[1]["objective"])
    build = sum(a[3] for a in attempts)
    solve = sum(a[4] for a in attempts)
    status = info["status"]
    message = f"Ipopt: {info['ipopt_status']} (sign of gamma: {info['sign']})"
    if status != "solved" and violations:
        message += "; violated: " + "; ".join(violations[:3])
    extra = {
        "objective": info["objective"],
        "cost_terms": info["cost_terms"],
        "gamma_sign": info["sign"],
        "certified_min_abs_gamma": info["certified_min_abs_gamma"],
        "certification": CERTIFICATION,
        "refinements": info["refinements"],
        "sign_choices": [a[1] for a in attempts],
        "violations": violations,
    }
    solver = SolverInfo(
        iterations=sum(a[1]["iterations"] for a in attempts),
        build_time_s=build,
        solve_time_s=solve,
        message=message,
        extra=extra,
    )
    return OptimizeResult(status=status, plan=plan, solver=solver, violations=violations)


__all__ = ["OptimizeResult", "optimize"]
