"""The flat optimizer's NLP, built once per problem structure and cached.

Decision variables (:mod:`cpopt.flatopt.layout`): the inner B-spline coefficients of each CP
coordinate in each phase, the node values freed in ``optimizer.free``, the compensator inputs
alpha at the nodes where the fourth CP derivative is pinned, and the margin of the
``gamma_margin`` objective. Fixed node values are solver parameters, so one solver serves every
problem of the same structure.

Boundary elimination: the first and last 4 coefficients of a phase (5 with ``smooth_torque``)
are linear functions of the node values, so the boundary conditions hold exactly.

A phase's curve is an object of its family (:class:`SplineCurve`, or
:class:`~cpopt.flatopt.path_timing.PathTimingCurve` for ``curve: path_timing``) that adds its
decision blocks and boundary conditions and yields the CP derivatives at any normalised times;
everything after that is common to the families.

Each phase has its own sign of gamma. Where two phases of opposite signs meet (a via state that
resets xi) with ``smooth_torque``, the compensator inputs alpha are shared by both sides and
|gamma| sits at the margin on both, so the torque steps there only by the base acceleration
that the smallest admissible xi reset, 2 gamma_min (1 + GAMMA_SAFETY) along the link, implies.

Lifting: the CP derivatives of each sample are decision variables tied to the coefficients by
linear constraints, and every sample-wise quantity (torques, joint motion, reach) is one of the
outputs of the compiled per-sample library (:mod:`cpopt.flatopt.samples`). The transcription
writes them as symbols Y; :mod:`cpopt.flatopt.assemble` joins the library's derivatives and
CasADi's exact derivatives of the rest, and the sample part of the Hessian of the Lagrangian is
block diagonal (10 x 10 per sample).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..closedform.bspline import SplineBasis
from ..closedform.nodes import MIN_PHASE, NODE_FIELDS, has_reset, node_names
from ..model import flat
from ..model.limits import Limit
from ..model.objectives import default_hessian, squared_norm, weights
from ..problem import Problem
from ..problem.holding import holding_pattern
from ..runtime.solver import IterationReporter, ipopt_options
from . import path_timing
from .assemble import SampleBlock, assemble
from .constraints import Constraints
from .ipopt_settings import GAMMA_GRID, RESUME_OPTIONS, WARM_GAMMA_GRID, warm_options
from .layout import Layout
from .quadrature import Grid, PhaseSamples, piece_counts
from .samples import NY, QD, REACH, TAU, Q, mapped_outputs

GAMMA_SAFETY = 2e-3
"""Relative margin added to gamma_min on the sample grid (the exact certificate after the solve
then rarely needs a refinement round)."""
CURVATURE = {"exact": "all", "gauss_newton": "none"}
"""The curvature of the samples' outputs each ``optimizer.solver.hessian`` keeps
(:data:`cpopt.flatopt.assemble.CURVATURE`)."""
LIMIT_SAFETY = 2e-3
"""Relative margin kept from torque and velocity limits on the sample grid."""
REACH_EPS = {"RRR": 1e-4, "PRR": 1e-4, "RPR": 1e-4, "PPR": -1.0}
"""Smallest reach margin [m] kept at the samples, per arm kind (a PPR gantry reaches anywhere)."""


def coefficient_count(settings) -> int:
    """Coefficients per CP coordinate per phase of an ``optimizer`` block."""
    return settings.coefficients if settings.curve == "bspline" else settings.degree + 1


@dataclass(frozen=True)
class SplineCurve:
    """One phase's CP curve of the free B-spline family (``curve: bspline`` or ``polynomial``):
    coefficients (n x 2) on the phase's normalised time, h its duration [s]."""

    basis: SplineBasis
    coefficients: ca.MX
    h: ca.MX

    def derivatives(self, s: np.ndarray, orders: int = 5) -> list:
        """CP derivatives 0..orders-1 at normalised times s, each (len(s), 2) [m/s^r]."""
        return [
            ca.mtimes(basis_matrix(self.basis, s, r), self.coefficients) / self.h**r
            for r in range(orders)
        ]

    @property
    def packed(self) -> ca.MX:
        """What the unpacked solution holds of the phase: its coefficient matrix."""
        return self.coefficients


