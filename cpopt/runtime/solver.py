"""The solver call shared by the planners: Ipopt's options from a problem's settings, Ipopt's
return status mapped to cpopt's statuses, and typed solver statistics.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Protocol

import casadi as ca
import numpy as np

from . import progress
from .budget import check_stop

IPOPT_STATUS = {
    "Solve_Succeeded": "solved",
    "Solved_To_Acceptable_Level": "solved",
    "Infeasible_Problem_Detected": "infeasible",
    "Maximum_Iterations_Exceeded": "max_iterations",
    "Maximum_CpuTime_Exceeded": "max_iterations",
    "Maximum_WallTime_Exceeded": "time_limit",
}
"""Ipopt's return status -> cpopt's status; any other return status is ``not_converged``."""


def status_of(return_status: str) -> str:
    """cpopt's status (``solved``, ``infeasible``, ...) for an Ipopt return status."""
    return IPOPT_STATUS.get(return_status, "not_converged")


DEFAULT_MU_STRATEGY = "adaptive"
"""Ipopt's barrier update where ``optimizer.solver.mu_strategy`` is not set (the flat
optimizer's warm starts choose their own, :func:`cpopt.flatopt.ipopt_settings.warm_options`)."""


def ipopt_options(settings, mu_strategy: bool = True) -> dict:
    """Ipopt's own options from an ``optimizer.solver`` block (a ``SolverSpec``).

    ``mu_strategy`` False leaves Ipopt's barrier update at its default (the collocation peer
    has always run with it).
    """
    options = {
        "print_level": settings.print_level,
        "max_iter": settings.max_iter,
        "tol": settings.tol,
        "max_wall_time": settings.max_time,
        "sb": "yes",
    }
    if mu_strategy:
        options["mu_strategy"] = settings.mu_strategy or DEFAULT_MU_STRATEGY
    return options


FATROP_MU_INIT = 1e-2
"""Fatrop's initial barrier parameter: its default 0.1 stalls on the benchmark transfer."""


def fatrop_options(settings) -> dict:
    """nlpsol options for Fatrop from an ``optimizer.solver`` block (a ``SolverSpec``):
    expanded SX functions and the optimal-control structure detected from the constraints."""
    return {
        "expand": True,
        "structure_detection": "auto",
        "print_time": False,
        "record_time": True,
        "fatrop.print_level": settings.print_level,
        "fatrop.max_iter": settings.max_iter,
        "fatrop.tol": settings.tol,
        "fatrop.mu_init": FATROP_MU_INIT,
    }


class PlannerDetails(Protocol):
    """What a planner reports beyond the common statistics (typed per planner)."""

    def as_dict(self) -> dict:
        """JSON-ready figures, merged into ``solution.json``'s ``solver`` entry."""


@dataclass(frozen=True)
class SolverStats:
    """How a plan was found.

    Attributes
    ----------
    iterations : int
        Ipopt iterations over every solve the planner ran.
    build_time_s, solve_time_s : float
        Time spent building the NLP and in the solver [s].
    message : str
        What the solver said, in one line.
    objective : float or None
        The objective at the returned plan (optimizing planners).
    cost_terms : mapping of str to float
        Each objective term's value, by name, before weighting.
    violations : tuple of str
        Constraints the returned plan violates, the worst place of each by name and time.
    details : PlannerDetails or None
        The planner's own figures (sign of gamma, certificate, intervals, ...).
    stage_times : mapping of str to float
        Wall time of each stage of the solve [s]: ``plan``, ``sample``, ``verify`` (and
        ``track`` with a tracking block), from :class:`cpopt.pipeline.StageRecord`.
    """

    iterations: int = 0
    build_time_s: float = 0.0
    solve_time_s: float = 0.0
    message: str = ""
    objective: float | None = None
    cost_terms: Mapping[str, float] = field(default_factory=dict)
    violations: tuple[str, ...] = ()
    details: PlannerDetails | None = None
    stage_times: Mapping[str, float] = field(default_factory=dict)

    def as_dict(self) -> dict:
        """The ``solver`` entry of ``solution.json``."""
        out = {
            "iterations": self.iterations,
            "build_time_s": self.build_time_s,
            "solve_time_s": self.solve_time_s,
            "message": self.message,
            "stage_times": dict(self.stage_times),
        }
        if self.objective is not None:
            out.update(objective=self.objective, cost_terms=dict(self.cost_terms))
        if self.details is not None:
            out.update(self.details.as_dict(), violations=list(self.violations))
        return out


