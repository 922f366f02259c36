"""The seed of the switch search: where the unconstrained optimum wants gamma to cross zero.

A coarse direct collocation of the same problem without the regularity constraint
(:data:`SEED_INTERVALS` intervals; Hermite-Simpson, :mod:`cpopt.collocation.hermite_simpson`,
or the ``collocation/`` planner's rockit transcription where that one does not apply) is solved
first. Its gamma, read on
the collocation polynomials between the knots (not only at them), gives the crossings; crossings
closer than the shortest phase (:data:`cpopt.nodes.MIN_PHASE`) to each other cancel in pairs
(a dip too short for a phase of its own), and those closer to a node of the file than that are
moved inside. The signs of gamma between the crossings and the crossings' times are the pattern
(:func:`seed_pattern`); the seed's state and CP are the flat solve's warm start
(:func:`seeded_values`, :func:`cpopt.flatopt.warm_start.seeded_guess`).

Any trajectory serves as a seed: the polish of the search (:mod:`cpopt.flatopt.switching`)
seeds a neighbouring pattern with the plan it has solved.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..closedform.nodes import MIN_PHASE, NODE_FIELDS, node_names
from ..closedform.trajectory import Trajectory, gamma_crossings
from ..problem import Problem
from ..problem.holding import holding_pattern
from ..runtime.budget import check_time
from .transcribe import GAMMA_SAFETY

SEED_INTERVALS = 30
"""Collocation intervals of the seed (chosen by measurement: 30 finds the benchmark transfer's
three crossings within 5 ms of those at N = 200, in a third of the time of N = 60)."""
SIDE = 1e-9
"""Seconds before and after a node where its left and right states are read (a trajectory
holds a reset's time twice)."""
PUSH = 0.5
"""Where the seed's |gamma| is below gamma_min, a node value is moved to gamma_min + PUSH
[m/s^2] on its phase's side (a little inside the margin, so Ipopt starts interior)."""


@dataclass(frozen=True)
class SeedReport:
    """What the seed found and what it cost (``solution.json``: ``solver.search.seed``).

    Attributes
    ----------
    intervals : int
        Collocation intervals.
    status : str
        The collocation solve's status.
    iterations : int
        Its Ipopt iterations.
    time_s : float
        Wall time of the seed, building included [s].
    build_time_s, solve_time_s : float
        Building the NLP and Ipopt's solve [s].
    objective : float
        Its objective (the problem's, without the regularity constraint).
    crossings : tuple of float
        Every time its gamma changes sign [s].
    switch_times : tuple of float
        The crossings kept for the pattern [s] (close pairs cancelled, moved off the nodes).
    """

    intervals: int
    status: str
    iterations: int
    time_s: float
    objective: float
    crossings: tuple[float, ...]
    switch_times: tuple[float, ...]
    build_time_s: float = 0.0
    solve_time_s: float = 0.0

    def as_dict(self) -> dict:
        """JSON-ready figures."""
        return {
            "intervals": self.intervals,
            "status": self.status,
            "iterations": self.iterations,
            "time_s": self.time_s,
            "build_time_s": self.build_time_s,
            "solve_time_s": self.solve_time_s,
            "objective": self.objective,
            "crossings": list(self.crossings),
            "switch_times": list(self.switch_times),
        }


@dataclass(frozen=True)
class Seed:
    """A seed: the sampled trajectory and its report (``trajectory`` None when it failed)."""

    trajectory: Trajectory | None
    report: SeedReport


def shallow(traj: Trajectory, a: float, b: float, gamma_min: float) -> bool:
    """True when the seed's |gamma| stays below gamma_min between two crossings a < b [s]: an
    excursion to the other sign that a phase of that sign (|gamma| >= gamma_min throughout)
    would have to deepen as much as a phase of the surrounding sign would have to lift it."""
    inside = (traj.t > a) & (traj.t < b)
    return not inside.any() or float(np.abs(traj.gamma[inside]).max()) < gamma_min


def kept_crossings(
    times: tuple[float, ...], node_times: list[float], traj: Trajectory, gamma_min: float
) -> tuple[float, ...]:
    """The crossings a pattern can hold: a pair around a shallow excursion (:func:`shallow`)
    or closer than MIN_PHASE cancels (closest first), the rest are moved at least MIN_PHASE
    away from the file's nodes; a crossing with no room for that between two nodes is
    dropped."""
    kept = sorted(times)
    j = 0
    while j < len(kept) - 1:
        if shallow(traj, kept[j], kept[j + 1], gamma_min):
            del kept[j : j + 2]
        else:
            j += 1
    while len(kept) > 1:
        gaps = np.diff(kept)
        j = int(np.argmin(gaps))
        if gaps[j] >= MIN_PHASE:
            break
        del kept[j : j + 2]
    out: list[float] = []
    for t in kept:
        lo = max(n for n in node_times if n <= t)
        hi = min(n for n in node_times if n >= t)
        if hi - lo < 2 * MIN_PHASE:
            continue
        t = min(max(t, lo + MIN_PHASE), hi - MIN_PHASE)
        if out and t - out[-1] < MIN_PHASE:  # moved next to the previous one: the pair cancels
            out.pop()
        else:
            out.append(t)
    return tuple(out)


def coarse_seed(problem: Problem, intervals: int = SEED_INTERVALS, lean_only: bool = False) -> Seed:
    """Solve the problem by coarse collocation without the regularity constraint and read where
    its gamma crosses zero (see the module docstring). A failed solve still seeds (its last
    iterate) unless it returned no plan at all; nothing here raises on a valid problem. With
    ``lean_only`` a problem the Hermite-Simpson transcription does not take gets no seed (no
    trajectory) instead of rockit's, which takes seconds to build."""
    from ..collocation import collocate, joint_trajectory
    from ..collocation.hermite_simpson import SeedUnsupportedError, hermite_simpson

    tic = time.perf_counter()
    try:
        try:
            status, plan, stats = hermite_simpson(problem, intervals)
        except SeedUnsupportedError:  # other objectives: rockit's transcription
            if lean_only:
                raise
            result = collocate(problem, intervals=intervals, gamma_constraint=False)
            status, plan, stats = result.status, result.plan, result.solver
        traj = joint_trajectory(plan) if plan is not None else None
    except (RuntimeError, ValueError, ArithmeticError) as err:  # CasADi's errors are these
        check_time()  # a time limit that CasADi turned into a RuntimeError is not a failed seed
        traj, status, stats = None, f"failed: {str(err).splitlines()[0][:80]}", None
    found = gamma_crossings(traj.t, traj.gamma) if traj is not None else ()
    node_times = [n.t for n in problem.nodes]
    report = SeedReport(
        intervals=intervals,
        status=status,
        iterations=stats.iterations if stats else 0,
        time_s=time.perf_counter() - tic,
        objective=stats.objective if stats else math.nan,
        build_time_s=stats.build_time_s if stats else 0.0,
        solve_time_s=stats.solve_time_s if stats else 0.0,
        crossings=found,
        switch_times=kept_crossings(found, node_times, traj, problem.spec.optimizer.gamma_min)
        if traj is not None
        else (),
    )
    return Seed(traj, report)


SEED_BRANCH = 0.1
"""How far from the edge of the arm's branch a patterned seed keeps (RRR |sin q2|, PRR |cos q2|,
RPR's extension [m]; :func:`cpopt.kinematics.branch_margin`): a flat plan's fit of a seed that
grazes the edge (a random RRR transfer folding its elbow to sin q2 = 0.01) leaves the reach
between the samples, and the flat solve started at 1e27 times the seed's objective."""
PATTERNED_LIMIT = 60
"""Ipopt iterations of a patterned seed (:func:`patterned_seed`): the solved ones measured on
random problems took 9-40 from the seed; a hard RPR swing-down spent 10 s in 150 without
solving."""


def patterned_seed(
    problem: Problem,
    seed: Seed,
    times: tuple[float, ...],
    signs: tuple[int, ...],
    limit: int = PATTERNED_LIMIT,
    deadline: float = math.inf,
) -> Seed | None:
    """The seed solved again with a pattern of signs of gamma imposed: ``sign * gamma >=
    gamma_min`` on every piece between the file's nodes and the switch ``times`` [s], the
    torque free to step at a switch (a xi reset of the flat plan), started from ``seed``.

    A flat solve started from the unconstrained seed must first lift gamma off zero around
    each crossing, where the flat map is singular; from this one it starts regular (a random
    RPR transfer: 497 iterations to a failure from the seed, 193 to a plan from this). Its
    objective is what the pattern costs on the seed's coarse grid. Ipopt stops at ``deadline``
    (``time.monotonic()``) and the seed is then None: a search past its deadline keeps its
    best plan.

    Returns
    -------
    Seed or None
        The patterned seed, or None when the lean transcription does not take the problem,
        the seed has no trajectory or this solve did not solve.
    """
    from ..collocation import joint_trajectory
    from ..collocation.hermite_simpson import SeedUnsupportedError, hermite_simpson

    if seed.trajectory is None:
        return None
    tic = time.perf_counter()
    try:
        o = problem.spec.optimizer
        ceiling = o.gamma_min * (1 + GAMMA_SAFETY) if o.smooth_torque else None
        status, plan, stats = hermite_simpson(
            problem, seed.report.intervals, (times, signs), seed.trajectory, limit, ceiling,
            SEED_BRANCH, deadline,
        )  # fmt: skip
    except SeedUnsupportedError:
        return None
    except (RuntimeError, ValueError, ArithmeticError):  # CasADi's errors are these
        check_time()
        return None
    if status != "solved":
        return None
    report = SeedReport(
        intervals=seed.report.intervals,
        status=status,
        iterations=stats.iterations,
        time_s=time.perf_counter() - tic,
        objective=stats.objective,
        crossings=tuple(times),
        switch_times=tuple(times),
        build_time_s=stats.build_time_s,
        solve_time_s=stats.solve_time_s,
    )
    return Seed(PatternedTrajectory(**vars(joint_trajectory(plan))), report)


def _one_sided(traj: Trajectory, t: float, side: int) -> tuple[np.ndarray, np.ndarray]:
    """The seed's times and gamma on one side of t: before it (``side`` -1, t excluded) or from
    it on (+1; a collocation's sample at a knot carries the torque of the interval that starts
    there), so that a torque step at t (a patterned seed's switch) stays on its side."""
    keep = traj.t < t if side < 0 else traj.t >= t
    if keep.sum() < 2:
        keep = np.ones(traj.t.size, bool)
    return traj.t[keep], traj.gamma[keep]


def _gamma_and_rate(traj: Trajectory, t: float, side: int, one_sided: bool):
    """The seed's gamma [m/s^2] at t and its rate [m/s^3] over a few knots' steps: from the
    samples on ``side`` of t only with ``one_sided`` (extrapolated to t), else from all of
    them just on that side of t (the rate centred)."""
    width = max(MIN_PHASE / 2, 4 * float(np.median(np.diff(traj.t))))  # the knots' steps
    if not one_sided:
        at = t + side * SIDE
        lo, hi = max(at - width, traj.t[0]), min(at + width, traj.t[-1])
        rate = (np.interp(hi, traj.t, traj.gamma) - np.interp(lo, traj.t, traj.gamma)) / (hi - lo)
        return float(np.interp(at, traj.t, traj.gamma)), rate
    side = 1 if t <= traj.t[0] else -1 if t >= traj.t[-1] else side  # the ends: one side
    times, gammas = _one_sided(traj, t, side)
    near = times[-2:] if side < 0 else times[:2]  # extrapolated to t from its side
    slope = np.diff(np.interp(near, times, gammas))[0] / max(float(np.diff(near)[0]), 1e-12)
    edge = times[-1] if side < 0 else times[0]
    outside = not times[0] <= t <= times[-1]
    gamma = float(np.interp(t, times, gammas)) + slope * (t - edge) * outside
    lo, hi = (t - width, t) if side < 0 else (t, t + width)
    lo, hi = max(lo, times[0]), min(hi, times[-1])
    if hi <= lo:
        return gamma, 0.0
    return gamma, (np.interp(hi, times, gammas) - np.interp(lo, times, gammas)) / (hi - lo)


def state_at(
    traj: Trajectory,
    t: float,
    sign: int,
    gamma_min: float,
    K: float,
    g0: float,
    at_margin: bool = False,
    side: int = 1,
    one_sided: bool = False,
):
    """The extended state z (8) the seed suggests at time t for a phase of this sign of gamma:
    its pose and velocities, xi that gives its gamma moved to the sign's side
    (``gamma_min + PUSH`` where it is closer to zero than gamma_min; exactly at the margin with
    ``at_margin``, as a switch of a smooth-torque plan must be), eta from the rate of its gamma
    (gamma_dot = eta + 3 g0 cos(theta) thetadot), all on one ``side`` of t (-1 the left limit,
    +1 the right). A patterned seed's gamma steps at a switch: ``one_sided`` reads gamma and
    its rate from that side's samples only (a rate across the step gave eta of thousands and
    a fitted phase of 50 ms torques of 4e5 N m). The unconstrained seed's gamma steps at every
    knot and is read as it always was (one-sided there, the benchmark transfer's seeded solve
    no longer converged within 500 iterations)."""
    z = np.array([np.interp(t + side * SIDE, traj.t, traj.z[:, i]) for i in range(8)])
    gamma, rate = _gamma_and_rate(traj, t, side, one_sided)
    if at_margin:
        gamma = sign * gamma_min * (1 + GAMMA_SAFETY)
    elif sign * gamma < gamma_min * (1 + GAMMA_SAFETY):
        gamma = sign * (gamma_min + PUSH)
    theta, thetadot = z[2], z[5]
    z[6] = gamma + K * thetadot**2 - g0 * math.sin(theta)
    if not math.isfinite(z[7]):  # a collocation's eta is undefined: from its gamma's rate
        z[7] = rate - 3 * g0 * math.cos(theta) * thetadot
    return z


INSIDE = 0.02
"""How far inside a freed value's bounds a seeded value is clipped [fraction of the range]."""


def inside(lo: float, hi: float) -> tuple[float, float]:
    """The bounds [lo, hi] moved inside by :data:`INSIDE` of the range (finite ones)."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return lo, hi
    d = INSIDE * (hi - lo)
    return lo + d, hi - d


class PatternedTrajectory(Trajectory):
    """A patterned seed's samples (:func:`patterned_seed`): its torques continuous but at its
    switches, where :func:`seeded_values` reads it one-sided."""


def seeded_values(
    problem: Problem, signs: tuple[int, ...], traj: Trajectory, fixed_times: bool = True
) -> dict[str, float]:
    """The problem's values (SI) with every freed node value taken from the seed (within its
    bounds): the states at the nodes' times, xi and eta on each side for its phase's sign.

    With ``fixed_times`` node times and the duration keep their guesses (the switch times are
    the pattern's, already among them)."""
    arm = problem.arm
    gamma_min = problem.spec.optimizer.gamma_min
    values = dict(problem.values)
    names = node_names(len(problem.nodes))
    smooth = problem.spec.optimizer.smooth_torque
    held = holding_pattern(problem, signs)
    one_sided = isinstance(traj, PatternedTrajectory)
    for i, (name, node) in enumerate(zip(names, problem.nodes, strict=True)):
        sign_before, sign_after = signs[max(i - 1, 0)], signs[min(i, len(signs) - 1)]
        switch = smooth and sign_before != sign_after and f"{name}.xi_after" in problem.free
        before, after = (
            state_at(traj, node.t, sign, gamma_min, arm.K, arm.gravity, switch, side, one_sided)
            for side, sign in ((-1, sign_before), (1, sign_after))
        )
        if held[i]:
            before[6] = after[6] = 0.0
        suggested = dict(zip(NODE_FIELDS, before, strict=True))
        suggested["xi_after"], suggested["eta_after"] = after[6], after[7]
        for field, value in suggested.items():
            key = f"{name}.{field}"
            if key in problem.free:
                lo, hi = problem.free[key]
                values[key] = float(np.clip(value, *inside(lo, hi)))
    if not fixed_times and "duration" in problem.free:
        values["duration"] = float(traj.t[-1])
    return values


__all__ = [
    "PATTERNED_LIMIT",
    "PUSH",
    "SEED_INTERVALS",
    "PatternedTrajectory",
    "Seed",
    "SeedReport",
    "coarse_seed",
    "kept_crossings",
    "patterned_seed",
    "seeded_values",
    "state_at",
]
