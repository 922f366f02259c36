"""The switch search seeded by a coarse unconstrained collocation (``optimizer.switch_search:
seed``, the default; route (b) of issue 11, made to hold on problems nobody tuned it for in
issue 30).

1. **Seed** (:func:`cpopt.flatopt.seed.coarse_seed`): where the unconstrained optimum's gamma
   crosses zero gives the switch times and the signs between them.
2. **The bound**: the plans with the fewest switches the pins allow (one sign where nothing is
   pinned; each allowed sign from the closed form, the seed's favourite first, for
   :data:`BOUND_FIRST` iterations) are cheap and bound everything after: no plan costlier
   than the best of them is returned, and a later run that they dominate
   (:func:`~cpopt.flatopt.dominance.dominated`) is abandoned. After the seed's pattern they
   get their second starts (:func:`_bound_again`): a run cut at :data:`BOUND_FIRST` goes on to
   :data:`ONE_SIGN_LIMIT`, and a start from the seed is made where none solved or where the
   seed has that sign throughout, while the best plan is more than :data:`POLISH_GAIN` above
   the seed.
3. **Flat solve** of the seed's pattern, started from the seed (B-spline coefficients fitted to
   its CP, xi and eta from its state, :func:`cpopt.flatopt.warm_start.seeded_guess`). (A
   continuation in gamma_min, from a fraction of it up, was built and measured worse on the
   bundled switch problems and no better on the zoo: near gamma = 0 the flat map is singular;
   see docs/problems.md.) The switch times are held at the seed's crossings: a free switch time
   in a short phase scales every CP derivative there by a power of the phase's length, and
   Ipopt was measured to wander for hundreds of iterations with it. A pattern that does not
   solve from the seed is tried once from the closed form, then cut to one switch more than
   the bound's (:func:`_fewest`).
4. **Near the nodes**, when the seed's pattern did not solve: a switch closer than
   :data:`NEAR` of the motion to the start, the goal or a via state of the file gets
   alternatives: the pattern without it, and with it moved that far away
   (:func:`near_alternatives`). (A solved plan's switch near a node is dropped by the polish;
   trying both alternatives after a solved ``swing_up_switches`` cost 4 s and gained
   nothing.)
5. **Polish**: the patterns one switch away (:func:`cpopt.flatopt.switching.neighbours`),
   each started from the plan solved so far and given at most
   :data:`~cpopt.flatopt.switching.POLISH_LIMIT` iterations and abandoned once clearly
   dominated, while the polish has spent less than the flat solve did. A plan that already
   costs no more than :data:`POLISH_GAIN` above the seed is not polished.

The search keeps the best plan of every stage (``solver.search.method`` names the stage that
found it: ``one_sign``, ``seed``, ``near``, ``polish`` or ``greedy``, the greedy steps of
:func:`~cpopt.flatopt.switching.grow` from the bound when the seed's pattern did not solve;
the summary says why). It starts no
stage after its deadline, and every solve stops there (the solve's own deadline), so it
returns its best plan within the time limit. Nothing here raises on a valid problem.
"""

from __future__ import annotations

import math
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

from ..closedform.nodes import MIN_PHASE
from ..closedform.trajectory import sample
from ..problem import MAX_SWITCHES, Problem
from ..runtime import progress
from .dominance import DOMINATED_EARLIEST, SEEDED_EARLIEST, dominated
from .seed import Seed, coarse_seed, patterned_seed
from .switching import (
    POLISH_LIMIT,
    SIGN_WORDS,
    Pattern,
    Search,
    Solve,
    above_seed,
    agreeing,
    fewest_patterns,
    first_attempts,
    gamma_signs_on_grid,
    grow,
    needed_times,
    neighbours,
    pattern_of,
    preference,
    seed_order,
    seed_pattern,
    seed_throughout,
    solve_pattern,
    within_budget,
)


