"""The seeded switch search (optimizer.switch_search: seed): the coarse collocation seed, the
pattern it suggests, the warm start fitted to it (its values inside their bounds, a patterned
seed that ends at the holding torque where the flat plan does, a fit that keeps the arm's
pose), and a search that never raises."""

import time
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from cpopt.flatopt import optimize, solve_for_signs
from cpopt.flatopt.dominance import DOMINATED_EARLIEST, dominated
from cpopt.flatopt.seed import (
    INSIDE,
    coarse_seed,
    inside,
    kept_crossings,
    patterned_seed,
    seeded_values,
)
from cpopt.flatopt.seeded import (
    BOUND_FIRST,
    RESERVED_SHARE,
    Run,
    reserved_for_bound,
    worth_polishing,
)
from cpopt.flatopt.switching import (
    Pattern,
    first_attempts,
    grow,
    needed_times,
    neighbours,
    preference,
    seed_pattern,
    sign_assignments,
    with_switches,
)
from cpopt.problem import load_problem, parse_problem
from cpopt.verify.simulate import simulate_open_loop

ROOT = Path(__file__).resolve().parent.parent


def _auto(path: Path, **optimizer):
    """A problem with gamma_switches: auto, no sign asked, and other optimizer settings."""
    problem = load_problem(path)
    data = problem.spec.model_dump()
    data["planner"] = "optimize"
    data["optimizer"].update(gamma_switches="auto", gamma_sign=None, **optimizer)
    return parse_problem(data, problem.source, problem.name)


@pytest.fixture(scope="module")
def transfer():
    return _auto(ROOT / "benchmarks" / "problems" / "transfer.yaml")


@pytest.fixture(scope="module")
def transfer_seed(transfer):
    return coarse_seed(transfer)


def test_the_seed_finds_the_benchmark_transfers_three_crossings(transfer, transfer_seed):
    """The unconstrained optimum crosses gamma = 0 three times (0.09, 0.39, 0.45 s at N = 200);
    the dip between the last two stays shallower than gamma_min, so that pair cancels."""
    report = transfer_seed.report
    assert report.status == "solved" and report.intervals == 30
    assert report.crossings == pytest.approx((0.097, 0.397, 0.457), abs=0.01)
    assert report.switch_times == pytest.approx((0.097,), abs=0.01)
    pattern = seed_pattern(transfer, transfer_seed, 6)
    assert pattern.signs == (-1, 1)  # gamma < 0 while the link is swung, then > 0


def test_close_or_shallow_pairs_cancel_and_crossings_leave_the_nodes(transfer_seed):
    traj = transfer_seed.trajectory
    deep = (0.097, 0.6, 0.9)  # the seed's gamma is far from zero between these
    assert kept_crossings(deep, [0.0, 1.0], traj, 2.0) == deep
    assert kept_crossings((0.3, 0.32), [0.0, 1.0], traj, 0.0) == ()  # closer than MIN_PHASE
    assert kept_crossings((0.01,), [0.0, 1.0], traj, 0.0) == (0.05,)  # MIN_PHASE off the start


def test_neighbours_merge_pairs_before_dropping_switches(transfer, transfer_seed):
    from cpopt.flatopt.switching import Pattern

    old = Pattern((0.1, 0.4, 0.46), (-1, 1, -1, 1))
    found = neighbours(transfer, old)
    assert found[0] == Pattern((0.1,), (-1, 1))  # the short stretch 0.40-0.46 merged
    assert all(len(p.times) in (1, 2) for p in found)


def test_the_seeded_transfer_reaches_the_unconstrained_cost(transfer):
    """Measured: 40427 against 40369 for collocation without the regularity constraint at
    N = 200 (1.0014), one switch near 0.097 s, certified |gamma| >= gamma_min; its torques
    replayed open loop end 5e-9 from the goal (issue 18 asks 1e-6; 3e-6 before the phases
    ended exactly at their nodes' states and their pieces kept their derivatives' digits)."""
    result = optimize(transfer)
    assert simulate_open_loop(result.plan).final_state_error < 1e-7
    d = result.solver.details
    assert result.status == "solved"
    assert result.solver.objective == pytest.approx(40427.4, rel=2e-3)
    assert d.gamma_signs == ("negative", "positive")
    assert d.switch_times == pytest.approx((0.097,), abs=0.01)
    assert d.certified_min_abs_gamma >= 2.0
    figures = d.as_dict()["search"]
    assert figures["method"] == "seed"
    assert {"seed", "flat", "polish"} <= set(figures)
    assert figures["flat"]["iterations"] > 0 and figures["seed"]["time_s"] > 0
    # 40427 is below the seed's 40741: no neighbour pattern is tried (the summary says so, or
    # that the flat run spent the stages' iterations: 466-573 of 500, by the start's fit)
    assert figures["polish"]["patterns"] == 0
    assert "no polish" in figures["summary"] or "spent their 500" in figures["summary"]


