"""Checks of an optimized plan between its samples, and the report of violated constraints.

gamma is certified exactly on every polynomial piece of the CP curves (the end points and the
real roots of the derivative of |p'' + g0 e_y|^2); the reach margin, torque and joint-velocity
limits are checked on a fine grid. Where any fails, the optimizer adds samples there and solves
again. The objective's quadrature is checked piece by piece against a fine integral of the
plan; a piece where they differ by more than :data:`QUADRATURE_TOL` of the whole integral gets
twice the quadrature points, and the optimizer solves again.
"""

from __future__ import annotations

from dataclasses import replace
from itertools import pairwise

import numpy as np

from ..closedform.plan import CPPlan
from ..closedform.trajectory import flat_states, sample
from ..model.kinematics import ReachError, reach_margin
from ..model.limits import sampled
from ..model.objectives import abs_power, squared_norm, weights
from ..problem import Problem
from .ipopt_settings import WARM_GAMMA_GRID
from .quadrature import fine_rule
from .samples import QD, TAU, sample_values
from .transcribe import REACH_EPS, FlatNLP

CERTIFICATION = (
    "exact minimum of |p'' + g0 e_y| over every polynomial piece of the CP curves "
    "(end points and real roots of the derivative of its square)"
)
LIMIT_CHECK_SAMPLES = 2001
"""Samples per phase on which limits are checked after a solve."""
MAX_REFINEMENTS = 4
"""Re-solves with samples added where gamma, a limit or the quadrature failed."""
QUADRATURE_TOL = 1e-3
"""Largest difference between a piece's quadrature and its fine integral, relative to the
fine integral of the whole motion."""
REFINE_GROWTH = 2.0
"""Most a refinement round may multiply its previous round's objective. Measured on the zoo's
draws (seeds 1 and 2, 68 refinement rounds): the median ratio 1.000, every ratio but ten within
1.2, one at 1.4; the nine above 2 (2.2 to 633) were plans passing the edge of the reach whose
first round had under-sampled their torques, and every one of them went on growing (to 4e8 and
9e9, against collocation's 3e4-5e4), none certified, for up to 12 s of a 20-s search."""


def cost_kept(run, previous_run, refinements: int):
    """The solved run of a refinement round, ``not_converged`` when its objective grew past
    :data:`REFINE_GROWTH` times the previous round's (Ipopt's word
    ``Cost_Grew_<ratio>x_In_Refinement_<n>``): the previous round's samples missed the
    torques of a plan that is not what it priced."""
    before = previous_run.objective
    if not (before > 0 and run.objective > REFINE_GROWTH * before):
        return run
    word = f"Cost_Grew_{run.objective / before:.3g}x_In_Refinement_{refinements}"
    return replace(run, status="not_converged", return_status=word)


DIP_CLUSTER = np.r_[0.0, np.outer([-1.0, 1.0], 0.5 ** np.arange(5)).ravel()] / (WARM_GAMMA_GRID - 1)
"""The normalised times around a dip of |gamma| where a refinement adds points: the dip and,
on each side, one step of the coarser grid and its halves down to a sixteenth (finer than
either grid's step). A dip between two grid points is a sign change of gamma squeezed between
them, which the NLP moves a little each round when it gets one point only: a random RPR
swing-down ended its refinements at a certified 0.001 m/s^2."""


def dip_points(s: float) -> set[float]:
    """:data:`DIP_CLUSTER` around the normalised time ``s``, within the phase (rounded to
    1e-9, the key under which the grids merge points)."""
    return {round(float(x), 9) for x in np.clip(s + DIP_CLUSTER, 0.0, 1.0)}


STRETCH_POINTS = 8
"""About how many points a stretch of a failed check gets along it."""


