"""The flat optimizer: CP curves as B-splines, free compensator values, Ipopt.

The NLP (:mod:`~cpopt.flatopt.transcribe`) has the B-spline coefficients, the freed node values
and the compensator inputs as decision variables (:mod:`~cpopt.flatopt.layout`); it starts from
the closed form (:mod:`~cpopt.flatopt.warm_start`); after each solve gamma is certified exactly
and the limits are checked between the samples, and samples are added where they fail
(:mod:`~cpopt.flatopt.refine`). With ``curve: path_timing`` each phase's CP follows a path at
the pace of a timing law instead (:mod:`~cpopt.flatopt.path_timing`): another curve family
feeding the same NLP.

Each phase keeps its own sign of gamma. gamma depends on (xi, theta, thetadot): theta and
thetadot are continuous at via states, so two phases meeting at a via state share their sign
unless xi is reset there (``xi_after``). Which patterns of signs are tried, and where the
optimizer adds via states that reset xi to switch the sign (``gamma_switches``), is
:mod:`~cpopt.flatopt.switching`'s job; every pattern solved is reported.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

from ..closedform.curves import with_end_jets
from ..closedform.nodes import node_names, nodes_from_values, to_file
from ..closedform.plan import CPPlan, Phase
from ..closedform.trajectory import Trajectory, reachable
from ..model import flat
from ..model.objectives import weights
from ..problem import Problem
from ..runtime import progress
from ..runtime.budget import remaining, stopped_by_time
from ..runtime.solver import SolverStats, run_nlp
from . import basis, switching
from .basis import refine_basis
from .feasible_start import RESTORED, evaluable_start, restored_run
from .path_timing import chosen_points
from .refine import (
    CERTIFICATION,
    MAX_REFINEMENTS,
    between_samples,
    cost_kept,
    quadrature_gaps,
    unrefined_flaw,
    violations,
)
from .restart import restart
from .samples import sample_library
from .seeded import search as seeded_search
from .stopped import Recorded, stopped_search
from .transcribe import FlatNLP, build, initial_grids, phase_pieces
from .warm_start import exact_plan, initial_guess, seeded_guess

SIGN_NAMES = {1: "positive", -1: "negative"}
"""The words for the signs of gamma, as ``gamma_sign`` spells them."""


@dataclass(frozen=True)
class SignAttempt:
    """The outcome of solving for one pattern of signs of gamma (refinement rounds included).

    Attributes
    ----------
    signs : tuple of str
        The sign of gamma of each phase of the plan (``positive``, ``negative``).
    switch_times : tuple of float
        The times of the via states the optimizer added to switch the sign [s].
    active_gamma : tuple of (float, float)
        Where the margin |gamma| >= gamma_min binds: (time [s], multiplier) of each such
        constraint, for the search of :mod:`~cpopt.flatopt.switching`.
    """

    signs: tuple[str, ...]
    switch_times: tuple[float, ...]
    status: str
    ipopt_status: str
    objective: float
    cost_terms: dict
    iterations: int
    certified_min_abs_gamma: float
    refinements: int
    plan: CPPlan = field(repr=False)
    violations: tuple[str, ...] = ()
    build_time_s: float = 0.0
    solve_time_s: float = 0.0
    active_gamma: tuple[tuple[float, float], ...] = field(default=(), repr=False)

    @property
    def sign(self) -> str:
        """The sign of gamma of the first phase (of every phase without switches or xi
        resets)."""
        return self.signs[0]

    def as_dict(self) -> dict:
        """JSON-ready figures (without the plan)."""
        keys = (
            "sign", "signs", "switch_times", "status", "ipopt_status", "objective",
            "cost_terms", "iterations", "certified_min_abs_gamma", "refinements",
        )  # fmt: skip
        out = {k: getattr(self, k) for k in keys}
        out["time_s"] = self.build_time_s + self.solve_time_s
        return {k: list(v) if isinstance(v, tuple) else v for k, v in out.items()}


@dataclass(frozen=True)
class FlatDetails:
    """What the flat optimizer reports beyond the common solver statistics.

    Attributes
    ----------
    gamma_signs : tuple of str
        The sign of gamma of each phase of the returned plan.
    switch_times : tuple of float
        The times of the via states the optimizer added to switch the sign [s].
    sign_choices : tuple of SignAttempt
        Every pattern of signs (and switches) solved, in the order tried.
    search : str
        How the pattern was chosen, in one line.
    search_figures : dict
        ``solver.search`` in ``solution.json``: the method (``seed``, ``greedy``, or only a
        summary without switches) and the seeded search's stages (seed, flat, polish) with
        their iterations and wall times [s].
    """

    gamma_signs: tuple[str, ...]
    switch_times: tuple[float, ...]
    certified_min_abs_gamma: float
    refinements: int
    sign_choices: tuple[SignAttempt, ...]
    search: str = ""
    certification: str = CERTIFICATION
    search_figures: dict = field(default_factory=dict)

    @property
    def gamma_sign(self) -> str:
        """The sign of gamma of the first phase."""
        return self.gamma_signs[0]

    def as_dict(self) -> dict:
        """JSON-ready figures for ``solution.json``."""
        return {
            "gamma_sign": self.gamma_sign,
            "gamma_signs": list(self.gamma_signs),
            "switch_times": list(self.switch_times),
            "search": self.search_figures or {"summary": self.search},
            "certified_min_abs_gamma": self.certified_min_abs_gamma,
            "certification": self.certification,
            "refinements": self.refinements,
            "sign_choices": [a.as_dict() for a in self.sign_choices],
        }


@dataclass(frozen=True)
class OptimizeResult:
    """Outcome of :func:`optimize`.

    Attributes
    ----------
    status : str
        ``solved``, ``infeasible``, ``max_iterations`` or ``not_converged``.
    plan : CPPlan or None
        The optimal plan, or Ipopt's best iterate when it failed.
    solver : SolverStats
        Iterations, times, message, objective and the flat optimizer's details.
    """

    status: str
    plan: CPPlan | None
    solver: SolverStats

    @property
    def violations(self) -> tuple[str, ...]:
        """The constraints the returned plan violates, by name and time."""
        return self.solver.violations


def plan_from(
    problem: Problem,
    nlp: FlatNLP,
    x: np.ndarray,
    p: np.ndarray,
    signs: tuple[int, ...],
    switches: tuple[int, ...] = (),
):
    """Unpack a decision vector into a CPPlan, its node times and the cost terms.

    ``switches`` are the indices of the via states the optimizer added; the plan's free values
    are named as the problem file names them, and ``switch[j].<field>`` for those.
    """
    o = problem.spec.optimizer
    outs = nlp.unpack(x, p)
    values = dict(zip(problem.values, np.asarray(outs[0]).ravel(), strict=True))
    n_phases = len(problem.nodes) - 1
    nodes = nodes_from_values(values, len(problem.nodes))
    times = [node.t for node in nodes]
    phases = tuple(
        Phase(_phase_curve(problem, nodes, k, np.asarray(outs[1 + k])), sign)
        for k, sign in enumerate(signs)
    )
    w = weights(o.objective)
    terms = {k: float(v) for k, v in zip(w, outs[1 + n_phases :], strict=True)}
    shown = dict(zip(node_names(len(nodes)), node_names(len(nodes), switches), strict=True))
    free_values = {}
    for name in problem.free:
        node, dot, f = name.partition(".")
        free_values[f"{shown.get(node, node)}{dot}{f}"] = to_file(name, values[name])
    if o.curve == "path_timing":
        free_values.update(chosen_points(o.path, [outs[1 + k] for k in range(n_phases)]))
    plan = CPPlan(
        arm=problem.arm, nodes=tuple(nodes), phases=phases, planner="optimize",
        free_values=free_values, switches=tuple(switches),
    )  # fmt: skip
    return plan, times, terms


def _phase_curve(problem: Problem, nodes: list, k: int, packed: np.ndarray):
    """Phase k's CP curve; a B-spline phase ends exactly at its nodes' states
    (:func:`cpopt.curves.with_end_jets`: evaluated from its coefficients, a short phase's end
    loses digits). A path-timing phase is left as it is."""
    t0, t1 = nodes[k].t, nodes[k + 1].t
    curve = phase_pieces(problem, k, packed, t0, t1 - t0)
    if problem.spec.optimizer.curve == "path_timing":
        return curve
    K, g0 = problem.arm.K, problem.arm.gravity
    start = flat.output(nodes[k].state(after=True), K, g0)
    return with_end_jets(curve, start, flat.output(nodes[k + 1].state(), K, g0))


def _bounds(nlp: FlatNLP, problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = nlp.layout.bounds(problem.free)
    n_lifted = nlp.solver.size_in(0)[0] - nlp.layout.size
    return np.r_[lo, [-np.inf] * n_lifted], np.r_[hi, [np.inf] * n_lifted]


def active_gamma(nlp: FlatNLP, g: np.ndarray, lam_g: np.ndarray, times: list) -> tuple:
    """(time [s], multiplier) of every margin constraint on |gamma| that binds (within 1e-6
    of its bound, with a positive multiplier)."""
    out = []
    binding = (g - nlp.lbg <= 1e-6 * (1 + np.abs(nlp.lbg))) & (lam_g > 0)
    for (name, (phase, s)), lam in zip(nlp.rows, lam_g * binding, strict=True):
        if lam > 0 and name.startswith(("|gamma| >= gamma_min", "sign(gamma) at node")):
            out.append((times[phase] + s * (times[phase + 1] - times[phase]), float(lam)))
    return tuple(out)


def _row_keys(rows: list) -> list:
    """A key per constraint row that survives a refinement: its label and its rank among the
    rows of that label (the samples a refinement adds get labels of their own)."""
    seen: dict = {}
    keys = []
    for row in rows:
        seen[row] = seen.get(row, -1) + 1
        keys.append((row, seen[row]))
    return keys


def resumed_multipliers(previous: tuple, nlp: FlatNLP) -> dict:
    """``lam_x0`` and ``lam_g0`` for a refinement round from the previous round's solution
    (``previous``: its NLP and run): the core variables' and every surviving row's multipliers
    carried over, zero for the added samples' rows and lifted variables."""
    old_nlp, run = previous
    lam_x = np.zeros(nlp.solver.size_in(0)[0])
    core = nlp.layout.size
    lam_x[:core] = run.lam_x[:core]
    old = dict(zip(_row_keys(old_nlp.rows), -run.lam_g, strict=True))  # NlpRun's sign back
    lam_g = np.array([old.get(key, 0.0) for key in _row_keys(nlp.rows)])
    return {"lam_x0": lam_x, "lam_g0": lam_g}