def phase_pieces(problem: Problem, k: int, packed: np.ndarray, t0: float, h: float):
    """Phase k of a solved NLP as polynomial pieces on [t0, t0 + h] (from its ``packed``)."""
    o = problem.spec.optimizer
    if o.curve == "path_timing":
        return path_timing.to_pieces(o.path[k], packed, t0, h)
    return SplineBasis(o.degree, coefficient_count(o)).to_pieces(np.asarray(packed), t0, h)


@dataclass(frozen=True)
class FlatNLP:
    """A built NLP of the flat optimizer.

    Attributes
    ----------
    solver : casadi.Function
        Ipopt through ``nlpsol``.
    layout : Layout
        The core decision variables; lifted samples follow them in x.
    p_names : list of str
        The fixed node values that are parameters, in order.
    lbg, ubg : numpy.ndarray
        Constraint bounds.
    rows : list
        A label (name, (phase, s)) per constraint row.
    unpack : casadi.Function
        ``(x, p) -> (all node values, coefficients of each phase..., cost terms...)``.
    lift : casadi.Function
        ``(core x, p) -> lifted samples`` consistent with the core variables.
    constraints : casadi.Function
        ``(x, p) -> g``.
    samples : tuple of PhaseSamples
        Where each phase is sampled.
    reporter : IterationReporter
        The solver's iteration callback (progress, clean stops).
    """

    solver: ca.Function
    layout: Layout
    p_names: list
    lbg: np.ndarray
    ubg: np.ndarray
    rows: list
    unpack: ca.Function
    lift: ca.Function
    constraints: ca.Function
    samples: tuple
    reporter: IterationReporter

    def parameters(self, values: dict) -> np.ndarray:
        """The solver's parameters from every node value by name (SI units)."""
        return np.array([values[n] for n in self.p_names], float)

    def complete(self, core: np.ndarray, p: np.ndarray) -> np.ndarray:
        """A whole decision vector: the core variables and the lifted samples they imply."""
        core = np.asarray(core, float)[: self.layout.size]
        return np.concatenate([core, np.asarray(self.lift(core, p)).ravel()])


