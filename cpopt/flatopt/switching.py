"""Where gamma changes sign: the patterns of signs the flat optimizer solves for, and the via
states it adds to switch the sign (``optimizer.gamma_switches``).

A plan's phases each keep one sign of gamma. Across a via state that does not reset xi the
sign stays (theta, thetadot and xi are continuous); across one that resets xi it may change; a
fixed value of gamma at a phase's end, or ``gamma_sign`` (the sign at the start of each of the
file's phases), pins it. A *switch* is a via state the optimizer adds inside a phase, with free
time, free state (continuous across it), free xi and eta before and after it, and opposite
signs on its two sides: the plan passes from one side of gamma = 0 to the other without ever
being singular, and the torque steps there once.

The search (route (a) of issue 11): solve with the fewest switches the pinned signs need, then
add a switch where the margin |gamma| >= gamma_min binds hardest (the largest sum of the
constraints' multipliers over a stretch where it binds) or in the middle of the longest phase,
re-solve, and repeat until ``gamma_switches`` switches are placed or, with ``auto``, until a
switch lowers the cost by less than :data:`GAIN`. Every pattern solved is kept and reported.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from ..closedform.nodes import MIN_PHASE, NODE_FIELDS, node_names
from ..closedform.plan import Node
from ..problem import MAX_SWITCHES, Problem
from .dominance import SEEDED_EARLIEST, dominated
from .seed import Seed, coarse_seed

GAIN = 0.01
"""``auto`` keeps a switch only when it lowers the cost by at least this fraction."""
GRID = 801
"""Times over the motion on which patterns of signs are compared."""
POLISH_LIMIT = 150
"""Most Ipopt iterations of one polish attempt: a neighbour that needs more is not cheap."""
POLISH_SPAN = 0.2
"""A switch is dropped in the polish only where the stretch whose sign it flips is at most
this fraction of the motion."""
SWITCH_FIELDS = (*NODE_FIELDS, "xi_after", "eta_after", "t")
"""The values of a switch the optimizer chooses: the whole state, xi and eta on both sides
and the time."""
SIGN_WORDS = {"positive": 1, "negative": -1}


@dataclass(frozen=True)
class Pattern:
    """Switch times and signs: the structure of one NLP.

    Attributes
    ----------
    times : tuple of float
        Initial times of the switches [s] (the solve moves them).
    signs : tuple of int
        The sign of gamma of each phase of the plan (the file's phases split at the switches).
    """

    times: tuple[float, ...]
    signs: tuple[int, ...]


@dataclass(frozen=True)
class Search:
    """Every pattern solved, the best one, how the search ended, and its figures for
    ``solution.json`` (``solver.search``: the method, and for the seeded search the seed's,
    the flat solve's and the polish's iterations and times)."""

    attempts: tuple
    best: object
    summary: str
    figures: dict = field(default_factory=dict)


def _phases(problem: Problem, times: tuple[float, ...]) -> list[tuple[int, float, float]]:
    """The plan's phases for switch times: (the file's phase, start [s], end [s])."""
    ends = [n.t for n in problem.nodes]
    out = []
    for k in range(len(ends) - 1):
        cuts = [ends[k], *sorted(t for t in times if ends[k] < t < ends[k + 1]), ends[k + 1]]
        out += [(k, a, b) for a, b in itertools.pairwise(cuts)]
    return out


def _pins(problem: Problem, phases: list) -> list[set[int]]:
    """Per phase of the plan, the signs its fixed values of gamma and ``gamma_sign`` allow."""
    arrive, leave = problem.gamma_sides
    wanted = problem.spec.optimizer.gamma_sign or ["auto"] * (len(problem.nodes) - 1)
    out = []
    for j, (k, _, _) in enumerate(phases):
        allowed = {1, -1}
        first = j == 0 or phases[j - 1][0] != k
        last = j == len(phases) - 1 or phases[j + 1][0] != k
        sides = ([leave[k]] if first else []) + ([arrive[k + 1]] if last else [])
        for side in sides:
            if side.fixed:
                allowed &= {int(np.sign(side.gamma))}
        if first and wanted[k] in SIGN_WORDS:
            allowed &= {SIGN_WORDS[wanted[k]]}
        out.append(allowed)
    return out


def _groups(problem: Problem, phases: list) -> tuple[list[list[int]], list[int]]:
    """Groups of the plan's phases whose signs are tied (by switches and by via states of the
    file that do not reset xi), and each phase's sign relative to its group's first."""
    arrive, leave = problem.gamma_sides
    groups: list[list[int]] = []
    relation: list[int] = []
    for j, (k, _, _) in enumerate(phases):
        switch = j > 0 and phases[j - 1][0] == k
        if j and (switch or leave[k] is arrive[k]):  # no xi reset between j - 1 and j
            relation.append(-relation[-1] if switch else relation[-1])
            groups[-1].append(j)
        else:
            relation.append(1)
            groups.append([j])
    return groups, relation


def sign_assignments(problem: Problem, times: tuple[float, ...] = ()) -> list[tuple[int, ...]]:
    """Every pattern of signs the pins allow for switches at ``times``: opposite signs across a
    switch, the same across a via state of the file that does not reset xi, either across one
    that does."""
    phases = _phases(problem, times)
    pins = _pins(problem, phases)
    groups, relation = _groups(problem, phases)
    choices = []
    for group in groups:
        fits = [s for s in (1, -1) if all(s * relation[j] in pins[j] for j in group)]
        choices.append([tuple(s * relation[j] for j in group) for s in fits])
    return [sum(combo, ()) for combo in itertools.product(*choices)]


def _conflict(problem: Problem, times: tuple[float, ...]) -> tuple[float, float] | None:
    """The longest phase between two pins that disagree (start, end [s]), or None."""
    phases = _phases(problem, times)
    pins = _pins(problem, phases)
    groups, relation = _groups(problem, phases)
    for group in groups:
        pinned = [(j, next(iter(pins[j])) * relation[j]) for j in group if len(pins[j]) == 1]
        spans = [(j, j) for j in group if not pins[j]]  # both ends of one phase disagree
        spans += [(a, b) for (a, sa), (b, sb) in itertools.pairwise(pinned) if sa != sb]
        if spans:
            a, b = spans[0]
            _, t0, t1 = max(phases[a : b + 1], key=lambda ph: ph[2] - ph[1])
            return t0, t1
    return None


def needed_times(problem: Problem) -> tuple[float, ...]:
    """Switch times that make the pinned signs possible: one in the middle of the longest
    phase between two pins that disagree, until a pattern exists."""
    times: tuple[float, ...] = ()
    while (span := _conflict(problem, times)) is not None and len(times) < MAX_SWITCHES:
        times = tuple(sorted((*times, 0.5 * (span[0] + span[1]))))
    return times


def _interpolated(problem: Problem, t: float) -> np.ndarray:
    """The state z (8) between the file's nodes around t, interpolated linearly."""
    nodes = problem.nodes
    k = max(i for i, n in enumerate(nodes[:-1]) if n.t <= t)
    a, b = nodes[k].state(after=True), nodes[k + 1].state()
    s = (t - nodes[k].t) / (nodes[k + 1].t - nodes[k].t)
    return (1 - s) * a + s * b