def pattern_label(signs: tuple[int, ...], switches: int = 0) -> str:
    """How progress names a pattern: ``gamma positive``, or ``gamma -/+ (1 switch)``."""
    if len(set(signs)) == 1:
        return f"gamma {SIGN_NAMES[signs[0]]}"
    words = f"gamma {'/'.join('+' if s > 0 else '-' for s in signs)}"
    return words + (f" ({switches} switch{'es' if switches > 1 else ''})" if switches else "")


def _start(nlp: FlatNLP, problem: Problem, signs: tuple[int, ...], seed) -> np.ndarray:
    """The first round's initial vector: from the seed trajectory if there is one, else the
    closed form through the nodes."""
    if seed is None:
        return initial_guess(nlp, problem, signs)
    return seeded_guess(nlp, problem, signs, seed)


def _round_arguments(
    nlp: FlatNLP, problem: Problem, signs, seed, previous, deadline: float = math.inf
) -> dict:
    """nlpsol's arguments for a round: the first starts from the seed trajectory or the closed
    form, moved where its objective is a number when it is not
    (:func:`~cpopt.flatopt.feasible_start.evaluable_start`); a refinement round from the
    previous round's solution (``previous``: its NLP and run), its core variables lifted onto
    the new samples, with its multipliers."""
    p = nlp.parameters(problem.values)
    lbx, ubx = _bounds(nlp, problem)
    arguments = {"p": p, "lbx": lbx, "ubx": ubx, "lbg": nlp.lbg, "ubg": nlp.ubg}
    if previous is None:
        arguments["x0"] = _start(nlp, problem, signs, seed)
        damped = seed is not None and len(set(signs)) > 1  # a pattern of the switch search
        arguments["x0"], _ = evaluable_start(nlp, arguments, deadline, damped)
    else:
        arguments["x0"] = nlp.complete(previous[1].x, p)
        arguments.update(resumed_multipliers(previous, nlp))
    return arguments