@dataclass
class Stage:
    """Iterations and wall time [s] of one stage of the search."""

    iterations: int = 0
    time_s: float = 0.0
    tried: int = 0

    def add(self, attempt, tic: float) -> None:
        """Count an attempt that started at ``tic`` (time.perf_counter)."""
        self.iterations += attempt.iterations
        self.time_s += time.perf_counter() - tic
        self.tried += 1

    def add_all(self, attempts, tic: float) -> None:
        """Count attempts made one after the other from ``tic`` (time.perf_counter) on."""
        self.iterations += sum(a.iterations for a in attempts)
        self.time_s += time.perf_counter() - tic
        self.tried += len(attempts)

    def as_dict(self) -> dict:
        """JSON-ready figures."""
        return {"iterations": self.iterations, "time_s": self.time_s, "patterns": self.tried}


POLISH_GAIN = 0.01
"""Relative cost above the seed's below which the polish is skipped."""


def worth_polishing(problem: Problem, best, seed: Seed) -> bool:
    """True when the solved plan ``best`` may still gain from the polish: its objective is more
    than :data:`POLISH_GAIN` above the seed's. The seed's objective is the same functional
    without the regularity constraint (a lower bound up to its coarse grid's error), so it is
    compared only when the motion's duration is fixed (a seed keeps freed times at their
    guesses)."""
    if best.status != "solved":
        return False
    above = above_seed(problem, best, seed, POLISH_GAIN)
    return True if above is None else above


SWITCH_ITERATIONS = 500
"""Ipopt iterations the stages with switches (the seed's pattern and its cut, near a node,
greedy steps; the polish keeps its own caps) get together after the bound, before their first
solved rounds (a solved plan's refinement rounds are not cut): a seeded run on
a hard random problem (several switches, 30-90 ms an iteration) that would lose to the bound
wanders for thousands; the winners measured took 171 (``swing_up_switches``), 208
(``transfer_switch``) and 444 (a random RRR swing-up, 246 of them refining). Iterations, not
seconds, so that a search gives the same plan on a slower or busier machine."""
HOPELESS = 1.1
"""A pattern whose patterned seed (coarse collocation with its signs of gamma imposed) costs
more than this times the one-sign bound is not solved flat (:meth:`Run.hopeless`): the flat
plan of a pattern costs more than its coarse collocation, up to the coarse grid's error."""
PROMISING_EARLIEST = 100
"""Iterations a promising pattern's flat run (:meth:`Run.promising`) gets before the bound may
abandon it."""
NEAR = 0.1
"""A switch closer than this fraction of the motion to the start, the goal or a pinned via
state gets alternatives (:func:`near_alternatives`)."""


def _better(a, b) -> bool:
    """True when attempt a is a better plan than b (:func:`~cpopt.flatopt.switching.preference`)."""
    return preference(a) > preference(b)


def _bar(*attempts, seeded: bool = False, earliest: int | None = None):
    """``abandon`` for a run measured against the cheapest solved attempt (None without one);
    ``seeded`` for a run started from a seed fit (:data:`~cpopt.flatopt.switching.
    SEEDED_EARLIEST`), ``earliest`` for another first iteration it may be abandoned at."""
    solved = [a.objective for a in attempts if a is not None and a.status == "solved"]
    if earliest is None:
        earliest = SEEDED_EARLIEST if seeded else DOMINATED_EARLIEST
    return dominated(min(solved), earliest) if solved else None


