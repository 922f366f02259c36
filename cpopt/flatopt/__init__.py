"""The flat optimizer: CP curves as B-splines, free compensator values, Ipopt.

The NLP (:mod:`~cpopt.flatopt.transcribe`) has the B-spline coefficients, the freed node values
and the compensator inputs as decision variables (:mod:`~cpopt.flatopt.layout`); it starts from
the closed form (:mod:`~cpopt.flatopt.warm_start`); after each solve gamma is certified exactly
and the limits are checked between the samples, and samples are added where they fail
(:mod:`~cpopt.flatopt.refine`). With ``curve: path_timing`` each phase's CP follows a path at
the pace of a timing law instead (:mod:`~cpopt.flatopt.path_timing`): another curve family
feeding the same NLP.

The sign of gamma is one for the whole motion: gamma depends on (xi, theta, thetadot), all
continuous at via states (an eta reset does not change it), so two phases meeting at a via state
share their sign. ``auto`` tries both signs and keeps the better solution.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .. import flat, progress
from ..nodes import gamma_is_free, node_names, nodes_from_values, to_file
from ..objectives import weights
from ..plan import CPPlan, Phase
from ..problem import Problem
from ..solver import SolverStats, run_nlp
from .path_timing import chosen_points
from .refine import (
    CERTIFICATION,
    MAX_REFINEMENTS,
    between_samples,
    quadrature_gaps,
    violations,
)
from .transcribe import FlatNLP, build, initial_grids, phase_pieces
from .warm_start import initial_guess


@dataclass(frozen=True)
class SignAttempt:
    """The outcome of solving for one sign of gamma (refinement rounds included)."""

    sign: str
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

    def as_dict(self) -> dict:
        """JSON-ready figures (without the plan)."""
        keys = (
            "sign", "status", "ipopt_status", "objective", "cost_terms", "iterations",
            "certified_min_abs_gamma", "refinements",
        )  # fmt: skip
        return {k: getattr(self, k) for k in keys}


@dataclass(frozen=True)
class FlatDetails:
    """What the flat optimizer reports beyond the common solver statistics."""

    gamma_sign: str
    certified_min_abs_gamma: float
    refinements: int
    sign_choices: tuple[SignAttempt, ...]
    certification: str = CERTIFICATION

    def as_dict(self) -> dict:
        """JSON-ready figures for ``solution.json``."""
        return {
            "gamma_sign": self.gamma_sign,
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


def signs_to_try(problem: Problem) -> list[int]:
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
    for name, node in zip(node_names(len(problem.nodes)), problem.nodes, strict=True):
        if not gamma_is_free(name, problem.free):
            fixed.append(float(flat.gamma(node.state(), arm.K, arm.gravity)))
    signs = {int(np.sign(g)) for g in fixed if abs(g) > 0}
    return sorted(signs) if signs else [-1, 1]


def plan_from(problem: Problem, nlp: FlatNLP, x: np.ndarray, p: np.ndarray, sign: int):
    """Unpack a decision vector into a CPPlan, its node times and the cost terms."""
    o = problem.spec.optimizer
    outs = nlp.unpack(x, p)
    values = dict(zip(problem.values, np.asarray(outs[0]).ravel(), strict=True))
    n_phases = len(problem.nodes) - 1
    nodes = nodes_from_values(values, len(problem.nodes))
    times = [node.t for node in nodes]
    phases = tuple(
        Phase(
            phase_pieces(problem, k, np.asarray(outs[1 + k]), times[k], times[k + 1] - times[k]),
            sign,
        )
        for k in range(n_phases)
    )
    w = weights(o.objective)
    terms = {k: float(v) for k, v in zip(w, outs[1 + n_phases :], strict=True)}
    free_values = {name: to_file(name, values[name]) for name in problem.free}
    if o.curve == "path_timing":
        free_values.update(chosen_points(o.path, [outs[1 + k] for k in range(n_phases)]))
    plan = CPPlan(
        arm=problem.arm, nodes=tuple(nodes), phases=phases, planner="optimize",
        free_values=free_values,
    )  # fmt: skip
    return plan, times, terms


def _bounds(nlp: FlatNLP, problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = nlp.layout.bounds(problem.free)
    n_lifted = nlp.solver.size_in(0)[0] - nlp.layout.size
    return np.r_[lo, [-np.inf] * n_lifted], np.r_[hi, [np.inf] * n_lifted]


def solve_for_sign(problem: Problem, sign: int) -> SignAttempt:
    """Solve for one sign of gamma, refining the sample grid until the margin is certified."""
    grids, x0 = initial_grids(problem), None
    build_time = solve_time = 0.0
    iterations = refinements = 0
    word = "positive" if sign > 0 else "negative"
    for round_ in range(1, 2 + MAX_REFINEMENTS):
        label = f"gamma {word}" + (f", refinement {round_ - 1}" if round_ > 1 else "")
        progress.stage(f"flat optimizer: {label}")
        tic = time.perf_counter()
        nlp = build(problem, sign, grids)
        build_time += time.perf_counter() - tic  # ~0 when the solver was cached
        p = nlp.parameters(problem.values)
        # a refinement round keeps the core variables and lifts them onto the new samples
        x0 = initial_guess(nlp, problem, sign) if x0 is None else nlp.complete(x0, p)
        lbx, ubx = _bounds(nlp, problem)
        run = run_nlp(
            nlp.solver, nlp.reporter, label, x0=x0, p=p, lbx=lbx, ubx=ubx, lbg=nlp.lbg, ubg=nlp.ubg
        )
        solve_time += run.solve_time_s
        iterations += run.iterations
        plan, times, terms = plan_from(problem, nlp, run.x, p, sign)
        if run.status != "solved":
            break
        dips = between_samples(problem, plan, times)
        gaps = quadrature_gaps(problem, plan, nlp)
        if not any(dips) and not any(gaps):
            break
        grids = tuple(g.refined(*new) for g, *new in zip(grids, gaps, dips, strict=True))
        x0 = run.x
        refinements += 1
    # constraints of the plan the user gets: lifted samples recomputed from the core variables
    g = np.asarray(nlp.constraints(nlp.complete(run.x, p), p)).ravel()
    return SignAttempt(
        sign="positive" if sign > 0 else "negative",
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
    )


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
    attempts = [solve_for_sign(problem, sign) for sign in signs_to_try(problem)]
    solved = [a for a in attempts if a.status == "solved"]
    best = min(solved or attempts, key=lambda a: a.objective)
    message = f"Ipopt: {best.ipopt_status} (sign of gamma: {best.sign})"
    if best.status != "solved" and best.violations:
        message += "; violated: " + "; ".join(best.violations[:3])
    stats = SolverStats(
        iterations=sum(a.iterations for a in attempts),
        build_time_s=sum(a.build_time_s for a in attempts),
        solve_time_s=sum(a.solve_time_s for a in attempts),
        message=message,
        objective=best.objective,
        cost_terms=best.cost_terms,
        violations=best.violations,
        details=FlatDetails(
            gamma_sign=best.sign,
            certified_min_abs_gamma=best.certified_min_abs_gamma,
            refinements=best.refinements,
            sign_choices=tuple(attempts),
        ),
    )
    return OptimizeResult(status=best.status, plan=best.plan, solver=stats)


__all__ = ["FlatDetails", "OptimizeResult", "SignAttempt", "optimize"]