def _round_limit(limit, iterations: int, previous, refine_past_limit: bool):
    """The iteration cap of a round (None for Ipopt's own): what is left of ``limit``; a
    refinement round, resumed from a solved one (``previous``: its NLP and run), at most
    :data:`REFINE_LIMIT` (a long run there means the grid is not enough), and only that with
    ``refine_past_limit``; at most :data:`RESTORED_REFINE_LIMIT` after a restored round."""
    left = None if limit is None else max(limit - iterations, 1)
    if previous is None:
        return left
    most = RESTORED_REFINE_LIMIT if previous[1].return_status.startswith(RESTORED) else REFINE_LIMIT
    return most if refine_past_limit else min(left or most, most)


def _unpacked(problem: Problem, nlp: FlatNLP, run, arguments: dict, signs, switches):
    """(run, plan, node times, cost terms) of a round; a failed run whose iterate diverged so
    far that its node times no longer increase reports its start instead (objective NaN)."""
    p = arguments["p"]
    try:
        return (run, *plan_from(problem, nlp, run.x, p, signs, switches))
    except ValueError:
        if run.status == "solved":
            raise
        run = replace(run, x=arguments["x0"], objective=math.nan)
        return (run, *plan_from(problem, nlp, run.x, p, signs, switches))


def solve_for_signs(
    problem: Problem,
    signs: tuple[int, ...],
    switches: tuple[int, ...] = (),
    seed: Trajectory | None = None,
    limit: int | None = None,
    abandon=None,
    deadline: float = math.inf,
    refine_past_limit: bool = False,
) -> SignAttempt:
    """Solve for one pattern of signs of gamma (one per phase), refining the sample grid until
    the margin is certified.

    Parameters
    ----------
    problem : Problem
        The problem, with the via states the optimizer added among its nodes.
    signs : tuple of int
        The sign of gamma of each phase, +1 or -1.
    switches : tuple of int
        The indices of the nodes the optimizer added (:func:`cpopt.nodes.node_names`).
    seed : Trajectory, optional
        A trajectory to start from (:func:`~cpopt.flatopt.warm_start.seeded_guess`) instead of
        the closed form through the nodes.
    limit : int, optional
        Most Ipopt iterations over all rounds (a cheap attempt of the search's polish).
    abandon : callable, optional
        ``abandon(iteration, objective, infeasibility) -> bool``: stop a run another pattern
        has clearly beaten (status ``dominated``, :func:`cpopt.flatopt.dominance.dominated`).
    deadline : float
        ``time.monotonic()`` by which the solve returns what it has (status ``time_limit``
        when no round solved by then; a refinement round cut there keeps the last solved one).
    refine_past_limit : bool
        ``limit`` caps the rounds before the first solved one only: a solved plan gets its
        refinement rounds (each at most :data:`REFINE_LIMIT` iterations).
    """
    grids = initial_grids(problem)
    exact = seed is not None and exact_plan(seed)
    previous, iterations, build_time, solve_time = None, 0, 0.0, 0.0
    plan = times = None  # the last unpacked round's: the previous one when a round is cut
    refinements = 0
    pattern = pattern_label(signs, len(switches))
    for round_ in range(1, 2 + MAX_REFINEMENTS):
        label = pattern + (f", refinement {round_ - 1}" if round_ > 1 else "")
        progress.stage(f"flat optimizer: {label}")
        tic = time.perf_counter()
        # every round of a seeded solve keeps its rows in normalised time: a refinement round
        # takes the previous round's multipliers, which are in the rows' own units
        nlp = build(problem, signs, grids, seed is not None, previous is not None, None, exact)
        build_time += time.perf_counter() - tic  # ~0 when the solver was cached
        arguments = _round_arguments(nlp, problem, signs, seed, previous, deadline)
        left = _round_limit(limit, iterations, previous, refine_past_limit)
        run = run_nlp(nlp.solver, nlp.reporter, label, left, abandon, deadline, True, **arguments)
        solve_time += run.solve_time_s
        iterations += run.iterations
        if run.status == "time_limit" and round_ > 1:  # the last solved round stands, if it may
            nlp, run = previous
            run = _checked_at_deadline(problem, run, plan, times, nlp)
            break
        run = restored_run(nlp, arguments, run, deadline)  # a cut run's nearly feasible iterate
        run, plan, times, terms = _unpacked(problem, nlp, run, arguments, signs, switches)
        if previous is not None and run.status == "solved":
            run = cost_kept(run, previous[1], refinements)
        if run.status != "solved":
            break
        if time.monotonic() > deadline:  # no time to refine: the next round's checks, once
            run = _checked_at_deadline(problem, run, plan, times, nlp)
            break
        dips = between_samples(problem, plan, times)
        gaps = quadrature_gaps(problem, plan, nlp)
        if not any(dips) and not any(gaps):
            break
        grids = tuple(g.refined(*new) for g, *new in zip(grids, gaps, dips, strict=True))
        previous = (nlp, run)
        refinements += 1
    run = solved_if_certified(problem, run, plan, refinements)
    counts = (iterations, refinements, build_time, solve_time)
    return _attempt(nlp, run, arguments["p"], (plan, times, terms), signs, switches, counts)