def test_the_polish_is_skipped_only_near_the_seeds_cost(transfer, transfer_seed):
    """Within POLISH_GAIN (1 %) of the seed's 40741 the polish cannot gain; above it, or for a
    failed plan, or when the duration is free, the rule says nothing."""
    seed_cost = transfer_seed.report.objective
    assert seed_cost == pytest.approx(40740.7, rel=1e-3)

    def plan(status, objective):
        return SimpleNamespace(status=status, objective=objective)

    assert not worth_polishing(transfer, plan("solved", 1.009 * seed_cost), transfer_seed)
    assert worth_polishing(transfer, plan("solved", 1.011 * seed_cost), transfer_seed)
    assert not worth_polishing(transfer, plan("max_iterations", 0.5 * seed_cost), transfer_seed)
    free_duration = SimpleNamespace(free={"duration": (0.5, 2.0)})
    assert worth_polishing(free_duration, plan("solved", 0.5 * seed_cost), transfer_seed)


def test_the_seeded_start_fits_the_seed_and_keeps_the_signs(transfer, transfer_seed):
    """The warm start's CP follows the seed's, and its gamma has each phase's sign."""
    from cpopt.closedform.trajectory import sample
    from cpopt.flatopt import plan_from
    from cpopt.flatopt.seed import seeded_values
    from cpopt.flatopt.transcribe import build
    from cpopt.flatopt.warm_start import seeded_guess

    pattern = seed_pattern(transfer, transfer_seed, 6)
    problem, switches = with_switches(transfer, pattern.times, free_times=False)
    nlp = build(problem, pattern.signs)
    x0 = seeded_guess(nlp, problem, pattern.signs, transfer_seed.trajectory)
    p = nlp.parameters(seeded_values(problem, pattern.signs, transfer_seed.trajectory))
    plan, _, _ = plan_from(problem, nlp, x0, p, pattern.signs, switches)
    traj = sample(plan, 201)
    seed = transfer_seed.trajectory
    cp = np.column_stack([np.interp(traj.t, seed.t, seed.cp[:, i, 0]) for i in range(2)])
    assert np.abs(traj.cp[:, :, 0] - cp).max() < 0.05  # [m]; measured 0.026 (gamma pushed)
    for k, phase in enumerate(plan.phases):
        assert (phase.sigma * traj.gamma[traj.phase == k]).min() > 1.0  # [m/s^2]


@pytest.mark.slow
@pytest.mark.parametrize(
    "path, search, method",
    [
        # crashed the greedy once; its seed crosses nowhere: the one-sign bound is the plan
        (ROOT / "problems" / "rpr_transfer.yaml", "seed", "one_sign"),
        (ROOT / "problems" / "rpr_transfer.yaml", "greedy", "greedy"),
        # the seed's two switches (1.36, 1.80 s) solve at 479.3 from its patterned seed fitted
        # to the link's pose (flatopt.pose_fit); before that fit they did not (1094 iterations
        # from the seed) and an alternative near the via state (1.2 s) solved at 484.1 or
        # 501.5, two local optima which the rounding picked (issue 30: the greedy search had
        # kept one sign). That plan is 25.6 % above its seed, so refine_basis: auto solves it
        # again in a finer basis: 435.5 (measured, here and on CI) until the search's deadline;
        # unconstrained collocation N = 200 is 374.9
        (ROOT / "problems" / "prr_swing_up.yaml", "seed", ("seed", "near")),
    ],
    ids=["rpr transfer seed", "rpr transfer greedy", "prr swing-up seed"],
)
def test_no_search_raises_on_an_unseen_problem(path, search, method):
    problem = _auto(path, switch_search=search, samples=30)
    result = optimize(problem)
    assert result.status in ("solved", "max_iterations", "not_converged", "infeasible")
    assert result.plan is not None
    d = result.solver.details
    figures = d.as_dict()["search"]
    assert figures["method"] in ((method,) if isinstance(method, str) else method)
    # never costlier than a one-sign plan the search solved (the bound, issue 30)
    one_sign = [a.objective for a in d.sign_choices if a.status == "solved" and not a.switch_times]
    assert result.status == "solved" and result.solver.objective <= min(one_sign) * (1 + 1e-9)
    if path.name == "prr_swing_up.yaml":
        # a machine too slow for the refinement keeps 479.3 (or 484.1, 501.5); none goes
        # below the unconstrained optimum
        assert 0.99 * 374.9 < result.solver.objective < 1.01 * 501.5
        assert result.solver.objective < 0.2 * min(one_sign)


