"""Where a seeded flat solve starts: the seed's values inside their bounds, a patterned seed that
ends at the holding torque where the flat plan must, and a fit that keeps the arm's pose."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from cpopt.flatopt.seed import INSIDE, coarse_seed, inside, patterned_seed, seeded_values
from cpopt.flatopt.switching import seed_pattern, with_switches
from cpopt.problem import load_problem, parse_problem

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
    from cpopt.collocation.hermite_simpson import held_ends

    problem = _auto(ROOT / "problems" / "swing_up_holding.yaml")
    seed = coarse_seed(problem)
    held = held_ends(problem, (-1, 1))  # gamma from -g0 to +g0: one switch, here at 0.8 s
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