def _checked_at_deadline(problem: Problem, run, plan: CPPlan, times: list, nlp: FlatNLP):
    """The solved run of a plan the deadline kept from its refinement rounds,
    ``not_converged`` when the next round's checks find it mispriced
    (:func:`~cpopt.flatopt.refine.unrefined_flaw`)."""
    flaw = unrefined_flaw(problem, plan, times, nlp)
    return run if flaw is None else replace(run, status="not_converged", return_status=flaw)


def solved_if_certified(problem: Problem, run, plan: CPPlan, refinements: int):
    """The run, ``not_converged`` when it solved but its refinements left the certified |gamma|
    below gamma_min (Ipopt's word ``Gamma_Not_Certified_After_<n>_Refinements``): a plan
    whose gamma dips to zero between its samples is singular, whatever Ipopt says (a random
    RPR swing-down's one-sign plan, 0.001 m/s^2, whose simulation then diverged); and
    ``unreachable`` when it leaves the arm's reach between its samples
    (``Out_Of_Reach_Between_Samples``; :func:`cpopt.closedform.trajectory.reachable`): the search
    samples its best plan to seed the next patterns, and a random RRR swing-down's plan,
    solved on its grid, raised there."""
    if run.status != "solved":
        return run
    gamma_min = problem.spec.optimizer.gamma_min
    if plan.min_abs_gamma()[0] < gamma_min * (1 - CERTIFY_TOLERANCE):
        word = f"Gamma_Not_Certified_After_{refinements}_Refinements"
        return replace(run, status="not_converged", return_status=word)
    if reachable(plan) is None:
        return replace(run, status="unreachable", return_status="Out_Of_Reach_Between_Samples")
    return run