def polish(
    solve: Solve, problem: Problem, best, budget: float, figures: Stage, bar=None, skip=None
):
    """The cheapest plan among ``best`` and the patterns one switch away from it, each started
    from ``best``'s plan and capped at POLISH_LIMIT iterations, tried while the polish has
    spent less than ``budget`` seconds; a run is abandoned once ``best`` or the attempt ``bar``
    (the one-sign bound) dominates it; a pattern ``skip(pattern)`` is true of is not tried.
    Returns the best attempt and every attempt made."""
    attempts = []
    start = sample(best.plan)
    for pattern in neighbours(problem, pattern_of(best)):
        if figures.time_s >= budget:
            break
        if skip is not None and skip(pattern):
            continue
        progress.stage(f"switch search: polish, {len(pattern.times)} switch(es)")
        tic = time.perf_counter()
        # a neighbour still at twice the plan's cost after 30 iterations will not win (the
        # swing-up with two switches: both neighbours ran to the limit, 6.9 s, at 1e5-1e6)
        attempt = solve_pattern(solve, problem, pattern, start, POLISH_LIMIT, _bar(best, bar))
        figures.add(attempt, tic)
        attempts.append(attempt)
        if attempt.status == "solved" and _better(attempt, best):
            best = attempt
    return best, attempts


def near_alternatives(problem: Problem, pattern: Pattern, wanted) -> list[Pattern]:
    """For each switch closer than :data:`NEAR` of the motion to the start, the goal or a via
    state of the file: the pattern without it (the signs that agree with ``wanted`` the
    longest) and the pattern with it moved that far from the node."""
    duration = problem.nodes[-1].t
    ends = [n.t for n in problem.nodes]
    out: list[Pattern] = []
    for j, t in enumerate(pattern.times):
        node = min(ends, key=lambda e: abs(e - t))
        if abs(node - t) >= NEAR * duration:
            continue
        kept = tuple(x for i, x in enumerate(pattern.times) if i != j)
        moved = node + math.copysign(NEAR * duration, t - node)
        options = [agreeing(problem, kept, wanted)]
        if 0 < moved < duration and all(abs(moved - x) > MIN_PHASE for x in kept):
            times = tuple(sorted((*kept, moved)))
            signs = pattern.signs if times.index(moved) == j else None
            options.append(Pattern(times, signs) if signs else None)
        out += [p for p in options if p is not None and p not in out and p != pattern]
    return out


STAGES = ("bound", "patterned", "flat", "near", "polish", "greedy")
"""The search's stages after the seed, as ``solver.search`` names their figures."""


