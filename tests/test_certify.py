"""A flat solve's plan counts as solved only with its |gamma| certified above gamma_min, and a
dip between the samples gets a cluster of points (flatopt.refine.gamma_dips), and so does an
elbow nearly stretched between them (flatopt.refine.reach_dips)."""

from dataclasses import replace
from itertools import pairwise
from pathlib import Path

import numpy as np

import cpopt
from cpopt.closedform.trajectory import flat_states
from cpopt.flatopt import solved_if_certified, transcribe
from cpopt.flatopt.refine import (
    DIP_CLUSTER,
    REACH_CHECK_SAMPLES,
    gamma_dips,
    reach_dips,
    unrefined_flaw,
)
from cpopt.runtime.solver import NlpRun

REACH_FLAW = "Reach_Margin_Not_Certified_At_Deadline"
ROOT = Path(__file__).resolve().parent.parent


def _paper_plan():
    """The paper's transfer (closed form) and its problem, with gamma_min set just above and
    just below the plan's certified minimum of |gamma|."""
    problem = cpopt.load(ROOT / "problems" / "paper_transfer.yaml")
    plan = cpopt.solve(problem).plan
    return problem, plan, plan.min_abs_gamma()


def _with_gamma_min(problem, value: float):
    optimizer = problem.spec.optimizer.model_copy(update={"gamma_min": value})
    return replace(problem, spec=problem.spec.model_copy(update={"optimizer": optimizer}))


def test_a_solved_run_whose_gamma_dips_below_the_margin_is_not_converged():
    problem, plan, (low, _) = _paper_plan()
    run = NlpRun(x=np.zeros(1), objective=1.0, return_status="Solve_Succeeded", status="solved",
                 iterations=10, solve_time_s=0.1)  # fmt: skip
    above = solved_if_certified(_with_gamma_min(problem, 0.99 * low), run, plan, 4)
    assert above is run
    below = solved_if_certified(_with_gamma_min(problem, 1.01 * low), run, plan, 4)
    assert below.status == "not_converged"
    assert below.return_status == "Gamma_Not_Certified_After_4_Refinements"


def test_a_solved_run_out_of_the_arms_reach_is_unreachable():
    """The paper's transfer on an arm whose first two links are 40 % shorter: its samples leave
    the reach, so a solved run of it is unreachable, never solved."""
    problem, plan, (low, _) = _paper_plan()
    run = NlpRun(x=np.zeros(1), objective=1.0, return_status="Solve_Succeeded", status="solved",
                 iterations=10, solve_time_s=0.1)  # fmt: skip
    links = tuple(replace(k, length=0.6 * k.length) for k in plan.arm.links[:2])
    short = replace(plan, arm=replace(plan.arm, links=links + plan.arm.links[2:]))
    out = solved_if_certified(_with_gamma_min(problem, 0.99 * low), run, short, 0)
    assert out.status == "unreachable"
    assert out.return_status == "Out_Of_Reach_Between_Samples"


def test_a_dip_gets_eleven_points_around_it_within_its_phase():
    problem, plan, (low, t_low) = _paper_plan()
    times = [n.t for n in plan.nodes]
    dips = gamma_dips(_with_gamma_min(problem, 1.01 * low), plan, times)
    k = min(int(np.searchsorted(times, t_low, side="right")) - 1, len(plan.phases) - 1)
    s = (t_low - times[k]) / (times[k + 1] - times[k])
    cluster = {round(float(x), 9) for x in np.clip(s + DIP_CLUSTER, 0.0, 1.0)}
    assert len(DIP_CLUSTER) == 11 and cluster <= dips[k]
    assert all(0.0 <= x <= 1.0 for found in dips for x in found)


def test_the_built_nlps_are_kept_up_to_the_cache_size(monkeypatch):
    """Three structures (each sign, then each sign warm) with room for two: two kept, the
    oldest rebuilt when asked again (a new object)."""
    from cpopt.flatopt import transcribe

    problem = cpopt.load(ROOT / "problems" / "transfer_min_torque.yaml")
    monkeypatch.setattr(transcribe, "CACHE_SIZE", 2)
    first = transcribe.build(problem, (1,))
    transcribe.build(problem, (-1,))
    transcribe.build(problem, (1,), warm=True)
    assert transcribe.cached_structures() == 2
    assert transcribe.build(problem, (1,)) is not first
    assert transcribe.build(problem, (1,), warm=True) is transcribe.build(problem, (1,), warm=True)


def test_an_elbow_nearly_stretched_between_samples_gets_points_there():
    """The paper's transfer on an arm whose first two links reach just past the plan's farthest
    wrist point (a millionth further): there the elbow is within sin q2 = 0.003 of stretched,
    below the samples' bound 0.01, so the check adds the cluster around that time (and
    points along the stretch); on the paper's arm it adds none."""
    problem, plan, _ = _paper_plan()
    times = [n.t for n in plan.nodes]
    assert not any(reach_dips(plan, times))
    t = np.concatenate([np.linspace(a, b, REACH_CHECK_SAMPLES) for a, b in pairwise(times)])
    phase = np.repeat(np.arange(len(plan.phases)), REACH_CHECK_SAMPLES)
    _, z = flat_states(plan, t, phase)
    far = int(np.argmax(np.hypot(z[:, 0] - plan.arm.base[0], z[:, 1] - plan.arm.base[1])))
    reach = float(np.hypot(z[far, 0] - plan.arm.base[0], z[far, 1] - plan.arm.base[1]))
    first, second = plan.arm.links[:2]
    scale = reach * (1 + 1e-6) / (first.length + second.length)
    links = tuple(replace(k, length=scale * k.length) for k in (first, second))
    stretched = replace(plan, arm=replace(plan.arm, links=links + plan.arm.links[2:]))
    dips = reach_dips(stretched, times)
    assert unrefined_flaw(problem, stretched, times, None) == REACH_FLAW
    k = int(phase[far])
    s = round(far % REACH_CHECK_SAMPLES / (REACH_CHECK_SAMPLES - 1), 9)
    assert {round(float(x), 9) for x in np.clip(s + DIP_CLUSTER, 0.0, 1.0)} <= dips[k]
    assert sum(map(len, dips)) < 40  # one stretch: its cluster and eight points along it


def test_a_plan_the_deadline_kept_from_refining_is_priced_once_more():
    """A solved plan that the deadline kept from its refinement rounds counts as solved only
    if its quadrature is within 2 % of the fine integral: transfer_min_torque's plan on its own
    grid (50 samples: 82 547 against 82 698, 0.18 %) passes; on a grid of 10 samples its
    quadrature is 97 843, 18 % above, and it is not certified."""
    problem = cpopt.load(ROOT / "problems" / "transfer_min_torque.yaml")
    plan = cpopt.solve(problem).plan
    times = [n.t for n in plan.nodes]
    assert unrefined_flaw(problem, plan, times, transcribe.build(problem, (1,))) is None
    coarse = cpopt.load(ROOT / "problems" / "transfer_min_torque.yaml", **{"optimizer.samples": 10})
    flaw = unrefined_flaw(coarse, plan, times, transcribe.build(coarse, (1,)))
    assert flaw == "Cost_Not_Certified_At_Deadline"