@dataclass
class _Transcription:
    """What the transcription of one NLP shares between its steps."""

    problem: Problem
    signs: tuple[int, ...]
    holding: tuple
    sym: dict
    layout: Layout = field(default_factory=Layout)
    g: Constraints = field(default_factory=Constraints)
    alphas: dict = field(default_factory=dict)
    margin: object = None
    cost_terms: dict = field(default_factory=dict)
    lifted: list = field(default_factory=list)
    lifted_values: list = field(default_factory=list)
    coefficients: list = field(default_factory=list)
    blocks: list = field(default_factory=list)
    samples: list = field(default_factory=list)
    node_lifts: dict = field(default_factory=dict)  # (node, after, fourth) -> (symbol, value)
    warm: bool = False  # started from a seed trajectory (WARM_MU_INIT)
    from_plan: bool = False  # that seed is an exact plan (warm_options)
    resume: bool = False  # started from the previous round's solution and multipliers
    gamma_grid: int = GAMMA_GRID  # points per phase of |gamma| >= gamma_min
    ipopt: tuple = ()  # (name, value) pairs of Ipopt options set last

    @property
    def settings(self):
        return self.problem.spec.optimizer

    @property
    def flat(self) -> dict:
        return flat.flat_functions(self.problem.arm.K, self.problem.arm.gravity)

    @property
    def names(self) -> list[str]:
        return node_names(len(self.problem.nodes))

    @property
    def pinned(self) -> int:
        """CP derivatives fixed at a node: 0..3, and the fourth too with ``smooth_torque``."""
        return 5 if self.settings.smooth_torque else 4

    @property
    def basis(self) -> SplineBasis:
        return SplineBasis(self.settings.degree, coefficient_count(self.settings))

    @property
    def times(self) -> list:
        nm = self.names
        return [ca.MX(0.0), *(self.sym[f"{v}.t"] for v in nm[1:-1]), self.sym["duration"]]

    def value(self, name: str) -> ca.MX:
        """The symbol of a node value; a via state's ``xi_after`` (``eta_after``) is its ``xi``
        (``eta``) when the state has no such reset (:func:`cpopt.nodes.has_reset`): a freed
        value without a reset stays continuous across the node."""
        node, _, f = name.partition(".")
        if f in ("xi_after", "eta_after"):
            i = self.names.index(node)
            if not has_reset(self.problem.nodes[i], node, f[: -len("_after")], self.problem.free):
                return self.sym[f"{node}.{f[: -len('_after')]}"]
        return self.sym[name]

    def node_state(self, i: int, after: bool) -> ca.MX:
        """Node i's extended state z (8) as symbols, after its resets of xi and eta if
        ``after``."""
        name = self.names[i]
        values = [self.sym[f"{name}.{f}"] for f in NODE_FIELDS]
        if after and name.startswith("via"):
            values[-2] = self.value(f"{name}.xi_after")
            values[-1] = self.value(f"{name}.eta_after")
        return ca.vertcat(*values)

    def pinned_switch(self, i: int) -> bool:
        """True when node i is a via state where the sign of gamma changes and ``smooth_torque``
        pins |gamma| to the margin on both sides (:func:`_switch_constraints`)."""
        if not 0 < i < len(self.signs) or self.signs[i - 1] == self.signs[i]:
            return False
        return self.settings.smooth_torque and f"{self.names[i]}.xi_after" in self.problem.free

    def node_derivatives(self, i: int, after: bool, fourth: bool) -> ca.MX:
        """CP derivatives 0..3 at node i (2 x 4), and the fourth from its compensator inputs
        (2 x 5) with ``fourth``.

        At a via state whose xi reset is free (a switch) they are lifted: variables tied to the
        node's values by a constraint. The boundary coefficients are then linear in the
        decision variables: the flat map's curvature in the node's free state, which the fourth
        derivative at the node amplifies by (pieces / duration)^4, stays in one small
        constraint instead of in every sample near the node.
        """
        z = self.node_state(i, after)
        P = self.flat["output"](z)
        if fourth:
            P = ca.horzcat(P, self.flat["fourth"](z, self.alphas[i]))
        if f"{self.names[i]}.xi_after" not in self.problem.free:
            return P
        key = (i, after, fourth)
        if key not in self.node_lifts:
            lifted = ca.MX.sym(f"node{i}_{int(after)}", *P.shape)
            self.lifted.append(ca.vec(lifted))
            self.lifted_values.append(ca.vec(P))
            where = (i, 0.0) if after else (i - 1, 1.0)
            self.g.add(ca.vec(lifted - P), 0, 0, f"{self.names[i]}: CP derivatives", [where])
            self.node_lifts[key] = (lifted, P)
        return self.node_lifts[key][0]

    def depends_on_decisions(self, expr) -> bool:
        return ca.depends_on(expr, self.layout.vector())

    def node_jet(self, i: int, after: bool) -> ca.MX:
        """Node i's CP derivatives 0..3 (2 x 4), and the fourth (2 x 5) where it is pinned."""
        z = self.node_state(i, after)
        P = self.flat["output"](z)
        if self.settings.smooth_torque and i in self.alphas:
            P = ca.horzcat(P, self.flat["fourth"](z, self.alphas[i]))
        return P


def _settings_key(problem: Problem) -> tuple:
    o = problem.spec.optimizer
    objective = o.objective if isinstance(o.objective, str) else tuple(sorted(o.objective.items()))
    return (
        o.curve,
        o.degree,
        o.coefficients,
        objective,
        o.gamma_min,
        o.smooth_torque,
        o.samples,
        o.limits.model_dump_json(),
        o.solver.model_dump_json(),  # Ipopt options are baked into the solver
        path_timing.structure(problem) if o.curve == "path_timing" else None,
    )