def test_collocation_reports_where_gamma_crosses_zero(transfer):
    """An unconstrained collocation plan that crosses gamma = 0 has min |gamma| = 0 and says
    where (at knots alone it reported 0.67 m/s^2)."""
    from cpopt.collocation import collocate, joint_metrics, joint_trajectory

    plan = collocate(transfer, intervals=30, gamma_constraint=False).plan
    m = joint_metrics(plan, joint_trajectory(plan))
    assert m.gamma_sign_changes == pytest.approx((0.097, 0.397, 0.457), abs=0.01)
    assert m.min_abs_gamma == 0.0 and m.min_abs_gamma_time == m.gamma_sign_changes[0]
    assert m.as_dict()["gamma_sign_changes"] == list(m.gamma_sign_changes)


def test_attempts_rank_solved_then_sane_then_fewest_violations():
    """The seeded search's retry once ended with Ipopt's Invalid_Number_Detected and an
    objective of 0, and won over a nearly feasible max_iterations plan (quick benchmark)."""

    def attempt(status, ipopt, objective, violations=()):
        return SimpleNamespace(
            status=status, ipopt_status=ipopt, objective=objective, violations=violations
        )

    solved = attempt("solved", "Solve_Succeeded", 5e4)
    near = attempt("max_iterations", "Maximum_Iterations_Exceeded", 4.1e4, ("one",))
    broken = attempt("not_converged", "Invalid_Number_Detected", 0.0)
    worse = attempt("max_iterations", "Maximum_Iterations_Exceeded", 3e4, ("one", "two"))
    ranked = sorted([broken, worse, near, solved], key=preference, reverse=True)
    assert ranked == [solved, near, worse, broken]


def _abandoned_at(objectives, infeasibilities=None, best=100.0):
    """The first iteration (1-based) at which dominated(best) abandons the run, or None."""
    abandon = dominated(best)
    infeasibilities = infeasibilities or [0.0] * len(objectives)
    for k, (f, inf) in enumerate(zip(objectives, infeasibilities, strict=True), start=1):
        if abandon(k, f, inf):
            return k
    return None


def test_a_dominated_run_is_abandoned_early_only_when_far_behind_or_stalled():
    # 5200 times the best from the start (swing_up_min_torque's losing sign): at iteration 10
    assert _abandoned_at([520000.0] * 40) == DOMINATED_EARLIEST == 10
    # falling 20 % an iteration from 30 times the best to 1.5: never abandoned
    assert _abandoned_at([max(3000.0 * 0.8**k, 150.0) for k in range(40)]) is None
    # falling to 2.09 times the best and staying (transfer_min_torque's): abandoned once stalled
    falling = [max(3000.0 * 0.8**k, 209.0) for k in range(40)]
    stalled_from = next(k for k, f in enumerate(falling, start=1) if f == 209.0)
    assert _abandoned_at(falling) == stalled_from + 5
    # 5 times the best and falling 3 % an iteration (not stalled): abandoned at iteration 30,
    # still above twice the best; from 4 times, it falls below twice the best first
    assert _abandoned_at([500.0 * 0.97**k for k in range(40)]) == 30
    assert _abandoned_at([400.0 * 0.97**k for k in range(40)]) is None
    # infeasible and not halving in 5 iterations (transfer_straight_line's restoration)
    stuck = [11.8] * 9 + [7.6] * 10
    assert _abandoned_at([90.0] * len(stuck), stuck) == 10
    halving = [11.8 * 0.8**k for k in range(40)]
    assert _abandoned_at([90.0] * 40, halving) is None