def with_switches(
    problem: Problem, times: tuple[float, ...], free_times: bool = True
) -> tuple[Problem, tuple[int, ...]]:
    """The problem with switches added at ``times``, and their indices among its nodes.

    A switch's values are free (its time between its neighbours, kept ``MIN_PHASE`` apart by
    the NLP, unless ``free_times`` is False: then it stays at ``times``); their initial guess
    is the file's node states interpolated linearly (the warm start then moves xi before and
    after it to the signs' sides). The file's via states keep their values and freed names,
    renumbered.
    """
    files = problem.nodes
    nodes, index, switches = [files[0]], {}, []
    ordered = sorted(times)
    for i, node in enumerate(files[1:], start=1):
        for t in [t for t in ordered if nodes[-1].t < t < node.t]:
            z = _interpolated(problem, t)
            switches.append(len(nodes))
            nodes.append(Node(t, *z[:6], xi=z[6], eta=z[7], xi_after=z[6], eta_after=z[7]))
        index[i] = len(nodes)
        nodes.append(node)
    old, new = node_names(len(problem.nodes)), node_names(len(nodes))
    renamed = {old[i]: new[index.get(i, 0)] for i in range(len(old))}
    free = {}
    for name, bounds in problem.free.items():
        node, dot, f = name.partition(".")
        free[f"{renamed.get(node, node)}{dot}{f}"] = bounds
    fields = SWITCH_FIELDS if free_times else SWITCH_FIELDS[:-1]
    for i in switches:
        free.update({f"{new[i]}.{f}": (-math.inf, math.inf) for f in fields})
    return replace(problem, nodes=tuple(nodes), free=free), tuple(switches)


