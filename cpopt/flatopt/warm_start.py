"""The flat optimizer's initial guess: the paper's closed form through the nodes, projected onto
the B-spline basis.

Where a node's guessed values give gamma the other sign than the phase's being solved for and its
xi (or, after a via state's reset, xi_after) is free, it is moved to the sign's side
(gamma_min + 2 m/s^2 past zero). Where the closed form
is singular (e.g. a swing-up with x_s = x_g, the paper's remark), its curve is used anyway with a
lateral CP excursion K sin^2(pi s) added, which moves the guess off gamma = 0.
"""

from __future__ import annotations

import numpy as np

from ..closedform.bspline import SplineBasis, fit
from ..closedform.nodes import has_reset, node_names, nodes_from_values
from ..closedform.plan import CPPlan, SingularPlanError, closed_form
from ..closedform.trajectory import Trajectory
from ..model import flat
from ..problem import Problem
from .path_timing import initial_blocks, timing_guess, unpack
from .pose_fit import LinearRows, PoseTarget, refined
from .seed import PUSH, SIDE, seeded_values
from .transcribe import FlatNLP, coefficient_count


def initial_plan(problem: Problem, signs: tuple[int, ...]) -> CPPlan:
    """The closed-form plan through the nodes at their guessed values, xi moved where needed."""
    arm = problem.arm
    K, g0 = arm.K, arm.gravity
    gamma_min = problem.spec.optimizer.gamma_min
    values = problem.values
    xis = {}
    for i, name in enumerate(node_names(len(problem.nodes))):
        sides = [("xi", name, signs[max(i - 1, 0)])]
        if name.startswith("via") and has_reset(problem.nodes[i], name, "xi", problem.free):
            sides.append(("xi_after", f"{name}.xi_after", signs[i]))
        for field, key, sign in sides:
            xi = values[f"{name}.{field}"]
            gamma = flat.gamma(problem.nodes[i].state(after=field == "xi_after"), K, g0)
            if sign * gamma < gamma_min and f"{name}.{field}" in problem.free:
                xi += sign * (gamma_min + 2.0) - gamma
            xis[key] = xi
    nodes = nodes_from_values(values, len(problem.nodes), xis)
    try:
        return closed_form(arm, nodes)
    except SingularPlanError:
        return closed_form(arm, nodes, check=False)


def fallback_excursion(plan: CPPlan) -> list[float]:
    """Per phase, the amplitude [m] of the lateral CP excursion added to a singular closed form
    (K where |gamma| gets below 0.1 m/s^2, else 0)."""
    out = []
    for ph in plan.phases:
        value, _ = ph.curve.min_norm_of_acceleration_plus((0.0, plan.arm.gravity))
        out.append(plan.arm.K if value < 0.1 else 0.0)
    return out


def spline_coefficients(problem: Problem, plan: CPPlan) -> list[np.ndarray]:
    """Per phase, the closed-form curve projected onto the B-spline basis (n x 2), with the
    fallback excursion where the closed form is singular."""
    o = problem.spec.optimizer
    n = coefficient_count(o)
    basis = SplineBasis(o.degree, n)
    coefficients = []
    for ph, bump in zip(plan.phases, fallback_excursion(plan), strict=True):
        C = fit(basis, ph.curve)
        C[:, 0] += bump * np.sin(np.pi * np.linspace(0, 1, n)) ** 2
        coefficients.append(C)
    return coefficients


def initial_guess(nlp: FlatNLP, problem: Problem, signs: tuple[int, ...]) -> np.ndarray:
    """The whole initial decision vector: core variables and the lifted samples they imply
    (a path-timing problem starts from its file's control points and a smooth timing law)."""
    o = problem.spec.optimizer
    plan = initial_plan(problem, signs)
    if o.curve == "path_timing":
        blocks, coefficients = initial_blocks(problem), []
    else:
        blocks, coefficients = {}, spline_coefficients(problem, plan)
    p = nlp.parameters(problem.values)
    x = nlp.complete(_core(nlp, problem, _moved_xi(problem, plan), coefficients, blocks), p)
    return x if o.curve != "path_timing" else _joined_timing(nlp, problem, x, p)


def _moved_xi(problem: Problem, plan: CPPlan) -> dict[str, float]:
    """The problem's values with xi (and xi after a via state's reset) as the initial plan
    moved them."""
    values = dict(problem.values)
    for name, node in zip(node_names(len(plan.nodes)), plan.nodes, strict=True):
        values[f"{name}.xi"] = node.state()[6]
        if f"{name}.xi_after" in values:
            values[f"{name}.xi_after"] = node.state(after=True)[6]
    return values