@pytest.mark.slow
def test_a_seeded_pattern_solves_from_its_patterned_seed():
    """swing_up_holding with links 1 and 2 heavier (1.5, 1.3 kg) over 2 s, gamma_switches
    auto: the seed's three switches (0.79, 0.99, 1.20 s) did not solve from the seed (Ipopt
    stopped on an invalid number); started from the patterned seed (the coarse collocation
    with those signs of gamma imposed, 13 iterations), where the flat objective starts far
    lower, they solve at 846.7 (measured; unconstrained collocation N = 200: 836.1, 1.013),
    below the bound, the one switch the pinned signs need at 1.16 s, 873.1 (what the search
    returned before the patterned seed)."""
    problem = load_problem(ROOT / "problems" / "swing_up_holding.yaml")
    data = problem.spec.model_dump()
    data["arm"]["links"][0]["mass"], data["arm"]["links"][1]["mass"] = 1.5, 1.3
    data["motion"]["duration"] = 2.0
    data["optimizer"]["gamma_switches"] = "auto"
    result = optimize(parse_problem(data, problem.source, problem.name))
    d = result.solver.details
    assert result.status == "solved"
    assert result.solver.objective == pytest.approx(846.7, rel=0.01)
    assert d.switch_times == pytest.approx((0.792, 0.994, 1.198), abs=0.01)
    assert d.certified_min_abs_gamma >= 2.0
    figures = d.as_dict()["search"]
    assert figures["method"] == "seed" and figures["bound"]["patterns"] == 1
    assert figures["patterned"]["patterns"] >= 1 and "0.97 x the bound" in figures["summary"]


def test_the_patterned_seed_keeps_each_sign_and_steps_only_at_its_switch(transfer, transfer_seed):
    """The benchmark transfer's seed solved again with its pattern imposed (one switch at
    0.097 s, negative then positive): sign * gamma >= gamma_min at every knot and midpoint,
    and between them up to the coarse grid's error; its torques are continuous but at the
    switch; it costs 40402 (measured), below the unconstrained seed's 40741 (its torques
    linear, not constant, between the knots)."""
    from cpopt.collocation.hermite_simpson import SUBSTEPS
    from cpopt.flatopt.seed import PatternedTrajectory, patterned_seed

    shaped = patterned_seed(transfer, transfer_seed, (0.09714813681125078,), (-1, 1))
    assert shaped is not None and shaped.report.status == "solved"
    assert shaped.report.objective == pytest.approx(40402.5, rel=1e-3)
    traj = shaped.trajectory
    assert isinstance(traj, PatternedTrajectory)
    before, after = traj.t < 0.0971, traj.t > 0.0972
    gamma_min = transfer.spec.optimizer.gamma_min
    assert (-traj.gamma[before]).min() >= 0.9 * gamma_min
    assert traj.gamma[after].min() >= 0.9 * gamma_min
    # each knot's torque against its left limit, extrapolated along the interval before
    knots = np.arange(SUBSTEPS, traj.t.size - 1, SUBSTEPS)
    left = 2 * traj.tau[knots - 1] - traj.tau[knots - 2]
    jumps = np.abs(traj.tau[knots] - left).max(axis=1)
    at_switch = np.isclose(traj.t[knots], 0.0971, atol=1e-3)
    assert at_switch.sum() == 1 and jumps[at_switch][0] > 10.0  # [N m]
    assert jumps[~at_switch].max() < 1e-9


def test_a_hopeless_pattern_is_not_solved_flat(transfer, transfer_seed):
    """A pattern whose patterned seed costs more than HOPELESS times the bound is skipped:
    with a bound at half the transfer's patterned cost, its one switch is hopeless."""
    from cpopt.flatopt import solve_for_signs
    from cpopt.flatopt.seeded import HOPELESS, Run
    from cpopt.flatopt.switching import Pattern

    run = Run(transfer, solve_for_signs, transfer_seed)
    pattern = Pattern((0.09714813681125078,), (-1, 1))
    run.bound = SimpleNamespace(status="solved", objective=40402.5 / (2 * HOPELESS))
    assert run.hopeless(pattern)
    run.bound = SimpleNamespace(status="solved", objective=40402.5)
    assert not run.hopeless(pattern)
    assert run.stages["patterned"].tried == 1  # solved once, kept for the pattern