@dataclass(frozen=True)
class NlpRun:
    """One call of an NLP solver.

    Attributes
    ----------
    x : numpy.ndarray
        The returned decision vector (the best iterate when the solve failed).
    objective : float
        The objective there.
    return_status : str
        Ipopt's own word.
    status : str
        cpopt's status (:func:`status_of`).
    iterations : int
        Ipopt iterations.
    solve_time_s : float
        Wall time of the call [s].
    lam_g : numpy.ndarray
        The constraints' multipliers, positive where a lower bound binds.
    lam_x : numpy.ndarray
        The variables' bound multipliers as nlpsol returns them (for a warm start).
    """

    x: np.ndarray
    objective: float
    return_status: str
    status: str
    iterations: int
    solve_time_s: float
    lam_g: np.ndarray = field(default_factory=lambda: np.zeros(0))
    lam_x: np.ndarray = field(default_factory=lambda: np.zeros(0))


def read_stats(stats: Mapping) -> tuple[str, str, int]:
    """(the solver's return status, cpopt's status, iterations) from a CasADi stats dict.

    Ipopt names its status; Fatrop returns a number (0 on success) and a ``success`` flag, and
    its failures map to ``max_iterations`` when the iteration limit was reached, else
    ``not_converged``.
    """
    status = stats.get("return_status", "unknown")
    iterations = int(stats.get("iter_count", 0))
    if isinstance(status, str):
        return status, status_of(status), iterations
    word = "solved" if stats.get("success") else "not_converged"
    return f"return status {status}", word, iterations


STALL_WINDOW = 100
"""Iterations over which a feasible run's objective must move for the run to go on
(:class:`Stall`)."""
STALL_CHANGE = 5e-3
"""The relative change of the objective below which a run has stalled (measured on a random
RRR transfer with four switches: 1e-3 never stopped its creep of 0.5 % per 100 iterations;
5e-3 stopped it at 1.017 times unconstrained collocation in 8 s, where it had run out of time
with no plan)."""
STALL_FEASIBLE = 1e-5
"""The largest constraint violation of an iterate a stalled run may stop at (the flat plan is
then certified and verified like any other; a creeping run's iterates were feasible to 1e-5
every few tens of iterations, to 1e-6 rarely)."""


STALL_NEARLY = 1e-2
"""The largest constraint violation of an iterate whose objective still tells a stall
(:class:`Stall`): a creeping run's iterates swing between feasible and violations of 1e-3 to
1e-1 (a random PRR transfer with six switches: feasible to 7e-6 at iteration 343, objective
7029.06; 1e-2 to 5e-2 from there on, 7019.7 at iteration 434 and no more feasible iterate by
its 500th)."""