def _core(nlp: FlatNLP, problem: Problem, values: dict, coefficients: list, blocks: dict):
    """The core decision variables: freed node values from ``values`` (SI), zero compensator
    inputs, the margin at gamma_min, the coefficients and path blocks."""
    o = problem.spec.optimizer
    core = []
    for block in nlp.layout.blocks:
        if block.kind == "value":
            core.append(values[block.name])
        elif block.kind == "alpha":
            core.extend([0.0] * block.size)
        elif block.kind == "margin":
            core.append(o.gamma_min)
        elif block.kind == "coefficients":
            lo, hi = block.rows
            core.extend(coefficients[block.phase][lo:hi].T.ravel())
        elif block.kind == "control_points":
            core.extend(blocks[block.name])
        else:  # timing
            lo, hi = block.rows
            core.extend(blocks[f"phase[{block.phase}].timing"][lo:hi])
    return np.asarray(core, float)


def _joined_timing(nlp: FlatNLP, problem: Problem, x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The initial vector with each timing law's inner coefficients joining its ends smoothly
    (the ends follow from the nodes and the initial path)."""
    outs = nlp.unpack(x, p)
    paths = problem.spec.optimizer.path
    core = np.array(x[: nlp.layout.size], float)
    start = 0
    for block in nlp.layout.blocks:
        if block.kind == "timing":
            _, c = unpack(paths[block.phase], outs[1 + block.phase])
            core[start : start + block.size] = timing_guess(paths[block.phase], c, block.rows)
        start += block.size
    return nlp.complete(core, p)


def _seeded_alphas(nlp: FlatNLP, core: np.ndarray, problem: Problem, seed: Trajectory) -> None:
    """Put the seed's compensator inputs at the nodes into ``core`` (in place) where it has them
    (an exact plan does; a collocation's stay zero)."""
    start = 0
    for block in nlp.layout.blocks:
        if block.kind == "alpha":
            t = problem.nodes[int(block.name[len("alpha[") : -1])].t
            alpha = [np.interp(t, seed.t, seed.alpha[:, j]) for j in range(block.size)]
            if np.all(np.isfinite(alpha)):
                core[start : start + block.size] = alpha
        start += block.size


FIT_SAMPLES = 200
"""Points per phase where a seed's CP is fitted."""


def seeded_guess(
    nlp: FlatNLP,
    problem: Problem,
    signs: tuple[int, ...],
    seed: Trajectory,
    orders: tuple[int, ...] | None = None,
    pose: bool = True,
) -> np.ndarray:
    """The whole initial decision vector from a seed trajectory (a coarse collocation, or a
    plan already solved): freed node values from its state (:func:`cpopt.flatopt.seed.
    seeded_values`), and each phase's free coefficients fitted to its CP by least squares with
    the eliminated boundary coefficients, which the node values fix, kept; ``orders``: the CP
    derivative orders fitted (None: those of :func:`targets`); ``pose`` False skips the
    refinement of a collocation seed's fit to the link's pose
    (:func:`cpopt.flatopt.pose_fit.refined`)."""
    o = problem.spec.optimizer
    values = seeded_values(problem, signs, seed)
    p = nlp.parameters(values)
    basis = SplineBasis(o.degree, coefficient_count(o))
    zero = [np.zeros((basis.count, 2))] * (len(problem.nodes) - 1)
    core = _core(nlp, problem, values, zero, {})  # the boundary rows follow from the values
    where, start = [], 0
    for block in nlp.layout.blocks:
        if block.kind == "coefficients":
            where.append((block, start))
        start += block.size
    _seeded_alphas(nlp, core, problem, seed)
    outs = nlp.unpack(nlp.complete(core, p), p)
    times = [n.t for n in nodes_from_values(values, len(problem.nodes))]
    for k in range(len(problem.nodes) - 1):
        blocks = [(b, at) for b, at in where if b.phase == k]
        free = np.zeros(basis.count, bool)
        for b, _ in blocks:
            free[b.rows[0] : b.rows[1]] = True
        C = np.array(outs[1 + k], float)
        span = (times[k], times[k + 1])
        least = signs[k] * (o.gamma_min + PUSH)
        arm = problem.arm if pose else None
        C[free] = fitted(basis, C, free, seed, span, least, orders, arm)
        for b, at in blocks:
            core[at : at + b.size] = C[b.rows[0] : b.rows[1]].T.ravel()
    return nlp.complete(core, p)


EXACT_FIT = 1e-3
"""The unit of misfit [m] when fitting an exact plan (a polish or a re-solve starts from one):
every CP derivative 0..4, the r-th in units of what a coefficient's change of this size does
to it at most, so that every order counts alike and a plan in the same basis is reproduced
(the benchmark transfer's switch plan re-solved from itself: 9 Ipopt iterations, where a fit
of its position and acceleration alone started 240 iterations away)."""
SEED_FIT = {0: 1e-2, 2: 0.1, 4: 1e3}
"""The units of misfit when fitting a collocation seed, whose torques are piecewise constant:
its CP position [m] and acceleration [m/s^2], and the fourth derivative [m/s^4] pulled towards
zero as smoothing (a position fit alone leaves the ends, where the node values fix the jet,
free to kink, and the torque follows the fourth derivative)."""


def exact_plan(seed: Trajectory) -> bool:
    """True when ``seed`` samples an exact plan (its CP's fourth derivative defined), not a
    collocation (whose CP has no fourth derivative)."""
    return bool(np.all(np.isfinite(seed.cp[:, :, 4])))


def reproduced(seed: Trajectory, t: np.ndarray, least: float) -> bool:
    """True when the fit reproduces ``seed`` at times t: an exact plan (:func:`exact_plan`)
    whose gamma keeps the sign of ``least`` there (a re-solve, a polish dropping no switch
    here); across a sign change its jet would fight the moved acceleration."""
    gamma = np.interp(t, seed.t, seed.gamma)
    return exact_plan(seed) and bool(np.all(np.sign(least) * gamma > 0))


def targets(
    seed: Trajectory, t: np.ndarray, least: float, h: float, gains: dict[int, float]
) -> dict[int, tuple[np.ndarray, float]]:
    """What the fit aims at at times t of a phase lasting h [s], per CP derivative order r:
    (target (len(t), 2), unit of misfit), :data:`EXACT_FIT` (``gains[r]``: the most a unit
    coefficient changes the r-th derivative in the phase's own time; the orders of ``gains``
    are those aimed at) for an exact plan whose
    gamma keeps the sign of ``least`` there, else :data:`SEED_FIT`. The
    acceleration is moved along the link so that sign(least) gamma >= |least|
    (p'' + g0 e_y = gamma (cos, sin)(theta)): a stretch where the seed's gamma is too small or
    of the other sign would start the phase near its singularity."""
    gamma = np.interp(t, seed.t, seed.gamma)
    exact = reproduced(seed, t, least)
    units = {r: EXACT_FIT * gains[r] / h**r for r in gains} if exact else SEED_FIT
    out = {}
    for r, unit in units.items():
        column = seed.cp[:, :, r] if exact or r < 4 else np.zeros_like(seed.cp[:, :, 0])
        out[r] = (np.column_stack([np.interp(t, seed.t, column[:, i]) for i in range(2)]), unit)
    theta = np.interp(t, seed.t, seed.z[:, 2])
    wanted = np.sign(least) * np.maximum(np.sign(least) * gamma, abs(least))
    along = np.column_stack([np.cos(theta), np.sin(theta)])
    if 2 in out:
        acceleration, unit = out[2]
        out[2] = (acceleration + (wanted - gamma)[:, None] * along, unit)
    return out


def fitted(
    basis: SplineBasis,
    C: np.ndarray,
    free: np.ndarray,
    seed: Trajectory,
    span: tuple[float, float],
    least: float,
    orders: tuple[int, ...] | None = None,
    arm=None,
) -> np.ndarray:
    """The free rows of a phase's coefficients (the others fixed) that fit the seed's CP and its
    derivatives on ``span`` [s] (:func:`targets`, those of ``orders`` among them when any
    are) by least squares; with the ``arm`` (its K and gravity), a collocation seed's fit is
    then refined to keep the third link's pose (:func:`cpopt.flatopt.pose_fit.refined`)."""
    h = span[1] - span[0]
    inside = SIDE / h  # the phase's own limits at its ends: a plan holds a reset's time twice
    s = np.linspace(inside, 1.0 - inside, FIT_SAMPLES)
    exact = reproduced(seed, span[0] + s * h, least)
    if not exact:
        s = np.linspace(0.0, 1.0, FIT_SAMPLES)  # a collocation seed: continuous at the ends
    # only the orders fitted: each basis matrix at these s (new for every phase length) costs
    # a Cox-de Boor recursion, most of a re-plan's warm start when all five were made
    aimed = range(5) if not exact or orders is None else [r for r in range(5) if r in orders]
    gains = {r: float(np.abs(basis.matrix(s, r)).max()) for r in aimed or range(5)}
    rows, rhs = [], []
    aims = targets(seed, span[0] + s * h, least, h, gains)
    if orders is not None and set(orders) & set(aims):
        aims = {r: aim for r, aim in aims.items() if r in orders}
    for order, (target, unit) in aims.items():
        B = basis.matrix(s, order) / h**order / unit
        rows.append(B[:, free])
        rhs.append(target / unit - B[:, ~free] @ C[~free])
    A, b = np.vstack(rows), np.vstack(rhs)
    solution, *_ = np.linalg.lstsq(A, b, rcond=None)
    if exact or arm is None or orders is not None:
        return solution
    t = span[0] + s * h
    B0, B2 = basis.matrix(s, 0), basis.matrix(s, 2) / h**2
    lin = LinearRows(
        A, b, B0[:, free], B2[:, free], B0[:, ~free] @ C[~free], B2[:, ~free] @ C[~free]
    )
    pose = PoseTarget(
        base=np.column_stack([np.interp(t, seed.t, seed.z[:, i]) for i in range(2)]),
        theta=np.interp(t, seed.t, seed.z[:, 2]),
        sign=int(np.sign(least)),
        least=abs(least),
        K=arm.K,
        gravity=arm.gravity,
    )
    return refined(solution, lin, pose)