@dataclass
class Run:
    """What the stages of one search share: the problem, the solve, the seed, the one-sign
    bound, every attempt so far (``opening``: the bound's first runs), each stage's figures
    and the deadline (``time.monotonic()``)."""

    problem: Problem
    solve: Solve
    seed: Seed
    deadline: float = math.inf
    iterations_left: float = math.inf
    bound: object = None
    tried: list = field(default_factory=list)
    opening: list = field(default_factory=list)
    stages: dict = field(default_factory=lambda: {name: Stage() for name in STAGES})
    shaped: dict = field(default_factory=dict)

    def patterned(self, pattern: Pattern) -> Seed | None:
        """The seed solved again with ``pattern`` imposed (:func:`~cpopt.flatopt.seed.
        patterned_seed`; once per pattern, counted in the stage ``patterned``)."""
        if pattern not in self.shaped:
            if time.monotonic() > self.deadline:  # none started past the deadline
                return None
            progress.stage(f"switch search: the seed with {len(pattern.times)} switch(es)")
            tic = time.perf_counter()
            shaped = patterned_seed(
                self.problem, self.seed, pattern.times, pattern.signs, deadline=self.deadline
            )
            figures = self.stages["patterned"]
            figures.iterations += shaped.report.iterations if shaped else 0
            figures.time_s += time.perf_counter() - tic
            figures.tried += 1
            self.shaped[pattern] = shaped
        return self.shaped[pattern]

    def priced(self, pattern: Pattern) -> float:
        """The pattern's patterned seed's objective over the solved bound's (NaN without
        either, or for a bound that is not positive): what the coarse collocation says the
        pattern costs against one sign (both torque integrals: the only objective a patterned
        seed takes)."""
        shaped = self.patterned(pattern)
        if shaped is None or self.bound is None or self.bound.status != "solved":
            return math.nan
        if not self.bound.objective > 0:
            return math.nan
        return shaped.report.objective / self.bound.objective

    def hopeless(self, pattern: Pattern) -> bool:
        """True when the pattern's patterned seed costs more than :data:`HOPELESS` times the
        solved bound: its flat plan, restricted further, will not beat the bound."""
        return self.priced(pattern) > HOPELESS

    def promising(self, pattern: Pattern) -> bool:
        """True when the pattern's patterned seed costs less than the solved bound: the coarse
        collocation says it wins, so its flat run is judged against the bound only from
        :data:`PROMISING_EARLIEST` iterations on. Abandoned earlier, random draws lost runs that
        then solved below it: an RRR transfer at iteration 29 (solves at 0.48 x the bound),
        another at 44 (0.93 x)."""
        return self.priced(pattern) < 1.0

    def late(self) -> bool:
        """True once the deadline has passed or the stages with switches have spent their
        iterations: no stage starts after it."""
        return time.monotonic() > self.deadline or self.iterations_left <= 0

    def solved_before(self, pattern: Pattern) -> bool:
        """True when an attempt solved ``pattern``'s signs with switches within MIN_PHASE of
        its times (a plan one sign agrees with already is not solved again)."""
        return any(
            a.status == "solved"
            and tuple(SIGN_WORDS[w] for w in a.signs) == pattern.signs
            and len(a.switch_times) == len(pattern.times)
            and all(
                abs(x - y) < MIN_PHASE for x, y in zip(a.switch_times, pattern.times, strict=False)
            )
            for a in self.tried
        )

    def attempt(self, stage: str, pattern: Pattern, start, cap=None, **options):
        """Solve ``pattern`` from the trajectory ``start`` (:func:`solve_pattern`) within the
        iterations left, or ``cap`` iterations (whatever is left), counted in ``stage`` and
        kept among the attempts."""
        tic = time.perf_counter()
        left = self.iterations_left if cap is None else cap
        limit = None if math.isinf(left) else max(int(left), 1)
        options = {"refine_past_limit": True, "deadline": self.deadline, **options}
        result = solve_pattern(self.solve, self.problem, pattern, start, limit, **options)
        self.stages[stage].add(result, tic)
        self.tried.append(result)
        self.iterations_left -= result.iterations if cap is None else 0
        return result


def search(problem: Problem, solve: Solve, deadline: float = math.inf) -> Search:
    """The seeded switch search (see the module docstring).

    Parameters
    ----------
    problem : Problem
        A problem with ``gamma_switches`` other than 0.
    solve : callable
        ``solve(problem, signs, switches, seed=None, limit=None, abandon=None, **options)
        -> SignAttempt`` (:func:`cpopt.flatopt.solve_for_signs`, its deadline bound).
    deadline : float
        ``time.monotonic()`` after which no stage starts: the best plan so far is returned.

    Returns
    -------
    Search
        Every attempt, the best, a summary and the figures of the seed, the one-sign bound,
        the flat solve, the alternatives near the nodes and the polish (``solution.json``:
        ``solver.search``).
    """
    wanted = problem.spec.optimizer.gamma_switches
    budget = MAX_SWITCHES if wanted == "auto" else wanted
    progress.stage("switch search: coarse collocation seed")
    run = Run(problem, solve, coarse_seed(problem), deadline)
    run.bound = _one_sign_bound(run)
    run.iterations_left = SWITCH_ITERATIONS  # for the stages with switches
    seed = run.seed
    pattern = seed_pattern(problem, seed, budget) if seed.trajectory is not None else None
    notes = []
    best, method = run.bound, "one_sign"
    if pattern is None or pattern.times == needed_times(problem):
        notes.append("the seed suggests no switch beyond the fixed signs'")
        best, method = _bound_again(run, best, method, notes)
    elif run.late():
        notes.append("search deadline reached before the seed's pattern")
    else:
        with reserved_for_bound(run, notes):
            seeded = _seeded_attempt(run, pattern)
            if seeded is not None and _better(seeded, best):
                best, method = seeded, "seed"
            notes.append(_verdict(seeded, run))
            failed = seeded is None or seeded.status != "solved"
            if failed:  # a solved plan's near switches: the polish drops them
                best, method = _near(run, pattern, best, method)
        best, method = _bound_again(run, best, method, notes)
        best, method = _polished(run, best, method, notes)
        if failed and method == "one_sign" and not run.late():
            best, method = _grown(run, best, method, notes)
    if time.monotonic() > run.deadline:
        notes.append("search deadline reached")
    elif run.iterations_left <= 0:
        notes.append(f"the stages with switches spent their {SWITCH_ITERATIONS} iterations")
    summary = _summary(wanted, seed, pattern, best, method, run.bound, notes)
    figures = {"method": method, "summary": summary, "seed": seed.report.as_dict()}
    figures.update({name: stage.as_dict() for name, stage in run.stages.items()})
    return Search(tuple(run.tried), best, summary, figures)