CERTIFY_TOLERANCE = 1e-3
"""How far below gamma_min [fraction] a solved plan's certified |gamma| may end (the NLP's
rows hold gamma_min at its samples to Ipopt's tolerance)."""


def _attempt(nlp: FlatNLP, run, p, unpacked, signs, switches, counts) -> SignAttempt:
    """The SignAttempt of a solve's last round (``unpacked``: its plan, node times and cost
    terms; ``p`` the solver's parameters); ``counts`` are the iterations, refinements, build
    and solve times [s] of all its rounds."""
    plan, times, terms = unpacked
    iterations, refinements, build_time, solve_time = counts
    # constraints of the plan the user gets: lifted samples recomputed from the core variables
    g = np.asarray(nlp.constraints(nlp.complete(run.x, p), p)).ravel()
    return SignAttempt(
        signs=tuple(SIGN_NAMES[s] for s in signs),
        switch_times=tuple(float(plan.nodes[i].t) for i in switches),
        status=run.status,
        ipopt_status=run.return_status,
        objective=run.objective,
        cost_terms=terms,
        iterations=iterations,
        certified_min_abs_gamma=plan.min_abs_gamma()[0],
        refinements=refinements,
        plan=plan,
        violations=tuple(violations(nlp, g, times)),
        build_time_s=build_time,
        solve_time_s=solve_time,
        active_gamma=active_gamma(nlp, g, run.lam_g, times),
    )