Solve = Callable[..., object]
"""``solve(problem, signs, switches) -> SignAttempt``, as
:func:`cpopt.flatopt.solve_for_signs`."""


@dataclass(frozen=True)
class Stretch:
    """A stretch of time where the margin |gamma| >= gamma_min binds.

    Attributes
    ----------
    weight : float
        The sum of the binding constraints' multipliers.
    t : float
        Their multiplier-weighted mean time [s].
    start, end : float
        Where the stretch begins and ends [s].
    """

    weight: float
    t: float
    start: float
    end: float


def stretches(active: tuple, duration: float) -> list[Stretch]:
    """The stretches where the margin binds, heaviest first, from (time, multiplier) pairs
    (rows closer than 1 % of the duration belong to one stretch)."""
    out, current = [], []
    for t, lam in sorted(active):
        if current and t - current[-1][0] > 0.01 * duration:
            out.append(current)
            current = []
        current.append((t, lam))
    out += [current] if current else []
    result = []
    for rows in out:
        t, lam = np.array(rows).T
        result.append(Stretch(float(lam.sum()), float(t @ lam / lam.sum()), t[0], t[-1]))
    return sorted(result, key=lambda s: -s.weight)


def _carried(problem: Problem, old: Pattern, times: tuple[float, ...]) -> list[int]:
    """The signs of ``old`` carried over to the phases of switches at ``times``."""
    before = _phases(problem, old.times)
    out = []
    for k, a, b in _phases(problem, times):
        mid = 0.5 * (a + b)
        out.append(next(s for (kk, aa, bb), s in zip(before, old.signs, strict=True)
                        if kk == k and aa <= mid <= bb))  # fmt: skip
    return out


def _inside(problem: Problem, times: tuple[float, ...], t: float) -> float | None:
    """t moved at least MIN_PHASE away from the nodes and switches around it, or None."""
    marks = sorted({n.t for n in problem.nodes} | set(times))
    lo = max((m for m in marks if m <= t), default=None)
    hi = min((m for m in marks if m >= t), default=None)
    if lo is None or hi is None or hi - lo < 2 * MIN_PHASE:
        return None
    return min(max(t, lo + MIN_PHASE), hi - MIN_PHASE)


def single_switch(problem: Problem, old: Pattern, t: float) -> list[Pattern]:
    """The patterns that add one switch at time t [s] with either side flipped (those the pins
    allow)."""
    t = _inside(problem, old.times, t)
    if t is None:
        return []
    times = tuple(sorted((*old.times, t)))
    carried = _carried(problem, old, times)
    j = _phases(problem, times).index(next(ph for ph in _phases(problem, times) if ph[1] == t))
    groups, _ = _groups(problem, _phases(problem, times))
    group = next(g for g in groups if j in g)
    options = []
    for flipped in ([i for i in group if i >= j], [i for i in group if i < j]):
        signs = tuple(-s if i in flipped else s for i, s in enumerate(carried))
        if signs in sign_assignments(problem, times):
            options.append(Pattern(times, signs))
    return options