ONE_SIGN_LIMIT = 500
"""Ipopt iterations a one-sign run of the bound gets before its first solved round (its
refinement rounds follow): twice the most a solved one took on the zoo's draws (seeds 1 and 2,
58 solved: median 26, at most 244), where the runs that did not solve ran 500 to 1800
iterations, up to 10 s of a 20-s search, before failing."""
BOUND_FIRST = 150
"""Iterations a one-sign run from the closed form gets before the seed's pattern is solved; a
run cut there gets the rest of :data:`ONE_SIGN_LIMIT` after it (:func:`_bound_again`), judged
against the best plan solved by then. Most solved runs need far fewer (the zoo's median 26);
the runs that do not solve spent seconds there (a random PRR swing-down's two signs: 3.1 s
for 500 iterations at 4.6e7, where its seed's pattern then solved in 0.25 s at 1068)."""


RESERVED_SHARE = 0.5
"""The share of the time left after the bound's first runs that the seed's pattern and its
alternatives near the nodes may take when no one-sign plan solved and one was cut at
:data:`BOUND_FIRST` (:func:`reserved_for_bound`)."""


@contextmanager
def reserved_for_bound(run: Run, notes: list):
    """Within it, the run's deadline is :data:`RESERVED_SHARE` of the time left, when the
    bound has no solved plan and a run of it was cut short (:func:`_cut_short`): that run's
    second start (:func:`_bound_again`) keeps the rest. Without the reserve, at an 8-s limit
    a random PRR swing-down's seeded pattern took every second left and did not solve, where
    the one-sign plan solves in 4 s alone: ``auto`` returned no plan."""
    deadline, now = run.deadline, time.monotonic()
    cut = any(_cut_short(run, p) for p in fewest_patterns(run.problem))
    if run.bound.status != "solved" and cut and math.isfinite(deadline) and now < deadline:
        run.deadline = now + RESERVED_SHARE * (deadline - now)
        notes.append(f"{1 - RESERVED_SHARE:.0%} of the time left kept for the one-sign plans")
    try:
        yield
    finally:
        run.deadline = deadline


def _one_sign_bound(run: Run):
    """The best plan with the fewest switches the pins allow (one sign where nothing is
    pinned), each allowed sign solved from the closed form for :data:`BOUND_FIRST`
    iterations, the seed's favourite first."""
    progress.stage("switch search: the one-sign plans (the bound)")
    patterns = fewest_patterns(run.problem)
    tic = time.perf_counter()
    attempts = first_attempts(run.solve, run.problem, patterns, run.seed, BOUND_FIRST)
    run.stages["bound"].add_all(attempts, tic)
    run.tried += attempts
    run.opening = attempts
    return max(attempts, key=preference)