CACHE_SIZE = 48
"""Most NLPs kept built (least recently used dropped first): a long-lived process (a sweep's
worker, a notebook, the zoo) builds new structures for every problem and pattern, and an
unbounded cache grew without end (each NLP holds its expression graphs and Ipopt)."""
_CACHE: OrderedDict = OrderedDict()


def cached_structures() -> int:
    """How many NLPs are kept built (at most :data:`CACHE_SIZE`)."""
    return len(_CACHE)


def initial_grids(problem: Problem) -> tuple[Grid, ...]:
    """Each phase's sample grid before any refinement (:mod:`cpopt.flatopt.quadrature`)."""
    o = problem.spec.optimizer
    if o.curve == "path_timing":  # the timing law's pieces (the path's knots move with it)
        bases = [path_timing.timing_basis(p) for p in o.path]
    else:
        bases = [SplineBasis(o.degree, coefficient_count(o))] * (len(problem.nodes) - 1)
    return tuple(Grid(piece_counts(o.samples, b.breaks.size - 1)) for b in bases)


def build(
    problem: Problem,
    signs: tuple[int, ...],
    grids: tuple[Grid, ...] | None = None,
    warm: bool = False,
    resume: bool = False,
    gamma_grid: int | None = None,
    from_plan: bool = False,
    ipopt: tuple[tuple[str, object], ...] = (),
) -> FlatNLP:
    """Build (or fetch) the NLP for a problem structure, the signs of gamma and sample grids.

    Parameters
    ----------
    problem : Problem
        The problem; only its structure (arm, node count, freed names, xi resets, settings)
        matters, its fixed values are parameters of the returned solver.
    signs : tuple of int
        The sign of gamma of each phase, +1 or -1.
    grids : tuple of Grid, optional
        Each phase's samples (default :func:`initial_grids`; refinement adds to them).
    warm : bool
        The solver is for starts from a seed trajectory (:data:`WARM_MU_INIT`).
    resume : bool
        The solver starts from a previous solution's multipliers (:data:`RESUME_OPTIONS`).
    gamma_grid : int, optional
        Equally spaced points per phase where |gamma| >= gamma_min is a constraint
        (:data:`WARM_GAMMA_GRID` for a warm solve, else :data:`GAMMA_GRID`, when None).
    from_plan : bool
        A warm solve's seed is an exact plan (:func:`warm_options`).
    ipopt : tuple of (str, object)
        Ipopt options set after every other (a re-plan's own,
        :data:`cpopt.flatopt.replan.REPLAN_IPOPT`).
    """
    grids = initial_grids(problem) if grids is None else grids
    if gamma_grid is None:
        gamma_grid = WARM_GAMMA_GRID if warm else GAMMA_GRID
    holding = holding_pattern(problem, signs)
    names = node_names(len(problem.nodes))
    resets = tuple(
        (has_reset(node, name, "xi", problem.free), has_reset(node, name, "eta", problem.free))
        for name, node in zip(names[1:-1], problem.nodes[1:-1], strict=True)
    )
    key = (
        problem.arm,
        len(problem.nodes),
        tuple(sorted(problem.free)),
        resets,
        signs,
        grids,
        holding,
        _settings_key(problem),
        warm,
        resume,
        gamma_grid,
        from_plan,
        ipopt,
    )
    if key in _CACHE:
        _CACHE.move_to_end(key)
    else:
        sym = {n: ca.MX.sym(n) for n in problem.values}
        options = {"warm": warm, "resume": resume, "gamma_grid": gamma_grid, "ipopt": ipopt}
        tr = _Transcription(problem, signs, holding, sym, from_plan=from_plan, **options)
        _decisions(tr)
        for k in range(len(problem.nodes) - 1):
            _phase(tr, k, grids[k].samples())
        _switch_constraints(tr)
        _holding_constraints(tr)
        _whole_motion_terms(tr)
        _CACHE[key] = _finish(tr)
        while len(_CACHE) > CACHE_SIZE:
            _CACHE.popitem(last=False)
    return _CACHE[key]