def next_patterns(problem: Problem, old: Pattern, stretch: Stretch) -> list[Pattern]:
    """The patterns that add a switch where a stretch binds: one switch with either side
    flipped (those the pins allow), or, when neither is allowed, a pair around the stretch
    with its middle flipped."""
    options = single_switch(problem, old, stretch.t)
    if options:
        return options
    half = max(0.5 * (stretch.end - stretch.start), 0.5 * MIN_PHASE)
    first = _inside(problem, old.times, stretch.t - half)
    second = _inside(problem, old.times, stretch.t + half)
    if first is None or second is None or second - first < MIN_PHASE:
        return []
    times = tuple(sorted((*old.times, first, second)))
    carried = _carried(problem, old, times)
    middle = next(i for i, ph in enumerate(_phases(problem, times)) if ph[1] == first)
    signs = tuple(-s if i == middle else s for i, s in enumerate(carried))
    return [Pattern(times, signs)] if signs in sign_assignments(problem, times) else []


def within_budget(times: tuple[float, ...], budget: int, duration: float) -> tuple[float, ...]:
    """At most ``budget`` switch times: the closest pair cancels while two or more are too
    many, then the crossing nearest an end of the motion goes."""
    kept = sorted(times)
    while len(kept) > budget:
        if len(kept) - budget >= 2:
            j = int(np.argmin(np.diff(kept)))
            del kept[j : j + 2]
        else:
            kept.remove(min(kept, key=lambda t: min(t, duration - t)))
    return tuple(kept)


def signs_on_grid(problem: Problem, pattern: Pattern) -> np.ndarray:
    """A pattern's sign of gamma at :data:`GRID` equally spaced times over the motion."""
    t = np.linspace(0.0, problem.nodes[-1].t, GRID)
    cuts = np.array([b for _, _, b in _phases(problem, pattern.times)[:-1]])
    return np.take(pattern.signs, np.searchsorted(cuts, t, side="right"))


def gamma_signs_on_grid(problem: Problem, traj) -> np.ndarray:
    """The sign (+1 or -1) of a sampled trajectory's gamma at the :data:`GRID` times."""
    t = np.linspace(0.0, problem.nodes[-1].t, GRID)
    return np.where(np.interp(t, traj.t, traj.gamma) >= 0, 1, -1)


def agreement(problem: Problem, pattern: Pattern, wanted: np.ndarray) -> int:
    """At how many of the :data:`GRID` times a pattern has the sign ``wanted`` there."""
    return int(np.sum(signs_on_grid(problem, pattern) == wanted))


def agreeing(problem: Problem, times: tuple[float, ...], wanted: np.ndarray) -> Pattern | None:
    """Of the signs the pins allow for switches at ``times``, the pattern that agrees with the
    signs ``wanted`` (:func:`agreement`) the longest; None when the pins allow none."""
    allowed = [Pattern(times, signs) for signs in sign_assignments(problem, times)]
    return max(allowed, key=lambda p: agreement(problem, p, wanted)) if allowed else None


def seed_pattern(problem: Problem, seed: Seed, budget: int) -> Pattern | None:
    """The pattern a seed suggests: its crossings (at most ``budget``) and, of the signs the pins
    allow for them, the one that agrees with the sign of the seed's gamma the longest."""
    times = within_budget(seed.report.switch_times, budget, problem.nodes[-1].t)
    return agreeing(problem, times, gamma_signs_on_grid(problem, seed.trajectory))