def _may_gain(problem: Problem, best, seed: Seed) -> bool:
    """True while the best plan so far may still gain from another start: none is solved, or
    it costs more than :data:`POLISH_GAIN` above the seed (:func:`worth_polishing`; the seed
    is the optimum without the regularity constraint, on a coarse grid)."""
    return best.status != "solved" or worth_polishing(problem, best, seed)


def _cut_short(run: Run, pattern: Pattern) -> bool:
    """True when the bound's run of ``pattern`` from the closed form stopped at
    :data:`BOUND_FIRST` iterations without solving."""
    return any(
        a.status != "solved"
        and a.iterations >= BOUND_FIRST
        and tuple(SIGN_WORDS[w] for w in a.signs) == pattern.signs
        for a in run.opening
    )


def _bound_again(run: Run, best, method: str, notes: list):
    """The one-sign plans' fair chance, after the seed's pattern, for each allowed sign (the
    seed's favourite first) while the best plan may still gain (:func:`_may_gain`):

    * a start from the seed, when no one-sign plan solved (the closed form through the nodes
      may leave the arm's reach, its torques then not numbers, where the seed, a joint-space
      plan, stays inside) or when the seed has that sign throughout (the closed form's local
      optimum may be far above the seed's: a random PRR transfer solved at 43 times the seed's
      cost from the closed form and within 0.1 % of it from the seed, in 16 iterations);
    * then a run from the closed form cut at :data:`BOUND_FIRST` runs again to
      :data:`ONE_SIGN_LIMIT`, abandoned once the best solved plan dominates it. (Run first, it
      solved a random PRR swing-down at 1.39 times the seed's start's cost, which the 8-s
      limit then cut.)
    """
    seeded = run.seed.trajectory is not None
    started = 0
    for pattern in seed_order(run.problem, fewest_patterns(run.problem), run.seed):
        starts = []
        if seeded and (
            run.bound.status != "solved" or seed_throughout(run.problem, pattern, run.seed)
        ):
            starts.append(run.seed.trajectory)
        if _cut_short(run, pattern):  # after the seed's start: this one failed once already
            starts.append(None)
        for start in starts:
            if time.monotonic() > run.deadline or not _may_gain(run.problem, best, run.seed):
                break
            progress.stage("switch search: a one-sign plan, second start")
            bar = _bar(best, seeded=start is not None)
            retry = run.attempt("bound", pattern, start, ONE_SIGN_LIMIT, abandon=bar)
            started += 1
            if _better(retry, run.bound):
                run.bound = retry
            if _better(retry, best):
                best, method = retry, "one_sign"
    if started:
        notes.append(f"{started} second start(s) of the one-sign plans")
    return best, method


PATTERNED_RETRY = 250
"""Ipopt iterations (before its first solved round) a pattern's second start gets after its
first failed, beyond the iterations left to the search (that failure has often spent them
all: a random RPR transfer failed after 497 iterations from the seed, and solved in 193 from
its patterned seed; the heavier swing_up_holding the other way round)."""


PROBE_RATIO = 0.5
"""A pattern's flat solve starts from its patterned seed first when the flat objective there
is below this fraction of the one at the fit of the unconstrained seed (:func:`_starts`).
Measured on random draws (first iterates, patterned / seed, and the iterations each start then
took): 0.125 (206 against 325, an RPR swing-up), 0.135 (100 / 149, a PRR swing-down), 0.15
(233 / 260, an RRR transfer), 0.68 (100 / 151, a PPR swing-up); 0.0027 the other way (386 /
246, both solved, an RPR transfer); the benchmark transfer 0.55 (its patterned seed wanders);
a tenth, the first value, left the first three starting from the seed."""


def _first_objective(run: Run, pattern: Pattern, start) -> float:
    """The flat objective at the fit of ``start`` (Ipopt stopped at its first iterate)."""
    first: list[float] = []

    def probe(iteration: int, objective: float, infeasibility: float = 0.0) -> bool:
        first.append(objective)
        return True

    solve_pattern(run.solve, run.problem, pattern, start, 1, probe)
    return first[0] if first and math.isfinite(first[0]) else math.inf