class Stall:
    """Ipopt's "solved to an acceptable level" by the objective's progress: a run whose
    feasible iterates' objective has moved less than :data:`STALL_CHANGE` (relative) over
    :data:`STALL_WINDOW` iterations stops, and so does one whose nearly feasible iterate
    (violations up to :data:`STALL_NEARLY`) is that close to the best feasible objective a
    window before; the run then returns its best feasible iterate (:class:`BestFeasible`).

    Ipopt's own acceptable test needs the scaled dual infeasibility small for a number of
    iterations in a row; a flat plan's NLP with many switches can creep along a valley with it
    at 1-10 for hundreds of iterations (a random RRR transfer with four switches: 2862 at
    iteration 34, 2739 at 470, 2736 at 1000 and not converged, against unconstrained
    collocation's 2705), and a search then had no plan when its time ran out.
    """

    def __init__(self) -> None:
        self.feasible: list[tuple[int, float]] = []
        self.aged = 0  # how many of them are STALL_WINDOW iterations old: their best is known
        self.best_aged = math.inf

    def stalled(self, iteration: int, objective: float, infeasibility: float) -> bool:
        """True when this iterate is nearly feasible (STALL_NEARLY) and its objective within
        STALL_CHANGE of the best feasible one at least STALL_WINDOW iterations before it."""
        if not math.isfinite(objective) or infeasibility > STALL_NEARLY:
            return False
        if infeasibility <= STALL_FEASIBLE:
            self.feasible.append((iteration, objective))
        while self.aged < len(self.feasible) and self.feasible[self.aged][0] <= (
            iteration - STALL_WINDOW
        ):
            self.best_aged = min(self.best_aged, self.feasible[self.aged][1])
            self.aged += 1
        if not math.isfinite(self.best_aged):
            return False
        reference = self.best_aged
        return abs(objective - reference) <= STALL_CHANGE * max(abs(reference), 1e-12)


class BestFeasible:
    """The feasible iterate (violations up to :data:`STALL_FEASIBLE`) with the lowest objective
    a run has passed: what a run that stalls, or that cpopt cuts (its iteration cap, the
    search's deadline), returns. Its
    constraints hold like a converged plan's, and the flat plan is then certified and verified
    like any other; it is the optimum only up to how far the run had come (Ipopt's word
    ``Best_Feasible_Iterate_At_<iteration>`` says so)."""

    def __init__(self, tolerance: float = STALL_FEASIBLE) -> None:
        self.tolerance = tolerance  # the largest violation of an iterate it keeps
        self.objective, self.iteration = math.inf, 0
        self.x = self.lam_x = self.lam_g = None

    def offer(self, iteration: int, objective: float, infeasibility: float, arg) -> None:
        """Keep this iterate (nlpsol's outputs ``arg``: x, f, g, lam_x, lam_g, lam_p) when it
        is feasible, lower than the best so far and not the run's start (``iteration`` 1, Ipopt's
        iteration 0: a start Ipopt could not step from, its Hessian not a number, is no plan;
        a random RPR swing-down's closed-form start was kept so and failed verification)."""
        if iteration <= 1 or infeasibility > self.tolerance or not objective < self.objective:
            return
        self.objective, self.iteration = objective, iteration
        self.x, self.lam_x, self.lam_g = (np.asarray(arg[i], float).ravel() for i in (0, 3, 4))

    def run(self, total: int, elapsed: float) -> NlpRun | None:
        """The NlpRun of this iterate (None without one) for a run of ``total`` iterations
        that took ``elapsed`` [s]."""
        if self.x is None:
            return None
        return NlpRun(
            x=self.x, objective=self.objective,
            return_status=f"Best_Feasible_Iterate_At_{self.iteration}", status="solved",
            iterations=total, solve_time_s=elapsed, lam_g=-self.lam_g, lam_x=self.lam_x,
        )  # fmt: skip


def bound_violation(g, lower: np.ndarray, upper: np.ndarray) -> float:
    """The largest violation of ``lower <= g <= upper`` (0 when there are no rows, inf when a
    row is not a number)."""
    g = np.asarray(g, float).ravel()
    if not np.isfinite(g).all():
        return math.inf
    return float(np.max(np.maximum(lower - g, g - upper), initial=0.0))


RESTORABLE = 1e-2
"""The largest constraint violation of an iterate a cut run keeps to be moved onto its
constraints when it passed no feasible one (:attr:`IterationReporter.nearly`,
:func:`cpopt.flatopt.feasible_start.restored_run`): a creeping run's iterates swing between
violations of 1e-3 and 1e-1 (:data:`STALL_NEARLY`)."""


