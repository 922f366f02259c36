"""Re-planning from a measured state: the remaining motion solved once, fast, with a fallback.

A re-plan at time t is the flat optimizer's NLP for the remaining motion
(:mod:`cpopt.flatopt.remaining_motion`): the same transcription, objective and limits, its start
pinned to the measured (q, qd) with xi and eta free, its pattern of signs of gamma and the
switch times still ahead kept. The NLP is built and compiled once per structure (the fixed
node values are its parameters, :func:`cpopt.flatopt.transcribe.build` caches it), warm
started from the current plan (the fourth derivative of its CP refitted on the remaining
phases, :data:`FIT_ORDERS`), and solved by Ipopt within a deadline. One round only, on a
coarser grid of |gamma| than the planner's (:data:`GAMMA_GRID`): a re-plan does not refine
its sample grid (a refinement is a new structure and a new build); its gamma is certified
exactly (within :data:`GAMMA_TOLERANCE`), its limits on the grid, and a re-plan that does
not solve, or solves too late, keeps the previous plan (but for the SQP's ``feasible``
iterate at its deadline, :data:`USABLE`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..closedform.plan import CPPlan
from ..closedform.trajectory import Trajectory, reachable, sample
from ..problem import Problem
from ..runtime.solver import run_nlp
from . import replan_sqp
from .remaining_motion import Remaining, remaining, shifted
from .transcribe import build, initial_grids
from .warm_start import initial_guess, seeded_guess

SOLVER_SETTINGS = {"tol": 1e-6, "mu_strategy": "monotone", "print_level": 0}
"""Ipopt's settings for a re-plan (``optimizer.solver`` keys): a re-plan starts next to its
optimum, where the monotone barrier from the warm start's small mu_init
(:data:`~cpopt.flatopt.ipopt_settings.WARM_MU_INIT`) takes fewer iterations than the adaptive one,
and 1e-6 is far below what a plan tracked by feedback at 1 kHz can tell apart."""
REPLAN_IPOPT = (("mu_init", 1e-5),)
"""Ipopt's options for a re-plan beyond its settings: the barrier starts at 1e-5 (a re-plan
starts next to its optimum, warm started with the previous re-plan's multipliers). Measured
in pairs (each re-plan of the loop of benchmarks/replan_loop.py solved both ways, 44
re-plans of transfer_min_torque, 74 of swing_up_holding) against 1e-3
(:data:`~cpopt.flatopt.ipopt_settings.WARM_MU_INIT`): median Ipopt iterations 14 -> 13 and
15 -> 14, CPU time a re-plan 6 % and 5 % less (median of the pairs' ratios), the same solved
fractions and slowest re-plans. MUMPS without its KKT scaling
(``mumps_permuting_scaling``, ``mumps_scaling`` 0) took 3 % less at the median but
transfer_min_torque's slowest re-plans twice as long (p99 292 -> 548 ms); Ipopt's gradient
scaling off, 2 % more and one re-plan fewer solved."""
FIT_ORDERS = (4,)
"""The CP derivative orders the warm start fits to the current plan (its fourth alone: the
torque's). The start's jet is the measured state's, the current plan's differs, and a fit of
every order (as a re-solve's) puts the whole difference into a spike of the fourth derivative
next to the start, which the optimum spreads over the phase. Measured on transfer_min_torque,
re-plans every 20 ms from its states perturbed by 2 mm and 0.02 rad/s (88 re-plans, the
compensator held): every order, Ipopt's median 38 iterations and 73 % solved; the fourth
alone, 20 and 98 %."""
GAMMA_GRID = 41
"""Points per phase where a re-plan constrains |gamma| >= gamma_min (the planner's 241 cost
each Ipopt iteration 200 rows a phase); the solved re-plan is then certified exactly
(:meth:`cpopt.plan.CPPlan.min_abs_gamma`, :data:`GAMMA_TOLERANCE`). Measured as for
:data:`FIT_ORDERS` (loaded machine): transfer_min_torque 241 points, a median of 20 Ipopt
iterations; 41 points, 14 (certified |gamma| up to 0.7 % below gamma_min between the points);
swing_up_holding (148 re-plans) every order fitted and 241 points, 28 iterations and 47 %
solved; the fourth order and 41 points, 18 and 84 %."""
GAMMA_TOLERANCE = 0.5
"""How far below gamma_min [fraction] a re-plan's certified |gamma| may dip between its grid
points: the margin keeps the flat map away from its singularity (gamma = 0), and a re-plan is
followed for one re-plan period only (at a tolerance of 2 %, 43 of swing_up_holding's 148
re-plans were refused)."""
POST_RESERVE = 2.5
"""The time a re-plan keeps after its solver for unpacking and certifying the plan, as a
multiple of the time it spent before the solver (both are a few milliseconds of Python that
scale alike with the machine's speed; measured on transfer_min_torque's re-plan loop at a
20-ms deadline, idle: 2.0-2.8 ms before the solver, 4.5-5.7 ms after): at 1.5, 45 of 88
re-plans whose solver ran to its deadline were ``late``, their plans thrown away. The first
re-plan of a structure has only this; the next ones take :data:`POST_TIMES`' figure when it
is larger."""
POST_MARGIN = 1.25
""":data:`POST_TIMES` keeps this multiple of the time measured."""
POST_TIMES: dict[tuple, float] = {}
"""The time [s] the last certified re-plan of each NLP structure (:func:`structure`) took
after its solver, times :data:`POST_MARGIN`: the reserve of the next one (a process-wide
record of measured times, not of results). Measured on swing_up_holding's re-plan loop at a
20-ms deadline: with the reserve from the time before the solver alone (2.5 ms of it once
its B-spline fits were trimmed, against 5-8 ms after), 70 of 148 re-plans ended late or
without a feasible iterate."""
CHECK_SAMPLES = 101
"""Samples a phase of a re-plan's reach check (:func:`reachable`), which are also the next
re-plan's seed: the planner's 401 took 6.7 ms of a 25-ms re-plan (transfer_min_torque), and a
re-plan is followed for one re-plan period, tracked on its own control grid (where flat_mpc
checks its reach again), and refitted from these samples by the next re-plan (20 CP
coefficients a phase at most)."""
REPLAN_ITERATIONS = 100
"""Most Ipopt iterations of a re-plan (a warm-started re-plan near its plan takes a few; one
that needs more has lost its basin and the previous plan is the better bet)."""
SQP_ITERATIONS = 30
"""Most SQP iterations of a re-plan (:mod:`cpopt.flatopt.replan_sqp`; one from the plan's own
state converges in about six)."""
USABLE = ("solved", "feasible")
"""Statuses of a re-plan whose plan is followed. ``feasible``: the SQP stopped at its deadline
or iteration limit and returned its best iterate that keeps every row (limits, |gamma| on the
grid, reach), then certified like a solved one: a plan from the measured state to the goal
within the limits, less than optimal in its objective (the real-time iteration of fast MPC:
the next re-plan goes on optimizing from it). Following it, not the previous plan, is what
re-planning is for: the previous plan starts from a state the arm is not in."""
METHODS = ("ipopt", "sqp")
"""How a re-plan solves its NLP: ``ipopt`` on the lifted NLP (the default), ``sqp`` condensed
to its core variables (:mod:`cpopt.flatopt.replan_sqp`). Measured with
benchmarks/replan_loop.py (two rounds, idle): on transfer_min_torque the SQP is faster (median
29.6 against 48.1 ms) and solves a little less (86.4 against 90.9 %); on swing_up_holding it
solves 52.7 % against 93.9 % (its iterations stall on the goal's curved rows), so Ipopt
stays the default."""


@dataclass(frozen=True)
class Replan:
    """The outcome of :func:`replan`.

    Attributes
    ----------
    status : str
        ``solved``; ``feasible`` (the SQP's best feasible iterate at its deadline or
        iteration limit, certified like a solved one: :data:`USABLE`); ``holding`` (less
        than :data:`~cpopt.flatopt.remaining_motion.NEAR_NODE` left: the plan holds the
        goal); ``late`` (solved after the deadline); ``gamma_margin`` (solved on its grid,
        |gamma| below gamma_min between its points); ``out_of_reach`` (solved on its grid,
        out of the arm's reach between its points); or the solver's status (``time_limit``,
        ``max_iterations``, ``infeasible``, ``not_converged``).
    plan : CPPlan
        The plan to follow from now on, in the plan's clock: the new one when solved, else the
        previous one.
    kept_previous : bool
        True when ``plan`` is the previous plan.
    t : float
        The re-plan instant [s].
    iterate : CPPlan or None
        The solver's last iterate as a plan on [t, T] (the best it had when it failed).
    objective : float
        The remaining motion's objective at the iterate.
    iterations : int
        Ipopt iterations.
    time_s : float
        Wall time of the re-plan, warm start and unpacking included [s].
    multipliers : Multipliers or None
        The newest solved re-plan's multipliers, for the next re-plan's ``warm``.
    message : str
        The solver's own word (Ipopt's return status).
    samples : Trajectory or None
        The new plan sampled (the reach check's), for the next re-plan's ``seed``; None when
        the previous plan is kept.
    """

    status: str
    plan: CPPlan
    kept_previous: bool
    t: float
    iterate: CPPlan | None = None
    objective: float = math.nan
    iterations: int = 0
    time_s: float = 0.0
    multipliers: Multipliers | None = None
    message: str = ""
    samples: Trajectory | None = None

    @property
    def solved(self) -> bool:
        """True when the plan is a new one, solved to optimality in time."""
        return self.status == "solved"

    @property
    def usable(self) -> bool:
        """True when the plan is a new one to follow: solved, or a feasible iterate of a
        solver stopped at its deadline or iteration limit (:data:`USABLE`)."""
        return self.status in USABLE


def variable_bounds(nlp, problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the whole decision vector: the core's, the lifted samples unbounded."""
    lo, hi = nlp.layout.bounds(problem.free)
    n_lifted = nlp.solver.size_in(0)[0] - nlp.layout.size
    return np.r_[lo, [-np.inf] * n_lifted], np.r_[hi, [np.inf] * n_lifted]


def shifted_seed(seed: Trajectory, t: float) -> Trajectory:
    """The samples of the current plan in the re-plan's clock (time t [s] becomes 0)."""
    from dataclasses import replace

    return replace(seed, t=seed.t - t)


@dataclass(frozen=True)
class Multipliers:
    """A solved re-plan's multipliers, for the next re-plan of the same structure.

    Attributes
    ----------
    structure : tuple
        What the NLP's rows depend on: node count, signs of gamma, switches, freed names.
    lam_x, lam_g : numpy.ndarray
        Bound and constraint multipliers as nlpsol returns them.
    """

    structure: tuple
    lam_x: np.ndarray
    lam_g: np.ndarray


def structure(rest: Remaining) -> tuple:
    """The NLP structure of a remaining motion (two with the same share their rows)."""
    p = rest.problem
    return (len(p.nodes), rest.signs, rest.switches, tuple(sorted(p.free)))


def with_replan_settings(problem: Problem, torque_limit=None) -> Problem:
    """The problem with the re-plan's Ipopt settings (:data:`SOLVER_SETTINGS`) and, if given,
    the motors' ``torque_limit`` (2,) [N m or N] as its torque limits (a joint's None keeps
    the problem's)."""
    from dataclasses import replace

    from ..model.limits import arm_limits

    o = problem.spec.optimizer
    update = {"solver": o.solver.model_copy(update=SOLVER_SETTINGS)}
    if torque_limit is not None:
        torque = [
            a if a is not None else b for a, b in zip(torque_limit, o.limits.torque, strict=True)
        ]
        update["limits"] = o.limits.model_copy(update={"torque": torque})
    optimizer = o.model_copy(update=update)
    spec = problem.spec.model_copy(update={"optimizer": optimizer})
    return replace(problem, spec=spec, limits=arm_limits(optimizer.limits, problem.arm))


def start_vector(nlp, problem: Problem, signs, seed: Trajectory, p: np.ndarray) -> np.ndarray:
    """The initial vector: the current plan refitted (:func:`seeded_guess`), or the closed
    form through the nodes where the objective is not finite there (measured: a re-plan of a
    re-plan of transfer_min_torque on the model, whose start's free fourth CP derivative
    had grown large, fitted a sample where the torque is NaN, and Ipopt stopped at once)."""
    x0 = seeded_guess(nlp, problem, signs, seed, FIT_ORDERS)
    if np.isfinite(float(nlp.solver.get_function("nlp_f")(x0, p))):
        return x0
    return initial_guess(nlp, problem, signs)


def _solve(rest: Remaining, seed: Trajectory, clock: tuple, limits: tuple, warm, motors):
    """(run, new plan in the plan's clock, multipliers, the solver's end as a
    ``time.monotonic()`` instant) of one solve of the remaining motion; ``clock`` the
    re-plan's (start, deadline) ``time.monotonic()`` instants (the solver stops ahead of the
    deadline by :data:`POST_RESERVE` times the time spent before it, or by
    :data:`POST_TIMES`' figure for the structure when larger);
    ``limits`` (method, most iterations); ``warm`` (:class:`Multipliers` or None) the previous
    re-plan's multipliers, used when its structure is this one's (the solver then starts from
    the primal-dual point); ``motors`` the torque limits to plan within (None: the
    problem's)."""
    from . import plan_from

    method, iterations = limits
    problem = with_replan_settings(rest.problem, motors)
    signs, switches = rest.signs, rest.switches
    key = structure(rest)
    resume = warm is not None and warm.structure == key
    if method == "ipopt" and resume and warm.lam_x.size == 0:
        resume = False  # an SQP re-plan's multipliers have no bound multipliers for Ipopt
    grids = initial_grids(problem)
    nlp = build(problem, signs, grids, warm=True, resume=resume and method == "ipopt",
                gamma_grid=GAMMA_GRID, ipopt=REPLAN_IPOPT)  # fmt: skip
    p = nlp.parameters(problem.values)
    lbx, ubx = variable_bounds(nlp, problem)
    x0 = start_vector(nlp, problem, signs, shifted_seed(seed, rest.t0), p)
    started, deadline = clock
    deadline -= max(POST_RESERVE * (time.monotonic() - started), POST_TIMES.get(key, 0.0))
    if method == "sqp":
        lam0 = -warm.lam_g if resume else None  # NlpRun's sign back
        bounds = (lbx, ubx, nlp.lbg, nlp.ubg)
        run = replan_sqp.solve(nlp, x0, p, bounds, iterations, deadline, lam0)
    else:
        arguments = {"x0": x0, "p": p, "lbx": lbx, "ubx": ubx, "lbg": nlp.lbg, "ubg": nlp.ubg}
        if resume:
            arguments.update(lam_x0=warm.lam_x, lam_g0=-warm.lam_g)  # NlpRun's sign back
        run = run_nlp(nlp.solver, nlp.reporter, "", iterations, None, deadline, **arguments)
    solved_at = time.monotonic()  # what follows is the re-plan's own time
    usable = run.status in USABLE
    multipliers = Multipliers(key, run.lam_x, run.lam_g) if usable else warm
    try:
        plan, _, _ = plan_from(problem, nlp, run.x, p, signs, switches)
    except ValueError:  # an iterate so far off that its phases no longer make curves
        return run, None, multipliers, solved_at
    return run, shifted(plan, rest.t0), multipliers, solved_at


def verdict(
    status: str, new: CPPlan | None, gamma_min: float, samples: Trajectory | None = None
) -> str:
    """A re-plan's status from the solver's: ``not_converged`` when its iterate makes no plan,
    ``gamma_margin`` when the plan's certified |gamma| is below ``gamma_min`` [m/s^2],
    ``out_of_reach`` when it leaves the arm's reach between its samples (:func:`reachable`;
    ``samples``: what it gave, when the caller has it)."""
    if status not in USABLE:
        return status
    if new is None:
        return "not_converged"
    if new.min_abs_gamma()[0] < gamma_min * (1 - GAMMA_TOLERANCE):
        return "gamma_margin"
    samples = reachable(new, CHECK_SAMPLES) if samples is None else samples
    return status if samples is not None else "out_of_reach"


def replan(
    problem: Problem,
    plan: CPPlan,
    t: float,
    q,
    qd,
    deadline_s: float = math.inf,
    seed: Trajectory | None = None,
    iterations: int | None = None,
    warm: Multipliers | None = None,
    free_compensator: bool = True,
    torque_limit=None,
    method: str = "ipopt",
) -> Replan:
    """Re-plan the remaining motion of ``plan`` from the measured joint state at time t.

    Parameters
    ----------
    problem : Problem
        The problem ``plan`` solves (objective, limits, freed values and bounds).
    plan : CPPlan
        The current plan (a flat plan of :func:`cpopt.flatopt.optimize`, or a re-plan of it).
    t : float
        The re-plan instant in the plan's clock [s].
    q, qd : array_like
        The measured joint positions and velocities (3,) [rad or m, rad/s or m/s].
    deadline_s : float
        Wall time the re-plan may take [s]; Ipopt is stopped there and a re-plan that ends
        later (``late``) keeps the previous plan.
    seed : Trajectory, optional
        ``sample(plan)``, when the caller has it (a loop re-planning from the same plan).
    iterations : int, optional
        Most solver iterations (None: :data:`SQP_ITERATIONS` or :data:`REPLAN_ITERATIONS`).
    warm : Multipliers, optional
        The previous re-plan's multipliers (:attr:`Replan.multipliers`): a re-plan of the same
        structure starts from them.
    free_compensator : bool
        xi and eta at t free (the default) or held at the plan's.
    torque_limit : sequence of (float or None), optional
        The motors' torque limits [N m or N] the re-plan keeps (None: the problem's).
    method : str
        One of :data:`METHODS`: Ipopt on the lifted NLP (the default) or the condensed SQP.

    Returns
    -------
    Replan
        The plan to follow and how it was obtained; never a silent success: a failed solve
        keeps the previous plan and reports the solver's status and its iterate.
    """
    tic = time.perf_counter()
    started = time.monotonic()
    rest = remaining(problem, plan, t, q, qd, free_compensator)
    if rest is None:
        return Replan("holding", plan, True, t, time_s=time.perf_counter() - tic, multipliers=warm)
    seed = sample(plan) if seed is None else seed
    if iterations is None:
        iterations = SQP_ITERATIONS if method == "sqp" else REPLAN_ITERATIONS
    limits = (method, iterations)
    clock = (started, started + deadline_s)
    run, new, multipliers, solved_at = _solve(rest, seed, clock, limits, warm, torque_limit)
    samples = reachable(new, CHECK_SAMPLES) if run.status in USABLE and new is not None else None
    status = verdict(run.status, new, problem.spec.optimizer.gamma_min, samples)
    if samples is not None:  # a whole unpacking and certificate: the next one's reserve
        POST_TIMES[structure(rest)] = POST_MARGIN * (time.monotonic() - solved_at)
    elapsed = time.perf_counter() - tic
    if status in USABLE and elapsed > deadline_s:
        status = "late"
    return _outcome(status, (plan, new, samples), t, run, elapsed, multipliers)


def _outcome(status: str, plans: tuple, t: float, run, elapsed: float, multipliers) -> Replan:
    """The :class:`Replan` of a finished re-plan; ``plans`` (previous plan, new plan or None,
    the new plan's samples or None)."""
    previous, new, samples = plans
    ok = status in USABLE
    return Replan(
        status=status,
        plan=new if ok else previous,
        kept_previous=not ok,
        t=t,
        iterate=new,
        objective=run.objective,
        iterations=run.iterations,
        time_s=elapsed,
        multipliers=multipliers,
        message=run.return_status,
        samples=samples if ok else None,
    )


__all__ = [
    "METHODS",
    "REPLAN_IPOPT",
    "REPLAN_ITERATIONS",
    "SQP_ITERATIONS",
    "USABLE",
    "Multipliers",
    "Replan",
    "reachable",
    "replan",
    "shifted_seed",
    "start_vector",
    "structure",
    "variable_bounds",
    "with_replan_settings",
]