def _starts(run: Run, pattern: Pattern) -> list:
    """Where a pattern's flat solve starts, in order: the unconstrained seed (the bundled
    problems' winners start there), then its patterned seed; the other way round when the fit
    of the seed starts higher (:data:`PROBE_RATIO`). Measured at the first iterate: the
    benchmark transfer 2.0e5 from the seed, 1.1e5 from its patterned seed (which then wanders:
    seed first); a
    random RPR transfer 1.4e13 and 1.4e4, a random RRR transfer 9.5e27 and 1.2e5, where the
    seed's fit leaves the reach."""
    shaped = run.patterned(pattern)
    if shaped is None:
        return [run.seed.trajectory]
    tic = time.perf_counter()
    seeded = _first_objective(run, pattern, run.seed.trajectory)
    patterned = _first_objective(run, pattern, shaped.trajectory)
    run.stages["patterned"].time_s += time.perf_counter() - tic
    if patterned < PROBE_RATIO * seeded:
        return [shaped.trajectory, run.seed.trajectory]
    return [run.seed.trajectory, shaped.trajectory]


def _pattern_attempts(run: Run, stage: str, pattern: Pattern, bar):
    """One pattern solved flat from its starts (:func:`_starts`); the second, when the first
    did not solve, gets :data:`PATTERNED_RETRY` iterations of its own; without a patterned
    seed the retry is from the closed form. None when its patterned seed is hopeless
    (:meth:`Run.hopeless`). A promising pattern (:meth:`Run.promising`) is measured against
    the bound alone, and later than ``bar`` would."""
    if run.hopeless(pattern):
        return None
    if run.promising(pattern):
        bar = _bar(run.bound, earliest=PROMISING_EARLIEST)
    starts = _starts(run, pattern)
    best = run.attempt(stage, pattern, starts[0], abandon=bar)
    if best.status == "solved" or time.monotonic() > run.deadline:
        return best
    if len(starts) > 1:
        retry = run.attempt(stage, pattern, starts[1], abandon=bar, cap=PATTERNED_RETRY)
    elif best.status not in ("dominated", "time_limit") and not run.late():
        retry = run.attempt(stage, pattern, None, abandon=_bar(run.bound))
    else:
        return best
    return retry if _better(retry, best) else best


def _seeded_attempt(run: Run, pattern: Pattern):
    """The seed's pattern (:func:`_pattern_attempts`), then cut to fewer switches
    (:func:`_fewest`) when it did not solve; each abandoned once the bound dominates it. None
    when nothing was tried."""
    progress.stage(f"switch search: the seed's pattern, {len(pattern.times)} switch(es)")
    bar = _bar(run.bound, seeded=True)
    best = _pattern_attempts(run, "flat", pattern, bar)
    fewer = _fewest(run, pattern)
    if (best is not None and best.status == "solved") or fewer is None or run.late():
        return best
    progress.stage("switch search: the seed's strongest crossing alone")
    single = _pattern_attempts(run, "flat", fewer, bar)
    if single is None:
        return best
    return single if best is None or _better(single, best) else best


def _fewest(run: Run, pattern: Pattern) -> Pattern | None:
    """The seed's pattern cut to one switch more than the bound's (close pairs cancelled, then
    the crossings nearest the ends dropped, :func:`~cpopt.flatopt.switching.within_budget`),
    or None when that is the pattern itself."""
    least = len(needed_times(run.problem)) + 1
    if len(pattern.times) <= least:
        return None
    times = within_budget(pattern.times, least, run.problem.nodes[-1].t)
    wanted = gamma_signs_on_grid(run.problem, run.seed.trajectory)
    return agreeing(run.problem, times, wanted)


