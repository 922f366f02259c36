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

from ..budget import check_time
from ..nodes import MIN_PHASE, NODE_FIELDS, node_names
from ..problem import Problem
from ..trajectory import Trajectory, gamma_crossings
from .transcribe import GAMMA_SAFETY, holding_pattern

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


def state_at(
    traj: Trajectory,
    t: float,
    sign: int,
    gamma_min: float,
    K: float,
    g0: float,
    at_margin: bool = False,
):
    """The extended state z (8) the seed suggests at time t for a phase of this sign of gamma:
    its pose and velocities, xi that gives its gamma moved to the sign's side
    (``gamma_min + PUSH`` where it is closer to zero than gamma_min; exactly at the margin with
    ``at_margin``, as a switch of a smooth-torque plan must be), eta from the rate of its gamma
    (gamma_dot = eta + 3 g0 cos(theta) thetadot)."""
    z = np.array([np.interp(t, traj.t, traj.z[:, i]) for i in range(8)])
    gamma = float(np.interp(t, traj.t, traj.gamma))
    if at_margin:
        gamma = sign * gamma_min * (1 + GAMMA_SAFETY)
    elif sign * gamma < gamma_min * (1 + GAMMA_SAFETY):
        gamma = sign * (gamma_min + PUSH)
    theta, thetadot = z[2], z[5]
    z[6] = gamma + K * thetadot**2 - g0 * math.sin(theta)
    if not math.isfinite(z[7]):  # a collocation's eta is undefined: from its gamma's rate
        width = max(MIN_PHASE / 2, 4 * float(np.median(np.diff(traj.t))))  # the knots' steps
        lo, hi = max(t - width, traj.t[0]), min(t + width, traj.t[-1])
        rate = (np.interp(hi, traj.t, traj.gamma) - np.interp(lo, traj.t, traj.gamma)) / (hi - lo)
        z[7] = rate - 3 * g0 * math.cos(theta) * thetadot
    return z


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
    for i, (name, node) in enumerate(zip(names, problem.nodes, strict=True)):
        sign_before, sign_after = signs[max(i - 1, 0)], signs[min(i, len(signs) - 1)]
        switch = smooth and sign_before != sign_after and f"{name}.xi_after" in problem.free
        before, after = (
            state_at(traj, node.t + side, sign, gamma_min, arm.K, arm.gravity, at_margin=switch)
            for side, sign in ((-SIDE, sign_before), (SIDE, sign_after))
        )
        if held[i]:
            before[6] = after[6] = 0.0
        suggested = dict(zip(NODE_FIELDS, before, strict=True))
        suggested["xi_after"], suggested["eta_after"] = after[6], after[7]
        for field, value in suggested.items():
            key = f"{name}.{field}"
            if key in problem.free:
                lo, hi = problem.free[key]
                values[key] = float(np.clip(value, lo, hi))
    if not fixed_times and "duration" in problem.free:
        values["duration"] = float(traj.t[-1])
    return values


__all__ = [
    "PUSH",
    "SEED_INTERVALS",
    "Seed",
    "SeedReport",
    "coarse_seed",
    "kept_crossings",
    "seeded_values",
    "state_at",
]