class IterationReporter(ca.Callback):
    """Ipopt's iteration callback (nlpsol option ``iteration_callback``): each iteration is
    reported to :func:`cpopt.runtime.progress.iteration` with the label of the run.

    A stop (Ctrl-C, the wall-clock limit) raised while the callback runs would be swallowed by
    CasADi; the callback keeps it, asks Ipopt to stop, and :func:`run_nlp` raises it again once
    Ipopt has returned.

    Parameters
    ----------
    nx, ng, np_ : int
        Sizes of the NLP's decision vector, constraints and parameters.
    """

    def __init__(self, nx: int, ng: int, np_: int) -> None:
        ca.Callback.__init__(self)
        self.sizes = {"x": nx, "lam_x": nx, "g": ng, "lam_g": ng, "lam_p": np_, "f": 1}
        self.count, self.label, self.stop = 0, "", None
        self.best = self.nearly = None  # a run's iterates kept (start)
        self.construct("iterations", {})

    def get_n_in(self) -> int:
        return ca.nlpsol_n_out()

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return ca.nlpsol_out(i)

    def get_name_out(self, i: int) -> str:
        return "stop"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self.sizes.get(ca.nlpsol_out(i), 0), 1)

    def start(
        self,
        label: str,
        limit: int | None = None,
        abandon=None,
        lbg=None,
        ubg=None,
        deadline: float = math.inf,
        stall: bool = False,
    ) -> None:
        """Reset the count for a new run called ``label``, stopped after ``limit`` iterations
        if given (a cap below the solver's own ``max_iter``, without rebuilding the solver),
        once ``abandon(iteration, objective, infeasibility)`` is true (a run another has
        already beaten; the infeasibility is the largest violation of ``lbg <= g <= ubg``), or
        once ``time.monotonic()`` passes ``deadline`` [s] (a search's own deadline, which
        leaves it the time to return its best plan); with ``stall``, once its objective has
        stalled at a feasible iterate (:class:`Stall`)."""
        self.count, self.label, self.stop, self.limit = 0, label, None, limit
        self.stall, self.stalled = (Stall() if stall else None), False
        self.best = BestFeasible() if stall else None
        self.nearly = BestFeasible(RESTORABLE) if stall else None  # restored if nothing better
        self.capped, self.abandon, self.abandoned = False, abandon, False
        self.deadline, self.late = deadline, False
        self.bounds = (
            (np.asarray(lbg, float).ravel(), np.asarray(ubg, float).ravel())
            if lbg is not None and ubg is not None
            else None
        )

    def infeasibility(self, g) -> float:
        """The largest violation of the run's constraint bounds by ``g`` (0 without bounds)."""
        if self.bounds is None:
            return 0.0
        return bound_violation(g, *self.bounds)

    def eval(self, arg) -> list:
        self.count += 1
        try:
            progress.iteration(self.count, self.label)
        except BaseException as stop:  # Ctrl-C or the time limit: stop Ipopt, raise later
            self.stop = stop
        self.capped = self.limit is not None and self.count > self.limit
        if self.abandon is not None or self.stall is not None:
            infeasibility = self.infeasibility(arg[2])
        if self.abandon is not None:
            self.abandoned = bool(self.abandon(self.count, float(arg[1]), infeasibility))
        if self.stall is not None:
            self.best.offer(self.count, float(arg[1]), infeasibility, arg)
            self.nearly.offer(self.count, float(arg[1]), infeasibility, arg)
            # a stall returns a feasible iterate: this one, or the best kept (none when the
            # only feasible one was the start, which BestFeasible does not keep)
            returnable = infeasibility <= STALL_FEASIBLE or self.best.x is not None
            stalled = self.stall.stalled(self.count, float(arg[1]), infeasibility)
            self.stalled = stalled and returnable
        self.late = time.monotonic() > self.deadline
        stop = self.stop is not None or self.capped or self.abandoned or self.late or self.stalled
        return [1 if stop else 0]