def test_inside_moves_finite_bounds_in_by_a_fraction_of_the_range():
    assert inside(-40.0, 40.0) == pytest.approx((-40.0 + 80 * INSIDE, 40.0 - 80 * INSIDE))
    assert inside(-np.inf, 3.0) == (-np.inf, 3.0)


def test_a_seeded_value_past_its_bound_stays_clear_of_it(transfer, transfer_seed):
    """A value the seed suggests beyond its bound is clipped INSIDE of the range inside it:
    Ipopt pushes a start that sits on a bound inside by 1 % of it, which moved a random RRR
    transfer's goal xi and eta (clipped at 40 and 200) and started its lifted samples 299 off
    their rows (measured: inf_pr 2.99e2 at iteration 0, 0 once clipped inside)."""
    pattern = seed_pattern(transfer, transfer_seed, 6)
    problem, _ = with_switches(transfer, pattern.times, free_times=False)
    key = next(k for k in problem.free if k.endswith(".eta") and not k.startswith("switch"))
    free = dict(problem.free)
    values = seeded_values(problem, pattern.signs, transfer_seed.trajectory)
    width = 1e-3  # [m/s^3] a range the seed's eta is far outside of
    free[key] = (values[key] + 10.0, values[key] + 10.0 + width)
    clipped = seeded_values(replace(problem, free=free), pattern.signs, transfer_seed.trajectory)
    assert clipped[key] == pytest.approx(free[key][0] + INSIDE * width, abs=1e-12)


def test_a_patterned_seed_ends_at_the_holding_torque_where_the_flat_plan_does():
    """swing_up_holding (smooth torque, rest ends held at xi = 0 with the base still): the
    patterned seed's actuated joints do not accelerate at a held end (measured 1e-9 rad/s^2 or
    less), where without the held rows a random RRR swing-up's ended at gamma = 2.5 m/s^2
    against its flat plan's g0."""
    from cpopt.problem.holding import holding_pattern

    problem = _auto(ROOT / "problems" / "swing_up_holding.yaml")
    seed = coarse_seed(problem)
    pattern = holding_pattern(problem, (-1, 1))  # gamma from -g0 to +g0: one switch at 0.8 s
    held = (pattern[0], pattern[-1])
    assert held == (True, True)
    shaped = patterned_seed(problem, seed, (0.8,), (-1, 1))
    assert shaped is not None
    qdd = shaped.trajectory.qdd
    for end, index in zip(held, (0, -1), strict=True):
        if end:
            assert np.abs(qdd[index, :2]).max() < 1e-6  # [rad/s^2]


def test_the_pose_fit_keeps_the_links_base_where_the_seed_has_it(transfer, transfer_seed):
    """The benchmark transfer's seeded start for its seed's pattern: the third link's base of
    the fitted plan stays within 1 cm of the seed's (measured 2.1 mm) where the linear fit
    alone (positions and accelerations in their units) left it 5.8 cm away."""
    from cpopt.closedform.trajectory import sample
    from cpopt.flatopt import plan_from
    from cpopt.flatopt.transcribe import build
    from cpopt.flatopt.warm_start import seeded_guess

    pattern = seed_pattern(transfer, transfer_seed, 6)
    problem, switches = with_switches(transfer, pattern.times, free_times=False)
    nlp = build(problem, pattern.signs)
    seed = transfer_seed.trajectory
    p = nlp.parameters(seeded_values(problem, pattern.signs, seed))
    misfits = []
    for pose in (True, False):
        x0 = seeded_guess(nlp, problem, pattern.signs, seed, pose=pose)
        plan, _, _ = plan_from(problem, nlp, x0, p, pattern.signs, switches)
        traj = sample(plan, 201)
        base = np.column_stack([np.interp(traj.t, seed.t, seed.z[:, i]) for i in range(2)])
        misfits.append(float(np.hypot(*(traj.z[:, :2] - base).T).max()))
    assert misfits[0] < 0.01  # [m]
    assert misfits[1] > 0.04