def _decisions(tr: _Transcription) -> None:
    """The freed values, compensator inputs at pinned nodes and the margin variable."""
    for name in tr.sym:
        if name in tr.problem.free:
            tr.layout.add(name, "value", tr.sym[name])
    if tr.settings.smooth_torque:
        for i in range(len(tr.problem.nodes)):
            if tr.holding[i]:  # holding torque: alpha2 = 0 keeps the base still
                a1 = tr.layout.add(f"alpha[{i}]", "alpha", ca.MX.sym(f"alpha1_{i}"))
                tr.alphas[i] = ca.vertcat(a1, 0)
            elif 0 < i < len(tr.problem.nodes) - 1:
                tr.alphas[i] = tr.layout.add(f"alpha[{i}]", "alpha", ca.MX.sym(f"alpha_{i}", 2))
    tr.cost_terms = {k: 0 for k in weights(tr.settings.objective)}
    if "gamma_margin" in tr.cost_terms:
        tr.margin = tr.layout.add("margin", "margin", ca.MX.sym("margin"))


def _boundary_rows(tr: _Transcription, i: int, after: bool, h) -> ca.MX | None:
    """CP derivatives at node i scaled to normalised time (pinned count x 2), or None when the
    fourth derivative is to be pinned but this node has no compensator inputs."""
    if tr.settings.smooth_torque and i not in tr.alphas:
        return None
    P = tr.node_derivatives(i, after, tr.settings.smooth_torque)
    count = int(P.shape[1])
    scale = ca.vertcat(*[h**r for r in range(count)])
    return (P * ca.repmat(scale.T, 2, 1)).T


def _unpinned_end(tr: _Transcription, k: int, i: int, after: bool, h, head: bool) -> list:
    """An end whose fourth derivative is free: 4 eliminated coefficients and a free fifth."""
    inverse = np.linalg.inv(tr.basis.end_matrices(4)[0 if head else 1])
    scale = ca.vertcat(*[h**r for r in range(4)])
    P = tr.node_derivatives(i, after, False)
    fixed = ca.mtimes(inverse, (P * ca.repmat(scale.T, 2, 1)).T)
    n = coefficient_count(tr.settings)
    rows = (4, 5) if head else (n - 5, n - 4)
    label = "head" if head else "tail"
    free = tr.layout.add(
        f"phase[{k}].coefficients[{rows[0]}:{rows[1]}]",
        "coefficients",
        ca.MX.sym(f"c{k}_{label}", 1, 2),
        phase=k,
        rows=rows,
    )
    return [fixed, free] if head else [free, fixed]


def _coefficients(tr: _Transcription, k: int, h) -> ca.MX:
    """Phase k's coefficient matrix (n x 2): boundary rows eliminated, inner rows free."""
    R = tr.pinned
    n = coefficient_count(tr.settings)
    if n < 2 * R:
        raise ValueError(f"{n} coefficients cannot hold {R} boundary conditions at each end")
    E0, E1 = (np.linalg.inv(E) for E in tr.basis.end_matrices(R))
    head = _boundary_rows(tr, k, True, h)
    tail = _boundary_rows(tr, k + 1, False, h)
    parts = _unpinned_end(tr, k, k, True, h, True) if head is None else [ca.mtimes(E0, head)]
    inner = tr.layout.add(
        f"phase[{k}].coefficients[{R}:{n - R}]",
        "coefficients",
        ca.MX.sym(f"c{k}", n - 2 * R, 2),
        phase=k,
        rows=(R, n - R),
    )
    parts.append(inner)
    if tail is None:
        parts += _unpinned_end(tr, k, k + 1, False, h, False)
    else:
        parts.append(ca.mtimes(E1, tail))
    return ca.vertcat(*parts)


def basis_matrix(basis: SplineBasis, s: np.ndarray, order: int) -> ca.DM:
    """The basis matrix as a sparse CasADi matrix: its structural zeros keep every sample
    depending on the few coefficients of its piece (a dense one makes Jacobians dense)."""
    return ca.sparsify(ca.DM(basis.matrix(s, order)))