def _near(run: Run, pattern: Pattern, best, method: str):
    """The alternatives of switches near a node (:func:`near_alternatives`), started from the
    seed; the best plan and the method that found it."""
    wanted = gamma_signs_on_grid(run.problem, run.seed.trajectory)
    for alternative in near_alternatives(run.problem, pattern, wanted):
        if run.late():
            break
        if run.solved_before(alternative):
            continue
        progress.stage(f"switch search: near a node, {len(alternative.times)} switch(es)")
        attempt = _pattern_attempts(run, "near", alternative, _bar(best, run.bound, seeded=True))
        if attempt is None:
            continue
        if _better(attempt, best):
            best, method = attempt, "near"
    return best, method


def _polished(run: Run, best, method: str, notes: list):
    """The polish around the best plan with switches, when it may still gain
    (:func:`worth_polishing`)."""
    if not best.switch_times or run.late():
        return best, method
    if not worth_polishing(run.problem, best, run.seed):
        notes.append(f"no polish (within {POLISH_GAIN:.0%} of the seed's cost)")
        return best, method
    budget = run.stages["flat"].time_s
    polished, more = polish(  # capped by POLISH_LIMIT and the flat solve's time
        run.solve, run.problem, best, budget, run.stages["polish"], run.bound, run.solved_before
    )
    run.tried += more
    notes.append(f"polish tried {run.stages['polish'].tried} neighbour(s)")
    return (polished, "polish") if polished is not best else (best, method)


def _grown(run: Run, best, method: str, notes: list):
    """The greedy steps from the bound (:func:`~cpopt.flatopt.switching.grow`), when the
    seed's pattern did not solve: a switch more where the one-sign plan's margin binds."""
    progress.stage("switch search: the seed's pattern did not solve, greedy steps")
    tic = time.perf_counter()
    # judged like a seeded run: a greedy candidate of transfer_switch was 82 times the
    # one-sign plan at iteration 10 and then solved a quarter below it
    grown, more, said = grow(
        run.problem, run.solve, run.bound, run.deadline, SEEDED_EARLIEST, run.iterations_left
    )
    run.stages["greedy"].add_all(more, tic)
    run.iterations_left -= sum(a.iterations for a in more)
    run.tried += more
    notes.append(f"greedy steps from the bound: {said}")
    return (grown, "greedy") if _better(grown, best) else (best, method)


def _verdict(seeded, run: Run) -> str:
    """What became of the seed's pattern, against the bound."""
    bound = run.bound
    if seeded is None:
        costs = [s.report.objective for s in run.shaped.values() if s is not None]
        ratio = min(costs) / bound.objective if costs else math.nan
        return f"the seed's pattern costs {ratio:.3g} x the bound on the coarse grid: not tried"
    if seeded.status == "dominated":
        return f"the seed's pattern dominated by the one-sign bound ({seeded.ipopt_status})"
    if seeded.status != "solved":
        return f"the seed's pattern did not solve ({seeded.status})"
    if bound.status == "solved":
        return f"the seed's pattern at {seeded.objective / bound.objective:.3g} x the bound"
    return "the seed's pattern solved, the one-sign plans did not"


def _summary(wanted, seed, pattern, best, method, bound, notes) -> str:
    """One line: the plan kept, which stage found it, the bound, what became of the rest."""
    shown = _times(pattern.times) if pattern is not None else "none"
    bound_word = f"{bound.objective:.6g}" if bound.status == "solved" else bound.status
    found = f"found by {method}" if best.status == "solved" else f"none solved, best {method}"
    return (
        f"{len(best.switch_times)} switch(es) ({wanted} asked), {found}: "
        f"objective {best.objective:.6g}, one-sign bound {bound_word}; seed crossings at "
        f"{_times(seed.report.crossings)}, pattern {shown}; " + "; ".join(notes)
    )


def _times(times) -> str:
    return "[" + ", ".join(f"{t:.3f}" for t in times) + "] s"


__all__ = [
    "NEAR",
    "Run",
    "Stage",
    "near_alternatives",
    "polish",
    "search",
    "solve_pattern",
]