def neighbours(problem: Problem, old: Pattern) -> list[Pattern]:
    """The patterns one switch away: two adjacent switches merged (the short stretch between
    them takes its neighbours' sign), then each switch dropped whose shorter side is at most
    :data:`POLISH_SPAN` of the motion, the shortest stretch first; each with the signs that
    agree with ``old`` the longest."""
    wanted = signs_on_grid(problem, old)
    times = sorted(old.times)
    merged = [(times[j + 1] - times[j], (j, j + 1)) for j in range(len(times) - 1)]
    bounds = [0.0, *times, problem.nodes[-1].t]
    dropped = [(min(bounds[j + 1] - bounds[j], bounds[j + 2] - bounds[j + 1]), (j,))
               for j in range(len(times))]  # fmt: skip
    # flipping the sign of gamma over a long stretch is never a cheap solve: not tried
    dropped = [d for d in dropped if d[0] <= POLISH_SPAN * problem.nodes[-1].t]
    out = []
    for _, gone in sorted(merged) + sorted(dropped):
        kept = tuple(x for j, x in enumerate(times) if j not in gone)
        pattern = agreeing(problem, kept, wanted)
        if pattern is not None and pattern not in out:
            out.append(pattern)
    return out


def solve_from_nodes(
    solve: Solve, problem: Problem, pattern: Pattern, abandon=None, limit: int | None = None
):
    """Solve one pattern from the closed form through the file's nodes and switch states
    interpolated between them. (Starting from the previous plan was measured worse: where the
    new pattern flips the sign of a long stretch its CP curve asks for the link turned by half
    a turn, and a failed solve costs its whole iteration limit.)"""
    augmented, switches = with_switches(problem, pattern.times)
    # a cap on the search's iterations: a solved plan still gets its refinement rounds
    past = limit is not None
    return solve(
        augmented, pattern.signs, switches, abandon=abandon, limit=limit, refine_past_limit=past
    )


def solve_pattern(
    solve: Solve, problem: Problem, pattern: Pattern, start, limit=None, abandon=None, **options
):
    """Solve one pattern with its switch times held, started from the trajectory ``start``
    (from the closed form through the nodes when it is None); ``limit``, ``abandon`` and the
    ``options`` (a ``deadline``, ``refine_past_limit``) as in
    :func:`cpopt.flatopt.solve_for_signs`."""
    augmented, switches = with_switches(problem, pattern.times, free_times=False)
    return solve(
        augmented, pattern.signs, switches, seed=start, limit=limit, abandon=abandon, **options
    )


def seed_order(problem: Problem, patterns: list[Pattern], seed: Seed | None = None) -> list:
    """The patterns with the one the coarse unconstrained collocation ``seed`` agrees with
    first (without one, the lean seed only, 0.3 s; where it does not apply, or fails, the
    order stays)."""
    if len(patterns) < 2:
        return patterns
    seed = coarse_seed(problem, lean_only=True) if seed is None else seed
    if seed.trajectory is None:
        return patterns
    wanted = gamma_signs_on_grid(problem, seed.trajectory)
    return sorted(patterns, key=lambda p: -agreement(problem, p, wanted))


def first_attempts(
    solve: Solve,
    problem: Problem,
    patterns: list[Pattern],
    seed: Seed | None = None,
    limit: int | None = None,
) -> list:
    """Solve the first patterns, the seed's favourite first (:func:`seed_order`); a later run
    is abandoned once a solved one dominates it (:func:`dominated`). ``limit`` caps each
    run's Ipopt iterations before its first solved round (its refinements still run)."""
    attempts = []
    for pattern in seed_order(problem, patterns, seed):
        solved = [a.objective for a in attempts if a.status == "solved"]
        abandon = dominated(min(solved)) if solved else None
        attempts.append(solve_from_nodes(solve, problem, pattern, abandon, limit))
    return attempts


SEED_GAP = 0.01
"""Relative cost above a coarse seed's objective beyond which a plan solved from the closed
form is started again from the seed (:func:`seed_start`)."""
SEED_START_LIMIT = 500
"""Ipopt iterations a start from the seed gets before its first solved round."""


def above_seed(problem: Problem, best, seed: Seed, gap: float = SEED_GAP) -> bool | None:
    """True when the plan ``best`` costs more than ``gap`` (relative) above the seed's
    objective (the same functional without the regularity constraint, on a coarse grid);
    None where the two do not compare: the motion's duration free (a seed keeps freed times
    at their guesses) or a seed without an objective."""
    objective = seed.report.objective
    if "duration" in problem.free or not math.isfinite(objective):
        return None
    return best.objective > (1 + gap) * objective