def _curve(tr: _Transcription, k: int, h):
    """Phase k's curve of the problem's family, its decision blocks and boundary conditions."""
    if tr.settings.curve != "path_timing":
        return SplineCurve(tr.basis, _coefficients(tr, k, h), h)
    return path_timing.phase_curve(
        tr.settings.path[k],
        k,
        h,
        (tr.node_jet(k, True), tr.node_jet(k + 1, False)),
        (
            path_timing.zero_orders(tr.problem, k, True),
            path_timing.zero_orders(tr.problem, k + 1, False),
        ),
        tr.layout,
        tr.g,
        (tr.names[k], tr.names[k + 1]),
    )


def _phase(tr: _Transcription, k: int, samples: PhaseSamples) -> None:
    """Everything of phase k: its curve, samples, constraints and objective terms."""
    times = tr.times
    h = times[k + 1] - times[k]
    curve = _curve(tr, k, h)
    tr.coefficients.append(curve.packed)
    tr.samples.append(samples)
    s, m = samples.s, samples.quadrature
    D = curve.derivatives(s)  # each (len(s), 2)
    # sample j's CP derivatives as the 2 x 5 block j of one 2 x 5N matrix
    P_all = ca.reshape(ca.vertcat(*[d.T for d in D]), 2, 5 * len(s))
    lifted = ca.MX.sym(f"P{k}", 2, 5 * len(s))
    tr.lifted.append(ca.vec(lifted))
    tr.lifted_values.append(ca.vec(P_all))
    where = [(k, float(sj)) for sj in s]
    # A solve started from a seed has its rows in normalised time (times h^r): a short phase's
    # high derivatives are large in seconds (1e4-1e5 m/s^4 after a switch at 0.1 s), and rows
    # that large left Ipopt crawling at an absolute infeasibility of 1e-4 until it stopped at
    # an "acceptable" point (the benchmark transfer: 259 iterations; 164 and converged
    # scaled). From the closed form the scaled rows were measured worse (transfer_switch's
    # greedy search diverged on both switch patterns), so cold starts keep seconds.
    row_scale = ca.repmat(ca.horzcat(*[h**r for r in range(5)]), 2, len(s)) if tr.warm else 1
    tr.g.add(
        ca.vec((lifted - P_all) * row_scale),
        0,
        0,
        f"lifted samples (phase {k + 1})",
        [w for w in where for _ in range(10)],
    )
    Y = ca.MX.sym(f"Y{k}", NY, len(s))  # the samples' outputs (see assemble)
    sigma = np.full(len(s), float(tr.signs[k]))
    tr.blocks.append(SampleBlock(lifted, Y, sigma))
    tau, qd = Y[TAU, :], Y[QD, :]
    _gamma_constraints(tr, k, curve, s[m:])
    if tr.problem.arm.kind != "PPR":
        reach = Y[REACH, :]
        tr.g.add(reach.T, REACH_EPS[tr.problem.arm.kind], ca.inf, f"reach (phase {k + 1})", where)
    _limit_constraints(tr, {"tau": tau, "q": Y[Q, :], "qd": qd}, where)
    w = samples.weights
    if "torque" in tr.cost_terms:
        tr.cost_terms["torque"] += h * ca.dot(w, squared_norm(tau[:, :m]).T)
    if "energy" in tr.cost_terms:
        consistent = mapped_outputs(tr.problem.arm, len(s))(P_all, ca.DM(sigma).T)
        _energy(tr, k, h, Y, consistent, samples)
    if "v_squared" in tr.cost_terms:
        tr.cost_terms["v_squared"] += h * ca.dot(w, squared_norm(D[4][:m, :].T).T)
    _node_constraints(tr, k, h)