REFINE_LIMIT = 400
"""Most Ipopt iterations of a refinement round, which resumes from a solved round (7-50 on the
bundled problems, more than 150 on a random RRR swing-up's seeded pattern, whose first round
under-sampled its cost by 14 %; a random RPR swing-down's losing sign of gamma ran its 1000
there and did not solve)."""
RESTORED_REFINE_LIMIT = 100
"""Most Ipopt iterations of a refinement round after a restored round
(:func:`cpopt.flatopt.feasible_start.restored_run`), its nearly feasible iterate restored
again when cut: from a restored iterate, which is no optimum, a random PPR swing-down's
refinement rounds crept for 490 iterations to the search's deadline."""
RESERVE = 0.15
"""The fraction of the time left when the optimizer starts that its searches leave to what
follows them (sampling and verifying the plan), at least :data:`RESERVE_MIN` and at most
:data:`RESERVE_MAX` seconds."""
RESERVE_MIN = 0.25
RESERVE_MAX = 1.0


def search_deadline() -> float:
    """``time.monotonic()`` by which a search returns its best plan: the active time limit
    (:func:`cpopt.budget.remaining`) less a reserve for verification (none without a limit)."""
    left = remaining()
    return time.monotonic() + left - min(max(RESERVE * left, RESERVE_MIN), RESERVE_MAX)


def optimize(problem: Problem, start: CPPlan | None = None) -> OptimizeResult:
    """Optimize a problem's plan with Ipopt (see the module docstring).

    Parameters
    ----------
    problem : Problem
        A problem with ``planner: optimize``.
    start : CPPlan, optional
        A plan of a neighbouring problem (another mass, duration, limit) to start from: its
        pattern of signs of gamma is solved once from it, without the switch search
        (:mod:`cpopt.flatopt.restart`); the usual search runs when that does not solve.

    Returns
    -------
    OptimizeResult
        The best plan over the patterns of signs of gamma tried, with an honest status: a
        failed solve returns Ipopt's best iterate, its status and the violated constraints by
        name and time.
    """
    sample_library(problem.arm.kind)  # compiled first on a fresh machine: not counted below
    deadline = search_deadline()
    solve = Recorded(partial(solve_for_signs, deadline=deadline))
    try:
        search = _search(problem, start, solve, deadline)
    except BaseException as err:  # a stage overran the deadline and the time limit struck
        search = stopped_search(problem, solve.made) if stopped_by_time(err) else None
        if search is None:
            raise
    return result_of(search)