def far_above_seed(problem: Problem, best, seed: Seed) -> bool:
    """True when ``best`` is solved and costs more than :data:`SEED_GAP` above the seed
    (:func:`above_seed`; False where they do not compare)."""
    return best.status == "solved" and above_seed(problem, best, seed) is True


def seed_throughout(problem: Problem, pattern: Pattern, seed: Seed) -> bool:
    """True when the seed's gamma has ``pattern``'s sign at every :data:`GRID` time."""
    wanted = gamma_signs_on_grid(problem, seed.trajectory)
    return agreement(problem, pattern, wanted) == len(wanted)


def fewest_patterns(problem: Problem) -> list[Pattern]:
    """The patterns with the fewest switches the pins allow (one sign where nothing is
    pinned), one per allowed assignment of signs."""
    times = needed_times(problem)
    return [Pattern(times, signs) for signs in sign_assignments(problem, times)]


def seed_start(solve: Solve, problem: Problem, patterns: list[Pattern], seed, attempts) -> list:
    """The seed's favourite of the first ``patterns`` (:func:`seed_order`) started from the
    seed's trajectory, when none of ``attempts`` solved or when the seed has that pattern's
    signs throughout and the best solved plan is far above it (:func:`far_above_seed`): the
    closed form's local optimum may be far above the seed's (a random PRR transfer solved at
    43 times the seed's objective from the closed form and within 0.1 % of it from the seed,
    in 16 iterations). Abandoned once the best solved plan dominates it. Returns the attempts
    made (none or one)."""
    if seed is None or seed.trajectory is None or not patterns:
        return []
    best = _best(attempts)
    favourite = seed_order(problem, patterns, seed)[0]
    throughout = seed_throughout(problem, favourite, seed)
    if best.status == "solved" and not (throughout and far_above_seed(problem, best, seed)):
        return []
    abandon = dominated(best.objective, SEEDED_EARLIEST) if best.status == "solved" else None
    options = {"refine_past_limit": True}
    start = seed.trajectory
    return [solve_pattern(solve, problem, favourite, start, SEED_START_LIMIT, abandon, **options)]


def pattern_of(attempt) -> Pattern:
    """The pattern (switch times, signs) of a solved attempt."""
    return Pattern(attempt.switch_times, tuple(ph.sigma for ph in attempt.plan.phases))


def preference(attempt) -> tuple:
    """Sort key of attempts, the best plan largest: solved first; then an iterate with numbers
    (Ipopt's ``Invalid_Number_Detected`` leaves an objective of 0 that must not win); then,
    among unsolved ones, the fewest violated constraints; then the lowest objective."""
    sane = attempt.ipopt_status != "Invalid_Number_Detected" and math.isfinite(attempt.objective)
    solved = attempt.status == "solved"  # a solved plan's residual violations do not count
    return (solved, sane, 0 if solved else -len(attempt.violations), -attempt.objective)


def _best(attempts):
    return max(attempts, key=preference)


def candidates(problem: Problem, best, budget: int) -> list[Pattern]:
    """The patterns to try with a switch more than ``best``'s: where the margin binds hardest
    (the first stretch that takes one), and in the middle of the longest phase when that is
    farther than a tenth of the motion from there (a one-sign plan need not touch the margin
    near the crossings of the unconstrained optimum: the benchmark swing-up binds at 1.51 s
    and 0 s, and crosses at 1.04 s)."""
    old = pattern_of(best)
    duration = problem.nodes[-1].t
    out: list[Pattern] = []
    for stretch in stretches(best.active_gamma, duration):
        out = [p for p in next_patterns(problem, old, stretch) if len(p.times) <= budget]
        if out:
            break
    _, a, b = max(_phases(problem, old.times), key=lambda ph: ph[2] - ph[1])
    middle = 0.5 * (a + b)
    placed = {t for p in out for t in p.times} - set(old.times)
    if all(abs(middle - t) > 0.1 * duration for t in placed):
        out += [p for p in single_switch(problem, old, middle) if len(p.times) <= budget]
    return out