def _gamma_constraints(tr: _Transcription, k: int, curve, extra: np.ndarray) -> None:
    """|gamma| >= gamma_min on ``tr.gamma_grid`` equally spaced points and at the extra
    samples (gamma is cheap: the norm of the CP's acceleration plus g0 e_y)."""
    g0 = tr.problem.arm.gravity
    gmin = (tr.margin if tr.margin is not None else tr.settings.gamma_min) * (1 + GAMMA_SAFETY)
    s_gamma = np.r_[np.linspace(0.0, 1.0, tr.gamma_grid), extra]
    # a pinned switch holds |gamma| = gamma_min at the node exactly; the grid's copy would be
    # a redundant active constraint there
    keep = ~(((s_gamma == 0) & tr.pinned_switch(k)) | ((s_gamma == 1) & tr.pinned_switch(k + 1)))
    s_gamma = s_gamma[keep]
    acc = curve.derivatives(s_gamma, 3)[2] + ca.repmat(ca.DM([[0, g0]]), len(s_gamma), 1)
    tr.g.add(
        ca.sum2(acc**2) - gmin**2,
        0,
        ca.inf,
        f"|gamma| >= gamma_min (phase {k + 1})",
        [(k, float(sj)) for sj in s_gamma],
    )


def _limit_constraints(tr: _Transcription, quantities: dict, where: list) -> None:
    """The arm's limits at every sample (magnitude limits kept LIMIT_SAFETY inside)."""
    limit: Limit
    for limit in tr.problem.limits:
        lo, hi = limit.bounds(LIMIT_SAFETY)
        values = quantities[limit.quantity][limit.joint, :].T
        tr.g.add(values, lo, hi, limit.label, where)


def _energy(tr: _Transcription, k: int, h, Y, consistent, samples: PhaseSamples) -> None:
    """|tau_i q_i'| through its epigraph: slack >= +-power, exact and smooth for Ipopt."""
    m = samples.quadrature
    power = Y[TAU, :m] * Y[QD, :m][:2, :]
    slack = ca.MX.sym(f"e{k}", 2, m)
    tr.lifted.append(ca.vec(slack))
    tr.lifted_values.append(ca.vec(ca.fabs(consistent[TAU, :m] * consistent[QD, :m][:2, :])))
    where = [(k, float(sj)) for sj in samples.s[:m] for _ in range(2)]
    tr.g.add(ca.vec(slack - power), 0, ca.inf, f"energy slack (phase {k + 1})", where)
    tr.g.add(ca.vec(slack + power), 0, ca.inf, f"energy slack (phase {k + 1})", where)
    tr.cost_terms["energy"] += h * ca.dot(samples.weights, ca.sum1(slack).T)


def _node_constraints(tr: _Transcription, k: int, h) -> None:
    """The phase's sign of gamma at its nodes where it is free; a minimum phase duration."""
    gmin = (tr.margin if tr.margin is not None else tr.settings.gamma_min) * (1 + GAMMA_SAFETY)
    for i, after, tn in ((k, True, 0.0), (k + 1, False, 1.0)):
        gam = tr.flat["gamma"](tr.node_state(i, after))
        if tr.depends_on_decisions(gam) and not tr.pinned_switch(i):
            tr.g.add(
                tr.signs[k] * gam - gmin,
                0,
                ca.inf,
                f"sign(gamma) at node (phase {k + 1})",
                [(k, tn)],
            )
    if tr.depends_on_decisions(h):
        tr.g.add(h, MIN_PHASE, ca.inf, f"phase {k + 1} duration >= {MIN_PHASE}", [(k, 0.0)])


def _switch_constraints(tr: _Transcription) -> None:
    """With ``smooth_torque``, |gamma| at the margin on both sides of a via state where the
    sign changes: the xi reset, and with it the torque step, is the smallest the margin
    allows (alpha, shared by both sides, keeps the rest of the torque continuous)."""
    gmin = tr.settings.gamma_min * (1 + GAMMA_SAFETY)
    for i in range(1, len(tr.signs)):
        if not tr.pinned_switch(i):
            continue
        for after, sign in ((False, tr.signs[i - 1]), (True, tr.signs[i])):
            gam = tr.flat["gamma"](tr.node_state(i, after))
            if tr.depends_on_decisions(gam):
                side = "after" if after else "before"
                tr.g.add(
                    sign * gam - gmin,
                    0,
                    0,
                    f"{tr.names[i]}: |gamma| = gamma_min {side} the switch",
                    [(i - 1 + after, 0.0 if after else 1.0)],
                )