def test_greedy_steps_need_a_solved_plan_and_say_so():
    """With an unsolved bound the greedy steps try nothing and name the reason (they said
    "0 switch(es): the most allowed" before, as if the budget had stopped them)."""
    optimizer = SimpleNamespace(gamma_switches="auto")
    problem = SimpleNamespace(spec=SimpleNamespace(optimizer=optimizer))
    bound = SimpleNamespace(status="not_converged", switch_times=())

    def solve(*args, **kwargs):
        raise AssertionError("no candidate is solved without a plan to step from")

    best, attempts, said = grow(problem, solve, bound)
    assert best is bound and attempts == []
    assert said == "no solved plan to step from (the bound not_converged)"


def test_the_bounds_runs_stop_at_their_iteration_limit(transfer):
    """``first_attempts(..., limit)`` caps each one-sign run's first round (the search's bound
    passes ONE_SIGN_LIMIT). At 3 iterations the seed's favourite sign of the benchmark transfer
    stops there and keeps its best certified iterate (iteration 4 counted from 1); the other
    sign's first round is cut the same way and its refinement round then runs past the cap, as
    a solved plan's refinements must (measured: 50 iterations, one refinement)."""
    times = needed_times(transfer)
    patterns = [Pattern(times, signs) for signs in sign_assignments(transfer, times)]
    attempts = first_attempts(solve_for_signs, transfer, patterns, None, 3)
    assert len(attempts) == 2
    first, second = attempts
    assert first.iterations == 3 and first.refinements == 0
    assert first.ipopt_status == "Best_Feasible_Iterate_At_4"
    assert second.status == "solved" and second.refinements == 1
    assert 45 <= second.iterations <= 55  # past the cap of 3: the refinement ran in full


def test_a_best_plan_that_fails_verification_gives_way_to_the_next_solved_one(monkeypatch):
    """The search's best plan of swing_up_switches (its seed's pattern) is made to fail the
    closed-loop simulation (the first verification returns a divergence); the next solved
    plan of the search, verified for real, is returned instead: solved, ``runner_up``, costlier
    than the best and no costlier than the one-sign bound (3424.8)."""
    import cpopt
    import cpopt.pipeline
    from cpopt.verify.simulate import DivergedVerification

    real, calls = cpopt.pipeline.verify, []

    def first_diverges(plan, residual, poles):
        calls.append(plan)
        if len(calls) == 1:
            return DivergedVerification("closed_loop", 0.5, "the test's divergence", residual)
        return real(plan, residual, poles)

    monkeypatch.setattr(cpopt.pipeline, "verify", first_diverges)
    solution = cpopt.solve(ROOT / "problems" / "swing_up_switches.yaml")
    search = solution.solver.details.search_figures
    assert solution.status == "solved" and solution.verification.passed()
    assert search["method"] == "runner_up" and "the test's divergence" in search["summary"]
    best = min(a.objective for a in solution.solver.details.sign_choices if a.status == "solved")
    assert best < solution.solver.objective <= 3424.8 * (1 + 1e-3)
    assert len(calls) == 2 and calls[1] is solution.plan


def test_the_seeds_pattern_leaves_the_cut_one_sign_run_its_share_of_the_time(transfer):
    """While the seed's pattern runs, the search's deadline is RESERVED_SHARE of the time left
    when no one-sign plan solved and one was cut at BOUND_FIRST iterations; it is restored
    after, and untouched when the bound solved or no run was cut."""
    start = time.monotonic()
    run = Run(transfer, solve=None, seed=None, deadline=start + 10.0)
    cut = SimpleNamespace(status="not_converged", iterations=BOUND_FIRST, signs=("positive",))
    run.opening, run.bound, notes = [cut], cut, []
    with reserved_for_bound(run, notes):
        left = run.deadline - start
    assert RESERVED_SHARE * 10.0 <= left < RESERVED_SHARE * 10.0 + 0.05  # + half the time taken
    assert run.deadline == start + 10.0
    assert notes == ["50% of the time left kept for the one-sign plans"]
    solved = SimpleNamespace(**{**vars(cut), "status": "solved"})
    short = SimpleNamespace(**{**vars(cut), "iterations": BOUND_FIRST - 1})
    for bound, opening in [(solved, [cut]), (cut, [short])]:
        run.bound, run.opening = bound, opening
        with reserved_for_bound(run, notes):
            assert run.deadline == start + 10.0
    assert len(notes) == 1