def run_nlp(
    solver: ca.Function,
    reporter: IterationReporter | None = None,
    label: str = "",
    limit: int | None = None,
    abandon=None,
    deadline: float = math.inf,
    stall: bool = False,
    **arguments,
) -> NlpRun:
    """Call a CasADi ``nlpsol`` solver with its arguments (x0, p, lbx, ubx, lbg, ubg).

    ``reporter`` is the solver's :class:`IterationReporter`, if it has one; ``label`` names the
    run in progress lines and above Ipopt's output (``--verbose``); ``limit`` caps the
    iterations through the reporter (a run stopped there is ``max_iterations``); ``abandon``
    stops it once ``abandon(iteration, objective, infeasibility)`` is true (status
    ``dominated``), ``deadline`` once ``time.monotonic()`` passes it (status ``time_limit``;
    see :meth:`IterationReporter.start`); ``stall`` accepts a run whose objective has stalled
    at a feasible iterate (:class:`Stall`; status ``solved``, Ipopt's word
    ``Stalled_Acceptable_At_<iteration>``).
    """
    if label:
        progress.ipopt_run(label)
    if reporter is not None:
        bounds = arguments.get("lbg"), arguments.get("ubg")
        reporter.start(label, limit, abandon, *bounds, deadline=deadline, stall=stall)
    start = time.perf_counter()
    solution = solver(**arguments)
    elapsed = time.perf_counter() - start
    if reporter is not None and reporter.stop is not None:
        raise reporter.stop
    check_stop()
    ipopt, status, iterations = read_stats(solver.stats())
    if reporter is not None and reporter.stalled:
        ipopt, status = f"Stalled_Acceptable_At_{iterations}", "solved"
        best = reporter.best.run(iterations, elapsed) if reporter.best else None
        if best is not None:  # the creep's lowest feasible iterate, not its last
            return replace(best, return_status=f"{ipopt}_Best_At_{reporter.best.iteration}")
    if reporter is not None and reporter.capped:
        ipopt, status = f"Iteration_Cap_{limit}", "max_iterations"
    if reporter is not None and reporter.abandoned:
        ipopt, status = f"Abandoned_Dominated_At_{iterations}", "dominated"
    if reporter is not None and reporter.late:
        ipopt, status = f"Search_Deadline_At_{iterations}", "time_limit"
    # only a run cpopt cut (its cap, the search's deadline) keeps its best feasible iterate:
    # where Ipopt itself gave up (its own max_iter, a failed restoration), refining that iterate
    # blew up (a random RRR swing-down's one-sign run: 1000 iterations, then four refinement
    # rounds from 2.3e4 to 1.5e7 and out of reach, 18 s of its 20)
    cut = reporter is not None and (reporter.capped or reporter.late)
    if cut and reporter.best is not None and reporter.best.x is not None:
        return reporter.best.run(iterations, elapsed)
    return NlpRun(
        x=np.asarray(solution["x"]).ravel(),
        objective=float(solution["f"]),
        return_status=ipopt,
        status=status,
        iterations=iterations,
        solve_time_s=elapsed,
        lam_g=-np.asarray(solution["lam_g"]).ravel(),
        lam_x=np.asarray(solution["lam_x"]).ravel(),
    )


__all__ = [
    "IPOPT_STATUS",
    "RESTORABLE",
    "STALL_CHANGE",
    "STALL_FEASIBLE",
    "STALL_NEARLY",
    "STALL_WINDOW",
    "BestFeasible",
    "IterationReporter",
    "NlpRun",
    "PlannerDetails",
    "SolverStats",
    "Stall",
    "bound_violation",
    "fatrop_options",
    "ipopt_options",
    "read_stats",
    "run_nlp",
    "status_of",
]