def thinned(points) -> list:
    """About :data:`STRETCH_POINTS` of a stretch's sorted points, evenly picked."""
    points = sorted(points)
    return points[:: max(1, len(points) // STRETCH_POINTS)]


def gamma_dips(problem: Problem, plan: CPPlan, times: list) -> list[set]:
    """Per phase, the normalised times where the certified |gamma| is below gamma_min, each
    with :data:`DIP_CLUSTER` around it (within the phase)."""
    target = problem.spec.optimizer.gamma_min * (1 - 1e-6) - 1e-9
    found = [set() for _ in plan.phases]
    for k, ph in enumerate(plan.phases):
        for value, t in ph.curve.piece_minima((0.0, problem.arm.gravity)):
            if value < target:
                found[k] |= dip_points((t - times[k]) / (times[k + 1] - times[k]))
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


REACH_CHECK_SAMPLES = 2001
"""Samples per phase on which the reach margin is checked after a solve (the third link's base
alone, no inverse kinematics: 3.4 ms a phase)."""


def reach_dips(plan: CPPlan, times: list) -> list[set]:
    """Per phase, the normalised times where the reach margin falls below the samples' bound
    (:data:`cpopt.flatopt.transcribe.REACH_EPS`; an RRR elbow closer than sin q2 = 0.01 to
    stretched) on a grid of :data:`REACH_CHECK_SAMPLES`: each stretch's deepest point with
    :data:`DIP_CLUSTER` around it (:func:`dip_points`), and points along it
    (:func:`thinned`).

    Near the edge the joint rates grow like 1 / sin q2 and the torques faster: a random RRR
    swing-up (zoo seed 63) kept sin q2 >= 0.01 at its samples and passed 0.0006 between them,
    its torque integral 14 150 on its quadrature and 7.3e5 on a grid of 4001 a phase.
    """
    found = [set() for _ in plan.phases]
    eps = REACH_EPS[plan.arm.kind]
    if eps <= 0:
        return found
    s = np.linspace(0.0, 1.0, REACH_CHECK_SAMPLES)
    for k in range(len(plan.phases)):
        t = times[k] + s * (times[k + 1] - times[k])
        _, z = flat_states(plan, t, np.full(t.size, k))
        margin = np.asarray(reach_margin(plan.arm, z[:, 0], z[:, 1]))
        short = (margin < eps * (1 - 1e-6)).astype(int)
        edges = np.flatnonzero(np.diff(np.r_[0, short, 0]))  # each stretch's start and end
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            found[k] |= dip_points(s[a + int(np.argmin(margin[a:b]))])
            found[k].update(round(float(x), 9) for x in thinned(s[a:b]))
    return found


def between_samples(problem: Problem, plan: CPPlan, times: list) -> list[set]:
    """Per phase, the normalised times where gamma_min, the reach margin or a limit fails
    between samples."""
    gamma, reach = gamma_dips(problem, plan, times), reach_dips(plan, times)
    found = [a | b for a, b in zip(gamma, reach, strict=True)]
    excursions = limit_excursions(problem, plan, times)
    if excursions is None:
        return found
    # a few points per stretch of a limit's violation (found on a fine grid) are enough
    return [a | set(thinned(b)) for a, b in zip(found, excursions, strict=True)]


INTEGRAL_TERMS = frozenset({"torque", "energy", "v_squared"})
"""The objective terms that are integrals over the motion (the quadrature's business)."""


def integrand(problem: Problem, P: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The weighted integrand of the objective's integral terms at samples (an objective
    with none has none: see :data:`INTEGRAL_TERMS`).

    Parameters
    ----------
    P : numpy.ndarray
        CP derivatives 0..4 (N, 2, 5).
    y : numpy.ndarray
        The samples' outputs (N, 9) (:data:`cpopt.flatopt.samples.OUTPUTS`).
    """
    w = weights(problem.spec.optimizer.objective)
    terms = {
        "torque": lambda: squared_norm(y[:, TAU].T),
        "energy": lambda: abs_power(y[:, TAU].T, y[:, QD].T),
        "v_squared": lambda: squared_norm(P[:, :, 4].T),
    }
    return sum(w[k] * terms[k]() for k in terms if k in w)


def quadrature_pieces(problem: Problem, plan: CPPlan, nlp: FlatNLP) -> list[tuple]:
    """Per phase, the quadrature of the objective's integral terms on each piece of its grid
    and the fine integral of the plan there (two arrays, objective units); an empty list
    when the objective has no integral term."""
    if not INTEGRAL_TERMS & set(weights(problem.spec.optimizer.objective)):
        return []
    per_phase = []
    for ph, samples in zip(plan.phases, nlp.samples, strict=True):
        curve, h = ph.curve, ph.curve.t1 - ph.curve.t0
        pieces = int(samples.piece.max()) + 1
        breaks = np.linspace(0.0, 1.0, pieces + 1)
        fine = [fine_rule(a, b) for a, b in pairwise(breaks)]
        s = np.concatenate([samples.s[: samples.quadrature], *(rule[0] for rule in fine)])
        P = curve.derivatives(curve.t0 + s * h, 4)
        f = integrand(problem, P, sample_values(plan.arm, P, ph.sigma))
        m = samples.quadrature
        quad = np.bincount(samples.piece, weights=samples.weights * f[:m], minlength=pieces)
        exact = (f[m:].reshape(pieces, -1) * np.stack([rule[1] for rule in fine])).sum(axis=1)
        per_phase.append((h * quad, h * exact))
    return per_phase


def quadrature_gaps(problem: Problem, plan: CPPlan, nlp: FlatNLP) -> list[set[int]]:
    """Per phase, the pieces whose quadrature differs from the fine integral of the plan by
    more than :data:`QUADRATURE_TOL` of the whole fine integral."""
    per_phase = quadrature_pieces(problem, plan, nlp)
    if not per_phase:
        return [set() for _ in plan.phases]
    total = sum(exact.sum() for _, exact in per_phase)
    tol = QUADRATURE_TOL * abs(total) + 1e-12
    return [set(np.flatnonzero(np.abs(q - e) > tol).tolist()) for q, e in per_phase]


DEADLINE_COST_TOL = 0.02
"""Largest difference between a plan's quadrature and its fine integral, relative to the fine
integral, with which a solved round the deadline stopped before its refinement still counts as
solved (:func:`unrefined_flaw`)."""


def unrefined_flaw(problem: Problem, plan: CPPlan, times: list, nlp: FlatNLP) -> str | None:
    """Why a solved plan that the deadline kept from its refinement rounds may not count as
    solved (Ipopt's style of word), or None when it may.

    Such a plan's objective is its quadrature, unchecked: a random RPR swing-up (zoo seed 6,
    8-s limit) priced 31 874 there and 4.6e5 on the zoo's fine grid, its elbow nearly stretched
    between samples, and as ``solved`` it beat the one-sign plan (24 828). So the checks the
    next round would have made run once: the reach margin between samples, and the whole
    quadrature against the fine integral (:data:`DEADLINE_COST_TOL`). gamma_min and the arm's
    reach itself (not its margin) are certified for every plan anyway
    (:func:`cpopt.flatopt.solved_if_certified`)."""
    if any(reach_dips(plan, times)):
        return "Reach_Margin_Not_Certified_At_Deadline"
    per_phase = quadrature_pieces(problem, plan, nlp)
    quad = sum(q.sum() for q, _ in per_phase)
    exact = sum(e.sum() for _, e in per_phase)
    if abs(quad - exact) > DEADLINE_COST_TOL * abs(exact) + 1e-12:
        return "Cost_Not_Certified_At_Deadline"
    return None


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
