"""Checks of an optimized plan between its samples, and the report of violated constraints.

gamma is certified exactly on every polynomial piece of the CP curves (the end points and the
real roots of the derivative of |p'' + g0 e_y|^2); torque and joint-velocity limits are checked
on a fine grid. Where either fails, the optimizer adds samples there and solves again.
"""

from __future__ import annotations

import numpy as np

from ..kinematics import ReachError
from ..limits import sampled
from ..plan import CPPlan
from ..problem import Problem
from ..trajectory import sample
from .transcribe import FlatNLP

CERTIFICATION = (
    "exact minimum of |p'' + g0 e_y| over every polynomial piece of the CP curves "
    "(end points and real roots of the derivative of its square)"
)
LIMIT_CHECK_SAMPLES = 2001
"""Samples per phase on which limits are checked after a solve."""
MAX_REFINEMENTS = 4
"""Re-solves with samples added where gamma or a limit failed between samples."""


def gamma_dips(problem: Problem, plan: CPPlan, times: list) -> list[set]:
    """Per phase, the normalised times where the certified |gamma| is below gamma_min."""
    target = problem.spec.optimizer.gamma_min * (1 - 1e-6) - 1e-9
    found = [set() for _ in plan.phases]
    for k, ph in enumerate(plan.phases):
        for value, t in ph.curve.piece_minima((0.0, problem.arm.gravity)):
            if value < target:
                found[k].add(round((t - times[k]) / (times[k + 1] - times[k]), 9))
    return found


def limit_excursions(problem: Problem, plan: CPPlan, times: list) -> list[set] | None:
    """Per phase, the normalised times where a torque or joint-velocity limit fails on a grid
    of :data:`LIMIT_CHECK_SAMPLES`; None when there is nothing to check (no such limit, or a
    plan out of reach, which the solve reports itself)."""
    checked = [limit for limit in problem.limits if limit.magnitude]
    if not checked:
        return None
    per_phase = max(LIMIT_CHECK_SAMPLES, problem.spec.verification.samples)
    try:
        traj = sample(plan, per_phase=per_phase)
    except ReachError:
        return None
    found = [set() for _ in plan.phases]
    for limit in checked:
        excess = limit.excess(sampled(limit, traj)) - 1e-6 * limit.upper
        for j in np.flatnonzero(excess > 0):
            k = int(traj.phase[j])
            found[k].add(round((traj.t[j] - times[k]) / (times[k + 1] - times[k]), 9))
    return found


def between_samples(problem: Problem, plan: CPPlan, times: list) -> list[set]:
    """Per phase, the normalised times where gamma_min or a limit fails between samples."""
    found = gamma_dips(problem, plan, times)
    excursions = limit_excursions(problem, plan, times)
    if excursions is None:
        return found
    merged = [a | b for a, b in zip(found, excursions, strict=True)]
    # a few points per stretch of violation are enough
    return [set(sorted(f)[:: max(1, len(f) // 8)]) for f in merged]


def violations(nlp: FlatNLP, g: np.ndarray, times: list, tol: float = 1e-6) -> list[str]:
    """The violated constraints, the worst place of each by name and time (at most 10)."""
    excess = np.maximum(nlp.lbg - g, g - nlp.ubg)
    out = []
    seen = set()
    for i in np.argsort(-excess):
        if excess[i] <= tol or len(out) == 10:
            break
        name, (phase, s) = nlp.rows[i]
        if name in seen:
            continue
        seen.add(name)
        t = times[phase] + s * (times[phase + 1] - times[phase])
        out.append(
            f"{name} at t = {t:.4g} s: value {g[i]:.4g}, bounds "
            f"[{nlp.lbg[i]:.4g}, {nlp.ubg[i]:.4g}]"
        )
    return out