def result_of(search: switching.Search) -> OptimizeResult:
    """The OptimizeResult of a search: its best plan, status and message, the iterations and
    times of every attempt (the seeded search's collocation seed included) and its figures."""
    attempts, best = search.attempts, search.best
    if len(set(best.signs)) == 1:
        message = f"Ipopt: {best.ipopt_status} (sign of gamma: {best.sign})"
    else:
        message = f"Ipopt: {best.ipopt_status} (signs of gamma: {'/'.join(best.signs)})"
    if best.status != "solved" and best.violations:
        message += "; violated: " + "; ".join(best.violations[:3])
    seed = search.figures.get("seed", {})  # the seeded search's collocation counts too
    stats = SolverStats(
        iterations=sum(a.iterations for a in attempts) + seed.get("iterations", 0),
        build_time_s=sum(a.build_time_s for a in attempts) + seed.get("build_time_s", 0.0),
        solve_time_s=sum(a.solve_time_s for a in attempts) + seed.get("solve_time_s", 0.0),
        message=message,
        objective=best.objective,
        cost_terms=best.cost_terms,
        violations=best.violations,
        details=FlatDetails(
            gamma_signs=best.signs,
            switch_times=best.switch_times,
            certified_min_abs_gamma=best.certified_min_abs_gamma,
            refinements=best.refinements,
            sign_choices=tuple(attempts),
            search=search.summary,
            search_figures=search.figures,
        ),
    )
    return OptimizeResult(status=best.status, plan=best.plan, solver=stats)


def _search(problem: Problem, start: CPPlan | None, solve, deadline: float):
    """The search the problem asks for (started from ``start`` when given), its plan's basis
    refined as ``refine_basis`` asks (:func:`cpopt.flatopt.basis.wanted`)."""
    o = problem.spec.optimizer
    search, why_not, started = None, "", time.monotonic()
    if start is not None:
        progress.stage("flat optimizer: started from the given plan")
        search, why_not = restart(problem, solve, start)
    if search is None:
        seeded = o.gamma_switches != 0 and o.switch_search == "seed"
        search = (seeded_search if seeded else switching.search)(problem, solve, deadline)
        if why_not:
            summary = f"{why_not}: the usual search; {search.summary}"
            search = replace(
                search, summary=summary, figures={**search.figures, "summary": summary}
            )
    if basis.wanted(o.refine_basis, o.curve, search):
        search = _with_finer_basis(problem, solve, search, (started, deadline))
    return search


def _with_finer_basis(problem: Problem, solve, search, clock: tuple):
    """The search with its plan's basis refined (:func:`cpopt.flatopt.basis.refine_basis`):
    the refinements among its attempts, their figures as ``solver.search.basis``; ``clock``
    the search's start and deadline (``time.monotonic()`` instants). With ``refine_basis:
    auto`` the refinements stop within :data:`~cpopt.flatopt.basis.AUTO_GAP` of the seed and
    by :func:`~cpopt.flatopt.basis.auto_deadline`."""
    started, deadline = clock
    gap = basis.seed_gap(search)
    if problem.spec.optimizer.refine_basis == "auto":
        seed_objective = search.best.objective / (1.0 + gap)
        target = (1.0 + basis.AUTO_GAP) * seed_objective
        deadline = basis.auto_deadline(started, deadline)
        why = f"refined automatically, the plan {gap:.1%} above the seed"
    else:
        target, why = -math.inf, "refined as asked"
    best, more, figures = refine_basis(problem, solve, search.best, deadline, target)
    figures = {**figures, "seed_gap": gap, "summary": f"{why}; {figures['summary']}"}
    summary = f"{search.summary}; basis: {figures['summary']}"
    return replace(
        search,
        attempts=(*search.attempts, *more),
        best=best,
        summary=summary,
        figures={**search.figures, "summary": summary, "basis": figures},
    )


__all__ = ["SIGN_NAMES", "FlatDetails", "OptimizeResult", "SignAttempt", "optimize"]