def search(problem: Problem, solve: Solve, deadline: float = math.inf) -> Search:
    """Solve the patterns of signs a problem allows and, with ``gamma_switches``, add switches
    where the margin binds (see the module docstring).

    Parameters
    ----------
    problem : Problem
        The problem.
    solve : callable
        ``solve(problem, signs, switches) -> SignAttempt``.
    deadline : float
        ``time.monotonic()`` after which no pattern with a switch more is tried.

    Returns
    -------
    Search
        Every attempt, the best (the cheapest solved one, else the cheapest), and a summary.
    """
    wanted = problem.spec.optimizer.gamma_switches
    budget = MAX_SWITCHES if wanted == "auto" else wanted
    times = needed_times(problem) if budget else ()
    first = [Pattern(times, signs) for signs in sign_assignments(problem, times)]
    seed = coarse_seed(problem, lean_only=True) if len(first) > 1 else None
    attempts = first_attempts(solve, problem, first, seed)
    started = seed_start(solve, problem, first, seed, attempts)
    attempts += started
    best = _best(attempts)
    best, more, said = grow(problem, solve, best, deadline)
    attempts += more
    summary = f"{len(best.switch_times)} switch(es) ({wanted} asked): "
    summary += f"{len(times)} switch(es) needed by the fixed signs; {said}"
    if started:
        summary += f"; the seed's favourite sign started from the seed ({started[0].status})"
    return Search(tuple(attempts), best, summary, {"method": "greedy", "summary": summary})


def grow(
    problem: Problem,
    solve: Solve,
    best,
    deadline: float = math.inf,
    earliest: int | None = None,
    iterations: float = math.inf,
) -> tuple:
    """The greedy steps from a solved plan ``best``: add a switch where the margin binds
    (:func:`candidates`), each candidate solved from the closed form, while a switch more
    lowers the cost (by :data:`GAIN` with ``auto``) and ``gamma_switches`` allows one more.
    With ``earliest`` a candidate is abandoned once ``best`` dominates it
    (:func:`dominated` from that iteration); the candidates get ``iterations`` Ipopt
    iterations together. Returns the best attempt, the attempts made and why the steps
    stopped."""
    wanted = problem.spec.optimizer.gamma_switches
    budget = MAX_SWITCHES if wanted == "auto" else wanted
    attempts: list = []
    if best.status != "solved":  # the steps add a switch to a plan: none to add it to
        return best, attempts, f"no solved plan to step from (the bound {best.status})"
    left = iterations
    while len(best.switch_times) < budget:  # best stays solved: only a solved one replaces it
        if time.monotonic() > deadline:
            return best, attempts, "search deadline reached"
        if left <= 0:
            return best, attempts, "the search's iterations spent"
        patterns = candidates(problem, best, budget)
        if not patterns:
            return best, attempts, "no place left for a switch"
        tried = []
        for pattern in patterns:
            if left <= 0:
                break
            # each run its own: the rule keeps the run's history
            abandon = None if earliest is None else dominated(best.objective, earliest)
            limit = None if math.isinf(left) else int(left)
            tried.append(solve_from_nodes(solve, problem, pattern, abandon, limit))
            left -= tried[-1].iterations
        attempts += tried
        better = _best(tried)
        gain = (best.objective - better.objective) / max(abs(best.objective), 1e-12)
        if better.status != "solved":
            return best, attempts, "no pattern with a switch more was solved: stopped"
        if gain <= 0 or (wanted == "auto" and gain < GAIN):
            return best, attempts, f"a switch more lowered the cost by {gain:.2%}: stopped"
        best = better
    return best, attempts, f"{len(best.switch_times)} switch(es): the most allowed"