def _holding_constraints(tr: _Transcription) -> None:
    """xi = 0 at held rest ends whose xi is free."""
    for i, hold in enumerate(tr.holding):
        name = tr.names[i]
        if hold and f"{name}.xi" in tr.problem.free:
            tr.g.add(
                tr.sym[f"{name}.xi"], 0, 0, f"{name}: xi = 0 for the holding torque", [(0, 0.0)]
            )


def _whole_motion_terms(tr: _Transcription) -> None:
    """Objective terms of the whole motion: its duration, the gamma margin (kept >= gamma_min)."""
    if "duration" in tr.cost_terms:
        tr.cost_terms["duration"] = tr.sym["duration"]
    if "gamma_margin" in tr.cost_terms:
        tr.cost_terms["gamma_margin"] = -tr.margin
        tr.g.add(tr.margin, tr.settings.gamma_min, ca.inf, "gamma margin >= gamma_min", [(0, 0.0)])


def _consistent_lifts(tr: _Transcription) -> ca.MX:
    """The lifted variables' values as functions of the core variables alone (the samples'
    values go through lifted node derivatives: those are replaced by what they stand for)."""
    values = ca.vertcat(*tr.lifted_values)
    if not tr.node_lifts:
        return values
    lifted, stand_for = zip(*tr.node_lifts.values(), strict=True)
    return ca.substitute(
        values, ca.vertcat(*map(ca.vec, lifted)), ca.vertcat(*map(ca.vec, stand_for))
    )


def _finish(tr: _Transcription) -> FlatNLP:
    """Assemble the NLP and its helper functions, create the solver."""
    o = tr.settings
    w = weights(o.objective)
    cost = sum(w[k] * tr.cost_terms[k] for k in w)
    x_core = tr.layout.vector()
    x = ca.vertcat(x_core, *tr.lifted)
    p_names = [n for n in tr.sym if n not in tr.problem.free]
    p = ca.vertcat(*[tr.sym[n] for n in p_names])
    g = ca.vertcat(*tr.g.exprs)
    hessian = o.solver.hessian or default_hessian(o.objective)
    nlp = assemble(x, p, cost, g, tr.blocks, tr.problem.arm, CURVATURE[hessian])
    reporter = IterationReporter(x.numel(), g.numel(), p.numel())
    opts = {
        "print_time": False,
        "show_eval_warnings": False,
        "ipopt": {
            **ipopt_options(o.solver),
            **(warm_options(o.solver, tr.from_plan) if tr.warm else {}),
            **(RESUME_OPTIONS if tr.resume else {}),
            **dict(tr.ipopt),
        },
        "iteration_callback": reporter,
        **nlp.options,
    }
    solver = ca.nlpsol("flat", "ipopt", {"x": x, "p": p, "f": nlp.f, "g": nlp.g}, opts)
    values = ca.vertcat(*[tr.value(n) for n in tr.sym])
    Y = ca.horzcat(*[b.Y for b in tr.blocks])
    outs = ca.Function(
        "unpack_y", [x, p, Y], [values, *tr.coefficients, *[tr.cost_terms[k] for k in w]]
    )
    return FlatNLP(
        solver=solver,
        layout=tr.layout,
        p_names=p_names,
        lbg=np.array(tr.g.lower, float),
        ubg=np.array(tr.g.upper, float),
        rows=tr.g.rows,
        unpack=ca.Function("unpack", [x, p], outs(x, p, nlp.outputs(x, p))),
        lift=ca.Function("lift", [x_core, p], [_consistent_lifts(tr)]),
        constraints=ca.Function("constraints", [x, p], [nlp.g]),
        samples=tuple(tr.samples),
        reporter=reporter,
    )
